/*
 * lodkit — multiresolution 3D geometry for networked graphics.
 *
 * This header is the whole public C API and its reference documentation.
 * Conventions (see README.md):
 *   - every public symbol starts with lk_ / LK_;
 *   - functions that can fail return an lk_status and, when given a non-NULL
 *     lk_error, write a message saying what went wrong and where
 *     (file:line for text formats, byte offset for binary ones);
 *   - the caller owns what it passes in; results live in structs that have a
 *     matching lk_*_free; no global state, so every function is thread-safe
 *     as long as two threads do not write the same object;
 *   - positions are stored as float, accumulations that need accuracy
 *     (areas, distances, quadrics) are done in double.
 */
#ifndef LODKIT_H
#define LODKIT_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define LK_VERSION_MAJOR 0
#define LK_VERSION_MINOR 1
#define LK_VERSION_PATCH 0
#define LK_VERSION_STRING "0.1.0"

/* Returns LK_VERSION_STRING of the library actually linked. */
const char *lk_version(void);

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
    LK_ERR_UNSUPPORTED  /* valid input that lodkit does not handle (yet) */
} lk_status;

/* Per-call error report. Zero-initialise it (or call lk_error_clear) before
 * use; functions fill it only on failure. */
typedef struct lk_error {
    lk_status status;
    char message[512];
} lk_error;

void lk_error_clear(lk_error *error);
/* Sets status and a printf-style message; returns status so callers can
 * write `return lk_error_set(err, LK_ERR_PARSE, "...")`. Accepts error==NULL. */
lk_status lk_error_set(lk_error *error, lk_status status, const char *format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
/* A short English name for a status ("parse error", ...). */
const char *lk_status_string(lk_status status);

/* Optional progress callback for long work: fraction in [0,1], stage is a
 * short label. Return non-zero to cancel (the function then fails with
 * LK_ERR_INVALID and "cancelled"). */
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
    float *positions;   /* 3 * vertex_count: x y z */
    float *normals;     /* 3 * vertex_count or NULL */
    float *texcoords;   /* 2 * vertex_count or NULL: u v with v up (OBJ/PLY convention;
                         * glTF's v-down coordinates are flipped when read) */
    float *colors;      /* 4 * vertex_count or NULL: r g b a in [0,1] */
    uint32_t *indices;  /* 3 * triangle_count, counter-clockwise front faces */
} lk_mesh;

/* Attribute flags for lk_mesh_alloc. */
enum {
    LK_ATTR_NORMALS = 1u << 0,
    LK_ATTR_TEXCOORDS = 1u << 1,
    LK_ATTR_COLORS = 1u << 2
};

/* Largest vertex or triangle count lodkit accepts (indices are uint32_t). */
#define LK_MAX_ELEMENTS ((size_t)0xFFFFFFF0u)

/* Sets every field to zero/NULL. */
void lk_mesh_init(lk_mesh *mesh);
/* Frees the arrays and re-initialises the mesh. Accepts NULL. */
void lk_mesh_free(lk_mesh *mesh);
/* Allocates a mesh (contents uninitialised) with the attributes in flags. */
lk_status lk_mesh_alloc(lk_mesh *mesh, size_t vertex_count, size_t triangle_count,
                        unsigned attribute_flags, lk_error *error);
/* Deep copy of src into dst (dst is overwritten, not freed first). */
lk_status lk_mesh_copy(lk_mesh *dst, const lk_mesh *src, lk_error *error);
/* Checks indices < vertex_count and finite positions/attributes.
 * Reports the first offending triangle or vertex. */
lk_status lk_mesh_validate(const lk_mesh *mesh, lk_error *error);

/* Axis-aligned bounds of all vertices; returns the diagonal length
 * (0 for an empty mesh, and then min/max are zero). min/max may be NULL. */
double lk_mesh_bounds(const lk_mesh *mesh, float min[3], float max[3]);
/* Total surface area (double accumulation). */
double lk_mesh_area(const lk_mesh *mesh);
/* Translates every vertex by (dx,dy,dz). */
void lk_mesh_translate(lk_mesh *mesh, double dx, double dy, double dz);

/* Vertex -> triangle adjacency in compressed rows:
 * the triangles around vertex v are triangles[offsets[v] .. offsets[v+1]). */
typedef struct lk_vertex_adjacency {
    size_t vertex_count;
    uint32_t *offsets;   /* vertex_count + 1 */
    uint32_t *triangles; /* 3 * triangle_count */
} lk_vertex_adjacency;
lk_status lk_vertex_adjacency_build(const lk_mesh *mesh, lk_vertex_adjacency *adjacency,
                                    lk_error *error);
void lk_vertex_adjacency_free(lk_vertex_adjacency *adjacency);

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
lk_status lk_edge_adjacency_build(const lk_mesh *mesh, lk_edge_adjacency *adjacency,
                                  lk_error *error);
void lk_edge_adjacency_free(lk_edge_adjacency *adjacency);

/* Merges vertices whose positions lie within `tolerance` (absolute, model
 * units; 0 = exactly equal) of each other, keeping the first vertex's
 * attributes, and rewrites the indices. Vertices that differ in normals or
 * texture coordinates are merged too (their attributes are dropped in
 * favour of the first). Unreferenced vertices are kept (use
 * lk_mesh_remove_unused_vertices). Returns the number of vertices merged in
 * *merged_count (may be NULL). Cost: O(V) expected with a hash grid. */
lk_status lk_mesh_weld(lk_mesh *mesh, double tolerance, size_t *merged_count, lk_error *error);

/* Removes triangles with a repeated vertex index (degenerate) and triangles
 * that use the same three vertices as an earlier one in any order or
 * orientation (duplicates). Counts may be NULL. */
lk_status lk_mesh_remove_degenerate(lk_mesh *mesh, size_t *degenerate_removed,
                                    size_t *duplicate_removed, lk_error *error);

/* Drops vertices that no triangle uses (only if the mesh has triangles) and
 * compacts the arrays, preserving order. */
lk_status lk_mesh_remove_unused_vertices(lk_mesh *mesh, size_t *removed_count, lk_error *error);

/* Connected components of triangles (triangles sharing a vertex are
 * connected). component[t] receives the component of triangle t, numbered
 * from 0 in order of first triangle; may be NULL. Returns the count in
 * *component_count. */
lk_status lk_mesh_components(const lk_mesh *mesh, uint32_t *component, size_t *component_count,
                             lk_error *error);

/* Topology and geometry summary of a mesh (what `lodkit info` prints). */
typedef struct lk_mesh_stats {
    size_t vertex_count;
    size_t triangle_count;
    size_t used_vertex_count;       /* vertices referenced by a triangle */
    size_t edge_count;              /* unique undirected edges */
    size_t boundary_edge_count;     /* edges with one triangle */
    size_t nonmanifold_edge_count;  /* edges with three or more triangles */
    size_t nonmanifold_vertex_count;/* vertices whose triangle fan is not a single disk/half-disk */
    size_t degenerate_triangle_count;/* triangles with a repeated index */
    size_t duplicate_triangle_count; /* same vertex set as an earlier triangle */
    size_t component_count;
    size_t boundary_loop_count;     /* connected sets of boundary edges */
    long long euler_characteristic; /* V - E + F over used vertices */
    long long genus;                /* (2C - chi - loops)/2; -1 when not a manifold */
    double area;
    double diagonal;
    float min[3], max[3];
} lk_mesh_stats;
lk_status lk_mesh_compute_stats(const lk_mesh *mesh, lk_mesh_stats *stats, lk_error *error);

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
    LK_FORMAT_GLTF,     /* .gltf (JSON) or .glb (binary); read only */
    LK_FORMAT_UNKNOWN
} lk_format;

/* Short lowercase name ("obj", "ply", ...). */
const char *lk_format_name(lk_format format);
/* Format from a file name's extension (case-insensitive), or LK_FORMAT_UNKNOWN. */
lk_format lk_format_from_path(const char *path);
/* Format from the first bytes of a file (magic numbers and keywords), or
 * LK_FORMAT_UNKNOWN. */
lk_format lk_format_sniff(const void *data, size_t size);

typedef enum lk_ply_encoding {
    LK_PLY_BINARY_LE = 0,
    LK_PLY_BINARY_BE,
    LK_PLY_ASCII
} lk_ply_encoding;

typedef struct lk_read_options {
    /* Refuse inputs that would need more memory than this many bytes for the
     * mesh arrays (0 = 8 GiB). Claims in headers are also checked against the
     * file size before anything is allocated. */
    size_t max_bytes;
} lk_read_options;

/* Reads a mesh or point set from a file. format LK_FORMAT_AUTO picks it from
 * the extension, falling back to the content. options may be NULL.
 * On failure `mesh` is left empty and error says FILE:LINE or FILE: byte N. */
lk_status lk_mesh_read(const char *path, lk_format format, const lk_read_options *options,
                       lk_mesh *mesh, lk_error *error);
/* Same from memory; `name` is used in messages and for the extension when
 * format is AUTO. glTF files that reference external .bin files cannot be
 * read from memory (use lk_mesh_read). */
lk_status lk_mesh_read_memory(const void *data, size_t size, const char *name, lk_format format,
                              const lk_read_options *options, lk_mesh *mesh, lk_error *error);

typedef struct lk_write_options {
    lk_ply_encoding ply_encoding; /* default binary little-endian */
    int skip_normals;             /* non-zero: do not write normals */
    int skip_texcoords;
    int skip_colors;
    int stl_ascii;                /* non-zero: ASCII STL instead of binary */
} lk_write_options;

/* Writes a mesh. The file is written to a temporary file next to `path` and
 * renamed over it at the end, so a failure never leaves a partial file.
 * options may be NULL (defaults). Formats that cannot hold an attribute
 * silently omit it (OFF keeps colours, SMF/STL keep positions only). */
lk_status lk_mesh_write(const char *path, lk_format format, const lk_mesh *mesh,
                        const lk_write_options *options, lk_error *error);

/* ------------------------------------------------------------------------ */
/* Surface distance (Metro-style)                                           */
/* ------------------------------------------------------------------------ */

/* A bounding-volume hierarchy over a mesh's triangles for nearest-point
 * queries. A mesh without triangles is indexed as a point set.
 * Build: O(T log T); query: O(log T) typical. The index keeps its own copy
 * of the geometry, so the mesh may be freed after building. */
typedef struct lk_surface_index lk_surface_index;
lk_status lk_surface_index_build(const lk_mesh *mesh, lk_surface_index **index, lk_error *error);
void lk_surface_index_free(lk_surface_index *index);
/* Nearest point of the surface to `point`. Returns the distance; writes the
 * closest point and triangle (or point) index when non-NULL. Searches only
 * within `max_distance` (pass INFINITY for no bound); returns INFINITY if
 * nothing is that close. Thread-safe (read-only). */
double lk_surface_index_nearest(const lk_surface_index *index, const double point[3],
                                double max_distance, double closest[3], uint32_t *primitive);

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
    uint64_t seed;     /* deterministic sampling seed (default 1) */
    int thread_count;  /* 0 = number of online CPUs */
} lk_metro_options;

typedef struct lk_distance_stats {
    double max;   /* over all samples (vertices, edges, faces) */
    double mean;  /* area-weighted: over face samples */
    double rms;   /* area-weighted: over face samples */
    size_t sample_count;  /* all samples taken on the source surface */
} lk_distance_stats;

typedef struct lk_metro_result {
    double diagonal;          /* bounding-box diagonal of mesh A */
    lk_distance_stats forward;  /* samples of A measured to B */
    lk_distance_stats backward; /* samples of B measured to A */
    double hausdorff;         /* max(forward.max, backward.max) */
    size_t sample_count;      /* forward + backward samples */
    double seconds;           /* wall time, including index building */
} lk_metro_result;

/* Fills options with the defaults described above. */
void lk_metro_options_default(lk_metro_options *options);
/* Measures the distance between two surfaces in both directions.
 * options may be NULL. Results are deterministic for a given seed,
 * whatever the thread count. Cost: O((S_a + S_b) log T) with S samples. */
lk_status lk_metro(const lk_mesh *a, const lk_mesh *b, const lk_metro_options *options,
                   lk_metro_result *result, lk_progress_fn progress, void *progress_user,
                   lk_error *error);

/* One-sided measure: samples of `source` to `target_index`. */
lk_status lk_metro_one_sided(const lk_mesh *source, const lk_surface_index *target_index,
                             const lk_metro_options *options, lk_distance_stats *stats,
                             lk_error *error);


/* ------------------------------------------------------------------------ */
/* Simplification: quadric error metric and vertex clustering               */
/* ------------------------------------------------------------------------ */

typedef enum lk_simplify_method {
    LK_SIMPLIFY_QEM = 0,   /* Garland-Heckbert pair contraction (src/qem.c) */
    LK_SIMPLIFY_UNIFORM,   /* Rossignac-Borrel uniform-grid clustering (src/cluster.c) */
    LK_SIMPLIFY_FLOATING   /* Low-Tan floating-cell clustering (src/cluster.c) */
} lk_simplify_method;

/* Flags for lk_simplify_options.flags. */
enum {
    LK_SIMPLIFY_LOCK_BORDER = 1u << 0, /* QEM: border vertices never move or vanish */
    LK_SIMPLIFY_ATTRIBUTES = 1u << 1,  /* QEM: quadrics also weigh normals/UVs/colours */
    LK_SIMPLIFY_NO_FEATURES = 1u << 2, /* QEM: no crease/corner constraint quadrics */
    LK_SIMPLIFY_RECORD = 1u << 3       /* QEM: record the contraction history */
};

typedef struct lk_simplify_options {
    /* Stopping rules; simplification stops at the first one reached, and at
     * least one must be set (0 = unset). */
    double target_ratio;     /* fraction of the input triangles to keep, (0, 1] */
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
} lk_simplify_options;

/* Fills options with the defaults: no target (set one), feature_angle 40,
 * feature_weight 1, attribute_weight 1, flags 0. */
void lk_simplify_options_default(lk_simplify_options *options);

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
    float error;          /* this collapse's error in model units (see lk_simplify_result.error) */
    uint32_t first_vanished;
    uint32_t vanished_count;
} lk_collapse;

typedef struct lk_simplify_result {
    lk_mesh mesh;            /* the simplified mesh, unused vertices removed */
    double error;            /* reached error in model units: for QEM the largest
                                sqrt(quadric cost / quadric area) over performed
                                collapses (an RMS plane distance); for clustering
                                the largest distance a vertex moved */
    double diagonal;         /* bounding-box diagonal of the input */
    int target_reached;      /* 0 when no target could be reached (e.g. every
                                remaining collapse would break the topology); the
                                nearest result is returned and the status is LK_OK */
    uint32_t *vertex_map;    /* input vertex -> output vertex, UINT32_MAX if gone */
    size_t collapse_count;   /* with LK_SIMPLIFY_RECORD */
    lk_collapse *collapses;
    uint32_t *vanished;      /* triangle ids referenced by collapses */
    size_t vanished_count;
    double seconds;          /* wall time of the simplification */
} lk_simplify_result;

void lk_simplify_result_free(lk_simplify_result *result);

/* Simplifies a triangle mesh. The input is not modified. Degenerate and
 * duplicate triangles are ignored; a mesh without triangles is refused
 * (LK_ERR_INVALID). QEM simplifies non-manifold and open meshes without
 * creating new non-manifold edges; clustering merges whole cells and may
 * create them (inherent to the method), and when every triangle collapses
 * returns an empty mesh with target_reached = 0. QEM cost: O(T log T) time, O(T)
 * memory; clustering: O(T) per cell size tried. */
lk_status lk_simplify(const lk_mesh *mesh, lk_simplify_method method, const lk_simplify_options *options,
                      lk_simplify_result *result, lk_progress_fn progress, void *progress_user,
                      lk_error *error);

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
lk_status lk_subdivide(const lk_mesh *mesh, lk_subdivide_scheme scheme, unsigned iterations, lk_mesh *out,
                       lk_error *error);

#ifdef __cplusplus
}
#endif

#endif /* LODKIT_H */
