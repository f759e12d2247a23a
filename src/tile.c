/* SPDX-License-Identifier: MIT */
/* Re-tiling contours of neighbouring slices into a closed mesh (the
 * paper's section 3.5 uses a Delaunay/Voronoi construction between slices;
 * lodkit stitches contours, which is closed by construction).
 *
 * Topology first: every contour has a lower side (towards plane k - 1) and
 * an upper side. Each side is closed by exactly one of: a band to the
 * neighbouring slice, or a cap (an ear-clipped triangulation of the
 * contour). A band joins two loops, each one contour or several joined by
 * bridges; it uses each loop edge once and each of its diagonals twice; a
 * bridge quad uses its two loop-replaced contour edges once and its own
 * edges twice; a cap uses each contour edge once and each inner diagonal
 * twice. So every contour edge has exactly two triangles (one per side),
 * every other edge two, and each vertex's triangles form one fan: a closed
 * 2-manifold whatever the geometry. Orientation: a band walks its lower
 * loop forwards and its upper loop backwards; upper caps follow contour
 * order, lower caps run backwards; bridge quads follow their loop's side.
 * Contours from lk_mesh_slice run along axis x outward normal, so the
 * triangles face outwards.
 *
 * Correspondence: contours of planes k and k+1 with the same orientation
 * (outer with outer, hole with hole) whose overlap area (estimated on a
 * 24 x 24 grid over the intersection of their boxes) is significant are
 * connected; each connected group becomes one band (see lk_slices_tile in
 * lodkit.h for the rules). A contour paired on neither side (a feature
 * thinner than two spacings) would need two caps on the same polygon, which
 * share their diagonals: it is left out instead.
 *
 * A hole paired with no hole of the other slice, whose inside is mostly
 * empty there, is a pit that opens into a notch (or the reverse): it joins
 * the group of the contour around it and is bridged into its loop across
 * the wall that the other slice no longer has, instead of being capped.
 *
 * Stitching: the least total diagonal length over the (i, j) grid (Fuchs,
 * Kedem & Uselton), with the walk constrained so that no diagonal is used
 * twice, tried from several start pairs (a start pair is a diagonal of the
 * result, and the nearest point to one fixed point can lie across a notch). */
#include "internal.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define OVERLAP_GRID 24
/* Branches smaller than this share of the largest contour of their group
 * and slice are capped, not bridged. */
#define SMALL_BRANCH 0.01
/* Share of the smaller contour's area that makes an overlap count. */
#define SIGNIFICANT_OVERLAP 0.1

typedef struct overlap_pair {
    double overlap;
    uint32_t lower, upper;
} overlap_pair;

typedef struct box2 {
    double min[2], max[2];
} box2;

typedef struct tile_output {
    uint32_t *indices;
    size_t count, capacity; /* triangles */
} tile_output;

static int emit(tile_output *out, uint32_t a, uint32_t b, uint32_t c)
{
    if (out->count == out->capacity) {
        size_t capacity = out->capacity ? 2 * out->capacity : 1024;
        uint32_t *indices = lk__realloc_array(out->indices, 3 * capacity, sizeof(uint32_t));
        if (!indices) return 0;
        out->indices = indices;
        out->capacity = capacity;
    }
    out->indices[3 * out->count] = a;
    out->indices[3 * out->count + 1] = b;
    out->indices[3 * out->count + 2] = c;
    out->count++;
    return 1;
}

static int point_in_polygon(const double *points, size_t count, double x, double y)
{
    int inside = 0;
    for (size_t i = 0, j = count - 1; i < count; j = i++) {
        const double *p = points + 2 * i, *q = points + 2 * j;
        if ((p[1] > y) != (q[1] > y)) {
            double cross = p[0] + (y - p[1]) / (q[1] - p[1]) * (q[0] - p[0]);
            if (x < cross) inside = !inside;
        }
    }
    return inside;
}

static double overlap_area(const lk_slices *slices, const lk_contour *a, const box2 *box_a, const lk_contour *b,
                           const box2 *box_b)
{
    double lo[2], hi[2];
    for (int k = 0; k < 2; k++) {
        lo[k] = fmax(box_a->min[k], box_b->min[k]);
        hi[k] = fmin(box_a->max[k], box_b->max[k]);
        if (!(hi[k] > lo[k])) return 0;
    }
    const double *pa = slices->points + 2 * (size_t)a->first, *pb = slices->points + 2 * (size_t)b->first;
    double cell_x = (hi[0] - lo[0]) / OVERLAP_GRID, cell_y = (hi[1] - lo[1]) / OVERLAP_GRID;
    size_t inside = 0;
    for (int i = 0; i < OVERLAP_GRID; i++)
        for (int j = 0; j < OVERLAP_GRID; j++) {
            double x = lo[0] + (i + 0.5) * cell_x, y = lo[1] + (j + 0.5) * cell_y;
            if (point_in_polygon(pa, a->count, x, y) && point_in_polygon(pb, b->count, x, y)) inside++;
        }
    return (double)inside * cell_x * cell_y;
}

static double distance2(const double *p, const double *q)
{
    double dx = p[0] - q[0], dy = p[1] - q[1];
    return dx * dx + dy * dy;
}

/* Contour points of a model near FLT_MAX (3.4e38) may overshoot the float
 * range by a rounding or a wavelet's ringing: clamp instead of writing inf. */
static float finite_float(double value)
{
    if (value > FLT_MAX) return FLT_MAX;
    if (value < -FLT_MAX) return -FLT_MAX;
    return (float)value;
}

/* Band between lower contour a and upper contour b: the triangulated
 * annulus of least total diagonal length (dynamic programming over the
 * (i, j) grid of Fuchs, Kedem & Uselton), the pairing starting at the upper
 * point nearest to a's first point. The walk is a monotone lattice path from
 * (0, 0) to (na, nb) where (i, j) stands for the diagonal a_i - b_j, indices
 * modulo the sizes. So that no diagonal is used twice ((i, 0) and (i, nb)
 * are the same one, as are (0, j) and (na, j)), the path starts along a
 * (state (1, 0)), ends along b (from (na, nb - 1)) and avoids (na, 0). */
typedef struct stitch_work {
    double *cost; /* (na + 1) * (nb + 1); double: sums of lengths near 1e38 overflow float */
    unsigned char *came_from_a;
    size_t capacity;
} stitch_work;

/* A closed loop of points: one contour, or several joined by bridges. */
typedef struct loop {
    uint32_t *index; /* point ids */
    size_t count, capacity;
} loop;

static int loop_reserve(loop *l, size_t count)
{
    if (count <= l->capacity) return 1;
    size_t capacity = l->capacity ? l->capacity : 64;
    while (capacity < count) capacity *= 2;
    uint32_t *index = lk__realloc_array(l->index, capacity, sizeof(uint32_t));
    if (!index) return 0;
    l->index = index;
    l->capacity = capacity;
    return 1;
}

/* Fills the table for the pairing that starts with a[a_offset] - b[b_offset];
 * returns the least total diagonal length (INFINITY on allocation failure
 * is reported through *ok = 0). */
static double stitch_fill(const lk_slices *slices, const loop *a, const loop *b, size_t a_offset, size_t b_offset,
                          stitch_work *work, int *ok)
{
    const double *points = slices->points;
    size_t na = a->count, nb = b->count;
#define A_INDEX(i) (a->index[((i) + a_offset) % na])
#define B_INDEX(j) (b->index[((j) + b_offset) % nb])
#define A_POINT(i) (points + 2 * (size_t)A_INDEX(i))
#define B_POINT(j) (points + 2 * (size_t)B_INDEX(j))
    size_t width = nb + 1, cells = (na + 1) * width;
    if (cells > work->capacity) {
        double *cost = lk__realloc_array(work->cost, cells, sizeof(double));
        if (!cost) return *ok = 0, INFINITY;
        work->cost = cost;
        unsigned char *from = lk__realloc_array(work->came_from_a, cells, 1);
        if (!from) return *ok = 0, INFINITY;
        work->came_from_a = from;
        work->capacity = cells;
    }
    double *cost = work->cost;
    unsigned char *from_a = work->came_from_a;
    for (size_t i = 0; i <= na; i++) {
        for (size_t j = 0; j <= nb; j++) {
            size_t cell = i * width + j;
            if (i == 0 && j == 0) {
                cost[cell] = 0;
                continue;
            }
            int forbidden = (i == 0 && j > 0) || (j == nb && i < na) || (i == na && j == 0);
            double c = INFINITY;
            unsigned char via_a = 0;
            if (!forbidden) {
                double diagonal = sqrt(distance2(A_POINT(i), B_POINT(j)));
                if (i > 0 && isfinite(cost[cell - width]) && !(i == na && j == nb)) {
                    c = cost[cell - width] + diagonal;
                    via_a = 1;
                }
                if (j > 0 && isfinite(cost[cell - 1]) && cost[cell - 1] + diagonal < c) {
                    c = cost[cell - 1] + diagonal;
                    via_a = 0;
                }
            }
            cost[cell] = c;
            from_a[cell] = via_a;
        }
    }
    /* The closing diagonal a_0 - b_0 is the path's first and last edge. */
    return cost[na * width + nb] + sqrt(distance2(A_POINT(0), B_POINT(0)));
}

/* Start pairs tried: the closest pair of points of the two loops, and for
 * STITCH_STARTS points spread along a, the nearest point of b. A single
 * start (a's first point and its nearest point of b) can pair across a
 * notch: the whole band then turns around it in long fans. */
#define STITCH_STARTS 4

static int stitch(const lk_slices *slices, const loop *a, const loop *b, stitch_work *work, tile_output *out)
{
    const double *points = slices->points;
    size_t na = a->count, nb = b->count;
    size_t starts_a[STITCH_STARTS + 1] = {0}, starts_b[STITCH_STARTS + 1] = {0}, start_count = 0;
    double closest = INFINITY;
    for (size_t i = 0; i < na; i++)
        for (size_t j = 0; j < nb; j++) {
            double d = distance2(points + 2 * (size_t)a->index[i], points + 2 * (size_t)b->index[j]);
            if (d < closest) {
                closest = d;
                starts_a[0] = i;
                starts_b[0] = j;
            }
        }
    start_count = 1;
    for (size_t k = 0; k < STITCH_STARTS && k < na; k++) {
        size_t i = k * na / STITCH_STARTS, nearest = 0;
        double best = INFINITY;
        for (size_t j = 0; j < nb; j++) {
            double d = distance2(points + 2 * (size_t)a->index[i], points + 2 * (size_t)b->index[j]);
            if (d < best) {
                best = d;
                nearest = j;
            }
        }
        starts_a[start_count] = i;
        starts_b[start_count] = nearest;
        start_count++;
    }
    size_t a_offset = starts_a[0], b_offset = starts_b[0];
    double best_cost = INFINITY;
    int ok = 1;
    for (size_t k = 0; k < start_count; k++) {
        double c = stitch_fill(slices, a, b, starts_a[k], starts_b[k], work, &ok);
        if (!ok) return 0;
        if (c < best_cost) {
            best_cost = c;
            a_offset = starts_a[k];
            b_offset = starts_b[k];
        }
    }
    stitch_fill(slices, a, b, a_offset, b_offset, work, &ok);
    if (!ok) return 0;
    size_t width = nb + 1;
    const unsigned char *from_a = work->came_from_a;
    /* Walk back from (na, nb); the last move is along b by construction.
     * A move off the table (possible only if no finite path was found,
     * e.g. with non-finite lengths) goes along the other side instead, so
     * the walk always ends at (0, 0). */
    size_t i = na, j = nb;
    while (i > 0 || j > 0) {
        size_t cell = i * width + j;
        if ((from_a[cell] && i > 0) || j == 0) {
            if (!emit(out, A_INDEX(i - 1), A_INDEX(i), B_INDEX(j))) return 0;
            i--;
        } else {
            if (!emit(out, A_INDEX(i), B_INDEX(j), B_INDEX(j - 1))) return 0;
            j--;
        }
    }
#undef A_INDEX
#undef B_INDEX
#undef A_POINT
#undef B_POINT
    return 1;
}

/* Appends contour c to loop l (empty: c becomes the loop). Otherwise the
 * pair (p in l, q in c) whose quad (below) has the shortest sides p-q and
 * p'-q' (squared, penalised where they leave the other slice's contours) is
 * bridged: the loop runs ... p, q, c's
 * points around to q's predecessor q', then l's successor p' of p ...;
 * the quadrilateral p p' q' q, whose two edges p-p' and q'-q left the loop,
 * becomes two triangles on the loop's side (`upper` as for caps: the loop
 * is the lower contour of the band above it when upper is 1).
 * A contour bridged on both sides (a tunnel between slices) must not reuse
 * an edge between the two contours: `bridged` marks the quads' corners, and
 * a quad may not have marked corners on both of its sides. Returns 0 on
 * allocation failure, 2 when no bridge is allowed (c is left out: it gets a
 * cap), 1 otherwise. */
/* The contours of the other slice of a group: a bridge whose points lie
 * inside one of them crosses a place where the surface passes between the
 * two planes (the flank joining the branches), so it stays within about a
 * spacing of it; elsewhere it may hang in empty space. */
typedef struct bridge_partners {
    const uint32_t *group;
    uint32_t root;
    size_t first, end;   /* contour ids of the other slice */
    const uint32_t *ids; /* or, when not NULL, these contour ids */
    size_t id_count;
    /* The loop's first (largest) contour: points [anchor_first, +anchor_count). */
    uint32_t anchor_first, anchor_count;
} bridge_partners;

static int inside_partner(const lk_slices *slices, const bridge_partners *partners, double x, double y)
{
    int inside = 0;
    size_t count = partners->ids ? partners->id_count : partners->end - partners->first;
    for (size_t i = 0; i < count; i++) {
        size_t c = partners->ids ? partners->ids[i] : partners->first + i;
        if (!partners->ids && partners->group[c] != partners->root) continue;
        const lk_contour *contour = &slices->contours[c];
        if (point_in_polygon(slices->points + 2 * (size_t)contour->first, contour->count, x, y)) inside = !inside;
    }
    return inside;
}

/* A bridge entirely outside the other slice's contours costs this many
 * times its squared length (in proportion for partly outside ones). */
#define OUTSIDE_PENALTY 16.0
/* The same when the contours to bridge are known to be joined between the
 * planes (pieces from lk_mesh_slice): every branch is bridged then, however
 * small, and a strong penalty sent bridges from a small branch half way
 * round a coarse contour to stay over the other slice (bunny at 12.5%
 * without refinement: 3.00% Hausdorff at 16, 1.09% at 4, 1.85% at 1). */
#define PIECE_OUTSIDE_PENALTY 4.0
/* A bridge to a contour bridged earlier (not the loop's largest one) costs
 * this many times its squared length: branches joined between the planes
 * mostly join the main part, and two neighbouring branches (a cow's legs
 * cut near the hooves) are close to each other but joined far up. */
#define ELSEWHERE_PENALTY 4.0
/* Points tested along a bridge: BRIDGE_PROBES - 1 inner points. */
#define BRIDGE_PROBES 6

static int in_anchor(const bridge_partners *partners, uint32_t point)
{
    return point >= partners->anchor_first && point - partners->anchor_first < partners->anchor_count;
}

static int loop_append(const lk_slices *slices, loop *l, const lk_contour *c, int upper, unsigned char *bridged,
                       const bridge_partners *partners, int prefer_outside, tile_output *out)
{
    const double *points = slices->points;
    if (!loop_reserve(l, l->count + c->count)) return 0;
    if (l->count == 0) {
        for (uint32_t i = 0; i < c->count; i++) l->index[i] = c->first + i;
        l->count = c->count;
        return 1;
    }
    size_t best_p = SIZE_MAX, best_q = 0;
    double best = INFINITY;
    for (size_t p = 0; p < l->count; p++) {
        int marked_p = bridged[l->index[p]] || bridged[l->index[(p + 1) % l->count]];
        for (uint32_t q = 0; q < c->count; q++) {
            if (marked_p && (bridged[c->first + q] || bridged[c->first + (q + c->count - 1) % c->count])) continue;
            /* Both bridges of the quad count: p-q and its far side p'-q'. */
            const double *a = points + 2 * (size_t)l->index[p], *b = points + 2 * ((size_t)c->first + q);
            const double *a2 = points + 2 * (size_t)l->index[(p + 1) % l->count];
            const double *b2 = points + 2 * ((size_t)c->first + (q + c->count - 1) % c->count);
            double d = distance2(a, b) + distance2(a2, b2);
            if (d >= best) continue;
            int outside = 0;
            for (int k = 1; k < BRIDGE_PROBES; k++) {
                double t = (double)k / BRIDGE_PROBES;
                outside += prefer_outside !=
                           !inside_partner(slices, partners, a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]));
                outside += prefer_outside !=
                           !inside_partner(slices, partners, a2[0] + t * (b2[0] - a2[0]), a2[1] + t * (b2[1] - a2[1]));
            }
            double penalty = partners->ids ? PIECE_OUTSIDE_PENALTY : OUTSIDE_PENALTY;
            d *= 1 + (penalty - 1) * outside / (2 * (BRIDGE_PROBES - 1));
            if (partners->anchor_count &&
                !(in_anchor(partners, l->index[p]) && in_anchor(partners, l->index[(p + 1) % l->count])))
                d *= ELSEWHERE_PENALTY;
            if (d < best) {
                best = d;
                best_p = p;
                best_q = q;
            }
        }
    }
    if (best_p == SIZE_MAX) return 2;
    uint32_t p = l->index[best_p], p_next = l->index[(best_p + 1) % l->count];
    uint32_t q = c->first + (uint32_t)best_q, q_prev = c->first + (uint32_t)((best_q + c->count - 1) % c->count);
    bridged[p] = bridged[p_next] = bridged[q] = bridged[q_prev] = 1;
    /* Quad triangles: (p, p', q') and (q', q, p) traverse p->p' and q'->q
     * as the loop's own side does for contour edges (see cap()). */
    if (upper) {
        if (!emit(out, p, p_next, q_prev) || !emit(out, q_prev, q, p)) return 0;
    } else {
        if (!emit(out, q_prev, p_next, p) || !emit(out, p, q, q_prev)) return 0;
    }
    /* Insert c's points, starting at q, after position best_p. */
    size_t tail = l->count - (best_p + 1);
    memmove(l->index + best_p + 1 + c->count, l->index + best_p + 1, tail * sizeof(uint32_t));
    for (uint32_t k = 0; k < c->count; k++) l->index[best_p + 1 + k] = c->first + (uint32_t)((best_q + k) % c->count);
    l->count += c->count;
    return 1;
}

static double cross3(const double *a, const double *b, const double *c)
{
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

/* Ear clipping of a loop (one contour, or several joined by bridges).
 * upper: triangles follow loop order (facing +axis for an outer contour),
 * else reversed. next/prev: scratch of loop->count entries. */
static int cap_loop(const lk_slices *slices, const loop *l, int upper, uint32_t *link_next, uint32_t *link_prev,
                    tile_output *out)
{
    const double *points = slices->points;
    size_t n = l->count;
    double area = 0;
    for (size_t i = 0; i < n; i++) {
        const double *p = points + 2 * (size_t)l->index[i], *q = points + 2 * (size_t)l->index[(i + 1) % n];
        area += p[0] * q[1] - p[1] * q[0];
    }
    double sign = area < 0 ? -1 : 1;
    for (size_t i = 0; i < n; i++) {
        link_next[i] = (uint32_t)((i + 1) % n);
        link_prev[i] = (uint32_t)((i + n - 1) % n);
    }
#define LOOP_POINT(i) (points + 2 * (size_t)l->index[i])
    size_t remaining = n, current = 0, misses = 0;
    while (remaining > 3) {
        size_t prev = link_prev[current], next = link_next[current];
        const double *p = LOOP_POINT(prev), *c = LOOP_POINT(current), *q = LOOP_POINT(next);
        int ear = sign * cross3(p, c, q) > 0;
        if (ear) {
            for (size_t k = link_next[next]; k != prev; k = link_next[k]) {
                const double *r = LOOP_POINT(k);
                if (sign * cross3(p, c, r) >= 0 && sign * cross3(c, q, r) >= 0 && sign * cross3(q, p, r) >= 0 &&
                    !(r[0] == p[0] && r[1] == p[1]) && !(r[0] == q[0] && r[1] == q[1]) &&
                    !(r[0] == c[0] && r[1] == c[1])) {
                    ear = 0;
                    break;
                }
            }
        }
        /* After a full round without an ear (a self-touching or degenerate
         * polygon) clip anyway: the topology stays right. */
        if (ear || misses >= remaining) {
            uint32_t a = l->index[prev], b = l->index[current], d = l->index[next];
            if (!(upper ? emit(out, a, b, d) : emit(out, d, b, a))) return 0;
            link_next[prev] = (uint32_t)next;
            link_prev[next] = (uint32_t)prev;
            remaining--;
            misses = 0;
            current = next;
        } else {
            misses++;
            current = next;
        }
    }
#undef LOOP_POINT
    size_t prev = link_prev[current], next = link_next[current];
    uint32_t a = l->index[prev], b = l->index[current], d = l->index[next];
    return upper ? emit(out, a, b, d) : emit(out, d, b, a);
}

/* ---- caps that keep the surface a 2-manifold ----------------------------- */

/* Undirected edges with the number of triangles using them (open
 * addressing; a key is the two point ids, smaller first). */
typedef struct edge_uses {
    uint64_t *keys; /* UINT64_MAX = empty */
    unsigned char *uses;
    size_t capacity, count;
} edge_uses;

static uint64_t edge_key(uint32_t a, uint32_t b) { return a < b ? (uint64_t)a << 32 | b : (uint64_t)b << 32 | a; }

static size_t edge_slot(const edge_uses *set, uint64_t key)
{
    size_t mask = set->capacity - 1, slot = (size_t)((key * 0x9E3779B97F4A7C15ull) >> 17) & mask;
    while (set->keys[slot] != UINT64_MAX && set->keys[slot] != key) slot = (slot + 1) & mask;
    return slot;
}

static unsigned edge_uses_of(const edge_uses *set, uint32_t a, uint32_t b)
{
    if (set->capacity == 0) return 0; /* nothing added yet (caps only) */
    size_t slot = edge_slot(set, edge_key(a, b));
    return set->keys[slot] == UINT64_MAX ? 0 : set->uses[slot];
}

static int edge_uses_add(edge_uses *set, uint32_t a, uint32_t b)
{
    if (2 * (set->count + 1) > set->capacity) {
        edge_uses grown = {NULL, NULL, set->capacity ? 2 * set->capacity : 1024, 0};
        grown.keys = lk__malloc_array(grown.capacity, sizeof(uint64_t));
        grown.uses = lk__malloc_array(grown.capacity, 1);
        if (!grown.keys || !grown.uses) {
            free(grown.keys);
            free(grown.uses);
            return 0;
        }
        for (size_t i = 0; i < grown.capacity; i++) grown.keys[i] = UINT64_MAX;
        for (size_t i = 0; i < set->capacity; i++) {
            if (set->keys[i] == UINT64_MAX) continue;
            size_t slot = edge_slot(&grown, set->keys[i]);
            grown.keys[slot] = set->keys[i];
            grown.uses[slot] = set->uses[i];
        }
        grown.count = set->count;
        free(set->keys);
        free(set->uses);
        *set = grown;
    }
    uint64_t key = edge_key(a, b);
    size_t slot = edge_slot(set, key);
    if (set->keys[slot] == UINT64_MAX) {
        set->keys[slot] = key;
        set->uses[slot] = 0;
        set->count++;
    }
    if (set->uses[slot] < 255) set->uses[slot]++;
    return 1;
}

static int edge_uses_add_triangles(edge_uses *set, const uint32_t *indices, size_t triangle_count)
{
    for (size_t t = 0; t < triangle_count; t++)
        for (int c = 0; c < 3; c++)
            if (!edge_uses_add(set, indices[3 * t + c], indices[3 * t + (c + 1) % 3])) return 0;
    return 1;
}

static int compare_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return (x > y) - (x < y);
}

/* A side of some contours still to close: the loop's point ids, the plane
 * it lies on and which side of it the cap faces. */
typedef struct pending_cap {
    size_t first, count; /* in the pending index list */
    uint32_t slice;
    int upper;
} pending_cap;

typedef struct cap_work {
    pending_cap *caps;
    size_t cap_count, cap_capacity;
    uint32_t *index; /* loops of all pending caps */
    size_t index_count, index_capacity;
    double *apexes; /* 3 per new vertex: (u, v, axis position) */
    size_t apex_count, apex_capacity;
} cap_work;

static void cap_work_free(cap_work *work)
{
    free(work->caps);
    free(work->index);
    free(work->apexes);
}

static int pending_cap_add(cap_work *work, const loop *l, uint32_t slice, int upper)
{
    if (work->cap_count == work->cap_capacity) {
        size_t capacity = work->cap_capacity ? 2 * work->cap_capacity : 64;
        pending_cap *caps = lk__realloc_array(work->caps, capacity, sizeof(pending_cap));
        if (!caps) return 0;
        work->caps = caps;
        work->cap_capacity = capacity;
    }
    if (work->index_count + l->count > work->index_capacity) {
        size_t capacity = work->index_capacity ? work->index_capacity : 1024;
        while (capacity < work->index_count + l->count) capacity *= 2;
        uint32_t *index = lk__realloc_array(work->index, capacity, sizeof(uint32_t));
        if (!index) return 0;
        work->index = index;
        work->index_capacity = capacity;
    }
    memcpy(work->index + work->index_count, l->index, l->count * sizeof(uint32_t));
    work->caps[work->cap_count++] = (pending_cap){work->index_count, l->count, slice, upper};
    work->index_count += l->count;
    return 1;
}

/* Closes every pending cap. An ear-clipped cap whose diagonals are edges
 * already (the same contour capped on both sides, a component crossing a
 * single plane, or two contours joined by bridges on one side and by a cap
 * on the other) would give those edges four triangles; such a cap becomes
 * a fan around a new vertex at the loop's centroid, half a spacing off the
 * plane on the cap's side (where the surface ends between the planes).
 * Cost: O(n^2) per cap of n points, O(1) per edge lookup. */
static int close_pending_caps(const lk_slices *slices, cap_work *work, tile_output *tris, lk_tile_info *info)
{
    edge_uses set = {NULL, NULL, 0, 0};
    tile_output trial = {NULL, 0, 0};
    loop l = {NULL, 0, 0};
    uint32_t *links = NULL;
    uint64_t *keys = NULL;
    size_t link_capacity = 0, key_capacity = 0;
    int ok = 0;
    if (!edge_uses_add_triangles(&set, tris->indices, tris->count)) goto done;
    for (size_t i = 0; i < work->cap_count; i++) {
        const pending_cap *pending = &work->caps[i];
        l.index = work->index + pending->first;
        l.count = pending->count;
        if (l.count > link_capacity) {
            free(links);
            link_capacity = 2 * l.count;
            links = lk__malloc_array(2 * link_capacity, sizeof(uint32_t));
            if (!links) goto done;
        }
        trial.count = 0;
        if (!cap_loop(slices, &l, pending->upper, links, links + link_capacity, &trial)) goto done;
        /* Count each edge of the cap once per use and compare with what is
         * there already: at most two triangles per edge in the end. */
        if (3 * trial.count > key_capacity) {
            free(keys);
            key_capacity = 6 * trial.count;
            keys = lk__malloc_array(key_capacity, sizeof(uint64_t));
            if (!keys) goto done;
        }
        for (size_t t = 0; t < trial.count; t++)
            for (int c = 0; c < 3; c++)
                keys[3 * t + c] = edge_key(trial.indices[3 * t + c], trial.indices[3 * t + (c + 1) % 3]);
        qsort(keys, 3 * trial.count, sizeof(uint64_t), compare_u64);
        int clash = 0;
        for (size_t k = 0; k < 3 * trial.count && !clash;) {
            size_t run = 1;
            while (k + run < 3 * trial.count && keys[k + run] == keys[k]) run++;
            clash = edge_uses_of(&set, (uint32_t)(keys[k] >> 32), (uint32_t)keys[k]) + run > 2;
            k += run;
        }
        size_t before = tris->count;
        if (!clash) {
            for (size_t t = 0; t < trial.count; t++)
                if (!emit(tris, trial.indices[3 * t], trial.indices[3 * t + 1], trial.indices[3 * t + 2])) goto done;
        } else {
            if (work->apex_count == work->apex_capacity) {
                size_t capacity = work->apex_capacity ? 2 * work->apex_capacity : 16;
                double *apexes = lk__realloc_array(work->apexes, 3 * capacity, sizeof(double));
                if (!apexes) goto done;
                work->apexes = apexes;
                work->apex_capacity = capacity;
            }
            double *apex = work->apexes + 3 * work->apex_count;
            apex[0] = apex[1] = 0;
            for (size_t k = 0; k < l.count; k++) {
                apex[0] += slices->points[2 * (size_t)l.index[k]] / (double)l.count;
                apex[1] += slices->points[2 * (size_t)l.index[k] + 1] / (double)l.count;
            }
            apex[2] = lk_slices_plane(slices, pending->slice) + (pending->upper ? 0.5 : -0.5) * slices->spacing;
            uint32_t id = (uint32_t)(slices->point_count + work->apex_count++);
            for (size_t k = 0; k < l.count; k++) {
                uint32_t a = l.index[k], b = l.index[(k + 1) % l.count];
                if (!(pending->upper ? emit(tris, a, b, id) : emit(tris, b, a, id))) goto done;
            }
            info->apexes++;
        }
        if (!edge_uses_add_triangles(&set, tris->indices + 3 * before, tris->count - before)) goto done;
        info->caps++;
    }
    ok = 1;
done:
    free(set.keys);
    free(set.uses);
    free(trial.indices);
    free(links);
    free(keys);
    return ok;
}

/* ---- tiling by the surface pieces between the planes ---------------------- */

typedef struct piece_entry {
    uint32_t piece, contour;
    int upper; /* the contour lies on the slab's upper plane */
} piece_entry;

static int piece_entry_order(const void *a, const void *b)
{
    const piece_entry *x = a, *y = b;
    if (x->piece != y->piece) return x->piece < y->piece ? -1 : 1;
    if (x->upper != y->upper) return x->upper - y->upper;
    return (x->contour > y->contour) - (x->contour < y->contour);
}

/* Joins `count` contours (one side of a piece) into one loop: the largest
 * first, the others bridged into it (holes joined to an outer contour
 * across the place that is open on the other plane). Marks the sides it
 * closes in `closed`. Returns 0 on allocation failure. */
static int join_side(const lk_slices *slices, const uint32_t *ids, size_t count, int upper_plane,
                     const uint32_t *other_ids, size_t other_count, loop *target, unsigned char *bridged,
                     unsigned char *closed, tile_output *tris, lk_tile_info *info)
{
    target->count = 0;
    size_t largest = 0;
    for (size_t i = 1; i < count; i++)
        if (fabs(slices->contours[ids[i]].area) > fabs(slices->contours[ids[largest]].area)) largest = i;
    bridge_partners partners = {NULL,
                                0,
                                0,
                                0,
                                other_ids,
                                other_count,
                                slices->contours[ids[largest]].first,
                                slices->contours[ids[largest]].count};
    int largest_outer = slices->contours[ids[largest]].area > 0;
    for (size_t pass = 0; pass < 2; pass++)
        for (size_t i = 0; i < count; i++) {
            if ((pass == 0) != (i == largest)) continue;
            const lk_contour *contour = &slices->contours[ids[i]];
            int prefer_outside = contour->area < 0 && largest_outer;
            /* A contour on the slab's lower plane closes its upper side. */
            int appended = loop_append(slices, target, contour, !upper_plane, bridged, &partners, prefer_outside, tris);
            if (!appended) return 0;
            if (appended == 2) continue; /* no bridge allowed: capped on its own later */
            closed[ids[i]] |= upper_plane ? 1 : 2;
            if (pass == 1) info->bridges++;
        }
    return 1;
}

/* Bands and caps from the pieces: for each slab (between planes j - 1 and
 * j, and the two ends), the contours touching one piece form a group. A
 * group with contours on both planes is a band between the two joined
 * loops; a group on one plane only (the surface ends between the planes:
 * a tip, the bottom of a U, a torus's underside joining its outer contour
 * and its hole) is one cap over the joined loop. */
static int tile_by_pieces(const lk_slices *slices, const size_t *slice_first, unsigned char *closed,
                          unsigned char *bridged, loop *lower_loop, loop *upper_loop, stitch_work *stitch_tables,
                          tile_output *tris, cap_work *caps, lk_tile_info *info)
{
    size_t largest_slab = 0;
    for (size_t j = 0; j <= slices->slice_count; j++) {
        size_t first = slice_first[j > 0 ? j - 1 : 0], end = slice_first[j < slices->slice_count ? j + 1 : j];
        if (end - first > largest_slab) largest_slab = end - first;
    }
    piece_entry *entries = lk__malloc_array(largest_slab ? largest_slab : 1, sizeof(piece_entry));
    uint32_t *ids = lk__malloc_array(2 * (largest_slab ? largest_slab : 1), sizeof(uint32_t));
    int ok = 0;
    if (!entries || !ids) goto done;
    for (size_t j = 0; j <= slices->slice_count; j++) {
        size_t count = 0;
        if (j > 0)
            for (size_t c = slice_first[j - 1]; c < slice_first[j]; c++)
                entries[count++] = (piece_entry){slices->contours[c].above, (uint32_t)c, 0};
        if (j < slices->slice_count)
            for (size_t c = slice_first[j]; c < slice_first[j + 1]; c++)
                entries[count++] = (piece_entry){slices->contours[c].below, (uint32_t)c, 1};
        qsort(entries, count, sizeof(piece_entry), piece_entry_order);
        for (size_t g = 0; g < count;) {
            size_t end = g;
            while (end < count && entries[end].piece == entries[g].piece) end++;
            size_t lower_count = 0, upper_count = 0;
            uint32_t *lower_ids = ids, *upper_ids = ids + largest_slab;
            for (size_t i = g; i < end; i++) {
                if (entries[i].upper)
                    upper_ids[upper_count++] = entries[i].contour;
                else
                    lower_ids[lower_count++] = entries[i].contour;
            }
            g = end;
            if (lower_count && !join_side(slices, lower_ids, lower_count, 0, upper_ids, upper_count, lower_loop,
                                          bridged, closed, tris, info))
                goto done;
            if (upper_count && !join_side(slices, upper_ids, upper_count, 1, lower_ids, lower_count, upper_loop,
                                          bridged, closed, tris, info))
                goto done;
            if (lower_count && upper_count) {
                if (!stitch(slices, lower_loop, upper_loop, stitch_tables, tris)) goto done;
                info->bands++;
            } else if (lower_count) {
                if (!pending_cap_add(caps, lower_loop, (uint32_t)(j - 1), 1)) goto done;
            } else {
                if (!pending_cap_add(caps, upper_loop, (uint32_t)j, 0)) goto done;
            }
        }
    }
    ok = 1;
done:
    free(entries);
    free(ids);
    return ok;
}

lk_status lk_slices_tile(const lk_slices *slices, lk_mesh *out, lk_tile_info *info, lk_error *error)
{
    lk_tile_info local_info;
    if (!info) info = &local_info;
    memset(info, 0, sizeof *info);
    if (!slices || !out) return lk_error_set(error, LK_ERR_INVALID, "lk_slices_tile: NULL argument");
    lk_mesh_init(out);
    size_t contour_count = slices->contour_count;
    for (size_t c = 0; c < contour_count; c++) {
        const lk_contour *contour = &slices->contours[c];
        if (contour->count < 3 || (size_t)contour->first + contour->count > slices->point_count ||
            contour->slice >= slices->slice_count || (c > 0 && contour->slice < slices->contours[c - 1].slice))
            return lk_error_set(error, LK_ERR_INVALID,
                                "contour %zu is malformed (fewer than 3 points, out of range or out of slice order)",
                                c);
    }
    size_t *slice_first = lk__calloc_array(slices->slice_count + 1, sizeof(size_t));
    unsigned char *paired = lk__calloc_array(contour_count ? contour_count : 1, 1); /* bit 0 lower, bit 1 upper */
    box2 *boxes = lk__malloc_array(contour_count, sizeof(box2));
    size_t largest = 3;
    for (size_t c = 0; c < contour_count; c++)
        if (slices->contours[c].count > largest) largest = slices->contours[c].count;
    uint32_t *links = lk__malloc_array(2 * largest, sizeof(uint32_t));
    uint32_t *remap = lk__malloc_array(slices->point_count ? slices->point_count : 1, sizeof(uint32_t));
    uint32_t *group = lk__malloc_array(contour_count ? contour_count : 1, sizeof(uint32_t));
    unsigned char *bridged = lk__calloc_array(slices->point_count ? slices->point_count : 1, 1);
    double *best_overlap = lk__malloc_array(contour_count ? contour_count : 1, sizeof(double));
    overlap_pair *pairs = NULL;
    size_t pair_capacity = 0;
    loop lower_loop = {NULL, 0, 0}, upper_loop = {NULL, 0, 0};
    tile_output tris = {NULL, 0, 0};
    stitch_work stitch_tables = {NULL, NULL, 0};
    cap_work caps;
    memset(&caps, 0, sizeof caps);
    lk_status status = LK_OK;
    if (!slice_first || !paired || !boxes || !links || !remap || !group || !bridged || !best_overlap) {
        status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate tiling tables");
        goto done;
    }
    for (size_t c = 0; c < contour_count; c++) slice_first[slices->contours[c].slice + 1]++;
    for (size_t k = 0; k < slices->slice_count; k++) slice_first[k + 1] += slice_first[k];
    for (size_t c = 0; c < contour_count; c++) {
        const lk_contour *contour = &slices->contours[c];
        box2 *box = &boxes[c];
        box->min[0] = box->min[1] = INFINITY;
        box->max[0] = box->max[1] = -INFINITY;
        for (uint32_t i = 0; i < contour->count; i++) {
            const double *p = slices->points + 2 * ((size_t)contour->first + i);
            for (int k = 0; k < 2; k++) {
                box->min[k] = fmin(box->min[k], p[k]);
                box->max[k] = fmax(box->max[k], p[k]);
            }
        }
    }
    /* Contours from lk_mesh_slice know the surface pieces between the
     * planes: tile by those. Contours made by hand (pieces unknown) are
     * paired by overlap below. */
    int by_pieces = contour_count > 0;
    for (size_t c = 0; c < contour_count; c++)
        if (!slices->contours[c].below || !slices->contours[c].above) by_pieces = 0;
    if (by_pieces && !tile_by_pieces(slices, slice_first, paired, bridged, &lower_loop, &upper_loop, &stitch_tables,
                                     &tris, &caps, info))
        goto nomem;
    /* Bands: the overlap graph of each pair of neighbouring slices splits
     * into connected groups; each group's lower contours are bridged into
     * one loop, its upper contours into another, and the two loops are
     * stitched. A group of one lower and one upper contour is a plain band;
     * bigger groups are the branchings (splits and merges). */
    for (size_t k = 0; !by_pieces && k + 1 < slices->slice_count; k++) {
        size_t lower_first = slice_first[k], upper_end = slice_first[k + 2];
        size_t local = upper_end - lower_first;
        if (local == 0) continue;
        for (size_t c = lower_first; c < upper_end; c++) {
            group[c] = (uint32_t)c;
            best_overlap[c] = 0;
        }
        size_t pair_count = 0;
        for (size_t lower = slice_first[k]; lower < slice_first[k + 1]; lower++)
            for (size_t upper = slice_first[k + 1]; upper < upper_end; upper++) {
                const lk_contour *a = &slices->contours[lower], *b = &slices->contours[upper];
                if ((a->area < 0) != (b->area < 0)) continue;
                double overlap = overlap_area(slices, a, &boxes[lower], b, &boxes[upper]);
                if (overlap <= 0) continue;
                if (pair_count == pair_capacity) {
                    size_t capacity = pair_capacity ? 2 * pair_capacity : 64;
                    overlap_pair *grown = lk__realloc_array(pairs, capacity, sizeof(overlap_pair));
                    if (!grown) goto nomem;
                    pairs = grown;
                    pair_capacity = capacity;
                }
                pairs[pair_count].overlap = overlap;
                pairs[pair_count].lower = (uint32_t)lower;
                pairs[pair_count].upper = (uint32_t)upper;
                pair_count++;
                best_overlap[lower] = fmax(best_overlap[lower], overlap);
                best_overlap[upper] = fmax(best_overlap[upper], overlap);
            }
        /* A pair joins a group when its overlap is the best of one of its
         * contours or a real share (SIGNIFICANT_OVERLAP) of the smaller one:
         * slivers from contours that merely shift must not turn two
         * parallel bands into one bridged group. */
        for (size_t i = 0; i < pair_count; i++) {
            uint32_t lower = pairs[i].lower, upper = pairs[i].upper;
            double smaller = fmin(fabs(slices->contours[lower].area), fabs(slices->contours[upper].area));
            if (!(pairs[i].overlap >= SIGNIFICANT_OVERLAP * smaller || pairs[i].overlap == best_overlap[lower] ||
                  pairs[i].overlap == best_overlap[upper]))
                continue;
            /* union (smallest id is the root) */
            uint32_t ra = lower, rb = upper;
            while (group[ra] != ra) ra = group[ra];
            while (group[rb] != rb) rb = group[rb];
            if (ra < rb)
                group[rb] = ra;
            else if (rb < ra)
                group[ra] = rb;
        }
        if (pair_count == 0) continue;
        for (size_t c = lower_first; c < upper_end; c++) {
            uint32_t r = (uint32_t)c;
            while (group[r] != r) r = group[r];
            group[c] = r;
        }
        /* A hole with no partner on the other slice either ends between
         * the planes (a pit: capped) or opens there into the outside (a
         * pit that becomes part of a notch, or the reverse). In the second
         * case it joins the group of the contour around it and is bridged
         * into that contour's loop, so the band follows the notch instead of
         * spanning it and a cap does not cover the open pit. */
        for (size_t h = lower_first; h < upper_end; h++) {
            const lk_contour *hole = &slices->contours[h];
            if (!(hole->area < 0)) continue;
            int lower_side = h < slice_first[k + 1];
            size_t own_first = lower_side ? slice_first[k] : slice_first[k + 1];
            size_t own_end = lower_side ? slice_first[k + 1] : upper_end;
            size_t other_first = lower_side ? slice_first[k + 1] : slice_first[k];
            size_t other_end = lower_side ? upper_end : slice_first[k + 1];
            int partnered = 0;
            for (size_t c = other_first; c < other_end; c++) partnered |= group[c] == group[h];
            if (partnered) continue;
            const double *inner = slices->points + 2 * (size_t)hole->first;
            size_t around = SIZE_MAX;
            for (size_t c = own_first; c < own_end; c++) {
                const lk_contour *outer = &slices->contours[c];
                if (!(outer->area > 0) ||
                    !point_in_polygon(slices->points + 2 * (size_t)outer->first, outer->count, inner[0], inner[1]))
                    continue;
                if (around == SIZE_MAX || outer->area < slices->contours[around].area) around = c;
            }
            if (around == SIZE_MAX) continue;
            partnered = 0;
            for (size_t c = other_first; c < other_end; c++) partnered |= group[c] == group[around];
            if (!partnered) continue;
            /* Share of the hole that is material on the other slice. */
            const box2 *box = &boxes[h];
            size_t inside = 0, material = 0;
            for (int i = 0; i < OVERLAP_GRID; i++)
                for (int j = 0; j < OVERLAP_GRID; j++) {
                    double x = box->min[0] + (i + 0.5) * (box->max[0] - box->min[0]) / OVERLAP_GRID;
                    double y = box->min[1] + (j + 0.5) * (box->max[1] - box->min[1]) / OVERLAP_GRID;
                    if (!point_in_polygon(inner, hole->count, x, y)) continue;
                    inside++;
                    int solid = 0;
                    for (size_t c = other_first; c < other_end; c++) {
                        const lk_contour *other = &slices->contours[c];
                        if (point_in_polygon(slices->points + 2 * (size_t)other->first, other->count, x, y))
                            solid = !solid;
                    }
                    material += (size_t)solid;
                }
            if (inside == 0 || 2 * material >= inside) continue;
            group[h] = group[around];
        }
        for (size_t root = slice_first[k]; root < slice_first[k + 1]; root++) {
            if (group[root] != root) continue;
            size_t uppers = 0;
            for (size_t c = slice_first[k + 1]; c < upper_end; c++) uppers += group[c] == root;
            if (uppers == 0) continue;
            lower_loop.count = upper_loop.count = 0;
            bridge_partners above = {group, (uint32_t)root, slice_first[k + 1], upper_end, NULL, 0, 0, 0};
            bridge_partners below = {group, (uint32_t)root, slice_first[k], slice_first[k + 1], NULL, 0, 0, 0};
            for (int side = 0; side < 2; side++) {
                size_t first = side == 0 ? root : slice_first[k + 1], end = side == 0 ? slice_first[k + 1] : upper_end;
                loop *target = side == 0 ? &lower_loop : &upper_loop;
                /* The largest contour starts the loop; branches much smaller
                 * than it are capped instead of bridged (a bridge to a tiny
                 * blob spans the blob's whole neighbourhood on the plane). */
                size_t largest_contour = SIZE_MAX;
                for (size_t c = first; c < end; c++)
                    if (group[c] == root &&
                        (largest_contour == SIZE_MAX ||
                         fabs(slices->contours[c].area) > fabs(slices->contours[largest_contour].area)))
                        largest_contour = c;
                double largest_area = fabs(slices->contours[largest_contour].area);
                for (size_t pass = 0; pass < 2; pass++)
                    for (size_t c = first; c < end; c++) {
                        if (group[c] != root || (pass == 0) != (c == largest_contour)) continue;
                        if (pass == 1 && fabs(slices->contours[c].area) < SMALL_BRANCH * largest_area) continue;
                        /* A hole joined to the contour around it (see
                         * above) is bridged across the wall that is gone
                         * on the other slice: outside its contours. */
                        int prefer_outside = slices->contours[c].area < 0 && slices->contours[largest_contour].area > 0;
                        int appended = loop_append(slices, target, &slices->contours[c], side == 0, bridged,
                                                   side == 0 ? &above : &below, prefer_outside, &tris);
                        if (!appended) goto nomem;
                        if (appended == 2) continue;
                        paired[c] |= side == 0 ? 2 : 1;
                        if (pass == 1) info->bridges++;
                    }
            }
            if (!stitch(slices, &lower_loop, &upper_loop, &stitch_tables, &tris)) goto nomem;
            info->bands++;
        }
    }
    /* Caps for the sides still open. Paired by overlap, a contour paired on
     * neither side (a feature thinner than two spacings) is left out; with
     * pieces known it is a whole component crossing one plane, kept (one
     * side ear-clipped, the other a fan: see close_pending_caps). */
    for (size_t c = 0; c < contour_count; c++) {
        const lk_contour *contour = &slices->contours[c];
        if (paired[c] == 0 && !by_pieces) {
            info->dropped++;
            continue;
        }
        for (int side = 0; side < 2; side++) {
            if (paired[c] & (1 << side)) continue;
            loop single = {links, 0, 2 * largest};
            for (uint32_t i = 0; i < contour->count; i++) single.index[i] = contour->first + i;
            single.count = contour->count;
            if (!pending_cap_add(&caps, &single, contour->slice, side == 1)) goto nomem;
            paired[c] |= (unsigned char)(1 << side);
        }
    }
    if (!close_pending_caps(slices, &caps, &tris, info)) goto nomem;
    /* Vertices: the points of the contours kept, then the caps' apexes. */
    size_t vertex_count = 0;
    for (size_t p = 0; p < slices->point_count; p++) remap[p] = UINT32_MAX;
    for (size_t c = 0; c < contour_count; c++) {
        if (paired[c] == 0) continue;
        const lk_contour *contour = &slices->contours[c];
        for (uint32_t i = 0; i < contour->count; i++) remap[contour->first + i] = (uint32_t)vertex_count++;
    }
    size_t contour_vertex_count = vertex_count;
    vertex_count += caps.apex_count;
    status = lk_mesh_alloc(out, vertex_count, tris.count, 0, error);
    if (status != LK_OK) goto done;
    unsigned axis = (unsigned)slices->axis - 1;
    for (size_t c = 0; c < contour_count; c++) {
        if (paired[c] == 0) continue;
        const lk_contour *contour = &slices->contours[c];
        double plane = lk_slices_plane(slices, contour->slice);
        for (uint32_t i = 0; i < contour->count; i++) {
            const double *p = slices->points + 2 * ((size_t)contour->first + i);
            float *q = out->positions + 3 * (size_t)remap[contour->first + i];
            q[axis] = finite_float(plane);
            q[slices->u_axis] = finite_float(p[0]);
            q[slices->v_axis] = finite_float(p[1]);
        }
    }
    for (size_t i = 0; i < caps.apex_count; i++) {
        const double *apex = caps.apexes + 3 * i;
        float *q = out->positions + 3 * (contour_vertex_count + i);
        q[axis] = finite_float(apex[2]);
        q[slices->u_axis] = finite_float(apex[0]);
        q[slices->v_axis] = finite_float(apex[1]);
    }
    for (size_t i = 0; i < 3 * tris.count; i++) {
        uint32_t id = tris.indices[i];
        out->indices[i] =
            id < slices->point_count ? remap[id] : (uint32_t)(contour_vertex_count + (id - slices->point_count));
    }
    goto done;
nomem:
    status = lk_error_set(error, LK_ERR_NOMEM, "cannot allocate band triangles");
done:
    free(slice_first);
    free(paired);
    free(boxes);
    free(links);
    free(remap);
    free(group);
    free(bridged);
    free(best_overlap);
    free(pairs);
    free(lower_loop.index);
    free(upper_loop.index);

    free(tris.indices);
    cap_work_free(&caps);
    free(stitch_tables.cost);
    free(stitch_tables.came_from_a);
    if (status != LK_OK) lk_mesh_free(out);
    return status;
}
