/* SPDX-License-Identifier: MIT */
/* The glTF scene writer's binary data: the buffer the accessors are
 * written into, their view records, the grouping of accessors into
 * bufferViews, and EXT_meshopt_compression of those views with
 * meshoptimizer's codecs and filters (Debian's libmeshoptimizer). The
 * writers of attributes (io_gltf_mesh_write.c) and of skins and animations
 * (io_gltf_skin_write.c) fill it. */
#include "bytes.h"
#include "io_gltf.h"

#include <meshoptimizer.h>

#include <pthread.h>
#include <stdlib.h>
#include <string.h>

/* Reserves `bytes` at the end of the buffer, after padding it to 4 bytes;
 * returns the offset (writer->failed on allocation failure). */
size_t lk__gltf_reserve(mesh_writer *writer, size_t bytes)
{
    while (writer->bin.size % 4) {
        if (!lk__buffer_reserve(&writer->bin, 1)) {
            writer->failed = true;
            return 0;
        }
        writer->bin.data[writer->bin.size++] = 0;
    }
    if (!lk__buffer_reserve(&writer->bin, bytes)) {
        writer->failed = true;
        return 0;
    }
    size_t offset = writer->bin.size;
    writer->bin.size += bytes;
    return offset;
}

/* An accessor of `count` elements over [offset, offset + bytes) of the
 * buffer (target 0: data that is not vertex data); its bufferView comes
 * later (group_views). Returns the accessor's
 * JSON (NULL on failure). */
cJSON *lk__gltf_add_accessor(mesh_writer *writer, size_t offset, size_t bytes, size_t stride, int target,
                             int component_type, bool normalized, size_t count, const char *type)
{
    cJSON *accessor = cJSON_CreateObject();
    if (!accessor) {
        writer->failed = true;
        return NULL;
    }
    size_t component_size = component_type == COMPONENT_FLOAT || component_type == COMPONENT_UNSIGNED_INT     ? 4
                            : component_type == COMPONENT_SHORT || component_type == COMPONENT_UNSIGNED_SHORT ? 2
                                                                                                              : 1;
    if (writer->record_count == writer->record_capacity) {
        size_t capacity = writer->record_capacity ? 2 * writer->record_capacity : 16;
        view_record *records = lk__realloc_array(writer->records, capacity, sizeof(view_record));
        if (!records) {
            cJSON_Delete(accessor);
            writer->failed = true;
            return NULL;
        }
        writer->records = records;
        writer->record_capacity = capacity;
    }
    writer->records[writer->record_count++] = (view_record){
        accessor,         offset,      bytes,
        stride,           count,       target == GLTF_TARGET_ELEMENT_ARRAY_BUFFER ? (unsigned)component_size : 0,
        GLTF_FILTER_NONE, target == 0, false};
    cJSON_AddItemToArray(writer->accessors, accessor);
    cJSON_AddNumberToObject(accessor, "bufferView", 0); /* set by group_views */
    cJSON_AddNumberToObject(accessor, "componentType", component_type);
    if (normalized) cJSON_AddBoolToObject(accessor, "normalized", true);
    cJSON_AddNumberToObject(accessor, "count", (double)count);
    cJSON_AddStringToObject(accessor, "type", type);
    writer->accessor_count++;
    return accessor;
}

/* The accessors' bufferViews, as gltfpack lays them out: one view per kind
 * of data (indices of one size; attributes of one stride and filter), the
 * accessors of a kind one after the other in it (byteOffset). Fewer views
 * is less JSON (a bufferView per accessor was 40% of a compressed
 * 2CylinderEngine's bytes), and meshopt's codecs see one long stream per
 * kind. Rewrites writer->bin in that order; writer->records then hold
 * the views (json: the view's JSON). */
bool lk__gltf_group_views(mesh_writer *writer)
{
    size_t record_count = writer->record_count;
    if (record_count == 0) return true;
    size_t *group = lk__malloc_array(record_count, sizeof *group);
    view_record *views = lk__malloc_array(record_count, sizeof *views);
    lk__buffer grouped = {0};
    size_t view_count = 0;
    bool ok = group && views;
    for (size_t i = 0; ok && i < record_count; i++) {
        const view_record *record = &writer->records[i];
        size_t g = 0;
        while (g < view_count && !(views[g].stride == record->stride && views[g].index_size == record->index_size &&
                                   views[g].filter == record->filter && views[g].plain == record->plain &&
                                   views[g].sequence == record->sequence))
            g++;
        if (g == view_count)
            views[view_count++] = (view_record){
                NULL, 0, 0, record->stride, 0, record->index_size, record->filter, record->plain, record->sequence};
        group[i] = g;
    }
    for (size_t g = 0; ok && g < view_count; g++) {
        view_record *view = &views[g];
        while (ok && grouped.size % 4) {
            ok = lk__buffer_reserve(&grouped, 1);
            if (ok) grouped.data[grouped.size++] = 0;
        }
        view->offset = grouped.size;
        for (size_t i = 0; ok && i < record_count; i++) {
            const view_record *record = &writer->records[i];
            if (group[i] != g) continue;
            ok = lk__buffer_reserve(&grouped, record->bytes);
            if (!ok) break;
            cJSON_ReplaceItemInObject(record->json, "bufferView", cJSON_CreateNumber((double)g));
            if (grouped.size > view->offset)
                cJSON_AddNumberToObject(record->json, "byteOffset", (double)(grouped.size - view->offset));
            memcpy(grouped.data + grouped.size, writer->bin.data + record->offset, record->bytes);
            grouped.size += record->bytes;
            view->count += record->count;
        }
        view->bytes = grouped.size - view->offset;
        view->json = ok ? cJSON_CreateObject() : NULL;
        if (!view->json) {
            ok = false;
            break;
        }
        cJSON_AddItemToArray(writer->views, view->json);
        cJSON_AddNumberToObject(view->json, "buffer", 0);
        if (view->offset) cJSON_AddNumberToObject(view->json, "byteOffset", (double)view->offset);
        cJSON_AddNumberToObject(view->json, "byteLength", (double)view->bytes);
        if (view->plain) continue;
        if (!view->index_size) cJSON_AddNumberToObject(view->json, "byteStride", (double)view->stride);
        cJSON_AddNumberToObject(view->json, "target",
                                view->index_size ? GLTF_TARGET_ELEMENT_ARRAY_BUFFER : GLTF_TARGET_ARRAY_BUFFER);
    }
    free(group);
    if (!ok) {
        free(views);
        lk__buffer_free(&grouped);
        return false;
    }
    lk__buffer_free(&writer->bin);
    writer->bin = grouped;
    free(writer->records);
    writer->records = views;
    writer->record_count = writer->record_capacity = view_count;
    writer->view_count += view_count;
    return true;
}

/* `count` elements of `components` floats (target: the view's, 0 for data
 * that is not vertex data); min/max when with_bounds. Returns the accessor
 * index. */
size_t lk__gltf_add_float_data(mesh_writer *writer, const float *values, size_t count, unsigned components,
                               const char *type, bool with_bounds, int target)
{
    size_t bytes = count * components * 4, offset = lk__gltf_reserve(writer, bytes);
    if (writer->failed) return 0;
    double low[16], high[16]; /* up to MAT4 */
    for (unsigned c = 0; c < components && c < 16; c++) low[c] = high[c] = count ? values[c] : 0.0;
    for (size_t i = 0; i < count * components; i++) {
        lk__store_f32le(writer->bin.data + offset + 4 * i, values[i]);
        unsigned c = (unsigned)(i % components);
        if (c >= 16) continue;
        if (values[i] < low[c]) low[c] = values[i];
        if (values[i] > high[c]) high[c] = values[i];
    }
    cJSON *accessor =
        lk__gltf_add_accessor(writer, offset, bytes, 4 * components, target, COMPONENT_FLOAT, false, count, type);
    if (accessor && with_bounds) {
        cJSON *min = cJSON_AddArrayToObject(accessor, "min"), *max = cJSON_AddArrayToObject(accessor, "max");
        for (unsigned c = 0; c < components; c++) {
            /* The float's own value: the validator compares the bounds
             * with the stored floats exactly. */
            cJSON_AddItemToArray(min, cJSON_CreateNumber((double)(float)low[c]));
            cJSON_AddItemToArray(max, cJSON_CreateNumber((double)(float)high[c]));
        }
    }
    return writer->accessor_count - 1;
}

/* Index codec version 1 (meshoptimizer 0.14 and later; every decoder of
 * EXT_meshopt_compression reads it, gltfpack writes it): a few percent
 * smaller than version 0. The setting is process-wide, hence once. */
static pthread_once_t index_version_once = PTHREAD_ONCE_INIT;
static void set_index_version(void) { meshopt_encodeIndexVersion(1); }

/* EXT_meshopt_compression: every view recorded so far encoded into
 * `packed`; the views move to buffer 1 (the fallback without data) and
 * name their compressed bytes in buffer 0. */
bool lk__gltf_compress_views(mesh_writer *writer, lk__buffer *packed)
{
    pthread_once(&index_version_once, set_index_version);
    for (size_t i = 0; i < writer->record_count; i++) {
        const view_record *record = &writer->records[i];
        const unsigned char *source = writer->bin.data + record->offset;
        size_t bound = record->sequence     ? meshopt_encodeIndexSequenceBound(record->count, UINT32_MAX / 2)
                       : record->index_size ? meshopt_encodeIndexBufferBound(record->count, UINT32_MAX / 2)
                                            : meshopt_encodeVertexBufferBound(record->count, record->stride);
        while (packed->size % 4) {
            if (!lk__buffer_reserve(packed, 1)) return false;
            packed->data[packed->size++] = 0;
        }
        if (!lk__buffer_reserve(packed, bound)) return false;
        size_t written;
        if (record->index_size) {
            unsigned int *indices = lk__malloc_array(record->count, sizeof(unsigned int));
            if (!indices) return false;
            for (size_t k = 0; k < record->count; k++)
                indices[k] = record->index_size == 2 ? lk__load_u16le(source + 2 * k) : lk__load_u32le(source + 4 * k);
            written = record->sequence
                          ? meshopt_encodeIndexSequence(packed->data + packed->size, bound, indices, record->count)
                          : meshopt_encodeIndexBuffer(packed->data + packed->size, bound, indices, record->count);
            free(indices);
        } else {
            written =
                meshopt_encodeVertexBuffer(packed->data + packed->size, bound, source, record->count, record->stride);
        }
        if (written == 0) return false;
        cJSON *extension = cJSON_CreateObject();
        if (!extension) return false;
        cJSON_AddNumberToObject(extension, "buffer", 0);
        cJSON_AddNumberToObject(extension, "byteOffset", (double)packed->size);
        cJSON_AddNumberToObject(extension, "byteLength", (double)written);
        cJSON_AddNumberToObject(extension, "byteStride",
                                (double)(record->index_size ? record->index_size : record->stride));
        cJSON_AddStringToObject(extension, "mode",
                                record->sequence     ? "INDICES"
                                : record->index_size ? "TRIANGLES"
                                                     : "ATTRIBUTES");
        static const char *const filters[] = {NULL, "OCTAHEDRAL", "QUATERNION", "EXPONENTIAL"};
        if (record->filter != GLTF_FILTER_NONE) cJSON_AddStringToObject(extension, "filter", filters[record->filter]);
        cJSON_AddNumberToObject(extension, "count", (double)record->count);
        cJSON_AddItemToObject(cJSON_AddObjectToObject(record->json, "extensions"), "EXT_meshopt_compression",
                              extension);
        cJSON_ReplaceItemInObject(record->json, "buffer", cJSON_CreateNumber(1));
        packed->size += written;
    }
    return true;
}

/* `count` floats equal in a and b, or both absent. */
bool lk__gltf_same_floats(const float *a, const float *b, size_t count)
{
    if (!a || !b) return a == b;
    return a == b || memcmp(a, b, count * sizeof(float)) == 0;
}
