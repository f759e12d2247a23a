/* SPDX-License-Identifier: MIT */
/* What the glTF files share, private to them: the constants of the
 * specification, the reader's state, and the functions of the document
 * model (io_gltf_document.c: JSON, containers, buffers, accessors) and of
 * the mesh reader (io_gltf.c: scene graph to lk_mesh) that the files after
 * them use. The animation reader (io_gltf_anim.c) builds on both; the
 * writer (io_gltf_write.c) only needs the constants. Not installed. */
#ifndef LODKIT_IO_GLTF_H
#define LODKIT_IO_GLTF_H

#include "anim_io.h"

#include <cjson/cJSON.h>

enum {
    COMPONENT_BYTE = 5120,
    COMPONENT_UNSIGNED_BYTE = 5121,
    COMPONENT_SHORT = 5122,
    COMPONENT_UNSIGNED_SHORT = 5123,
    COMPONENT_UNSIGNED_INT = 5125,
    COMPONENT_FLOAT = 5126
};

enum {
    MODE_POINTS = 0,
    MODE_LINES = 1,
    MODE_LINE_LOOP = 2,
    MODE_LINE_STRIP = 3,
    MODE_TRIANGLES = 4,
    MODE_TRIANGLE_STRIP = 5,
    MODE_TRIANGLE_FAN = 6
};

/* Bit masks of accepted accessor types (bit = number of components). */
#define TYPE_SCALAR (1u << 1)
#define TYPE_VEC2 (1u << 2)
#define TYPE_VEC3 (1u << 3)
#define TYPE_VEC4 (1u << 4)
#define TYPE_MAT4 (1u << 16) /* only where asked for: 16 components */

typedef struct gltf_buffer {
    bool loaded;
    const unsigned char *data; /* byteLength bytes */
    size_t size;               /* byteLength, checked against the real data */
    unsigned char *owned;      /* decoded data: URI or external file, else NULL */
} gltf_buffer;

/* A top-level JSON array turned into a pointer vector: cJSON arrays are
 * linked lists, and indexing them for every reference would be quadratic. */
typedef struct json_table {
    const cJSON **items;
    size_t count;
    size_t allocated; /* items charged to the budget */
} json_table;

typedef struct gltf_reader {
    const lk__read_context *ctx;
    lk_error *error;
    const cJSON *root;
    json_table accessors, buffer_views, buffers_json, meshes, nodes, scenes;

    /* GLB BIN chunk (buffer 0 without uri), if any. */
    bool is_glb;
    bool has_bin_chunk;
    const unsigned char *bin_chunk;
    size_t bin_chunk_size;

    gltf_buffer *buffers; /* buffers_json.count entries, loaded on first use */
    /* bufferViews compressed with EXT_meshopt_compression, decoded on first
     * use (buffer_views.count entries, allocated with the first one). */
    gltf_buffer *decoded_views;
    size_t buffer_bytes; /* decoded data: URIs and external files held so far */
    size_t json_bytes;   /* the parsed JSON tree's charge to the budget */

    /* Output, grown primitive by primitive (charged to the budget). */
    lk__buffer positions, normals, texcoords, colors, indices;
    size_t vertex_count, triangle_count;
    bool has_normals, has_texcoords, has_colors;
    size_t skipped_line_primitives; /* without keep_lines */
    /* The scene reader keeps line primitives: their segments, as indices
     * into the primitive's own vertices (2 per segment). */
    bool keep_lines;
    lk__buffer lines;
    size_t line_count;

    /* lk__gltf_open_accessor accepts sparse accessors (their readers
     * apply them: lk__gltf_read_accessor_floats); others refuse them. */
    bool sparse_allowed;

    /* Animation reading: where each primitive's vertices went. */
    bool record_instances;
    size_t current_mesh;
    lk__buffer instances; /* gltf_instance */
} gltf_reader;

/* One primitive instanced by one node: its vertices are
 * [base, base + count) of the output. */
typedef struct gltf_instance {
    const cJSON *primitive;
    size_t mesh;
    size_t node; /* SIZE_MAX when the mesh is not in a node */
    size_t base, count;
} gltf_instance;

/* A validated accessor, ready to be decoded element by element. */
typedef struct gltf_accessor {
    size_t index;              /* accessors[index], for messages */
    const unsigned char *data; /* first element; NULL means all zeros (no bufferView) */
    size_t count;
    size_t stride;
    unsigned component_type;
    unsigned component_count;
    bool normalized;
    const cJSON *sparse; /* the accessor's "sparse" object (only where sparse_allowed), or NULL */
} gltf_accessor;

typedef struct primitive_attributes {
    gltf_accessor position, normal, texcoord, color;
    bool has_normal, has_texcoord, has_color;
} primitive_attributes;

/* ---- io_gltf_document.c: errors ------------------------------------------ */

/* Sets "NAME: WHERE.KEY: message" (KEY may be NULL, WHERE may be ""). */
lk_status lk__gltf_fail(const gltf_reader *reader, lk_status status, const char *where, const char *key,
                        const char *format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 5, 6)))
#endif
    ;
lk_status lk__gltf_nomem(const gltf_reader *reader);
lk_status lk__gltf_over_budget(const gltf_reader *reader);
/* Zeroed scratch of count * size bytes charged to the read's budget, or
 * NULL with *status set; freed (and given back) by lk__gltf_charged_free. */
void *lk__gltf_charged_calloc(const gltf_reader *reader, size_t count, size_t size, lk_status *status);
void lk__gltf_charged_free(const gltf_reader *reader, void *memory, size_t count, size_t size);
const char *lk__gltf_json_type_name(const cJSON *item);

/* ---- io_gltf_document.c: typed access to JSON members ---------------------- */

const cJSON *lk__gltf_member(const cJSON *object, const char *key);
bool lk__gltf_is_json_uint(const cJSON *item);
lk_status lk__gltf_check_uint(const gltf_reader *reader, const cJSON *item, const char *where, const char *key);
/* Optional (or required) non-negative integer member. */
lk_status lk__gltf_get_uint(const gltf_reader *reader, const cJSON *object, const char *where, const char *key,
                            bool required, uint64_t default_value, uint64_t *out);
/* Optional members of one type; *out is NULL when absent. */
lk_status lk__gltf_get_object(const gltf_reader *reader, const cJSON *object, const char *where, const char *key,
                              const cJSON **out);
lk_status lk__gltf_get_array(const gltf_reader *reader, const cJSON *object, const char *where, const char *key,
                             const cJSON **out);
lk_status lk__gltf_get_string(const gltf_reader *reader, const cJSON *object, const char *where, const char *key,
                              const cJSON **out);
/* Optional array of exactly `count` finite numbers; *present says whether
 * it was there (values untouched otherwise). */
lk_status lk__gltf_get_number_array(const gltf_reader *reader, const cJSON *object, const char *where, const char *key,
                                    size_t count, double *values, bool *present);

/* ---- io_gltf_document.c: tables, the document, accessors, containers ------- */

void lk__gltf_table_free(const gltf_reader *reader, json_table *table);
/* Turns an optional top-level array of objects into a table. */
lk_status lk__gltf_build_table(gltf_reader *reader, const char *key, json_table *table);
/* Resolves a reference `WHERE.KEY: index` into `table`, the top-level
 * array `table_name` ("accessors") of elements called `what` ("accessor"). */
lk_status lk__gltf_resolve(const gltf_reader *reader, const json_table *table, const char *what, const char *table_name,
                           uint64_t index, const char *where, const char *key, const cJSON **out);
/* Checks the asset, the extensions, the types of every top-level array and
 * the materials, and builds the reader's tables. */
lk_status lk__gltf_check_document(gltf_reader *reader);
/* Validates accessors[index] for a use that accepts the types in
 * `type_mask` (`expected` says which, for messages). */
lk_status lk__gltf_open_accessor(gltf_reader *reader, uint64_t index, const char *referrer, const char *key,
                                 unsigned type_mask, bool is_index, const char *expected, gltf_accessor *out);
/* The bytes of bufferViews[view_index] (referred to by referrer.key),
 * checked against its buffer; *byte_stride 0 when absent. */
lk_status lk__gltf_view_bytes(gltf_reader *reader, uint64_t view_index, const char *referrer, const char *key,
                              const unsigned char **data, uint64_t *length, uint64_t *byte_stride);
/* The bytes of an image uri (base64 data: or a file next to the document)
 * in a new array charged to the read's budget. */
lk_status lk__gltf_uri_bytes(gltf_reader *reader, const char *uri, const char *where, unsigned char **out,
                             size_t *size);
/* Element `element` as floats (normalized integers mapped to [0,1] or [-1,1]). */
void lk__gltf_accessor_floats(const gltf_accessor *accessor, size_t element, float *values);
uint32_t lk__gltf_accessor_index(const gltf_accessor *accessor, size_t element);
/* Replaces the elements an accessor's "sparse" object names in `values`
 * (accessor->count elements of accessor->component_count floats), checking
 * its indices (increasing, in range) and views. */
lk_status lk__gltf_apply_sparse(gltf_reader *reader, const gltf_accessor *accessor, float *values);
/* Parses the JSON text (at `file_offset` of the file, for messages) under
 * the read's budget. */
lk_status lk__gltf_parse_json(gltf_reader *reader, const char *text, size_t length, size_t file_offset, cJSON **root);
/* Splits a .glb file into its JSON text and optional BIN chunk. */
lk_status lk__gltf_parse_glb(gltf_reader *reader, const unsigned char *data, size_t size, const char **json,
                             size_t *json_length);

/* ---- io_gltf_anim.c: shared with the scene reader ------------------------- */

/* accessors[index] (referred to by where.key) decoded whole as finite
 * floats, component_count per element, charged to the read's budget;
 * *out is the caller's on success only. */
lk_status lk__gltf_read_accessor_floats(gltf_reader *reader, uint64_t index, const char *where, const char *key,
                                        unsigned type_mask, const char *expected, gltf_accessor *accessor, float **out);

/* ---- io_gltf_write.c: shared by the writers ------------------------------- */

/* mesh->normals at unit length into `out` (3 floats per vertex); a missing
 * one (zero, NaN) becomes the area-weighted normal of the vertex's
 * triangles in `positions`, or +z. False when out of memory. */
bool lk__gltf_unit_normals(const lk_mesh *mesh, const float *positions, float *out);

/* ---- io_gltf_primitive.c: a primitive's data for the scene writer ---------- */

/* A copy of `in` made ready for the compact encodings: equal vertices
 * merged, empty triangles dropped, triangles in vertex-cache order and
 * vertices in order of first use; false when out of memory (free `out`
 * with lk__gltf_compacted_free either way). */
bool lk__gltf_compact_for_codecs(const lk_scene_primitive *in, lk_scene_primitive *out);
void lk__gltf_compacted_free(lk_scene_primitive *primitive);
/* Which TEXCOORD_n sets a material's JSON samples, bit n. */
unsigned lk__gltf_sampled_texcoord_sets(const cJSON *item);
/* Whether a material's JSON samples a normal map. */
bool lk__gltf_uses_normal_map(const cJSON *item);
/* Per-vertex tangents (4 floats) of a normal-mapped mesh from its unit
 * normals and texture coordinates. */
void lk__gltf_compute_tangents(const lk_mesh *mesh, const float *normals, float *out);

/* ---- io_gltf_files.c: what a .gltf names beside itself --------------------- */

/* PATH's folder and stem + suffix ("/d/model.gltf", ".bin" -> "/d/model.bin")
 * and the URI the .gltf names it by (the stem percent-encoded, "model.bin");
 * free both. */
lk_status lk__gltf_sibling_names(const char *path, const char *suffix, char **file_path, char **uri, lk_error *error);
/* Writes `size` bytes to file_path whole (a temporary file renamed) or not at all. */
lk_status lk__gltf_write_sibling(const char *file_path, const void *data, size_t size, lk_error *error);
/* The file extension of an image's MIME type ("image/jpeg" -> "jpg"; "bin" when unknown). */
const char *lk__gltf_image_extension(const char *mime_type);
/* Appends an image's bytes as the writer stores them to `out`: a PNG
 * without its iCCP chunks (glTF: images SHOULD NOT embed ICC profiles and
 * clients MUST ignore them; the validator warns IMAGE_FEATURES_UNSUPPORTED;
 * the pixels do not change), anything else (or a PNG whose chunks do not
 * parse) as it is. False when out of memory. */
bool lk__gltf_image_bytes(const unsigned char *data, size_t size, lk__buffer *out);

/* ---- io_gltf_hoist.c: the writer's last step -------------------------------- */

/* Moves the mesh, skin, morph weights and MSFT_lod levels of every node that
 * holds a skinned mesh under a parent onto a new root node appended to
 * root.nodes (glTF ignores a skinned mesh's node transforms; the Khronos
 * validator warns NODE_SKINNED_MESH_NON_ROOT); false when out of memory. */
bool lk__gltf_hoist_skinned_meshes(cJSON *root);

/* ---- io_gltf_views.c: the scene writer's buffer, accessors and views ------- */

#define GLTF_TARGET_ARRAY_BUFFER 34962
#define GLTF_TARGET_ELEMENT_ARRAY_BUFFER 34963

/* EXT_meshopt_compression's filters: what a view's bytes went through. */
typedef enum gltf_filter {
    GLTF_FILTER_NONE,
    GLTF_FILTER_OCTAHEDRAL,
    GLTF_FILTER_QUATERNION,
    GLTF_FILTER_EXPONENTIAL
} gltf_filter;

/* An accessor's data in the buffer, then (lk__gltf_group_views) a
 * bufferView: what EXT_meshopt_compression needs. */
typedef struct view_record {
    cJSON *json; /* the accessor's JSON; after grouping, the view's */
    size_t offset, bytes, stride, count;
    unsigned index_size; /* 0: vertex attributes */
    gltf_filter filter;  /* meshopt filter the bytes are the output of */
    bool plain;          /* not vertex data (animation keys, inverse bind matrices): a
                            view without target and byteStride, as glTF wants */
    bool sequence;       /* indices of line segments: meshopt's INDICES mode, not TRIANGLES */
} view_record;

typedef struct mesh_writer {
    lk__buffer bin;
    cJSON *views, *accessors;
    size_t view_count; /* items of views (cJSON counts them by walking the list) */
    size_t accessor_count;
    view_record *records;
    size_t record_count, record_capacity;
    uint64_t flags; /* lk_write_options.gltf_flags */
    bool quantized; /* some attribute is not float: KHR_mesh_quantization */
    bool failed;
} mesh_writer;

/* Reserves `bytes` at the end of the buffer, after padding it to 4 bytes;
 * returns the offset (writer->failed on allocation failure). */
size_t lk__gltf_reserve(mesh_writer *writer, size_t bytes);
/* An accessor of `count` elements over [offset, offset + bytes) of the
 * buffer (target 0: data that is not vertex data); its bufferView comes
 * later (lk__gltf_group_views). Returns the accessor's JSON (NULL on
 * failure); its view record is the writer's last. */
cJSON *lk__gltf_add_accessor(mesh_writer *writer, size_t offset, size_t bytes, size_t stride, int target,
                             int component_type, bool normalized, size_t count, const char *type);
/* `count` elements of `components` floats (target: the view's, 0 for data
 * that is not vertex data); min/max when with_bounds. Returns the accessor
 * index. */
size_t lk__gltf_add_float_data(mesh_writer *writer, const float *values, size_t count, unsigned components,
                               const char *type, bool with_bounds, int target);
/* One bufferView per kind of data; see io_gltf_views.c. */
bool lk__gltf_group_views(mesh_writer *writer);
/* EXT_meshopt_compression of every view into `packed`. */
bool lk__gltf_compress_views(mesh_writer *writer, lk__buffer *packed);
/* `count` floats equal in a and b, or both absent. */
bool lk__gltf_same_floats(const float *a, const float *b, size_t count);

/* ---- io_gltf_skin_write.c: joints, weights, skins and animations out -------- */

/* A position grid (KHR_mesh_quantization): value = origin + step * integer. */
typedef struct position_grid {
    float origin[3];
    float step;
} position_grid;

/* m (column-major) = m x translate(origin) x scale(step): a transform
 * that took float positions takes the grid's integers to the same place. */
void lk__gltf_matrix_times_grid(double m[16], const position_grid *grid);
/* Every primitive with vertices has joints and weights. */
bool lk__gltf_mesh_is_skinned(const lk_scene_mesh *mesh);
/* JOINTS_0 and WEIGHTS_0 of `count` vertices into a primitive's
 * `attributes`: weights summing to 1 (bytes with LK_GLTF_QUANTIZE), joints
 * without weight 0. False on failure (writer->failed). */
bool lk__gltf_add_skin_attributes(mesh_writer *writer, cJSON *attributes, const uint16_t *joints, const float *weights,
                                  size_t count);
/* The scene's skins; skin_grids[s] (NULL or step 0: none) is the grid of
 * the positions of the meshes skin s binds, folded into its inverse bind
 * matrices. */
bool lk__gltf_add_skins(mesh_writer *writer, cJSON *root, const lk_scene *scene, const position_grid *skin_grids);
/* The scene's animations. */
bool lk__gltf_add_animations(mesh_writer *writer, cJSON *root, const lk_scene *scene);

/* ---- io_gltf.c: the mesh reader -------------------------------------------- */

lk_status lk__gltf_open_attributes(gltf_reader *reader, const cJSON *primitive, const char *where,
                                   primitive_attributes *attributes);
/* The node's local transform: `matrix`, or translation * rotation * scale. */
lk_status lk__gltf_node_local_matrix(const gltf_reader *reader, const cJSON *node, const char *where, double m[16]);
/* One primitive in its mesh's coordinates into the output arrays (lines
 * are skipped and counted). */
lk_status lk__gltf_read_local_primitive(gltf_reader *reader, const cJSON *primitive, const char *where);
/* Parses the container and the JSON and checks the document. */
lk_status lk__gltf_open_document(gltf_reader *reader, const char *data, size_t size, cJSON **root);
/* Parses the container and the JSON, checks the document and reads the
 * default scene into the reader's output arrays. */
lk_status lk__gltf_load(gltf_reader *reader, const char *data, size_t size, cJSON **root);
/* Moves the output arrays into `mesh` and empties them. */
lk_status lk__gltf_take_mesh(gltf_reader *reader, lk_mesh *mesh);
/* Frees what the reader holds and the JSON tree, giving back their charges. */
void lk__gltf_release(gltf_reader *reader, cJSON *root);

#endif
