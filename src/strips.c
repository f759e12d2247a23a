/* SPDX-License-Identifier: MIT */
/* Triangle strips and progressive strips (Kim, Yang, Han: "Progressive
 * Strips: a rendering-effective mesh representation for progressive
 * transmission").
 *
 *   - lk_stripify: lodkit's greedy stripifier and meshoptimizer's, joined
 *     into one sequence with degenerate triangles (no primitive restart in
 *     OpenGL ES 2.0);
 *   - lk_strip_filter: the DTFS filter of section 4, which drops the
 *     degenerate triangles a simplified strip accumulates and rebuilds
 *     strips from the survivors;
 *   - progressive strips (sections 2-3): the strip at a level replaces every
 *     vertex not yet split off by its ancestor, and the cost of each vertex
 *     split is measured for the naive encoding and for the R+2/R+1/R-1/R-2
 *     encoding (E-PS);
 *   - the bandwidth of Fig. 4: indices sent to the GPU per level.
 *
 * Strip winding everywhere: triple j = (s[j], s[j+1], s[j+2]) draws that
 * triangle when j is even and (s[j+1], s[j], s[j+2]) when j is odd. An
 * oriented triangle is compared up to cyclic rotation. */
#include "internal.h"

#include <meshoptimizer.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------------------ */
/* Small helpers                                                            */
/* ------------------------------------------------------------------------ */

static bool triple_is_degenerate(uint32_t a, uint32_t b, uint32_t c) { return a == b || b == c || a == c; }

/* True when (x,y,z) is a cyclic rotation of (a,b,c). */
static bool same_rotation(uint32_t x, uint32_t y, uint32_t z, uint32_t a, uint32_t b, uint32_t c)
{
    return (x == a && y == b && z == c) || (x == b && y == c && z == a) || (x == c && y == a && z == b);
}

/* The oriented triangle drawn by triple (x,y,z) at a position of `parity`. */
static void drawn_triangle(uint32_t x, uint32_t y, uint32_t z, size_t parity, uint32_t out[3])
{
    if (parity & 1)
        out[0] = y, out[1] = x, out[2] = z;
    else
        out[0] = x, out[1] = y, out[2] = z;
}

size_t lk_strip_triangles(const uint32_t *strip, size_t strip_length, uint32_t *destination)
{
    size_t count = 0;
    for (size_t j = 0; j + 2 < strip_length; j++) {
        uint32_t a = strip[j], b = strip[j + 1], c = strip[j + 2];
        if (triple_is_degenerate(a, b, c)) continue;
        drawn_triangle(a, b, c, j, destination + 3 * count);
        count++;
    }
    return count;
}

/* ------------------------------------------------------------------------ */
/* lodkit's greedy stripifier                                               */
/* ------------------------------------------------------------------------ */
/* Two triangles can follow each other in a strip when they share an edge
 * with opposite directions (consistent orientation): then the strip draws
 * both with their own orientation. The strip grows from the triangle with
 * the fewest unvisited neighbours (the ones most likely to be left alone
 * later), first forward, then - after reversing the sequence - backward,
 * always into the neighbour with the fewest unvisited neighbours. From the
 * last triangle (y,z,x) of the sequence the next one normally crosses edge
 * {z,x}; rewriting the tail as (y,z,y,x) - one degenerate triangle - makes
 * it cross {y,x} instead (the swap), which costs one index where ending
 * the strip costs a join of up to three indices plus three for the first
 * triangle of the next one. Cost: O(T) for manifold meshes (neighbours are
 * found among the half-edges leaving one vertex); an edge shared by k
 * triangles adds O(k^2).
 *
 * Reversing a strip reverses every triple and keeps the parity difference
 * between any two of them, so once it is placed at the parity that draws
 * its first triangle right, it draws all of them right: the parity a strip
 * needs is only decided when it is appended to the output. */

#define NO_TRIANGLE UINT32_MAX
/* Buckets of "unvisited neighbours": 0, 1, 2 and 3-or-more. */
#define NEIGHBOUR_BUCKETS 4

typedef struct greedy_state {
    size_t triangle_count;
    const uint32_t *corners;   /* 3 * triangle_count, none degenerate */
    uint32_t *edge_offsets;    /* vertex_count + 1: half-edges grouped by origin vertex */
    uint32_t *edge_target;     /* 3 * triangle_count */
    uint32_t *edge_triangle;   /* 3 * triangle_count */
    uint32_t *live_neighbours; /* per triangle: unvisited neighbours, over its three edges */
    unsigned char *visited;
    /* Lazy stacks by min(live_neighbours, 3): counts only fall, so a
     * triangle enters each stack at most once; stale entries (visited, or
     * moved to a lower stack) are skipped when popped. */
    uint32_t *bucket[NEIGHBOUR_BUCKETS];
    size_t bucket_size[NEIGHBOUR_BUCKETS];
} greedy_state;

static unsigned bucket_of(uint32_t live) { return live < NEIGHBOUR_BUCKETS - 1 ? live : NEIGHBOUR_BUCKETS - 1; }

/* Origin and target of the half-edges that can follow triangle t across its
 * edge {a,b}: the reverse of t's own direction along that edge. */
static void neighbour_direction(const uint32_t *c, uint32_t a, uint32_t b, uint32_t *from, uint32_t *to)
{
    bool t_goes_a_to_b = (c[0] == a && c[1] == b) || (c[1] == a && c[2] == b) || (c[2] == a && c[0] == b);
    *from = t_goes_a_to_b ? b : a;
    *to = t_goes_a_to_b ? a : b;
}

static void greedy_visit(greedy_state *s, uint32_t t)
{
    s->visited[t] = 1;
    const uint32_t *c = s->corners + 3 * (size_t)t;
    for (int k = 0; k < 3; k++) {
        uint32_t a = c[k], b = c[(k + 1) % 3];
        for (uint32_t e = s->edge_offsets[b]; e < s->edge_offsets[b + 1]; e++) {
            if (s->edge_target[e] != a) continue;
            uint32_t n = s->edge_triangle[e];
            if (s->visited[n]) continue;
            unsigned before = bucket_of(s->live_neighbours[n]);
            s->live_neighbours[n]--;
            unsigned after = bucket_of(s->live_neighbours[n]);
            if (after != before) s->bucket[after][s->bucket_size[after]++] = n;
        }
    }
}

/* The unvisited triangle that can follow t across edge {a,b} with the
 * fewest unvisited neighbours (the first such on ties), or NO_TRIANGLE. */
static uint32_t greedy_best_neighbour(const greedy_state *s, uint32_t t, uint32_t a, uint32_t b)
{
    uint32_t from, to;
    neighbour_direction(s->corners + 3 * (size_t)t, a, b, &from, &to);
    uint32_t best = NO_TRIANGLE, best_live = UINT32_MAX;
    for (uint32_t e = s->edge_offsets[from]; e < s->edge_offsets[from + 1]; e++) {
        if (s->edge_target[e] != to) continue;
        uint32_t n = s->edge_triangle[e];
        if (s->visited[n] || s->live_neighbours[n] >= best_live) continue;
        best = n;
        best_live = s->live_neighbours[n];
    }
    return best;
}

static uint32_t third_corner(const uint32_t *c, uint32_t a, uint32_t b)
{
    for (int k = 0; k < 3; k++)
        if (c[k] != a && c[k] != b) return c[k];
    return c[0]; /* not reached: triangles are not degenerate */
}

/* Grows work[0..length) forward from its last triangle *last (drawn by the
 * last three entries); returns the new length. */
static size_t greedy_extend(greedy_state *s, uint32_t *work, size_t length, uint32_t *last)
{
    for (;;) {
        uint32_t y = work[length - 3], z = work[length - 2], x = work[length - 1];
        uint32_t normal = greedy_best_neighbour(s, *last, z, x);
        uint32_t swapped = greedy_best_neighbour(s, *last, y, x);
        /* A swap costs one index more than going straight on, a new strip
         * two to six more: turn only when the straight way is closed or the
         * turn's triangle has fewer ways out (it is the one more likely to
         * be stranded later). Turning on ties, or never turning while the
         * straight way is open, both measured worse (bunny 1.70 and 1.28
         * indices per triangle against 1.23). */
        uint32_t next = normal;
        bool swap = false;
        if (swapped != NO_TRIANGLE &&
            (normal == NO_TRIANGLE || s->live_neighbours[swapped] < s->live_neighbours[normal])) {
            next = swapped;
            swap = true;
        }
        if (next == NO_TRIANGLE) return length;
        if (swap && length == 3) {
            /* a lone triangle turns for free: (z,x,y) draws it as (y,z,x) does */
            work[0] = z, work[1] = x, work[2] = y;
        } else if (swap) {
            work[length - 1] = y;
            work[length++] = x;
        }
        work[length++] = third_corner(s->corners + 3 * (size_t)next, swap ? y : z, x);
        greedy_visit(s, next);
        *last = next;
    }
}

static void reverse_indices(uint32_t *values, size_t count)
{
    for (size_t i = 0, j = count; i + 1 < j; i++, j--) {
        uint32_t v = values[i];
        values[i] = values[j - 1];
        values[j - 1] = v;
    }
}

/* Indices needed before a strip whose first triple must sit at a position
 * of parity `need`, when `length` indices (the last one `tail`) are already
 * out: nothing or one repeat when the strip starts with `tail`, else the
 * degenerate bridge (tail, first) plus one repeat of first when the parity
 * is wrong. */
static size_t join_cost(size_t length, uint32_t tail, uint32_t first, size_t need)
{
    if (length == 0) return need & 1;
    if (tail == first) return (length & 1) == need ? 0 : 1;
    return ((length + 2) & 1) == need ? 2 : 3;
}

/* Writes the join of join_cost() at out[length]; returns the new length. */
static size_t append_join(uint32_t *out, size_t length, uint32_t first, size_t need)
{
    uint32_t tail = length ? out[length - 1] : first;
    size_t cost = join_cost(length, tail, first, need);
    size_t k = 0;
    if (cost >= 2) {
        out[length++] = tail;
        k = 1;
    }
    for (; k < cost; k++) out[length++] = first;
    return length;
}

/* Appends the strip work[0..length) (first triple drawing triangle `first`,
 * last triple drawing `last`) to out, forward or reversed, whichever joins
 * for less. A lone triangle may start at any corner in either parity. */
static size_t greedy_emit(const greedy_state *s, uint32_t *out, size_t out_length, uint32_t *work, size_t length,
                          uint32_t first, uint32_t last)
{
    uint32_t tail = out_length ? out[out_length - 1] : 0;
    if (length == 3) {
        const uint32_t *c = s->corners + 3 * (size_t)first;
        size_t best_cost = SIZE_MAX;
        uint32_t form[3] = {c[0], c[1], c[2]};
        size_t form_need = 0;
        for (int k = 0; k < 3; k++) {
            uint32_t x = c[k], y = c[(k + 1) % 3], z = c[(k + 2) % 3];
            /* (x,y,z) draws the triangle at an even position, (x,z,y) at an odd one */
            for (size_t need = 0; need < 2; need++) {
                size_t cost = join_cost(out_length, tail, x, need);
                if (cost < best_cost) {
                    best_cost = cost;
                    form[0] = x, form[1] = need ? z : y, form[2] = need ? y : z;
                    form_need = need;
                }
            }
        }
        out_length = append_join(out, out_length, form[0], form_need);
        memcpy(out + out_length, form, sizeof form);
        return out_length + 3;
    }
    const uint32_t *cf = s->corners + 3 * (size_t)first, *cl = s->corners + 3 * (size_t)last;
    size_t need_forward = same_rotation(work[0], work[1], work[2], cf[0], cf[1], cf[2]) ? 0 : 1;
    size_t need_reversed =
        same_rotation(work[length - 1], work[length - 2], work[length - 3], cl[0], cl[1], cl[2]) ? 0 : 1;
    size_t cost_forward = join_cost(out_length, tail, work[0], need_forward);
    size_t cost_reversed = join_cost(out_length, tail, work[length - 1], need_reversed);
    size_t need = need_forward;
    if (cost_reversed < cost_forward) {
        reverse_indices(work, length);
        need = need_reversed;
    }
    out_length = append_join(out, out_length, work[0], need);
    memcpy(out + out_length, work, length * sizeof *work);
    return out_length + length;
}

static void greedy_free(greedy_state *s)
{
    free(s->edge_offsets);
    free(s->edge_target);
    free(s->edge_triangle);
    free(s->live_neighbours);
    free(s->visited);
    for (int b = 0; b < NEIGHBOUR_BUCKETS; b++) free(s->bucket[b]);
}

/* corners: triangle_count non-degenerate triangles with indices < vertex_count. */
static lk_status stripify_lodkit(const uint32_t *corners, size_t triangle_count, size_t vertex_count, uint32_t **strip,
                                 size_t *strip_length, lk_error *error)
{
    greedy_state s;
    memset(&s, 0, sizeof s);
    s.triangle_count = triangle_count;
    s.corners = corners;
    s.edge_offsets = lk__calloc_array(vertex_count + 1, sizeof(uint32_t));
    s.edge_target = lk__malloc_array(triangle_count, 3 * sizeof(uint32_t));
    s.edge_triangle = lk__malloc_array(triangle_count, 3 * sizeof(uint32_t));
    s.live_neighbours = lk__calloc_array(triangle_count, sizeof(uint32_t));
    s.visited = lk__calloc_array(triangle_count, 1);
    bool ok = s.edge_offsets && s.edge_target && s.edge_triangle && s.live_neighbours && s.visited;
    for (int b = 0; b < NEIGHBOUR_BUCKETS; b++)
        ok = ok && (s.bucket[b] = lk__malloc_array(triangle_count, sizeof(uint32_t)));
    /* one strip: 3 + 2 per further triangle (swaps); output: at most 3 join
     * indices per strip on top */
    uint32_t *work = lk__malloc_array(2 * triangle_count + 4, sizeof(uint32_t));
    uint32_t *out = lk__malloc_array(6 * triangle_count + 4, sizeof(uint32_t));
    if (!ok || !work || !out) {
        greedy_free(&s);
        free(work);
        free(out);
        return lk_error_set(error, LK_ERR_NOMEM, "stripify: cannot allocate working arrays for %zu triangles",
                            triangle_count);
    }

    /* half-edges by origin (counting sort) */
    for (size_t i = 0; i < 3 * triangle_count; i++) s.edge_offsets[corners[i] + 1]++;
    for (size_t v = 0; v < vertex_count; v++) s.edge_offsets[v + 1] += s.edge_offsets[v];
    for (size_t t = 0; t < triangle_count; t++)
        for (int k = 0; k < 3; k++) {
            uint32_t e = s.edge_offsets[corners[3 * t + k]]++;
            s.edge_target[e] = corners[3 * t + (k + 1) % 3];
            s.edge_triangle[e] = (uint32_t)t;
        }
    for (size_t v = vertex_count; v > 0; v--) s.edge_offsets[v] = s.edge_offsets[v - 1];
    s.edge_offsets[0] = 0;

    for (size_t t = 0; t < triangle_count; t++) {
        const uint32_t *c = corners + 3 * t;
        for (int k = 0; k < 3; k++) {
            uint32_t a = c[k], b = c[(k + 1) % 3];
            for (uint32_t e = s.edge_offsets[b]; e < s.edge_offsets[b + 1]; e++)
                s.live_neighbours[t] += s.edge_target[e] == a;
        }
    }
    /* pushed last to first so that equal candidates pop in input order */
    for (size_t t = triangle_count; t > 0; t--) {
        unsigned b = bucket_of(s.live_neighbours[t - 1]);
        s.bucket[b][s.bucket_size[b]++] = (uint32_t)(t - 1);
    }

    size_t out_length = 0;
    for (;;) {
        uint32_t start = NO_TRIANGLE;
        for (unsigned b = 0; b < NEIGHBOUR_BUCKETS && start == NO_TRIANGLE; b++) {
            while (s.bucket_size[b]) {
                uint32_t t = s.bucket[b][--s.bucket_size[b]];
                if (!s.visited[t] && bucket_of(s.live_neighbours[t]) == b) {
                    start = t;
                    break;
                }
            }
        }
        if (start == NO_TRIANGLE) break;
        greedy_visit(&s, start);

        /* leave the start triangle towards its neighbour with the fewest ways out */
        const uint32_t *c = corners + 3 * (size_t)start;
        int exit_edge = 0;
        uint32_t exit_live = UINT32_MAX;
        for (int k = 0; k < 3; k++) {
            uint32_t n = greedy_best_neighbour(&s, start, c[k], c[(k + 1) % 3]);
            if (n != NO_TRIANGLE && s.live_neighbours[n] < exit_live) {
                exit_live = s.live_neighbours[n];
                exit_edge = k;
            }
        }
        work[0] = c[(exit_edge + 2) % 3];
        work[1] = c[exit_edge];
        work[2] = c[(exit_edge + 1) % 3];
        uint32_t last = start;
        size_t length = greedy_extend(&s, work, 3, &last);
        uint32_t first = last;
        reverse_indices(work, length);
        last = start;
        length = greedy_extend(&s, work, length, &last);
        out_length = greedy_emit(&s, out, out_length, work, length, first, last);
    }
    greedy_free(&s);
    free(work);
    uint32_t *shrunk = lk__realloc_array(out, out_length, sizeof(uint32_t));
    *strip = shrunk ? shrunk : out;
    *strip_length = out_length;
    return LK_OK;
}

/* ------------------------------------------------------------------------ */
/* meshoptimizer's stripifier and lk_stripify                               */
/* ------------------------------------------------------------------------ */

_Static_assert(sizeof(unsigned int) == sizeof(uint32_t), "meshoptimizer indices are 32-bit here");

/* meshopt_stripify with restart_index 0 joins its strips with degenerate
 * triangles instead of a restart index; its input goes through the
 * strip-friendly vertex cache order first, which makes the strips longer. */
static lk_status stripify_meshopt(const uint32_t *corners, size_t triangle_count, size_t vertex_count, uint32_t **strip,
                                  size_t *strip_length, lk_error *error)
{
    size_t index_count = 3 * triangle_count;
    unsigned int *ordered = lk__malloc_array(index_count, sizeof(unsigned int));
    unsigned int *out = lk__malloc_array(meshopt_stripifyBound(index_count), sizeof(unsigned int));
    if (!ordered || !out) {
        free(ordered);
        free(out);
        return lk_error_set(error, LK_ERR_NOMEM, "stripify: cannot allocate %zu indices", index_count);
    }
    meshopt_optimizeVertexCacheStrip(ordered, corners, index_count, vertex_count);
    size_t length = meshopt_stripify(out, ordered, index_count, vertex_count, 0);
    free(ordered);
    unsigned int *shrunk = lk__realloc_array(out, length, sizeof(unsigned int));
    *strip = shrunk ? shrunk : out;
    *strip_length = length;
    return LK_OK;
}

lk_status lk_stripify(const uint32_t *indices, size_t triangle_count, size_t vertex_count, lk_stripifier method,
                      uint32_t **strip, size_t *strip_length, lk_stripifier *used, lk_error *error)
{
    if (!strip || !strip_length || (triangle_count && !indices))
        return lk_error_set(error, LK_ERR_INVALID, "stripify: NULL argument");
    *strip = NULL;
    *strip_length = 0;
    if (method != LK_STRIPIFY_BEST && method != LK_STRIPIFY_LODKIT && method != LK_STRIPIFY_MESHOPT)
        return lk_error_set(error, LK_ERR_INVALID, "stripify: unknown method %d", (int)method);
    /* the half-edge arrays index 3 * triangle_count entries with uint32_t */
    if (vertex_count > LK_MAX_ELEMENTS || triangle_count > LK_MAX_ELEMENTS / 3)
        return lk_error_set(error, LK_ERR_LIMIT, "stripify: %zu triangles over %zu vertices is too large",
                            triangle_count, vertex_count);

    uint32_t *corners = lk__malloc_array(triangle_count, 3 * sizeof(uint32_t));
    if (!corners) return lk_error_set(error, LK_ERR_NOMEM, "stripify: cannot copy %zu triangles", triangle_count);
    size_t kept = 0;
    for (size_t t = 0; t < triangle_count; t++) {
        const uint32_t *c = indices + 3 * t;
        for (int k = 0; k < 3; k++)
            if (c[k] >= vertex_count) {
                free(corners);
                return lk_error_set(error, LK_ERR_RANGE, "stripify: triangle %zu uses vertex %u of %zu", t,
                                    (unsigned)c[k], vertex_count);
            }
        if (triple_is_degenerate(c[0], c[1], c[2])) continue;
        memcpy(corners + 3 * kept, c, 3 * sizeof *c);
        kept++;
    }

    lk_stripifier chosen = method == LK_STRIPIFY_MESHOPT ? LK_STRIPIFY_MESHOPT : LK_STRIPIFY_LODKIT;
    lk_status status = LK_OK;
    if (kept == 0) {
        *strip = lk__malloc_array(0, sizeof(uint32_t));
        if (!*strip) status = lk_error_set(error, LK_ERR_NOMEM, "stripify: out of memory");
    } else if (method == LK_STRIPIFY_LODKIT) {
        status = stripify_lodkit(corners, kept, vertex_count, strip, strip_length, error);
    } else if (method == LK_STRIPIFY_MESHOPT) {
        status = stripify_meshopt(corners, kept, vertex_count, strip, strip_length, error);
    } else {
        uint32_t *other = NULL;
        size_t other_length = 0;
        status = stripify_lodkit(corners, kept, vertex_count, strip, strip_length, error);
        if (status == LK_OK) status = stripify_meshopt(corners, kept, vertex_count, &other, &other_length, error);
        if (status == LK_OK && other_length < *strip_length) {
            free(*strip);
            *strip = other;
            *strip_length = other_length;
            chosen = LK_STRIPIFY_MESHOPT;
        } else {
            free(other);
        }
        if (status != LK_OK) {
            free(*strip);
            *strip = NULL;
            *strip_length = 0;
        }
    }
    free(corners);
    if (status == LK_OK && used) *used = chosen;
    return status;
}

/* ------------------------------------------------------------------------ */
/* DTFS: degenerate-triangle-free scanning                                  */
/* ------------------------------------------------------------------------ */
/* The paper scans the triples of a simplified strip, keeps those with three
 * distinct vertices and rebuilds strips from consecutive survivors (a b c),
 * (d e f): the normal case {a,b,c,f}, the swap case {a,b,c,b,f}, otherwise
 * a new strip. Both cases draw the same second triangle - they only differ
 * in the edge left open for the third - so here the decision is taken on
 * the output side: a triangle sharing the open edge {u,v} of the output
 * with the right orientation costs one index, and it leaves (v,f) open, or
 * (u,f) for one index more when only that edge leads on to the next
 * survivor (one triangle of look-ahead).
 *
 * A triangle that does not continue the output starts a new strip. Since a
 * triangle can be written starting at any of its corners at either parity
 * ((r,a,b) at an even position and (r,b,a) at an odd one draw the same
 * triangle), no parity fix is ever needed, and the start corner can be one
 * the output just ended with:
 *   starts with v (the last index): write r a b                 3 indices
 *   starts with u (the one before): write u u a b, (u,v,u) and
 *     (v,u,u) and (u,u,a) being degenerate                      4 indices
 *   else the bridge v r: (u,v,v) (v,v,r) (v,r,r) (r,r,a) are
 *     degenerate                                                5 indices
 * while the paper's form-keeping split needs 5 or 6. Among equal costs the
 * corner that leaves an edge leading on to the next survivor wins, and a
 * start that costs more but leads on is preferred when the estimate
 * (cost + 1 when it leads on, + 4 when it does not) says so. */

/* Output state: only the last three indices matter to the decisions. */
typedef struct filter_output {
    uint32_t *destination; /* NULL: only count */
    size_t length;
    uint32_t w, u, v; /* destination[length-3 .. length-1] */
} filter_output;

static void filter_put(filter_output *o, uint32_t value)
{
    if (o->destination) o->destination[o->length] = value;
    o->length++;
    o->w = o->u, o->u = o->v, o->v = value;
}

/* Does triple (x, y, f) at a position of `parity` draw triangle t (f being
 * t's third corner)? That is: does t run x -> y (even) or y -> x (odd)? */
static bool filter_attaches(uint32_t x, uint32_t y, size_t parity, const uint32_t *t)
{
    if (!t) return false;
    uint32_t from = parity & 1 ? y : x, to = parity & 1 ? x : y;
    return (t[0] == from && t[1] == to) || (t[1] == from && t[2] == to) || (t[2] == from && t[0] == to);
}

/* Finds the next triple at or after j with distinct vertices and writes the
 * triangle it draws; returns its position or SIZE_MAX. `kept`, when given,
 * has bit j set for exactly those triples (see the bandwidth sweep). */
static size_t filter_next(const uint32_t *strip, size_t strip_length, const uint64_t *kept, size_t j, uint32_t t[3])
{
    if (strip_length < 3 || j >= strip_length - 2) return SIZE_MAX;
    size_t triples = strip_length - 2;
    if (kept) {
        size_t word = j >> 6;
        uint64_t bits = kept[word] & (~(uint64_t)0 << (j & 63));
        while (!bits) {
            if (++word >= (triples + 63) >> 6) return SIZE_MAX;
            bits = kept[word];
        }
        j = (word << 6) + (size_t)__builtin_ctzll(bits);
        if (j >= triples) return SIZE_MAX;
        drawn_triangle(strip[j], strip[j + 1], strip[j + 2], j, t);
        return j;
    }
    for (; j < triples; j++) {
        uint32_t a = strip[j], b = strip[j + 1], c = strip[j + 2];
        if (triple_is_degenerate(a, b, c)) continue;
        drawn_triangle(a, b, c, j, t);
        return j;
    }
    return SIZE_MAX;
}

/* The last position of the run of surviving triples that starts at j
 * (itself a survivor). */
static size_t filter_run_end(const uint32_t *strip, size_t strip_length, const uint64_t *kept, size_t j)
{
    size_t triples = strip_length - 2;
    if (kept) {
        for (;;) {
            size_t word = j >> 6;
            uint64_t holes = ~kept[word] & (~(uint64_t)0 << (j & 63));
            if (holes) {
                size_t end = (word << 6) + (size_t)__builtin_ctzll(holes) - 1;
                return end < triples ? end : triples - 1;
            }
            j = (word + 1) << 6;
            if (j >= triples) return triples - 1;
        }
    }
    while (j + 1 < triples && !triple_is_degenerate(strip[j + 1], strip[j + 2], strip[j + 3])) j++;
    return j;
}

/* Appends triangle t (which does not hold the open edge) as a new strip. */
static void filter_start(filter_output *o, const uint32_t *t, const uint32_t *next)
{
    int best_score = 1 << 30, best_cost = 0;
    uint32_t best_form[3] = {t[0], t[1], t[2]};
    for (int k = 0; k < 3; k++) {
        uint32_t r = t[k], a = t[(k + 1) % 3], b = t[(k + 2) % 3];
        int cost;
        size_t position; /* of the new triple */
        if (o->length == 0)
            cost = 3, position = 0;
        else if (r == o->v)
            cost = 3, position = o->length;
        else if (r == o->u)
            cost = 4, position = o->length + 1;
        else
            cost = 5, position = o->length + 2;
        uint32_t form[3] = {r, position & 1 ? b : a, position & 1 ? a : b};
        bool leads_on = filter_attaches(form[1], form[2], position + 1, next);
        int score = cost + (leads_on ? 1 : 4);
        if (score < best_score || (score == best_score && cost < best_cost)) {
            best_score = score;
            best_cost = cost;
            memcpy(best_form, form, sizeof form);
        }
    }
    if (o->length > 0) {
        if (best_form[0] == o->u)
            filter_put(o, o->u);
        else if (best_form[0] != o->v)
            filter_put(o, o->v), filter_put(o, best_form[0]);
    }
    for (int k = 0; k < 3; k++) filter_put(o, best_form[k]);
}

static size_t filter_strip(const uint32_t *strip, size_t strip_length, const uint64_t *kept, uint32_t *destination,
                           size_t *triangle_count)
{
    filter_output o = {destination, 0, 0, 0, 0};
    uint32_t current[3], next[3];
    size_t triangles = 0;
    /* `in_step`: the output ends with the input triple at this position,
     * same form and parity. Then survivors right after it that are followed
     * right after by another survivor go straight on (the decisions below
     * would say the same), which is most of a fine level: such runs are
     * copied without looking at each triangle. */
    size_t in_step = SIZE_MAX;
    size_t j = filter_next(strip, strip_length, kept, 0, current);
    while (j != SIZE_MAX) {
        size_t k = filter_next(strip, strip_length, kept, j + 1, next);
        const uint32_t *ahead = k != SIZE_MAX ? next : NULL;
        triangles++;
        if (in_step != SIZE_MAX && j == in_step + 1 && k == j + 1) {
            /* the whole run of consecutive survivors j, j+1, ..., end goes
             * straight on up to its last one, which is decided below */
            size_t end = filter_run_end(strip, strip_length, kept, k);
            for (size_t i = j + 2; i < end + 2; i++) filter_put(&o, strip[i]);
            triangles += end - j;
            j = end;
            k = filter_next(strip, strip_length, kept, j + 1, next);
            ahead = k != SIZE_MAX ? next : NULL;
            drawn_triangle(strip[j], strip[j + 1], strip[j + 2], j, current);
        }
        if (o.length >= 3 && filter_attaches(o.u, o.v, o.length - 2, current)) {
            uint32_t f = third_corner(current, o.u, o.v);
            /* straight on leaves (v,f) open at the next position; the swap
             * (u,v,u,f) leaves (u,f) one position later */
            bool straight_leads_on = filter_attaches(o.v, f, o.length - 1, ahead);
            bool swap_leads_on = filter_attaches(o.u, f, o.length, ahead);
            if (swap_leads_on && !straight_leads_on) filter_put(&o, o.u);
            filter_put(&o, f);
        } else {
            filter_start(&o, current, ahead);
        }
        in_step = o.w == strip[j] && o.u == strip[j + 1] && o.v == strip[j + 2] && ((o.length - 3) & 1) == (j & 1)
                      ? j
                      : SIZE_MAX;
        memcpy(current, next, sizeof current);
        j = k;
    }
    if (triangle_count) *triangle_count = triangles;
    return o.length;
}

size_t lk_strip_filter_bound(size_t strip_length)
{
    /* every surviving triangle costs at most 5 indices (the first 3), and
     * there are at most strip_length - 2 of them */
    if (strip_length < 3) return 0;
    if (strip_length - 2 > SIZE_MAX / 5) return SIZE_MAX;
    return 5 * (strip_length - 2);
}

size_t lk_strip_filter(const uint32_t *strip, size_t strip_length, uint32_t *destination)
{
    return filter_strip(strip, strip_length, NULL, destination, NULL);
}

/* ------------------------------------------------------------------------ */
/* Progressive strips                                                       */
/* ------------------------------------------------------------------------ */

#define NO_ENTRY UINT32_MAX

/* Checks what the strip functions rely on: counts that add up, strip
 * entries that name vertices, and kept vertices older than the split. */
static lk_status check_progressive(const lk_progressive_strips *ps, const lk_progressive_mesh *pm, lk_error *error)
{
    if (!pm) return lk_error_set(error, LK_ERR_INVALID, "progressive strips: NULL progressive mesh");
    if (pm->vertex_count > LK_MAX_ELEMENTS || pm->triangle_count > LK_MAX_ELEMENTS / 3 ||
        pm->base_vertex_count > pm->vertex_count || pm->split_count != pm->vertex_count - pm->base_vertex_count)
        return lk_error_set(error, LK_ERR_RANGE,
                            "progressive strips: %zu vertices = %zu base + %zu splits does not add up",
                            pm->vertex_count, pm->base_vertex_count, pm->split_count);
    if (pm->split_count && !pm->splits)
        return lk_error_set(error, LK_ERR_INVALID, "progressive strips: progressive mesh without splits");
    for (size_t k = 0; k < pm->split_count; k++)
        if (pm->splits[k].kept >= pm->base_vertex_count + k)
            return lk_error_set(error, LK_ERR_RANGE,
                                "progressive strips: split %zu keeps vertex %u, not older than %zu", k,
                                (unsigned)pm->splits[k].kept, pm->base_vertex_count + k);
    if (ps) {
        if (ps->strip_length && !ps->strip)
            return lk_error_set(error, LK_ERR_INVALID, "progressive strips: NULL strip");
        if (ps->strip_length > LK_MAX_ELEMENTS)
            return lk_error_set(error, LK_ERR_LIMIT, "progressive strips: strip of %zu entries is too long",
                                ps->strip_length);
        for (size_t j = 0; j < ps->strip_length; j++)
            if (ps->strip[j] >= pm->vertex_count)
                return lk_error_set(error, LK_ERR_RANGE, "progressive strips: strip entry %zu names vertex %u of %zu",
                                    j, (unsigned)ps->strip[j], pm->vertex_count);
    }
    return LK_OK;
}

/* ancestor[v] = the vertex that stands for v at `level`. */
static void level_ancestors(const lk_progressive_mesh *pm, size_t level, uint32_t *ancestor)
{
    size_t present = pm->base_vertex_count + level;
    for (size_t v = 0; v < pm->vertex_count; v++)
        ancestor[v] = v < present ? (uint32_t)v : ancestor[pm->splits[v - pm->base_vertex_count].kept];
}

lk_status lk_progressive_strips_level(const lk_progressive_strips *ps, const lk_progressive_mesh *pm, size_t level,
                                      uint32_t *destination, lk_error *error)
{
    if (!ps) return lk_error_set(error, LK_ERR_INVALID, "progressive strips: NULL argument");
    lk_status status = check_progressive(ps, pm, error);
    if (status != LK_OK) return status;
    if (ps->strip_length && !destination)
        return lk_error_set(error, LK_ERR_INVALID, "progressive strips: NULL destination");
    if (level > pm->split_count) level = pm->split_count;
    uint32_t *ancestor = lk__malloc_array(pm->vertex_count, sizeof(uint32_t));
    if (!ancestor)
        return lk_error_set(error, LK_ERR_NOMEM, "progressive strips: cannot allocate %zu vertices", pm->vertex_count);
    level_ancestors(pm, level, ancestor);
    for (size_t j = 0; j < ps->strip_length; j++) destination[j] = ancestor[ps->strip[j]];
    free(ancestor);
    return LK_OK;
}

/* ---- strip edge collapses: naive and encoded (E-PS) ---------------------
 *
 * Collapsing q into p (in the order the simplification did it: split
 * split_count-1 first) rewrites the strip entries that stand for q.
 *
 * Naive PS: every entry whose current value is q becomes p, including the
 * copies earlier collapses made of q, so copies pile up and the inverse
 * split must list them all.
 *
 * E-PS: an entry is either direct (a vertex id) or a reference,
 * R+1, R+2 to the entry at that offset, whose value it takes. A collapse
 * rewrites only the direct entries holding q (entries referring to them
 * follow by themselves): each becomes a reference to a neighbour at offset
 * -1, +1, -2 or +2 that already stands for p (a collapsed edge is a strip
 * edge, so one is usually there), or else direct p. The inverse split sets
 * exactly those entries back to direct q, so its offsets are the direct q
 * entries at collapse time.
 *
 * The full-level strip is encoded the same way from the start: an entry
 * repeating the vertex one or two places before it (the swap's and the
 * joins' repeats) is. So no two direct entries within two
 * places of each other ever hold the same vertex (a collapse checks the
 * neighbours before making an entry direct p), and a split lists one
 * offset per cluster of copies instead of one per copy. Starting with
 * every entry direct instead gives 3.715 (cow) and 3.327 (bunny) updates
 * per split instead of 3.118 and 2.947.
 *
 * References never form a cycle: the initial ones point backwards; later
 * an entry e becomes a reference only while it is direct (the end of every
 * chain through it) and holds q, and the entry it points to stands for
 * p != q, so that entry's chain does not reach e; afterwards e never
 * changes again. Each reference links two different chains into one, as
 * in a forest. Resolution during the
 * simulation uses a union-find copy of the links (path halving), so the
 * whole simulation costs O(L + V + total updates) up to the near-constant
 * find. */

/* Base-level encoding of a reference entry: codes at the top of uint32_t,
 * above every vertex id (LK_MAX_ELEMENTS). */
#define EPS_REFERENCE_BASE 0xFFFFFFFCu
static const int eps_offsets[4] = {-2, -1, +1, +2};
/* search order: nearest first, backward first */
static const int eps_search[4] = {1, 2, 0, 3};

typedef struct eps_state {
    size_t length;
    uint32_t *value;  /* direct entries: current vertex; references: EPS_REFERENCE_BASE + code */
    uint32_t *parent; /* union-find over references; direct entries are roots */
    uint32_t *next;   /* next direct entry holding the same vertex */
    uint32_t *head;   /* per vertex: first direct entry holding it */
} eps_state;

static uint32_t eps_find(uint32_t *parent, uint32_t entry)
{
    while (parent[entry] != entry) {
        parent[entry] = parent[parent[entry]];
        entry = parent[entry];
    }
    return entry;
}

static void eps_free(eps_state *s)
{
    free(s->value);
    free(s->parent);
    free(s->next);
    free(s->head);
}

/* Runs every collapse on `strip` (full level). Fills naive_updates and
 * encoded_updates (split_count each). When `rewritten` is given, appends
 * for each collapse (in collapse order, split_count-1 first) the positions
 * of the entries it rewrote; when `base` is given, writes the base-level
 * encoding there (length entries). */
static lk_status eps_collapse_all(const uint32_t *strip, size_t length, const lk_progressive_mesh *pm,
                                  uint32_t *naive_updates, uint32_t *encoded_updates, lk__buffer *rewritten,
                                  uint32_t *base, lk_error *error)
{
    eps_state s;
    s.length = length;
    s.value = lk__malloc_array(length, sizeof(uint32_t));
    s.parent = lk__malloc_array(length, sizeof(uint32_t));
    s.next = lk__malloc_array(length, sizeof(uint32_t));
    s.head = lk__malloc_array(pm->vertex_count, sizeof(uint32_t));
    uint32_t *naive_count = lk__calloc_array(pm->vertex_count, sizeof(uint32_t));
    if (!s.value || !s.parent || !s.next || !s.head || !naive_count) {
        eps_free(&s);
        free(naive_count);
        return lk_error_set(error, LK_ERR_NOMEM, "progressive strips: cannot allocate a strip of %zu entries", length);
    }
    for (size_t v = 0; v < pm->vertex_count; v++) s.head[v] = NO_ENTRY;
    for (size_t j = 0; j < length; j++) {
        uint32_t v = strip[j];
        naive_count[v]++;
        s.parent[j] = (uint32_t)j;
        s.value[j] = v;
        if (j >= 1 && strip[j - 1] == v) {
            s.value[j] = EPS_REFERENCE_BASE + 1;
            s.parent[j] = (uint32_t)(j - 1);
        } else if (j >= 2 && strip[j - 2] == v) {
            s.value[j] = EPS_REFERENCE_BASE + 0;
            s.parent[j] = (uint32_t)(j - 2);
        }
    }
    for (size_t j = length; j > 0; j--) {
        uint32_t v = s.value[j - 1];
        if (v >= EPS_REFERENCE_BASE) continue;
        s.next[j - 1] = s.head[v];
        s.head[v] = (uint32_t)(j - 1);
    }

    lk_status status = LK_OK;
    for (size_t k = pm->split_count; k-- > 0;) {
        uint32_t q = (uint32_t)(pm->base_vertex_count + k), p = pm->splits[k].kept;
        naive_updates[k] = naive_count[q];
        naive_count[p] += naive_count[q];
        naive_count[q] = 0;

        uint32_t updates = 0;
        uint32_t entry = s.head[q];
        s.head[q] = NO_ENTRY;
        while (entry != NO_ENTRY) {
            uint32_t following = s.next[entry];
            updates++;
            if (rewritten && !lk__buffer_append(rewritten, &entry, sizeof entry)) {
                status = lk_error_set(error, LK_ERR_NOMEM, "progressive strips: out of memory recording splits");
                break;
            }
            int code = -1;
            for (int i = 0; i < 4 && code < 0; i++) {
                long long neighbour = (long long)entry + eps_offsets[eps_search[i]];
                if (neighbour < 0 || neighbour >= (long long)length) continue;
                uint32_t root = eps_find(s.parent, (uint32_t)neighbour);
                if (s.value[root] == p) code = eps_search[i];
            }
            if (code >= 0) {
                s.value[entry] = EPS_REFERENCE_BASE + (uint32_t)code;
                s.parent[entry] = (uint32_t)((long long)entry + eps_offsets[code]);
            } else {
                s.value[entry] = p;
                s.next[entry] = s.head[p];
                s.head[p] = entry;
            }
            entry = following;
        }
        if (status != LK_OK) break;
        encoded_updates[k] = updates;
    }
    if (status == LK_OK && base) memcpy(base, s.value, length * sizeof(uint32_t));
    eps_free(&s);
    free(naive_count);
    return status;
}

void lk_progressive_strips_free(lk_progressive_strips *ps)
{
    if (!ps) return;
    free(ps->strip);
    free(ps->naive_updates);
    free(ps->encoded_updates);
    memset(ps, 0, sizeof *ps);
}

lk_status lk_progressive_strips_build(const lk_progressive_mesh *pm, lk_stripifier method, lk_progressive_strips *out,
                                      lk_error *error)
{
    return lk_progressive_strips_build_ex(pm, method, out, NULL, NULL, error);
}

lk_status lk_progressive_strips_build_ex(const lk_progressive_mesh *pm, lk_stripifier method,
                                         lk_progressive_strips *out, lk_progress_fn progress, void *progress_user,
                                         lk_error *error)
{
    if (!out) return lk_error_set(error, LK_ERR_INVALID, "progressive strips: NULL output");
    memset(out, 0, sizeof *out);
    lk_status status = check_progressive(NULL, pm, error);
    if (status != LK_OK) return status;
    if (method != LK_STRIPIFY_BEST && method != LK_STRIPIFY_LODKIT && method != LK_STRIPIFY_MESHOPT)
        return lk_error_set(error, LK_ERR_INVALID, "progressive strips: unknown stripifier %d", (int)method);
    if (pm->triangle_count && !pm->indices)
        return lk_error_set(error, LK_ERR_INVALID, "progressive strips: progressive mesh without triangles");

    /* both stripifiers run whatever the method, so that both are measured */
    lk_progressive_strips result;
    memset(&result, 0, sizeof result);
    uint32_t *lodkit = NULL, *meshopt = NULL;
    size_t lodkit_length = 0, meshopt_length = 0;
    if (progress && progress(progress_user, 0.0, "strips")) return lk_error_set(error, LK_ERR_INVALID, "cancelled");
    status = lk_stripify(pm->indices, pm->triangle_count, pm->vertex_count, LK_STRIPIFY_LODKIT, &lodkit, &lodkit_length,
                         NULL, error);
    if (status == LK_OK && progress && progress(progress_user, 0.4, "strips"))
        status = lk_error_set(error, LK_ERR_INVALID, "cancelled");
    if (status == LK_OK)
        status = lk_stripify(pm->indices, pm->triangle_count, pm->vertex_count, LK_STRIPIFY_MESHOPT, &meshopt,
                             &meshopt_length, NULL, error);
    if (status == LK_OK && progress && progress(progress_user, 0.6, "strips"))
        status = lk_error_set(error, LK_ERR_INVALID, "cancelled");
    if (status != LK_OK) {
        free(lodkit);
        free(meshopt);
        return status;
    }
    size_t triangles = 0;
    for (size_t t = 0; t < pm->triangle_count; t++) {
        const uint32_t *c = pm->indices + 3 * t;
        triangles += !triple_is_degenerate(c[0], c[1], c[2]);
    }
    if (triangles) {
        result.lodkit_indices_per_triangle = (double)lodkit_length / (double)triangles;
        result.meshopt_indices_per_triangle = (double)meshopt_length / (double)triangles;
    }
    bool take_meshopt = method == LK_STRIPIFY_MESHOPT || (method == LK_STRIPIFY_BEST && meshopt_length < lodkit_length);
    result.stripifier = take_meshopt ? LK_STRIPIFY_MESHOPT : LK_STRIPIFY_LODKIT;
    result.strip = take_meshopt ? meshopt : lodkit;
    result.strip_length = take_meshopt ? meshopt_length : lodkit_length;
    free(take_meshopt ? lodkit : meshopt);

    result.naive_updates = lk__calloc_array(pm->split_count, sizeof(uint32_t));
    result.encoded_updates = lk__calloc_array(pm->split_count, sizeof(uint32_t));
    if (!result.naive_updates || !result.encoded_updates) {
        lk_progressive_strips_free(&result);
        return lk_error_set(error, LK_ERR_NOMEM, "progressive strips: cannot allocate %zu splits", pm->split_count);
    }
    status = eps_collapse_all(result.strip, result.strip_length, pm, result.naive_updates, result.encoded_updates, NULL,
                              NULL, error);
    if (status != LK_OK) {
        lk_progressive_strips_free(&result);
        return status;
    }
    if (pm->split_count) {
        double naive = 0, encoded = 0;
        for (size_t k = 0; k < pm->split_count; k++) {
            naive += result.naive_updates[k];
            encoded += result.encoded_updates[k];
        }
        result.mean_naive_updates = naive / (double)pm->split_count;
        result.mean_encoded_updates = encoded / (double)pm->split_count;
        /* d = (v_q, q, o_1..o_r): 24-byte position, 2-byte index and offsets */
        result.naive_detail_bytes = 24 + 2 + 2 * result.mean_naive_updates;
        result.encoded_detail_bytes = 24 + 2 + 2 * result.mean_encoded_updates;
    }
    *out = result;
    if (progress) (void)progress(progress_user, 1.0, "strips"); /* done: too late to cancel */
    return LK_OK;
}

/* Decoder side of E-PS, for tests (and a reference for src/stream_decode.c):
 * collapses the strip to the base-level encoding, then applies the splits
 * in order - split k sets the entries its collapse rewrote back to direct
 * q - and resolves the references at each of `levels` (non-decreasing,
 * clamped to split_count) into out_strips[i] (ps->strip_length entries
 * each). Declared in internal.h. */
lk_status lk__eps_resolved_levels(const lk_progressive_strips *ps, const lk_progressive_mesh *pm, const size_t *levels,
                                  size_t count, uint32_t **out_strips, lk_error *error)
{
    if (!ps || (count && (!levels || !out_strips))) return lk_error_set(error, LK_ERR_INVALID, "E-PS: NULL argument");
    lk_status status = check_progressive(ps, pm, error);
    if (status != LK_OK) return status;
    for (size_t i = 1; i < count; i++)
        if (levels[i] < levels[i - 1]) return lk_error_set(error, LK_ERR_INVALID, "E-PS: levels must not decrease");
    size_t length = ps->strip_length;
    uint32_t *naive = lk__malloc_array(pm->split_count, sizeof(uint32_t));
    uint32_t *encoded = lk__malloc_array(pm->split_count, sizeof(uint32_t));
    uint32_t *state = lk__malloc_array(length, sizeof(uint32_t));
    uint32_t *chain = lk__malloc_array(length, sizeof(uint32_t));
    size_t *first = lk__malloc_array(pm->split_count + 1, sizeof(size_t));
    lk__buffer rewritten = {0};
    if (!naive || !encoded || !state || !chain || !first) {
        status = lk_error_set(error, LK_ERR_NOMEM, "E-PS: out of memory");
        goto done;
    }
    status = eps_collapse_all(ps->strip, length, pm, naive, encoded, &rewritten, state, error);
    if (status != LK_OK) goto done;
    /* positions were recorded in collapse order: split split_count-1 first */
    first[pm->split_count] = 0;
    for (size_t k = pm->split_count; k-- > 0;) first[k] = first[k + 1] + encoded[k];
    const uint32_t *positions = (const uint32_t *)rewritten.data;

    size_t level = 0;
    for (size_t i = 0; i < count; i++) {
        size_t target = levels[i] < pm->split_count ? levels[i] : pm->split_count;
        for (; level < target; level++) {
            /* split `level` undoes the collapse whose positions start after
             * those of the later collapses */
            size_t start = first[level + 1];
            for (size_t r = 0; r < encoded[level]; r++)
                state[positions[start + r]] = (uint32_t)(pm->base_vertex_count + level);
        }
        uint32_t *out = out_strips[i];
        /* resolve: follow references to a direct entry or one already
         * resolved at this level, then write the value along the way */
        for (size_t j = 0; j < length; j++) out[j] = NO_ENTRY;
        for (size_t j = 0; j < length; j++) {
            size_t depth = 0;
            uint32_t e = (uint32_t)j;
            while (out[e] == NO_ENTRY && state[e] >= EPS_REFERENCE_BASE) {
                if (depth == length) {
                    status = lk_error_set(error, LK_ERR_RANGE, "E-PS: reference cycle at entry %zu", j);
                    goto done;
                }
                chain[depth++] = e;
                long long target_entry = (long long)e + eps_offsets[state[e] - EPS_REFERENCE_BASE];
                if (target_entry < 0 || target_entry >= (long long)length) {
                    status = lk_error_set(error, LK_ERR_RANGE, "E-PS: entry %u refers outside the strip", (unsigned)e);
                    goto done;
                }
                e = (uint32_t)target_entry;
            }
            uint32_t value = out[e] != NO_ENTRY ? out[e] : state[e];
            out[e] = value;
            while (depth) out[chain[--depth]] = value;
        }
    }
done:
    free(naive);
    free(encoded);
    free(state);
    free(chain);
    free(first);
    lk__buffer_free(&rewritten);
    return status;
}

/* ---- bandwidth over levels (Fig. 4) ------------------------------------- */

lk_status lk_progressive_strips_bandwidth(const lk_progressive_strips *ps, const lk_progressive_mesh *pm,
                                          const size_t *levels, size_t level_count, lk_strip_bandwidth *out,
                                          lk_progress_fn progress, void *progress_user, lk_error *error)
{
    if (!ps || (level_count && (!levels || !out)))
        return lk_error_set(error, LK_ERR_INVALID, "strip bandwidth: NULL argument");
    lk_status status = check_progressive(ps, pm, error);
    if (status != LK_OK) return status;
    for (size_t i = 1; i < level_count; i++)
        if (levels[i] < levels[i - 1])
            return lk_error_set(error, LK_ERR_INVALID, "strip bandwidth: levels must be ascending (%zu after %zu)",
                                levels[i], levels[i - 1]);
    if (level_count == 0) return LK_OK;

    /* The strip is kept resolved at the current level, with the entries
     * standing for each vertex in a list. Split k (q = base + k off p)
     * moves from p's list the entries whose full-level vertex descends
     * from q: the splits form a forest (q's parent is p), and "descends
     * from q" is an interval test on its pre-order numbering. */
    size_t vertex_count = pm->vertex_count, base = pm->base_vertex_count, length = ps->strip_length;
    uint32_t *subtree = lk__malloc_array(vertex_count, sizeof(uint32_t));
    uint32_t *order = lk__malloc_array(vertex_count, sizeof(uint32_t));
    uint32_t *cursor = lk__malloc_array(vertex_count, sizeof(uint32_t));
    uint32_t *head = lk__malloc_array(vertex_count, sizeof(uint32_t));
    uint32_t *current = lk__malloc_array(length, sizeof(uint32_t));
    uint32_t *next = lk__malloc_array(length, sizeof(uint32_t));
    /* kept triples: a split only turns p into the new vertex q, so a triple
     * with three distinct vertices keeps them at every finer level; the set
     * only grows, and a split looks at the three triples around each entry
     * it changes. The filter then skips runs of degenerate triples a word
     * at a time. */
    size_t triples = length >= 3 ? length - 2 : 0;
    uint64_t *kept = lk__calloc_array((triples + 63) / 64 + 1, sizeof(uint64_t));
    if (!subtree || !order || !cursor || !head || !current || !next || !kept) {
        status = lk_error_set(error, LK_ERR_NOMEM, "strip bandwidth: out of memory for %zu vertices", vertex_count);
        goto done;
    }
    for (size_t v = 0; v < vertex_count; v++) subtree[v] = 1;
    for (size_t v = vertex_count; v-- > base;) subtree[pm->splits[v - base].kept] += subtree[v];
    /* pre-order numbers without recursion: parents come before children */
    uint32_t running = 0;
    for (size_t v = 0; v < vertex_count; v++) {
        if (v < base) {
            order[v] = running;
            running += subtree[v];
        } else {
            uint32_t parent = pm->splits[v - base].kept;
            order[v] = cursor[parent];
            cursor[parent] += subtree[v];
        }
        cursor[v] = order[v] + 1;
    }

    level_ancestors(pm, 0, cursor); /* cursor is free again: ancestors at the base level */
    for (size_t v = 0; v < vertex_count; v++) head[v] = NO_ENTRY;
    for (size_t j = length; j-- > 0;) {
        current[j] = cursor[ps->strip[j]];
        next[j] = head[current[j]];
        head[current[j]] = (uint32_t)j;
    }
    for (size_t j = 0; j < triples; j++)
        if (!triple_is_degenerate(current[j], current[j + 1], current[j + 2])) kept[j >> 6] |= (uint64_t)1 << (j & 63);

    size_t level = 0;
    for (size_t i = 0; i < level_count; i++) {
        size_t target = levels[i] < pm->split_count ? levels[i] : pm->split_count;
        for (; level < target; level++) {
            uint32_t q = (uint32_t)(base + level), p = pm->splits[level].kept;
            uint32_t low = order[q], high = order[q] + subtree[q];
            uint32_t entry = head[p], stay = NO_ENTRY, move = NO_ENTRY;
            while (entry != NO_ENTRY) {
                uint32_t following = next[entry];
                uint32_t at = order[ps->strip[entry]];
                if (at >= low && at < high) {
                    current[entry] = q;
                    next[entry] = move;
                    move = entry;
                } else {
                    next[entry] = stay;
                    stay = entry;
                }
                entry = following;
            }
            head[p] = stay;
            head[q] = move;
            /* only now that every moved entry holds q */
            for (entry = move; entry != NO_ENTRY; entry = next[entry])
                for (size_t t = entry >= 2 ? entry - 2 : 0; t <= entry && t < triples; t++)
                    if (!triple_is_degenerate(current[t], current[t + 1], current[t + 2]))
                        kept[t >> 6] |= (uint64_t)1 << (t & 63);
        }
        size_t triangles = 0;
        size_t filtered = filter_strip(current, length, kept, NULL, &triangles);
        out[i].level = target;
        out[i].triangles = triangles;
        out[i].pm_indices = 3 * triangles;
        out[i].strip_indices = length;
        out[i].filtered_indices = filtered;
        if (progress && progress(progress_user, (double)(i + 1) / (double)level_count, "strip bandwidth")) {
            status = lk_error_set(error, LK_ERR_INVALID, "strip bandwidth: cancelled");
            goto done;
        }
    }
done:
    free(subtree);
    free(order);
    free(cursor);
    free(head);
    free(current);
    free(next);
    free(kept);
    return status;
}
