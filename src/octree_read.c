/* SPDX-License-Identifier: MIT */
/* Reading point octrees (lodkit.h, "Point octrees"; docs/formats.md,
 * "Point octree"): the JSON index parsed and checked (lk_octree_open,
 * lk_octree_open_memory), nodes loaded with their length and CRC-32
 * checked (lk_octree_load_node, lk_octree_load_node_quantized), and the
 * helpers the builder (src/octree.c) shares. */
#include "bytes.h"
#include "internal.h"
#include "octree_internal.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <zlib.h>

uint32_t lk__octree_crc32(const unsigned char *bytes, size_t size)
{
    uLong crc = crc32(0L, Z_NULL, 0);
    while (size > 0) { /* zlib takes uInt lengths */
        uInt piece = size > (1u << 30) ? (1u << 30) : (uInt)size;
        crc = crc32(crc, bytes, piece);
        bytes += piece;
        size -= piece;
    }
    return (uint32_t)crc;
}

void lk__octree_oct_decode(const uint16_t in[2], float n[3])
{
    float x = in[0] / 65535.0f * 2.0f - 1.0f, y = in[1] / 65535.0f * 2.0f - 1.0f;
    float z = 1.0f - fabsf(x) - fabsf(y);
    if (z < 0.0f) {
        float fx = (1.0f - fabsf(y)) * (x >= 0.0f ? 1.0f : -1.0f);
        float fy = (1.0f - fabsf(x)) * (y >= 0.0f ? 1.0f : -1.0f);
        x = fx;
        y = fy;
    }
    float length = sqrtf(x * x + y * y + z * z);
    n[0] = x / length;
    n[1] = y / length;
    n[2] = z / length;
}

char *lk__octree_join_path(const char *folder, const char *name)
{
    size_t a = strlen(folder), c = strlen(name);
    char *path = malloc(a + c + 2);
    if (!path) return NULL;
    memcpy(path, folder, a);
    path[a] = '/';
    memcpy(path + a + 1, name, c + 1);
    return path;
}

/* ---- reading an octree ------------------------------------------------------------- */

struct lk_octree {
    lk_octree_info info;
    lk_octree_node *nodes;
    char *names;     /* the nodes' names, NUL-separated */
    char *data_path; /* NULL: opened from memory */
    char *index_name;
};

void lk_octree_close(lk_octree *octree)
{
    if (!octree) return;
    free(octree->nodes);
    free(octree->names);
    free(octree->data_path);
    free(octree->index_name);
    free(octree);
}

const lk_octree_info *lk_octree_get_info(const lk_octree *octree) { return &octree->info; }

const lk_octree_node *lk_octree_node_at(const lk_octree *octree, size_t index)
{
    return index < octree->info.node_count ? &octree->nodes[index] : NULL;
}

/* Largest integer a JSON number (a double) holds exactly. */
#define OT_JSON_MAX_INTEGER 9007199254740992.0

static bool json_uint(const cJSON *item, double most, uint64_t *out)
{
    if (!cJSON_IsNumber(item)) return false;
    double v = item->valuedouble;
    if (!(v >= 0.0 && v <= most && v == floor(v))) return false;
    *out = (uint64_t)v;
    return true;
}

static bool json_finite(const cJSON *item, double *out)
{
    if (!cJSON_IsNumber(item) || !isfinite(item->valuedouble)) return false;
    *out = item->valuedouble;
    return true;
}

static bool json_vector3(const cJSON *item, double out[3])
{
    if (!cJSON_IsArray(item) || cJSON_GetArraySize(item) != 3) return false;
    for (int k = 0; k < 3; k++)
        if (!json_finite(cJSON_GetArrayItem(item, k), &out[k])) return false;
    return true;
}

static lk_status parse_index(lk_octree *o, const char *text, size_t size, const char *name, lk_error *error)
{
    char *copy = malloc(size + 1);
    if (!copy) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    memcpy(copy, text, size);
    copy[size] = '\0';
    const char *end = NULL;
    cJSON *root = cJSON_ParseWithLengthOpts(copy, size, &end, 0);
    if (root) {
        while (end < copy + size && (*end == ' ' || *end == '\t' || *end == '\r' || *end == '\n')) end++;
    }
    if (!root || end < copy + size) {
        size_t offset = end && end >= copy && end <= copy + size ? (size_t)(end - copy) : 0;
        size_t line = 1;
        for (size_t i = 0; i < offset; i++) line += copy[i] == '\n';
        cJSON_Delete(root);
        free(copy);
        return lk__error_at_line(error, LK_ERR_PARSE, name, line, "%s",
                                 root ? "unexpected data after the JSON document" : "invalid JSON");
    }
    free(copy);
    lk_status status = LK_OK;
    lk_octree_info *info = &o->info;
    const cJSON *item = cJSON_GetObjectItemCaseSensitive(root, "format");
    uint64_t number;
#define FAIL(...)                                                                                                      \
    do {                                                                                                               \
        status = lk_error_set(error, LK_ERR_PARSE, __VA_ARGS__);                                                       \
        goto done;                                                                                                     \
    } while (0)
    if (!cJSON_IsObject(root)) FAIL("%s: the index is not a JSON object", name);
    if (!cJSON_IsString(item) || strcmp(item->valuestring, OT_FORMAT_NAME) != 0)
        FAIL("%s: \"format\" is not \"%s\"", name, OT_FORMAT_NAME);
    if (!json_uint(cJSON_GetObjectItemCaseSensitive(root, "version"), 1e9, &number) || number < OT_OLDEST_VERSION ||
        number > OT_VERSION)
        FAIL("%s: \"version\" is not %d to %d (this reader reads versions %d to %d)", name, OT_OLDEST_VERSION,
             OT_VERSION, OT_OLDEST_VERSION, OT_VERSION);
    item = cJSON_GetObjectItemCaseSensitive(root, "data");
    if (!cJSON_IsString(item) || !item->valuestring[0] || strchr(item->valuestring, '/') ||
        strchr(item->valuestring, '\\') || item->valuestring[0] == '.')
        FAIL("%s: \"data\" is not a plain file name", name);
    if (o->data_path) {
        char *slash = strrchr(o->data_path, '/');
        size_t folder = slash ? (size_t)(slash - o->data_path) : 0;
        char *path = malloc(folder + strlen(item->valuestring) + 2);
        if (!path) FAIL("out of memory");
        if (slash)
            snprintf(path, folder + strlen(item->valuestring) + 2, "%.*s/%s", (int)folder, o->data_path,
                     item->valuestring);
        else
            strcpy(path, item->valuestring);
        free(o->data_path);
        o->data_path = path;
    }
    if (!json_uint(cJSON_GetObjectItemCaseSensitive(root, "points"), OT_JSON_MAX_INTEGER, &info->points))
        FAIL("%s: \"points\" is not a count", name);
    if (!json_finite(cJSON_GetObjectItemCaseSensitive(root, "spacing"), &info->spacing) || !(info->spacing > 0))
        FAIL("%s: \"spacing\" is not a positive number", name);
    if (!json_vector3(cJSON_GetObjectItemCaseSensitive(root, "scale"), info->scale) || !(info->scale[0] > 0) ||
        !(info->scale[1] > 0) || !(info->scale[2] > 0))
        FAIL("%s: \"scale\" is not three positive numbers", name);
    if (!json_vector3(cJSON_GetObjectItemCaseSensitive(root, "offset"), info->offset))
        FAIL("%s: \"offset\" is not three numbers", name);
    if (!json_finite(cJSON_GetObjectItemCaseSensitive(root, "cube_size"), &info->cube_size) || !(info->cube_size > 0))
        FAIL("%s: \"cube_size\" is not a positive number", name);
    const cJSON *bounds = cJSON_GetObjectItemCaseSensitive(root, "bounds");
    if (!json_vector3(cJSON_GetObjectItemCaseSensitive(bounds, "min"), info->min) ||
        !json_vector3(cJSON_GetObjectItemCaseSensitive(bounds, "max"), info->max))
        FAIL("%s: \"bounds\" has no \"min\" and \"max\" of three numbers", name);
    /* attributes: position, [rgb], [normal], radius, [clip], in that order */
    const cJSON *attributes = cJSON_GetObjectItemCaseSensitive(root, "attributes");
    enum { KNOWN = 5 };
    static const char *const known[KNOWN][2] = {
        {"position", "int32x3"}, {"rgb", "uint8x3"}, {"normal", "oct16"}, {"radius", "float32"}, {"clip", "snorm8x4"}};
    static const int known_bytes[KNOWN] = {12, 3, 4, 4, 4};
    int next = 0, seen[KNOWN] = {0};
    size_t stride = 0;
    if (!cJSON_IsArray(attributes)) FAIL("%s: \"attributes\" is not an array", name);
    const cJSON *attribute;
    cJSON_ArrayForEach(attribute, attributes)
    {
        const cJSON *a_name = cJSON_GetObjectItemCaseSensitive(attribute, "name");
        const cJSON *a_encoding = cJSON_GetObjectItemCaseSensitive(attribute, "encoding");
        if (!cJSON_IsString(a_name) || !cJSON_IsString(a_encoding))
            FAIL("%s: an attribute without name and encoding", name);
        int which = -1;
        for (int a = next; a < KNOWN; a++)
            if (strcmp(a_name->valuestring, known[a][0]) == 0) which = a;
        if (which < 0)
            FAIL("%s: attribute \"%.64s\" is unknown or out of order (expected position, rgb, normal, radius, clip)",
                 name, a_name->valuestring);
        if (strcmp(a_encoding->valuestring, known[which][1]) != 0)
            FAIL("%s: attribute %s: encoding \"%.64s\" (expected %s)", name, known[which][0], a_encoding->valuestring,
                 known[which][1]);
        if (!json_uint(cJSON_GetObjectItemCaseSensitive(attribute, "bytes"), 64, &number) ||
            number != (uint64_t)known_bytes[which])
            FAIL("%s: attribute %s: \"bytes\" is not %d", name, known[which][0], known_bytes[which]);
        seen[which] = 1;
        stride += (size_t)known_bytes[which];
        next = which + 1;
    }
    if (!seen[0] || !seen[3]) FAIL("%s: the attributes must include position and radius", name);
    if (seen[4] && !seen[2]) FAIL("%s: attribute clip needs normal (a clip line lies in the tangent plane)", name);
    info->has_colors = seen[1];
    info->has_normals = seen[2];
    info->has_clips = seen[4];
    if (!json_uint(cJSON_GetObjectItemCaseSensitive(root, "stride"), 64, &number) || number != stride)
        FAIL("%s: \"stride\" is not %zu (the attributes' bytes)", name, stride);
    info->stride = stride;
    const cJSON *nodes = cJSON_GetObjectItemCaseSensitive(root, "nodes");
    if (!cJSON_IsArray(nodes) || cJSON_GetArraySize(nodes) < 1) FAIL("%s: \"nodes\" is not a non-empty array", name);
    size_t count = (size_t)cJSON_GetArraySize(nodes), name_bytes = 0;
    const cJSON *node;
    cJSON_ArrayForEach(node, nodes)
    {
        const cJSON *n_name = cJSON_GetObjectItemCaseSensitive(node, "name");
        name_bytes += (cJSON_IsString(n_name) ? strlen(n_name->valuestring) : 0) + 1;
    }
    o->nodes = lk__calloc_array(count, sizeof *o->nodes);
    o->names = malloc(name_bytes);
    if (!o->nodes || !o->names) FAIL("out of memory");
    char *names = o->names;
    size_t index = 0;
    uint64_t total = 0;
    cJSON_ArrayForEach(node, nodes)
    {
        lk_octree_node *out = &o->nodes[index];
        const cJSON *n_name = cJSON_GetObjectItemCaseSensitive(node, "name");
        if (!cJSON_IsString(n_name)) FAIL("%s: nodes[%zu]: no \"name\"", name, index);
        const char *text_name = n_name->valuestring;
        size_t length = strlen(text_name);
        if (length < 1 || length > OT_MAX_BITS + 1 || text_name[0] != 'r' ||
            strspn(text_name + 1, "01234567") != length - 1)
            FAIL("%s: nodes[%zu]: name \"%.40s\" is not r followed by at most %d digits 0-7", name, index, text_name,
                 OT_MAX_BITS);
        memcpy(names, text_name, length + 1);
        out->name = names;
        names += length + 1;
        uint64_t level;
        if (!json_uint(cJSON_GetObjectItemCaseSensitive(node, "level"), 64, &level) || level != length - 1)
            FAIL("%s: nodes[%zu] (%s): \"level\" is not %zu", name, index, out->name, length - 1);
        out->level = (unsigned)level;
        if (!json_uint(cJSON_GetObjectItemCaseSensitive(node, "points"), OT_JSON_MAX_INTEGER, &out->points) ||
            !json_uint(cJSON_GetObjectItemCaseSensitive(node, "offset"), OT_JSON_MAX_INTEGER, &out->offset) ||
            !json_uint(cJSON_GetObjectItemCaseSensitive(node, "length"), OT_JSON_MAX_INTEGER, &out->length))
            FAIL("%s: nodes[%zu] (%s): \"points\", \"offset\" or \"length\" is not a count", name, index, out->name);
        uint64_t crc;
        if (!json_uint(cJSON_GetObjectItemCaseSensitive(node, "crc32"), 4294967295.0, &crc))
            FAIL("%s: nodes[%zu] (%s): \"crc32\" is not a 32-bit number", name, index, out->name);
        out->crc32 = (uint32_t)crc;
        if (out->points > out->length / stride || out->length != out->points * stride)
            FAIL("%s: nodes[%zu] (%s): length %llu is not points * stride (%llu * %zu)", name, index, out->name,
                 (unsigned long long)out->length, (unsigned long long)out->points, stride);
        if (out->offset + out->length < out->offset || out->offset + out->length > OT_JSON_MAX_INTEGER)
            FAIL("%s: nodes[%zu] (%s): offset + length overflows", name, index, out->name);
        if (index > 0) {
            const lk_octree_node *before = &o->nodes[index - 1];
            if (before->level > out->level || (before->level == out->level && strcmp(before->name, out->name) >= 0))
                FAIL("%s: nodes[%zu] (%s): the nodes are not sorted by level then name (or repeat one)", name, index,
                     out->name);
        } else if (out->level != 0)
            FAIL("%s: nodes[0] is %s, not the root r", name, out->name);
        double side = info->cube_size;
        for (int k = 0; k < 3; k++) out->min[k] = info->offset[k];
        for (size_t d = 1; d < length; d++) {
            side *= 0.5;
            int child = text_name[d] - '0';
            for (int k = 0; k < 3; k++)
                if (child >> (2 - k) & 1) out->min[k] += side;
        }
        for (int k = 0; k < 3; k++) {
            out->max[k] = out->min[k] + side;
            /* a cube too small to tell apart from its corner at that offset */
            if (!(out->max[k] > out->min[k]) || !isfinite(out->max[k]))
                FAIL("%s: nodes[%zu] (%s): its cube (side %g) cannot be represented at offset %g", name, index,
                     out->name, side, info->offset[k]);
        }
        total += out->points;
        index++;
    }
    if (total != info->points)
        FAIL("%s: the nodes hold %llu points, \"points\" says %llu", name, (unsigned long long)total,
             (unsigned long long)info->points);
    info->node_count = count;
    /* each node's children: its parent is one digit shorter, at a lower
     * index (sorted by level, then name) */
    for (size_t i = 1; i < count; i++) {
        lk_octree_node *child = &o->nodes[i];
        size_t parent = lk__octree_find_node(o, child->name, child->level - 1);
        if (parent < count) o->nodes[parent].children |= 1u << (child->name[child->level] - '0');
    }
#undef FAIL
done:
    cJSON_Delete(root);
    return status;
}

static lk_status open_index(const char *json, size_t size, const char *name, const char *data_path, lk_octree **octree,
                            lk_error *error)
{
    *octree = NULL;
    lk_octree *o = calloc(1, sizeof *o);
    if (!o) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    if (data_path && !(o->data_path = strdup(data_path))) {
        free(o);
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    }
    lk_status status = parse_index(o, json, size, name, error);
    if (status == LK_OK && o->data_path) {
        struct stat info;
        if (stat(o->data_path, &info) != 0)
            status = lk_error_set(error, LK_ERR_IO, "%s: %s", o->data_path, strerror(errno));
        for (size_t i = 0; status == LK_OK && i < o->info.node_count; i++) {
            const lk_octree_node *node = &o->nodes[i];
            if (node->offset + node->length > (uint64_t)info.st_size)
                status = lk_error_set(
                    error, LK_ERR_PARSE, "%s: node %s: bytes %llu to %llu lie past the end of %s (%llu bytes)", name,
                    node->name, (unsigned long long)node->offset, (unsigned long long)(node->offset + node->length),
                    o->data_path, (unsigned long long)info.st_size);
        }
    }
    if (status != LK_OK) {
        lk_octree_close(o);
        return status;
    }
    *octree = o;
    return LK_OK;
}

lk_status lk_octree_open_memory(const char *json, size_t size, const char *name, lk_octree **octree, lk_error *error)
{
    return open_index(json, size, name ? name : "octree.json", NULL, octree, error);
}

lk_status lk_octree_open(const char *path, lk_octree **octree, lk_error *error)
{
    *octree = NULL;
    struct stat info;
    char *index_path = NULL;
    if (stat(path, &info) == 0 && S_ISDIR(info.st_mode))
        index_path = lk__octree_join_path(path, OT_INDEX_NAME);
    else
        index_path = strdup(path);
    if (!index_path) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    char *text = NULL;
    size_t size = 0;
    lk_status status = lk__read_file(index_path, (size_t)1 << 30, &text, &size, error);
    if (status == LK_OK) status = open_index(text, size, index_path, index_path, octree, error);
    free(text);
    free(index_path);
    return status;
}

static lk_status read_node_bytes(const lk_octree *o, size_t index, unsigned char **bytes, lk_error *error)
{
    *bytes = NULL;
    if (index >= o->info.node_count)
        return lk_error_set(error, LK_ERR_INVALID, "node %zu does not exist (the octree has %zu)", index,
                            o->info.node_count);
    if (!o->data_path) return lk_error_set(error, LK_ERR_INVALID, "this octree was opened without its data file");
    const lk_octree_node *node = &o->nodes[index];
    if (node->length > SIZE_MAX - 1) return lk_error_set(error, LK_ERR_LIMIT, "node %s is too large", node->name);
    unsigned char *data = malloc(node->length ? (size_t)node->length : 1);
    if (!data) return lk_error_set(error, LK_ERR_NOMEM, "node %s: out of memory", node->name);
    FILE *file = fopen(o->data_path, "rb");
    lk_status status = LK_OK;
    if (!file)
        status = lk_error_set(error, LK_ERR_IO, "%s: %s", o->data_path, strerror(errno));
    else {
        if (fseeko(file, (off_t)node->offset, SEEK_SET) != 0 ||
            fread(data, 1, (size_t)node->length, file) != node->length)
            status = lk_error_set(error, LK_ERR_IO, "%s: node %s: bytes %llu to %llu cannot be read (file cut short?)",
                                  o->data_path, node->name, (unsigned long long)node->offset,
                                  (unsigned long long)(node->offset + node->length));
        fclose(file);
    }
    if (status == LK_OK && lk__octree_crc32(data, (size_t)node->length) != node->crc32)
        status = lk_error_set(error, LK_ERR_PARSE, "%s: node %s: CRC-32 mismatch at byte %llu (the data is corrupt)",
                              o->data_path, node->name, (unsigned long long)node->offset);
    if (status != LK_OK) {
        free(data);
        return status;
    }
    *bytes = data;
    return LK_OK;
}

lk_status lk_octree_load_node_quantized(const lk_octree *octree, size_t index, int32_t **positions, size_t *count,
                                        lk_error *error)
{
    *positions = NULL;
    *count = 0;
    unsigned char *bytes;
    lk_status status = read_node_bytes(octree, index, &bytes, error);
    if (status != LK_OK) return status;
    size_t n = (size_t)octree->nodes[index].points;
    int32_t *out = lk__malloc_array(n ? 3 * n : 1, sizeof *out);
    if (!out) {
        free(bytes);
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    }
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++)
            out[3 * i + (size_t)k] = lk__load_i32le(bytes + i * octree->info.stride + 4 * (size_t)k);
    free(bytes);
    *positions = out;
    *count = n;
    return LK_OK;
}

size_t lk__octree_find_node(const lk_octree *octree, const char *name, unsigned level)
{
    size_t lo = 0, hi = octree->info.node_count;
    while (lo < hi) { /* first node not before (level, name) */
        size_t mid = lo + (hi - lo) / 2;
        const lk_octree_node *node = &octree->nodes[mid];
        int before = node->level < level || (node->level == level && strncmp(node->name, name, level + 1) < 0);
        if (before)
            lo = mid + 1;
        else
            hi = mid;
    }
    if (lo < octree->info.node_count && octree->nodes[lo].level == level &&
        strncmp(octree->nodes[lo].name, name, level + 1) == 0)
        return lo;
    return octree->info.node_count;
}

lk_status lk_octree_load_node(const lk_octree *octree, size_t index, lk_mesh *points, lk_error *error)
{
    return lk__octree_load_node(octree, index, points, NULL, 1, error);
}

lk_status lk_octree_load_node_clips(const lk_octree *octree, size_t index, lk_mesh *points, float **clips,
                                    lk_error *error)
{
    return lk__octree_load_node(octree, index, points, clips, 1, error);
}

lk_status lk__octree_load_node(const lk_octree *octree, size_t index, lk_mesh *points, float **clips, int floored,
                               lk_error *error)
{
    lk_mesh_init(points);
    if (clips) *clips = NULL;
    unsigned char *bytes;
    lk_status status = read_node_bytes(octree, index, &bytes, error);
    if (status != LK_OK) return status;
    const lk_octree_info *info = &octree->info;
    size_t n = (size_t)octree->nodes[index].points;
    unsigned flags =
        LK_ATTR_RADII | (info->has_colors ? LK_ATTR_COLORS : 0u) | (info->has_normals ? LK_ATTR_NORMALS : 0u);
    status = lk_mesh_alloc(points, n, 0, flags, error);
    /* An inner node drawn alone: at least its spacing, so that its points
     * cover where its children's are missing (version 1 stored them so). */
    const lk_octree_node *node = &octree->nodes[index];
    float floor_radius = floored && node->children ? (float)ldexp(info->spacing, -(int)node->level) : 0.0f;
    float *clip_lines = NULL;
    if (status == LK_OK && clips && info->has_clips) {
        clip_lines = lk__malloc_array(n ? n : 1, 4 * sizeof *clip_lines);
        if (!clip_lines) status = lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu clip lines", n);
    }
    for (size_t i = 0; status == LK_OK && i < n; i++) {
        const unsigned char *p = bytes + i * info->stride;
        for (int k = 0; k < 3; k++)
            points->positions[3 * i + (size_t)k] = (float)(lk__load_i32le(p + 4 * k) * info->scale[k]);
        p += 12;
        if (info->has_colors) {
            for (int k = 0; k < 3; k++) points->colors[4 * i + (size_t)k] = p[k] / 255.0f;
            points->colors[4 * i + 3] = 1.0f;
            p += 3;
        }
        if (info->has_normals) {
            uint16_t oct[2] = {lk__load_u16le(p), lk__load_u16le(p + 2)};
            lk__octree_oct_decode(oct, points->normals + 3 * i);
            p += 4;
        }
        float radius = lk__load_f32le(p);
        points->radii[i] = radius < floor_radius ? floor_radius : radius;
        p += 4;
        if (clip_lines)
            for (int k = 0; k < 4; k++) {
                /* snorm8: -128 is -1 as -127 is */
                int value = (int8_t)p[k];
                clip_lines[4 * i + (size_t)k] = (float)(value < -127 ? -127 : value) / 127.0f;
            }
    }
    free(bytes);
    if (status != LK_OK) {
        lk_mesh_free(points);
        free(clip_lines);
        return status;
    }
    if (clips) *clips = clip_lines;
    return status;
}
