/* SPDX-License-Identifier: MIT */
/* Internal helpers shared by lodkit's source files. Not installed. */
#ifndef LODKIT_INTERNAL_H
#define LODKIT_INTERNAL_H

#include "lodkit.h"

#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>

/* ---- checked allocation ------------------------------------------------ */
/* Return NULL when count*size overflows or malloc fails. count==0 gives a
 * valid 1-byte allocation so callers can treat NULL as failure. */
void *lk__malloc_array(size_t count, size_t size);
void *lk__calloc_array(size_t count, size_t size);
void *lk__realloc_array(void *ptr, size_t count, size_t size);
/* Like lk__malloc_array (zeroed when `zero`), for an array read at random:
 * aligned to a cache line, and from 4 MiB on Linux asks for transparent
 * huge pages, so that its random accesses miss the TLB less (the QEM
 * simplifier: 10% faster on a 1.1M-triangle mesh). Also for a large array
 * about to be filled (a file's bytes, a mesh's arrays): one 2 MiB page
 * fault instead of 512 small ones halves the time a reader spends in the
 * kernel. Free with free(). */
void *lk__alloc_random_access(size_t count, size_t size, bool zero);
/* The triangles of `mesh` without degenerate ones (a repeated corner) and
 * without repeats of a vertex set already seen (lk_mesh_remove_degenerate's
 * rule), as a mesh sharing every array of `mesh` but the indices: *clean
 * takes mesh's indices when nothing is removed (*owned_indices = NULL),
 * otherwise a compacted copy that the caller frees (*owned_indices). The
 * simplifiers read their input only: no copy of the vertex data. */
lk_status lk__mesh_clean_view(const lk_mesh *mesh, lk_mesh *clean, uint32_t **owned_indices, lk_error *error);

/* Growable array of bytes; used by parsers that do not know counts upfront. */
typedef struct lk__buffer {
    unsigned char *data;
    size_t size;     /* bytes used */
    size_t capacity; /* bytes allocated */
} lk__buffer;
/* Appends bytes; returns false on allocation failure. */
bool lk__buffer_append(lk__buffer *buffer, const void *bytes, size_t size);
/* Ensures room for `extra` more bytes. */
bool lk__buffer_reserve(lk__buffer *buffer, size_t extra);
/* Appends a formatted note (one line, at most 319 characters) to `notes`
 * unless the same line is already there; returns true when it was added.
 * Best effort: out of memory loses the note. */
bool lk__notes_vadd(lk__buffer *notes, const char *format, va_list args);
void lk__buffer_free(lk__buffer *buffer);
/* Hands the bytes over to the caller (trimmed to size; NULL when empty) and
 * leaves the buffer empty. */
void *lk__buffer_take(lk__buffer *buffer);

/* ---- memory budget of one read ------------------------------------------
 * Everything a read holds at once counts against one limit: the input's
 * bytes, decoded buffers (base64 data: URIs, external buffers, inflated
 * members), parse trees, the parser's growing arrays, the result and any
 * copy or scratch array proportional to the input. Each such allocation is
 * charged before it is made and released when it is freed, so a read never
 * holds more than `limit` bytes of them (lk_read_options in lodkit.h says
 * what is left out: the program itself, allocator slack, fixed-size
 * scratch). */
typedef struct lk__budget {
    size_t limit; /* bytes the read may hold at once (never 0) */
    size_t held;  /* bytes charged and not yet released */
} lk__budget;
/* Bytes that can still be charged. */
static inline size_t lk__budget_room(const lk__budget *budget)
{
    return budget->held < budget->limit ? budget->limit - budget->held : 0;
}
/* Charges count * size bytes; returns false, charging nothing, when they do
 * not fit (or the product overflows). */
bool lk__budget_charge(lk__budget *budget, size_t count, size_t size);
/* Gives back bytes charged before (never below zero). */
void lk__budget_release(lk__budget *budget, size_t count, size_t size);
/* Charges the arrays lk_mesh_alloc makes for these counts and LK_ATTR_*
 * flags; false, charging nothing, when they do not fit. */
bool lk__budget_charge_mesh(lk__budget *budget, size_t vertex_count, size_t triangle_count, unsigned flags);
/* The capacity (in elements of `size` bytes) that a growing array of
 * `capacity` elements should get to hold `need` (first_capacity when it has
 * none yet): doubled when the budget has room for that, else `need` plus
 * half of the room left, so that arrays growing side by side near the limit
 * leave room to each other and the reallocations stay few (at least one
 * element). 0 when `need` itself does not fit. Charges nothing. */
size_t lk__budget_grow_capacity(const lk__budget *budget, size_t capacity, size_t need, size_t size,
                                size_t first_capacity);
/* lk__buffer_reserve charged to `budget`, growing as
 * lk__budget_grow_capacity says (the capacity is what is held), so
 * LK_ERR_LIMIT means the bytes themselves do not fit. Returns LK_OK,
 * LK_ERR_LIMIT or LK_ERR_NOMEM and sets no message (the caller knows where
 * it is). */
lk_status lk__buffer_reserve_charged(lk__buffer *buffer, size_t extra, lk__budget *budget);
/* lk__buffer_append through lk__buffer_reserve_charged. */
lk_status lk__buffer_append_charged(lk__buffer *buffer, const void *bytes, size_t size, lk__budget *budget);
/* lk__buffer_take for a charged buffer: the unused capacity is trimmed and
 * released; the bytes handed over stay charged. */
void *lk__buffer_take_charged(lk__buffer *buffer, lk__budget *budget);
/* lk__buffer_free for a charged buffer: releases its capacity. */
void lk__buffer_free_charged(lk__buffer *buffer, lk__budget *budget);

/* ---- files ------------------------------------------------------------- */
/* The one way lodkit opens a file to read it (readers, GDAL's inputs, the
 * server). Only a regular file is accepted: a FIFO, socket, device or
 * directory is refused with a message naming what it is ("PATH: is a FIFO,
 * not a regular file"), before anything could block on it or read it
 * forever (it is opened O_NONBLOCK, checked with fstat, and only then made
 * blocking; without `folder` a stat() refuses it before it is even opened).
 * Without `folder`, `path` is opened as given (symbolic links followed).
 * With `folder`, `path` is relative to that directory and is opened one
 * component at a time without following any symbolic link ("..", an
 * absolute path or a link anywhere on the way is refused): the file is a
 * regular file inside the folder, whatever links lie there.
 * On failure: LK_ERR_IO, a message "PATH: reason" (PATH as given, so a
 * caller can take the reason after that prefix), and errno says why:
 * the open's own errno (ENOENT, EACCES, ...), ELOOP for a refused link,
 * ENOTDIR for a component that is not a directory, EISDIR for a directory,
 * EPERM for another kind of file or a path leaving the folder.
 * On success *fd is a blocking O_RDONLY|O_CLOEXEC descriptor and *info
 * (if not NULL) its fstat. */
struct stat;
lk_status lk__open_input(const char *folder, const char *path, int *fd, struct stat *info, lk_error *error);
/* Reads the whole file opened as fd (info: its fstat) into a
 * NUL-terminated heap buffer (size excludes the NUL). A file larger than
 * max_bytes (0: no limit) is refused (LK_ERR_LIMIT) before anything is
 * allocated. A file that changes while it is read (shrinks, grows, is
 * rewritten: size or mtime differ afterwards) gives LK_ERR_IO "NAME: read
 * error: the file changed while it was read", never a partial buffer. */
lk_status lk__read_opened(int fd, const struct stat *info, const char *name, size_t max_bytes, char **data,
                          size_t *size, lk_error *error);
/* Reads bytes [0, length) of the file opened as fd (length <= its size
 * in info) into out; LK_ERR_IO "read error" when the file changed under
 * the read (shorter now, or its size or mtime differ afterwards). */
lk_status lk__read_prefix(int fd, const struct stat *info, const char *name, size_t length, void *out, lk_error *error);
/* lk__open_input(NULL, path) + lk__read_opened: a whole file, within max_bytes (0: no limit). */
lk_status lk__read_file(const char *path, size_t max_bytes, char **data, size_t *size, lk_error *error);
/* lk__read_file (whole, no limit of its own) with the bytes charged to `budget`: a file larger than what
 * the budget has left is refused before it is read ("NAME: the file has N
 * bytes, more than the memory budget of M bytes"). After freeing the data,
 * lk__budget_release(budget, size, 1). */
lk_status lk__read_file_charged(const char *path, lk__budget *budget, char **data, size_t *size, lk_error *error);
/* The refusal above, for `size` bytes held elsewhere (a buffer in memory). */
lk_status lk__input_too_large(const char *name, unsigned long long size, const lk__budget *budget, lk_error *error);

/* The first triangle of every set with the same three vertices (in any
 * order), in mesh order, written to out (triangle_count entries); with
 * skip_degenerate, triangles repeating a vertex are left out too. Returns
 * how many, or SIZE_MAX when out of memory. O(T log T). */
size_t lk__unique_triangles(const lk_mesh *mesh, bool skip_degenerate, uint32_t *out);

/* Atomic output: open a temporary file next to `path`, write to `file`,
 * then lk__atomic_commit (fflush+fsync+rename) or lk__atomic_abort (remove). */
typedef struct lk__atomic_sink lk__atomic_sink; /* the descriptor and its first write error */
typedef struct lk__atomic_file {
    FILE *file;
    char *final_path;
    char *temp_path;
    lk__atomic_sink *sink;
} lk__atomic_file;
lk_status lk__atomic_open(lk__atomic_file *out, const char *path, lk_error *error);
lk_status lk__atomic_commit(lk__atomic_file *out, lk_error *error);
void lk__atomic_abort(lk__atomic_file *out);
/* lk__atomic_abort after a writer failed with `error` set: when the failure
 * was a write to the file, its OS reason (e.g. "No space left on device") is
 * added to the message. Returns error->status. */
lk_status lk__atomic_fail(lk__atomic_file *out, lk_error *error);
/* Creates an empty folder next to `path` named like the temporary files,
 * ".NAME.TAG-XXXXXX" (mode 0777 less the umask, as mkdir gives), and returns
 * its path in *temp_path (free it). For outputs that are whole folders: the
 * new one is built there and renamed into place (same file system). */
lk_status lk__temp_dir_create(const char *path, const char *tag, char **temp_path, lk_error *error);

/* ---- text parsing ------------------------------------------------------ */
/* All take a cursor *p and a hard end (buffers need not be NUL-terminated).
 * Spaces are ' ', '\t', '\r', '\v', '\f'; newlines are never skipped by
 * lk__skip_spaces. */
static inline bool lk__is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }
static inline const char *lk__skip_spaces(const char *p, const char *end)
{
    while (p < end && lk__is_space(*p)) p++;
    return p;
}
/* Returns a pointer just past the next '\n' (or end). */
const char *lk__skip_line(const char *p, const char *end);
/* Parses a decimal floating-point number (also "nan", "inf", "infinity",
 * with sign) after skipping spaces. On success advances *p and returns
 * true. Correctly rounded for up to 19 significant digits and exponents in
 * [-22, 22] (fast path), via strtod otherwise. */
bool lk__parse_double(const char **p, const char *end, double *out);
/* Parses an optionally signed decimal integer after skipping spaces.
 * Fails on overflow of long long. */
bool lk__parse_int64(const char **p, const char *end, long long *out);
/* Sets "NAME:LINE: message" (text formats' error location). */
lk_status lk__error_at_line(lk_error *error, lk_status status, const char *name, size_t line, const char *format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 5, 6)))
#endif
    ;
lk_status lk__error_at_line_v(lk_error *error, lk_status status, const char *name, size_t line, const char *format,
                              va_list args);
/* Sets "NAME: byte OFFSET: message" (binary formats' error location). */
lk_status lk__error_at_byte(lk_error *error, lk_status status, const char *name, size_t offset, const char *format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 5, 6)))
#endif
    ;
lk_status lk__error_at_byte_v(lk_error *error, lk_status status, const char *name, size_t offset, const char *format,
                              va_list args);
/* Copies the token at p (after spaces, at most 24 characters) into out, for
 * messages such as "got 'abc'". */
void lk__quote_token(const char *p, const char *end, char *out, size_t out_size);
/* Case-insensitive comparison of [p, p+len) with a NUL-terminated word. */
bool lk__word_equals(const char *p, size_t len, const char *word);

/* ---- per-format readers and writers (src/io_*.c) ----------------------- */
/* Readers: parse `data` (size bytes, NUL-terminated at data[size] when it
 * comes from lk__read_file, but readers must not rely on it) into an empty
 * `mesh`. `name` is the file name for messages. On failure they must leave
 * `mesh` empty (lk_mesh_free it) and set error with name:line or
 * name: byte N. The budget already holds the input's bytes; readers charge
 * everything they allocate that grows with the input, the mesh included
 * (they may leave the mesh's arrays charged when they succeed). */
typedef struct lk__read_context {
    const char *name;      /* file name for messages */
    const char *directory; /* directory of the file for external references, or NULL */
    lk__budget *budget;    /* what the whole read may hold (limit = lk_read_options.max_bytes) */
} lk__read_context;

lk_status lk__read_obj(const char *data, size_t size, const lk__read_context *ctx, lk_mesh *mesh, lk_error *error);
lk_status lk__read_ply(const char *data, size_t size, const lk__read_context *ctx, lk_mesh *mesh, lk_error *error);
lk_status lk__read_off(const char *data, size_t size, const lk__read_context *ctx, lk_mesh *mesh, lk_error *error);
lk_status lk__read_smf(const char *data, size_t size, const lk__read_context *ctx, lk_mesh *mesh, lk_error *error);
lk_status lk__read_xyz(const char *data, size_t size, const lk__read_context *ctx, lk_mesh *mesh, lk_error *error);
/* PCD (src/io_pcd.c): points with a NaN or infinite coordinate are dropped. */
lk_status lk__read_pcd(const char *data, size_t size, const lk__read_context *ctx, lk_mesh *mesh, lk_error *error);
/* PCD point records one at a time, for the octree's streaming reader
 * (src/octree_input.c): binary records of record_size bytes from
 * data_offset, or ascii lines from line data_line (blank lines skipped). */
typedef struct lk__pcd_stream {
    struct pcd_header *header; /* the parsed header (src/io_pcd.c) */
    int binary;                /* 1: binary records; 0: ascii lines */
    size_t data_offset, data_line, record_size;
    unsigned long long points; /* records (points with a coordinate not finite are dropped) */
    int has_normals, has_colors;
} lk__pcd_stream;
/* Parses the header in head[0 .. head_size) (the file's first bytes) of a
 * file of file_size bytes. LK_ERR_UNSUPPORTED (no message to show) for
 * binary_compressed data or a header longer than `head`: read it whole. */
lk_status lk__pcd_stream_open(const char *head, size_t head_size, unsigned long long file_size, const char *name,
                              lk__pcd_stream *stream, lk_error *error);
void lk__pcd_stream_close(lk__pcd_stream *stream);
/* One binary record: false when the point is dropped. */
bool lk__pcd_stream_record(const lk__pcd_stream *stream, const unsigned char *record, double xyz[3], float normal[3],
                           uint8_t rgb[3]);
/* One ascii point line [p, end), number `line`: *kept false when dropped. */
lk_status lk__pcd_stream_line(const lk__pcd_stream *stream, const char *p, const char *end, const char *name,
                              size_t line, double xyz[3], float normal[3], uint8_t rgb[3], bool *kept, lk_error *error);
/* LAS (src/io_las.c): positions and RGB; LAZ is refused with how to decompress it. */
lk_status lk__read_las(const char *data, size_t size, const lk__read_context *ctx, lk_mesh *mesh, lk_error *error);
/* PLY point clouds read in batches (src/octree_input.c): where x y z,
 * nx ny nz and red green blue lie in each record of a first element
 * "vertex" of fixed-size scalar properties. */
typedef struct lk__ply_layout {
    unsigned long long count; /* vertices */
    size_t body_offset;       /* first byte of the first record */
    size_t record_size;
    int big_endian;
    int has_normals, has_colors;
    int ascii;             /* ASCII body: one record per vertex of property_count numbers */
    size_t body_line;      /* ASCII: the line number of body_offset */
    size_t property_count; /* properties of a vertex record */
    size_t at[9];          /* byte in the record (ASCII: index of the value) of x y z nx ny nz red green blue (SIZE_MAX:
                     absent) */
    int type[9];           /* their types, for lk__ply_stream_value */
    double color_scale[3];
} lk__ply_layout;
/* Parses the header in head[0 .. head_size) (the file's first bytes) of a
 * file of file_size bytes. LK_ERR_UNSUPPORTED (no message to show) when the
 * file cannot be streamed that way (lists or other elements first,
 * a header longer than `head`): read it whole instead. Other errors are
 * the file's, with NAME:LINE. */
lk_status lk__ply_stream_layout(const char *head, size_t head_size, unsigned long long file_size, const char *name,
                                lk__ply_layout *layout, lk_error *error);
double lk__ply_stream_value(const unsigned char *bytes, int type, int big_endian);
/* An ASCII value as its declared type holds it (a float property: rounded
 * to float, as the whole-file reader stores it). */
double lk__ply_ascii_value(double value, int type);
/* XYZ lines (src/io_xyz.c), for lk__read_xyz and the octree's streaming
 * reader: the count of numbers the first point line set. */
typedef struct lk__xyz_lines {
    int numbers_per_line; /* 0 until the first point line, then 3 or 6 */
    size_t first_line;
} lk__xyz_lines;
/* One line [p, end) (no newline), number `line` of file `name`: *count = 0
 * for a blank or '#' comment line, else 3 or 6 (x y z [nx ny nz]) in
 * values, the same count as the first point line. Errors say NAME:LINE. */
lk_status lk__xyz_line(lk__xyz_lines *state, const char *p, const char *end, const char *name, size_t line,
                       double values[6], int *count, lk_error *error);
/* The LAS header's fields that locate and decode the point records, for
 * lk__read_las and the octree's streaming reader (src/octree.c). */
typedef struct lk__las_header {
    size_t header_size;
    size_t point_offset;  /* first byte of the first point record */
    unsigned format;      /* point data record format, 0 to 10 */
    size_t record_length; /* bytes of one point record */
    unsigned long long point_count;
    size_t count_at; /* the byte the count came from, for messages */
    double scale[3], offset[3];
} lk__las_header;
/* Parses and checks the public header block. `data` holds the file's first
 * bytes (at least min(size, 375) of them, and at least 256 readable), `size`
 * is the whole file's size (offsets are checked against it). Errors say
 * NAME: byte N. */
lk_status lk__las_parse_header(const unsigned char *data, size_t size, const char *name, lk__las_header *header,
                               lk_error *error);
/* Where the 16-bit RGB of a record of point format `format` starts; 0: none. */
unsigned lk__las_rgb_offset(unsigned format);
lk_status lk__read_stl(const char *data, size_t size, const lk__read_context *ctx, lk_mesh *mesh, lk_error *error);
lk_status lk__read_gltf(const char *data, size_t size, const lk__read_context *ctx, lk_mesh *mesh, lk_error *error);
/* lk_mesh_read_memory with the directory external references are read
 * from (glTF buffers, opened with lk__open_input below it): what the
 * server parses is the bytes of the descriptor it opened, named by the
 * path relative to the served folder. Format from the name, else sniffed. */
lk_status lk__mesh_read_buffer(const void *data, size_t size, const char *name, const char *directory,
                               const lk_read_options *options, lk_mesh *mesh, lk_error *error);
/* lk_mesh_read charging everything to `budget`; the mesh's arrays stay
 * charged (for readers of several files, such as an Acclaim set). */
lk_status lk__mesh_read_charged(const char *path, lk_format format, lk__budget *budget, lk_mesh *mesh, lk_error *error);

/* Writers: write the whole mesh to an open stream; the caller handles the
 * temporary file. Return LK_ERR_IO on a write error. */
lk_status lk__write_obj(FILE *file, const lk_mesh *mesh, const lk_write_options *options, lk_error *error);
lk_status lk__write_ply(FILE *file, const lk_mesh *mesh, const lk_write_options *options, lk_error *error);
/* glTF 2.0 (src/io_gltf_mesh_write.c): .glb when binary, else .gltf with its buffer in NAME.bin next to
 * `path`. */
lk_status lk__write_gltf_mesh(FILE *file, const char *path, bool binary, const lk_mesh *mesh,
                              const lk_write_options *options, lk_error *error);
/* A whole scene (lk_scene_write). */
lk_status lk__write_gltf_scene(FILE *file, const char *path, bool binary, const lk_scene *scene,
                               const lk_write_options *options, lk_error *error);
/* glTF into a scene (src/io_gltf_scene.c, lk_scene_read). */
lk_status lk__read_gltf_scene(const char *data, size_t size, const lk__read_context *ctx, lk_scene *scene,
                              lk_error *error);
/* OBJ with its .mtl materials into a scene (src/io_obj_scene.c,
 * lk_scene_read): a primitive per material, textures from files in
 * ctx->directory (NULL: none read, a note says so). */
lk_status lk__read_obj_scene(const char *data, size_t size, const lk__read_context *ctx, lk_scene *scene,
                             lk_error *error);
/* The same with `mtl` (mtl_size bytes, or NULL) read as the text of every
 * mtllib the .obj names, from memory (the fuzz target's way in). */
lk_status lk__read_obj_scene_text(const char *data, size_t size, const char *mtl, size_t mtl_size,
                                  const lk__read_context *ctx, lk_scene *scene, lk_error *error);
/* lk_scene_flatten, and (materials not NULL) the material of each triangle
 * of the mesh in a new array (free), -1 for none. */
lk_status lk__scene_flatten_materials(const lk_scene *scene, lk_mesh *mesh, int32_t **materials, lk_error *error);
/* For each mesh (stretches: mesh_count entries), the largest factor by
 * which the world transforms of the nodes drawing it stretch it; 0 for a
 * mesh no node draws. world_extent (may be NULL): the longest side of the
 * box around every drawn mesh's box as placed in the world (0: nothing
 * drawn). Errors: a node tree with a cycle or out of range. */
lk_status lk__scene_mesh_stretches(const lk_scene *scene, double *stretches, double *world_extent, lk_error *error);
/* src/scene_copy.c: a node with no mesh, camera or children and the
 * identity transform. */
void lk__scene_node_init(lk_scene_node *node);
/* A deep copy of `in` with room for extra_nodes more nodes and extra_meshes
 * more meshes (zeroed; the counts are in's). */
lk_status lk__scene_copy(lk_scene *out, const lk_scene *in, size_t extra_nodes, size_t extra_meshes, lk_error *error);
/* A copy of `count` elements of `size` bytes (NULL when in is NULL or count
 * 0); false when out of memory. */
bool lk__scene_copy_array(void **out, const void *in, size_t count, size_t size);
/* A deep copy of one primitive of a mesh with target_count morph targets;
 * false when out of memory (free what was copied with
 * lk__scene_primitive_free). */
bool lk__scene_copy_primitive(lk_scene_primitive *out, const lk_scene_primitive *in, size_t target_count);
/* A deep copy of a mesh (false when out of memory; lk_scene_free frees
 * what was copied once the mesh is counted in a scene). */
bool lk__scene_copy_mesh(lk_scene_mesh *out, const lk_scene_mesh *in);
/* Frees what a primitive holds. */
void lk__scene_primitive_free(lk_scene_primitive *primitive);
/* src/scene_skin.c: skinned primitives posed by their joints. world(joint) x
 * inverse bind matrix of each joint of `skin` into out (16 doubles a joint;
 * worlds: 16 per node; a joint that is no node uses `fallback`). */
void lk__scene_joint_matrices(const lk_scene *scene, const double *worlds, const lk_scene_skin *skin,
                              const double fallback[16], double *out);
/* The blended matrix of vertex v (its weights over joint_matrices; an
 * unweighted vertex follows its first joint) into out; NULL when that joint
 * does not exist. */
const double *lk__scene_skin_matrix(const lk_scene_primitive *primitive, size_t v, const double *joint_matrices,
                                    size_t joint_count, double out[16]);
/* The primitive of mesh mesh_index posed by the first node drawing it with a
 * skin (3 floats a vertex, malloc'd), or NULL (not skinned, no such node, out
 * of memory). */
float *lk__scene_posed_primitive(const lk_scene *scene, const double *worlds, size_t mesh_index,
                                 const lk_scene_primitive *primitive);
/* src/scene_anim_trim.c: copies of the scene's animations without the keys
 * their neighbours reproduce and the channels that hold their node's rest
 * value (compact glTF output); *out is NULL when the scene has none. Free
 * with lk__scene_animations_free (the names are the scene's). */
lk_status lk__scene_trimmed_animations(const lk_scene *scene, lk_scene_animation **out, lk_error *error);
void lk__scene_animations_free(lk_scene_animation *animations, size_t count);
/* Levels of detail of one mesh with MSFT_lod (lk_mesh_write_lods). */
lk_status lk__write_gltf_levels(FILE *file, const char *path, bool binary, const lk_mesh *levels, size_t level_count,
                                const lk_lod_level_info *info, const lk_write_options *options, lk_error *error);
lk_status lk__write_off(FILE *file, const lk_mesh *mesh, const lk_write_options *options, lk_error *error);
lk_status lk__write_smf(FILE *file, const lk_mesh *mesh, const lk_write_options *options, lk_error *error);
lk_status lk__write_xyz(FILE *file, const lk_mesh *mesh, const lk_write_options *options, lk_error *error);
lk_status lk__write_stl(FILE *file, const lk_mesh *mesh, const lk_write_options *options, lk_error *error);
/* LAS 1.2, point format 0 (or 2 with colours); a mesh's vertices, its triangles dropped. */
lk_status lk__write_las(FILE *file, const lk_mesh *mesh, const lk_write_options *options, lk_error *error);

/* Checks that a header's claimed element count can be real: `count` elements
 * of at least `min_bytes_each` bytes must fit in `available` bytes, and the
 * mesh arrays (bytes_per_element each) must fit in what the budget has left
 * (nothing is charged). Sets a LK_ERR_LIMIT message mentioning `what` and
 * `where` otherwise. */
lk_status lk__check_claim(unsigned long long count, size_t min_bytes_each, size_t available, size_t bytes_per_element,
                          const lk__budget *budget, const char *what, const char *where, lk_error *error);

/* 4x4 matrices, column-major like glTF's: m[column * 4 + row]. out may be
 * a or b. */
void lk__mat4_identity(double m[16]);
void lk__mat4_multiply(const double a[16], const double b[16], double out[16]);

/* Writes a float with the shortest decimal form that reads back exactly. */
int lk__format_float(char *buffer, size_t size, float value);

/* ---- simplification back ends (src/qem.c, src/cluster.c) ---------------
 * Called by lk_simplify (src/simplify.c) with validated options, a mesh
 * already cleaned of degenerate/duplicate triangles and of non-finite
 * values, and a zeroed result whose `diagonal` is set. They fill result->mesh,
 * error, target_reached, vertex_map (input vertex -> output vertex) and, for
 * QEM with LK_SIMPLIFY_RECORD, the history. vertex indices in history refer
 * to `mesh` (which has the same vertices as the user's input). */
lk_status lk__simplify_qem(const lk_mesh *mesh, const lk_simplify_options *options, lk_simplify_result *result,
                           lk_progress_fn progress, void *progress_user, lk_error *error);
/* lk__simplify_qem with the triangle-list pool held to pool_limit entries
 * (at least 3 * triangle_count) instead of 2^32 - 1: the tests reach its
 * compaction on small meshes. */
lk_status lk__simplify_qem_pool_limit(const lk_mesh *mesh, const lk_simplify_options *options, size_t pool_limit,
                                      lk_simplify_result *result, lk_progress_fn progress, void *progress_user,
                                      lk_error *error);
/* A part of a larger mesh (src/qem_parallel.c): simplified in the whole
 * mesh's normalisation (center, extent), so costs, max_error and
 * pair_distance mean what they mean for the whole, with locked[v] != 0
 * for input vertices that never move or vanish (those shared with other
 * parts). */
typedef struct lk__qem_part {
    const unsigned char *locked;
    double center[3], extent;
} lk__qem_part;
lk_status lk__simplify_qem_part(const lk_mesh *mesh, const lk_simplify_options *options, const lk__qem_part *part,
                                lk_simplify_result *result, lk_progress_fn progress, void *progress_user,
                                lk_error *error);
/* QEM on part_count parts simplified on as many threads (slabs of equal
 * triangle counts along the longest axis, the vertices they share locked),
 * then a pass over a band around the cuts. Same contract as
 * lk__simplify_qem except the history (LK_SIMPLIFY_RECORD is refused). */
lk_status lk__simplify_qem_parallel(const lk_mesh *mesh, const lk_simplify_options *options, unsigned part_count,
                                    lk_simplify_result *result, lk_progress_fn progress, void *progress_user,
                                    lk_error *error);
lk_status lk__simplify_uniform(const lk_mesh *mesh, const lk_simplify_options *options, lk_simplify_result *result,
                               lk_progress_fn progress, void *progress_user, lk_error *error);
lk_status lk__simplify_floating(const lk_mesh *mesh, const lk_simplify_options *options, lk_simplify_result *result,
                                lk_progress_fn progress, void *progress_user, lk_error *error);
/* Clustering's per-vertex weights (src/cluster_weights.c): used[] (in a
 * triangle with three distinct corners), importance[], and the counts and
 * surface area that seed the cell-size search. `vertex_block` holds 16
 * bytes per vertex (any content): importance[] is its second half, and
 * the uniform pass sums its per-vertex edge directions in the whole block
 * first (with `directions`, 4 bytes per vertex, as counters), so that it
 * touches no memory the clustering does not use after it (on a fresh
 * process every new page costs a fault: on the 1.1M-triangle bunny a
 * separate 24-byte table was half of a 1% clustering's faults). */
typedef struct lk__cluster_weights {
    const lk_mesh *mesh;
    unsigned char *used;            /* per vertex, filled */
    void *vertex_block;             /* 16 bytes per vertex; its second half becomes the importances */
    uint32_t *directions;           /* uniform: per vertex, workspace */
    size_t used_count, solid_count; /* filled: used vertices, non-degenerate triangles */
    double area;                    /* filled: the non-degenerate triangles' (estimated) */
} lk__cluster_weights;
/* Uniform cells' weights, edges measured in units of `scale` (any positive
 * length of the model's size). */
lk_status lk__cluster_mean_direction_weights(lk__cluster_weights *weights, double scale, lk_error *error);
/* Floating cells' weights (Low & Tan). */
lk_status lk__cluster_largest_angle_weights(lk__cluster_weights *weights, lk_error *error);
/* ---- QEM on several frames (src/qem.c, qem_frames.c), run by
 * lk_animation_simplify (src/anim_simplify.c) ----------------------------
 * The engine's state stays opaque here (src/qem_state.h). */
typedef struct lk__qem lk__qem;
/* What the simplification reached so far. */
typedef struct lk__qem_outcome {
    size_t live_triangles, live_vertices;
    bool parked_for_error; /* a pair was refused for exceeding max_error */
    double error;          /* largest contraction error so far, model units */
    double diagonal;       /* of the bounds of every frame (the normalisation) */
    size_t folds_from;     /* live triangles when folds were first allowed (0: never) */
} lk__qem_outcome;
/* Sets up the QEM of an animation's frames on `clean` (its connectivity
 * without degenerate or duplicate triangles, with the reference frame's
 * positions; options checked): *out is NULL on failure. */
lk_status lk__qem_frames_start(const lk_mesh *clean, const lk_animation *animation,
                               const lk_anim_simplify_options *options, lk__qem **out, lk_error *error);
/* Marks the vertices whose input id has seam[id] != 0 as seam vertices:
 * a seam vertex never merges into a vertex off the seam (it stays put
 * and the other one goes), so texture seams are never cut across. */
void lk__qem_mark_seams(lk__qem *s, const unsigned char *seam);
/* Contracts pairs until a target count is reached or no pair is left. */
lk_status lk__qem_run(lk__qem *s, size_t target_triangles, size_t target_vertices, lk_progress_fn progress,
                      void *progress_user, lk_error *error);
/* The current state as an animation (result->animation and vertex_map,
 * indexed by the vertices of `mesh`, the clean mesh given to the start). */
lk_status lk__qem_animation_output(lk__qem *s, const lk_mesh *mesh, const lk_animation *animation,
                                   lk_anim_simplify_result *result, lk_error *error);
/* After lk__qem_animation_output: survivor[o], the clean vertex kept as
 * output vertex o, and source_triangle[t], the clean triangle of output
 * triangle t. */
lk_status lk__qem_output_sources(const lk__qem *s, const uint32_t *vertex_map, uint32_t *survivor,
                                 uint32_t *source_triangle, lk_error *error);
void lk__qem_outcome_of(const lk__qem *s, lk__qem_outcome *out);
void lk__qem_free(lk__qem *s);
/* Bytes of per-frame data for V vertices and F frames (SIZE_MAX on overflow). */
size_t lk__qem_frame_bytes(size_t vertex_count, size_t frame_count, bool lost_surface);

/* Wavelet simplification by planar sampling (src/wavelet_simplify.c, running
 * slice.c, wavelet.c and tile.c). */
lk_status lk__simplify_wavelet(const lk_mesh *mesh, const lk_simplify_options *options, lk_simplify_result *result,
                               lk_progress_fn progress, void *progress_user, lk_error *error);

/* ---- progressive strips (src/strips.c) --------------------------------
 * Test hook: replays the E-PS strip (entries holding a vertex or an R+-1/
 * R+-2 reference) from the base level and writes, for each ascending level,
 * the strip resolved through the references into out_strips[i]
 * (ps->strip_length entries each, caller-allocated). It must equal
 * lk_progressive_strips_level. */
lk_status lk__eps_resolved_levels(const lk_progressive_strips *ps, const lk_progressive_mesh *pm, const size_t *levels,
                                  size_t count, uint32_t **out_strips, lk_error *error);

/* ---- elevation grids in memory (src/heightfield.c) ---------------------- */

/* Sets field->min_height and max_height from its heights. */
void lk__heightfield_compute_range(lk_heightfield *field);

/* ---- elevation grids (src/io_dem.c) -------------------------------------
 * lodkit's own heightmap readers (PGM P2/P5, grey PNG, NumPy .npz) on bytes
 * in memory; `name` is used in messages. lk_dem_read calls it for
 * .pgm/.png/.npz files, so does the server on an opened descriptor; the
 * fuzz target calls it directly. */
lk_status lk__dem_read_memory(const void *data, size_t size, const char *name, const lk_dem_options *options,
                              lk_heightfield *out, lk_error *error);
/* lk_dem_read of a file opened with lk__open_input (fd, info): our own
 * formats are read from the descriptor, GDAL opens `path` and must find
 * the same file there; `name` is what messages call it (the server passes
 * the path relative to its folder). */
lk_status lk__dem_read_opened(int fd, const struct stat *info, const char *path, const char *name,
                              const lk_dem_options *options, lk_heightfield *out, lk_error *error);

/* ---- point sets (src/points.c) ------------------------------------------
 * For the tests and the bench: medians[i] = the lower median (rank
 * (k - 1) / 2) of points->radii over point i's k nearest other points, the
 * neighbourhood lk_points_estimate_radii clamps against (k clamped to
 * N - 1; ties by index). points->radii must be set. */
lk_status lk__points_neighbour_medians(const lk_mesh *points, unsigned neighbours, float *medians, lk_error *error);
/* The clip lines (lk_points_estimate_clips' rule) of the points queries[0 ..
 * query_count) among positions[3 * count] (with their normals), into
 * clips[4 * query_count] (offsets in model units), and in reach[query_count]
 * the distance of the farthest neighbour asked (0 with fewer than two
 * points). For octree levels: the neighbours are those of one level's set. */
lk_status lk__points_estimate_clips_of(const float *positions, const float *normals, size_t count,
                                       const uint32_t *queries, size_t query_count, unsigned neighbours, float *clips,
                                       float *reach, lk_error *error);

/* ---- misc -------------------------------------------------------------- */
/* splitmix64: a good 64-bit mix for deterministic, counter-based randomness. */
static inline uint64_t lk__mix64(uint64_t x)
{
    x += 0x9E3779B97F4A7C15ull;
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
    x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
    return x ^ (x >> 31);
}

/* Places the value of rank `nth` of values[0 .. count) at values[nth], no
 * greater ones before it and no smaller ones after it (deterministic
 * three-way quickselect, expected O(count)). */
void lk__select_float(float *values, size_t count, size_t nth);
/* Uniform double in [0,1) from 53 bits of a 64-bit value. */
static inline double lk__unit_double(uint64_t x) { return (double)(x >> 11) * (1.0 / 9007199254740992.0); }
/* Monotonic wall clock in seconds. */
double lk__now(void);
/* With the environment variable LODKIT_MEMORY_TRACE set, prints the
 * process's resident and peak resident memory (VmRSS, VmHWM of
 * /proc/self/status) after `stage` to stderr: where the memory of a large
 * run goes, without a heap profiler (docs/benchmarks.md). Otherwise does
 * nothing. */
void lk__memory_trace(const char *stage);

#endif
