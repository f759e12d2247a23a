/* SPDX-License-Identifier: MIT */
/* Progressive stream format (.lks): the encoder (lk_stream_encode) and
 * lk_stream_write_file. Positions are quantised, the base mesh and every
 * chunk of vertex splits are written as the decoder will read them
 * (predictions follow the decoder's state), each payload is deflated when
 * that is smaller, and the decoding core (stream_decode.c) decodes all of
 * it before any byte leaves the encoder: that yields the triangle counts
 * of the chunk table and proves that the stream decodes back to the
 * progressive strip it was given. */
#include "bytes.h"
#include "stream2_internal.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

/* ---- encoder -------------------------------------------------------------- */

void lk_stream_options_default(lk_stream_options *options)
{
    memset(options, 0, sizeof *options);
    options->position_bits = 0;
    options->splits_per_chunk = 1024;
    options->compress = 1;
}

typedef struct lks_encoding {
    size_t base, splits, vertex_count, length;
    int32_t top;
    int32_t *base_quantised;  /* 3 * base */
    int32_t *split_quantised; /* 3 * splits: q's position */
    int32_t *kept_quantised;  /* 3 * splits: p's position after the split */
    uint32_t *resolved;       /* the base-level strip r_0 */
    lk__buffer masks;         /* mask bytes, collapse order */
    size_t *mask_offset;      /* splits: where split k's mask starts in masks */
    uint32_t *mask_bits;      /* splits: candidates of split k */
} lks_encoding;

static void lks_encoding_free(lks_encoding *encoding)
{
    free(encoding->base_quantised);
    free(encoding->split_quantised);
    free(encoding->kept_quantised);
    free(encoding->resolved);
    lk__buffer_free(&encoding->masks);
    free(encoding->mask_offset);
    free(encoding->mask_bits);
}

/* Computes every split's mask by collapsing the full strip back to the base
 * level (split k from the last to the first: q's entries merge into p's
 * list, and the mask marks which merged entries came from q), and leaves
 * the base-level strip in encoding->resolved. */
static lk_status lks_compute_masks(const lk_progressive_mesh *pm, const lk_progressive_strips *ps,
                                   lks_encoding *encoding, lk_error *error)
{
    size_t vertex_count = encoding->vertex_count, length = encoding->length;
    uint32_t *head = lk__malloc_array(vertex_count, sizeof(uint32_t));
    uint32_t *next = lk__malloc_array(length, sizeof(uint32_t));
    encoding->resolved = lk__malloc_array(length, sizeof(uint32_t));
    encoding->mask_offset = lk__malloc_array(encoding->splits, sizeof(size_t));
    encoding->mask_bits = lk__malloc_array(encoding->splits, sizeof(uint32_t));
    if (!head || !next || !encoding->resolved || !encoding->mask_offset || !encoding->mask_bits) {
        free(head);
        free(next);
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory for a strip of %zu entries", length);
    }
    for (size_t v = 0; v < vertex_count; v++) head[v] = LKS_NONE;
    for (size_t j = length; j-- > 0;) {
        uint32_t v = ps->strip[j];
        next[j] = head[v];
        head[v] = (uint32_t)j;
    }
    for (size_t k = encoding->splits; k-- > 0;) {
        uint32_t q = (uint32_t)(encoding->base + k), kept = pm->splits[k].kept;
        /* First pass counts the merged list so its mask can be reserved. */
        size_t candidates = 0;
        for (uint32_t j = head[kept]; j != LKS_NONE; j = next[j]) candidates++;
        for (uint32_t j = head[q]; j != LKS_NONE; j = next[j]) candidates++;
        if (candidates > UINT32_MAX) {
            free(head);
            free(next);
            return lk_error_set(error, LK_ERR_LIMIT, "split %zu: %zu candidate strip entries", k, candidates);
        }
        size_t bytes = (candidates + 7) / 8;
        encoding->mask_offset[k] = encoding->masks.size;
        encoding->mask_bits[k] = (uint32_t)candidates;
        if (!lk__buffer_reserve(&encoding->masks, bytes)) {
            free(head);
            free(next);
            return lk_error_set(error, LK_ERR_NOMEM, "out of memory for split masks");
        }
        unsigned char *mask = encoding->masks.data + encoding->masks.size;
        memset(mask, 0, bytes);
        encoding->masks.size += bytes;
        uint32_t a = head[kept], b = head[q];
        uint32_t *tail = &head[kept];
        size_t bit = 0;
        while (a != LKS_NONE || b != LKS_NONE) {
            if (b == LKS_NONE || (a != LKS_NONE && a < b)) {
                *tail = a;
                tail = &next[a];
                a = next[a];
            } else {
                *tail = b;
                tail = &next[b];
                b = next[b];
                mask[bit >> 3] |= (unsigned char)(1u << (bit & 7));
            }
            bit++;
        }
        *tail = LKS_NONE;
        head[q] = LKS_NONE;
    }
    for (size_t v = 0; v < encoding->base; v++)
        for (uint32_t j = head[v]; j != LKS_NONE; j = next[j]) encoding->resolved[j] = (uint32_t)v;
    free(head);
    free(next);
    return LK_OK;
}

/* Raw payload of the base chunk. */
static void lks_write_base(const lks_encoding *encoding, lks_writer *payload)
{
    lks_writer positions = {0};
    int64_t previous[3] = {0, 0, 0};
    for (size_t v = 0; v < encoding->base; v++)
        for (int axis = 0; axis < 3; axis++) {
            int64_t value = encoding->base_quantised[3 * v + axis];
            lks_write_varint(&positions, lks_zigzag(value - previous[axis]));
            previous[axis] = value;
        }
    lks_write_varint(payload, positions.buffer.size);
    payload->section_start[0] = payload->buffer.size;
    lks_write_bytes(payload, positions.buffer.data, positions.buffer.size);
    payload->section_start[1] = payload->buffer.size;
    payload->section_count = 2;
    if (positions.failed) payload->failed = true;
    lk__buffer_free(&positions.buffer);

    const uint32_t *r = encoding->resolved;
    int64_t literal = 0;
    lks_recent recent = {{0}, 0};
    for (size_t j = 0; j < encoding->length; j++) {
        if (j >= 1 && r[j] == r[j - 1]) {
            lks_write_varint(payload, 0);
        } else if (j >= 2 && r[j] == r[j - 2]) {
            lks_write_varint(payload, 1);
        } else {
            unsigned index = lk__lks_recent_use(&recent, r[j]);
            if (index < LKS_RECENT_SIZE) {
                lks_write_varint(payload, LKS_TOKEN_RECENT + index);
            } else {
                lks_write_varint(payload, LKS_TOKEN_LITERAL + lks_zigzag((int64_t)r[j] - literal));
                literal = r[j];
            }
        }
    }
}

/* Raw payload of the split chunk [first, first + count). `state` is the
 * decoder's view at level `first` and is advanced exactly as a decoder
 * would, so the predictions made here are the ones the decoder makes. */
static void lks_write_splits(const lk_progressive_mesh *pm, const lks_encoding *encoding, size_t first, size_t count,
                             lks_state *state, lks_writer *payload)
{
    lks_writer kept_section = {0}, mask_section = {0}, position_section = {0};
    for (size_t k = first; k < first + count; k++) {
        uint32_t kept = pm->splits[k].kept;
        uint32_t q = (uint32_t)state->present;
        const int32_t *split_position = &encoding->split_quantised[3 * k];
        const int32_t *kept_position = &encoding->kept_quantised[3 * k];
        const unsigned char *mask = encoding->masks.data + encoding->mask_offset[k];
        bool moved = memcmp(kept_position, &state->quantised[3 * (size_t)kept], 3 * sizeof(int32_t)) != 0;
        lks_write_varint(&kept_section, (uint64_t)kept << 1 | (moved ? 1u : 0u));
        lks_write_bytes(&mask_section, mask, ((size_t)encoding->mask_bits[k] + 7) / 8);
        lk__lks_split_entries(state, kept, mask);
        int64_t predicted[3];
        lk__lks_predict_split(state, q, kept, predicted);
        for (int axis = 0; axis < 3; axis++)
            lks_write_varint(&position_section, lks_zigzag(split_position[axis] - predicted[axis]));
        memcpy(&state->quantised[3 * (size_t)q], split_position, 3 * sizeof(int32_t));
        if (moved) {
            lk__lks_predict_kept(state, kept, predicted);
            for (int axis = 0; axis < 3; axis++)
                lks_write_varint(&position_section, lks_zigzag(kept_position[axis] - predicted[axis]));
            memcpy(&state->quantised[3 * (size_t)kept], kept_position, 3 * sizeof(int32_t));
        }
    }
    lks_write_varint(payload, kept_section.buffer.size);
    lks_write_varint(payload, mask_section.buffer.size);
    payload->section_start[0] = payload->buffer.size;
    lks_write_bytes(payload, kept_section.buffer.data, kept_section.buffer.size);
    payload->section_start[1] = payload->buffer.size;
    lks_write_bytes(payload, mask_section.buffer.data, mask_section.buffer.size);
    payload->section_start[2] = payload->buffer.size;
    lks_write_bytes(payload, position_section.buffer.data, position_section.buffer.size);
    payload->section_count = 3;
    if (kept_section.failed || mask_section.failed || position_section.failed) payload->failed = true;
    lk__buffer_free(&kept_section.buffer);
    lk__buffer_free(&mask_section.buffer);
    lk__buffer_free(&position_section.buffer);
}

/* Deflates a chunk payload (zlib format, level 9), ending a deflate block
 * at each section start so every section gets Huffman codes of its own
 * (3.6% smaller on the bunny than one run over the whole payload; any
 * inflater reads it). Returns NULL, and the caller stores the payload raw,
 * when that is not smaller or zlib fails. */
static unsigned char *lks_deflate(const lks_writer *payload, size_t *stored_size)
{
    size_t raw_size = payload->buffer.size;
    if (raw_size > UINT32_MAX) return NULL;
    z_stream stream;
    memset(&stream, 0, sizeof stream);
    if (deflateInit2(&stream, 9, Z_DEFLATED, 15, 9, Z_DEFAULT_STRATEGY) != Z_OK) return NULL;
    /* Each block boundary costs at most a few bytes beyond deflateBound. */
    size_t capacity = deflateBound(&stream, (uLong)raw_size) + 64;
    unsigned char *out = malloc(capacity);
    if (!out) {
        deflateEnd(&stream);
        return NULL;
    }
    stream.next_out = out;
    stream.avail_out = (uInt)capacity;
    size_t start = 0;
    int result = Z_OK;
    for (int section = 0; section <= payload->section_count && result != Z_STREAM_END; section++) {
        bool last = section == payload->section_count;
        size_t end = last ? raw_size : payload->section_start[section];
        stream.next_in = payload->buffer.data + start;
        stream.avail_in = (uInt)(end - start);
        result = deflate(&stream, last ? Z_FINISH : Z_BLOCK);
        if (result != Z_OK && result != Z_STREAM_END && result != Z_BUF_ERROR) break;
        start = end;
    }
    size_t total = stream.total_out;
    deflateEnd(&stream);
    if (result != Z_STREAM_END || total >= raw_size) {
        free(out);
        return NULL;
    }
    *stored_size = total;
    return out;
}

static lk_status lks_check_inputs(const lk_progressive_mesh *pm, const lk_progressive_strips *ps,
                                  const lk_stream_options *options, lk_error *error)
{
    if (options->position_bits != 0 && (options->position_bits < 4 || options->position_bits > 24))
        return lk_error_set(error, LK_ERR_INVALID, "position_bits %u: use 0 (automatic) or 4..24",
                            options->position_bits);
    if (options->splits_per_chunk < 1 || options->splits_per_chunk > UINT32_MAX)
        return lk_error_set(error, LK_ERR_INVALID, "splits_per_chunk %zu: use 1..%u", options->splits_per_chunk,
                            (unsigned)UINT32_MAX);
    if (pm->vertex_count > LK_MAX_ELEMENTS || pm->triangle_count > LK_MAX_ELEMENTS ||
        ps->strip_length > LK_MAX_ELEMENTS)
        return lk_error_set(error, LK_ERR_LIMIT, "progressive mesh too large for a stream");
    if (pm->base_vertex_count > pm->vertex_count || pm->split_count != pm->vertex_count - pm->base_vertex_count)
        return lk_error_set(error, LK_ERR_INVALID, "progressive mesh: %zu vertices is not base %zu + %zu splits",
                            pm->vertex_count, pm->base_vertex_count, pm->split_count);
    if ((pm->base_vertex_count && !pm->base_positions) || (pm->split_count && !pm->splits) ||
        (ps->strip_length && !ps->strip))
        return lk_error_set(error, LK_ERR_INVALID, "progressive mesh or strips without their arrays");
    for (size_t k = 0; k < pm->split_count; k++)
        if (pm->splits[k].kept >= pm->base_vertex_count + k)
            return lk_error_set(error, LK_ERR_INVALID, "split %zu: kept vertex %u is not present before the split", k,
                                (unsigned)pm->splits[k].kept);
    for (size_t j = 0; j < ps->strip_length; j++)
        if (ps->strip[j] >= pm->vertex_count)
            return lk_error_set(error, LK_ERR_INVALID, "strip entry %zu: vertex %u is not a vertex of the mesh (%zu)",
                                j, (unsigned)ps->strip[j], pm->vertex_count);
    return LK_OK;
}

lk_status lk_stream_encode(const lk_progressive_mesh *pm, const lk_progressive_strips *ps,
                           const lk_stream_options *options, unsigned char **bytes, size_t *size, lk_error *error)
{
    lk_stream_options defaults;
    lk_stream_options_default(&defaults);
    if (!options) options = &defaults;
    if (!pm || (!ps && options->version != 2) || !bytes || !size)
        return lk_error_set(error, LK_ERR_INVALID, "lk_stream_encode: NULL argument");
    *bytes = NULL;
    *size = 0;
    if (options->version > 2)
        return lk_error_set(error, LK_ERR_INVALID, "stream version %llu: use 1 or 2",
                            (unsigned long long)options->version);
    if (options->version == 2) return lk__lks2_encode(pm, NULL, options, bytes, size, NULL, error);
    lk_status status = lks_check_inputs(pm, ps, options, error);
    if (status != LK_OK) return status;

    lks_header header;
    memset(&header, 0, sizeof header);
    lk_stream_info *info = &header.info;
    status = lk__lks_choose_quantisation(pm, options->position_bits, info->quantisation_min, info->quantisation_step,
                                         &info->position_bits, error);
    if (status != LK_OK) return status;
    header.quantised_max = (int32_t)((1u << info->position_bits) - 1);
    info->version = LKS_VERSION;
    info->vertex_count = pm->vertex_count;
    info->base_vertex_count = pm->base_vertex_count;
    info->split_count = pm->split_count;
    info->strip_length = ps->strip_length;
    info->quantisation_error =
        lk__lks_quantisation_error(info->quantisation_min, info->quantisation_step, info->position_bits);
    info->diagonal = isfinite(pm->diagonal) && pm->diagonal >= 0 ? pm->diagonal : 0;
    size_t splits_per_chunk = options->splits_per_chunk;
    size_t split_chunks = (pm->split_count + splits_per_chunk - 1) / splits_per_chunk;
    info->chunk_count = 1 + split_chunks;
    header.splits_per_chunk = splits_per_chunk;
    if (info->chunk_count > (UINT32_MAX - LKS_FIXED_HEADER_SIZE - LKS_TABLE_CRC_SIZE) / LKS_TABLE_ENTRY_SIZE)
        return lk_error_set(error, LK_ERR_LIMIT, "%zu chunks do not fit in a chunk table", info->chunk_count);

    lks_encoding encoding;
    memset(&encoding, 0, sizeof encoding);
    encoding.base = pm->base_vertex_count;
    encoding.splits = pm->split_count;
    encoding.vertex_count = pm->vertex_count;
    encoding.length = ps->strip_length;
    encoding.top = header.quantised_max;
    lks_writer *payloads = lk__calloc_array(info->chunk_count, sizeof(lks_writer));
    lk_stream_chunk_info *chunks = lk__calloc_array(info->chunk_count, sizeof(lk_stream_chunk_info));
    unsigned char **stored = lk__calloc_array(info->chunk_count, sizeof(unsigned char *));
    size_t *stored_sizes = lk__calloc_array(info->chunk_count, sizeof(size_t));
    int32_t *current = lk__malloc_array(pm->vertex_count, 3 * sizeof(int32_t));
    encoding.base_quantised = lk__malloc_array(encoding.base, 3 * sizeof(int32_t));
    encoding.split_quantised = lk__malloc_array(encoding.splits, 3 * sizeof(int32_t));
    encoding.kept_quantised = lk__malloc_array(encoding.splits, 3 * sizeof(int32_t));
    lks_state state = {0}, writer_state = {0};
    lks_undo undo = {0};
    if (!payloads || !chunks || !stored || !stored_sizes || !current || !encoding.base_quantised ||
        !encoding.split_quantised || !encoding.kept_quantised) {
        status = lk_error_set(error, LK_ERR_NOMEM, "out of memory encoding a stream");
        goto done;
    }

    const float *min = info->quantisation_min, *step = info->quantisation_step;
    for (size_t v = 0; v < encoding.base; v++)
        for (int axis = 0; axis < 3; axis++)
            encoding.base_quantised[3 * v + axis] =
                lk__lks_quantise(pm->base_positions[3 * v + axis], min[axis], step[axis], encoding.top);
    for (size_t k = 0; k < encoding.splits; k++)
        for (int axis = 0; axis < 3; axis++) {
            encoding.split_quantised[3 * k + axis] =
                lk__lks_quantise(pm->splits[k].position[axis], min[axis], step[axis], encoding.top);
            encoding.kept_quantised[3 * k + axis] =
                lk__lks_quantise(pm->splits[k].kept_position[axis], min[axis], step[axis], encoding.top);
        }
    status = lks_compute_masks(pm, ps, &encoding, error);
    if (status != LK_OK) goto done;

    /* The positions every vertex ends with, replayed independently of the
     * decoding core for the self-check below. */
    memcpy(current, encoding.base_quantised, encoding.base * 3 * sizeof(int32_t));
    for (size_t k = 0; k < encoding.splits; k++) {
        memcpy(&current[3 * (encoding.base + k)], &encoding.split_quantised[3 * k], 3 * sizeof(int32_t));
        memcpy(&current[3 * (size_t)pm->splits[k].kept], &encoding.kept_quantised[3 * k], 3 * sizeof(int32_t));
    }

    /* Raw payloads. The split writer follows the decoder's state (base
     * level first), since predictions depend on it. */
    lks_write_base(&encoding, &payloads[0]);
    if (payloads[0].failed) {
        status = lk_error_set(error, LK_ERR_NOMEM, "out of memory writing the base chunk");
        goto done;
    }
    {
        lk_error check = {0};
        lks_where where = {0, 0};
        status = lk__lks_decode_base(&writer_state, &header, payloads[0].buffer.data, payloads[0].buffer.size, &where,
                                     &check);
        if (status == LK_OK) status = lk__lks_state_reserve(&writer_state, encoding.vertex_count, &check);
        if (status != LK_OK) {
            status = lk_error_set(error, status == LK_ERR_NOMEM ? LK_ERR_NOMEM : LK_ERR_INVALID,
                                  "stream self-check failed: %s", check.message);
            goto done;
        }
    }
    for (size_t c = 1; c < info->chunk_count; c++) {
        size_t first = (c - 1) * splits_per_chunk;
        size_t count = first + splits_per_chunk <= encoding.splits ? splits_per_chunk : encoding.splits - first;
        chunks[c].first_split = (uint32_t)first;
        chunks[c].split_count = (uint32_t)count;
        lks_write_splits(pm, &encoding, first, count, &writer_state, &payloads[c]);
    }
    for (size_t c = 0; c < info->chunk_count; c++) {
        if (payloads[c].failed) {
            status = lk_error_set(error, LK_ERR_NOMEM, "out of memory writing chunk %zu", c);
            goto done;
        }
        if (payloads[c].buffer.size > UINT32_MAX - LKS_CHUNK_HEADER_SIZE) {
            status = lk_error_set(error, LK_ERR_LIMIT,
                                  "chunk %zu: payload of %zu bytes exceeds 4 GiB (use fewer "
                                  "splits per chunk)",
                                  c, payloads[c].buffer.size);
            goto done;
        }
    }

    /* Decode what was written: triangle counts for the table, and proof that
     * the stream gives back the progressive strip and the positions. */
    for (size_t c = 0; c < info->chunk_count; c++) {
        lks_where where = {c, 0};
        const unsigned char *payload = payloads[c].buffer.data;
        size_t payload_size = payloads[c].buffer.size;
        lk_error check = {0};
        if (c == 0) {
            status = lk__lks_decode_base(&state, &header, payload, payload_size, &where, &check);
        } else {
            status = lk__lks_apply_chunk(&state, &undo, payload, payload_size, &chunks[c], chunks[c].split_count, false,
                                         &where, &check);
        }
        if (status != LK_OK) {
            /* The encoder wrote something its decoder refuses: a bug here, or
             * inputs this format cannot carry. */
            status = lk_error_set(error, status == LK_ERR_NOMEM ? LK_ERR_NOMEM : LK_ERR_INVALID,
                                  "stream self-check failed: %s", check.message);
            goto done;
        }
        chunks[c].triangle_count = (uint32_t)state.triangles;
        if (c == 0) info->base_triangle_count = state.triangles;
    }
    info->triangle_count = state.triangles;
    if ((encoding.length && memcmp(state.resolved, ps->strip, encoding.length * sizeof(uint32_t)) != 0) ||
        (encoding.vertex_count && memcmp(state.quantised, current, encoding.vertex_count * 3 * sizeof(int32_t)) != 0)) {
        status = lk_error_set(error, LK_ERR_INVALID, "stream self-check failed: the decoded full level differs");
        goto done;
    }
    if (info->triangle_count != pm->triangle_count) {
        status = lk_error_set(error, LK_ERR_INVALID,
                              "the progressive strip draws %zu triangles but the progressive mesh has %zu (strips "
                              "built from another mesh?)",
                              info->triangle_count, pm->triangle_count);
        goto done;
    }

    /* Stored payloads, the table and the header. */
    for (size_t c = 0; c < info->chunk_count; c++) {
        size_t raw_size = payloads[c].buffer.size;
        stored_sizes[c] = raw_size;
        if (options->compress && raw_size > 0) {
            stored[c] = lks_deflate(&payloads[c], &stored_sizes[c]);
            if (!stored[c]) stored_sizes[c] = raw_size;
        }
        if (!stored[c]) {
            stored[c] = lk__buffer_take(&payloads[c].buffer);
            if (!stored[c] && raw_size == 0) stored[c] = NULL;
        }
        chunks[c].raw_size = (uint32_t)raw_size;
    }
    status = lk__lks_assemble(&header, chunks, stored, stored_sizes, bytes, size, error);
    goto done;


done:
    if (payloads)
        for (size_t c = 0; c < info->chunk_count; c++) lk__buffer_free(&payloads[c].buffer);
    if (stored)
        for (size_t c = 0; c < info->chunk_count; c++) free(stored[c]);
    free(payloads);
    free(stored);
    free(stored_sizes);
    free(chunks);
    free(current);
    lks_encoding_free(&encoding);
    lk__lks_state_free(&state);
    lk__lks_state_free(&writer_state);
    lk__lks_undo_free(&undo);
    return status;
}

lk_status lk_stream_encode_with_attributes(const lk_progressive_mesh *pm, const lk_mesh *input,
                                           const lk_stream_options *options, unsigned char **bytes, size_t *size,
                                           lk_error *error)
{
    lk_stream_options defaults;
    lk_stream_options_default(&defaults);
    defaults.version = 2;
    if (!options) options = &defaults;
    if (!pm || !bytes || !size)
        return lk_error_set(error, LK_ERR_INVALID, "lk_stream_encode_with_attributes: NULL argument");
    *bytes = NULL;
    *size = 0;
    if (options->version != 2)
        return lk_error_set(error, LK_ERR_INVALID, "stream attributes need version 2 (options.version = 2)");
    if (options->normal_bits != 0 && (options->normal_bits < 4 || options->normal_bits > 16))
        return lk_error_set(error, LK_ERR_INVALID, "normal_bits %llu: use 0 (10) or 4..16",
                            (unsigned long long)options->normal_bits);
    if (options->texcoord_bits != 0 && (options->texcoord_bits < 4 || options->texcoord_bits > 24))
        return lk_error_set(error, LK_ERR_INVALID, "texcoord_bits %llu: use 0 (12) or 4..24",
                            (unsigned long long)options->texcoord_bits);
    return lk__lks2_encode(pm, input, options, bytes, size, NULL, error);
}

lk_status lk_stream_write_file(const char *path, const unsigned char *bytes, size_t size, lk_error *error)
{
    if (!path || (!bytes && size)) return lk_error_set(error, LK_ERR_INVALID, "lk_stream_write_file: NULL argument");
    lk__atomic_file file;
    lk_status status = lk__atomic_open(&file, path, error);
    if (status != LK_OK) return status;
    if (size && fwrite(bytes, 1, size, file.file) != size) {
        lk_error_set(error, LK_ERR_IO, "%s: write error", path);
        return lk__atomic_fail(&file, error);
    }
    return lk__atomic_commit(&file, error);
}
