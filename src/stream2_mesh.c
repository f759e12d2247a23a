/* SPDX-License-Identifier: MIT */
/* The mesh a version-2 stream decoder builds (stream2_internal.h): vertices
 * with quantised positions, triangles, and per vertex a linked list of its
 * corners, so a vertex split touches only the triangles around one vertex.
 * The encoder runs the same code, so vertex and triangle numbers, fans,
 * contexts and predictions agree bit for bit. */
#include "stream2_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void lk__lks2_mesh_free(lks2_mesh *mesh)
{
    free(mesh->quantised);
    free(mesh->head);
    free(mesh->valence);
    free(mesh->corners);
    free(mesh->next_corner);
    free(mesh->attributes);
    memset(mesh, 0, sizeof *mesh);
}

lk_status lk__lks2_mesh_reserve(lks2_mesh *mesh, size_t vertex_count, size_t triangle_count, lk_error *error)
{
    if (vertex_count > mesh->vertex_capacity) {
        int32_t *quantised = lk__realloc_array(mesh->quantised, vertex_count, 3 * sizeof(int32_t));
        if (quantised) mesh->quantised = quantised;
        if (mesh->attribute_count) {
            int32_t *attributes =
                lk__realloc_array(mesh->attributes, vertex_count, mesh->attribute_count * sizeof(int32_t));
            if (!attributes)
                return lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu stream vertices", vertex_count);
            mesh->attributes = attributes;
        }
        uint32_t *head = lk__realloc_array(mesh->head, vertex_count, sizeof(uint32_t));
        if (head) mesh->head = head;
        uint32_t *valence = lk__realloc_array(mesh->valence, vertex_count, sizeof(uint32_t));
        if (valence) mesh->valence = valence;
        if (!quantised || !head || !valence)
            return lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu stream vertices", vertex_count);
        mesh->vertex_capacity = vertex_count;
    }
    if (triangle_count > mesh->triangle_capacity) {
        uint32_t *corners = lk__realloc_array(mesh->corners, triangle_count, 3 * sizeof(uint32_t));
        if (corners) mesh->corners = corners;
        uint32_t *next = lk__realloc_array(mesh->next_corner, triangle_count, 3 * sizeof(uint32_t));
        if (next) mesh->next_corner = next;
        if (!corners || !next)
            return lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu stream triangles", triangle_count);
        mesh->triangle_capacity = triangle_count;
    }
    return LK_OK;
}

uint32_t lk__lks2_add_vertex(lks2_mesh *mesh, const int32_t position[3], uint32_t like)
{
    uint32_t v = (uint32_t)mesh->vertex_count++;
    memcpy(mesh->quantised + 3 * (size_t)v, position, 3 * sizeof(int32_t));
    mesh->head[v] = LKS_NONE;
    mesh->valence[v] = 0;
    size_t stride = mesh->attribute_count;
    if (stride && like != LKS_NONE)
        memcpy(mesh->attributes + stride * v, mesh->attributes + stride * like, stride * sizeof(int32_t));
    else if (stride)
        memset(mesh->attributes + stride * v, 0, stride * sizeof(int32_t));
    return v;
}

void lk__lks2_add_triangle(lks2_mesh *mesh, uint32_t a, uint32_t b, uint32_t c)
{
    size_t t = mesh->triangle_count++;
    uint32_t vertices[3] = {a, b, c};
    for (int k = 0; k < 3; k++) {
        uint32_t corner = (uint32_t)(3 * t + (size_t)k);
        mesh->corners[corner] = vertices[k];
        mesh->next_corner[corner] = mesh->head[vertices[k]];
        mesh->head[vertices[k]] = corner;
        mesh->valence[vertices[k]]++;
    }
}

size_t lk__lks2_vertex_triangles(const lks2_mesh *mesh, uint32_t v, uint32_t *out, size_t capacity)
{
    size_t count = 0;
    for (uint32_t corner = mesh->head[v]; corner != LKS_NONE; corner = mesh->next_corner[corner]) {
        if (count < capacity) out[count] = corner / 3;
        count++;
    }
    return count;
}

/* The vertex of triangle t after v (and before v) in drawing order. */
static uint32_t after(const lks2_mesh *mesh, uint32_t t, uint32_t v)
{
    const uint32_t *c = mesh->corners + 3 * (size_t)t;
    return c[0] == v ? c[1] : c[1] == v ? c[2] : c[0];
}
static uint32_t before(const lks2_mesh *mesh, uint32_t t, uint32_t v)
{
    const uint32_t *c = mesh->corners + 3 * (size_t)t;
    return c[0] == v ? c[2] : c[1] == v ? c[0] : c[1];
}

static int compare_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return (x > y) - (x < y);
}

/* Fans of up to this many triangles are ordered through small hash tables
 * in O(count); larger ones (rare: a vertex of valence above 32) compare
 * every pair. Both give the same order. */
#define FAN_HASHED_MAX 32u

/* Slot of vertex w in a table of `mask + 1` slots (a power of two). */
static uint32_t fan_slot(uint32_t w, uint32_t mask) { return (w * 0x9E3779B1u >> 16) & mask; }

/* The chain's steps through hash tables: `previous_at` maps each triangle's
 * `previous` vertex to its index (false when two triangles share one: the
 * caller then compares pairs), `next_seen` holds every `next`. */
static bool order_fan_hashed(const uint32_t *next, const uint32_t *previous, size_t count, size_t *start,
                             size_t *openings, uint32_t *following)
{
    uint32_t keys[2 * FAN_HASHED_MAX], indices[2 * FAN_HASHED_MAX], seen[2 * FAN_HASHED_MAX];
    uint32_t size = 8;
    while (size < 2 * count) size *= 2;
    uint32_t mask = size - 1;
    for (uint32_t i = 0; i < size; i++) keys[i] = LKS_NONE, seen[i] = LKS_NONE;
    for (size_t i = 0; i < count; i++) {
        uint32_t slot = fan_slot(previous[i], mask);
        while (keys[slot] != LKS_NONE) {
            if (keys[slot] == previous[i]) return false;
            slot = (slot + 1) & mask;
        }
        keys[slot] = previous[i];
        indices[slot] = (uint32_t)i;
        slot = fan_slot(next[i], mask);
        while (seen[slot] != LKS_NONE && seen[slot] != next[i]) slot = (slot + 1) & mask;
        seen[slot] = next[i];
    }
    *openings = 0;
    for (size_t i = 0; i < count; i++) {
        /* Led: some triangle's next is this one's previous (never its own:
         * a triangle's three corners differ). */
        uint32_t slot = fan_slot(previous[i], mask);
        while (seen[slot] != LKS_NONE && seen[slot] != previous[i]) slot = (slot + 1) & mask;
        if (seen[slot] == LKS_NONE) *start = i, ++*openings;
        /* The one triangle whose previous is this one's next, if any. */
        following[i] = (uint32_t)count;
        slot = fan_slot(next[i], mask);
        while (keys[slot] != LKS_NONE && keys[slot] != next[i]) slot = (slot + 1) & mask;
        if (keys[slot] != LKS_NONE) following[i] = indices[slot];
    }
    return true;
}

unsigned lk__lks2_order_fan(const lks2_mesh *mesh, uint32_t v, uint32_t *fan, size_t count, uint32_t *scratch)
{
    uint32_t *next = scratch, *previous = scratch + count, *placed = scratch + 2 * count;
    uint32_t following_hashed[FAN_HASHED_MAX];
    for (size_t i = 0; i < count; i++) {
        next[i] = after(mesh, fan[i], v);
        previous[i] = before(mesh, fan[i], v);
        placed[i] = 0;
    }
    /* The chain's first triangle: the one no other triangle leads into
     * (an open fan, at a border), else the lowest numbered (closed). */
    size_t start = count, lowest = 0, openings = 0;
    bool hashed =
        count <= FAN_HASHED_MAX && order_fan_hashed(next, previous, count, &start, &openings, following_hashed);
    for (size_t i = 0; i < count; i++) {
        if (fan[i] < fan[lowest]) lowest = i;
        if (hashed) continue;
        bool led = false;
        for (size_t j = 0; j < count && !led; j++) led = j != i && next[j] == previous[i];
        if (!led) start = i, openings++;
    }
    unsigned shape = openings == 0 ? LKS2_FAN_CLOSED : openings == 1 ? LKS2_FAN_OPEN : LKS2_FAN_UNORDERED;
    if (shape == LKS2_FAN_CLOSED) start = lowest;
    if (shape != LKS2_FAN_UNORDERED) {
        /* Follow the chain; every step must be the one way on. */
        size_t at = start;
        for (size_t done = 0; done < count; done++) {
            placed[at] = 1;
            fan[count + done] = fan[at]; /* the caller gave room for 2 * count */
            if (done + 1 == count) break;
            size_t following = count, ways = 0;
            if (hashed) {
                /* previous values are distinct: at most one way on */
                following = following_hashed[at];
                ways = following < count && !placed[following];
            } else {
                for (size_t j = 0; j < count; j++)
                    if (!placed[j] && previous[j] == next[at]) following = j, ways++;
            }
            if (ways != 1) {
                shape = LKS2_FAN_UNORDERED;
                break;
            }
            at = following;
        }
        if (shape != LKS2_FAN_UNORDERED) memcpy(fan, fan + count, count * sizeof *fan);
    }
    if (shape == LKS2_FAN_UNORDERED) qsort(fan, count, sizeof *fan, compare_u32);
    return shape;
}

void lk__lks2_move_corner(lks2_mesh *mesh, uint32_t t, uint32_t v, uint32_t to)
{
    uint32_t *link = &mesh->head[v];
    while (*link != LKS_NONE && *link / 3 != t) link = &mesh->next_corner[*link];
    if (*link == LKS_NONE) return;
    uint32_t corner = *link;
    *link = mesh->next_corner[corner];
    mesh->valence[v]--;
    mesh->valence[to]++;
    mesh->corners[corner] = to;
    mesh->next_corner[corner] = mesh->head[to];
    mesh->head[to] = corner;
}

void lk__lks2_predict(const lks2_mesh *mesh, uint32_t v, const int32_t fallback[3], int32_t out[3])
{
    int64_t sum[3] = {0, 0, 0};
    int64_t count = 0;
    for (uint32_t corner = mesh->head[v]; corner != LKS_NONE; corner = mesh->next_corner[corner]) {
        uint32_t base = corner - corner % 3;
        for (uint32_t k = 0; k < 3; k++) {
            uint32_t other = mesh->corners[base + k];
            if (other == v) continue;
            for (int axis = 0; axis < 3; axis++) sum[axis] += mesh->quantised[3 * (size_t)other + (size_t)axis];
            count++;
        }
    }
    for (int axis = 0; axis < 3; axis++)
        out[axis] = count ? (int32_t)((2 * sum[axis] + count) / (2 * count)) : fallback[axis];
}

/* The prediction and the ring's frame in one walk of v's corners. The
 * ring's normal is the sum over v's triangles (v, a, b) of (a - c) x (b -
 * c), c the prediction, on positions with the hint's low bits dropped (R =
 * Q >> hint_shift). Since (a - c) x (b - c) = a x b - (a - b) x c, the walk
 * sums a x b and a - b, and c enters once at the end: the same integers
 * (web/stream2.js takes the first form, exact in doubles for fans of fewer
 * than 2^28 triangles). Each product is below 2^24: these 64-bit sums
 * cannot overflow below 2^37 triangles.
 * The normal is then scaled down, truncating towards zero, until its
 * largest component is below 2^15: lk__lks2_frame_offset's products then
 * stay below 2^41 (2^47 in a corrupt stream). */
void lk__lks2_predict_frame(const lks2_mesh *mesh, uint32_t v, const int32_t fallback[3], int32_t predicted[3],
                            lks2_frame *frame)
{
    static const unsigned char after[3] = {1, 2, 0}, before[3] = {2, 0, 1};
    unsigned shift = mesh->hint_shift;
    int64_t sum[3] = {0, 0, 0}, count = 0, cross[3] = {0, 0, 0}, lead[3] = {0, 0, 0};
    for (uint32_t corner = mesh->head[v]; corner != LKS_NONE; corner = mesh->next_corner[corner]) {
        uint32_t k = corner % 3, base = corner - k;
        uint32_t first = mesh->corners[base + after[k]], second = mesh->corners[base + before[k]];
        const int32_t *a = mesh->quantised + 3 * (size_t)first, *b = mesh->quantised + 3 * (size_t)second;
        /* the prediction's sum: the corners other than v (lk__lks2_predict) */
        if (first != v) {
            for (int axis = 0; axis < 3; axis++) sum[axis] += a[axis];
            count++;
        }
        if (second != v) {
            for (int axis = 0; axis < 3; axis++) sum[axis] += b[axis];
            count++;
        }
        int64_t a0 = a[0] >> shift, a1 = a[1] >> shift, a2 = a[2] >> shift;
        int64_t b0 = b[0] >> shift, b1 = b[1] >> shift, b2 = b[2] >> shift;
        cross[0] += a1 * b2 - a2 * b1;
        cross[1] += a2 * b0 - a0 * b2;
        cross[2] += a0 * b1 - a1 * b0;
        lead[0] += a0 - b0, lead[1] += a1 - b1, lead[2] += a2 - b2;
    }
    for (int axis = 0; axis < 3; axis++)
        predicted[axis] = count ? (int32_t)((2 * sum[axis] + count) / (2 * count)) : fallback[axis];
    int64_t c[3] = {predicted[0] >> shift, predicted[1] >> shift, predicted[2] >> shift};
    int64_t n[3] = {cross[0] - (lead[1] * c[2] - lead[2] * c[1]), cross[1] - (lead[2] * c[0] - lead[0] * c[2]),
                    cross[2] - (lead[0] * c[1] - lead[1] * c[0])};
    int normal_axis = 0; /* the largest component; the lowest axis on ties */
    for (int axis = 1; axis < 3; axis++)
        if (llabs(n[axis]) > llabs(n[normal_axis])) normal_axis = axis;
    int64_t largest = llabs(n[normal_axis]), divisor = 1;
    while (largest / divisor >= (1 << 15)) divisor *= 2;
    for (int axis = 0; axis < 3; axis++) frame->normal[axis] = n[axis] / divisor; /* C truncates towards zero */
    frame->axis[0] = (normal_axis + 1) % 3;
    frame->axis[1] = (normal_axis + 2) % 3;
    frame->axis[2] = normal_axis;
}

/* -(n0 * first + n1 * second) / n2, rounded half up (0 when n2 is 0): the
 * third component of a vertex in the plane across the normal whose first
 * two components are `first` and `second`, all relative to the
 * prediction. The quotient lies within |first| + |second| + 1 of 0 (in
 * a corrupt stream up to about 2^32: hence 64 bits). */
int64_t lk__lks2_frame_offset(const lks2_frame *frame, int32_t first, int32_t second)
{
    int64_t n0 = frame->normal[frame->axis[0]], n1 = frame->normal[frame->axis[1]];
    int64_t n2 = frame->normal[frame->axis[2]];
    if (n2 == 0) return 0;
    int64_t across = n0 * first + n1 * second;
    int64_t numerator = n2 > 0 ? -across : across, denominator = n2 > 0 ? n2 : -n2;
    int64_t twice = 2 * numerator + denominator, below = 2 * denominator;
    return twice >= 0 ? twice / below : -((-twice + below - 1) / below); /* floor */
}

void lk__lks2_predict_attributes(const lks2_mesh *mesh, uint32_t v, const int32_t *fallback, int32_t *out)
{
    size_t stride = mesh->attribute_count;
    int64_t sum[LKS2_MAX_ATTRIBUTES] = {0};
    int64_t count = 0;
    for (uint32_t corner = mesh->head[v]; corner != LKS_NONE; corner = mesh->next_corner[corner]) {
        uint32_t base = corner - corner % 3;
        for (uint32_t k = 0; k < 3; k++) {
            uint32_t other = mesh->corners[base + k];
            if (other == v) continue;
            for (size_t c = 0; c < stride; c++) sum[c] += mesh->attributes[stride * other + c];
            count++;
        }
    }
    for (size_t c = 0; c < stride; c++) out[c] = count ? (int32_t)((2 * sum[c] + count) / (2 * count)) : fallback[c];
}

void lk__lks2_attributes_layout(lks2_attributes *attributes)
{
    unsigned count = 0;
    if (attributes->flags & LKS2_FLAG_NORMALS) {
        int32_t top = (int32_t)((1u << attributes->normal_bits) - 1);
        attributes->top[count++] = top;
        attributes->top[count++] = top;
    }
    if (attributes->flags & LKS2_FLAG_TEXCOORDS) {
        int32_t top = (int32_t)((1u << attributes->texcoord_bits) - 1);
        attributes->top[count++] = top;
        attributes->top[count++] = top;
    }
    if (attributes->flags & LKS2_FLAG_COLORS)
        for (int c = 0; c < 4; c++) attributes->top[count++] = 255;
    attributes->count = count;
}

void lk__lks2_encode_normal(const float normal[3], unsigned bits, int32_t out[2])
{
    double x = normal[0], y = normal[1], z = normal[2];
    double sum = fabs(x) + fabs(y) + fabs(z);
    if (!(sum > 0) || !isfinite(sum)) x = 0, y = 0, z = 1, sum = 1;
    x /= sum, y /= sum, z /= sum;
    if (z < 0) {
        double folded_x = (1 - fabs(y)) * (x < 0 ? -1 : 1), folded_y = (1 - fabs(x)) * (y < 0 ? -1 : 1);
        x = folded_x, y = folded_y;
    }
    double top = (double)((1u << bits) - 1);
    out[0] = (int32_t)floor((x * 0.5 + 0.5) * top + 0.5);
    out[1] = (int32_t)floor((y * 0.5 + 0.5) * top + 0.5);
}

void lk__lks2_decode_normal(const int32_t code[2], unsigned bits, float out[3])
{
    double top = (double)((1u << bits) - 1);
    double x = code[0] / top * 2 - 1, y = code[1] / top * 2 - 1;
    double z = 1 - fabs(x) - fabs(y);
    if (z < 0) {
        double unfolded_x = (1 - fabs(y)) * (x < 0 ? -1 : 1), unfolded_y = (1 - fabs(x)) * (y < 0 ? -1 : 1);
        x = unfolded_x, y = unfolded_y;
    }
    double length = sqrt(x * x + y * y + z * z);
    out[0] = (float)(x / length);
    out[1] = (float)(y / length);
    out[2] = (float)(z / length);
}

void lk__lks2_models_init(lks2_models *models)
{
    lks2_probs_init(models->split, LKS2_SPLIT_CONTEXTS);
    lks2_probs_init(models->move, LKS2_MOVE_CONTEXTS);
    lks2_probs_init(models->predicted_ok, 2);
    lks2_probs_init(models->kind, 4);
    lks2_uint_model_init(&models->escape_count);
    models->orientation = LKS2_PROB_INIT;
    for (int axis = 0; axis < 3; axis++) lks2_uint_model_init(&models->residual[axis]);
    lks2_uint_model_init(&models->batch_size);
    for (int c = 0; c < 3; c++) lks2_uint_model_init(&models->corner[c]);
    for (unsigned c = 0; c < LKS2_MAX_ATTRIBUTES; c++) lks2_uint_model_init(&models->attribute[c]);
}

unsigned lk__lks2_split_context(const lks2_mesh *mesh, uint32_t v)
{
    uint32_t count = mesh->valence[v];
    return count < LKS2_SPLIT_CONTEXTS - 1 ? (unsigned)count : LKS2_SPLIT_CONTEXTS - 1;
}

/* True when triangles s and t share a vertex other than v: an edge through v. */
static bool share_edge(const lks2_mesh *mesh, uint32_t v, uint32_t s, uint32_t t)
{
    for (int i = 0; i < 3; i++) {
        uint32_t a = mesh->corners[3 * (size_t)s + (size_t)i];
        if (a == v) continue;
        for (int k = 0; k < 3; k++)
            if (mesh->corners[3 * (size_t)t + (size_t)k] == a) return true;
    }
    return false;
}

/* The context from the decisions alone (0..23). */
static unsigned decision_context(const lks2_mesh *mesh, uint32_t v, const uint32_t *fan, const unsigned char *moved,
                                 size_t index, unsigned shape)
{
    if (index == 0) return shape == LKS2_FAN_UNORDERED ? 0 : shape == LKS2_FAN_OPEN ? 1 : 2;
    if (shape != LKS2_FAN_UNORDERED) {
        /* Along the chain: the previous decision and how many times the
         * decisions changed so far (a split moves one run of triangles). */
        unsigned changes = 0;
        for (size_t j = 1; j < index; j++) changes += moved[j] != moved[j - 1];
        if (changes > 2) changes = 2;
        return 3 + (shape == LKS2_FAN_CLOSED) * 6 + changes * 2 + moved[index - 1];
    }
    unsigned moving = 0, staying = 0;
    for (size_t j = 0; j < index; j++) {
        if (!share_edge(mesh, v, fan[j], fan[index])) continue;
        if (moved[j])
            moving += moving < 2;
        else
            staying += staying < 2;
    }
    return 15 + 3 * moving + staying;
}

unsigned lk__lks2_move_context(const lks2_mesh *mesh, uint32_t v, const lks2_fan *ordered, size_t index)
{
    const uint32_t *fan = ordered->triangles;
    const unsigned char *moved = ordered->moved;
    unsigned shape = ordered->shape;
    return decision_context(mesh, v, fan, moved, index, shape) + 24u * ordered->hint[index];
}

size_t lk__lks2_predict_restored(const lks2_mesh *mesh, uint32_t p, uint32_t q, const uint32_t *fan,
                                 const unsigned char *moved, size_t fan_size, unsigned shape, uint32_t *out,
                                 size_t capacity)
{
    size_t count = 0;
    if (shape != LKS2_FAN_UNORDERED) {
        /* One triangle where the chain passes from a staying triangle to a
         * moving one or back, across their shared edge (p, w). */
        size_t steps = shape == LKS2_FAN_CLOSED ? fan_size : fan_size - 1;
        for (size_t i = 0; i < steps; i++) {
            size_t j = i + 1 == fan_size ? 0 : i + 1;
            if (moved[i] == moved[j]) continue;
            uint32_t w = after(mesh, fan[i], p);
            if (count < capacity) {
                uint32_t *triangle = out + 3 * count;
                triangle[0] = p, triangle[1] = moved[i] ? w : q, triangle[2] = moved[i] ? q : w;
            }
            count++;
        }
        return count;
    }
    for (size_t s = 0; s < fan_size; s++) {
        if (moved[s]) continue;
        const uint32_t *staying = mesh->corners + 3 * (size_t)fan[s];
        for (int i = 0; i < 3; i++) {
            uint32_t w = staying[i];
            if (w == p) continue;
            bool bordered = false;
            for (size_t m = 0; m < fan_size && !bordered; m++) {
                if (!moved[m]) continue;
                const uint32_t *moving = mesh->corners + 3 * (size_t)fan[m];
                bordered = moving[0] == w || moving[1] == w || moving[2] == w;
            }
            if (!bordered) continue;
            if (count < capacity) {
                uint32_t *triangle = out + 3 * count;
                /* The new triangle crosses edge (p, w) the other way round. */
                if (after(mesh, fan[s], p) == w)
                    triangle[0] = p, triangle[1] = q, triangle[2] = w;
                else
                    triangle[0] = p, triangle[1] = w, triangle[2] = q;
            }
            count++;
        }
    }
    return count;
}

void lk__lks2_exclude(const lks2_mesh *mesh, uint32_t v, uint32_t *stamp, uint32_t serial)
{
    stamp[v] = serial;
    for (uint32_t corner = mesh->head[v]; corner != LKS_NONE; corner = mesh->next_corner[corner]) {
        uint32_t base = corner - corner % 3;
        for (uint32_t k = 0; k < 3; k++) stamp[mesh->corners[base + k]] = serial;
    }
}

void lk__lks2_fan_free(lks2_fan *fan)
{
    free(fan->triangles);
    free(fan->moved);
    free(fan->hint);
    free(fan->spoke);
    free(fan->offset);
    free(fan->scratch);
    free(fan->restored);
    memset(fan, 0, sizeof *fan);
}

bool lk__lks2_fan_load(lks2_fan *fan, const lks2_mesh *mesh, uint32_t v)
{
    size_t count = lk__lks2_vertex_triangles(mesh, v, fan->triangles, fan->capacity);
    if (count > fan->capacity) {
        size_t capacity = 2 * count;
        uint32_t *triangles = lk__realloc_array(fan->triangles, 2 * capacity, sizeof(uint32_t));
        if (triangles) fan->triangles = triangles;
        unsigned char *moved = lk__realloc_array(fan->moved, capacity, 1);
        if (moved) fan->moved = moved;
        unsigned char *hint = lk__realloc_array(fan->hint, capacity, 1);
        if (hint) fan->hint = hint;
        int64_t *spoke = lk__realloc_array(fan->spoke, capacity, sizeof(int64_t));
        if (spoke) fan->spoke = spoke;
        int64_t *offset = lk__realloc_array(fan->offset, capacity, 3 * sizeof(int64_t));
        if (offset) fan->offset = offset;
        if (!hint || !spoke || !offset) return false;
        uint32_t *scratch = lk__realloc_array(fan->scratch, 3 * capacity, sizeof(uint32_t));
        if (scratch) fan->scratch = scratch;
        if (!triangles || !moved || !scratch) return false;
        fan->capacity = capacity;
        lk__lks2_vertex_triangles(mesh, v, fan->triangles, fan->capacity);
    }
    fan->count = count;
    fan->shape = lk__lks2_order_fan(mesh, v, fan->triangles, count, fan->scratch);
    /* The split vertex's new neighbour usually lies towards the centroid
     * of the merged ring (the ring is the union of both vertices' rings):
     * triangles on that side are likely to move. */
    /* Positions lose their bits above 12 first, so every product stays
     * below 2^53 (exact in a JavaScript decoder too). */
    unsigned shift = mesh->hint_shift;
    int64_t pv[3], centroid[3] = {0, 0, 0};
    for (int axis = 0; axis < 3; axis++) pv[axis] = mesh->quantised[3 * (size_t)v + (size_t)axis] >> shift;
    /* Per triangle: the sum of its two other corners' offsets from v (its
     * dot product with the centroid is the sum of theirs) and its squared
     * spokes. */
    int64_t *offset = fan->offset, spoke_total = 0;
    for (size_t i = 0; i < count; i++) {
        const uint32_t *corners = mesh->corners + 3 * (size_t)fan->triangles[i];
        int64_t sum[3] = {0, 0, 0}, spoke = 0;
        for (int k = 0; k < 3; k++) {
            uint32_t w = corners[k];
            if (w == v) continue;
            const int32_t *position = mesh->quantised + 3 * (size_t)w;
            for (int axis = 0; axis < 3; axis++) {
                int64_t d = (position[axis] >> shift) - pv[axis];
                sum[axis] += d;
                spoke += d * d;
            }
        }
        for (int axis = 0; axis < 3; axis++) offset[3 * i + (size_t)axis] = sum[axis], centroid[axis] += sum[axis];
        fan->spoke[i] = spoke;
        spoke_total += spoke;
    }
    for (size_t i = 0; i < count; i++) {
        const int64_t *o = offset + 3 * i;
        fan->hint[i] = o[0] * centroid[0] + o[1] * centroid[1] + o[2] * centroid[2] > 0;
    }
    for (size_t i = 0; i < count; i++)
        fan->hint[i] |= (unsigned char)(((int64_t)count * fan->spoke[i] > spoke_total) << 1);
    return true;
}

size_t lk__lks2_fan_restore(lks2_fan *fan, const lks2_mesh *mesh, uint32_t p, uint32_t q)
{
    size_t count = lk__lks2_predict_restored(mesh, p, q, fan->triangles, fan->moved, fan->count, fan->shape,
                                             fan->restored, fan->restored_capacity);
    if (count > fan->restored_capacity) {
        uint32_t *restored = lk__realloc_array(fan->restored, 2 * count, 3 * sizeof(uint32_t));
        if (!restored) return SIZE_MAX;
        fan->restored = restored;
        fan->restored_capacity = 2 * count;
        lk__lks2_predict_restored(mesh, p, q, fan->triangles, fan->moved, fan->count, fan->shape, fan->restored,
                                  fan->restored_capacity);
    }
    return count;
}
