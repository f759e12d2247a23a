/* SPDX-License-Identifier: MIT */
/* Version-2 progressive stream: the encoder.
 *
 * The progressive mesh's vertex splits are regrouped into batches: a batch
 * takes splits in refinement order whose neighbourhoods (p, q and p's ring
 * when the split happens) are pairwise disjoint and disjoint from those of
 * the earlier splits it passes over, so the splits of a batch commute and
 * give exactly the meshes of the refinement order. The decoder learns a
 * batch's split vertices as one bit per vertex in its own vertex order,
 * modelled by the vertex's triangle count (vertices next to an earlier one
 * are skipped: they cannot split in the same batch), then each split as: which of p's triangles go
 * to q (one modelled bit each, the context being the decisions already
 * taken for neighbouring triangles), whether the restored triangles are
 * the predicted ones (one per edge between the moved and staying triangles),
 * and the new position(s) as residuals from the mean of the vertex's ring,
 * taken apart in the ring's frame (across its normal, then along it from
 * the plane through the mean: lk__lks2_predict_frame).
 * Everything is coded with the adaptive binary range coder of
 * stream2_internal.h; the models restart in every chunk.
 *
 * The encoder keeps the decoder's mesh (stream2_mesh.c) in step, so every
 * number it writes is one the decoder can compute, and decodes the whole
 * stream before returning it (lk__lks2_check). */
#include "bytes.h"
#include "stream2_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Splits a batch may take, as a fraction of the vertices present, and how
 * far past the first waiting split it looks for them. */
#define BATCH_FRACTION 0.25
#define BATCH_WINDOW 4
/* A chunk ends after the batch that takes the vertex count past this factor
 * times its count at the chunk's start. */
#define CHUNK_GROWTH 1.5

typedef struct lks2_encoding {
    const lk_progressive_mesh *pm;
    size_t base, splits;
    int32_t top;
    int32_t *base_quantised;  /* 3 * base */
    int32_t *split_quantised; /* 3 * splits: q's position */
    int32_t *kept_quantised;  /* 3 * splits: p's position after the split */
    /* The neighbourhood of every split in refinement order. */
    uint32_t *set_start; /* splits + 1 */
    uint32_t *set_vertices;
    /* Decoding order. */
    uint32_t *order;       /* splits, batch after batch, each by p's decoder number */
    uint32_t *batch_start; /* batch_count + 1, into order */
    size_t batch_count;
    /* Decoder numbering. */
    uint32_t *decoder_vertex; /* PM vertex -> decoder vertex, LKS_NONE until present */
    uint32_t *pm_vertex;      /* decoder vertex -> PM vertex */
    uint32_t *pm_triangle;    /* decoder triangle -> PM triangle */
    /* Attributes: quantised per input vertex, and whose attributes each
     * vertex shows (a PM vertex holding another's position holds its
     * attributes too). */
    lks2_attributes attributes;
    int32_t *input_attributes; /* attributes.count per input vertex */
    uint32_t *base_identity;   /* base vertices: input vertex */
    uint32_t *p_identity;      /* per split: input vertex of p after it */
    uint32_t *q_identity;      /* per split: input vertex of q after it */
} lks2_encoding;

static void encoding_free(lks2_encoding *e)
{
    free(e->base_quantised);
    free(e->split_quantised);
    free(e->kept_quantised);
    free(e->set_start);
    free(e->set_vertices);
    free(e->order);
    free(e->batch_start);
    free(e->decoder_vertex);
    free(e->pm_vertex);
    free(e->pm_triangle);
    free(e->input_attributes);
    free(e->base_identity);
    free(e->p_identity);
    free(e->q_identity);
}

static uint32_t parent(const lks2_encoding *e, uint32_t v) { return e->pm->splits[v - e->base].kept; }

/* PM vertex v's nearest ancestor below `limit` (present at level limit - base). */
static uint32_t resolve_below(const lks2_encoding *e, uint32_t v, size_t limit)
{
    while (v >= limit) v = parent(e, v);
    return v;
}

/* True when full-level vertex v is q or descends from it. */
static bool descends(const lks2_encoding *e, uint32_t v, uint32_t q)
{
    while (v > q) v = parent(e, v);
    return v == q;
}

/* ---- neighbourhoods in refinement order ------------------------------------- */

static lk_status compute_sets(lks2_encoding *e, lk_error *error)
{
    const lk_progressive_mesh *pm = e->pm;
    lks2_mesh mesh = {0};
    lks2_fan fan = {0};
    lk__buffer sets = {0};
    lk_status status = lk__lks2_mesh_reserve(&mesh, pm->vertex_count, pm->triangle_count, error);
    e->set_start = lk__malloc_array(e->splits + 1, sizeof(uint32_t));
    if (status == LK_OK && !e->set_start)
        status = lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu splits", e->splits);
    if (status != LK_OK) goto done;
    static const int32_t origin[3] = {0, 0, 0};
    for (size_t v = 0; v < e->base; v++) lk__lks2_add_vertex(&mesh, origin, LKS_NONE);
    size_t base_triangles = lk_progressive_mesh_level_triangles(pm, 0);
    for (size_t t = 0; t < base_triangles; t++) {
        const uint32_t *c = pm->indices + 3 * t;
        lk__lks2_add_triangle(&mesh, resolve_below(e, c[0], e->base), resolve_below(e, c[1], e->base),
                              resolve_below(e, c[2], e->base));
    }
    for (size_t k = 0; k < e->splits; k++) {
        uint32_t q = (uint32_t)(e->base + k), p = pm->splits[k].kept;
        if (!lk__lks2_fan_load(&fan, &mesh, p)) {
            status = lk_error_set(error, LK_ERR_NOMEM, "out of memory for a vertex fan");
            goto done;
        }
        e->set_start[k] = (uint32_t)(sets.size / sizeof(uint32_t));
        uint32_t pair[2] = {p, q};
        bool ok = lk__buffer_append(&sets, pair, sizeof pair);
        size_t fan_size = fan.count;
        for (size_t i = 0; i < fan_size && ok; i++)
            for (int c = 0; c < 3 && ok; c++) {
                uint32_t w = mesh.corners[3 * (size_t)fan.triangles[i] + (size_t)c];
                if (w != p) ok = lk__buffer_append(&sets, &w, sizeof w);
            }
        if (!ok || sets.size / sizeof(uint32_t) > UINT32_MAX) {
            status = lk_error_set(error, LK_ERR_NOMEM, "out of memory for split neighbourhoods");
            goto done;
        }
        lk__lks2_add_vertex(&mesh, origin, LKS_NONE);
        for (size_t i = 0; i < fan_size; i++) {
            uint32_t t = fan.triangles[i];
            const uint32_t *full = pm->indices + 3 * (size_t)t;
            if (descends(e, full[0], q) || descends(e, full[1], q) || descends(e, full[2], q))
                lk__lks2_move_corner(&mesh, t, p, q);
        }
        const lk_vertex_split *split = &pm->splits[k];
        for (uint32_t t = split->first_triangle; t < split->first_triangle + split->triangle_count; t++) {
            const uint32_t *full = pm->indices + 3 * (size_t)t;
            lk__lks2_add_triangle(&mesh, resolve_below(e, full[0], q + 1), resolve_below(e, full[1], q + 1),
                                  resolve_below(e, full[2], q + 1));
        }
    }
    e->set_start[e->splits] = (uint32_t)(sets.size / sizeof(uint32_t));
    e->set_vertices = lk__buffer_take(&sets);
done:
    lk__buffer_free(&sets);
    lk__lks2_fan_free(&fan);
    lk__lks2_mesh_free(&mesh);
    return status;
}

/* ---- batches --------------------------------------------------------------- */

/* Splits j < k (refinement order) conflict when p_k is in j's neighbourhood
 * or p_j in k's (a neighbourhood being p, q and p's ring when the split
 * happens): then one changes the other's fan. Splits that do not conflict
 * commute. A batch takes, in refinement order, splits that conflict
 * neither with the splits it took nor with those it passed over (which
 * must stay before them). */
static lk_status schedule(lks2_encoding *e, lk_error *error)
{
    size_t vertex_count = e->pm->vertex_count;
    uint32_t *pending = lk__malloc_array(e->splits, sizeof(uint32_t));
    /* Per vertex: the serial of the batch in which it is the p of a split
     * taken (or passed over), or in the neighbourhood of one. */
    uint32_t *taken_p = lk__calloc_array(vertex_count, sizeof(uint32_t));
    uint32_t *taken_near = lk__calloc_array(vertex_count, sizeof(uint32_t));
    uint32_t *passed_p = lk__calloc_array(vertex_count, sizeof(uint32_t));
    uint32_t *passed_near = lk__calloc_array(vertex_count, sizeof(uint32_t));
    e->order = lk__malloc_array(e->splits, sizeof(uint32_t));
    e->batch_start = lk__malloc_array(e->splits + 1, sizeof(uint32_t));
    e->decoder_vertex = lk__malloc_array(vertex_count, sizeof(uint32_t));
    e->pm_vertex = lk__malloc_array(vertex_count, sizeof(uint32_t));
    lk_status status = LK_OK;
    if (!pending || !taken_p || !taken_near || !passed_p || !passed_near || !e->order || !e->batch_start ||
        !e->decoder_vertex || !e->pm_vertex) {
        status = lk_error_set(error, LK_ERR_NOMEM, "out of memory scheduling %zu splits", e->splits);
        goto done;
    }
    for (size_t k = 0; k < e->splits; k++) pending[k] = (uint32_t)k;
    for (size_t v = 0; v < vertex_count; v++) e->decoder_vertex[v] = LKS_NONE;
    size_t pending_count = e->splits, ordered = 0, present = e->base;
    uint32_t serial = 0;
    e->batch_count = 0;
    while (pending_count > 0) {
        serial++;
        size_t target = (size_t)((double)present * BATCH_FRACTION);
        if (target < 1) target = 1;
        size_t window = target * BATCH_WINDOW, kept = 0, first = ordered;
        e->batch_start[e->batch_count++] = (uint32_t)ordered;
        for (size_t i = 0; i < pending_count; i++) {
            uint32_t k = pending[i];
            if (ordered - first >= target || i >= window) {
                pending[kept++] = k;
                continue;
            }
            const uint32_t *set = e->set_vertices + e->set_start[k];
            size_t set_size = e->set_start[k + 1] - e->set_start[k];
            uint32_t p = set[0];
            bool conflict = taken_near[p] == serial || passed_near[p] == serial;
            for (size_t j = 0; j < set_size && !conflict; j++)
                conflict = taken_p[set[j]] == serial || passed_p[set[j]] == serial;
            uint32_t *mark_p = conflict ? passed_p : taken_p, *mark_near = conflict ? passed_near : taken_near;
            mark_p[p] = serial;
            for (size_t j = 0; j < set_size; j++) mark_near[set[j]] = serial;
            if (conflict)
                pending[kept++] = k;
            else
                e->order[ordered++] = k;
        }
        pending_count = kept;
        present += ordered - first;
    }
    e->batch_start[e->batch_count] = (uint32_t)ordered;
done:
    free(pending);
    free(taken_p);
    free(taken_near);
    free(passed_p);
    free(passed_near);
    return status;
}

/* ---- payloads -------------------------------------------------------------- */

typedef struct sort_item {
    uint32_t key, split;
} sort_item;

static int compare_items(const void *a, const void *b)
{
    const sort_item *x = a, *y = b;
    return (x->key > y->key) - (x->key < y->key);
}

static void encode_residual(lks2_encoder *coder, lks2_models *models, const int32_t actual[3],
                            const int32_t predicted[3])
{
    for (int axis = 0; axis < 3; axis++) {
        lks2_encode_uint(coder, &models->residual[axis], lks2_zigzag32(actual[axis] - predicted[axis]));
    }
}

/* A split vertex's position in its ring's frame (mesh->ring_frame): the
 * two components across the ring's normal, then the one along it less the
 * offset that would put the vertex in the plane through the prediction. */
static void encode_in_frame(lks2_encoder *coder, lks2_models *models, const lks2_frame *frame, const int32_t actual[3],
                            const int32_t predicted[3])
{
    int32_t first = actual[frame->axis[0]] - predicted[frame->axis[0]];
    int32_t second = actual[frame->axis[1]] - predicted[frame->axis[1]];
    int32_t along =
        (int32_t)(actual[frame->axis[2]] - predicted[frame->axis[2]] - lk__lks2_frame_offset(frame, first, second));
    lks2_encode_uint(coder, &models->residual[0], lks2_zigzag32(first));
    lks2_encode_uint(coder, &models->residual[1], lks2_zigzag32(second));
    lks2_encode_uint(coder, &models->residual[2], lks2_zigzag32(along));
}

/* Attribute residuals against a prediction, one model per component. */
static void encode_attributes(lks2_encoder *coder, lks2_models *models, size_t stride, const int32_t *actual,
                              const int32_t *predicted)
{
    for (size_t c = 0; c < stride; c++)
        lks2_encode_uint(coder, &models->attribute[c], lks2_zigzag32(actual[c] - predicted[c]));
}

static void encode_float(lks2_encoder *coder, float value)
{
    uint32_t bits;
    memcpy(&bits, &value, sizeof bits);
    lks2_encode_direct(coder, bits, 32);
}

/* The base chunk starts with how the attributes are quantised. */
static void write_attribute_parameters(lks2_encoder *coder, const lks2_attributes *attributes)
{
    if (attributes->flags & LKS2_FLAG_NORMALS) lks2_encode_direct(coder, attributes->normal_bits, 5);
    if (attributes->flags & LKS2_FLAG_TEXCOORDS) {
        lks2_encode_direct(coder, attributes->texcoord_bits, 5);
        for (int axis = 0; axis < 2; axis++) {
            encode_float(coder, attributes->texcoord_min[axis]);
            encode_float(coder, attributes->texcoord_step[axis]);
        }
    }
}

/* The order the base triangles are written in: from a seed triangle
 * (the first not yet written, in the progressive mesh's order), the
 * triangles around each written vertex in the order the vertices were
 * first named, so that a corner names a recent vertex (a small `back`).
 * Any order decodes: this one only makes the base chunk smaller (the cow
 * at 11 bits: 425 -> 370 bytes of base connectivity against the
 * progressive mesh's order, first frame 1,271 -> 1,226 bytes). Writes
 * base_triangles entries to `order`; false when out of memory. */
static bool base_triangle_order(const lks2_encoding *e, size_t base_triangles, uint32_t *order)
{
    const lk_progressive_mesh *pm = e->pm;
    size_t base = e->base;
    uint32_t *first = lk__calloc_array(base + 1, sizeof(uint32_t));
    uint32_t *around = lk__malloc_array(3 * base_triangles + 1, sizeof(uint32_t));
    uint32_t *corners = lk__malloc_array(3 * base_triangles + 1, sizeof(uint32_t));
    uint32_t *named = lk__malloc_array(base + 1, sizeof(uint32_t)); /* vertices in first-named order */
    unsigned char *written = lk__calloc_array(base_triangles + 1, 1), *seen = lk__calloc_array(base + 1, 1);
    bool ok = first && around && corners && named && written && seen;
    if (ok) {
        for (size_t c = 0; c < 3 * base_triangles; c++) {
            corners[c] = resolve_below(e, pm->indices[c], base);
            first[corners[c] + 1]++;
        }
        for (size_t v = 0; v < base; v++) first[v + 1] += first[v];
        for (size_t t = 0; t < base_triangles; t++)
            for (int k = 0; k < 3; k++) around[first[corners[3 * t + (size_t)k]]++] = (uint32_t)t;
        for (size_t v = base; v > 0; v--) first[v] = first[v - 1];
        first[0] = 0;
        size_t written_count = 0, named_count = 0, next_named = 0;
        for (size_t seed = 0; seed < base_triangles; seed++) {
            if (written[seed]) continue;
            uint32_t pending = (uint32_t)seed;
            for (;;) {
                written[pending] = 1;
                order[written_count++] = pending;
                for (int k = 0; k < 3; k++) {
                    uint32_t v = corners[3 * (size_t)pending + (size_t)k];
                    if (!seen[v]) seen[v] = 1, named[named_count++] = v;
                }
                /* the next triangle: around the earliest named vertex that has one left */
                pending = UINT32_MAX;
                while (next_named < named_count && pending == UINT32_MAX) {
                    uint32_t v = named[next_named];
                    for (uint32_t i = first[v]; i < first[v + 1] && pending == UINT32_MAX; i++)
                        if (!written[around[i]]) pending = around[i];
                    if (pending == UINT32_MAX) next_named++;
                }
                if (pending == UINT32_MAX) break;
            }
        }
    }
    free(first), free(around), free(corners), free(named), free(written), free(seen);
    return ok;
}

/* The base chunk: each corner of the base triangles (in
 * base_triangle_order) as "how far back from the next new vertex" (0: a
 * new one; vertices are numbered in first use), vertices no triangle uses
 * after them, then every position as the delta from the vertex before.
 * Builds the decoder's base mesh as it goes. False when out of memory. */
static bool write_base(lks2_encoding *e, lks2_mesh *mesh, lks2_encoder *coder)
{
    const lk_progressive_mesh *pm = e->pm;
    lks2_models models;
    lk__lks2_models_init(&models);
    write_attribute_parameters(coder, &e->attributes);
    size_t base_triangles = lk_progressive_mesh_level_triangles(pm, 0);
    uint32_t *order = lk__malloc_array(base_triangles + 1, sizeof(uint32_t));
    if (!order || !base_triangle_order(e, base_triangles, order)) {
        free(order);
        return false;
    }
    uint32_t next_new = 0;
    for (size_t i = 0; i < base_triangles; i++)
        for (int c = 0; c < 3; c++) {
            uint32_t v = resolve_below(e, pm->indices[3 * (size_t)order[i] + (size_t)c], e->base);
            uint32_t back = 0;
            if (e->decoder_vertex[v] == LKS_NONE) {
                e->decoder_vertex[v] = next_new;
                e->pm_vertex[next_new++] = v;
            } else {
                back = next_new - e->decoder_vertex[v];
            }
            lks2_encode_uint(coder, &models.corner[c], back);
        }
    for (uint32_t v = 0; v < e->base; v++)
        if (e->decoder_vertex[v] == LKS_NONE) {
            e->decoder_vertex[v] = next_new;
            e->pm_vertex[next_new++] = v;
        }
    int32_t previous[3] = {0, 0, 0}, previous_attributes[LKS2_MAX_ATTRIBUTES] = {0};
    size_t stride = e->attributes.count;
    for (uint32_t d = 0; d < e->base; d++) {
        const int32_t *position = e->base_quantised + 3 * (size_t)e->pm_vertex[d];
        encode_residual(coder, &models, position, previous);
        memcpy(previous, position, sizeof previous);
        lk__lks2_add_vertex(mesh, position, LKS_NONE);
        if (stride) {
            const int32_t *values = e->input_attributes + stride * e->base_identity[e->pm_vertex[d]];
            encode_attributes(coder, &models, stride, values, previous_attributes);
            memcpy(previous_attributes, values, stride * sizeof(int32_t));
            memcpy(mesh->attributes + stride * d, values, stride * sizeof(int32_t));
        }
    }
    for (size_t i = 0; i < base_triangles; i++) {
        uint32_t d[3];
        for (int c = 0; c < 3; c++)
            d[c] = e->decoder_vertex[resolve_below(e, pm->indices[3 * (size_t)order[i] + (size_t)c], e->base)];
        e->pm_triangle[mesh->triangle_count] = order[i];
        lk__lks2_add_triangle(mesh, d[0], d[1], d[2]);
    }
    free(order);
    return true;
}

/* A restored triangle seen from p: the third vertex and whether it reads
 * (p, q, w) (0) or (p, w, q) (1) in drawing order; false when it does not
 * hold both p and q. */
static bool restored_form(const uint32_t t[3], uint32_t p, uint32_t q, uint32_t *w, unsigned *flipped)
{
    for (int i = 0; i < 3; i++) {
        if (t[i] != p) continue;
        uint32_t b = t[(i + 1) % 3], c = t[(i + 2) % 3];
        if (b == q && c != p && c != q) {
            *w = c, *flipped = 0;
            return true;
        }
        if (c == q && b != p && b != q) {
            *w = b, *flipped = 1;
            return true;
        }
    }
    return false;
}

typedef struct chunk_writer {
    lks2_encoding *e;
    lks2_mesh *mesh;
    lks2_models models; /* carried from split chunk to split chunk */
    lks2_fan fan;
    uint32_t *stamp;
    uint32_t serial;
    sort_item *items;
} chunk_writer;

/* Vertex v's new position and, after it, the attributes of input vertex
 * `identity`, each against its prediction from v's ring. */
static void write_vertex(const lks2_encoding *e, lks2_mesh *mesh, lks2_encoder *coder, lks2_models *models, uint32_t v,
                         const int32_t merged[3], const int32_t *merged_attributes, const int32_t position[3],
                         uint32_t identity)
{
    int32_t predicted[LKS2_MAX_ATTRIBUTES > 3 ? LKS2_MAX_ATTRIBUTES : 3];
    if (mesh->ring_frame) {
        lks2_frame frame;
        lk__lks2_predict_frame(mesh, v, merged, predicted, &frame);
        encode_in_frame(coder, models, &frame, position, predicted);
    } else {
        lk__lks2_predict(mesh, v, merged, predicted);
        encode_residual(coder, models, position, predicted);
    }
    memcpy(mesh->quantised + 3 * (size_t)v, position, 3 * sizeof(int32_t));
    size_t stride = e->attributes.count;
    if (!stride) return;
    const int32_t *values = e->input_attributes + stride * identity;
    lk__lks2_predict_attributes(mesh, v, merged_attributes, predicted);
    encode_attributes(coder, models, stride, values, predicted);
    memcpy(mesh->attributes + stride * v, values, stride * sizeof(int32_t));
}

/* One split, p = decoder vertex of the split's kept vertex. */
static lk_status write_split(chunk_writer *w, lks2_encoder *coder, lks2_models *models, uint32_t k, lk_error *error)
{
    lks2_encoding *e = w->e;
    lks2_mesh *mesh = w->mesh;
    const lk_progressive_mesh *pm = e->pm;
    const lk_vertex_split *split = &pm->splits[k];
    uint32_t q_pm = (uint32_t)(e->base + k), p = e->decoder_vertex[split->kept];
    if (!lk__lks2_fan_load(&w->fan, mesh, p))
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory for a vertex fan");
    size_t fan_size = w->fan.count;
    uint32_t *fan = w->fan.triangles;
    unsigned char *moved = w->fan.moved;
    for (size_t i = 0; i < fan_size; i++) {
        const uint32_t *full = pm->indices + 3 * (size_t)e->pm_triangle[fan[i]];
        moved[i] = descends(e, full[0], q_pm) || descends(e, full[1], q_pm) || descends(e, full[2], q_pm);
        lks2_encode_bit(coder, &models->move[lk__lks2_move_context(mesh, p, &w->fan, i)], moved[i]);
    }
    uint32_t q = (uint32_t)mesh->vertex_count;
    e->decoder_vertex[q_pm] = q;
    e->pm_vertex[q] = q_pm;
    size_t predicted = lk__lks2_fan_restore(&w->fan, mesh, p, q);
    if (predicted == SIZE_MAX) return lk_error_set(error, LK_ERR_NOMEM, "out of memory for restored triangles");
    /* The restored triangles in decoder numbers, matched to the prediction. */
    size_t count = split->triangle_count;
    uint32_t actual[3 * 8];
    uint32_t actual_pm[8];
    bool matches = count == predicted && count <= 8;
    if (count > 8) return lk_error_set(error, LK_ERR_INVALID, "split %u restores %zu triangles", (unsigned)k, count);
    for (size_t i = 0; i < count; i++) {
        const uint32_t *full = pm->indices + 3 * ((size_t)split->first_triangle + i);
        for (int c = 0; c < 3; c++) {
            uint32_t v = full[c];
            while (e->decoder_vertex[v] == LKS_NONE) v = parent(e, v);
            actual[3 * i + (size_t)c] = e->decoder_vertex[v];
        }
        actual_pm[i] = split->first_triangle + (uint32_t)i;
    }
    uint32_t order[8];
    bool used[8] = {false};
    for (size_t i = 0; i < predicted && matches; i++) {
        bool found = false;
        for (size_t j = 0; j < count && !found; j++) {
            if (used[j]) continue;
            const uint32_t *a = actual + 3 * j, *b = w->fan.restored + 3 * i;
            for (int r = 0; r < 3 && !found; r++)
                found = a[r] == b[0] && a[(r + 1) % 3] == b[1] && a[(r + 2) % 3] == b[2];
            if (found) used[j] = true, order[i] = (uint32_t)j;
        }
        matches = found;
    }
    lks2_encode_bit(coder, &models->predicted_ok[predicted > 0], matches);
    if (!matches) {
        lks2_encode_uint(coder, &models->escape_count, (uint32_t)count);
        unsigned width = lks2_bit_length(q);
        for (size_t i = 0; i < count; i++) {
            uint32_t third;
            unsigned flipped;
            if (!restored_form(actual + 3 * i, p, q, &third, &flipped))
                return lk_error_set(error, LK_ERR_INVALID, "split %u restores a triangle without both of its vertices",
                                    (unsigned)k);
            lks2_encode_direct(coder, third, width);
            lks2_encode_bit(coder, &models->orientation, flipped);
            order[i] = (uint32_t)i;
        }
    }
    /* Apply as the decoder will. */
    int32_t merged[3];
    memcpy(merged, mesh->quantised + 3 * (size_t)p, sizeof merged);
    lk__lks2_add_vertex(mesh, merged, p);
    for (size_t i = 0; i < fan_size; i++)
        if (moved[i]) lk__lks2_move_corner(mesh, fan[i], p, q);
    for (size_t i = 0; i < count; i++) {
        const uint32_t *t = matches ? w->fan.restored + 3 * i : actual + 3 * order[i];
        uint32_t a = t[0], b = t[1], c = t[2];
        if (!matches) {
            uint32_t third = 0;
            unsigned flipped = 0;
            restored_form(actual + 3 * i, p, q, &third, &flipped);
            a = p, b = flipped ? third : q, c = flipped ? q : third;
        }
        e->pm_triangle[mesh->triangle_count] = actual_pm[order[i]];
        lk__lks2_add_triangle(mesh, a, b, c);
    }
    const int32_t *new_q = e->split_quantised + 3 * (size_t)k, *new_p = e->kept_quantised + 3 * (size_t)k;
    unsigned kind = !memcmp(new_p, merged, sizeof merged)   ? LKS2_NEW_Q
                    : !memcmp(new_q, merged, sizeof merged) ? LKS2_NEW_P
                                                            : LKS2_NEW_BOTH;
    lks2_encode_tree(coder, models->kind, 2, kind);
    int32_t merged_attributes[LKS2_MAX_ATTRIBUTES];
    size_t stride = e->attributes.count;
    if (stride) memcpy(merged_attributes, mesh->attributes + stride * p, stride * sizeof(int32_t));
    if (kind != LKS2_NEW_P)
        write_vertex(e, mesh, coder, models, q, merged, merged_attributes, new_q, stride ? e->q_identity[k] : 0);
    if (kind != LKS2_NEW_Q)
        write_vertex(e, mesh, coder, models, p, merged, merged_attributes, new_p, stride ? e->p_identity[k] : 0);
    return LK_OK;
}

/* The batches [first, last) as one chunk payload. */
static lk_status write_chunk(chunk_writer *w, size_t first, size_t last, lks2_encoder *coder, lk_error *error)
{
    lks2_encoding *e = w->e;
    lks2_models *models = &w->models;
    for (size_t b = first; b < last; b++) {
        size_t start = e->batch_start[b], size = e->batch_start[b + 1] - start;
        for (size_t i = 0; i < size; i++) {
            uint32_t k = e->order[start + i];
            w->items[i].key = e->decoder_vertex[e->pm->splits[k].kept];
            w->items[i].split = k;
        }
        qsort(w->items, size, sizeof *w->items, compare_items);
        lks2_encode_uint(coder, &models->batch_size, (uint32_t)(size - 1));
        w->serial++;
        uint32_t cursor = 0;
        for (size_t i = 0; i < size; i++) {
            uint32_t p = w->items[i].key;
            if (w->stamp[p] == w->serial)
                return lk_error_set(error, LK_ERR_INVALID, "internal: split vertex %u excluded from its batch",
                                    (unsigned)p);
            /* One bit per vertex not yet excluded, up to p. */
            for (uint32_t v = cursor; v <= p; v++)
                if (w->stamp[v] != w->serial)
                    lks2_encode_bit(coder, &models->split[lk__lks2_split_context(w->mesh, v)], v == p);
            lk__lks2_exclude(w->mesh, p, w->stamp, w->serial);
            cursor = p + 1;
        }
        for (size_t i = 0; i < size; i++) {
            lk_status status = write_split(w, coder, models, w->items[i].split, error);
            if (status != LK_OK) return status;
        }
    }
    return LK_OK;
}

/* Quantises the input's attributes and works out whose attributes every
 * vertex shows after every split: at the full level each vertex is its own
 * input vertex; undoing a split whose p took q's position (endpoint
 * placement kept q's end) gives p q's identity. */
static lk_status prepare_attributes(lks2_encoding *e, const lk_mesh *input, unsigned normal_bits,
                                    unsigned texcoord_bits, lk_error *error)
{
    const lk_progressive_mesh *pm = e->pm;
    lks2_attributes *a = &e->attributes;
    memset(a, 0, sizeof *a);
    if (!input || !pm->vertex_order) return LK_OK;
    a->flags = (input->normals ? LKS2_FLAG_NORMALS : 0u) | (input->texcoords ? LKS2_FLAG_TEXCOORDS : 0u) |
               (input->colors ? LKS2_FLAG_COLORS : 0u);
    if (!a->flags) return LK_OK;
    for (size_t v = 0; v < pm->vertex_count; v++)
        if (pm->vertex_order[v] >= input->vertex_count)
            return lk_error_set(error, LK_ERR_INVALID, "progressive mesh vertex %zu comes from input vertex %u of %zu",
                                v, (unsigned)pm->vertex_order[v], input->vertex_count);
    a->normal_bits = normal_bits ? normal_bits : 10;
    a->texcoord_bits = texcoord_bits ? texcoord_bits : 12;
    if (a->flags & LKS2_FLAG_TEXCOORDS) {
        float min[3] = {0, 0, 0}, max[3] = {0, 0, 0}, step[3];
        bool any = false;
        for (size_t v = 0; v < input->vertex_count; v++)
            for (int axis = 0; axis < 2; axis++) {
                float value = input->texcoords[2 * v + (size_t)axis];
                if (!isfinite(value)) continue;
                if (!any || value < min[axis]) min[axis] = value;
                if (!any || value > max[axis]) max[axis] = value;
                if (axis == 1) any = true;
            }
        lk__lks_steps(min, max, a->texcoord_bits, step);
        for (int axis = 0; axis < 2; axis++) a->texcoord_min[axis] = min[axis], a->texcoord_step[axis] = step[axis];
    }
    lk__lks2_attributes_layout(a);
    size_t stride = a->count;
    e->input_attributes = lk__malloc_array(input->vertex_count ? input->vertex_count : 1, stride * sizeof(int32_t));
    e->base_identity = lk__malloc_array(pm->vertex_count ? pm->vertex_count : 1, sizeof(uint32_t));
    e->p_identity = lk__malloc_array(e->splits ? e->splits : 1, sizeof(uint32_t));
    e->q_identity = lk__malloc_array(e->splits ? e->splits : 1, sizeof(uint32_t));
    int32_t *current = lk__malloc_array(pm->vertex_count ? pm->vertex_count : 1, 3 * sizeof(int32_t));
    unsigned char *took_q = lk__malloc_array(e->splits ? e->splits : 1, 1);
    if (!e->input_attributes || !e->base_identity || !e->p_identity || !e->q_identity || !current || !took_q) {
        free(current);
        free(took_q);
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory for vertex attributes");
    }
    for (size_t v = 0; v < input->vertex_count; v++) {
        int32_t *out = e->input_attributes + stride * v;
        size_t c = 0;
        if (a->flags & LKS2_FLAG_NORMALS) {
            lk__lks2_encode_normal(input->normals + 3 * v, a->normal_bits, out + c);
            c += 2;
        }
        if (a->flags & LKS2_FLAG_TEXCOORDS) {
            for (int axis = 0; axis < 2; axis++)
                out[c + (size_t)axis] = lk__lks_quantise(input->texcoords[2 * v + (size_t)axis], a->texcoord_min[axis],
                                                         a->texcoord_step[axis], a->top[c]);
            c += 2;
        }
        if (a->flags & LKS2_FLAG_COLORS)
            for (int channel = 0; channel < 4; channel++) {
                float value = input->colors[4 * v + (size_t)channel];
                value = value > 0 ? (value < 1 ? value : 1) : 0; /* NaN too */
                out[c++] = (int32_t)floorf(value * 255.0f + 0.5f);
            }
    }
    /* Which splits give p q's old position (kind LKS2_NEW_P): replayed in
     * refinement order, as the decoder sees it. */
    memcpy(current, e->base_quantised, e->base * 3 * sizeof(int32_t));
    for (size_t k = 0; k < e->splits; k++) {
        uint32_t p = pm->splits[k].kept, q = (uint32_t)(e->base + k);
        const int32_t *merged = current + 3 * (size_t)p;
        const int32_t *new_p = e->kept_quantised + 3 * k, *new_q = e->split_quantised + 3 * k;
        took_q[k] = memcmp(new_p, merged, 3 * sizeof(int32_t)) != 0 && memcmp(new_q, merged, 3 * sizeof(int32_t)) == 0;
        memcpy(current + 3 * (size_t)q, new_q, 3 * sizeof(int32_t));
        memcpy(current + 3 * (size_t)p, new_p, 3 * sizeof(int32_t));
    }
    uint32_t *identity = e->base_identity; /* over PM vertices, from the full level down */
    for (size_t v = 0; v < pm->vertex_count; v++) identity[v] = pm->vertex_order[v];
    for (size_t k = e->splits; k-- > 0;) {
        uint32_t p = pm->splits[k].kept, q = (uint32_t)(e->base + k);
        e->p_identity[k] = identity[p];
        e->q_identity[k] = identity[q];
        if (took_q[k]) identity[p] = identity[q];
    }
    free(current);
    free(took_q);
    return LK_OK;
}

static lk_status check_inputs(const lk_progressive_mesh *pm, unsigned position_bits, lk_error *error)
{
    if (position_bits != 0 && (position_bits < 4 || position_bits > 24))
        return lk_error_set(error, LK_ERR_INVALID, "position_bits %u: use 0 (automatic) or 4..24", position_bits);
    if (pm->vertex_count > LK_MAX_ELEMENTS || pm->triangle_count > LK_MAX_ELEMENTS)
        return lk_error_set(error, LK_ERR_LIMIT, "progressive mesh too large for a stream");
    if (pm->base_vertex_count > pm->vertex_count || pm->split_count != pm->vertex_count - pm->base_vertex_count)
        return lk_error_set(error, LK_ERR_INVALID, "progressive mesh: %zu vertices is not base %zu + %zu splits",
                            pm->vertex_count, pm->base_vertex_count, pm->split_count);
    if ((pm->base_vertex_count && !pm->base_positions) || (pm->split_count && !pm->splits) ||
        (pm->triangle_count && !pm->indices))
        return lk_error_set(error, LK_ERR_INVALID, "progressive mesh without its arrays");
    for (size_t k = 0; k < pm->split_count; k++)
        if (pm->splits[k].kept >= pm->base_vertex_count + k)
            return lk_error_set(error, LK_ERR_INVALID, "split %zu: kept vertex %u is not present before the split", k,
                                (unsigned)pm->splits[k].kept);
    for (size_t i = 0; i < 3 * pm->triangle_count; i++)
        if (pm->indices[i] >= pm->vertex_count)
            return lk_error_set(error, LK_ERR_INVALID, "triangle %zu names vertex %u of %zu", i / 3,
                                (unsigned)pm->indices[i], pm->vertex_count);
    return LK_OK;
}

static lk_status finish_payload(lks2_encoder *coder, unsigned char **stored, size_t *stored_size, lk_error *error)
{
    lks2_encoder_flush(coder);
    if (coder->failed) {
        lk__buffer_free(&coder->out);
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory writing a stream chunk");
    }
    *stored_size = coder->out.size;
    *stored = lk__buffer_take(&coder->out);
    return LK_OK;
}

lk_status lk__lks2_encode(const lk_progressive_mesh *pm, const lk_mesh *input, const lk_stream_options *options,
                          unsigned char **bytes, size_t *size, uint32_t **vertex_map, lk_error *error)
{
    return lk__lks2_encode_framed(pm, input, options, true, bytes, size, vertex_map, error);
}

lk_status lk__lks2_encode_framed(const lk_progressive_mesh *pm, const lk_mesh *input, const lk_stream_options *options,
                                 bool ring_frame, unsigned char **bytes, size_t *size, uint32_t **vertex_map,
                                 lk_error *error)
{
    unsigned position_bits = options->position_bits;
    if (!pm || !bytes || !size) return lk_error_set(error, LK_ERR_INVALID, "lk__lks2_encode: NULL argument");
    *bytes = NULL;
    *size = 0;
    if (vertex_map) *vertex_map = NULL;
    lk_status status = check_inputs(pm, position_bits, error);
    if (status != LK_OK) return status;

    lks_header header;
    memset(&header, 0, sizeof header);
    lk_stream_info *info = &header.info;
    status = lk__lks_choose_quantisation(pm, position_bits, info->quantisation_min, info->quantisation_step,
                                         &info->position_bits, error);
    if (status != LK_OK) return status;
    header.quantised_max = (int32_t)((1u << info->position_bits) - 1);
    info->version = LKS2_VERSION;
    info->vertex_count = pm->vertex_count;
    info->base_vertex_count = pm->base_vertex_count;
    info->split_count = pm->split_count;
    info->quantisation_error =
        lk__lks_quantisation_error(info->quantisation_min, info->quantisation_step, info->position_bits);
    info->diagonal = isfinite(pm->diagonal) && pm->diagonal >= 0 ? pm->diagonal : 0;

    lks2_encoding e;
    memset(&e, 0, sizeof e);
    e.pm = pm;
    e.base = pm->base_vertex_count;
    e.splits = pm->split_count;
    e.top = header.quantised_max;
    lks2_mesh mesh = {0};
    chunk_writer writer = {0};
    lk_stream_chunk_info *chunks = NULL;
    unsigned char **stored = NULL;
    size_t *stored_sizes = NULL;
    size_t chunk_count = 0;
    e.base_quantised = lk__malloc_array(e.base, 3 * sizeof(int32_t));
    e.split_quantised = lk__malloc_array(e.splits, 3 * sizeof(int32_t));
    e.kept_quantised = lk__malloc_array(e.splits, 3 * sizeof(int32_t));
    e.pm_triangle = lk__malloc_array(pm->triangle_count, sizeof(uint32_t));
    if ((e.base && !e.base_quantised) || (e.splits && (!e.split_quantised || !e.kept_quantised)) ||
        (pm->triangle_count && !e.pm_triangle)) {
        status = lk_error_set(error, LK_ERR_NOMEM, "out of memory encoding a stream");
        goto done;
    }
    const float *min = info->quantisation_min, *step = info->quantisation_step;
    for (size_t v = 0; v < e.base; v++)
        for (int axis = 0; axis < 3; axis++)
            e.base_quantised[3 * v + axis] =
                lk__lks_quantise(pm->base_positions[3 * v + axis], min[axis], step[axis], e.top);
    for (size_t k = 0; k < e.splits; k++)
        for (int axis = 0; axis < 3; axis++) {
            e.split_quantised[3 * k + axis] =
                lk__lks_quantise(pm->splits[k].position[axis], min[axis], step[axis], e.top);
            e.kept_quantised[3 * k + axis] =
                lk__lks_quantise(pm->splits[k].kept_position[axis], min[axis], step[axis], e.top);
        }
    status = prepare_attributes(&e, input, (unsigned)options->normal_bits, (unsigned)options->texcoord_bits, error);
    header.flags = e.attributes.flags | (ring_frame ? LKS2_FLAG_RING_FRAME : 0u);
    mesh.attribute_count = e.attributes.count;
    if (status == LK_OK) status = compute_sets(&e, error);
    if (status == LK_OK) status = schedule(&e, error);
    if (status == LK_OK) status = lk__lks2_mesh_reserve(&mesh, pm->vertex_count, pm->triangle_count, error);
    if (status != LK_OK) goto done;
    mesh.hint_shift = info->position_bits > 12 ? info->position_bits - 12 : 0;
    mesh.ring_frame = ring_frame;

    /* Chunks: the base, then batches until the vertex count has grown by
     * CHUNK_GROWTH. */
    size_t most_chunks = 1 + e.batch_count;
    chunks = lk__calloc_array(most_chunks, sizeof *chunks);
    stored = lk__calloc_array(most_chunks, sizeof *stored);
    stored_sizes = lk__calloc_array(most_chunks, sizeof *stored_sizes);
    writer.e = &e;
    writer.mesh = &mesh;
    lk__lks2_models_init(&writer.models); /* once: split chunks carry them on */
    writer.stamp = lk__calloc_array(pm->vertex_count, sizeof(uint32_t));
    writer.items = lk__malloc_array(e.splits ? e.splits : 1, sizeof(sort_item));
    if (!chunks || !stored || !stored_sizes || !writer.stamp || !writer.items) {
        status = lk_error_set(error, LK_ERR_NOMEM, "out of memory encoding a stream");
        goto done;
    }
    lks2_encoder coder;
    lks2_encoder_init(&coder);
    if (!write_base(&e, &mesh, &coder)) {
        lk__buffer_free(&coder.out);
        status = lk_error_set(error, LK_ERR_NOMEM, "out of memory encoding a stream");
        goto done;
    }
    status = finish_payload(&coder, &stored[0], &stored_sizes[0], error);
    if (status != LK_OK) goto done;
    chunks[0].is_base = 1;
    chunks[0].triangle_count = (uint32_t)mesh.triangle_count;
    chunks[0].raw_size = (uint32_t)stored_sizes[0];
    info->base_triangle_count = mesh.triangle_count;
    chunk_count = 1;
    size_t batch = 0, done_splits = 0;
    while (batch < e.batch_count) {
        size_t first = batch, start_vertices = mesh.vertex_count;
        while (batch < e.batch_count &&
               (batch == first || (double)(e.base + e.batch_start[batch]) < CHUNK_GROWTH * (double)start_vertices))
            batch++;
        lks2_encoder_init(&coder);
        status = write_chunk(&writer, first, batch, &coder, error);
        if (status == LK_OK) status = finish_payload(&coder, &stored[chunk_count], &stored_sizes[chunk_count], error);
        if (status != LK_OK) {
            lk__buffer_free(&coder.out);
            goto done;
        }
        lk_stream_chunk_info *chunk = &chunks[chunk_count++];
        chunk->first_split = (uint32_t)done_splits;
        chunk->split_count = e.batch_start[batch] - e.batch_start[first];
        done_splits += chunk->split_count;
        chunk->triangle_count = (uint32_t)mesh.triangle_count;
        chunk->raw_size = (uint32_t)stored_sizes[chunk_count - 1];
    }
    info->triangle_count = mesh.triangle_count;
    info->chunk_count = chunk_count;
    if (mesh.triangle_count != pm->triangle_count) {
        status = lk_error_set(error, LK_ERR_INVALID, "stream self-check failed: %zu triangles written of %zu",
                              mesh.triangle_count, pm->triangle_count);
        goto done;
    }
    status = lk__lks_assemble(&header, chunks, stored, stored_sizes, bytes, size, error);
    if (status != LK_OK) goto done;
    status = lk__lks2_check(*bytes, *size, &mesh, error);
    if (status == LK_OK && vertex_map) {
        *vertex_map = lk__malloc_array(pm->vertex_count ? pm->vertex_count : 1, sizeof(uint32_t));
        if (!*vertex_map)
            status = lk_error_set(error, LK_ERR_NOMEM, "out of memory for a vertex map");
        else
            for (size_t d = 0; d < pm->vertex_count; d++)
                (*vertex_map)[d] = pm->vertex_order ? pm->vertex_order[e.pm_vertex[d]] : e.pm_vertex[d];
    }
    if (status != LK_OK) {
        free(*bytes);
        *bytes = NULL;
        *size = 0;
    }
done:
    if (stored)
        for (size_t c = 0; c < chunk_count; c++) free(stored[c]);
    free(stored);
    free(stored_sizes);
    free(chunks);
    free(writer.stamp);
    free(writer.items);
    lk__lks2_fan_free(&writer.fan);
    lk__lks2_mesh_free(&mesh);
    encoding_free(&e);
    return status;
}
