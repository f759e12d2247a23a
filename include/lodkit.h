/* SPDX-License-Identifier: MIT */
/*
 * lodkit — multiresolution 3D geometry for networked graphics.
 *
 * This header is the whole public C API and its reference documentation.
 * Conventions (docs/api.md):
 *   - every public symbol starts with lk_ / LK_, and every public function
 *     and datum is declared with LK_API: that is all a shared library
 *     exports (lk__ names are the library's own);
 *   - functions that can fail return an lk_status and, when given a non-NULL
 *     lk_error, write a message saying what went wrong and where
 *     (file:line for text formats, byte offset for binary ones);
 *   - the caller owns what it passes in; results live in structs that have a
 *     matching lk_*_free, and a buffer a function hands back (its comment
 *     says "release with lk_free") is released with lk_free; no global
 *     state, so every function is thread-safe as long as two threads do not
 *     write the same object;
 *   - positions are stored as float, accumulations that need accuracy
 *     (areas, distances, quadrics) are done in double.
 *
 * ABI rule for option structs (lk_*_options): a program built against this
 * header keeps working, without being rebuilt, with a later library of the
 * same SOVERSION, because
 *   - the program fills an options struct with its lk_*_options_default, or
 *     zeroes it where the struct has none (= {0}, designated initialisers,
 *     memset: zero is then every field's default), before setting fields;
 *   - every options struct ends in `reserved` words that stay zero. A later
 *     version adds a field only in place of the first reserved words (a
 *     field smaller than a word takes a whole one), so the struct's size and
 *     every field's offset stay the same, and the new field's zero means
 *     what the library did before it existed;
 *   - no field is removed, moved, retyped or given another meaning;
 *   - when the reserved words run out, new options come in a new struct
 *     taken by a new function (as lk_animation_read_ex did), and the old
 *     struct and function stay.
 * Any other change to a public struct (meshes, results, statistics, which
 * the library fills) needs a new SOVERSION.
 */
#ifndef LODKIT_H
#define LODKIT_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

/* LK_API marks every public function and datum of this header. The
 * libraries are built with hidden visibility (-fvisibility=hidden), so a
 * shared library exports what carries LK_API and nothing else: internal
 * helpers (lk__*) stay private (scripts/check-exports.sh checks it). It is
 * default visibility under GCC and clang and empty elsewhere; a build may
 * define it first. */
#ifndef LK_API
#if defined(__GNUC__) || defined(__clang__)
#define LK_API __attribute__((visibility("default")))
#else
#define LK_API
#endif
#endif

#ifdef __cplusplus
extern "C" {
#endif

#define LK_VERSION_MAJOR 0
#define LK_VERSION_MINOR 1
#define LK_VERSION_PATCH 0
#define LK_VERSION_STRING "0.1.0"

/* Returns LK_VERSION_STRING of the library actually linked. */
LK_API const char *lk_version(void);

/* ------------------------------------------------------------------------ */
/* Errors                                                                   */
/* ------------------------------------------------------------------------ */

typedef enum lk_status {
    LK_OK = 0,
    LK_ERR_IO,          /* file could not be opened, read, written or renamed */
    LK_ERR_PARSE,       /* malformed input: message says file:line or offset */
    LK_ERR_RANGE,       /* index out of range, NaN/Inf, count mismatch */
    LK_ERR_LIMIT,       /* input claims more than it can hold or than allowed */
    LK_ERR_NOMEM,       /* allocation failed */
    LK_ERR_INVALID,     /* bad argument from the caller */
    LK_ERR_UNSUPPORTED, /* valid input that lodkit does not handle (yet) */
    LK_ERR_TRUNCATED    /* input ends early: what came before it was used */
} lk_status;

/* Per-call error report. Zero-initialise it (or call lk_error_clear) before
 * use; functions fill it only on failure. */
typedef struct lk_error {
    lk_status status;
    char message[512];
} lk_error;

/* Resets error to LK_OK and an empty message. Accepts NULL. */
LK_API void lk_error_clear(lk_error *error);
/* Sets status and a printf-style message; returns status so callers can
 * write `return lk_error_set(err, LK_ERR_PARSE, "...")`. Accepts error==NULL. */
LK_API lk_status lk_error_set(lk_error *error, lk_status status, const char *format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
/* A short English name for a status ("parse error", ...). */
LK_API const char *lk_status_string(lk_status status);

/* Releases a buffer that a lodkit function handed to the caller: the
 * functions whose comment says "release with lk_free" (lk_file_read,
 * lk_anim_error_map, lk_stripify, lk_stream_encode, lk_stream_inspect,
 * lk_stream_decoder_strip, lk_terrain_outline). Use it, not free(): the
 * buffer belongs to the library's allocator, which need not be the
 * program's. Accepts NULL. Results held in structs (lk_mesh,
 * lk_simplify_result, ...) are released by their own lk_*_free. */
LK_API void lk_free(void *pointer);

/* Optional progress callback for long work: fraction in [0,1], stage is a
 * short label. Return non-zero to cancel (the function then fails with
 * LK_ERR_INVALID and "cancelled"). lk_simplify (every method),
 * lk_animation_simplify and lk_animation_simplify_levels report 0 first
 * and, when they succeed, 1 last. */
typedef int (*lk_progress_fn)(void *user, double fraction, const char *stage);

/* ------------------------------------------------------------------------ */
/* Mesh                                                                     */
/* ------------------------------------------------------------------------ */

/* An indexed triangle mesh. Point sets are meshes with triangle_count == 0.
 * All arrays are heap-owned by the mesh (free with lk_mesh_free).
 * Attribute arrays are NULL when absent, otherwise one entry per vertex. */
typedef struct lk_mesh {
    size_t vertex_count;
    size_t triangle_count;
    float *positions;  /* 3 * vertex_count: x y z */
    float *normals;    /* 3 * vertex_count or NULL */
    float *texcoords;  /* 2 * vertex_count or NULL: u v with v up (OBJ/PLY convention;
                         * glTF's v-down coordinates are flipped when read) */
    float *colors;     /* 4 * vertex_count or NULL: r g b a in [0,1] */
    float *radii;      /* vertex_count or NULL: splat radius of each point (model units);
                         * PLY property "radius" */
    uint32_t *indices; /* 3 * triangle_count, counter-clockwise front faces */
} lk_mesh;

/* Attribute flags for lk_mesh_alloc. */
enum { LK_ATTR_NORMALS = 1u << 0, LK_ATTR_TEXCOORDS = 1u << 1, LK_ATTR_COLORS = 1u << 2, LK_ATTR_RADII = 1u << 3 };

/* Largest vertex or triangle count lodkit accepts (indices are uint32_t). */
#define LK_MAX_ELEMENTS ((size_t)0xFFFFFFF0u)

/* Sets every field to zero/NULL. */
LK_API void lk_mesh_init(lk_mesh *mesh);
/* Frees the arrays and re-initialises the mesh. Accepts NULL. */
LK_API void lk_mesh_free(lk_mesh *mesh);
/* Allocates a mesh (contents uninitialised) with the attributes in flags. */
LK_API lk_status lk_mesh_alloc(lk_mesh *mesh, size_t vertex_count, size_t triangle_count, unsigned attribute_flags,
                               lk_error *error);
/* Deep copy of src into dst (dst is overwritten, not freed first). */
LK_API lk_status lk_mesh_copy(lk_mesh *dst, const lk_mesh *src, lk_error *error);
/* Checks indices < vertex_count and finite positions/attributes.
 * Reports the first offending triangle or vertex. */
LK_API lk_status lk_mesh_validate(const lk_mesh *mesh, lk_error *error);

/* Axis-aligned bounds of all vertices; returns the diagonal length
 * (0 for an empty mesh, and then min/max are zero). min/max may be NULL. */
LK_API double lk_mesh_bounds(const lk_mesh *mesh, float min[3], float max[3]);
/* Total surface area (double accumulation). */
LK_API double lk_mesh_area(const lk_mesh *mesh);
/* Translates every vertex by (dx,dy,dz). */
LK_API void lk_mesh_translate(lk_mesh *mesh, double dx, double dy, double dz);

/* Vertex -> triangle adjacency in compressed rows:
 * the triangles around vertex v are triangles[offsets[v] .. offsets[v+1]). */
typedef struct lk_vertex_adjacency {
    size_t vertex_count;
    uint32_t *offsets;   /* vertex_count + 1 */
    uint32_t *triangles; /* 3 * triangle_count */
} lk_vertex_adjacency;
/* Builds the adjacency of `mesh` into `adjacency` (overwritten). */
LK_API lk_status lk_vertex_adjacency_build(const lk_mesh *mesh, lk_vertex_adjacency *adjacency, lk_error *error);
/* Frees the arrays and zeroes the struct. Accepts NULL. */
LK_API void lk_vertex_adjacency_free(lk_vertex_adjacency *adjacency);

/* Undirected edges and the triangles that use each one.
 * Edge e joins vertices[2e] < vertices[2e+1]; its triangles are
 * triangles[offsets[e] .. offsets[e+1]). Edges are sorted by (v0, v1).
 * triangle_edges[3t+k] is the edge from corner k to corner (k+1)%3 of t.
 * Cost: O(T log T) time, 9T words of memory. */
typedef struct lk_edge_adjacency {
    size_t edge_count;
    uint32_t *vertices;       /* 2 * edge_count */
    uint32_t *offsets;        /* edge_count + 1 */
    uint32_t *triangles;      /* 3 * triangle_count */
    uint32_t *triangle_edges; /* 3 * triangle_count */
} lk_edge_adjacency;
/* Builds the edges of `mesh` into `adjacency` (overwritten). */
LK_API lk_status lk_edge_adjacency_build(const lk_mesh *mesh, lk_edge_adjacency *adjacency, lk_error *error);
/* Frees the arrays and zeroes the struct. Accepts NULL. */
LK_API void lk_edge_adjacency_free(lk_edge_adjacency *adjacency);

/* Merges vertices whose positions lie within `tolerance` (absolute, model
 * units; 0 = exactly equal) of each other, keeping the first vertex's
 * attributes, and rewrites the indices. Vertices that differ in normals or
 * texture coordinates are merged too (their attributes are dropped in
 * favour of the first). Unreferenced vertices are kept (use
 * lk_mesh_remove_unused_vertices). Returns the number of vertices merged in
 * *merged_count (may be NULL). Cost: O(V) expected with a hash grid. */
LK_API lk_status lk_mesh_weld(lk_mesh *mesh, double tolerance, size_t *merged_count, lk_error *error);

/* Removes triangles with a repeated vertex index (degenerate) and triangles
 * that use the same three vertices as an earlier one in any order or
 * orientation (duplicates). Counts may be NULL. */
LK_API lk_status lk_mesh_remove_degenerate(lk_mesh *mesh, size_t *degenerate_removed, size_t *duplicate_removed,
                                           lk_error *error);

/* Drops vertices that no triangle uses (only if the mesh has triangles) and
 * compacts the arrays, preserving order. */
LK_API lk_status lk_mesh_remove_unused_vertices(lk_mesh *mesh, size_t *removed_count, lk_error *error);

/* Connected components of triangles (triangles sharing a vertex are
 * connected). component[t] receives the component of triangle t, numbered
 * from 0 in order of first triangle; may be NULL. Returns the count in
 * *component_count. */
LK_API lk_status lk_mesh_components(const lk_mesh *mesh, uint32_t *component, size_t *component_count, lk_error *error);

/* Topology and geometry summary of a mesh (what `lodkit info` prints). */
typedef struct lk_mesh_stats {
    size_t vertex_count;
    size_t triangle_count;
    size_t used_vertex_count;         /* vertices referenced by a triangle */
    size_t edge_count;                /* unique undirected edges */
    size_t boundary_edge_count;       /* edges with one triangle */
    size_t nonmanifold_edge_count;    /* edges with three or more triangles */
    size_t nonmanifold_vertex_count;  /* vertices whose triangle fan is not a single disk/half-disk */
    size_t degenerate_triangle_count; /* triangles with a repeated index */
    size_t duplicate_triangle_count;  /* same vertex set as an earlier triangle */
    size_t component_count;
    size_t boundary_loop_count;     /* connected sets of boundary edges */
    long long euler_characteristic; /* V - E + F over used vertices */
    long long genus;                /* (2C - chi - loops)/2; -1 when not a manifold */
    double area;
    double diagonal;
    float min[3], max[3];
} lk_mesh_stats;
/* Fills `stats` (overwritten) for `mesh`. */
LK_API lk_status lk_mesh_compute_stats(const lk_mesh *mesh, lk_mesh_stats *stats, lk_error *error);

/* ------------------------------------------------------------------------ */
/* File formats                                                             */
/* ------------------------------------------------------------------------ */

typedef enum lk_format {
    LK_FORMAT_AUTO = 0, /* by extension, then by content */
    LK_FORMAT_OBJ,
    LK_FORMAT_PLY,
    LK_FORMAT_OFF,
    LK_FORMAT_SMF,
    LK_FORMAT_XYZ,
    LK_FORMAT_STL,
    LK_FORMAT_GLTF, /* .gltf (JSON; written with NAME.bin) or .glb (binary) */
    LK_FORMAT_MD2,  /* Quake II key frames: frame 0 as a mesh; read only (see lk_animation_write) */
    LK_FORMAT_KMF,  /* key-frame model format: frame 0 as a mesh; read only (see lk_animation_write) */
    LK_FORMAT_PCD,  /* Point Cloud Library point cloud (ascii, binary, binary_compressed); read only */
    LK_FORMAT_LAS,  /* ASPRS LAS 1.0-1.4 lidar points (formats 0-10; written as 1.2, format 0 or 2); not LAZ */
    LK_FORMAT_UNKNOWN
} lk_format;

/* Short lowercase name ("obj", "ply", ...). */
LK_API const char *lk_format_name(lk_format format);
/* Format from a file name's extension (case-insensitive), or LK_FORMAT_UNKNOWN
 * (also for the extensions of formats lk_mesh_read does not read, such as
 * .lks or .tif: lk_format_info_from_path tells what those hold). */
LK_API lk_format lk_format_from_path(const char *path);
/* Format from the first bytes of a file (magic numbers and keywords), or
 * LK_FORMAT_UNKNOWN. */
LK_API lk_format lk_format_sniff(const void *data, size_t size);

/* ---- The format table (src/io.c) ----
 * Every file format lodkit knows, by extension: what a file of it holds,
 * which functions read and write it, and a few words for help texts. It is
 * the one list: lk_mesh_read, lk_mesh_write and their messages use it, and
 * so can a program's help or a server's index. Each extension belongs to
 * one entry. */
typedef enum lk_format_kind {
    LK_FORMAT_KIND_MESH = 0,  /* a triangle mesh (PLY may also hold a point set) */
    LK_FORMAT_KIND_POINTS,    /* a point set: a mesh without triangles */
    LK_FORMAT_KIND_ANIMATION, /* key frames of one connectivity (lk_animation) */
    LK_FORMAT_KIND_GRID,      /* an elevation grid (lk_heightfield) */
    LK_FORMAT_KIND_STREAM     /* a progressive stream (.lks) */
} lk_format_kind;

/* "mesh", "point set", "animation", "elevation grid", "progressive stream";
 * NULL for an unknown value. */
LK_API const char *lk_format_kind_name(lk_format_kind kind);

/* Which functions read or write a format (lk_format_info.read / .write). */
enum {
    LK_IO_MESH = 1u << 0,      /* lk_mesh_read / lk_mesh_write (of an animation: frame 0) */
    LK_IO_ANIMATION = 1u << 1, /* lk_animation_read / lk_animation_write */
    LK_IO_GRID = 1u << 2,      /* lk_dem_read */
    LK_IO_STREAM = 1u << 3     /* lk_stream_inspect and lk_stream_decoder_* / lk_stream_encode */
};

typedef struct lk_format_info {
    const char *name;        /* short lowercase name; for the formats of lk_mesh_read,
                                lk_format_name's ("obj", "gltf") */
    const char *extensions;  /* lowercase, without dots, separated by one space, the
                                usual one first: "xyz xyzn pts" */
    lk_format_kind kind;     /* what a file of it holds */
    lk_format format;        /* lk_mesh_read / lk_mesh_write's value, or LK_FORMAT_UNKNOWN
                                when neither reads it */
    unsigned read;           /* LK_IO_* flags: the functions that read it */
    unsigned write;          /* LK_IO_* flags: the functions that write it (0: none) */
    const char *description; /* a few words: "Wavefront OBJ", "GeoTIFF (through GDAL)" */
} lk_format_info;

/* Entry `index` of the table, or NULL past the last one:
 *   const lk_format_info *info;
 *   for (size_t i = 0; (info = lk_format_info_at(i)); i++) ...
 * Entries are static (never freed) and come in a fixed order: meshes and
 * point sets, animations, elevation grids, streams. */
LK_API const lk_format_info *lk_format_info_at(size_t index);
/* The entry of a file name's extension (case-insensitive), or NULL. */
LK_API const lk_format_info *lk_format_info_from_path(const char *path);

typedef enum lk_ply_encoding { LK_PLY_BINARY_LE = 0, LK_PLY_BINARY_BE, LK_PLY_ASCII } lk_ply_encoding;

typedef struct lk_read_options {
    /* Memory budget of one read, in bytes (0 = 8 GiB). Everything the read
     * holds at once counts against it together: the input (the file
     * lk_mesh_read holds whole, or the caller's bytes given to
     * lk_mesh_read_memory), decoded buffers (glTF base64 data: URIs,
     * external .bin files), glTF's parsed JSON tree, the parser's growing
     * arrays and scratch tables (welding hash, index maps), and the mesh.
     * Claims in headers are checked against the file size and the budget
     * before anything is allocated, growing arrays as they grow; past the
     * budget the read fails with LK_ERR_LIMIT, naming it (a file larger
     * than it is refused before it is read). What a read may hold beyond
     * max_bytes is a constant: the first 16 MiB of a glTF's JSON tree (so
     * that small documents read under any budget), allocator slack (freed
     * blocks malloc keeps, a block being moved by realloc) and fixed-size
     * scratch (an ASF skeleton of at most 4096 bones, per-property values,
     * names); with the program's own ~35 MiB, a `lodkit` read peaks under
     * --max-memory + 64 MiB (tests/cli/test_cli_limits.sh). Work done on
     * the mesh after the read (statistics, simplification) is not part of
     * it. docs/formats.md. */
    size_t max_bytes;
    uint64_t reserved[8]; /* zero: room for fields of later versions (ABI rule, top of file) */
} lk_read_options;

/* Reads a mesh or point set from a file. format LK_FORMAT_AUTO picks it from
 * the extension, falling back to the content. options may be NULL.
 * On failure `mesh` is left empty and error says FILE:LINE or FILE: byte N. */
LK_API lk_status lk_mesh_read(const char *path, lk_format format, const lk_read_options *options, lk_mesh *mesh,
                              lk_error *error);
/* Same from memory; `name` is used in messages and for the extension when
 * format is AUTO. glTF files that reference external .bin files cannot be
 * read from memory (use lk_mesh_read). */
LK_API lk_status lk_mesh_read_memory(const void *data, size_t size, const char *name, lk_format format,
                                     const lk_read_options *options, lk_mesh *mesh, lk_error *error);

typedef struct lk_write_options {
    lk_ply_encoding ply_encoding; /* default binary little-endian */
    int skip_normals;             /* non-zero: do not write normals */
    int skip_texcoords;
    int skip_colors;
    int stl_ascii;        /* non-zero: ASCII STL instead of binary */
    uint64_t gltf_flags;  /* .glb/.gltf: LK_GLTF_* (0: floats, uncompressed, images embedded) */
    uint64_t reserved[7]; /* zero: room for fields of later versions (ABI rule, top of file) */
} lk_write_options;

/* lk_write_options.gltf_flags (docs/formats.md, "glTF 2.0 meshes"). */
enum {
    LK_GLTF_QUANTIZE = 1u << 0,       /* KHR_mesh_quantization: 14-bit positions over the scene's extent (node
                                   scale and translation), 8-bit normals and tangents, 12-bit texture
                                   coordinates in [0, 1], 8-bit colours */
    LK_GLTF_MESHOPT = 1u << 1,        /* EXT_meshopt_compression: meshoptimizer's codecs on every bufferView
                                   (required by the file: the uncompressed fallback holds no data).
                                   Either flag also drops texture coordinates and tangents that no
                                   material samples; this one also merges equal vertices and drops
                                   triangles whose corners are one vertex, as gltfpack does */
    LK_GLTF_EXTERNAL_IMAGES = 1u << 2 /* .gltf: each image in its own file next to the .gltf (STEM_N.png,
                                         .jpg, ...) referenced by URI, as most .gltf files ship, instead
                                         of inside the .bin; no effect on .glb (self-contained) */
};

/* Writes a mesh. The file is written to a temporary file next to `path` and
 * renamed over it at the end, so a failure never leaves a partial file.
 * options may be NULL (defaults). Formats that cannot hold an attribute
 * silently omit it (OFF keeps colours, SMF/STL keep positions only). */
LK_API lk_status lk_mesh_write(const char *path, lk_format format, const lk_mesh *mesh, const lk_write_options *options,
                               lk_error *error);

/* One level of a chain written by lk_mesh_write_lods. */
typedef struct lk_lod_level_info {
    double screen_coverage; /* MSFT_screencoverage: below this share of the screen height (the
                               model's bounding sphere against the viewport) the next level takes
                               over; the last level's value culls the model (0: never) */
    double error;           /* the level's error in model units, written to the node's
                               extras.lodkit.error (0 for the input itself) */
} lk_lod_level_info;

/* Writes levels of detail of one mesh, finest first, as one glTF 2.0 file
 * (.glb, or .gltf with NAME.bin; other extensions are refused) using the
 * MSFT_lod extension: level 0 is the node in the scene (every glTF loader
 * draws it), levels 1.. are the nodes its MSFT_lod ids list, and level 0's
 * extras.MSFT_screencoverage has one value per level (info may be NULL:
 * zeros). Each node's extras.lodkit says its level, triangles and error.
 * Written whole or not at all, like lk_mesh_write. Cost: O(total size). */
LK_API lk_status lk_mesh_write_lods(const char *path, const lk_mesh *levels, size_t level_count,
                                    const lk_lod_level_info *info, const lk_write_options *options, lk_error *error);

/* ------------------------------------------------------------------------ */
/* Scenes: node trees, meshes of several primitives, materials, textures     */
/* (src/scene.c; glTF: src/io_gltf_scene.c, src/io_gltf_mesh_write.c)       */
/* ------------------------------------------------------------------------ */

/* What a glTF file holds beyond one mesh, kept so that commands work per
 * primitive and write the scene back (docs/formats.md, "Scenes"). Indices
 * between the arrays are glTF's own (a material's texture 2 is
 * textures[2]); -1 means none. Materials, textures, samplers and cameras
 * are kept as the JSON objects of the file (so PBR parameters and the
 * KHR_materials_* / KHR_texture_* extensions pass through untouched), with
 * the few values lodkit itself uses decoded next to them. Every string and
 * array is owned by the scene (lk_scene_free). */
typedef struct lk_scene_primitive {
    lk_mesh mesh;      /* in its mesh's own coordinates; triangle_count 0: a point set (or lines) */
    int32_t material;  /* index into materials, -1: glTF's default material */
    float *tangents;   /* 4 * mesh.vertex_count or NULL: glTF TANGENT, xyz and the
                           bitangent sign w (normal maps need them) */
    float *texcoords1; /* 2 * mesh.vertex_count or NULL: TEXCOORD_1 (v up, like texcoords) */
    uint16_t *joints;  /* 4 * mesh.vertex_count or NULL: JOINTS_0, indices into the joints of
                           the skin of the node drawing the mesh */
    float *weights;    /* 4 * mesh.vertex_count or NULL: WEIGHTS_0 (with joints) */
    /* Morph targets (glTF "targets"; their number is the mesh's target_count):
     * per target 3 floats per vertex, target k's vertex v at
     * 3 * (k * mesh.vertex_count + v). Each array is NULL when no target has
     * that attribute (a target without it holds zeros). Shape k of the
     * primitive is positions + target_positions of k; a renderer adds each
     * target's deltas times its weight. */
    float *target_positions; /* POSITION deltas */
    float *target_normals;   /* NORMAL deltas */
    float *target_tangents;  /* TANGENT deltas (xyz; glTF has no w delta) */
    /* Line segments (glTF LINES; LINE_STRIP and LINE_LOOP become their
     * segments): segment s joins vertices lines[2s] and lines[2s + 1]. A
     * primitive with lines has no triangles; simplification, flattening
     * and rendering leave it out, writing keeps it. */
    uint32_t *lines;
    size_t line_count;
} lk_scene_primitive;

typedef struct lk_scene_mesh {
    char *name; /* NULL: none */
    lk_scene_primitive *primitives;
    size_t primitive_count;
    size_t target_count; /* morph targets of every primitive (glTF: all the same) */
    float *weights;      /* target_count default weights (glTF mesh.weights), or NULL: zeros */
    char **target_names; /* target_count names (mesh.extras.targetNames, as Blender and
                            three.js write them; a NULL entry: none), or NULL */
} lk_scene_mesh;

typedef struct lk_scene_node {
    char *name;   /* NULL: none */
    int32_t mesh; /* index into meshes, -1 none */
    int32_t camera;
    uint32_t *children; /* indices into nodes */
    size_t child_count;
    int has_matrix;        /* the file gave a matrix (else translation, rotation, scale) */
    double matrix[16];     /* the local transform, column-major like glTF (always set) */
    double translation[3]; /* when !has_matrix */
    double rotation[4];    /* unit quaternion x y z w */
    double scale[3];
    uint32_t *lod_nodes; /* MSFT_lod: coarser levels of this node, finest first */
    size_t lod_count;
    char *extras;   /* the node's "extras" JSON, or NULL */
    int32_t skin;   /* index into skins; -1 (or any index >= skin_count, such as a zeroed
                     node's 0): none. glTF: only with a mesh whose primitives have joints */
    float *weights; /* the node's own morph weights (glTF node.weights, overriding its
                       mesh's), its mesh's target_count of them, or NULL */
} lk_scene_node;

typedef struct lk_scene_material {
    char *name;
    float base_color[4];        /* pbrMetallicRoughness.baseColorFactor (default 1 1 1 1) */
    int32_t base_color_texture; /* pbrMetallicRoughness.baseColorTexture.index, or -1 */
    char *json;                 /* the whole glTF material object */
} lk_scene_material;

typedef struct lk_scene_texture {
    int32_t image;   /* "source": index into images, or -1 */
    int32_t sampler; /* index into samplers, or -1 */
    char *json;      /* the whole glTF texture object */
} lk_scene_texture;

typedef struct lk_scene_image {
    char *name;
    char *mime_type;     /* "image/png", "image/jpeg", ... */
    unsigned char *data; /* the encoded image file, size bytes */
    size_t size;
} lk_scene_image;

/* A skin: the nodes its joints are, and how the mesh sits in each joint's
 * space at rest. */
typedef struct lk_scene_skin {
    char *name;                   /* NULL: none */
    uint32_t *joints;             /* indices into nodes */
    size_t joint_count;           /* >= 1 */
    float *inverse_bind_matrices; /* 16 * joint_count, column-major, or NULL: identities */
    int32_t skeleton;             /* the skeleton's root node, or -1 */
} lk_scene_skin;

/* What an animation channel drives. */
typedef enum lk_scene_path {
    LK_SCENE_PATH_TRANSLATION = 0, /* 3 values per key */
    LK_SCENE_PATH_ROTATION = 1,    /* 4: a unit quaternion x y z w */
    LK_SCENE_PATH_SCALE = 2,       /* 3 */
    LK_SCENE_PATH_WEIGHTS = 3      /* morph weights: the node's mesh's target_count values per key */
} lk_scene_path;

typedef enum lk_scene_interpolation {
    LK_SCENE_LINEAR = 0,
    LK_SCENE_STEP = 1,
    LK_SCENE_CUBICSPLINE = 2 /* each key holds in-tangent, value, out-tangent */
} lk_scene_interpolation;

/* Key times and values, as the file gives them. */
typedef struct lk_scene_animation_sampler {
    lk_scene_interpolation interpolation;
    float *input;        /* key_count times in seconds, increasing */
    size_t key_count;    /* >= 1 */
    float *output;       /* output_count * components values */
    size_t output_count; /* key_count, or 3 * key_count for CUBICSPLINE */
    unsigned components; /* 3 (translation, scale), 4 (rotation) or 1 (weights: output_count
                            is then target_count times the above) */
} lk_scene_animation_sampler;

typedef struct lk_scene_animation_channel {
    uint32_t sampler; /* index into the animation's samplers */
    uint32_t node;    /* index into nodes */
    lk_scene_path path;
} lk_scene_animation_channel;

/* A glTF animation: channels, each driving one property of one node. */
typedef struct lk_scene_animation {
    char *name; /* NULL: none */
    lk_scene_animation_sampler *samplers;
    size_t sampler_count;
    lk_scene_animation_channel *channels;
    size_t channel_count; /* >= 1 */
} lk_scene_animation;

typedef struct lk_scene {
    lk_scene_node *nodes;
    size_t node_count;
    uint32_t *roots; /* the nodes of the scene drawn (glTF's default scene) */
    size_t root_count;
    lk_scene_mesh *meshes;
    size_t mesh_count;
    lk_scene_material *materials;
    size_t material_count;
    lk_scene_texture *textures;
    size_t texture_count;
    lk_scene_image *images;
    size_t image_count;
    char **samplers; /* JSON objects */
    size_t sampler_count;
    char **cameras; /* JSON objects */
    size_t camera_count;
    char **required_extensions; /* extensionsRequired of the file that the scene still uses */
    size_t required_extension_count;
    char *notes; /* what reading left out, one line each ("meshes[0].primitives[0]: lines dropped ..."), or NULL */
    lk_scene_skin *skins;
    size_t skin_count;
    lk_scene_animation *animations;
    size_t animation_count;
} lk_scene;

/* Sets every field to zero/NULL. */
LK_API void lk_scene_init(lk_scene *scene);
/* Frees everything the scene holds and re-initialises it. Accepts NULL. */
LK_API void lk_scene_free(lk_scene *scene);
/* Reads a scene. glTF keeps its default scene: node tree, meshes with their
 * primitives, materials, textures, samplers, images (decoded from the GLB,
 * data: URIs or files next to the .gltf), cameras, skins (with JOINTS_0 and
 * WEIGHTS_0), morph targets (POSITION, NORMAL and TANGENT deltas, sparse
 * accessors included; default weights, node weights, extras.targetNames)
 * and animations of nodes and of morph weights; line primitives as segments
 * (lk_scene_primitive.lines). Attributes other than POSITION, NORMAL,
 * TANGENT, TEXCOORD_0/1, COLOR_0, JOINTS_0 and WEIGHTS_0 (in targets too),
 * properties glTF 2.0 does not define and unknown extensions (dropped from
 * the objects that carried them) are left out and listed in scene->notes. An OBJ with `usemtl` gives one node and mesh
 * with a primitive per material, the materials and textures of its .mtl
 * files (read from the .obj's folder; what cannot be found is a note, see
 * docs/formats.md, "OBJ materials"). Every other format, and an OBJ
 * without `usemtl`, gives one node holding one mesh of one primitive (what
 * lk_mesh_read reads). Errors as lk_mesh_read. */
LK_API lk_status lk_scene_read(const char *path, const lk_read_options *options, lk_scene *scene, lk_error *error);
/* Same from memory; `name` gives the format by its extension and is used in
 * messages. A .gltf that names external files (buffers, images) cannot be
 * read from memory; an OBJ's .mtl files are not read (a note says so). */
LK_API lk_status lk_scene_read_memory(const void *data, size_t size, const char *name, const lk_read_options *options,
                                      lk_scene *scene, lk_error *error);
/* Writes a scene: .glb or .gltf (+ NAME.bin; images go into the buffer) keep
 * it whole; other formats get lk_scene_flatten's mesh. Written whole or not
 * at all; options as lk_mesh_write (gltf_flags included). */
LK_API lk_status lk_scene_write(const char *path, const lk_scene *scene, const lk_write_options *options,
                                lk_error *error);
/* A scene of one node, mesh and primitive holding `mesh`, which it takes
 * (mesh is left empty). */
LK_API lk_status lk_scene_from_mesh(lk_scene *scene, lk_mesh *mesh, lk_error *error);
/* Every primitive the scene draws, placed by its node's world transform,
 * as one mesh (attributes a primitive lacks are zero, colours white;
 * animations not played; a skinned mesh posed by its joints at the nodes'
 * own transforms, its node's transform not applied, as glTF says).
 * Point primitives are left out when the scene has triangles. */
LK_API lk_status lk_scene_flatten(const lk_scene *scene, lk_mesh *mesh, lk_error *error);
/* Deep copy of src into dst (dst is overwritten, not freed first). */
LK_API lk_status lk_scene_copy(lk_scene *dst, const lk_scene *src, lk_error *error);
/* One scene holding levels of detail (MSFT_lod) of scenes that share a node
 * tree and meshes (levels[k] is levels[0] with its meshes simplified,
 * finest first): a copy of level 0 whose every node with a mesh lists, in
 * its MSFT_lod ids, a new node per coarser level (same transform, that
 * level's mesh, extras.lodkit: level, triangles, error) and carries
 * extras.MSFT_screencoverage (info may be NULL: zeros). */
LK_API lk_status lk_scene_lod_chain(const lk_scene *levels, size_t level_count, const lk_lod_level_info *info,
                                    lk_scene *out, lk_error *error);
/* Triangles of every mesh (each counted once, however many nodes use it). */
LK_API size_t lk_scene_triangle_count(const lk_scene *scene);

/* ------------------------------------------------------------------------ */
/* Output files and whole input files (src/output.c)                        */
/* ------------------------------------------------------------------------ */

/* An output file written whole or not at all, the way lodkit writes its own
 * (meshes, streams, PNGs): the bytes go to a hidden temporary file next to
 * the path, ".NAME.tmp-XXXXXX" (mode 0666 less the umask; hidden so that a
 * listing, a shell glob or `lodkit serve` never takes it for an output), and
 * lk_output_commit renames it over the path once they are on disk. A
 * failure or lk_output_abort never leaves a partial file at the path (a
 * kill -9 can leave the hidden temporary file behind, safe to delete). */
typedef struct lk_output lk_output;
/* Creates the temporary file for `path`. An existing path that is not a
 * regular file (a directory, FIFO or device) is refused (LK_ERR_IO, "PATH:
 * exists and is not a regular file; not replacing it"); a symbolic link is
 * replaced by the new file, its target left untouched. */
LK_API lk_status lk_output_open(const char *path, lk_output **output, lk_error *error);
/* The stream to write into (binary). Do not close it. */
LK_API FILE *lk_output_stream(lk_output *output);
/* Flushes and fsyncs the file and renames it over the path. The first write
 * error met on the way (also one of an earlier buffered fprintf: ENOSPC,
 * EFBIG, EIO) gives LK_ERR_IO "PATH: write error: REASON"; then, or when
 * the rename fails, the temporary file is removed and the path keeps what
 * it held. Frees `output` in every case. */
LK_API lk_status lk_output_commit(lk_output *output, lk_error *error);
/* Removes the temporary file and frees `output` (NULL is fine). */
LK_API void lk_output_abort(lk_output *output);
/* For an output that is a whole folder: creates an empty hidden folder next
 * to `path`, ".NAME.TAG-XXXXXX" (TAG a short word such as "tmp"; mode 0777
 * less the umask), to build the new folder in and rename into place (the
 * same file system). Its path is written to temp_path (`size` bytes; a path
 * that does not fit gives LK_ERR_INVALID and no folder). */
LK_API lk_status lk_output_folder_create(const char *path, const char *tag, char *temp_path, size_t size,
                                         lk_error *error);

/* Reads a whole file into *data (release with lk_free; a NUL follows its
 * *size bytes). Only a regular file is read: a FIFO, socket, device or directory
 * is refused before anything could block on it (LK_ERR_IO, "PATH: is a
 * FIFO, not a regular file"). A file larger than max_bytes (0: no limit) is
 * refused before anything is allocated (LK_ERR_LIMIT, "PATH: the file has N
 * bytes, more than the memory budget of M bytes"); one that changes while
 * it is read gives LK_ERR_IO, never a partial buffer. */
LK_API lk_status lk_file_read(const char *path, size_t max_bytes, unsigned char **data, size_t *size, lk_error *error);

/* ------------------------------------------------------------------------ */
/* Surface distance (Metro-style)                                           */
/* ------------------------------------------------------------------------ */

/* A bounding-volume hierarchy over a mesh's triangles for nearest-point
 * queries. A mesh without triangles is indexed as a point set.
 * Build: O(T log T); query: O(log T) typical. The index keeps its own copy
 * of the geometry, so the mesh may be freed after building. */
typedef struct lk_surface_index lk_surface_index;
/* Builds the index of `mesh` into *index; lk_surface_index_free (which
 * accepts NULL) frees it. */
LK_API lk_status lk_surface_index_build(const lk_mesh *mesh, lk_surface_index **index, lk_error *error);
LK_API void lk_surface_index_free(lk_surface_index *index);
/* Nearest point of the surface to `point`. Returns the distance; writes the
 * closest point and triangle (or point) index when non-NULL. Searches only
 * within `max_distance` (pass INFINITY for no bound); returns INFINITY if
 * nothing is that close. Thread-safe (read-only). */
LK_API double lk_surface_index_nearest(const lk_surface_index *index, const double point[3], double max_distance,
                                       double closest[3], uint32_t *primitive);

typedef struct lk_metro_options {
    /* Face samples per triangle on average (area-proportional); used when
     * sample_count is 0. Default 10. */
    double samples_per_face;
    /* Total face samples per surface; overrides samples_per_face if > 0. */
    size_t sample_count;
    /* Also sample every vertex and points along every edge (Metro does, so
     * that the maximum is not missed). Default on; set to -1 to disable. */
    int sample_vertices;
    int sample_edges;
    uint64_t seed;        /* deterministic sampling seed (default 1) */
    int thread_count;     /* 0 = number of online CPUs */
    uint64_t reserved[8]; /* zero: room for fields of later versions (ABI rule, top of file) */
} lk_metro_options;

typedef struct lk_distance_stats {
    double max;          /* over all samples (vertices, edges, faces) */
    double mean;         /* area-weighted: over face samples */
    double rms;          /* area-weighted: over face samples */
    size_t sample_count; /* all samples taken on the source surface */
} lk_distance_stats;

typedef struct lk_metro_result {
    double diagonal;            /* bounding-box diagonal of mesh A */
    lk_distance_stats forward;  /* samples of A measured to B */
    lk_distance_stats backward; /* samples of B measured to A */
    double hausdorff;           /* max(forward.max, backward.max) */
    size_t sample_count;        /* forward + backward samples */
    double seconds;             /* wall time, including index building */
} lk_metro_result;

/* Fills options with the defaults described above. */
LK_API void lk_metro_options_default(lk_metro_options *options);
/* Measures the distance between two surfaces in both directions.
 * options may be NULL. Results are deterministic for a given seed,
 * whatever the thread count. Cost: O((S_a + S_b) log T) with S samples. */
LK_API lk_status lk_metro(const lk_mesh *a, const lk_mesh *b, const lk_metro_options *options, lk_metro_result *result,
                          lk_progress_fn progress, void *progress_user, lk_error *error);

/* One-sided measure: samples of `source` to `target_index`. */
LK_API lk_status lk_metro_one_sided(const lk_mesh *source, const lk_surface_index *target_index,
                                    const lk_metro_options *options, lk_distance_stats *stats, lk_error *error);


/* ------------------------------------------------------------------------ */
/* Simplification: quadric error metric and vertex clustering               */
/* ------------------------------------------------------------------------ */

typedef enum lk_simplify_method {
    LK_SIMPLIFY_QEM = 0,  /* Garland-Heckbert pair contraction (src/qem.c) */
    LK_SIMPLIFY_UNIFORM,  /* Rossignac-Borrel uniform-grid clustering (src/cluster.c) */
    LK_SIMPLIFY_FLOATING, /* Low-Tan floating-cell clustering (src/cluster.c) */
    LK_SIMPLIFY_WAVELET   /* planar sampling + CDF 9/7 contour wavelets (src/wavelet_simplify.c) */
} lk_simplify_method;

/* Flags for lk_simplify_options.flags. */
enum {
    LK_SIMPLIFY_LOCK_BORDER = 1u << 0, /* QEM: border vertices never move or vanish */
    LK_SIMPLIFY_ATTRIBUTES = 1u << 1,  /* QEM: quadrics also weigh normals/UVs/colours */
    LK_SIMPLIFY_NO_FEATURES = 1u << 2, /* QEM: no crease/corner constraint quadrics */
    LK_SIMPLIFY_RECORD = 1u << 3,      /* QEM: record the contraction history */
    LK_SIMPLIFY_ENDPOINTS = 1u << 4,   /* QEM: half-edge collapses: the merged vertex stays
                                          at the cheaper endpoint instead of the optimum */
    LK_SIMPLIFY_NO_REFINE = 1u << 5,   /* wavelet: no refinement between the planes (the
                                          paper's pipeline only; see lk_slices_tile) */
    LK_SIMPLIFY_ROUNDS = 1u << 6       /* QEM: contract in rounds of independent pairs: within a
                                          round no pair has an end next to a vertex an earlier
                                          contraction of the round moved or re-linked, and a round
                                          ends when the cheapest pair left waiting costs less than
                                          a quarter of the next one. Costs a little order (the
                                          result is within a few percent of greedy's error), and
                                          a round's splits then form one batch of a version-2
                                          .lks stream: its split vertices cost about half the
                                          bits (lk_stream_encode; `lodkit progressive` sets it
                                          for version 2) */
};

typedef struct lk_simplify_options {
    /* Stopping rules; simplification stops at the first one reached, and at
     * least one must be set (0 = unset). */
    double target_ratio;     /* fraction of the input triangles to keep, (0, 1]
                                (of the non-degenerate ones; for clustering a
                                repeated triangle counts each time) */
    size_t target_triangles; /* triangles to keep */
    size_t target_vertices;  /* vertices to keep */
    double max_error;        /* QEM: largest allowed collapse error, as a fraction of
                                the bounding-box diagonal (0.01 = 1%): costlier
                                collapses are skipped, so result.error never exceeds
                                it; clustering: the
                                cell size (cube side; floating cells: ball diameter)
                                as a fraction of the diagonal */
    /* QEM: also contract non-edge vertex pairs closer than this (fraction of
     * the diagonal); 0 = edges only. Found with a spatial grid. */
    double pair_distance;
    double feature_angle;    /* degrees: edges with a larger dihedral angle are
                                creases kept by constraint quadrics (default 40) */
    double feature_weight;   /* weight of border/crease constraint quadrics (default 1) */
    double attribute_weight; /* weight of attributes with LK_SIMPLIFY_ATTRIBUTES (default 1) */
    unsigned flags;
    /* Wavelet (LK_SIMPLIFY_WAVELET): slices and their axis. slice_count 0
     * (default) = 150, the paper's count, for an error target; with a count
     * target the one of 150, 100, 70, 50, 35, 25, 16, 11, 8 with the smallest
     * max(in-plane error, spacing) (see docs/wavelet.md). slice_axis is an
     * lk_axis (default LK_AXIS_AUTO = 0: the bounding box's shortest side). */
    size_t slice_count;
    int slice_axis;
    int wavelet_criterion; /* wavelet: an lk_wavelet_criterion, how a contour's level is
                                chosen (default 0 = LK_WAVELET_ENERGY, the paper's eq. 7) */
    /* QEM: threads for meshes of at least LK_SIMPLIFY_PARALLEL_MIN triangles
     * (0 or 1 = one, the default; smaller meshes always take one). With T
     * threads the mesh is cut into T slabs of equal triangle counts along
     * its longest side, each simplified on its own thread with the vertices
     * on the cuts locked, then a band around the cuts is simplified once
     * more. The result depends on T but not on timing; error is within a
     * few percent of one thread's. With LK_SIMPLIFY_RECORD (a history
     * is one sequence) it runs on one thread. At most 64. */
    uint64_t thread_count;
    uint64_t reserved[7]; /* zero: room for fields of later versions (ABI rule, top of file) */
} lk_simplify_options;

/* Below this many triangles lk_simplify_options.thread_count is ignored:
 * cutting and joining would cost more than the second thread saves. */
#define LK_SIMPLIFY_PARALLEL_MIN 200000

/* Fills options with the defaults: no target (set one), feature_angle 40,
 * feature_weight 1, attribute_weight 1, flags 0. */
LK_API void lk_simplify_options_default(lk_simplify_options *options);

/* One contraction (QEM history): input vertex `removed` merges into input
 * vertex `kept`, which moves to `position`. The input triangles
 * result.vanished[first_vanished .. first_vanished + vanished_count) become
 * degenerate and disappear; every other triangle that used `removed` now
 * uses `kept`. Replaying the history on the input mesh in order gives the
 * output mesh (before vertex compaction). Triangle ids are those of the
 * input after degenerate and duplicate triangles are dropped (the same ids
 * when the input has none; lk_mesh_remove_degenerate gives that mesh). */
typedef struct lk_collapse {
    uint32_t kept;
    uint32_t removed;
    float position[3];
    float error; /* this collapse's error in model units (see lk_simplify_result.error) */
    uint32_t first_vanished;
    uint32_t vanished_count;
} lk_collapse;

typedef struct lk_simplify_result {
    lk_mesh mesh;          /* the simplified mesh, unused vertices removed */
    double error;          /* reached error in model units: for QEM the largest
                                sqrt(quadric cost / quadric area) over performed
                                collapses (an RMS plane distance); for clustering
                                the largest distance a vertex moved */
    double diagonal;       /* bounding-box diagonal of the input */
    int target_reached;    /* 0 when no target could be reached (e.g. every
                                remaining collapse would break the topology); the
                                nearest result is returned and the status is LK_OK */
    uint32_t *vertex_map;  /* input vertex -> output vertex, UINT32_MAX if gone */
    size_t collapse_count; /* with LK_SIMPLIFY_RECORD */
    lk_collapse *collapses;
    uint32_t *vanished; /* triangle ids referenced by collapses */
    size_t vanished_count;
    double seconds; /* wall time of the simplification */
} lk_simplify_result;

/* Frees the mesh and arrays of a result and zeroes it. Accepts NULL. */
LK_API void lk_simplify_result_free(lk_simplify_result *result);

/* Simplifies a triangle mesh. The input is not modified. Degenerate and
 * duplicate triangles are ignored; a mesh without triangles is refused
 * (LK_ERR_INVALID). QEM simplifies non-manifold and open meshes without
 * creating new non-manifold edges; clustering merges whole cells and may
 * create them (inherent to the method), and when every triangle collapses
 * returns an empty mesh with target_reached = 0. QEM cost: O(T log T) time, O(T)
 * memory; clustering: O(T) per cell size tried. */
LK_API lk_status lk_simplify(const lk_mesh *mesh, lk_simplify_method method, const lk_simplify_options *options,
                             lk_simplify_result *result, lk_progress_fn progress, void *progress_user, lk_error *error);

typedef struct lk_scene_simplify_stats {
    size_t primitives; /* primitives simplified */
    size_t triangles_in, triangles_out;
    double error; /* the largest primitive error, in world units (its mesh's error
                     times the largest scale of the nodes drawing it) */
} lk_scene_simplify_stats;

/* Simplifies every triangle primitive in place with lk_simplify; materials,
 * nodes and point primitives are untouched. target_ratio applies to each
 * primitive; target_triangles is shared out in proportion to their
 * triangles; max_error is a fraction of the whole scene's diagonal (in
 * each mesh's own units). Attributes are kept with LK_SIMPLIFY_ATTRIBUTES
 * (always set: texture seams and attribute discontinuities stay). A QEM
 * primitive with morph targets is simplified as an animation of its shapes
 * (the base and base + each target at full weight, lk_animation_simplify's
 * max scheme with the lost-surface term at LK_ANIM_LOST_SURFACE_DEFAULT,
 * which one-frame primitives leave out): one collapse order whose cost is
 * the worst over the shapes,
 * each output vertex placed at each shape's own optimum, so each target's
 * POSITION delta is that shape's position minus the base's; NORMAL and
 * TANGENT deltas come from the input vertex whose attributes the output
 * vertex took. Clustering keeps the deltas of that input vertex. With a
 * size target (ratio or triangles) and no morph targets, QEM runs twice,
 * with the crease and corner constraints and without them
 * (LK_SIMPLIFY_NO_FEATURES), and keeps the scene closer to the input as
 * drawn (Hausdorff distance, Metro's sampling): the constraints help
 * smooth models and hurt low-polygon ones, where most edges are sharp.
 * That doubles the time (and adds two distance measurements) unless the
 * caller sets LK_SIMPLIFY_NO_FEATURES. stats may be NULL. */
LK_API lk_status lk_scene_simplify(lk_scene *scene, lk_simplify_method method, const lk_simplify_options *options,
                                   lk_scene_simplify_stats *stats, lk_error *error);

/* ------------------------------------------------------------------------ */
/* Wavelet simplification by planar sampling (src/wavelet_simplify.c)      */
/* ------------------------------------------------------------------------ */
/* Jang, Lee, Han & Park 2004, "Efficient 3D object simplification using 2D
 * planar sampling and wavelet transform" (docs/wavelet.md has the details):
 * the surface is cut by equally spaced planes perpendicular to one axis into
 * closed 2D contours; each contour's two coordinate sequences go through a
 * CDF 9/7 wavelet transform, fine details are dropped, and the coarse
 * contours are tiled back into a closed triangle mesh.
 * lk_simplify(..., LK_SIMPLIFY_WAVELET, ...) runs the three steps below
 * (src/slice.c, wavelet.c, tile.c), then refines between the planes; they
 * are public so that tools can draw and measure each one. */

/* ---- CDF 9/7 on periodic sequences (src/wavelet.c) ---- */

/* The paper's analysis filters (Table 1): low-pass h_L[-4..4] sums to 1 and
 * is centred on even samples, high-pass h_H[-3..3] sums to 0 and is centred
 * on odd samples. One level of lk_wavelet_forward gives exactly
 *   a[i] = sum_j h_L[j] x[2i + j],   d[i] = sum_j h_H[j] x[2i + 1 + j]
 * with periodic indices; the synthesis filters are Table 2's (whose h'_L
 * column misprints h_L's +-4 tap: the 7-tap synthesis low-pass has none). */
LK_API extern const double lk_cdf97_analysis_low[9];  /* h_L[-4..4] */
LK_API extern const double lk_cdf97_analysis_high[7]; /* h_H[-3..3] */

/* In-place forward transform of a periodic (closed) sequence over `levels`
 * levels, by lifting. count must be a multiple of 2^levels, with at least 2
 * samples left at the coarsest level. Result layout (Mallat):
 * [a_L | d_L | d_{L-1} | ... | d_1], a_L holding count >> levels samples
 * and d_k count >> k. levels == 0 leaves data unchanged. */
LK_API lk_status lk_wavelet_forward(double *data, size_t count, unsigned levels, lk_error *error);
/* Exact inverse of lk_wavelet_forward (same layout); reconstructs to
 * rounding error (~1e-15 relative). */
LK_API lk_status lk_wavelet_inverse(double *data, size_t count, unsigned levels, lk_error *error);

/* ---- Planar sampling into contours (src/slice.c) ---- */

typedef enum lk_axis {
    LK_AXIS_AUTO = 0, /* the bounding box's shortest axis (the paper's choice) */
    LK_AXIS_X,
    LK_AXIS_Y,
    LK_AXIS_Z
} lk_axis;

/* One closed contour: points[first .. first + count) of its lk_slices, in
 * order, the last joined to the first. Seen from +axis, outer boundaries run
 * counter-clockwise (area > 0) and holes clockwise (area < 0), following the
 * input's outward (counter-clockwise) triangle orientation. */
typedef struct lk_contour {
    uint32_t slice; /* plane index */
    uint32_t first;
    uint32_t count;
    uint32_t level; /* after lk_slices_simplify: wavelet level kept (0 = all samples) */
    double area;    /* signed area in the (u, v) plane */
    /* Which piece of the surface lies on each side of the contour: `below`
     * names the connected piece of the surface between this plane and the
     * one under it (below plane 0: the rest of the surface under it),
     * `above` the piece between this plane and the next. Contours that share
     * a piece are joined by the surface between their planes: lk_slices_tile
     * connects exactly those, so a connected input stays connected. Set by
     * lk_mesh_slice (ids from 1; pieces are numbered across all planes),
     * kept by lk_slices_simplify. 0 = unknown (contours made by hand):
     * lk_slices_tile then pairs contours by the overlap of their areas. */
    uint32_t below, above;
} lk_contour;

/* The planar sampling of a closed surface. Plane k lies at
 * origin + (k + 0.5) * spacing along `axis`, so every surface point is
 * within spacing / 2 of a plane along the axis (the paper's sampling error).
 * Point coordinates are (u, v) with (u, v, axis) a right-handed permutation
 * of (x, y, z): (y, z) for X, (z, x) for Y, (x, y) for Z. */
typedef struct lk_slices {
    lk_axis axis;            /* LK_AXIS_X, _Y or _Z */
    unsigned u_axis, v_axis; /* 0, 1, 2 for x, y, z */
    size_t slice_count;
    double origin;         /* bounding-box minimum along the axis */
    double spacing;        /* extent / slice_count */
    double sampling_error; /* spacing / 2 */
    double diagonal;       /* bounding-box diagonal of the mesh */
    size_t contour_count;
    lk_contour *contours; /* ordered by slice */
    size_t point_count;
    double *points; /* 2 * point_count: u v */
} lk_slices;

/* Sets every field to zero/NULL. */
LK_API void lk_slices_init(lk_slices *slices);
/* Frees the arrays and re-initialises. Accepts NULL. */
LK_API void lk_slices_free(lk_slices *slices);
/* Position along the axis of plane k. */
LK_API double lk_slices_plane(const lk_slices *slices, size_t k);

/* Cuts a closed, consistently oriented 2-manifold (any number of
 * components) with slice_count >= 2 planes perpendicular to `axis` (AUTO:
 * the shortest bounding-box side) into contours: the exact plane-mesh
 * intersection, one point per crossed mesh edge, chained through the
 * triangles in the order their orientation gives. A vertex lying exactly on
 * a plane counts as above it (a symbolic offset), so every contour closes;
 * the repeated points this gives are merged. Refused with LK_ERR_UNSUPPORTED
 * and the count in the message: meshes with boundary (open) edges,
 * non-manifold edges or inconsistent orientation; with LK_ERR_INVALID: a
 * bounding box without extent along the axis, non-finite positions.
 * `out` is overwritten. Cost: O(T + P) for P points. */
LK_API lk_status lk_mesh_slice(const lk_mesh *mesh, lk_axis axis, size_t slice_count, lk_slices *out,
                               lk_progress_fn progress, void *progress_user, lk_error *error);

/* ---- Wavelet simplification of the contours (src/wavelet.c) ---- */

/* How a contour's level is chosen (docs/wavelet.md compares them). */
typedef enum lk_wavelet_criterion {
    /* The paper's eq. 7 (the default): the coarsest level whose dropped
     * detail coefficients (both coordinates, levels 1..L) have energy
     * sum c^2 <= threshold^2. */
    LK_WAVELET_ENERGY = 0,
    /* The coarsest level whose polygon stays within the threshold of every
     * sampled point (max norm). */
    LK_WAVELET_DISTANCE = 1
} lk_wavelet_criterion;
/* The criterion lk_simplify(..., LK_SIMPLIFY_WAVELET, ...) uses (chosen by
 * bench_wavelet, see docs/wavelet.md). */
#define LK_WAVELET_CRITERION_DEFAULT LK_WAVELET_ENERGY

typedef struct lk_contour_simplify_options {
    double max_error;               /* model units: the threshold (distance criterion: largest in-plane
                                distance from a sampled point to the simplified contour;
                                energy criterion: sqrt of the dropped energy); 0 = no bound */
    size_t target_vertices;         /* total points to keep (0 = no target) */
    lk_wavelet_criterion criterion; /* default (0) LK_WAVELET_ENERGY */
    uint64_t reserved[8];           /* zero: room for fields of later versions (ABI rule, top of file) */
} lk_contour_simplify_options;

typedef struct lk_contour_simplify_info {
    double error;               /* largest in-plane distance reached (model units) */
    double threshold;           /* the error threshold chosen by the search */
    size_t midpoints;           /* midpoints inserted to pad contours to 2^n samples */
    size_t untransformed;       /* contours with fewer than 4 points, kept as they are */
    size_t pruned;              /* vertices dropped as redundant after the level choice */
    size_t level_histogram[16]; /* contours per kept level */
    int target_reached;         /* 0 when even the coarsest contours exceed target_vertices */
} lk_contour_simplify_info;

/* Simplifies every contour of `in` into `out` (overwritten): each contour is
 * padded to 2^n samples with midpoints of its longest segments, transformed
 * (CDF 9/7, down to 4 coarse samples), and replaced by the coarsest level
 * whose discarded details are within the threshold: their energy (sum of
 * the squared detail coefficients of both coordinates, levels 1..L, at most
 * threshold^2; LK_WAVELET_ENERGY) or the distance they move a sampled point
 * from the polygon through that level's samples (LK_WAVELET_DISTANCE). The
 * level's points are the synthesis of the coarse coefficients alone, at the
 * coarse sample positions; vertices whose removal moves no sampled point
 * further than the threshold from the contour are then dropped (both
 * criteria). The threshold is max_error, or the smallest one that meets
 * target_vertices (bisection, stopped within 0.2% of the target), or the
 * smaller of the two. Contours with fewer than 4 points are kept.
 * Every output contour keeps at least 3 points. info may be NULL.
 * Cost: O(P log P) plus O(P) per bisection step. */
LK_API lk_status lk_slices_simplify(const lk_slices *in, const lk_contour_simplify_options *options, lk_slices *out,
                                    lk_contour_simplify_info *info, lk_progress_fn progress, void *progress_user,
                                    lk_error *error);

/* ---- Tiling (src/tile.c) ---- */

typedef struct lk_tile_info {
    size_t bands;   /* stitched groups of contours on neighbouring slices */
    size_t bridges; /* contours joined to another one of their slice at a branching */
    size_t caps;    /* contour sides closed by an ear-clipped polygon */
    size_t dropped; /* contours without pieces (made by hand) overlapping nothing on either
                       side (thinner than two slices), left out */
    size_t apexes;  /* caps closed as a fan around a new vertex half a spacing off the plane:
                       an ear-clipped cap's diagonal was an edge already (a contour closed
                       on both sides by caps, e.g. a part crossing one plane) */
} lk_tile_info;

/* Connects the contours into a closed triangle mesh (`out` overwritten).
 * Contours from lk_mesh_slice know the surface pieces between the planes
 * (lk_contour.below / .above): for each slab between neighbouring planes
 * (and below the first and above the last), the contours touching one
 * piece form a group; with contours on both planes it is a band between
 * the two loops the group's contours are joined into by bridges, with
 * contours on one plane only (the surface ends between the planes) one cap
 * over the joined loop. So the output has one component per input
 * component that crosses a plane, whatever the contours' shapes. A cap
 * whose ear-clipped diagonals are edges already becomes a fan around a new
 * vertex half a spacing off the plane (lk_tile_info.apexes).
 * Contours made by hand (pieces 0) are paired by overlap instead: for each
 * pair of neighbouring slices, contours with the same orientation
 * whose areas overlap (estimated on a grid; an overlap counts when it is the
 * best of one of the two contours or >= 10% of the smaller one) form
 * groups; a hole with no partner whose inside is mostly empty on the other
 * slice (a pit opening into a notch) joins the group of the contour around
 * it. In a group the contours of each slice are joined into one loop by
 * bridges (a branching: split or merge; the bridge is a quadrilateral on
 * the slice plane between close points, preferring bridges over the other
 * slice's contours, or outside them for a hole; branches under 1% of the
 * largest one's area are capped instead), and the two loops are stitched
 * with the least total diagonal length over 5 start pairs (the closest
 * pair of points, and the nearest partner of 4 points spread along the
 * lower loop). A contour side left without a group (first and last
 * slices, parts that appear or vanish) is capped with an ear-clipped
 * polygon. Every contour edge then has exactly two triangles, so the result
 * is a closed, consistently oriented 2-manifold (outward when the contours
 * come from lk_mesh_slice). Vertices are the contour points lifted to their
 * planes (dropped contours' points removed). info may be NULL.
 * Cost: O(n_a n_b) per band, O(n^2) per cap or bridge. */
LK_API lk_status lk_slices_tile(const lk_slices *slices, lk_mesh *out, lk_tile_info *info, lk_error *error);
/* Note: lk_simplify(mesh, LK_SIMPLIFY_WAVELET, options, ...) runs slicing,
 * contour simplification (options->wavelet_criterion) and tiling; then,
 * with a count target and unless LK_SIMPLIFY_NO_REFINE is set, 8% of the
 * vertex budget (plus what the tiling left unused) goes to vertices
 * inserted between the planes where the tiled surface is farthest from the
 * input, each on the input surface (docs/wavelet.md, "Refinement"; not in
 * the paper). The output stays a closed, consistently oriented 2-manifold
 * with at most the target's vertices, one component per input component
 * that crosses a slicing plane. An input with a few holes (at most 5% of
 * its edges on a boundary) is closed first: a triangle per 3-edge hole, a
 * fan around the centroid for longer ones; more open meshes are refused
 * (LK_ERR_UNSUPPORTED). A count target tries 150, 100, 70, 50, 35, 25,
 * 16, 11 and 8 slices (the nearest when none reaches it). Cost: the three steps, plus 6 rounds
 * of nearest-point queries (input vertices to the output, output triangles
 * to the input). */

/* ------------------------------------------------------------------------ */
/* Animated meshes: key frames, skinning, multi-frame QEM (src/anim.c)      */
/* ------------------------------------------------------------------------ */
/* A deforming mesh: one connectivity shared by frame_count frames. */
typedef struct lk_animation {
    lk_mesh mesh;             /* connectivity, attributes (texcoords, ...) and the
                                  positions of frame 0 */
    size_t frame_count;       /* >= 1 */
    float *frame_positions;   /* frame_count * mesh.vertex_count * 3 floats;
                                  frame f starts at f * vertex_count * 3 */
    double frames_per_second; /* playback rate (> 0) */
    char **frame_names;       /* frame_count names (MD2 frame names), or NULL */
} lk_animation;

/* Sets every field to zero/NULL. */
LK_API void lk_animation_init(lk_animation *animation);
/* Frees everything and re-initialises. Accepts NULL. */
LK_API void lk_animation_free(lk_animation *animation);
/* Copies frame `frame` into out (connectivity + attributes + that frame's
 * positions); out is overwritten, not freed first. */
LK_API lk_status lk_animation_frame(const lk_animation *animation, size_t frame, lk_mesh *out, lk_error *error);

/* ---- Reading and writing animations (src/anim_dispatch.c, io_md2.c, io_kmf.c,
 * io_acclaim.c, io_gltf.c; formats in docs/formats.md) ----
 * lk_animation_read picks the format from the extension:
 *   .kmf          lodkit's key-frame model format (SMF frames, one connectivity)
 *   .md2          Quake II key frames (positions quantised to 8 bits per axis)
 *   .gltf / .glb  one animation (animation_index) of the default scene: morph
 *                 targets and/or skins (linear-blend skinning), evaluated at
 *                 the union of its key times or resampled at frames_per_second
 *   .amc / .asf   an Acclaim set: X.asf (skeleton), X.amc (motion), X.smf
 *                 (rest-pose mesh) and X.wgt (bone weights) side by side; for
 *                 other names use lk_animation_read_acclaim.
 * Frames must all have the mesh's vertex count; every reader checks counts and
 * offsets against the file size before allocating and reports FILE:LINE (text)
 * or FILE: byte N (binary). */
typedef struct lk_animation_read_options {
    size_t max_bytes;         /* memory budget of the read (0 = 8 GiB), counted as for
                                  lk_read_options: the input, the mesh, the frames and whatever
                                  else the reader holds at once (an Acclaim set's four files,
                                  motion and weights share it) */
    size_t max_frames;        /* refuse animations with more frames (0 = 100000) */
    double frames_per_second; /* glTF: 0 = one frame per key time; > 0 = resample
                                  [first key, last key] at this rate. Acclaim: the
                                  AMC frame rate (0 = 120, the usual mocap rate) */
    size_t animation_index;   /* glTF: which animation (default 0) */
    int all_animations;       /* glTF: non-zero plays every animation at once
                                  (exporters such as COLLADA2GLTF write one
                                  animation per node); animation_index is ignored */
    uint64_t reserved[8];     /* zero: room for fields of later versions (ABI rule, top of file) */
} lk_animation_read_options;

/* What a reader noticed that was not an error (the CLI prints it). */
typedef struct lk_animation_report {
    size_t weights_normalised;  /* skinned vertices whose weights did not sum to 1
                                   (|sum - 1| > 1e-3) and were rescaled */
    size_t vertices_unweighted; /* skinned vertices with no weight: kept at rest */
    size_t bone_count;          /* ASF bones (root included) or glTF joints */
    size_t key_count;           /* source key frames (MD2/KMF frames, AMC frames,
                                   distinct glTF key times) */
    int skinned;                /* frames come from skinning */
    int morphed;                /* frames come from glTF morph targets */
} lk_animation_report;

/* Reads with default options. On failure `animation` is left empty. */
LK_API lk_status lk_animation_read(const char *path, lk_animation *animation, lk_error *error);
/* options and report may be NULL. */
LK_API lk_status lk_animation_read_ex(const char *path, const lk_animation_read_options *options,
                                      lk_animation *animation, lk_animation_report *report, lk_error *error);
/* Same from memory: `name` gives the format by its extension and is used in
 * messages. glTF files with external buffers and Acclaim sets cannot be read
 * from memory. */
LK_API lk_status lk_animation_read_memory(const void *data, size_t size, const char *name,
                                          const lk_animation_read_options *options, lk_animation *animation,
                                          lk_animation_report *report, lk_error *error);
/* Writes by extension, atomically (temp file + rename):
 *   .kmf   exact: floats printed with %.7g, or %.9g where needed to read
 *          back the same float; write + read gives identical frames;
 *   .md2   positions quantised per frame to 8 bits per axis; at most 32767
 *          vertices; normal indices 0; texcoords on the smallest skin size
 *          that keeps them whole texels (else 256); no glcmds;
 *   .gltf  morph-target animation in one file: frame 0 is the base mesh,
 *          frame f the target f-1, keyed at f / fps with weight 1 on it
 *          (LINEAR); at most 2048 frames; frame names are not kept and
 *          positions come back within float rounding (docs/formats.md). */
LK_API lk_status lk_animation_write(const char *path, const lk_animation *animation, lk_error *error);
/* Checks frame_count >= 1, frames_per_second > 0, indices in range and every
 * frame's positions finite. */
LK_API lk_status lk_animation_validate(const lk_animation *animation, lk_error *error);

/* ---- Acclaim skeletons (ASF), motions (AMC) and bone weights (WGT)
 * (src/io_acclaim.c; posing and skinning: src/anim_skeleton.c) ---- */
typedef enum lk_dof {
    LK_DOF_TX = 0,
    LK_DOF_TY,
    LK_DOF_TZ, /* translations (root only here) */
    LK_DOF_RX,
    LK_DOF_RY,
    LK_DOF_RZ, /* rotations, degrees (or radians per :units angle) */
    LK_DOF_L   /* length change: read, ignored by skinning */
} lk_dof;

typedef struct lk_bone {
    char name[64];
    int parent;          /* index into bones, -1 for the root */
    double direction[3]; /* unit direction of the bone in the base pose (global axes) */
    double length;       /* in ASF length units */
    double axis[3];      /* local frame orientation, degrees, ... */
    char axis_order[4];  /* ... applied in this order, e.g. "XYZ" (X first) */
    unsigned dof_count;  /* channels this bone has in the AMC, in file order */
    lk_dof dof[7];
    double limits[7][2]; /* per channel (min, max); +-INFINITY when unlimited */
} lk_bone;

/* bones[0] is the root: its direction/length are 0, its dof list is the
 * :root order, axis/axis_order its orientation, and `root_position` the
 * base position. */
typedef struct lk_skeleton {
    size_t bone_count;
    lk_bone *bones; /* parents come before children */
    double root_position[3];
    double length_unit;    /* :units length (informative; lengths are used as given) */
    int angles_in_radians; /* :units angle rad */
} lk_skeleton;

/* frame_count frames of skeleton->bones[b].dof_count values per bone;
 * values[f * channel_count + channel_offset[b] + k] is channel k of bone b. */
typedef struct lk_motion {
    size_t frame_count;
    size_t channel_count;
    size_t *channel_offset; /* bone_count */
    double *values;         /* as in the file (degrees unless the ASF says rad) */
} lk_motion;

/* Per-vertex bone influences in compressed rows: vertex v's influences are
 * [offsets[v], offsets[v+1]) of bones/weights (bone = skeleton index). */
typedef struct lk_bone_weights {
    size_t vertex_count;
    uint32_t *offsets; /* vertex_count + 1 */
    uint32_t *bones;
    float *weights;
} lk_bone_weights;

/* Reads an ASF skeleton (`skeleton` is overwritten). */
LK_API lk_status lk_skeleton_read(const char *path, lk_skeleton *skeleton, lk_error *error);
/* Frees the bones and zeroes the struct. Accepts NULL. */
LK_API void lk_skeleton_free(lk_skeleton *skeleton);
/* Needs the skeleton for the channel layout; unknown bones are errors. */
LK_API lk_status lk_motion_read(const char *path, const lk_skeleton *skeleton, lk_motion *motion, lk_error *error);
LK_API void lk_motion_free(lk_motion *motion);
/* Reads a WGT file for a mesh of vertex_count vertices. */
LK_API lk_status lk_bone_weights_read(const char *path, const lk_skeleton *skeleton, size_t vertex_count,
                                      lk_bone_weights *weights, lk_error *error);
LK_API void lk_bone_weights_free(lk_bone_weights *weights);
/* Same three from memory (name is used in messages); for tests and fuzzing. */
LK_API lk_status lk_skeleton_read_memory(const char *data, size_t size, const char *name, lk_skeleton *skeleton,
                                         lk_error *error);
LK_API lk_status lk_motion_read_memory(const char *data, size_t size, const char *name, const lk_skeleton *skeleton,
                                       lk_motion *motion, lk_error *error);
LK_API lk_status lk_bone_weights_read_memory(const char *data, size_t size, const char *name,
                                             const lk_skeleton *skeleton, size_t vertex_count, lk_bone_weights *weights,
                                             lk_error *error);

/* World transform (column-major 4x4, column vectors) of every bone for one
 * frame (frame == SIZE_MAX: the ASF base pose). out holds 16 * bone_count. */
LK_API lk_status lk_skeleton_pose(const lk_skeleton *skeleton, const lk_motion *motion, size_t frame, double *out,
                                  lk_error *error);

/* Linear-blend skinning of a rest-pose mesh (the ASF base pose) into one
 * frame per AMC frame: v_f = sum_b w_b * P_b(f) * P_b(base)^-1 * v. Weights
 * that do not sum to 1 are normalised (counted in report). The output's
 * frame 0 is AMC frame 1. report may be NULL. */
LK_API lk_status lk_animation_from_acclaim(const lk_mesh *rest_pose, const lk_skeleton *skeleton,
                                           const lk_motion *motion, const lk_bone_weights *weights,
                                           double frames_per_second, lk_animation *out, lk_animation_report *report,
                                           lk_error *error);
/* Reads the four files and skins them (any of asf/amc/wgt paths may differ
 * in stem); options and report may be NULL. */
LK_API lk_status lk_animation_read_acclaim(const char *smf_path, const char *asf_path, const char *amc_path,
                                           const char *wgt_path, const lk_animation_read_options *options,
                                           lk_animation *animation, lk_animation_report *report, lk_error *error);
/* ---- Deformation-sensitive simplification (src/qem.c, src/anim_simplify.c) ----
 * Cho & Chen 2004: QEM pair contraction on one connectivity for all frames.
 * Every vertex has one quadric per frame (area-weighted face planes, border
 * and crease constraints of that frame's positions, as lk_simplify builds);
 * a pair (a, b) gets, in every frame i, the position v_i minimising
 * Q_i,a + Q_i,b (lk_simplify's placement rules, frame by frame) and the
 * per-frame cost e_i = v_i^T (Q_i,a + Q_i,b) v_i. The pair's priority is
 *   LK_ANIM_SCHEME_MAX:   max_i e_i (the paper's scheme: keeps motion
 *                         features that show in a few frames only),
 *   LK_ANIM_SCHEME_AVG:   the mean of e_i over frames,
 *   LK_ANIM_SCHEME_FRAME: e_K of one frame K.
 * A contraction sums each frame's quadrics and moves the kept vertex to each
 * frame's own optimum; the link condition, the non-manifold test and the
 * normal-flip test hold in every frame. Costs of all frames are measured
 * in one normalisation (the bounds of all frames), so they are comparable. */
typedef enum lk_anim_scheme { LK_ANIM_SCHEME_MAX = 0, LK_ANIM_SCHEME_AVG, LK_ANIM_SCHEME_FRAME } lk_anim_scheme;

/* "max", "avg", "frame"; NULL for an unknown value. */
LK_API const char *lk_anim_scheme_name(lk_anim_scheme scheme);
/* Parses "max" / "avg" / "frame" (also "mean", "single"); 0 on success. */
LK_API int lk_anim_scheme_parse(const char *name, lk_anim_scheme *scheme);

typedef struct lk_anim_simplify_options {
    /* Targets (ratio / triangles / vertices: the first reached wins),
     * max_error (compared with the scheme's combination of the per-frame
     * errors), pair_distance (non-edge pairs found in the reference frame),
     * feature_angle, feature_weight and the flags LK_SIMPLIFY_LOCK_BORDER,
     * LK_SIMPLIFY_NO_FEATURES, LK_SIMPLIFY_ENDPOINTS (the cheaper end, by the
     * scheme, stays in every frame). LK_SIMPLIFY_ATTRIBUTES and
     * LK_SIMPLIFY_RECORD are refused (LK_ERR_UNSUPPORTED). Attributes
     * (texcoords, ...): with seams welded (default, see keep_seams) every
     * output corner keeps those of an input vertex; with keep_seams they are
     * interpolated along each pair in the reference frame. */
    lk_simplify_options simplify;
    lk_anim_scheme scheme; /* default LK_ANIM_SCHEME_MAX */
    size_t frame;          /* LK_ANIM_SCHEME_FRAME: the frame K (also the reference
                                  frame; otherwise frame 0 is) */
    size_t max_bytes;      /* refuse (LK_ERR_LIMIT) when the per-frame quadrics and
                                  positions, 124 bytes per vertex and frame (156 with
                                  the lost-surface term), would need
                                  more (0 = 2 GiB) */
    int keep_seams;        /* 0 (default): vertices whose positions are equal in every
                                  frame (split by texture seams, as MD2 readers do) are
                                  simplified as one vertex and split again on output: each
                                  triangle corner takes the attributes of the copy in its
                                  input triangle's connected part (its texture chart), so
                                  no triangle spans a seam and copies move together;
                                  non-zero: keep them apart (every seam is then a border
                                  whose two sides may drift apart: cracks) */
    int allow_folds;       /* 0 (default): a contraction that would turn a triangle's
                                  normal by more than ~78 degrees in any frame is refused,
                                  and the simplification stops where every remaining one is
                                  (target_reached = 0; on faerie.md2 near 30% of the
                                  triangles: a connectivity must suit every pose). Non-zero:
                                  from there on check the reference frame only, as
                                  lk_simplify does, so much lower targets are reached, though
                                  not always exactly: the link condition and the reference
                                  frame's test still refuse pairs (faerie.md2 at 10%, scheme
                                  frame 0: 68 of the 65 triangles, target_reached = 0); other
                                  frames may then fold (result.folds_from_triangles says where) */
    double lost_surface;   /* weight of the lost-surface term (default
                                  LK_ANIM_LOST_SURFACE_DEFAULT; 0: the paper's cost, quadrics
                                  alone). Each frame's cost of a pair adds lost_surface times
                                  the squared distances, each weighted by its vertex's area in
                                  that frame, from the input vertices merged into the pair so
                                  far to the triangles around the merged vertex; the scheme then
                                  combines the frames as before. Quadrics measure the merged
                                  vertex against the input's planes and miss what this sees on
                                  thin parts (a limb whose planes contain its axis folds into
                                  the body at almost no quadric cost). Cost: each evaluation
                                  reads frames x merged vertices x ~10 triangles (faerie.md2,
                                  10 levels: 1.3-1.7 s instead of 0.05 s for max and avg; the frame
                                  scheme measures its frame only) */
    uint64_t hold_seams;   /* non-zero (with welded seams): a welded vertex whose copies carry
                                  different attributes lies on a seam and never merges into a
                                  vertex off it (the pair keeps the seam vertex where it is), so
                                  no triangle comes to span a seam: what texture mapping needs
                                  (lk_scene_simplify sets it). 0 (default): seams are not
                                  constrained, as in the paper's comparisons */
    uint64_t reserved[7];  /* zero: room for fields of later versions (ABI rule, top of file) */
} lk_anim_simplify_options;

/* The default lost_surface weight: the lost surface counts 300 times a
 * quadric error of the same size, so it decides wherever it is not ~0 and the
 * quadrics order the rest. Chosen by measurement on faerie.md2 and
 * sydney.md2 (bench_anim, README "Animated models"): at 300 the max scheme
 * has the lowest worst frame of the three schemes at 9 of faerie's 9 levels
 * and 8 of sydney's, the only weight of 0, 100, 300, 1000 where it beats the
 * single-frame scheme at 50, 20 and 10% on both; on RiggedFigure (open
 * pieces) it hurts at 50-90%. */
#define LK_ANIM_LOST_SURFACE_DEFAULT 300.0

/* Defaults of lk_simplify_options_default (no target: set one), scheme max,
 * frame 0, max_bytes 0, lost_surface LK_ANIM_LOST_SURFACE_DEFAULT. */
LK_API void lk_anim_simplify_options_default(lk_anim_simplify_options *options);

typedef struct lk_anim_simplify_result {
    lk_animation animation;      /* the simplified animation: one connectivity, every input
                                  frame (mesh.positions = frame 0), fps and names kept */
    uint32_t *vertex_map;        /* input vertex -> output vertex, UINT32_MAX if gone */
    double error;                /* largest combined collapse error, model units (as
                                  lk_simplify_result.error, combined over frames by the scheme) */
    double diagonal;             /* bounding-box diagonal of all input frames together */
    int target_reached;          /* as in lk_simplify_result */
    size_t working_bytes;        /* memory of the per-frame quadrics and positions */
    size_t folds_from_triangles; /* allow_folds: the triangle count where the check went
                                  to the reference frame only (0: never) */
    double seconds;              /* wall time from the start of the call to this result */
} lk_anim_simplify_result;

/* Frees the animation and the vertex map of a result and zeroes it. Accepts
 * NULL. */
LK_API void lk_anim_simplify_result_free(lk_anim_simplify_result *result);

/* Simplifies an animation (not modified; degenerate and duplicate triangles
 * are ignored). options must set a target (LK_ERR_INVALID otherwise).
 * Cost: O(F (V + T log T)) time, 124 F V bytes of per-frame data; the
 * lost-surface term (on by default) adds 32 F V bytes and, per pair
 * evaluation, F x (input vertices merged into the pair) x ~10 point-triangle
 * distances: 10-30x the time (faerie.md2, 198 frames: 1.5 s instead of 0.05;
 * bunny.obj twisted over 10 frames, to 5%: 16 s instead of 1.5). */
LK_API lk_status lk_animation_simplify(const lk_animation *animation, const lk_anim_simplify_options *options,
                                       lk_anim_simplify_result *result, lk_progress_fn progress, void *progress_user,
                                       lk_error *error);
/* A LOD set in one run: results[k] keeps floor(ratios[k] * T) triangles
 * (ratios in (0, 1], any order). The collapse order does not depend on the
 * target, so each result equals a separate lk_animation_simplify call with
 * that ratio, for the cost of one call. The targets in options->simplify
 * are ignored (max_error still applies). */
LK_API lk_status lk_animation_simplify_levels(const lk_animation *animation, const lk_anim_simplify_options *options,
                                              const double *ratios, size_t level_count,
                                              lk_anim_simplify_result *results, lk_progress_fn progress,
                                              void *progress_user, lk_error *error);

/* Paper's Fig. 8 measure: out[k] = lk_metro(frame frames[k] of `simplified`,
 * frame frames[k] of `original`) (frames == NULL: frames 0 .. frame_count-1
 * of both, which must then have the same frame count). options may be NULL
 * (lk_metro defaults). Cost: frame_count Metro runs. */
LK_API lk_status lk_animation_metro(const lk_animation *simplified, const lk_animation *original, const size_t *frames,
                                    size_t frame_count, const lk_metro_options *options, lk_metro_result *out,
                                    lk_progress_fn progress, void *progress_user, lk_error *error);

/* The paper's Fig. 8 as a picture: a heat map of values[l * frame_count + f]
 * (level l from the bottom, frame f left to right; NaN draws grey) on a
 * logarithmic colour scale [scale_min, scale_max] (either <= 0: the range of
 * the positive values, at most three decades) with a colour legend, axis labels (level_ratios as
 * percentages, or level numbers when NULL; frame_numbers, or 0.. when NULL),
 * a title and a legend caption (both may be NULL), in lodkit's own 5x7
 * font. *rgba (width * height * 4 bytes; release with lk_free) suits
 * lk_image_write_png. */
LK_API lk_status lk_anim_error_map(const double *values, size_t level_count, size_t frame_count,
                                   const double *level_ratios, const size_t *frame_numbers, double scale_min,
                                   double scale_max, const char *title, const char *value_label, unsigned char **rgba,
                                   unsigned *width, unsigned *height, lk_error *error);

/* ------------------------------------------------------------------------ */
/* Subdivision                                                              */
/* ------------------------------------------------------------------------ */

typedef enum lk_subdivide_scheme {
    LK_SUBDIVIDE_LOOP = 0, /* Loop's smooth scheme (boundary rules included) */
    LK_SUBDIVIDE_MIDPOINT  /* split every triangle into four at edge midpoints */
} lk_subdivide_scheme;

/* Subdivides `iterations` times into `out` (overwritten; untouched on
 * failure): each iteration multiplies the triangle count by 4; the new
 * vertex of edge e is vertex_count + e (edge ids of lk_edge_adjacency_build).
 * Loop uses Loop's original weight beta(n); border vertices follow the
 * 1/8-3/4-1/8 border rule, and corners (border turns sharper than 130
 * degrees) and vertices on non-manifold edges keep their position; new
 * vertices on border and non-manifold edges are midpoints. Attributes are
 * interpolated linearly (normals renormalised). Degenerate triangles are
 * refused (LK_ERR_INVALID); sizes beyond LK_MAX_ELEMENTS give LK_ERR_LIMIT
 * before anything is allocated. Cost: O(T) per iteration. */
LK_API lk_status lk_subdivide(const lk_mesh *mesh, lk_subdivide_scheme scheme, unsigned iterations, lk_mesh *out,
                              lk_error *error);

/* ------------------------------------------------------------------------ */
/* Progressive meshes (src/pm.c)                                            */
/* ------------------------------------------------------------------------ */

/* One vertex split, the inverse of one QEM edge collapse (Hoppe's d =
 * (position of q, p, q, r, s)). Split k creates vertex q = base_vertex_count
 * + k next to the existing vertex p = `kept`, moves p back to
 * `kept_position`, and brings back the triangles
 * [first_triangle, first_triangle + triangle_count) of
 * lk_progressive_mesh.indices (two inside a closed manifold: (p,q,r) and
 * (p,s,q); one on a border). Vertices p, r, s are read from those
 * triangles. */
typedef struct lk_vertex_split {
    uint32_t kept;           /* p, a vertex that exists before the split (PM order) */
    uint32_t first_triangle; /* PM triangle id of the first restored triangle */
    uint32_t triangle_count; /* triangles restored by this split */
    float position[3];       /* position of the new vertex q */
    float kept_position[3];  /* position of p after the split */
    float error;             /* QEM error of the collapse this split undoes (model units) */
} lk_vertex_split;

/* A progressive mesh: a base mesh plus vertex splits back to the full mesh.
 * Vertices and triangles are numbered in the order they appear, so the mesh
 * at level k (k splits applied) uses vertices [0, base_vertex_count + k)
 * and triangles [0, lk_progressive_mesh_level_triangles(pm, k)); a corner
 * of `indices` (full-level numbering) that names a vertex v not yet present
 * stands for its nearest present ancestor: v -> splits[v - base_vertex_count].kept,
 * repeated (the kept vertex always has a smaller index). */
typedef struct lk_progressive_mesh {
    size_t vertex_count;   /* full level */
    size_t triangle_count; /* full level */
    size_t base_vertex_count;
    size_t base_triangle_count;
    size_t split_count;       /* vertex_count - base_vertex_count */
    float *base_positions;    /* 3 * base_vertex_count: positions at the base level */
    uint32_t *indices;        /* 3 * triangle_count: full-level corners, PM order */
    lk_vertex_split *splits;  /* split_count, in refinement order */
    uint32_t *vertex_order;   /* PM vertex -> vertex of the input mesh (the recorded permutation) */
    uint32_t *triangle_order; /* PM triangle -> triangle of the input mesh */
    double diagonal;          /* bounding-box diagonal of the input */
} lk_progressive_mesh;

typedef struct lk_progressive_options {
    double base_ratio;     /* base mesh triangles / input triangles (default 0.05, as in
                                  the progressive-strips paper) */
    size_t base_triangles; /* overrides base_ratio when non-zero */
    /* QEM settings (feature_angle, feature_weight, flags such as
     * LK_SIMPLIFY_ENDPOINTS or LK_SIMPLIFY_LOCK_BORDER); targets are ignored,
     * LK_SIMPLIFY_RECORD is implied, pair_distance must be 0 */
    lk_simplify_options simplify;
    uint64_t reserved[8]; /* zero: room for fields of later versions (ABI rule, top of file) */
} lk_progressive_options;

/* Fills options with the defaults given in the fields' comments. */
LK_API void lk_progressive_options_default(lk_progressive_options *options);

/* Builds a progressive mesh by QEM edge collapses down to the base mesh.
 * Degenerate and duplicate triangles and unused vertices of the input are
 * dropped first (vertex_order/triangle_order refer to the input as given).
 * Splitting all the way back gives the input's triangles exactly, in PM
 * numbering. Cost: that of lk_simplify plus O(V + T). */
LK_API lk_status lk_progressive_mesh_build(const lk_mesh *mesh, const lk_progressive_options *options,
                                           lk_progressive_mesh *out, lk_progress_fn progress, void *progress_user,
                                           lk_error *error);
/* Triangles present at level `level` (clamped to split_count). O(1). */
LK_API size_t lk_progressive_mesh_level_triangles(const lk_progressive_mesh *pm, size_t level);
/* The mesh at level `level` (clamped): vertices [0, base + level) with their
 * positions at that level, triangles in PM order with ancestors resolved.
 * `out` is overwritten. Cost: O(V + T). */
LK_API lk_status lk_progressive_mesh_level(const lk_progressive_mesh *pm, size_t level, lk_mesh *out, lk_error *error);
LK_API void lk_progressive_mesh_free(lk_progressive_mesh *pm);

/* ------------------------------------------------------------------------ */
/* Triangle strips and progressive strips (src/strips.c)                    */
/* ------------------------------------------------------------------------ */
/* A strip s of length n draws triangle j (0 <= j < n-2) as
 * (s[j], s[j+1], s[j+2]) for even j and (s[j+1], s[j], s[j+2]) for odd j
 * (GL_TRIANGLE_STRIP winding); triangles with a repeated vertex are
 * degenerate and draw nothing. lodkit strips are single sequences joined with
 * degenerate triangles, since OpenGL ES 2.0 has no primitive restart. */

typedef enum lk_stripifier {
    LK_STRIPIFY_BEST = 0, /* run both, keep the shorter strip */
    LK_STRIPIFY_LODKIT,   /* lodkit's own greedy stripifier */
    LK_STRIPIFY_MESHOPT   /* meshoptimizer's (Debian libmeshoptimizer), after its
                              strip-friendly vertex cache ordering */
} lk_stripifier;

/* Turns triangles into one strip whose non-degenerate triangles are exactly
 * the input triangles (each once, same orientation). Degenerate input
 * triangles are dropped. *strip: release with lk_free. `used`, when not
 * NULL, receives the stripifier kept (for BEST). Cost: O(T). */
LK_API lk_status lk_stripify(const uint32_t *indices, size_t triangle_count, size_t vertex_count, lk_stripifier method,
                             uint32_t **strip, size_t *strip_length, lk_stripifier *used, lk_error *error);
/* Largest output of lk_strip_filter for an input of strip_length indices. */
LK_API size_t lk_strip_filter_bound(size_t strip_length);
/* DTFS filter (degenerate-triangle-free scanning, section 4 of the paper):
 * keeps the non-degenerate triangles of `strip` in order and rebuilds
 * strips from consecutive ones: the normal case {a,b,c,f}, the swap case
 * {a,b,c,b,f}, else a new strip joined by degenerate triangles. The result
 * draws the same non-degenerate triangles with the same orientation.
 * Returns the output length (<= lk_strip_filter_bound). O(n). */
LK_API size_t lk_strip_filter(const uint32_t *strip, size_t strip_length, uint32_t *destination);
/* Writes the non-degenerate triangles of a strip (3 indices each, strip
 * winding resolved) and returns their count; destination holds
 * 3 * (strip_length - 2) indices at most. */
LK_API size_t lk_strip_triangles(const uint32_t *strip, size_t strip_length, uint32_t *destination);

/* Progressive strips (the paper's PS): the full-level strip of a
 * progressive mesh; the strip at level k replaces every vertex not yet
 * present by its ancestor (strip edge collapse by vertex repetition), so its
 * non-degenerate triangles are exactly those of the PM at level k. */
typedef struct lk_progressive_strips {
    uint32_t *strip; /* full-level strip, PM vertex ids */
    size_t strip_length;
    lk_stripifier stripifier;           /* the stripifier whose strip was kept */
    double lodkit_indices_per_triangle; /* both stripifiers, measured on the full mesh */
    double meshopt_indices_per_triangle;
    /* Strip positions rewritten by each vertex split (section 3):
     * naive PS (every copy of p that stands for q) and E-PS (collapses
     * encoded as R+2/R+1/R-1/R-2 references to a neighbouring p, so copies
     * of p do not accumulate). split_count entries each. */
    uint32_t *naive_updates;
    uint32_t *encoded_updates;
    double mean_naive_updates;
    double mean_encoded_updates;
    /* Mean bytes of one strip vertex split d = (v_q, q, o_1..o_r) with
     * 24-byte positions and 2-byte indices and offsets (section 5.2). */
    double naive_detail_bytes;
    double encoded_detail_bytes;
} lk_progressive_strips;

/* Stripifies pm's full level and measures the naive and E-PS split sizes.
 * Cost: O(L + V) after stripification (L = strip length). */
LK_API lk_status lk_progressive_strips_build(const lk_progressive_mesh *pm, lk_stripifier method,
                                             lk_progressive_strips *out, lk_error *error);
/* lk_progressive_strips_build with a progress callback (0.0 first, 1.0 when
 * done; non-zero cancels: LK_ERR_INVALID "cancelled"). */
LK_API lk_status lk_progressive_strips_build_ex(const lk_progressive_mesh *pm, lk_stripifier method,
                                                lk_progressive_strips *out, lk_progress_fn progress,
                                                void *progress_user, lk_error *error);
/* The unfiltered strip at level `level` (clamped) into destination
 * (strip_length entries). O(L + V). */
LK_API lk_status lk_progressive_strips_level(const lk_progressive_strips *ps, const lk_progressive_mesh *pm,
                                             size_t level, uint32_t *destination, lk_error *error);
LK_API void lk_progressive_strips_free(lk_progressive_strips *ps);

/* Indices sent to the GPU at one level (Fig. 4 of the paper). */
typedef struct lk_strip_bandwidth {
    size_t level;
    size_t triangles;        /* non-degenerate triangles at that level */
    size_t pm_indices;       /* independent triangles: 3 per triangle */
    size_t strip_indices;    /* unfiltered progressive strip (PS^nf): the full length */
    size_t filtered_indices; /* DTFS-filtered strip */
} lk_strip_bandwidth;

/* Measures the levels listed in `levels` (ascending) by applying splits
 * incrementally; out has level_count entries. Cost: O(L) per level. */
LK_API lk_status lk_progressive_strips_bandwidth(const lk_progressive_strips *ps, const lk_progressive_mesh *pm,
                                                 const size_t *levels, size_t level_count, lk_strip_bandwidth *out,
                                                 lk_progress_fn progress, void *progress_user, lk_error *error);

/* ------------------------------------------------------------------------ */
/* Progressive stream format (.lks, src/stream_*.c, docs/stream-format.md)  */
/* ------------------------------------------------------------------------ */

typedef struct lk_stream_options {
    unsigned position_bits;  /* quantisation bits per coordinate, 4..24; 0 (default) = the
                                 fewest that keep every position within 0.01% of the
                                 diagonal */
    size_t splits_per_chunk; /* vertex splits per chunk (default 1024) */
    int compress;            /* deflate chunk payloads when that makes them smaller (default 1) */
    uint64_t version;        /* format version: 0 or 1 (default) = version 1 (strips, deflate);
                                 2 = version 2 (vertex splits in batches, range-coded: several
                                 times smaller; splits_per_chunk and compress do not apply, the
                                 strips may be NULL; build the progressive mesh with
                                 LK_SIMPLIFY_ENDPOINTS so each split carries one position) */
    uint64_t normal_bits;    /* version 2 with attributes: octahedral bits per component, 4..16
                                 (0 = 10) */
    uint64_t texcoord_bits;  /* version 2 with attributes: bits per texture coordinate, 4..24
                                 (0 = 12); colours always take 8 bits per channel */
    uint64_t reserved[5];    /* zero: room for fields of later versions (ABI rule, top of file) */
} lk_stream_options;

/* Fills options with the defaults given in the fields' comments. */
LK_API void lk_stream_options_default(lk_stream_options *options);

/* The base mesh, in triangles, that `lodkit progressive` and `lodkit serve`
 * build version-2 streams on unless told otherwise: with 13-bit positions
 * its chunk is about 1.5 KB, so a client draws its first frame after the
 * first kilobytes (1.2% of the bunny's stream). */
#define LK_STREAM_V2_BASE_TRIANGLES 200

/* Encodes a progressive mesh and its progressive strips into a .lks stream
 * (*bytes: release with lk_free). Deterministic. Cost: O(L + V) (version 1),
 * O(V + T) plus the fans of the split vertices (version 2). */
LK_API lk_status lk_stream_encode(const lk_progressive_mesh *pm, const lk_progressive_strips *ps,
                                  const lk_stream_options *options, unsigned char **bytes, size_t *size,
                                  lk_error *error);
/* Version 2 with the vertex attributes of `input`, the mesh the progressive
 * mesh was built from (pm->vertex_order maps its vertices there): normals,
 * texture coordinates and colours, whichever input has, quantised
 * (options->normal_bits, texcoord_bits) and predicted from the ring like
 * positions. Decoders give them back in lk_stream_decoder_mesh. Same
 * cost as lk_stream_encode. */
LK_API lk_status lk_stream_encode_with_attributes(const lk_progressive_mesh *pm, const lk_mesh *input,
                                                  const lk_stream_options *options, unsigned char **bytes, size_t *size,
                                                  lk_error *error);
/* Writes bytes to path through a temporary file and a rename. */
LK_API lk_status lk_stream_write_file(const char *path, const unsigned char *bytes, size_t size, lk_error *error);

typedef struct lk_stream_info {
    unsigned version;
    size_t vertex_count, triangle_count; /* full level */
    size_t base_vertex_count, base_triangle_count;
    size_t split_count;
    size_t strip_length;
    unsigned position_bits;
    float quantisation_min[3]; /* position = min + q * step */
    float quantisation_step[3];
    double quantisation_error; /* largest position error, model units */
    double diagonal;           /* of the input */
    size_t chunk_count;
    size_t header_size; /* bytes before the first chunk */
    size_t total_size;  /* whole stream */
} lk_stream_info;

typedef struct lk_stream_chunk_info {
    uint64_t offset;         /* of the chunk header from the start of the stream */
    uint32_t size;           /* chunk header + payload bytes */
    uint32_t first_split;    /* level before the chunk (0 for the base chunk) */
    uint32_t split_count;    /* splits in the chunk (0 for the base chunk) */
    uint32_t triangle_count; /* triangles at the level reached after this chunk */
    uint32_t raw_size;       /* payload before compression */
    uint32_t crc32;          /* of the stored payload */
    int compressed;
    int is_base;
} lk_stream_chunk_info;

/* Reads the header and chunk table of a stream held in memory and checks
 * every chunk that is present (length, CRC). *chunks: release with lk_free.
 * A stream cut short gives LK_ERR_TRUNCATED with info/chunks still filled. */
LK_API lk_status lk_stream_inspect(const unsigned char *bytes, size_t size, lk_stream_info *info,
                                   lk_stream_chunk_info **chunks, lk_error *error);

/* Where a version-2 stream's bits go, in bits per vertex of the full mesh
 * (info.vertex_count). Measured by decoding it all: each part's symbols
 * cost -log2 of the probability the decoder gave them, so the parts add up
 * to the stream's size. */
typedef struct lk_stream_bits {
    double base;                       /* the base chunk: base positions, attributes, triangles */
    double split_vertices;             /* which vertices split, batch by batch */
    double moves;                      /* which triangles of a split vertex's fan move to the new vertex */
    double restored;                   /* the triangles each split restores, and which vertices get positions */
    double positions;                  /* the positions the splits bring */
    double normals, texcoords, colors; /* the splits' attributes (0 when absent) */
    double framing;                    /* header, chunk table, chunk headers, the coder's last bytes per chunk */
    double total;                      /* all of the above: 8 * total_size / vertex_count */
    uint64_t reserved[8];              /* zero: room for fields of later versions (ABI rule, top of file) */
} lk_stream_bits;

/* Decodes a whole version-2 stream held in memory and fills *bits. A
 * version-1 stream (deflated chunks: no per-symbol cost) gives
 * LK_ERR_INVALID; a damaged stream the decoder's error. Cost: one decode. */
LK_API lk_status lk_stream_bits_by_part(const unsigned char *bytes, size_t size, lk_stream_bits *bits, lk_error *error);

/* Incremental decoder: give it bytes as they arrive; every complete chunk
 * is decoded at once and the current level can be taken after any call. */
typedef struct lk_stream_decoder lk_stream_decoder;

/* max_level: stop after this many splits (SIZE_MAX = all). */
LK_API lk_status lk_stream_decoder_create(size_t max_level, lk_stream_decoder **out, lk_error *error);
/* Memory budget of the decoder (0 = the default, 8 GiB): a header whose
 * counts need more (20 bytes per vertex and 8 per strip entry for the
 * decoding state, 72 per chunk for the table), or a chunk table with a
 * chunk that would not fit next to that state (its stored bytes, its raw
 * bytes when compressed, 16 bytes per split), is refused with LK_ERR_LIMIT
 * ("header at byte N: ..." / "chunk table entry K at byte N: ...") before
 * anything of that size is allocated. Call it before the first feed
 * (LK_ERR_INVALID afterwards). */
LK_API lk_status lk_stream_decoder_set_max_bytes(lk_stream_decoder *decoder, size_t max_bytes, lk_error *error);
/* Consumes size bytes (the next ones of the stream). A malformed header or
 * a corrupt chunk (CRC mismatch, bad payload) fails with LK_ERR_PARSE
 * naming the chunk and its byte offset; the decoder keeps the last good
 * level and refuses further input. */
LK_API lk_status lk_stream_decoder_feed(lk_stream_decoder *decoder, const void *bytes, size_t size, lk_error *error);
/* Call after the last byte: LK_OK when the stream was complete (or
 * max_level was reached), LK_ERR_TRUNCATED with "stopped at byte N in
 * chunk K of M" otherwise (the levels decoded so far stay usable). */
LK_API lk_status lk_stream_decoder_finish(lk_stream_decoder *decoder, lk_error *error);
/* NULL until the header and chunk table have arrived. */
LK_API const lk_stream_info *lk_stream_decoder_info(const lk_stream_decoder *decoder);
LK_API size_t lk_stream_decoder_level(const lk_stream_decoder *decoder);  /* splits applied */
LK_API size_t lk_stream_decoder_chunks(const lk_stream_decoder *decoder); /* chunks decoded, base included */
LK_API size_t
lk_stream_decoder_bytes(const lk_stream_decoder *decoder); /* bytes consumed by decoded chunks and header */
/* The current mesh: vertices [0, base + level) in PM order (dequantised),
 * triangles = the non-degenerate triangles of the current strip (version
 * 2: the decoder's vertices and triangles, with the stream's normals,
 * texture coordinates and colours).
 * LK_ERR_INVALID before the base chunk. O(V + L). */
LK_API lk_status lk_stream_decoder_mesh(const lk_stream_decoder *decoder, lk_mesh *out, lk_error *error);
/* The current strip (*strip: release with lk_free): DTFS-filtered when
 * `filtered`, else the full-length progressive strip. */
LK_API lk_status lk_stream_decoder_strip(const lk_stream_decoder *decoder, int filtered, uint32_t **strip,
                                         size_t *length, lk_error *error);
LK_API void lk_stream_decoder_free(lk_stream_decoder *decoder);

/* ------------------------------------------------------------------------ */
/* Point sets (src/points.c)                                                */
/* ------------------------------------------------------------------------ */
/* A point set is an lk_mesh with triangle_count == 0; splatting needs
 * normals and radii. */

typedef struct lk_sample_options {
    size_t point_count;   /* points to draw on the surface (default 100000) */
    int poisson;          /* 1: Poisson-disk (blue noise) subset of a denser uniform sample;
                                0 (default): uniform, area-proportional */
    uint64_t seed;        /* deterministic for a given seed (default 1) */
    unsigned neighbours;  /* k of the k-nearest-neighbour radius (default 8) */
    double radius_scale;  /* radius = scale * distance to the k-th neighbour, clamped against
                                outliers as lk_points_estimate_radii says (default 1) */
    uint64_t reserved[8]; /* zero: room for fields of later versions (ABI rule, top of file) */
} lk_sample_options;

/* Fills options with the defaults given in the fields' comments. */
LK_API void lk_sample_options_default(lk_sample_options *options);

/* Samples a triangle mesh's surface into an oriented point set with splat
 * radii (`points` is overwritten): positions on the triangles, normals of
 * the triangles (or interpolated vertex normals when the mesh has them),
 * radii from lk_points_estimate_radii. Cost: O(T + N log N). */
LK_API lk_status lk_mesh_sample_points(const lk_mesh *mesh, const lk_sample_options *options, lk_mesh *points,
                                       lk_progress_fn progress, void *progress_user, lk_error *error);
/* Sets (allocating if needed) points->radii to scale * the distance to the
 * k-th nearest other point, so that splats overlap without holes; with
 * normals, to scale * the smaller of that distance and 1.25 times the
 * farthest corner of the point's Voronoi cell among those k points in its
 * tangent plane (discs that cover their cells leave no hole and reach less
 * far past a silhouette: the kitten scan's splat pixels off its surface
 * 6.1% -> 1.8%, fandisk's vertices 4.5% -> 1.5%). Clamped
 * so that stray points do not become large discs: no radius above 4x the
 * 99th percentile of all these radii, and none above 4x the lower median
 * (rank (k - 1) / 2) of the radii of its k nearest other points (applied
 * until no radius changes, so it holds for the radii returned).
 * Deterministic, whatever the thread count. Cost: O(N k log N) with a k-d
 * tree, O(N k) memory. */
LK_API lk_status lk_points_estimate_radii(lk_mesh *points, unsigned neighbours, double scale, lk_error *error);
/* Clip lines that keep splats inside a scan's open borders and gaps: a
 * disc centred on a border point reaches one radius into the empty side
 * (Haystack_Rock: 8.9-11.5% of the splat pixels off its surface, 5.7-8.3%
 * with these cuts; bench_radii).
 * A point is on a border when its k nearest neighbours (k in 1..256),
 * projected into its tangent plane, leave one empty wedge of 150 degrees
 * or more around it (two such wedges: a row of points, a scan line, not a
 * border); clips[4 i .. 4 i + 3] = (d, c) then says "draw only the part of
 * point i's disc where dot(offset from the point, d) <= c": d the unit
 * direction across the middle of the widest empty wedge, in the tangent
 * plane, c >= 0 the farthest any neighbour lies along d (0 when all lie
 * behind the point: the line through it, where a triangulation of the
 * points ends). Other points get (0, 0, 0, 0): nothing cut. The renderer
 * asks 16 neighbours (lk_render_options.clip_borders).
 * Needs normals. clips: 4 * vertex_count floats, caller-owned.
 * Deterministic, whatever the thread count. Cost: O(N k log N). */
LK_API lk_status lk_points_estimate_clips(const lk_mesh *points, unsigned neighbours, float *clips, lk_error *error);
/* Sets points->normals by PCA over the k nearest neighbours (k in 1..256),
 * oriented consistently by propagation over a minimum spanning tree of the
 * neighbour graph (Hoppe et al. 1992) whose edge cost 1 - |n_i.n_j| also
 * grows with how much the edge runs along the normals (so the two sides of
 * a thin sheet stay apart), seeded at each connected part's highest point
 * with its normal turned to +z. Existing normals are replaced; untouched on
 * failure. Cost: O(N k log N). */
LK_API lk_status lk_points_estimate_normals(lk_mesh *points, unsigned neighbours, lk_error *error);

/* ------------------------------------------------------------------------ */
/* Point octrees: out-of-core level of detail for large clouds (src/octree.c) */
/* ------------------------------------------------------------------------ */
/* A Potree-like octree: every node holds a subsample of the points in its
 * cube, each point in exactly one node. A node at level l (the root is
 * level 0) keeps the points that are at least spacing / 2^l from each
 * other (Poisson-disk in input order) and hands the rest to its eight
 * children; a node with at most max_node_points candidates keeps them all
 * (a leaf). Written as OUTDIR/octree.bin (the nodes' points, one after the
 * other) and OUTDIR/octree.json (the index: per node its name, level, point
 * count, byte offset, length and CRC-32), so that a static HTTP server can
 * serve each node by a Range request. docs/formats.md, "Point octree". */

/* What lk_octree_build does with normals. */
typedef enum lk_octree_normals {
    LK_OCTREE_NORMALS_AUTO = 0, /* keep the inputs' normals when every input has them, else none */
    LK_OCTREE_NORMALS_NONE,     /* write none */
    LK_OCTREE_NORMALS_ESTIMATE  /* estimate them (lk_points_estimate_normals per chunk; ~4 us a point) */
} lk_octree_normals;

typedef struct lk_octree_options {
    double spacing;         /* root spacing in model units (0, default: from the cloud, the root
                                cube's side / 2^L for the largest L <= 7 whose grid has at most an
                                eighth of the point count of occupied cells: side / 128, Potree's,
                                for large clouds; coarser for small clouds, whose root would
                                otherwise keep every point; docs/formats.md, "Point octree") */
    size_t max_node_points; /* a node with at most this many candidates is a leaf (0, default:
                                20000, or an eighth of the point count when that is fewer, so
                                that a small cloud still gets levels) */
    size_t chunk_points;    /* points one chunk may hold in memory (default 2,000,000; >= max_node_points
                                in practice): peak memory is about threads * chunk_points * 120 bytes */
    unsigned threads;       /* chunks built at once (0, default: the cores online) */
    const char *temp_dir;   /* folder for the spill files (NULL, default: OUTDIR) */
    lk_octree_normals normals;
    unsigned neighbours;     /* k of the splat radii and normals (default 8) */
    double scale;            /* quantisation step of the positions (0, default: a power of ten
                                near the cube's side / 2^30) */
    int no_radii;            /* 1: splat radius = the node's spacing (skips the k-nearest-neighbour
                                density estimate, the costliest step after the spill) */
    uint64_t max_read_bytes; /* inputs read whole (binary_compressed PCD and formats other than LAS,
                                PLY with a first element "vertex" of scalars, XYZ and PCD, which
                                stream in bounded memory): lk_read_options.max_bytes of their read
                                (0 = 8 GiB) */
    int no_clips;            /* 1: store no clip lines. By default an octree with normals stores,
                                per point, the clip line that cuts a border point's splat at the
                                border of the points drawn with it (its node's level and the levels
                                above: lk_points_estimate_clips' rule, 16 neighbours; about 1.5x
                                the radii's nearest-neighbour time) */
    uint64_t reserved[6];    /* zero: room for fields of later versions (ABI rule, top of file) */
} lk_octree_options;

/* Fills options with the defaults given in the fields' comments. */
LK_API void lk_octree_options_default(lk_octree_options *options);

typedef struct lk_octree_stats {
    uint64_t points;     /* points read (and written) */
    size_t nodes;        /* nodes in the index (some upper nodes may hold 0 points) */
    unsigned levels;     /* deepest level + 1 */
    size_t chunks;       /* chunks built in memory one by one */
    uint64_t temp_bytes; /* bytes spilled to the temporary files */
    double seconds;      /* wall-clock time of the build */
} lk_octree_stats;

/* Builds the octree of the point clouds in paths[0 .. path_count) (LAS,
 * PLY, XYZ, PCD; positions, RGB colours and normals kept) into the folder
 * out_dir (created if missing; octree.bin and octree.json are written
 * through temporary files and renamed into place, the data file first).
 * LAS, PLY (binary or ASCII, a first element "vertex" of scalar
 * properties), PCD (binary or ascii) and XYZ (line by line, in double) are
 * streamed in batches of 65,536 points: memory stays bounded by
 * chunk_points whatever their size (plus 24 MiB of counting grid, at most
 * 64 MiB of spill buffers and a 2 MiB line buffer). Other inputs
 * (binary_compressed PCD, OBJ, ...) are read whole, one file at a time,
 * within options->max_read_bytes.
 * Three passes over the input (bounds, counts per cell of a 128^3 grid,
 * spill of each point to its chunk's temporary file: cells are merged into
 * chunks of at most chunk_points), then the chunks are built on `threads`
 * threads and the levels above them from the chunks' roots. The output is
 * byte-identical for any thread count. Cost: O(N log N) time, N * 24 bytes
 * of temporary disk. stats may be NULL. Errors name the file (and byte). */
LK_API lk_status lk_octree_build(const char *const *paths, size_t path_count, const char *out_dir,
                                 const lk_octree_options *options, lk_octree_stats *stats, lk_progress_fn progress,
                                 void *progress_user, lk_error *error);

/* An octree opened for reading (lk_octree_open). */
typedef struct lk_octree lk_octree;

/* The index's description of the cloud. Positions are stored as int32
 * steps of `scale` from `offset` (the cloud's quantisation, not the
 * node's); the root cube is [offset, offset + cube_size) on each axis. */
typedef struct lk_octree_info {
    uint64_t points;
    size_t node_count;
    double spacing;        /* root spacing (model units) */
    double scale[3];       /* quantisation step per axis */
    double offset[3];      /* the root cube's minimum corner */
    double cube_size;      /* the root cube's side */
    double min[3], max[3]; /* tight bounds of the points */
    int has_colors, has_normals;
    size_t stride; /* bytes per point in the data file */
    int has_clips; /* the points carry clip lines (lk_octree_load_node_clips) */
} lk_octree_info;

typedef struct lk_octree_node {
    const char *name;      /* "r", then one digit 0..7 per level: child index x*4 + y*2 + z */
    unsigned level;        /* strlen(name) - 1 */
    uint64_t points;       /* point count */
    uint64_t offset;       /* first byte in octree.bin */
    uint64_t length;       /* bytes: points * stride */
    uint32_t crc32;        /* of those bytes (zlib's CRC-32) */
    double min[3], max[3]; /* the node's cube */
    unsigned children;     /* bit d set: child d (name + digit d) is in the index */
} lk_octree_node;

/* Opens an octree: `path` is its folder or its octree.json. The index is
 * parsed and checked (errors say octree.json:LINE); nodes past the data
 * file's end are refused. */
LK_API lk_status lk_octree_open(const char *path, lk_octree **octree, lk_error *error);
/* Parses an index from memory (`name` in messages); the data file is not
 * opened, so lk_octree_load_node fails on such an octree. For fuzzing and
 * tools that fetch the data elsewhere. */
LK_API lk_status lk_octree_open_memory(const char *json, size_t size, const char *name, lk_octree **octree,
                                       lk_error *error);
LK_API void lk_octree_close(lk_octree *octree);
LK_API const lk_octree_info *lk_octree_get_info(const lk_octree *octree);
/* Node `index` (0 .. node_count - 1), in the index's order (by level, then
 * name: a parent comes before its children), or NULL past the end. */
LK_API const lk_octree_node *lk_octree_node_at(const lk_octree *octree, size_t index);
/* Reads node `index` into `points` (overwritten): positions relative to
 * info.offset (model units, as floats: add offset for absolute ones),
 * colours, normals and radii when the octree has them. Checks the length
 * and the CRC-32. The radii are those for drawing the node without its
 * children: an inner node's at least its spacing, so that it leaves no
 * holes where its children's points are missing (lk_octree_load_selection
 * gives smaller ones where the children are drawn too). Cost: one read of
 * the node's bytes. */
LK_API lk_status lk_octree_load_node(const lk_octree *octree, size_t index, lk_mesh *points, lk_error *error);
/* Same as lk_octree_load_node, and the node's clip lines into *clips (4
 * floats a point, malloc'ed, free it with lk_free; NULL when the octree has
 * none, info.has_clips 0): point i's splat shows only the part of its disc
 * where dot(offset from the point, (clips[4 i], clips[4 i + 1], clips[4 i +
 * 2])) <= clips[4 i + 3] * its radius; (0, 0, 0, 0) cuts nothing. The
 * direction lies in the point's tangent plane. As lk_render_points'
 * clip_borders, found among the points drawn with it (docs/formats.md). */
LK_API lk_status lk_octree_load_node_clips(const lk_octree *octree, size_t index, lk_mesh *points, float **clips,
                                           lk_error *error);
/* Same as lk_octree_load_node, giving the quantised positions instead (3
 * per point, steps of info.scale from info.offset; *positions is
 * malloc'ed, free it with lk_free): exact, for tools and tests. */
LK_API lk_status lk_octree_load_node_quantized(const lk_octree *octree, size_t index, int32_t **positions,
                                               size_t *count, lk_error *error);
/* Loads the nodes a view draws together (`nodes`, node_count indices, e.g.
 * lk_octree_select's) into one point set, node after node in that order,
 * and their clip lines into *clips when clips is not NULL and the octree
 * has them (as lk_octree_load_node_clips). Radii as Potree's adaptive point
 * size: from a point's node, down the nodes among `nodes` whose cube holds
 * the point, the first one with a child there that exists but is not among
 * `nodes` sets the point's radius to at least its spacing (its sample and
 * its ancestors' are all that is drawn there), 1.5 times its spacing when
 * it lies below the point's node (the ancestors' sparser points overlap
 * less); where the path ends in a cube with no child, every point around
 * is drawn and the point keeps its own radius. So a node drawn without
 * its children gets lk_octree_load_node's radii, and at full resolution
 * each point is drawn at its own radius, never above. Clip lines keep their
 * place (offsets rescaled to the radii). Octrees of version 1 store radii
 * already floored at their node's spacing: no smaller ones there. Cost: the
 * nodes' reads plus, per point, a walk down the drawn nodes. */
LK_API lk_status lk_octree_load_selection(const lk_octree *octree, const size_t *nodes, size_t node_count,
                                          lk_mesh *points, float **clips, lk_error *error);

/* Choosing the nodes to draw for one view under a point budget
 * (src/octree_select.c), as Potree does: from the root, the node of largest
 * projected size is taken next, and its children (those in the view) become
 * candidates, until the next node would take the selection over the budget
 * or no candidate is left. A node's projected size is its spacing
 * (info.spacing / 2^level) in pixels at the distance from the eye to its
 * cube's centre: spacing / distance * (viewport_height / 2) / tan(fov_y / 2)
 * (infinite with the eye inside the cube's bounding sphere). A node whose
 * spacing projects below min_spacing_pixels is not taken (nor its subtree):
 * its points would land within a pixel of its ancestors'. The web viewer
 * (web/octree_view.js) chooses with the same rule. */
typedef struct lk_octree_select_options {
    uint64_t point_budget;     /* most points selected (default 1,000,000) */
    double min_spacing_pixels; /* stop refining below this projected spacing (default 1) */
    uint64_t reserved[8];      /* zero: room for fields of later versions (ABI rule, top of file) */
} lk_octree_select_options;

/* Fills options with the defaults given in the fields' comments. */
LK_API void lk_octree_select_options_default(lk_octree_select_options *options);

/* The view a selection is made for. Coordinates are relative to
 * info.offset, like lk_octree_load_node's positions. */
typedef struct lk_octree_view {
    double eye[3];            /* the camera's position */
    double fov_y;             /* vertical field of view, degrees (0 < fov_y < 180) */
    unsigned viewport_height; /* pixels */
    int has_clip;             /* 1: cull nodes outside the frustum of `clip` */
    double clip[16];          /* projection * view, column-major (OpenGL clip coordinates) */
} lk_octree_view;

/* Selects nodes for `view`: *nodes (malloc'ed, free with lk_free; NULL when
 * none) gets their indices in the order taken (largest projected size
 * first, so a parent before its children), *node_count their number and
 * *points (may be NULL) their point count, never above the budget (the
 * selection is empty when even the root exceeds it). Reads only the index.
 * Cost: O(V log V) for V nodes visited (taken plus candidates). */
LK_API lk_status lk_octree_select(const lk_octree *octree, const lk_octree_view *view,
                                  const lk_octree_select_options *options, size_t **nodes, size_t *node_count,
                                  uint64_t *points, lk_error *error);

/* ------------------------------------------------------------------------ */
/* Offscreen rendering: OpenGL ES 2.0 through EGL (src/gl/)                 */
/* ------------------------------------------------------------------------ */
/* Library: lodkit-gl (pkg-config lodkit-gl, CMake lodkit::gl; EGL, GLESv2,
 * libpng). */
/* Headless, on Mesa's surfaceless platform (llvmpipe without a GPU). The
 * GLSL ES 1.00 shaders are the .glsl files of src/shaders, compiled into the library;
 * the WebGL viewer loads the same files. */

typedef struct lk_renderer lk_renderer;

/* Creates an offscreen context and a width x height RGBA8 + depth
 * framebuffer. Fails with LK_ERR_UNSUPPORTED and a message naming the
 * missing driver packages when no EGL/GLES2 context can be made. */
LK_API lk_status lk_renderer_create(unsigned width, unsigned height, lk_renderer **out, lk_error *error);
LK_API void lk_renderer_free(lk_renderer *renderer);
/* "GL_RENDERER, GL_VERSION" of the context, for reports. */
LK_API const char *lk_renderer_description(const lk_renderer *renderer);

typedef struct lk_render_options {
    /* Camera: orbit around the centre of `bounds` (the drawn model's
     * bounding box unless use_bounds is set, so that two renders can share
     * one view). */
    double azimuth;   /* degrees around +y, 0 looks down -z (default 30) */
    double elevation; /* degrees above the horizon (default 20) */
    double distance;  /* in bounding-sphere radii from the centre; 0 (default) frames
                                the sphere in the field of view */
    double fov_y;     /* vertical field of view, degrees (default 35) */
    int use_bounds;
    float bounds_min[3], bounds_max[3];
    float background[3]; /* default white */
    float color[3];      /* surface colour when the model has none (default light grey-blue) */
    /* meshes */
    int wireframe; /* overlay the edges */
    int strips;    /* draw as one triangle strip (lk_stripify) instead of indexed triangles */
    /* point sets */
    unsigned passes;       /* 1: Phong splats with Gaussian alpha blending (the paper);
                                2: visibility pass + accumulation + normalisation (default 1) */
    int backface_culling;  /* drop back-facing splats in the vertex shader (default 1) */
    double radius_scale;   /* multiply every splat radius (default 1) */
    int flat_points;       /* plain square points of the projected size, no lighting, no
                                blending: the baseline Phong splats are compared with */
    double depth_epsilon;  /* 2-pass: visibility offset in radii along the view (default 1) */
    int up_axis;           /* the model's up axis, an lk_axis: the camera orbits around it
                                (azimuth) and `elevation` is measured from the plane across
                                it. LK_AXIS_Y and LK_AXIS_AUTO (0, the default) are y up,
                                looking down -z at azimuth 0; LK_AXIS_Z: z up, looking
                                down +y; LK_AXIS_X: x up, looking down -z */
    uint64_t clip_borders; /* point sets: cut the splats of border points at the border
                                (lk_points_estimate_clips, 16 neighbours, O(N log N) per
                                draw; lk_render_octree uses the clip lines the octree
                                stores, if any), so that a scan's outline and gaps stay
                                sharp (default 1; 0 in a zeroed struct: whole discs) */
    uint64_t reserved[7];  /* zero: room for fields of later versions (ABI rule, top of file) */
} lk_render_options;

/* Fills options with the defaults given in the fields' comments. */
LK_API void lk_render_options_default(lk_render_options *options);

typedef struct lk_render_stats {
    double milliseconds; /* GPU time of the draw (glFinish included), setup excluded */
    size_t primitives;   /* triangles or points submitted */
    size_t indices;      /* indices submitted (strips: strip length) */
} lk_render_stats;

/* Clears and draws a triangle mesh, lit (headlight + key light, Phong),
 * with vertex normals when present, else normals averaged from the faces.
 * stats may be NULL. */
LK_API lk_status lk_render_mesh(lk_renderer *renderer, const lk_mesh *mesh, const lk_render_options *options,
                                lk_render_stats *stats, lk_error *error);
/* Clears and draws a point set as Phong splats (point sprites whose size is
 * 2r n / z_eye * h_vp / (t - b), clamped to the supported range). Needs
 * normals; without radii a radius is estimated (lk_points_estimate_radii).
 * Zero, negative or non-finite radii are refused. */
LK_API lk_status lk_render_points(lk_renderer *renderer, const lk_mesh *points, const lk_render_options *options,
                                  lk_render_stats *stats, lk_error *error);
/* What lk_render_octree selected, loaded and drew. */
typedef struct lk_render_octree_stats {
    size_t nodes;    /* nodes selected and loaded */
    uint64_t points; /* points drawn (<= the budget) */
    uint64_t bytes;  /* bytes read from octree.bin */
    double select_milliseconds;
    double load_milliseconds; /* reading, CRC checks and decoding */
    double draw_milliseconds; /* as lk_render_stats.milliseconds */
} lk_render_octree_stats;

/* Clears and draws an octree (lk_octree_open) as lk_render_points draws a
 * point set, with only the nodes lk_octree_select picks for this camera
 * under `select` (NULL: the defaults, a budget of 1M points) loaded, with
 * radii as lk_octree_load_selection gives them (adaptive: at full
 * resolution each point at its own, as the whole cloud would be). The
 * camera frames the octree's tight bounds (info.min, info.max; or
 * options->bounds_min/max when use_bounds is set, relative to info.offset),
 * so the whole cloud drawn with lk_render_points from the same bounds gives
 * the same view. Needs normals in the octree. With options->clip_borders,
 * border splats are cut by the clip lines the octree stores (none stored:
 * whole discs). Fails with LK_ERR_LIMIT when the budget is below the root
 * node's point count. stats may be NULL. */
LK_API lk_status lk_render_octree(lk_renderer *renderer, const lk_octree *octree, const lk_render_options *options,
                                  const lk_octree_select_options *select, lk_render_octree_stats *stats,
                                  lk_error *error);
/* What lk_render_scene drew of the scene's materials. */
typedef struct lk_render_scene_info {
    size_t materials;        /* materials used by the drawn triangles */
    size_t textures_drawn;   /* base colour textures decoded and drawn */
    size_t textures_failed;  /* base colour textures that could not be decoded (drawn untextured) */
    char first_failure[160]; /* why the first of those failed ("" when none) */
} lk_render_scene_info;

/* Clears and draws a scene (lk_scene) as lk_render_mesh draws a mesh, each
 * triangle in its material's base colour: glTF's baseColorFactor times its
 * baseColorTexture (PNG or JPEG, decoded with libpng / libjpeg, sampled
 * with its TEXCOORD_0, repeated) times the vertex colour; triangles without
 * a material take options->color. The camera frames the scene as drawn
 * (lk_scene_flatten). A texture that cannot be decoded (WebP, KTX2, a
 * broken file) leaves its triangles untextured and is counted in info
 * (may be NULL). Cost: one draw call per material, images decoded once. */
LK_API lk_status lk_render_scene(lk_renderer *renderer, const lk_scene *scene, const lk_render_options *options,
                                 lk_render_stats *stats, lk_render_scene_info *info, lk_error *error);
/* Copies the framebuffer into rgba (width * height * 4 bytes, top row first). */
LK_API lk_status lk_renderer_read_pixels(const lk_renderer *renderer, unsigned char *rgba, lk_error *error);
LK_API void lk_renderer_size(const lk_renderer *renderer, unsigned *width, unsigned *height);

/* Writes an RGBA8 image as PNG (libpng) through a temporary file + rename. */
LK_API lk_status lk_image_write_png(const char *path, const unsigned char *rgba, unsigned width, unsigned height,
                                    lk_error *error);

/* ------------------------------------------------------------------------ */
/* Elevation grids (src/io_dem.c, src/heightfield.c)                        */
/* ------------------------------------------------------------------------ */
/* Library: lodkit-dem (pkg-config lodkit-dem, CMake lodkit::dem; GDAL,
 * libpng) for reading grids; the heightfield functions after lk_dem_read
 * are the core's. */

/* A regular grid of heights in metres. Sample (column i, row j) stands at
 * x = origin_x + i * spacing_x, y = origin_y + j * spacing_y (metres), and y
 * grows northwards: row 0 is the southern edge. North-up GIS rasters and
 * images (whose first stored row is the top, north) are flipped on reading. */
typedef struct lk_heightfield {
    size_t width, height;        /* samples per row, rows */
    float *heights;              /* width * height, row-major, finite (no-data filled) */
    double spacing_x, spacing_y; /* metres between samples (> 0) */
    double origin_x, origin_y;   /* metres */
    size_t nodata_count;         /* samples that were no-data and got filled from the nearest valid
                                  ones (0 after lk_heightfield_resample) */
    double min_height, max_height;
} lk_heightfield;

typedef struct lk_dem_options {
    int band;                  /* raster band, 1-based (default 1) */
    double z_scale;            /* multiply heights (e.g. 0.3048 for feet; default 1) */
    double spacing;            /* metres per sample for images without a geotransform
                                  (PNG/PGM heightmaps; default 1) */
    double image_height_range; /* PNG/PGM: metres spanned by the full 0..max sample range (default 1000) */
    size_t max_samples;        /* refuse grids larger than this (default 1 << 26); checked before
                                  anything of the grid's size is allocated */
    lk_progress_fn progress;   /* optional (default NULL): lk_dem_read reports 0.0 first and 1.0
                                  when the grid is read; non-zero cancels */
    void *progress_user;
    uint64_t reserved[8]; /* zero: room for fields of later versions (ABI rule, top of file) */
} lk_dem_options;

/* Most bytes lk_dem_read holds per sample of the grid at once (heights,
 * validity flags, the no-data fill, the decoded PNG rows or the inflated
 * .npz member, and the file): a memory budget of B bytes allows
 * max_samples = B / LK_DEM_BYTES_PER_SAMPLE. A read holds at most
 * max_samples * LK_DEM_BYTES_PER_SAMPLE bytes of them together, the file
 * of our own formats (PGM, PNG, NPZ, read whole) included: a file larger
 * than that is refused (LK_ERR_LIMIT) before it is read. GDAL's own block
 * cache (GDAL_CACHEMAX) is GDAL's. */
#define LK_DEM_BYTES_PER_SAMPLE 32u

/* Fills options with the defaults given in the fields' comments. */
LK_API void lk_dem_options_default(lk_dem_options *options);
/* Reads an elevation grid: PGM (P2/P5, 8 or 16-bit) and PNG (8/16-bit grey)
 * heightmaps and NumPy .npz archives (a 2-D "elevation" array with dx, dy,
 * xmin, ymin scalars, like matplotlib's sample DEMs) with lodkit's own
 * readers, everything else through GDAL with the drivers of formats held
 * in one file (GeoTIFF, netCDF, SRTM .hgt, DTED, ASCII and XYZ grids, Surfer,
 * USGS DEM, BT, ...) and no sidecar files: a VRT or another format whose
 * data can lie in other files is refused (LK_ERR_UNSUPPORTED), so are
 * GDAL's /vsi... paths; the subdataset syntax DRIVER:"FILE":NAME is read
 * (FILE checked like any input). Like every lodkit reader it reads only a
 * regular file (a FIFO, socket, device or directory: LK_ERR_IO, "PATH: is
 * a FIFO, not a regular file"). Geographic grids
 * (spacing in degrees) are converted to metres at the grid's mean latitude.
 * No-data samples are filled from the nearest valid ones; an all-no-data
 * grid is refused. Errors name the file (and the byte or line for our own
 * readers). */
LK_API lk_status lk_dem_read(const char *path, const lk_dem_options *options, lk_heightfield *out, lk_error *error);
/* Library: lodkit. Heightfields in memory (src/heightfield.c): terrain CLOD
 * works on any grid a program fills in, without lodkit-dem. */

/* Bilinear resampling to size x size samples spanning the same extent
 * (spacing adjusted); size 0 picks the smallest 2^n + 1 >= max(width, height). */
LK_API lk_status lk_heightfield_resample(const lk_heightfield *in, size_t size, lk_heightfield *out, lk_error *error);
LK_API void lk_heightfield_free(lk_heightfield *field);
/* A synthetic size x size terrain (seven octaves of smoothed value noise,
 * about 2 km of relief, deterministic) with the given spacing in metres:
 * test and benchmark ground with detail at every scale. */
LK_API lk_status lk_heightfield_fractal(size_t size, double spacing, lk_heightfield *out, lk_error *error);

/* ------------------------------------------------------------------------ */
/* Terrain continuous LOD (src/terrain.c)                                   */
/* ------------------------------------------------------------------------ */
/* Röttger et al. 1998 ("Real-time generation of continuous levels of
 * detail for height fields") with geomorphing and the crack elimination of
 * Ju & Kim ("Geomorphing crack elimination technique for improving terrain
 * rendering quality").
 *
 * The grid has (2^n + 1)^2 samples. Node k levels below the root has half
 * size r = 2^(n-1-k) samples and 9 points: 4 corners, 4 edge midpoints and
 * the centre. Each node has a roughness d2 = (largest height error of its
 * edge midpoints and centre against the linear interpolation of its corners
 * — both diagonals for the centre) / d, d being the node's size in metres
 * (2r times the larger grid spacing). A node is subdivided when
 *     f = l / (d * C * max(c * d2, 1)) < 1
 * with l the Euclidean (L2) 3-D distance from the eye to the node's centre
 * sample (x, y and its height), C the minimum global resolution and c the
 * error scale. d2 values are propagated upwards once, at creation: every
 * subdividable node X (size d) raises the d2 of its parent and of the two
 * parent-level nodes that share an edge with X to
 *     (max(c*d2_X, 1) / 2 + |centre_X - centre_Y| / (2 d C)) / c,
 * which by the triangle inequality makes "f_X < 1" imply "f_Y < 1": nodes
 * sharing an edge then differ by at most one level, whatever the eye
 * position. (Röttger's rule, d2 of the parent >= K d2 of the child with
 * K = C / (2(C-1)), propagated to the parent only, does not guarantee it
 * for this distance: on a 1025^2 fractal it leaves 17,425 two-level jumps
 * in a 500-frame flight, and with them T-junction cracks. The propagation
 * depends on C and c, so they are fixed at creation.)
 *
 * Leaves are drawn as triangle fans around their centre, through their
 * corners and the midpoints of the edges whose neighbour of the same size
 * exists (always on the grid border): 4 to 8 triangles, a conforming
 * triangulation (no vertex lies inside another triangle's edge).
 *
 * Geomorphing: the 16 points that appear when a node P is subdivided (the
 * centres and edge midpoints of its children) are drawn at
 *     v_g = v_p + b (v_c - v_p),  b = clamp(2 (1 - f_P), 0, 1)
 * where v_c is the true height and v_p the height of the coarser surface at
 * that point; b is "the blend of the child nodes", i.e. of the subdivision
 * that created them. Crack modes (what differs is how each leaf gets the
 * heights of its 9 points; the topology is the same in every mode):
 *   LK_TERRAIN_CRACKS_NONE: every leaf morphs its own centre and edge
 *     midpoints with its own blend, v_p interpolated from the true heights
 *     of its corners, corners at their true heights;
 *   LK_TERRAIN_CRACKS_MIDPOINT: as NONE, and an edge midpoint shared by two
 *     leaves uses the minimum of both blends (Röttger);
 *   LK_TERRAIN_CRACKS_PAPER: as MIDPOINT, plus the paper's two corner rules
 *     as written: (a/d) a corner on the parent's edge midpoint takes v_p on
 *     the parent edge and the minimum of the parent's and the parent
 *     neighbour's blends; (b/c) a corner on an ancestor's centre (any
 *     depth) takes v_p = min of the two ancestor diagonals' midpoint heights
 *     and the ancestor's blend;
 *   LK_TERRAIN_CRACKS_FULL (default): every grid vertex gets one height per
 *     frame, computed top-down: v_p is the height the coarser surface had
 *     there (the midpoint of the coarser edge or fan diagonal through it,
 *     using the already morphed heights of its ends) and b the blend of the
 *     subdivision that created it (minimum of both sides for an edge
 *     midpoint: the paper's rules, applied at every depth and
 *     hierarchically). Every triangle sharing a vertex then uses the same
 *     height, so there are no cracks; and a point appears exactly on the
 *     surface drawn before it, so there is no popping either. */

typedef enum lk_terrain_cracks {
    LK_TERRAIN_CRACKS_NONE = 0,
    LK_TERRAIN_CRACKS_MIDPOINT,
    LK_TERRAIN_CRACKS_PAPER,
    LK_TERRAIN_CRACKS_FULL
} lk_terrain_cracks;

/* "none", "midpoint", "paper", "full". */
LK_API const char *lk_terrain_cracks_name(lk_terrain_cracks mode);

typedef struct lk_terrain_options {
    double resolution;        /* C, minimum global resolution, > 0 (default 8) */
    double error_scale;       /* c, error scale, > 0 (default 50) */
    int morph;                /* geomorphing on (default 1); 0 draws every point at its true height */
    lk_terrain_cracks cracks; /* default LK_TERRAIN_CRACKS_FULL */
    int culling;              /* view-frustum culling of nodes (default 1) */
    double blend_override;    /* testing: in [0,1] forces every blend to this value; < 0 (default -1) off */
    size_t max_samples;       /* refuse grids larger than this (default 1 << 26) */
    uint64_t reserved[8];     /* zero: room for fields of later versions (ABI rule, top of file) */
} lk_terrain_options;

/* Fills options with the defaults given in the fields' comments. */
LK_API void lk_terrain_options_default(lk_terrain_options *options);

/* A camera looking from eye to target with +z up (positions in metres, the
 * grid's frame). */
typedef struct lk_terrain_view {
    double eye[3];
    double target[3];
    double fov_y;           /* vertical field of view, degrees, (0, 180) */
    double aspect;          /* width / height, > 0 */
    double viewport_height; /* pixels, > 0: converts popping to pixels */
} lk_terrain_view;

typedef struct lk_terrain lk_terrain;

/* Builds the quadtree of a (2^n + 1) x (2^n + 1) heightfield (n >= 2;
 * resample others with lk_heightfield_resample) and keeps a copy of the
 * heights: the field may be freed afterwards. options may be NULL. Refuses
 * non-square or wrongly sized grids, non-finite heights or spacings and
 * grids over options->max_samples. Cost: O(N^2) time, about 22 bytes per
 * sample. */
LK_API lk_status lk_terrain_create(const lk_heightfield *field, const lk_terrain_options *options, lk_terrain **out,
                                   lk_error *error);
LK_API void lk_terrain_free(lk_terrain *terrain);

/* Size, extent and memory of a terrain (lk_terrain_get_info). */
typedef struct lk_terrain_info {
    size_t size;     /* samples per side, 2^levels + 1 */
    unsigned levels; /* node levels (the root is level 0, the finest has half size 1) */
    size_t node_count;
    double spacing_x, spacing_y, origin_x, origin_y;
    double min_height, max_height;
    size_t memory_bytes; /* held by the terrain object */
} lk_terrain_info;
/* Fills info (zeroed when terrain is NULL). */
LK_API void lk_terrain_get_info(const lk_terrain *terrain, lk_terrain_info *info);
/* The options in use (defaults filled in). */
LK_API void lk_terrain_get_options(const lk_terrain *terrain, lk_terrain_options *options);

typedef struct lk_terrain_stats {
    size_t triangles;
    size_t vertices;
    size_t leaves;                 /* nodes drawn as fans */
    size_t nodes_visited;          /* nodes reached by the traversal */
    size_t nodes_evaluated;        /* nodes whose f was computed (also outside the frustum, next to visible leaves) */
    size_t nodes_culled;           /* nodes outside the view frustum (subtree skipped) */
    size_t morphing_nodes;         /* subdivided nodes with a blend < 1 */
    size_t restriction_violations; /* leaf edges whose neighbour is 2+ levels coarser (0 by construction) */
    unsigned max_level;            /* deepest leaf */
    double milliseconds;           /* wall time of the LOD update and mesh generation */
} lk_terrain_stats;

/* Selects the level of detail for `view`, morphs and writes the triangle
 * fans into `out` (positions in metres: x, y from the grid, z the morphed
 * height; counter-clockwise seen from +z). `out` must be empty
 * (lk_mesh_init) or hold a mesh from an earlier call (its arrays are
 * reallocated). A vertex is shared by every triangle that gives it the same
 * height. stats may be NULL. Cost: proportional to the nodes visited, not
 * to the grid size. */
LK_API lk_status lk_terrain_update(lk_terrain *terrain, const lk_terrain_view *view, lk_mesh *out,
                                   lk_terrain_stats *stats, lk_error *error);

/* The leaves drawn by the last update, as grid boxes. Valid until the next
 * update; NULL with *count 0 before the first. */
typedef struct lk_terrain_leaf {
    uint32_t x, y; /* grid index of the south-west corner */
    uint32_t size; /* samples spanned: the corners are x .. x + size */
    uint32_t level;
} lk_terrain_leaf;
/* The leaves (owned by the terrain) and their number in *count. */
LK_API const lk_terrain_leaf *lk_terrain_leaves(const lk_terrain *terrain, size_t *count);

/* The outline of the last update's leaves (the quadtree overlay): 6 floats
 * (x0 y0 z0 x1 y1 z1, true heights) per segment, *segments (release with
 * lk_free). */
LK_API lk_status lk_terrain_outline(const lk_terrain *terrain, float **segments, size_t *segment_count,
                                    lk_error *error);

typedef struct lk_terrain_crack_stats {
    size_t cracks;  /* grid points where a rendered vertex is off a rendered edge through that point */
    double max_gap; /* largest such height difference, metres */
    size_t checks;  /* (edge, vertex) pairs examined */
} lk_terrain_crack_stats;

/* Geometric crack count of a mesh on the terrain's grid (any mesh whose
 * vertices lie on grid points, e.g. from lk_terrain_update): for every
 * triangle edge, every vertex of the mesh other than the edge's own two
 * that lies on the edge's xy segment (T-junctions, and copies of an end
 * point with another height) must have the height interpolated along the
 * edge; places where it is off by more than `tolerance` metres (<= 0:
 * 1e-3) are counted once each. Cost: O(sum of edge lengths in samples *
 * log V). */
LK_API lk_status lk_terrain_count_cracks(const lk_terrain *terrain, const lk_mesh *mesh, double tolerance,
                                         lk_terrain_crack_stats *out, lk_error *error);

/* Heights of a mesh's surface at probes_per_side^2 probe points spread
 * evenly over the grid extent (corners included), row by row from the
 * south-west: heights[py * probes_per_side + px]; NaN where no triangle
 * covers the probe. probes_per_side >= 2. */
LK_API lk_status lk_terrain_sample_surface(const lk_terrain *terrain, const lk_mesh *mesh, size_t probes_per_side,
                                           float *heights, lk_error *error);

typedef struct lk_terrain_popping {
    double max_metres; /* largest |z_now - z_before| over visible probes */
    double max_pixels; /* largest projected change (at each probe's distance from the eye) */
    size_t probes;     /* probes inside the view frustum and covered in both frames */
} lk_terrain_popping;

/* Popping between two consecutive frames sampled with
 * lk_terrain_sample_surface: only probes inside `view`'s frustum (current
 * frame) count; pixels = metres * viewport_height / (2 distance tan(fov/2)). */
LK_API void lk_terrain_measure_popping(const lk_terrain *terrain, const lk_terrain_view *view, const float *before,
                                       const float *now, size_t probes_per_side, lk_terrain_popping *out);

/* The fixed flight: a circle of radius 0.3 * the smaller grid extent around
 * the grid's centre, flown counter-clockwise at `speed` grid spacings
 * (the larger spacing) per frame (<= 0: 0.5), 10 spacings above the highest
 * sample, looking ahead 30 degrees down; fov 60, aspect 4:3, 768 pixels. */
LK_API void lk_terrain_flight(const lk_terrain *terrain, size_t frame, double speed, lk_terrain_view *view);

/* A top-down map of the terrain, north up (like the paper's Fig. 9):
 * shaded relief with the colour ramp below, the squares of the last
 * update's leaves, the eye and view direction of `view` (may be NULL) and,
 * when `mesh` is given, a red ring at every crack of it (as counted by
 * lk_terrain_count_cracks with `tolerance`; the count goes to `cracks`,
 * which may be NULL). rgba holds width * height * 4 bytes, height from
 * lk_terrain_map_size (the grid's aspect ratio). */
LK_API void lk_terrain_map_size(const lk_terrain *terrain, unsigned width, unsigned *height);
LK_API lk_status lk_terrain_draw_map(const lk_terrain *terrain, const lk_terrain_view *view, const lk_mesh *mesh,
                                     double tolerance, unsigned width, unsigned char *rgba,
                                     lk_terrain_crack_stats *cracks, lk_error *error);

/* Per-vertex colours for a mesh on the grid: a hypsometric colour ramp
 * (blue under 0 m, green, brown, white at the top) times a hillshade from
 * the true grid normals (light from the north-west, 45 degrees up).
 * Allocates mesh->colors when absent. */
LK_API lk_status lk_terrain_color_mesh(const lk_terrain *terrain, lk_mesh *mesh, lk_error *error);

/* ------------------------------------------------------------------------ */
/* HTTP server (src/serve/, libmicrohttpd)                                  */
/* ------------------------------------------------------------------------ */
/* Library: lodkit-serve (pkg-config lodkit-serve, CMake lodkit::serve;
 * libmicrohttpd; uses lodkit-dem for terrain). */
/* An embedded HTTP server (docs/server.md) for a directory of content and
 * the WebGL viewer: raw files under /m/ with Range requests, ETags and
 * gzip for text; /api/index.json (the models in the directory, with their
 * counts); /api/points/ (point sets as LKMB buffers with normals and
 * radii); /api/terrain/ (the continuous-LOD terrain mesh for one view);
 * the viewer (web/, compiled in) at / and /web/, and the GLSL ES shaders
 * at /shaders/. Only GET and HEAD. Files are sent from a file descriptor,
 * never loaded whole (a file that shrinks while it is sent cuts the
 * connection: the client never gets bytes that are not the file's); paths
 * are refused when they contain "..", hidden components, backslashes or
 * NUL, or resolve (through symlinks) outside the directory. One thread per
 * connection (requests that build a terrain or a stream may take seconds
 * without stalling the others), at most max_connections of them, at most
 * max_connections_per_ip per client address (further connections are
 * closed at once); the memory caches are bounded. docs/server.md, "Faults
 * and limits", says what a client sees in each case. */

/* Receives one line per finished request, without a newline:
 *   127.0.0.1 "GET /m/bunny.lks" 206 65536 bytes 0.4 ms
 * and server events (stream builds, libmicrohttpd errors). Called from
 * the server's threads, possibly from several at once. */
typedef void (*lk_server_log_fn)(void *user, const char *line);

typedef struct lk_server_options {
    const char *host;                /* address to listen on, numeric or a name (default "127.0.0.1") */
    unsigned port;                   /* TCP port (default 8080); 0 = a free port (see lk_server_port) */
    const char *web_dir;             /* serve the viewer from this directory; NULL (default) = the
                                      copy compiled into the library */
    int simplify_on_demand;          /* /m/NAME.lks with only a mesh NAME.obj|ply|off|stl|smf|gltf|glb:
                                      build the stream (defaults of `lodkit progressive`) on the
                                      first request, cache it on disk, serve it (default 0) */
    const char *cache_dir;           /* where those streams go; NULL = DIR/.lodkit-cache */
    unsigned max_connections;        /* concurrent connections (default 256) */
    unsigned max_connections_per_ip; /* per client address (default 128) */
    unsigned timeout_seconds;        /* idle connections are closed after this, and a connection whose
                                      request headers have not all arrived this long after it opened
                                      (or after its previous response) is dropped: slow clients
                                      (default 30) */
    size_t connection_memory;        /* buffer per connection, request headers included (default 64 KiB) */
    size_t gzip_max_bytes;           /* largest text file compressed on the fly (default 8 MiB) */
    size_t cache_bytes;              /* memory for gzip results, index JSON, point buffers (default 128 MiB) */
    size_t terrain_bytes;            /* memory for cached terrains (at most 4; default 512 MiB): a new
                                      one that does not fit is refused with 503 */
    size_t max_points;               /* default ?max= of /api/points (default 1,000,000) */
    size_t max_file_bytes;           /* largest file parsed for the index and the APIs (default 1 GiB) */
    size_t max_memory;               /* memory budget of one file read (lk_read_options.max_bytes, DEM
                                      samples via LK_DEM_BYTES_PER_SAMPLE): mesh, point set and
                                      terrain requests over it are refused with 413 (default 1 GiB;
                                      `lodkit serve` passes --max-memory) */
    lk_server_log_fn log;            /* may be NULL: then nothing is logged */
    void *log_user;
    uint64_t reserved[8]; /* zero: room for fields of later versions (ABI rule, top of file) */
} lk_server_options;

/* Fills options with the defaults given in the fields' comments. */
LK_API void lk_server_options_default(lk_server_options *options);

typedef struct lk_server lk_server;

/* Starts serving `directory` on background threads and returns at once
 * (the socket is bound and listening when it returns). options may be
 * NULL (defaults). Fails with LK_ERR_IO when the directory cannot be
 * opened or the address cannot be bound (message says which). */
LK_API lk_status lk_server_start(const char *directory, const lk_server_options *options, lk_server **out,
                                 lk_error *error);
/* The port actually bound (the free port chosen for port 0). */
LK_API unsigned lk_server_port(const lk_server *server);
/* Closes the socket, cancels simplify-on-demand builds in progress, shuts
 * every connection down (slow, idle and stalled clients included), waits
 * for the connection threads (at most for one terrain or point-set
 * computation in progress) and frees everything. Accepts NULL. */
LK_API void lk_server_stop(lk_server *server);

#ifdef __cplusplus
}
#endif

#endif /* LODKIT_H */
