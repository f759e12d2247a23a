/* SPDX-License-Identifier: MIT */
/* Progressive stream format (.lks): the decoding core and the incremental
 * decoder (lk_stream_decoder_*). docs/stream-format.md specifies every
 * byte; stream_format.c reads the header and the chunk table.
 *
 * The decoder keeps the progressive strip fully resolved: r[j] is the
 * vertex present at the current level that strip entry j stands for. A
 * vertex split k (new vertex q = base + k next to p) rewrites some entries
 * from p to q; which ones is a bitmask over "the entries equal to p, in
 * strip order". To walk those entries without scanning the strip, every
 * present vertex has a list of its entries (head/next arrays threaded
 * through the strip positions, kept in increasing position), so a split
 * costs O(entries of p), the size of its mask.
 *
 * The same decoding core runs inside the encoder on the payloads it has just
 * written: that yields the triangle counts of the chunk table and proves,
 * before any byte leaves the encoder, that the stream decodes back to the
 * progressive strip it was given. */
#include "bytes.h"
#include "stream2_internal.h"

#include <stdlib.h>
#include <string.h>
#include <zlib.h>

/* Decoder memory budget unless lk_stream_decoder_set_max_bytes says otherwise
 * (the readers' default). */
#define LKS_DEFAULT_MAX_BYTES ((size_t)8 << 30)

/* ---- decoding core (shared by the decoder and the encoder's self-check) -- */

void lk__lks_state_free(lks_state *state)
{
    free(state->quantised);
    free(state->head);
    free(state->count);
    free(state->resolved);
    free(state->next);
    memset(state, 0, sizeof *state);
}

void lk__lks_undo_free(lks_undo *undo)
{
    free(undo->kept);
    free(undo->old_position);
    memset(undo, 0, sizeof *undo);
}

lk_status lk__lks_state_reserve(lks_state *state, size_t vertex_count, lk_error *error)
{
    if (vertex_count <= state->capacity) return LK_OK;
    int32_t *quantised = lk__realloc_array(state->quantised, vertex_count, 3 * sizeof(int32_t));
    if (quantised) state->quantised = quantised;
    uint32_t *head = lk__realloc_array(state->head, vertex_count, sizeof(uint32_t));
    if (head) state->head = head;
    uint32_t *count = lk__realloc_array(state->count, vertex_count, sizeof(uint32_t));
    if (count) state->count = count;
    /* A failed realloc leaves the old (still valid, smaller) array. */
    if (!quantised || !head || !count)
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu stream vertices", vertex_count);
    state->capacity = vertex_count;
    return LK_OK;
}

static lk_status lks_undo_reserve(lks_undo *undo, size_t split_count, lk_error *error)
{
    if (split_count <= undo->capacity) return LK_OK;
    uint32_t *kept = lk__realloc_array(undo->kept, split_count, sizeof(uint32_t));
    if (kept) undo->kept = kept;
    int32_t *old_position = lk__realloc_array(undo->old_position, split_count, 3 * sizeof(int32_t));
    if (old_position) undo->old_position = old_position;
    if (!kept || !old_position) return lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu splits", split_count);
    undo->capacity = split_count;
    return LK_OK;
}

static inline bool lks_triangle_drawn(const uint32_t *r, size_t t)
{
    return r[t] != r[t + 1] && r[t + 1] != r[t + 2] && r[t] != r[t + 2];
}

/* Sets r[j] = value and keeps the non-degenerate triangle count exact by
 * re-evaluating the (up to three) triangles that use entry j. */
static inline void lks_set_entry(lks_state *state, size_t j, uint32_t value)
{
    uint32_t *r = state->resolved;
    if (state->strip_length < 3) {
        r[j] = value;
        return;
    }
    size_t first = j >= 2 ? j - 2 : 0;
    size_t last = j < state->strip_length - 3 ? j : state->strip_length - 3;
    size_t before = 0, after = 0;
    for (size_t t = first; t <= last; t++) before += lks_triangle_drawn(r, t);
    r[j] = value;
    for (size_t t = first; t <= last; t++) after += lks_triangle_drawn(r, t);
    state->triangles = state->triangles - before + after;
}

static size_t lks_count_triangles(const uint32_t *r, size_t length)
{
    size_t triangles = 0;
    for (size_t t = 0; t + 2 < length; t++) triangles += lks_triangle_drawn(r, t);
    return triangles;
}

/* Moves v to the front (inserting it, and dropping the oldest entry when
 * full); returns v's index before the move, or LKS_RECENT_SIZE if absent. */
unsigned lk__lks_recent_use(lks_recent *recent, uint32_t v)
{
    unsigned index = 0;
    while (index < recent->size && recent->vertices[index] != v) index++;
    unsigned found = index < recent->size ? index : LKS_RECENT_SIZE;
    if (index == recent->size) {
        if (recent->size < LKS_RECENT_SIZE) recent->size++;
        index = recent->size - 1;
    }
    memmove(&recent->vertices[1], &recent->vertices[0], index * sizeof(uint32_t));
    recent->vertices[0] = v;
    return found;
}

/* Base chunk payload: varint position_bytes, positions (3 zigzag deltas per
 * base vertex from the previous one), strip tokens (the rest). */
lk_status lk__lks_decode_base(lks_state *state, const lks_header *header, const unsigned char *payload, size_t size,
                              const lks_where *where, lk_error *error)
{
    const lk_stream_info *info = &header->info;
    size_t base = info->base_vertex_count, length = info->strip_length;
    lks_reader reader = {payload, size, 0};
    uint64_t position_bytes;
    int code = lks_read_varint(&reader, &position_bytes);
    if (code != LKS_VARINT_OK)
        return lk__lks_chunk_error(error, where, "position section length %s", lk__lks_varint_problem(code));
    if (position_bytes > size - reader.position)
        return lk__lks_chunk_error(error, where, "position section of %llu bytes overruns the payload of %zu",
                                   (unsigned long long)position_bytes, size);
    lks_reader positions = {payload, reader.position + (size_t)position_bytes, reader.position};
    lks_reader tokens = {payload, size, positions.size};
    if (3 * (uint64_t)base > position_bytes)
        return lk__lks_chunk_error(error, where, "%zu base vertices cannot fit in %llu position bytes", base,
                                   (unsigned long long)position_bytes);
    if (length > size - tokens.position)
        return lk__lks_chunk_error(error, where, "a strip of %zu entries cannot fit in %zu token bytes", length,
                                   size - tokens.position);

    lks_state fresh = {0};
    fresh.base_vertex_count = base;
    fresh.quantised_max = header->quantised_max;
    fresh.strip_length = length;
    lk_status status = lk__lks_state_reserve(&fresh, base, error);
    if (status != LK_OK) {
        lk__lks_state_free(&fresh);
        return status;
    }
    fresh.resolved = lk__malloc_array(length, sizeof(uint32_t));
    fresh.next = lk__malloc_array(length, sizeof(uint32_t));
    if (!fresh.resolved || !fresh.next) {
        lk__lks_state_free(&fresh);
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory for a strip of %zu entries", length);
    }

    int64_t previous[3] = {0, 0, 0};
    for (size_t v = 0; v < base; v++) {
        for (int axis = 0; axis < 3; axis++) {
            uint64_t raw;
            size_t at = positions.position;
            code = lks_read_varint(&positions, &raw);
            if (code != LKS_VARINT_OK) {
                lk__lks_state_free(&fresh);
                return lk__lks_chunk_error(error, where, "base vertex %zu: position varint at payload byte %zu %s", v,
                                           at, lk__lks_varint_problem(code));
            }
            int64_t delta = lks_unzigzag(raw);
            if (delta < -(int64_t)header->quantised_max || delta > (int64_t)header->quantised_max ||
                previous[axis] + delta < 0 || previous[axis] + delta > header->quantised_max) {
                lk__lks_state_free(&fresh);
                return lk__lks_chunk_error(error, where,
                                           "base vertex %zu: delta %lld at payload byte %zu leaves the quantisation "
                                           "range 0..%d",
                                           v, (long long)delta, at, (int)header->quantised_max);
            }
            previous[axis] += delta;
            fresh.quantised[3 * v + axis] = (int32_t)previous[axis];
        }
    }
    if (positions.position != positions.size) {
        lk__lks_state_free(&fresh);
        return lk__lks_chunk_error(error, where, "%zu unused bytes at the end of the base position section",
                                   positions.size - positions.position);
    }

    int64_t literal = 0;
    lks_recent recent = {{0}, 0};
    for (size_t j = 0; j < length; j++) {
        uint64_t token;
        size_t at = tokens.position;
        code = lks_read_varint(&tokens, &token);
        if (code != LKS_VARINT_OK) {
            lk__lks_state_free(&fresh);
            return lk__lks_chunk_error(error, where, "strip entry %zu: token at payload byte %zu %s", j, at,
                                       lk__lks_varint_problem(code));
        }
        uint32_t value;
        if (token < LKS_TOKEN_RECENT) {
            if (j < token + 1) {
                lk__lks_state_free(&fresh);
                return lk__lks_chunk_error(
                    error, where, "strip entry %zu: token at payload byte %zu repeats an entry before the strip", j,
                    at);
            }
            value = fresh.resolved[j - 1 - token];
        } else if (token < LKS_TOKEN_LITERAL) {
            if (token - LKS_TOKEN_RECENT >= recent.size) {
                lk__lks_state_free(&fresh);
                return lk__lks_chunk_error(error, where,
                                           "strip entry %zu: token at payload byte %zu names recent vertex %u of %u", j,
                                           at, (unsigned)(token - LKS_TOKEN_RECENT), recent.size);
            }
            value = recent.vertices[token - LKS_TOKEN_RECENT];
            lk__lks_recent_use(&recent, value);
        } else {
            int64_t delta = lks_unzigzag(token - LKS_TOKEN_LITERAL);
            if (delta < -(int64_t)base || delta > (int64_t)base || literal + delta < 0 ||
                literal + delta >= (int64_t)base) {
                lk__lks_state_free(&fresh);
                return lk__lks_chunk_error(
                    error, where, "strip entry %zu: vertex %lld at payload byte %zu is not a base vertex (%zu)", j,
                    (long long)(literal + delta), at, base);
            }
            literal += delta;
            value = (uint32_t)literal;
            lk__lks_recent_use(&recent, value);
        }
        fresh.resolved[j] = value;
    }
    if (tokens.position != tokens.size) {
        lk__lks_state_free(&fresh);
        return lk__lks_chunk_error(error, where, "%zu unused bytes after the base strip",
                                   tokens.size - tokens.position);
    }

    for (size_t v = 0; v < base; v++) {
        fresh.head[v] = LKS_NONE;
        fresh.count[v] = 0;
    }
    for (size_t j = length; j-- > 0;) {
        uint32_t v = fresh.resolved[j];
        fresh.next[j] = fresh.head[v];
        fresh.head[v] = (uint32_t)j;
        fresh.count[v]++;
    }
    fresh.triangles = lks_count_triangles(fresh.resolved, length);
    fresh.present = base;
    fresh.has_base = true;
    lk__lks_state_free(state);
    *state = fresh;
    return LK_OK;
}

/* Takes back the last applied split (q = present - 1): its entries return
 * to p's list, merged by strip position, and p gets its old position. */
static void lks_undo_split(lks_state *state, uint32_t kept, const int32_t old_position[3])
{
    uint32_t q = (uint32_t)(state->present - 1);
    uint32_t a = state->head[kept], b = state->head[q];
    uint32_t *tail = &state->head[kept];
    while (a != LKS_NONE || b != LKS_NONE) {
        if (b == LKS_NONE || (a != LKS_NONE && a < b)) {
            *tail = a;
            tail = &state->next[a];
            a = state->next[a];
        } else {
            *tail = b;
            tail = &state->next[b];
            uint32_t following = state->next[b];
            lks_set_entry(state, b, kept);
            b = following;
        }
    }
    *tail = LKS_NONE;
    state->count[kept] += state->count[q];
    state->count[q] = 0;
    state->head[q] = LKS_NONE;
    memcpy(&state->quantised[3 * (size_t)kept], old_position, 3 * sizeof(int32_t));
    state->present--;
}

static void lks_rollback(lks_state *state, const lks_undo *undo, size_t applied)
{
    for (size_t i = applied; i-- > 0;) lks_undo_split(state, undo->kept[i], &undo->old_position[3 * i]);
}

/* Moves the entries of p picked by `mask` (bit i, least significant first,
 * stands for the i-th entry of p's list) to the new vertex q = present, and
 * makes q present. Both lists stay in increasing strip position. */
void lk__lks_split_entries(lks_state *state, uint32_t kept, const unsigned char *mask)
{
    uint32_t q = (uint32_t)state->present;
    size_t candidates = state->count[kept];
    uint32_t *p_tail = &state->head[kept];
    uint32_t *q_tail = &state->head[q];
    uint32_t entry = state->head[kept];
    size_t moved_entries = 0;
    for (size_t bit = 0; bit < candidates; bit++) {
        uint32_t following = state->next[entry];
        if ((mask[bit >> 3] >> (bit & 7)) & 1) {
            *q_tail = entry;
            q_tail = &state->next[entry];
            lks_set_entry(state, entry, q);
            moved_entries++;
        } else {
            *p_tail = entry;
            p_tail = &state->next[entry];
        }
        entry = following;
    }
    *p_tail = LKS_NONE;
    *q_tail = LKS_NONE;
    state->count[kept] = (uint32_t)(candidates - moved_entries);
    state->count[q] = (uint32_t)moved_entries;
    state->present++;
}

/* Mean of the other two corners of every triangle the strip draws around
 * v (so each neighbour counts once per shared triangle), rounded half up;
 * `fallback` when v draws no triangle. Positions are never negative, so
 * integer division is floor division here and in any other decoder. */
static void lks_ring_centroid(const lks_state *state, uint32_t v, const int32_t fallback[3], int64_t out[3])
{
    int64_t sum[3] = {0, 0, 0};
    int64_t corners = 0;
    size_t length = state->strip_length;
    const uint32_t *r = state->resolved;
    if (length >= 3) {
        for (uint32_t j = state->head[v]; j != LKS_NONE; j = state->next[j]) {
            size_t first = j >= 2 ? j - 2 : 0;
            size_t last = j < length - 3 ? j : length - 3;
            for (size_t t = first; t <= last; t++) {
                if (!lks_triangle_drawn(r, t)) continue;
                for (size_t corner = t; corner < t + 3; corner++) {
                    if (r[corner] == v) continue;
                    const int32_t *position = &state->quantised[3 * (size_t)r[corner]];
                    for (int axis = 0; axis < 3; axis++) sum[axis] += position[axis];
                    corners++;
                }
            }
        }
    }
    for (int axis = 0; axis < 3; axis++)
        out[axis] = corners ? (2 * sum[axis] + corners) / (2 * corners) : fallback[axis];
}

/* Predictions of the two positions a split carries (docs/stream-format.md
 * has the measurements behind them). q: (3 ring(q) + p) / 4, with p still
 * at its position before the split; p: (3 p + ring(p)) / 4, once q has its
 * position. The ring centroid predicts a vertex of a smooth surface well;
 * leaning towards p helps on coarse, irregular meshes. */
void lk__lks_predict_split(const lks_state *state, uint32_t q, uint32_t kept, int64_t out[3])
{
    const int32_t *current = &state->quantised[3 * (size_t)kept];
    int64_t ring[3];
    lks_ring_centroid(state, q, current, ring);
    for (int axis = 0; axis < 3; axis++) out[axis] = (3 * ring[axis] + current[axis] + 2) / 4;
}

void lk__lks_predict_kept(const lks_state *state, uint32_t kept, int64_t out[3])
{
    const int32_t *current = &state->quantised[3 * (size_t)kept];
    int64_t ring[3];
    lks_ring_centroid(state, kept, current, ring);
    for (int axis = 0; axis < 3; axis++) out[axis] = (3 * (int64_t)current[axis] + ring[axis] + 2) / 4;
}

/* Reads three zigzag deltas against `predicted` into `position`, refusing
 * anything outside the quantisation range. */
static lk_status lks_read_position(lks_reader *reader, const int64_t predicted[3], int32_t top, int32_t position[3],
                                   size_t split, const char *what, const lks_where *where, lk_error *error)
{
    for (int axis = 0; axis < 3; axis++) {
        uint64_t raw;
        size_t at = reader->position;
        int code = lks_read_varint(reader, &raw);
        if (code != LKS_VARINT_OK)
            return lk__lks_chunk_error(error, where, "split %zu: %s position varint at payload byte %zu %s", split,
                                       what, at, lk__lks_varint_problem(code));
        int64_t delta = lks_unzigzag(raw);
        if (delta < -(int64_t)top || delta > (int64_t)top || predicted[axis] + delta < 0 ||
            predicted[axis] + delta > top)
            return lk__lks_chunk_error(
                error, where,
                "split %zu: %s position delta %lld at payload byte %zu leaves the quantisation range "
                "0..%d",
                split, what, (long long)delta, at, (int)top);
        position[axis] = (int32_t)(predicted[axis] + delta);
    }
    return LK_OK;
}

/* Split chunk payload: varint p_bytes, varint mask_bytes, then the p
 * section, the mask section and the position section (the rest). Applies
 * up to `limit` of the chunk's split_count splits, recording each in undo
 * (reserved by the caller for `limit` splits; state reserved for
 * present + limit vertices). On failure the caller rolls back *applied
 * splits (the last one possibly without its positions). */
static lk_status lks_apply_splits(lks_state *state, const unsigned char *payload, size_t size, size_t split_count,
                                  size_t limit, lks_undo *undo, size_t *applied, const lks_where *where,
                                  lk_error *error)
{
    *applied = 0;
    lks_reader reader = {payload, size, 0};
    uint64_t p_bytes, mask_bytes;
    int code = lks_read_varint(&reader, &p_bytes);
    if (code == LKS_VARINT_OK) code = lks_read_varint(&reader, &mask_bytes);
    if (code != LKS_VARINT_OK)
        return lk__lks_chunk_error(error, where, "section length %s", lk__lks_varint_problem(code));
    size_t rest = size - reader.position;
    if (p_bytes > rest || mask_bytes > rest - p_bytes)
        return lk__lks_chunk_error(error, where, "sections of %llu + %llu bytes overrun the payload of %zu bytes",
                                   (unsigned long long)p_bytes, (unsigned long long)mask_bytes, size);
    lks_reader kept_reader = {payload, reader.position + (size_t)p_bytes, reader.position};
    lks_reader mask_reader = {payload, kept_reader.size + (size_t)mask_bytes, kept_reader.size};
    lks_reader position_reader = {payload, size, mask_reader.size};
    size_t level_before = state->present - state->base_vertex_count;

    for (size_t i = 0; i < limit; i++) {
        size_t split = level_before + i;
        size_t at = kept_reader.position;
        uint64_t kept_code;
        code = lks_read_varint(&kept_reader, &kept_code);
        if (code != LKS_VARINT_OK)
            return lk__lks_chunk_error(error, where, "split %zu: p varint at payload byte %zu %s", split, at,
                                       lk__lks_varint_problem(code));
        uint64_t kept64 = kept_code >> 1;
        bool moved = kept_code & 1;
        if (kept64 >= state->present)
            return lk__lks_chunk_error(error, where,
                                       "split %zu: p = %llu at payload byte %zu is not a present vertex (%zu present)",
                                       split, (unsigned long long)kept64, at, state->present);
        uint32_t kept = (uint32_t)kept64;
        size_t candidates = state->count[kept];
        size_t mask_length = (candidates + 7) / 8;
        const unsigned char *mask = payload + mask_reader.position;
        if (mask_length > mask_reader.size - mask_reader.position)
            return lk__lks_chunk_error(error, where,
                                       "split %zu: a mask of %zu bits at payload byte %zu runs past the mask section",
                                       split, candidates, mask_reader.position);
        if ((candidates & 7) && (mask[mask_length - 1] >> (candidates & 7)))
            return lk__lks_chunk_error(error, where,
                                       "split %zu: padding bits of the mask at payload byte %zu are not zero", split,
                                       mask_reader.position + mask_length - 1);
        mask_reader.position += mask_length;

        /* The entries move first: q's predicted position needs its triangles.
         * From here on the split is in the undo log. */
        uint32_t q = (uint32_t)state->present;
        undo->kept[i] = kept;
        memcpy(&undo->old_position[3 * i], &state->quantised[3 * (size_t)kept], 3 * sizeof(int32_t));
        lk__lks_split_entries(state, kept, mask);
        *applied = i + 1;

        int64_t predicted[3];
        int32_t position[3];
        lk__lks_predict_split(state, q, kept, predicted);
        lk_status status =
            lks_read_position(&position_reader, predicted, state->quantised_max, position, split, "q", where, error);
        if (status != LK_OK) return status;
        memcpy(&state->quantised[3 * (size_t)q], position, sizeof position);
        if (moved) {
            lk__lks_predict_kept(state, kept, predicted);
            status = lks_read_position(&position_reader, predicted, state->quantised_max, position, split, "p", where,
                                       error);
            if (status != LK_OK) return status;
            memcpy(&state->quantised[3 * (size_t)kept], position, sizeof position);
        }
    }
    if (limit == split_count) {
        if (kept_reader.position != kept_reader.size || mask_reader.position != mask_reader.size ||
            position_reader.position != position_reader.size)
            return lk__lks_chunk_error(error, where,
                                       "unused bytes after the last split (p section %zu, mask section %zu, position "
                                       "section %zu)",
                                       kept_reader.size - kept_reader.position, mask_reader.size - mask_reader.position,
                                       position_reader.size - position_reader.position);
    }
    return LK_OK;
}

/* Applies one split chunk whole, or leaves the state as it was. `limit`
 * (<= split_count) stops early for max_level; the triangle count is
 * checked against the table when asked and the chunk was applied to its
 * end (the encoder asks the other way round: it fills the table). */
lk_status lk__lks_apply_chunk(lks_state *state, lks_undo *undo, const unsigned char *payload, size_t size,
                              const lk_stream_chunk_info *chunk, size_t limit, bool check_triangles,
                              const lks_where *where, lk_error *error)
{
    if (state->present - state->base_vertex_count != chunk->first_split)
        return lk__lks_chunk_error(error, where, "starts at split %u but the decoder is at level %zu",
                                   (unsigned)chunk->first_split, state->present - state->base_vertex_count);
    lk_status status = lk__lks_state_reserve(state, state->present + limit, error);
    if (status == LK_OK) status = lks_undo_reserve(undo, limit, error);
    if (status != LK_OK) return status;
    size_t triangles_before = state->triangles;
    size_t applied = 0;
    status = lks_apply_splits(state, payload, size, chunk->split_count, limit, undo, &applied, where, error);
    if (status == LK_OK && check_triangles && limit == chunk->split_count && state->triangles != chunk->triangle_count)
        status = lk__lks_chunk_error(error, where, "the strip draws %zu triangles after the chunk, the table says %u",
                                     state->triangles, (unsigned)chunk->triangle_count);
    if (status != LK_OK) {
        lks_rollback(state, undo, applied);
        state->triangles = triangles_before;
    }
    return status;
}

/* Checks a chunk's header and CRC and hands back its raw payload: either a
 * pointer into `bytes` or, for a deflated one, *inflated (malloc'ed). */
static lk_status lks_open_chunk(const unsigned char *bytes, const lk_stream_chunk_info *chunk, const lks_where *where,
                                const unsigned char **payload, unsigned char **inflated, lk_error *error)
{
    *inflated = NULL;
    size_t stored = chunk->size - LKS_CHUNK_HEADER_SIZE;
    uint32_t header_stored = lk__load_u32le(bytes), header_crc = lk__load_u32le(bytes + 4);
    if (header_stored != stored || header_crc != chunk->crc32)
        return lk__lks_chunk_error(error, where,
                                   "chunk header (payload %u bytes, CRC %08x) disagrees with the table (%zu bytes, CRC "
                                   "%08x)",
                                   (unsigned)header_stored, (unsigned)header_crc, stored, (unsigned)chunk->crc32);
    const unsigned char *data = bytes + LKS_CHUNK_HEADER_SIZE;
    uint32_t crc = lk__lks_crc32(data, stored);
    if (crc != chunk->crc32)
        return lk__lks_chunk_error(error, where, "CRC-32 mismatch (stored %08x, computed %08x)", (unsigned)chunk->crc32,
                                   (unsigned)crc);
    if (!chunk->compressed) {
        *payload = data;
        return LK_OK;
    }
    unsigned char *raw = malloc(chunk->raw_size ? chunk->raw_size : 1);
    if (!raw)
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory for a chunk of %u bytes", (unsigned)chunk->raw_size);
    uLongf raw_length = chunk->raw_size;
    uLong source_length = (uLong)stored;
    int result = uncompress2(raw, &raw_length, data, &source_length);
    if (result != Z_OK || raw_length != chunk->raw_size || source_length != stored) {
        free(raw);
        return lk__lks_chunk_error(error, where,
                                   "deflated payload is corrupt (zlib: %s; inflated %lu of %u bytes from %lu of %zu)",
                                   result == Z_OK ? "ok" : zError(result), (unsigned long)raw_length,
                                   (unsigned)chunk->raw_size, (unsigned long)source_length, stored);
    }
    *payload = raw;
    *inflated = raw;
    return LK_OK;
}

/* ---- incremental decoder ------------------------------------------------------ */

enum { LKS_PHASE_HEADER, LKS_PHASE_TABLE, LKS_PHASE_CHUNKS, LKS_PHASE_DONE, LKS_PHASE_FAILED };

struct lk_stream_decoder {
    size_t max_level;
    size_t max_bytes;     /* memory budget for the decoder's own arrays and buffers */
    uint64_t state_bytes; /* what the header's counts need (state + table), checked against it */
    int phase;
    bool stopped;       /* max_level reached: later bytes are ignored */
    lk__buffer pending; /* bytes of the unit (header, table, chunk) being received */
    size_t received;    /* bytes fed so far */
    size_t consumed;    /* bytes of the header and the decoded chunks */
    bool has_info;
    lks_header header;
    lk_stream_chunk_info *chunks;
    size_t next_chunk; /* chunk being received */
    size_t chunks_decoded;
    lks_state state;
    lks_undo undo;
    lks2_state state2; /* version 2 */
    lk_error failure;  /* replayed once the decoder has failed */
};

lk_status lk_stream_decoder_create(size_t max_level, lk_stream_decoder **out, lk_error *error)
{
    if (!out) return lk_error_set(error, LK_ERR_INVALID, "lk_stream_decoder_create: NULL out");
    *out = calloc(1, sizeof **out);
    if (!*out) return lk_error_set(error, LK_ERR_NOMEM, "out of memory for a stream decoder");
    (*out)->max_level = max_level;
    (*out)->max_bytes = LKS_DEFAULT_MAX_BYTES;
    (*out)->phase = LKS_PHASE_HEADER;
    return LK_OK;
}

lk_status lk_stream_decoder_set_max_bytes(lk_stream_decoder *decoder, size_t max_bytes, lk_error *error)
{
    if (!decoder) return lk_error_set(error, LK_ERR_INVALID, "lk_stream_decoder_set_max_bytes: NULL decoder");
    if (decoder->phase != LKS_PHASE_HEADER || decoder->received != 0)
        return lk_error_set(error, LK_ERR_INVALID,
                            "lk_stream_decoder_set_max_bytes: the budget must be set before the first byte is fed");
    decoder->max_bytes = max_bytes ? max_bytes : LKS_DEFAULT_MAX_BYTES;
    return LK_OK;
}

/* What decoding needs for the counts of a checked header: per vertex its
 * quantised position, list head and count (20 bytes), per strip entry the
 * resolved vertex and the next link (8 bytes), per chunk its table entry
 * as received and as parsed. Refused before anything of that size is
 * allocated, so a 100-byte header cannot make the decoder ask for
 * gigabytes. */
static lk_status lks_check_header_budget(lk_stream_decoder *decoder, lk_error *error)
{
    const lk_stream_info *info = &decoder->header.info;
    uint64_t state = (uint64_t)info->vertex_count * 20u + (uint64_t)info->strip_length * 8u;
    /* Version 2: position, list head and batch stamp per vertex, corners
     * and links per triangle. */
    if (info->version == 2) state = (uint64_t)info->vertex_count * 20u + (uint64_t)info->triangle_count * 24u;
    uint64_t table = (uint64_t)info->chunk_count * (LKS_TABLE_ENTRY_SIZE + sizeof(lk_stream_chunk_info));
    if (table > decoder->max_bytes)
        return lk_error_set(error, LK_ERR_LIMIT,
                            "header at byte 48: a table of %zu chunk%s needs %llu bytes, more than the memory budget "
                            "of %zu bytes",
                            info->chunk_count, info->chunk_count == 1 ? "" : "s", (unsigned long long)table,
                            decoder->max_bytes);
    if (state > decoder->max_bytes - table && info->version == 2)
        return lk_error_set(error, LK_ERR_LIMIT,
                            "header at byte 24: %zu vertices and %zu triangles need %llu bytes to decode, more than "
                            "the memory budget of %zu bytes",
                            info->vertex_count, info->triangle_count, (unsigned long long)(state + table),
                            decoder->max_bytes);
    if (state > decoder->max_bytes - table)
        return lk_error_set(error, LK_ERR_LIMIT,
                            "header at byte 24: %zu vertices and a strip of %zu entries need %llu bytes to decode, "
                            "more than the memory budget of %zu bytes",
                            info->vertex_count, info->strip_length, (unsigned long long)(state + table),
                            decoder->max_bytes);
    decoder->state_bytes = state + table;
    return LK_OK;
}

/* Each chunk is buffered whole (when it arrives in pieces), inflated into
 * raw_size bytes when compressed, and its splits are logged for undo (16
 * bytes each): refuse a table whose chunks would not fit next to the
 * state, before any chunk arrives. */
static lk_status lks_check_table_budget(const lk_stream_decoder *decoder, lk_error *error)
{
    const lk_stream_info *info = &decoder->header.info;
    uint64_t room = decoder->max_bytes - decoder->state_bytes;
    for (size_t i = 0; i < info->chunk_count; i++) {
        const lk_stream_chunk_info *chunk = &decoder->chunks[i];
        uint64_t working = (uint64_t)chunk->size + (chunk->compressed ? (uint64_t)chunk->raw_size : 0) +
                           (uint64_t)chunk->split_count * 16u;
        if (working > room)
            return lk_error_set(error, LK_ERR_LIMIT,
                                "chunk table entry %zu at byte %zu: a chunk of %u bytes (%u raw) at offset %llu needs "
                                "%llu bytes next to the %llu of the decoder state, more than the memory budget of %zu "
                                "bytes",
                                i, (size_t)LKS_FIXED_HEADER_SIZE + i * LKS_TABLE_ENTRY_SIZE + 8, (unsigned)chunk->size,
                                (unsigned)chunk->raw_size, (unsigned long long)chunk->offset,
                                (unsigned long long)working, (unsigned long long)decoder->state_bytes,
                                decoder->max_bytes);
    }
    return LK_OK;
}

void lk_stream_decoder_free(lk_stream_decoder *decoder)
{
    if (!decoder) return;
    lk__buffer_free(&decoder->pending);
    free(decoder->chunks);
    lk__lks_state_free(&decoder->state);
    lk__lks_undo_free(&decoder->undo);
    lk__lks2_state_free(&decoder->state2);
    free(decoder);
}

/* Bytes of the unit the decoder waits for. */
static size_t lks_unit_size(const lk_stream_decoder *decoder)
{
    switch (decoder->phase) {
    case LKS_PHASE_HEADER: return LKS_FIXED_HEADER_SIZE;
    case LKS_PHASE_TABLE: return decoder->header.info.header_size - LKS_FIXED_HEADER_SIZE;
    case LKS_PHASE_CHUNKS: return decoder->chunks[decoder->next_chunk].size;
    default: return 0;
    }
}

static lk_status lks_decode_chunk(lk_stream_decoder *decoder, const unsigned char *bytes, lk_error *error)
{
    size_t index = decoder->next_chunk;
    const lk_stream_chunk_info *chunk = &decoder->chunks[index];
    lks_where where = {index, chunk->offset};
    const unsigned char *payload = NULL;
    unsigned char *inflated;
    lk_status status = lks_open_chunk(bytes, chunk, &where, &payload, &inflated, error);
    if (status != LK_OK) return status;
    size_t level = lk_stream_decoder_level(decoder);
    if (decoder->header.info.version == 2) {
        size_t limit = decoder->max_level - level;
        status = lk__lks2_decode_chunk(&decoder->state2, &decoder->header, chunk, payload, chunk->raw_size, limit,
                                       &where, error);
        size_t reached = lk_stream_decoder_level(decoder);
        if (status == LK_OK && reached == decoder->max_level && reached < decoder->header.info.split_count)
            decoder->stopped = true;
    } else if (chunk->is_base) {
        status = lk__lks_decode_base(&decoder->state, &decoder->header, payload, chunk->raw_size, &where, error);
        if (status == LK_OK && decoder->state.triangles != chunk->triangle_count) {
            status = lk__lks_chunk_error(error, &where, "the base strip draws %zu triangles, the table says %u",
                                         decoder->state.triangles, (unsigned)chunk->triangle_count);
            lk__lks_state_free(&decoder->state);
        }
        if (status == LK_OK && decoder->max_level == 0 && decoder->header.info.split_count > 0) decoder->stopped = true;
    } else {
        size_t limit = chunk->split_count;
        if (decoder->max_level - level < limit) limit = decoder->max_level - level;
        status = lk__lks_apply_chunk(&decoder->state, &decoder->undo, payload, chunk->raw_size, chunk, limit, true,
                                     &where, error);
        if (status == LK_OK && level + limit == decoder->max_level &&
            decoder->max_level < decoder->header.info.split_count)
            decoder->stopped = true;
    }
    free(inflated);
    if (status != LK_OK) return status;
    decoder->chunks_decoded++;
    decoder->consumed += chunk->size;
    decoder->next_chunk++;
    if (decoder->stopped || decoder->next_chunk == decoder->header.info.chunk_count) decoder->phase = LKS_PHASE_DONE;
    return LK_OK;
}

static lk_status lks_process_unit(lk_stream_decoder *decoder, const unsigned char *bytes, lk_error *error)
{
    switch (decoder->phase) {
    case LKS_PHASE_HEADER: {
        lk_status status = lk__lks_parse_header(bytes, &decoder->header, error);
        if (status == LK_OK) status = lks_check_header_budget(decoder, error);
        if (status == LK_OK && decoder->header.info.version == 2)
            status = lk__lks2_state_begin(&decoder->state2, &decoder->header, error);
        if (status != LK_OK) return status;
        decoder->phase = LKS_PHASE_TABLE;
        return LK_OK;
    }
    case LKS_PHASE_TABLE: {
        size_t chunk_count = decoder->header.info.chunk_count;
        decoder->chunks = lk__malloc_array(chunk_count, sizeof(lk_stream_chunk_info));
        if (!decoder->chunks) return lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu chunks", chunk_count);
        lk_status status = lk__lks_parse_table(bytes, &decoder->header, decoder->chunks, error);
        if (status == LK_OK) status = lks_check_table_budget(decoder, error);
        if (status != LK_OK) return status;
        decoder->has_info = true;
        decoder->consumed = decoder->header.info.header_size;
        decoder->phase = LKS_PHASE_CHUNKS;
        return LK_OK;
    }
    case LKS_PHASE_CHUNKS: return lks_decode_chunk(decoder, bytes, error);
    default: return LK_OK;
    }
}

static lk_status lks_replay_failure(const lk_stream_decoder *decoder, lk_error *error)
{
    return lk_error_set(error, decoder->failure.status, "%s", decoder->failure.message);
}

lk_status lk_stream_decoder_feed(lk_stream_decoder *decoder, const void *bytes, size_t size, lk_error *error)
{
    if (!decoder || (!bytes && size))
        return lk_error_set(error, LK_ERR_INVALID, "lk_stream_decoder_feed: NULL argument");
    if (decoder->phase == LKS_PHASE_FAILED) return lks_replay_failure(decoder, error);
    const unsigned char *input = bytes;
    while (size > 0) {
        if (decoder->phase == LKS_PHASE_DONE) {
            if (decoder->stopped) {
                /* max_level reached: the rest of a download is welcome and unused. */
                decoder->received += size;
                return LK_OK;
            }
            return lk_error_set(error, LK_ERR_PARSE, "byte %zu: data after the end of the stream (%zu bytes)",
                                decoder->received, decoder->header.info.total_size);
        }
        size_t unit = lks_unit_size(decoder);
        size_t have = decoder->pending.size;
        size_t take = unit - have < size ? unit - have : size;
        const unsigned char *unit_bytes = NULL;
        if (have == 0 && take == unit) {
            unit_bytes = input; /* the whole unit is here: no copy */
        } else {
            if (!lk__buffer_append(&decoder->pending, input, take))
                return lk_error_set(error, LK_ERR_NOMEM, "out of memory buffering %zu stream bytes", have + take);
            unit_bytes = decoder->pending.data;
        }
        decoder->received += take;
        input += take;
        size -= take;
        /* Say "not a stream" as soon as the magic is wrong, not after 96 bytes. */
        if (decoder->phase == LKS_PHASE_HEADER) {
            size_t known = have + take < sizeof lk__lks_magic ? have + take : sizeof lk__lks_magic;
            if (memcmp(unit_bytes, lk__lks_magic, known) != 0) {
                lk_error_set(&decoder->failure, LK_ERR_PARSE, "header at byte 0: not a lodkit stream (bad magic)");
                decoder->phase = LKS_PHASE_FAILED;
                lk__buffer_free(&decoder->pending);
                return lks_replay_failure(decoder, error);
            }
        }
        if (have + take < unit) break;
        lk_error local = {0};
        lk_status status = lks_process_unit(decoder, unit_bytes, &local);
        decoder->pending.size = 0;
        if (status != LK_OK) {
            decoder->failure = local;
            decoder->phase = LKS_PHASE_FAILED;
            lk__buffer_free(&decoder->pending);
            return lks_replay_failure(decoder, error);
        }
    }
    /* A finished decoder keeps no buffered bytes around. */
    if (decoder->phase == LKS_PHASE_DONE) lk__buffer_free(&decoder->pending);
    return LK_OK;
}

lk_status lk_stream_decoder_finish(lk_stream_decoder *decoder, lk_error *error)
{
    if (!decoder) return lk_error_set(error, LK_ERR_INVALID, "lk_stream_decoder_finish: NULL decoder");
    switch (decoder->phase) {
    case LKS_PHASE_DONE: return LK_OK;
    case LKS_PHASE_FAILED: return lks_replay_failure(decoder, error);
    case LKS_PHASE_HEADER:
        return lk_error_set(error, LK_ERR_TRUNCATED, "stream truncated: stopped at byte %zu in the header (%u bytes)",
                            decoder->received, LKS_FIXED_HEADER_SIZE);
    case LKS_PHASE_TABLE:
        return lk_error_set(error, LK_ERR_TRUNCATED,
                            "stream truncated: stopped at byte %zu in the chunk table (%zu chunk%s, header ends at "
                            "byte %zu)",
                            decoder->received, decoder->header.info.chunk_count,
                            decoder->header.info.chunk_count == 1 ? "" : "s", decoder->header.info.header_size);
    default:
        return lk_error_set(error, LK_ERR_TRUNCATED,
                            "stream truncated: stopped at byte %zu in chunk %zu of %zu (bytes %llu..%llu); level %zu "
                            "of %zu decoded",
                            decoder->received, decoder->next_chunk, decoder->header.info.chunk_count,
                            (unsigned long long)decoder->chunks[decoder->next_chunk].offset,
                            (unsigned long long)(decoder->chunks[decoder->next_chunk].offset +
                                                 decoder->chunks[decoder->next_chunk].size),
                            lk_stream_decoder_level(decoder), decoder->header.info.split_count);
    }
}

const lk_stream_info *lk_stream_decoder_info(const lk_stream_decoder *decoder)
{
    return decoder && decoder->has_info ? &decoder->header.info : NULL;
}

size_t lk_stream_decoder_level(const lk_stream_decoder *decoder)
{
    if (decoder && decoder->has_info && decoder->header.info.version == 2)
        return decoder->state2.has_base ? decoder->state2.mesh.vertex_count - decoder->state2.base_vertex_count : 0;
    if (!decoder || !decoder->state.has_base) return 0;
    return decoder->state.present - decoder->state.base_vertex_count;
}

size_t lk_stream_decoder_chunks(const lk_stream_decoder *decoder) { return decoder ? decoder->chunks_decoded : 0; }

size_t lk_stream_decoder_bytes(const lk_stream_decoder *decoder) { return decoder ? decoder->consumed : 0; }

/* Version 2: the decoder's mesh as it stands, dequantised. */
static lk_status lks2_current_mesh(const lk_stream_decoder *decoder, lk_mesh *out, lk_error *error)
{
    const lks2_state *state = &decoder->state2;
    if (!state->has_base)
        return lk_error_set(error, LK_ERR_INVALID, "no mesh yet: the base chunk has not been decoded");
    const lks2_mesh *mesh = &state->mesh;
    const lks2_attributes *attributes = &state->attributes;
    unsigned flags = (attributes->flags & LKS2_FLAG_NORMALS ? LK_ATTR_NORMALS : 0u) |
                     (attributes->flags & LKS2_FLAG_TEXCOORDS ? LK_ATTR_TEXCOORDS : 0u) |
                     (attributes->flags & LKS2_FLAG_COLORS ? LK_ATTR_COLORS : 0u);
    lk_mesh result;
    lk_status status = lk_mesh_alloc(&result, mesh->vertex_count, mesh->triangle_count, flags, error);
    if (status != LK_OK) return status;
    const lk_stream_info *info = &decoder->header.info;
    for (size_t v = 0; v < mesh->vertex_count; v++)
        for (int axis = 0; axis < 3; axis++)
            result.positions[3 * v + axis] = lks_dequantise(info->quantisation_min[axis], info->quantisation_step[axis],
                                                            mesh->quantised[3 * v + axis]);
    size_t stride = attributes->count;
    for (size_t v = 0; v < mesh->vertex_count && stride; v++) {
        const int32_t *values = mesh->attributes + stride * v;
        size_t c = 0;
        if (result.normals) {
            lk__lks2_decode_normal(values, attributes->normal_bits, result.normals + 3 * v);
            c += 2;
        }
        if (result.texcoords) {
            for (int axis = 0; axis < 2; axis++)
                result.texcoords[2 * v + axis] =
                    lks_dequantise(attributes->texcoord_min[axis], attributes->texcoord_step[axis], values[c + axis]);
            c += 2;
        }
        if (result.colors)
            for (int channel = 0; channel < 4; channel++)
                result.colors[4 * v + channel] = (float)values[c + (size_t)channel] / 255.0f;
    }
    if (mesh->triangle_count) memcpy(result.indices, mesh->corners, 3 * mesh->triangle_count * sizeof(uint32_t));
    *out = result;
    return LK_OK;
}

/* Version 2 carries no strip: the current triangles are stripified
 * (lk_stripify, lodkit's stripifier) on request. */
static lk_status lks2_current_strip(const lk_stream_decoder *decoder, int filtered, uint32_t **strip, size_t *length,
                                    lk_error *error)
{
    const lks2_state *state = &decoder->state2;
    if (!state->has_base)
        return lk_error_set(error, LK_ERR_INVALID, "no strip yet: the base chunk has not been decoded");
    const lks2_mesh *mesh = &state->mesh;
    lk_stripifier used;
    lk_status status = lk_stripify(mesh->corners, mesh->triangle_count, mesh->vertex_count, LK_STRIPIFY_LODKIT, strip,
                                   length, &used, error);
    if (status != LK_OK || !filtered) return status;
    uint32_t *out =
        lk__malloc_array(lk_strip_filter_bound(*length) ? lk_strip_filter_bound(*length) : 1, sizeof(uint32_t));
    if (!out) {
        lk_free(*strip);
        *strip = NULL;
        *length = 0;
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory for a strip");
    }
    *length = lk_strip_filter(*strip, *length, out);
    lk_free(*strip);
    *strip = out;
    return LK_OK;
}

lk_status lk_stream_decoder_mesh(const lk_stream_decoder *decoder, lk_mesh *out, lk_error *error)
{
    if (!decoder || !out) return lk_error_set(error, LK_ERR_INVALID, "lk_stream_decoder_mesh: NULL argument");
    if (decoder->has_info && decoder->header.info.version == 2) return lks2_current_mesh(decoder, out, error);
    const lks_state *state = &decoder->state;
    if (!state->has_base)
        return lk_error_set(error, LK_ERR_INVALID, "no mesh yet: the base chunk has not been decoded");
    size_t length = state->strip_length;
    uint32_t *triangles = lk__malloc_array(length >= 2 ? 3 * (length - 2) : 0, sizeof(uint32_t));
    if (!triangles) return lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu triangles", state->triangles);
    size_t triangle_count = length >= 3 ? lk_strip_triangles(state->resolved, length, triangles) : 0;
    lk_mesh mesh;
    lk_status status = lk_mesh_alloc(&mesh, state->present, triangle_count, 0, error);
    if (status != LK_OK) {
        free(triangles);
        return status;
    }
    const lk_stream_info *info = &decoder->header.info;
    for (size_t v = 0; v < state->present; v++)
        for (int axis = 0; axis < 3; axis++)
            mesh.positions[3 * v + axis] = lks_dequantise(info->quantisation_min[axis], info->quantisation_step[axis],
                                                          state->quantised[3 * v + axis]);
    memcpy(mesh.indices, triangles, 3 * triangle_count * sizeof(uint32_t));
    free(triangles);
    *out = mesh;
    return LK_OK;
}

lk_status lk_stream_decoder_strip(const lk_stream_decoder *decoder, int filtered, uint32_t **strip, size_t *length,
                                  lk_error *error)
{
    if (!decoder || !strip || !length)
        return lk_error_set(error, LK_ERR_INVALID, "lk_stream_decoder_strip: NULL argument");
    *strip = NULL;
    *length = 0;
    if (decoder->has_info && decoder->header.info.version == 2)
        return lks2_current_strip(decoder, filtered, strip, length, error);
    const lks_state *state = &decoder->state;
    if (!state->has_base)
        return lk_error_set(error, LK_ERR_INVALID, "no strip yet: the base chunk has not been decoded");
    size_t capacity = filtered ? lk_strip_filter_bound(state->strip_length) : state->strip_length;
    uint32_t *out = lk__malloc_array(capacity, sizeof(uint32_t));
    if (!out) return lk_error_set(error, LK_ERR_NOMEM, "out of memory for a strip of %zu entries", capacity);
    size_t out_length = state->strip_length;
    if (filtered)
        out_length = lk_strip_filter(state->resolved, state->strip_length, out);
    else
        memcpy(out, state->resolved, state->strip_length * sizeof(uint32_t));
    *strip = out;
    *length = out_length;
    return LK_OK;
}
