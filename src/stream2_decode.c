/* SPDX-License-Identifier: MIT */
/* Version-2 progressive stream: the decoding core. Mirrors stream2_encode.c
 * symbol by symbol (see the comment at its top and docs/stream-format.md);
 * every value read is checked before it is used, so a corrupt payload
 * gives a message naming its chunk, never a crash. */
#include "bytes.h"
#include "stream2_internal.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static bool read_residual(lks2_decoder *coder, lks2_models *models, const int32_t predicted[3], int32_t top,
                          int32_t out[3])
{
    for (int axis = 0; axis < 3; axis++) {
        uint32_t code;
        if (!lks2_decode_uint(coder, &models->residual[axis], &code)) return false;
        int64_t value = (int64_t)predicted[axis] + lks2_unzigzag32(code);
        if (value < 0 || value > top) return false;
        out[axis] = (int32_t)value;
    }
    return true;
}

/* A split vertex's position in its ring's frame (stream2_encode.c
 * encode_in_frame), each component within 0..top. */
static bool read_in_frame(lks2_decoder *coder, lks2_models *models, const lks2_frame *frame, const int32_t predicted[3],
                          int32_t top, int32_t out[3])
{
    uint32_t codes[3];
    for (int k = 0; k < 3; k++)
        if (!lks2_decode_uint(coder, &models->residual[k], &codes[k])) return false;
    int32_t first = lks2_unzigzag32(codes[0]), second = lks2_unzigzag32(codes[1]);
    int64_t value[3];
    value[frame->axis[0]] = (int64_t)predicted[frame->axis[0]] + first;
    value[frame->axis[1]] = (int64_t)predicted[frame->axis[1]] + second;
    value[frame->axis[2]] =
        (int64_t)predicted[frame->axis[2]] + lk__lks2_frame_offset(frame, first, second) + lks2_unzigzag32(codes[2]);
    for (int axis = 0; axis < 3; axis++) {
        if (value[axis] < 0 || value[axis] > top) return false;
        out[axis] = (int32_t)value[axis];
    }
    return true;
}

static lk_status payload_end(const lks2_decoder *coder, const lks_where *where, lk_error *error)
{
    if (coder->overrun) return lk__lks_chunk_error(error, where, "the payload ends before its last symbol");
    if (coder->position != coder->size)
        return lk__lks_chunk_error(error, where, "%zu bytes left over after the last symbol",
                                   coder->size - coder->position);
    return LK_OK;
}

/* The lk_stream_bits part of attribute component c: normals (2
 * components), texture coordinates (2), colours (4), those present, in
 * that order. */
static unsigned attribute_part(const lks2_attributes *attributes, unsigned c)
{
    if (attributes->flags & LKS2_FLAG_NORMALS) {
        if (c < 2) return LKS2_PART_NORMALS;
        c -= 2;
    }
    if (attributes->flags & LKS2_FLAG_TEXCOORDS) {
        if (c < 2) return LKS2_PART_TEXCOORDS;
    }
    return LKS2_PART_COLORS;
}

/* Attribute residuals against a prediction, each within its range. */
static bool read_attributes(lks2_state *state, lks2_decoder *coder, lks2_models *models,
                            const lks2_attributes *attributes, const int32_t *predicted, int32_t *out)
{
    for (unsigned c = 0; c < attributes->count; c++) {
        uint32_t code;
        bool ok = lks2_decode_uint(coder, &models->attribute[c], &code);
        if (state) lks2_account(state, coder, attribute_part(attributes, c));
        if (!ok) return false;
        int64_t value = (int64_t)predicted[c] + lks2_unzigzag32(code);
        if (value < 0 || value > attributes->top[c]) return false;
        out[c] = (int32_t)value;
    }
    return true;
}

static float decode_float(lks2_decoder *coder)
{
    uint32_t bits = lks2_decode_direct(coder, 32);
    float value;
    memcpy(&value, &bits, sizeof value);
    return value;
}

/* How the attributes are quantised, at the start of the base chunk. */
static bool read_attribute_parameters(lks2_decoder *coder, lks2_attributes *attributes)
{
    if (attributes->flags & LKS2_FLAG_NORMALS) {
        attributes->normal_bits = lks2_decode_direct(coder, 5);
        if (attributes->normal_bits < 4 || attributes->normal_bits > 16) return false;
    }
    if (attributes->flags & LKS2_FLAG_TEXCOORDS) {
        attributes->texcoord_bits = lks2_decode_direct(coder, 5);
        if (attributes->texcoord_bits < 4 || attributes->texcoord_bits > 24) return false;
        for (int axis = 0; axis < 2; axis++) {
            attributes->texcoord_min[axis] = decode_float(coder);
            attributes->texcoord_step[axis] = decode_float(coder);
            double top = (double)attributes->texcoord_min[axis] +
                         (double)((1u << attributes->texcoord_bits) - 1) * attributes->texcoord_step[axis];
            if (!isfinite(attributes->texcoord_min[axis]) || !(attributes->texcoord_step[axis] >= 0) ||
                !(fabs(top) <= FLT_MAX))
                return false;
        }
    }
    lk__lks2_attributes_layout(attributes);
    return true;
}

static lk_status decode_base(lks2_mesh *mesh, lks2_attributes *attributes, const lks_header *header,
                             const unsigned char *payload, size_t size, const lks_where *where, lk_error *error)
{
    const lk_stream_info *info = &header->info;
    size_t base = info->base_vertex_count, triangles = info->base_triangle_count;
    uint32_t *corners = lk__malloc_array(triangles ? 3 * triangles : 1, sizeof(uint32_t));
    if (!corners) return lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu base triangles", triangles);
    lks2_models models;
    lk__lks2_models_init(&models);
    lks2_decoder coder;
    lks2_decoder_init(&coder, payload, size);
    if (!read_attribute_parameters(&coder, attributes)) {
        free(corners);
        return lk__lks_chunk_error(error, where, "attribute quantisation out of range");
    }
    uint32_t next_new = 0;
    for (size_t t = 0; t < triangles; t++) {
        for (int c = 0; c < 3; c++) {
            uint32_t back;
            if (!lks2_decode_uint(&coder, &models.corner[c], &back) || back > next_new ||
                (back == 0 && next_new >= base)) {
                free(corners);
                return lk__lks_chunk_error(error, where, "base triangle %zu: corner %d names no vertex", t, c);
            }
            corners[3 * t + (size_t)c] = back ? next_new - back : next_new++;
        }
        const uint32_t *v = corners + 3 * t;
        if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2]) {
            free(corners);
            return lk__lks_chunk_error(error, where, "base triangle %zu repeats a vertex", t);
        }
    }
    int32_t previous[3] = {0, 0, 0}, previous_attributes[LKS2_MAX_ATTRIBUTES] = {0};
    size_t stride = attributes->count;
    for (size_t d = 0; d < base; d++) {
        int32_t position[3];
        if (!read_residual(&coder, &models, previous, header->quantised_max, position)) {
            free(corners);
            return lk__lks_chunk_error(error, where, "base vertex %zu: position outside the quantisation grid", d);
        }
        memcpy(previous, position, sizeof previous);
        lk__lks2_add_vertex(mesh, position, LKS_NONE);
        if (stride) {
            int32_t *values = mesh->attributes + stride * d;
            if (!read_attributes(NULL, &coder, &models, attributes, previous_attributes, values)) {
                free(corners);
                return lk__lks_chunk_error(error, where, "base vertex %zu: attribute out of range", d);
            }
            memcpy(previous_attributes, values, stride * sizeof(int32_t));
        }
    }
    for (size_t t = 0; t < triangles; t++)
        lk__lks2_add_triangle(mesh, corners[3 * t], corners[3 * t + 1], corners[3 * t + 2]);
    free(corners);
    return payload_end(&coder, where, error);
}

typedef struct split_scratch {
    lks2_fan fan;
    uint32_t *escaped; /* 3 per restored triangle named explicitly */
    size_t escaped_capacity;
    uint32_t *batch;
    size_t batch_capacity;
} split_scratch;

static void scratch_free(split_scratch *s)
{
    lk__lks2_fan_free(&s->fan);
    free(s->escaped);
    free(s->batch);
}

static bool grow(void **array, size_t *capacity, size_t needed, size_t size)
{
    if (needed <= *capacity) return true;
    size_t capacity_new = needed < 16 ? 16 : 2 * needed;
    void *grown = lk__realloc_array(*array, capacity_new, size);
    if (!grown) return false;
    *array = grown;
    *capacity = capacity_new;
    return true;
}

/* Vertex v's new position and attributes (stream2_encode.c write_vertex). */
static bool read_vertex(lks2_state *state, lks2_decoder *coder, lks2_models *models, uint32_t v,
                        const int32_t merged[3], const int32_t *merged_attributes, int32_t top)
{
    lks2_mesh *mesh = &state->mesh;
    int32_t predicted[LKS2_MAX_ATTRIBUTES > 3 ? LKS2_MAX_ATTRIBUTES : 3], position[3];
    bool ok;
    if (mesh->ring_frame) {
        lks2_frame frame;
        lk__lks2_predict_frame(mesh, v, merged, predicted, &frame);
        ok = read_in_frame(coder, models, &frame, predicted, top, position);
    } else {
        lk__lks2_predict(mesh, v, merged, predicted);
        ok = read_residual(coder, models, predicted, top, position);
    }
    lks2_account(state, coder, LKS2_PART_POSITIONS);
    if (!ok) return false;
    memcpy(mesh->quantised + 3 * (size_t)v, position, sizeof position);
    size_t stride = state->attributes.count;
    if (!stride) return true;
    lk__lks2_predict_attributes(mesh, v, merged_attributes, predicted);
    return read_attributes(state, coder, models, &state->attributes, predicted, mesh->attributes + stride * v);
}

/* One split at decoder vertex p. */
static lk_status read_split(lks2_state *state, split_scratch *s, lks2_decoder *coder, lks2_models *models, uint32_t p,
                            int32_t top, const lks_where *where, lk_error *error)
{
    lks2_mesh *mesh = &state->mesh;
    if (!lk__lks2_fan_load(&s->fan, mesh, p))
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory for the fan of vertex %u", (unsigned)p);
    size_t fan_size = s->fan.count;
    const uint32_t *fan = s->fan.triangles;
    unsigned char *moved = s->fan.moved;
    for (size_t i = 0; i < fan_size; i++)
        moved[i] = (unsigned char)lks2_decode_bit(coder, &models->move[lk__lks2_move_context(mesh, p, &s->fan, i)]);
    lks2_account(state, coder, LKS2_PART_MOVES);
    uint32_t q = (uint32_t)mesh->vertex_count;
    size_t predicted = lk__lks2_fan_restore(&s->fan, mesh, p, q);
    if (predicted == SIZE_MAX) return lk_error_set(error, LK_ERR_NOMEM, "out of memory for restored triangles");
    const uint32_t *restored = s->fan.restored;
    size_t count = predicted;
    if (!lks2_decode_bit(coder, &models->predicted_ok[predicted > 0])) {
        uint32_t escaped;
        if (!lks2_decode_uint(coder, &models->escape_count, &escaped) || escaped > 8)
            return lk__lks_chunk_error(error, where, "split of vertex %u: bad restored triangle count", (unsigned)p);
        count = escaped;
        if (!grow((void **)&s->escaped, &s->escaped_capacity, 3 * count + 1, sizeof(uint32_t)))
            return lk_error_set(error, LK_ERR_NOMEM, "out of memory for restored triangles");
        restored = s->escaped;
        unsigned width = lks2_bit_length(q);
        for (size_t i = 0; i < count; i++) {
            uint32_t third = lks2_decode_direct(coder, width);
            unsigned flipped = lks2_decode_bit(coder, &models->orientation);
            if (third >= q || third == p)
                return lk__lks_chunk_error(error, where, "split of vertex %u: restored triangle names vertex %u",
                                           (unsigned)p, (unsigned)third);
            uint32_t *t = s->escaped + 3 * i;
            t[0] = p, t[1] = flipped ? third : q, t[2] = flipped ? q : third;
        }
    }
    if (mesh->triangle_count + count > mesh->triangle_capacity)
        return lk__lks_chunk_error(error, where, "more triangles than the header and the chunk's splits allow (%zu)",
                                   mesh->triangle_capacity);
    size_t moving = 0;
    for (size_t i = 0; i < fan_size; i++) moving += moved[i];
    size_t stride = state->attributes.count;
    if (!grow((void **)&state->splits, &state->split_capacity, state->split_count + 1, sizeof *state->splits) ||
        !grow((void **)&state->moved, &state->moved_capacity, state->moved_count + moving, sizeof(uint32_t)) ||
        (stride && !grow((void **)&state->old_attributes, &state->old_attributes_capacity,
                         stride * (state->split_count + 1), sizeof(int32_t))))
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory for the undo log");
    int32_t merged[3];
    memcpy(merged, mesh->quantised + 3 * (size_t)p, sizeof merged);
    lks2_undo_split *undo = &state->splits[state->split_count++];
    undo->p = p;
    undo->triangles_before = (uint32_t)mesh->triangle_count;
    undo->moved_start = (uint32_t)state->moved_count;
    memcpy(undo->old_position, merged, sizeof merged);
    int32_t merged_attributes[LKS2_MAX_ATTRIBUTES];
    if (stride) {
        memcpy(merged_attributes, mesh->attributes + stride * p, stride * sizeof(int32_t));
        memcpy(state->old_attributes + stride * (state->split_count - 1), merged_attributes, stride * sizeof(int32_t));
    }
    lk__lks2_add_vertex(mesh, merged, p);
    for (size_t i = 0; i < fan_size; i++)
        if (moved[i]) {
            lk__lks2_move_corner(mesh, fan[i], p, q);
            state->moved[state->moved_count++] = fan[i];
        }
    for (size_t i = 0; i < count; i++) {
        const uint32_t *t = restored + 3 * i;
        lk__lks2_add_triangle(mesh, t[0], t[1], t[2]);
    }
    unsigned kind = lks2_decode_tree(coder, models->kind, 2);
    lks2_account(state, coder, LKS2_PART_RESTORED);
    if (kind > LKS2_NEW_BOTH)
        return lk__lks_chunk_error(error, where, "split of vertex %u: bad kind %u", (unsigned)p, kind);
    if (kind != LKS2_NEW_P && !read_vertex(state, coder, models, q, merged, merged_attributes, top))
        return lk__lks_chunk_error(error, where, "vertex %u: position or attribute out of range", (unsigned)q);
    if (kind != LKS2_NEW_Q && !read_vertex(state, coder, models, p, merged, merged_attributes, top))
        return lk__lks_chunk_error(error, where, "vertex %u: position or attribute out of range", (unsigned)p);
    return LK_OK;
}

/* Takes back the splits logged since the chunk began, last first. */
static void undo_chunk(lks2_state *state)
{
    lks2_mesh *mesh = &state->mesh;
    while (state->split_count > state->chunk_split_start) {
        const lks2_undo_split *undo = &state->splits[--state->split_count];
        uint32_t q = (uint32_t)(mesh->vertex_count - 1);
        while (mesh->triangle_count > undo->triangles_before) {
            uint32_t t = (uint32_t)--mesh->triangle_count;
            for (uint32_t k = 0; k < 3; k++) {
                uint32_t corner = 3 * t + k;
                uint32_t *link = &mesh->head[mesh->corners[corner]];
                while (*link != corner) link = &mesh->next_corner[*link];
                *link = mesh->next_corner[corner];
                mesh->valence[mesh->corners[corner]]--;
            }
        }
        while (state->moved_count > undo->moved_start)
            lk__lks2_move_corner(mesh, state->moved[--state->moved_count], q, undo->p);
        memcpy(mesh->quantised + 3 * (size_t)undo->p, undo->old_position, sizeof undo->old_position);
        size_t stride = state->attributes.count;
        if (stride)
            memcpy(mesh->attributes + stride * undo->p, state->old_attributes + stride * state->split_count,
                   stride * sizeof(int32_t));
        mesh->vertex_count--;
    }
    state->moved_count = state->chunk_moved_start;
}

/* Applies the first `limit` splits of a chunk, or leaves the state as it was. */
static lk_status apply_chunk(lks2_state *state, const lks_header *header, const lk_stream_chunk_info *chunk,
                             const unsigned char *payload, size_t size, size_t limit, const lks_where *where,
                             lk_error *error)
{
    size_t split_count = chunk->split_count;
    lks2_mesh *mesh = &state->mesh;
    if (mesh->vertex_count + split_count > mesh->vertex_capacity)
        return lk__lks_chunk_error(error, where, "more vertices than the chunk table allows (%zu)",
                                   mesh->vertex_capacity);
    /* The models go on from the previous split chunk (reset at the first);
     * a chunk taken back takes its updates back too. */
    if (!state->models_started) lk__lks2_models_init(&state->models), state->models_started = true;
    lks2_models *models = &state->models, before = state->models;
    lks2_decoder coder;
    lks2_decoder_init(&coder, payload, size);
    state->account_mark = lks2_decoder_bits(&coder);
    split_scratch scratch = {0};
    lk_status status = LK_OK;
    size_t applied = 0;
    if (!state->keep_log) state->split_count = 0, state->moved_count = 0;
    state->chunk_split_start = state->split_count;
    state->chunk_moved_start = state->moved_count;
    while (applied < limit && status == LK_OK) {
        uint32_t batch_size;
        if (!lks2_decode_uint(&coder, &models->batch_size, &batch_size) || batch_size >= split_count - applied) {
            status = lk__lks_chunk_error(error, where, "split %zu: batch larger than the chunk", applied);
            break;
        }
        batch_size++;
        if (!grow((void **)&scratch.batch, &scratch.batch_capacity, batch_size, sizeof(uint32_t))) {
            status = lk_error_set(error, LK_ERR_NOMEM, "out of memory for a batch of %u splits", (unsigned)batch_size);
            break;
        }
        state->serial++;
        uint32_t present = (uint32_t)mesh->vertex_count, cursor = 0;
        for (uint32_t i = 0; i < batch_size && status == LK_OK; i++) {
            /* One bit per vertex not yet excluded until a 1. */
            uint32_t v = cursor;
            for (;; v++) {
                while (v < present && state->stamp[v] == state->serial) v++;
                if (v >= present || lks2_decode_bit(&coder, &models->split[lk__lks2_split_context(mesh, v)])) break;
            }
            if (v >= present) {
                status = lk__lks_chunk_error(error, where, "split %zu: split vertex beyond the %u present", applied + i,
                                             (unsigned)present);
                break;
            }
            scratch.batch[i] = v;
            lk__lks2_exclude(mesh, v, state->stamp, state->serial);
            cursor = v + 1;
        }
        lks2_account(state, &coder, LKS2_PART_SPLIT_VERTICES); /* the batch's size and split bits */
        for (uint32_t i = 0; i < batch_size && applied < limit && status == LK_OK; i++, applied++)
            status = read_split(state, &scratch, &coder, models, scratch.batch[i], header->quantised_max, where, error);
        if (coder.overrun && status == LK_OK)
            status = lk__lks_chunk_error(error, where, "the payload ends before its last symbol");
    }
    scratch_free(&scratch);
    if (status == LK_OK && limit == split_count) status = payload_end(&coder, where, error);
    if (status == LK_OK && limit == split_count && mesh->triangle_count != chunk->triangle_count)
        status = lk__lks_chunk_error(error, where, "%zu triangles decoded, the table says %u", mesh->triangle_count,
                                     (unsigned)chunk->triangle_count);
    if (status != LK_OK) {
        undo_chunk(state);
        state->models = before;
    }
    if (!state->keep_log) state->split_count = 0, state->moved_count = 0;
    return status;
}

void lk__lks2_state_free(lks2_state *state)
{
    lk__lks2_mesh_free(&state->mesh);
    free(state->stamp);
    free(state->splits);
    free(state->moved);
    free(state->old_attributes);
    memset(state, 0, sizeof *state);
}

lk_status lk__lks2_state_begin(lks2_state *state, const lks_header *header, lk_error *error)
{
    (void)error;
    const lk_stream_info *info = &header->info;
    lk__lks2_state_free(state);
    state->base_vertex_count = info->base_vertex_count;
    state->mesh.hint_shift = info->position_bits > 12 ? info->position_bits - 12 : 0;
    state->mesh.ring_frame = (header->flags & LKS2_FLAG_RING_FRAME) != 0;
    state->attributes.flags = header->flags & LKS2_FLAGS;
    lk__lks2_attributes_layout(&state->attributes); /* the count; bits follow in the base chunk */
    state->mesh.attribute_count = state->attributes.count;
    return LK_OK;
}

/* Room for what a chunk that has arrived can add: its vertices, and at
 * most 8 triangles per split (never more than the header's counts). The
 * arrays grow with the bytes received, not with the header's claims. */
static lk_status reserve_for(lks2_state *state, const lks_header *header, size_t vertices, size_t triangles,
                             lk_error *error)
{
    const lk_stream_info *info = &header->info;
    if (triangles > info->triangle_count) triangles = info->triangle_count;
    size_t old_capacity = state->mesh.vertex_capacity;
    lk_status status = lk__lks2_mesh_reserve(&state->mesh, vertices ? vertices : 1, triangles ? triangles : 1, error);
    if (status != LK_OK) return status;
    if (state->mesh.vertex_capacity > old_capacity || !state->stamp) {
        uint32_t *stamp = lk__realloc_array(state->stamp, state->mesh.vertex_capacity, sizeof(uint32_t));
        if (!stamp) return lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu vertices", vertices);
        memset(stamp + (state->stamp ? old_capacity : 0), 0,
               (state->mesh.vertex_capacity - (state->stamp ? old_capacity : 0)) * sizeof(uint32_t));
        state->stamp = stamp;
    }
    return LK_OK;
}

lk_status lk__lks2_decode_chunk(lks2_state *state, const lks_header *header, const lk_stream_chunk_info *chunk,
                                const unsigned char *payload, size_t size, size_t limit, const lks_where *where,
                                lk_error *error)
{
    lks2_mesh *mesh = &state->mesh;
    const lk_stream_info *info = &header->info;
    lk_status status;
    if (chunk->is_base) {
        /* A base vertex or triangle costs at least 0.2 bits (18 decisions
         * at the most skewed probability), so fewer than 64 per byte. */
        if ((uint64_t)info->base_vertex_count > 64u * (uint64_t)size ||
            (uint64_t)info->base_triangle_count > 64u * (uint64_t)size)
            return lk__lks_chunk_error(error, where, "%zu bytes cannot hold %zu base vertices and %zu triangles", size,
                                       info->base_vertex_count, info->base_triangle_count);
        status = reserve_for(state, header, info->base_vertex_count, info->base_triangle_count, error);
        if (status == LK_OK) status = decode_base(mesh, &state->attributes, header, payload, size, where, error);
        if (status == LK_OK && mesh->triangle_count != chunk->triangle_count)
            status = lk__lks_chunk_error(error, where, "the base chunk holds %zu triangles, the table says %u",
                                         mesh->triangle_count, (unsigned)chunk->triangle_count);
        if (status != LK_OK) {
            mesh->vertex_count = 0;
            mesh->triangle_count = 0;
            return status;
        }
        state->has_base = true;
        if (state->account) state->account[LKS2_PART_BASE] += 8.0 * (double)size;
        return LK_OK;
    }
    if (!state->has_base) return lk__lks_chunk_error(error, where, "a split chunk before the base chunk");
    status = reserve_for(state, header, mesh->vertex_count + chunk->split_count,
                         mesh->triangle_count + 8 * (size_t)chunk->split_count, error);
    if (status != LK_OK) return status;
    if (limit > chunk->split_count) limit = chunk->split_count;
    return apply_chunk(state, header, chunk, payload, size, limit, where, error);
}

lk_status lk__lks2_decode(const unsigned char *bytes, size_t size, size_t max_chunks, double *account,
                          lks_header *header, lks2_mesh *mesh, lk_error *error)
{
    if (size < LKS_FIXED_HEADER_SIZE)
        return lk_error_set(error, LK_ERR_TRUNCATED, "stream truncated: %zu bytes, the header has %u", size,
                            LKS_FIXED_HEADER_SIZE);
    lk_status status = lk__lks_parse_header(bytes, header, error);
    if (status != LK_OK) return status;
    const lk_stream_info *info = &header->info;
    if (info->version != LKS2_VERSION)
        return lk_error_set(error, LK_ERR_PARSE, "header at byte 8: version %u, not 2", info->version);
    if (size < info->header_size) return lk_error_set(error, LK_ERR_TRUNCATED, "stream truncated in the chunk table");
    lk_stream_chunk_info *chunks = lk__malloc_array(info->chunk_count, sizeof *chunks);
    if (!chunks) return lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu chunks", info->chunk_count);
    lks2_state state = {0};
    status = lk__lks_parse_table(bytes + LKS_FIXED_HEADER_SIZE, header, chunks, error);
    if (status == LK_OK) status = lk__lks2_state_begin(&state, header, error);
    state.account = account;
    for (size_t c = 0; c < info->chunk_count && c < max_chunks && status == LK_OK; c++) {
        const lk_stream_chunk_info *chunk = &chunks[c];
        lks_where where = {c, chunk->offset};
        if (chunk->offset + chunk->size > size) {
            status = lk_error_set(error, LK_ERR_TRUNCATED, "stream truncated in chunk %zu", c);
            break;
        }
        const unsigned char *stored = bytes + chunk->offset + LKS_CHUNK_HEADER_SIZE;
        size_t stored_size = chunk->size - LKS_CHUNK_HEADER_SIZE;
        if (lk__load_u32le(bytes + chunk->offset) != stored_size ||
            lk__load_u32le(bytes + chunk->offset + 4) != chunk->crc32 ||
            lk__lks_crc32(stored, stored_size) != chunk->crc32) {
            status = lk__lks_chunk_error(error, &where, "chunk header or CRC-32 mismatch");
            break;
        }
        status = lk__lks2_decode_chunk(&state, header, chunk, stored, stored_size, SIZE_MAX, &where, error);
    }
    free(chunks);
    *mesh = state.mesh;
    memset(&state.mesh, 0, sizeof state.mesh);
    lk__lks2_state_free(&state);
    return status;
}
lk_status lk__lks2_check(const unsigned char *bytes, size_t size, const lks2_mesh *expected, lk_error *error)
{
    lks_header header;
    lks2_mesh mesh = {0};
    lk_error check = {0};
    lk_status status = lk__lks2_decode(bytes, size, SIZE_MAX, NULL, &header, &mesh, &check);
    if (status != LK_OK) {
        status = lk_error_set(error, status == LK_ERR_NOMEM ? LK_ERR_NOMEM : LK_ERR_INVALID,
                              "stream self-check failed: %s", check.message);
    } else if (mesh.vertex_count != expected->vertex_count || mesh.triangle_count != expected->triangle_count ||
               mesh.attribute_count != expected->attribute_count ||
               memcmp(mesh.quantised, expected->quantised, 3 * mesh.vertex_count * sizeof(int32_t)) != 0 ||
               memcmp(mesh.corners, expected->corners, 3 * mesh.triangle_count * sizeof(uint32_t)) != 0 ||
               (mesh.attribute_count && memcmp(mesh.attributes, expected->attributes,
                                               mesh.attribute_count * mesh.vertex_count * sizeof(int32_t)) != 0)) {
        status = lk_error_set(error, LK_ERR_INVALID, "stream self-check failed: the decoded full level differs");
    }
    lk__lks2_mesh_free(&mesh);
    return status;
}
