/* SPDX-License-Identifier: MIT */
/* The QEM simplifier's extension to several frames (qem_state.h: qem_frames,
 * qem_lost; qem.c runs it, qem_build.c builds its quadrics).
 *
 * Several frames (lk_animation_simplify; Cho & Chen, "Constructing scalable
 * 3D animated model by deformation sensitive simplification", 2004). One
 * connectivity, F frames of positions. Every vertex carries one quadric per
 * frame, built from that frame's positions by the same rules (area-weighted
 * face planes, border/non-manifold/crease constraints, corner points); a
 * pair gets one optimal position per frame, solved from that frame's summed
 * quadric exactly as above, and its cost combines the per-frame costs
 * v_i^T (Q_i,a + Q_i,b) v_i: their maximum (the paper's scheme), their mean,
 * or one frame's. A contraction sums every frame's quadrics and moves the
 * kept vertex to each frame's optimum; the orientation test runs in every
 * frame (with allow_folds, once every remaining pair is refused, in the
 * reference frame only: a connectivity that suits all poses runs out near
 * 30% of the triangles on faerie.md2). Vertices that coincide in every
 * frame (texture seams) are merged first unless keep_seams is set, or
 * every seam would be a border (anim_simplify.c welds them before and
 * splits them again after). The per-frame data live in separate
 * vertex-major arrays (frame after frame for one vertex, so a pair
 * evaluation reads two contiguous runs); the vertex records hold the
 * reference frame (frame 0, or the chosen frame of the single-frame
 * scheme), which orders vertices in space and finds non-edge pairs. All
 * frames share one normalisation (the bounds of every frame), so per-frame
 * costs are comparable. Queue keys are full evaluations (no cheap bound).
 * Not in the paper, on by default (lost_surface): each frame's cost also
 * counts how far the input vertices merged into the pair end up from the
 * triangles around the merged vertex (lost_surface_cost), which quadrics
 * miss on thin parts; every input vertex keeps its per-frame positions and
 * areas, and each surviving vertex the list of input vertices merged into
 * it.
 * lk_simplify never sets frames.count: its code paths and results are those
 * of the static simplifier, bit for bit. */
#include "qem_state.h"

/* Bytes of per-frame data for V vertices and F frames (SIZE_MAX on overflow);
 * the lost-surface term adds every input position and area per frame and
 * the member lists. */
size_t lk__qem_frame_bytes(size_t vertex_count, size_t frame_count, bool lost_surface)
{
    size_t per_slot = sizeof(quadric) + 3 * sizeof(double) + 3 * sizeof(float);
    if (lost_surface) per_slot += 4 * sizeof(double);
    if (frame_count && vertex_count > SIZE_MAX / frame_count) return SIZE_MAX;
    size_t slots = vertex_count * frame_count;
    size_t fixed = 3 * sizeof(double) * frame_count + (lost_surface ? 2 * sizeof(uint32_t) * vertex_count : 0);
    if (slots > (SIZE_MAX - fixed) / per_slot) return SIZE_MAX;
    return slots * per_slot + fixed;
}

/* Squared distance from point x to triangle (a, b, c). */
static double point_triangle_distance_sq(const double x[3], const double a[3], const double b[3], const double c[3])
{
    double ab[3], ac[3], ax[3];
    sub3(ab, b, a), sub3(ac, c, a), sub3(ax, x, a);
    double d1 = dot3(ab, ax), d2 = dot3(ac, ax);
    if (d1 <= 0 && d2 <= 0) return dot3(ax, ax); /* nearest to a */
    double bx[3];
    sub3(bx, x, b);
    double d3 = dot3(ab, bx), d4 = dot3(ac, bx);
    if (d3 >= 0 && d4 <= d3) return dot3(bx, bx); /* nearest to b */
    double cx[3];
    sub3(cx, x, c);
    double d5 = dot3(ab, cx), d6 = dot3(ac, cx);
    if (d6 >= 0 && d5 <= d6) return dot3(cx, cx); /* nearest to c */
    double point[3], u, v;
    double vc = d1 * d4 - d3 * d2, vb = d5 * d2 - d1 * d6, va = d3 * d6 - d5 * d4;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) { /* on edge ab */
        u = d1 / (d1 - d3);
        for (int k = 0; k < 3; k++) point[k] = a[k] + u * ab[k];
    } else if (vb <= 0 && d2 >= 0 && d6 <= 0) { /* on edge ac */
        v = d2 / (d2 - d6);
        for (int k = 0; k < 3; k++) point[k] = a[k] + v * ac[k];
    } else if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) { /* on edge bc */
        u = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        for (int k = 0; k < 3; k++) point[k] = b[k] + u * (c[k] - b[k]);
    } else { /* inside */
        double sum = va + vb + vc;
        if (!(sum > 0)) return dot3(ax, ax); /* degenerate */
        u = vb / sum, v = vc / sum;
        for (int k = 0; k < 3; k++) point[k] = a[k] + u * ab[k] + v * ac[k];
    }
    double d[3];
    sub3(d, x, point);
    return dot3(d, d);
}

#define LOST_FAN_MAX 96

/* The triangles that survive contracting va and vb (those of either end
 * without both), for the lost-surface term; 0 when more than LOST_FAN_MAX
 * (the term then takes the distances to the merged vertex itself, an upper
 * bound). */
static size_t lost_surface_fan(const qem *s, uint32_t va, uint32_t vb, uint32_t fan[LOST_FAN_MAX])
{
    size_t count = 0;
    for (int side = 0; side < 2; side++) {
        uint32_t v = side ? vb : va, other = side ? va : vb;
        const uint32_t *list = list_of(s, v);
        for (uint32_t i = 0; i < s->vertices[v].list_count; i++) {
            const uint32_t *t = s->indices + 3 * (size_t)list[i];
            if (triangle_has(t, other)) continue;
            if (count == LOST_FAN_MAX) return 0;
            fan[count++] = list[i];
        }
    }
    return count;
}

/* Lost surface in frame f: the input vertices merged into va and vb so far,
 * each weighted by its area, times the squared distance from its input
 * position to the triangles around the merged vertex at x. Quadrics measure
 * the merged vertex against the input's planes; this measures the input
 * against the new surface, which quadrics miss on thin parts: once a leg is
 * a few triangles its face planes contain its axis, and moving the foot up
 * into the hip is nearly free for the quadrics while the leg vanishes. */
static double lost_surface_cost(const qem *s, uint32_t va, uint32_t vb, const uint32_t *fan, size_t fan_count, size_t f,
                                const double x[3])
{
    size_t frames = s->frames.count;
    double total = 0;
    for (int side = 0; side < 2; side++) {
        for (uint32_t o = side ? vb : va; o != NONE; o = s->lost.member_next[o]) {
            const double *point = s->lost.origin_positions + 3 * (o * frames + f);
            /* x is a corner of every fan triangle: no farther than it */
            double best = distance_sq3(point, x);
            for (size_t i = 0; i < fan_count && best > 0; i++) {
                const uint32_t *t = s->indices + 3 * (size_t)fan[i];
                const double *corner[3];
                for (int k = 0; k < 3; k++)
                    corner[k] = t[k] == va || t[k] == vb ? x : s->frames.positions + 3 * (t[k] * frames + f);
                double d = point_triangle_distance_sq(point, corner[0], corner[1], corner[2]);
                best = d < best ? d : best;
            }
            total += s->lost.origin_weights[o * frames + f] * best;
        }
    }
    return s->lost.weight * total;
}

/* Several frames: each frame places the merged vertex by its own summed
 * quadric (locked and half-edge placements choose one end for all frames),
 * and the scheme combines the per-frame costs. With out->frames NULL (queue
 * keys) the single-frame scheme looks at its frame only. */
void lk__qem_evaluate_frames(const qem *s, uint32_t va, uint32_t vb, placement *out)
{
    size_t frames = s->frames.count;
    const quadric *qa = s->frames.quadrics + frames * va, *qb = s->frames.quadrics + frames * vb;
    const double *pa = s->frames.positions + 3 * frames * va, *pb = s->frames.positions + 3 * frames * vb;
    bool one_frame = s->frames.scheme == LK_ANIM_SCHEME_FRAME;
    size_t first = 0, last = frames;
    if (one_frame && !out->frames) first = s->frames.scheme_frame, last = first + 1;
    /* fixed: 0 = every frame keeps va where it is, 1 = vb, -1 = free */
    int fixed = -1;
    if ((s->flags[va] | s->flags[vb]) & FLAG_LOCKED) {
        fixed = (s->flags[va] & FLAG_LOCKED) ? 0 : 1;
    } else if ((s->flags[va] ^ s->flags[vb]) & FLAG_SEAM) {
        fixed = (s->flags[va] & FLAG_SEAM) ? 0 : 1;
    } else if (s->endpoints) {
        double cost_a = 0, cost_b = 0;
        for (size_t f = first; f < last; f++) {
            if (one_frame && f != s->frames.scheme_frame) continue;
            double q[10];
            for (int k = 0; k < 10; k++) q[k] = qa[f].m[k] + qb[f].m[k];
            double ca = quadric_value(q, q + 6, q[9], pa + 3 * f), cb = quadric_value(q, q + 6, q[9], pb + 3 * f);
            if (s->frames.scheme == LK_ANIM_SCHEME_AVG) {
                cost_a += ca, cost_b += cb;
            } else {
                cost_a = ca > cost_a ? ca : cost_a, cost_b = cb > cost_b ? cb : cost_b;
            }
        }
        fixed = cost_a <= cost_b ? 0 : 1;
    }
    uint32_t fan[LOST_FAN_MAX];
    bool lost = s->lost.weight > 0;
    size_t fan_count = lost ? lost_surface_fan(s, va, vb, fan) : 0;
    double cost = 0, error_sq = 0, side = 0;
    for (size_t f = first; f < last; f++) {
        double q[10], x[3];
        for (int k = 0; k < 10; k++) q[k] = qa[f].m[k] + qb[f].m[k];
        if (fixed == 0) {
            memcpy(x, pa + 3 * f, sizeof x);
        } else if (fixed == 1) {
            memcpy(x, pb + 3 * f, sizeof x);
        } else {
            double nearer = optimal_point(q, pa + 3 * f, pb + 3 * f, x);
            if (!one_frame || f == s->frames.scheme_frame) side += nearer;
        }
        if (out->frames) memcpy(out->frames + 3 * f, x, sizeof x);
        if (f == s->frames.reference) memcpy(out->position, x, sizeof x);
        if (one_frame && f != s->frames.scheme_frame) continue;
        double quadric_cost = quadric_value(q, q + 6, q[9], x);
        quadric_cost = quadric_cost > 0 ? quadric_cost : 0; /* NaN too */
        double frame_cost = quadric_cost;
        if (lost) frame_cost += lost_surface_cost(s, va, vb, fan, fan_count, f, x);
        /* the error (max_error, the result's error) stays the quadrics' distance */
        double weight = qa[f].weight + qb[f].weight;
        double frame_error_sq = weight > 0 ? quadric_cost / weight : 0;
        if (s->frames.scheme == LK_ANIM_SCHEME_MAX) {
            cost = frame_cost > cost ? frame_cost : cost;
            error_sq = frame_error_sq > error_sq ? frame_error_sq : error_sq;
        } else {
            cost += frame_cost, error_sq += frame_error_sq;
        }
    }
    if (s->frames.scheme == LK_ANIM_SCHEME_AVG) cost /= (double)frames, error_sq /= (double)frames;
    out->kept = fixed == 0 ? va : fixed == 1 ? vb : side <= 0 ? va : vb;
    out->removed = out->kept == va ? vb : va;
    out->cost = cost;
    out->error_sq = error_sq;
}

/* The orientation test of check_contraction in every frame but the
 * reference (which the caller has tested), with each frame's new position;
 * frames may fold while the contraction's count of folded frames stays
 * within allowed_folds. */
bool lk__qem_frames_keep_orientation(qem *s, const uint32_t *t, uint32_t moved, const placement *pl)
{
    size_t frames = s->frames.count;
    if (s->frames.allowed_folds >= frames - 1) return true;
    int k = t[0] == moved ? 0 : t[1] == moved ? 1 : 2;
    const double *r0 = s->frames.positions + 3 * frames * t[k];
    const double *r1 = s->frames.positions + 3 * frames * t[k == 2 ? 0 : k + 1];
    const double *r2 = s->frames.positions + 3 * frames * t[k == 0 ? 2 : k - 1];
    for (size_t f = 0; f < frames; f++) {
        if (f == s->frames.reference || s->frames.folded[f]) continue;
        if (corner_move_keeps_orientation(r0 + 3 * f, r1 + 3 * f, r2 + 3 * f, pl->frames + 3 * f)) continue;
        if (s->frames.folded_count == s->frames.allowed_folds) return false;
        s->frames.folded[f] = 1;
        s->frames.folded_count++;
    }
    return true;
}

/* Several frames: p takes q's quadrics and each frame's position. A frame
 * where p stays put keeps its exact float position. */
void lk__qem_contract_frames(qem *s, uint32_t p, uint32_t q, const placement *pl)
{
    size_t frames = s->frames.count;
    quadric *qp = s->frames.quadrics + frames * p;
    const quadric *qq = s->frames.quadrics + frames * q;
    double *position = s->frames.positions + 3 * frames * p;
    float *output = s->frames.output + 3 * frames * p;
    for (size_t f = 0; f < frames; f++) {
        for (int k = 0; k < 10; k++) qp[f].m[k] += qq[f].m[k];
        qp[f].weight += qq[f].weight;
        const double *x = pl->frames + 3 * f;
        double *old = position + 3 * f;
        if (old[0] == x[0] && old[1] == x[1] && old[2] == x[2]) continue;
        for (int k = 0; k < 3; k++) {
            old[k] = x[k];
            output[3 * f + k] = output_float(x[k] * s->extent + s->center[k]);
        }
    }
}
