/* SPDX-License-Identifier: MIT */
/* The format table (every format lodkit knows, by extension: kind, reader,
 * writer, description), format detection, and the mesh read/write entry
 * points; the formats themselves live in io_<format>.c, animations are read
 * and written through anim_dispatch.c, elevation grids through io_dem.c. */
#include "internal.h"
#include "anim_io.h"

#include <stdlib.h>
#include <string.h>

#define LK_DEFAULT_MAX_BYTES ((size_t)8 << 30)

typedef lk_status (*reader_fn)(const char *, size_t, const lk__read_context *, lk_mesh *, lk_error *);
typedef lk_status (*writer_fn)(FILE *, const lk_mesh *, const lk_write_options *, lk_error *);

/* The one format table. Adding a format is a row here, plus, for a format
 * lk_mesh_read reads, its LK_FORMAT_ value (lodkit.h) and its reader and
 * writer (io_NAME.c, declared in internal.h). Columns: name, extensions,
 * kind, lk_format, functions that read it, that write it, description;
 * then lk_mesh_read's reader and lk_mesh_write's writer (NULL when
 * LK_IO_MESH is not in the read / write flags). The order is lk_format's,
 * then animations, elevation grids (lk_dem_read: lodkit's own readers, then
 * the GDAL drivers it allows, io_dem.c), streams. */
/* glTF's writer also needs the path: a .gltf's buffer goes to NAME.bin
 * next to it, and .glb is chosen by the extension. */
typedef lk_status (*path_writer_fn)(FILE *, const char *, bool, const lk_mesh *, const lk_write_options *, lk_error *);

typedef struct format_row {
    lk_format_info info;
    reader_fn read_mesh;
    writer_fn write_mesh;
    path_writer_fn write_mesh_at; /* instead of write_mesh */
} format_row;

/* Short names for the table's columns. */
#define MESH LK_FORMAT_KIND_MESH
#define POINTS LK_FORMAT_KIND_POINTS
#define ANIMATION LK_FORMAT_KIND_ANIMATION
#define GRID LK_FORMAT_KIND_GRID
#define STREAM LK_FORMAT_KIND_STREAM
#define NO_FORMAT LK_FORMAT_UNKNOWN

static const format_row formats[] = {
    {{"obj", "obj", MESH, LK_FORMAT_OBJ, LK_IO_MESH, LK_IO_MESH, "Wavefront OBJ"}, lk__read_obj, lk__write_obj, NULL},
    {{"ply", "ply", MESH, LK_FORMAT_PLY, LK_IO_MESH, LK_IO_MESH,
      "Stanford PLY (ASCII or binary; meshes or point sets)"},
     lk__read_ply,
     lk__write_ply,
     NULL},
    {{"off", "off", MESH, LK_FORMAT_OFF, LK_IO_MESH, LK_IO_MESH, "Object File Format (OFF, COFF, NOFF, ...)"},
     lk__read_off,
     lk__write_off,
     NULL},
    {{"smf", "smf", MESH, LK_FORMAT_SMF, LK_IO_MESH, LK_IO_MESH, "Simple Model Format"},
     lk__read_smf,
     lk__write_smf,
     NULL},
    {{"xyz", "xyz xyzn pts", POINTS, LK_FORMAT_XYZ, LK_IO_MESH, LK_IO_MESH,
      "point set as text: x y z, or x y z nx ny nz, per line"},
     lk__read_xyz,
     lk__write_xyz,
     NULL},
    {{"stl", "stl", MESH, LK_FORMAT_STL, LK_IO_MESH, LK_IO_MESH, "STL (binary or ASCII)"},
     lk__read_stl,
     lk__write_stl,
     NULL},
    {{"gltf", "gltf", MESH, LK_FORMAT_GLTF, LK_IO_MESH | LK_IO_ANIMATION, LK_IO_MESH | LK_IO_ANIMATION,
      "glTF 2.0 (JSON; written with its buffer in NAME.bin): the default scene; morph-target and skinned "
      "animations"},
     lk__read_gltf,
     NULL,
     lk__write_gltf_mesh},
    {{"glb", "glb", MESH, LK_FORMAT_GLTF, LK_IO_MESH | LK_IO_ANIMATION, LK_IO_MESH,
      "glTF 2.0 binary: the default scene; morph-target and skinned animations"},
     lk__read_gltf,
     NULL,
     lk__write_gltf_mesh},
    {{"md2", "md2", ANIMATION, LK_FORMAT_MD2, LK_IO_MESH | LK_IO_ANIMATION, LK_IO_ANIMATION, "Quake II key frames"},
     lk__read_md2,
     NULL,
     NULL},
    {{"kmf", "kmf", ANIMATION, LK_FORMAT_KMF, LK_IO_MESH | LK_IO_ANIMATION, LK_IO_ANIMATION,
      "lodkit key-frame model format (SMF frames, docs/formats.md)"},
     lk__read_kmf,
     NULL,
     NULL},
    {{"pcd", "pcd", POINTS, LK_FORMAT_PCD, LK_IO_MESH, 0,
      "Point Cloud Library point cloud (ascii, binary or binary_compressed): x y z, normals, rgb/rgba"},
     lk__read_pcd,
     NULL,
     NULL},
    {{"las", "las", POINTS, LK_FORMAT_LAS, LK_IO_MESH, LK_IO_MESH,
      "ASPRS LAS 1.0-1.4 lidar point cloud (point formats 0-10): x y z, RGB; written as LAS 1.2 (format 0, or 2 "
      "with colours); LAZ is refused (decompress it to .las first)"},
     lk__read_las,
     lk__write_las,
     NULL},
    {{"acclaim", "asf amc", ANIMATION, NO_FORMAT, LK_IO_ANIMATION, 0,
      "Acclaim skeleton (.asf) and motion (.amc), with the rest pose X.smf and bone weights X.wgt"},
     NULL,
     NULL,
     NULL},
    {{"pgm", "pgm", GRID, NO_FORMAT, LK_IO_GRID, 0, "PGM heightmap (P2/P5, 8 or 16-bit)"}, NULL, NULL, NULL},
    {{"png", "png", GRID, NO_FORMAT, LK_IO_GRID, 0, "grey PNG heightmap (8 or 16-bit)"}, NULL, NULL, NULL},
    {{"npz", "npz", GRID, NO_FORMAT, LK_IO_GRID, 0, "NumPy archive of an elevation array (matplotlib's sample DEMs)"},
     NULL,
     NULL,
     NULL},
    {{"geotiff", "tif tiff", GRID, NO_FORMAT, LK_IO_GRID, 0, "GeoTIFF (through GDAL)"}, NULL, NULL, NULL},
    {{"netcdf", "nc cdf", GRID, NO_FORMAT, LK_IO_GRID, 0, "netCDF grid (through GDAL)"}, NULL, NULL, NULL},
    {{"aaigrid", "asc", GRID, NO_FORMAT, LK_IO_GRID, 0, "Arc/Info ASCII grid (through GDAL)"}, NULL, NULL, NULL},
    {{"srtm", "hgt", GRID, NO_FORMAT, LK_IO_GRID, 0, "SRTM height tile (through GDAL)"}, NULL, NULL, NULL},
    {{"dted", "dt0 dt1 dt2", GRID, NO_FORMAT, LK_IO_GRID, 0, "DTED elevation (through GDAL)"}, NULL, NULL, NULL},
    {{"usgsdem", "dem", GRID, NO_FORMAT, LK_IO_GRID, 0, "USGS DEM (through GDAL)"}, NULL, NULL, NULL},
    {{"surfer", "grd", GRID, NO_FORMAT, LK_IO_GRID, 0, "Surfer grid (through GDAL)"}, NULL, NULL, NULL},
    {{"bt", "bt", GRID, NO_FORMAT, LK_IO_GRID, 0, "VTP binary terrain (through GDAL)"}, NULL, NULL, NULL},
    {{"hf2", "hf2", GRID, NO_FORMAT, LK_IO_GRID, 0, "HF2 heightfield (through GDAL)"}, NULL, NULL, NULL},
    {{"terragen", "ter", GRID, NO_FORMAT, LK_IO_GRID, 0, "Terragen or Leveller terrain (through GDAL)"},
     NULL,
     NULL,
     NULL},
    {{"isg", "isg", GRID, NO_FORMAT, LK_IO_GRID, 0, "International Service for the Geoid grid (through GDAL)"},
     NULL,
     NULL,
     NULL},
    {{"sigdem", "sigdem", GRID, NO_FORMAT, LK_IO_GRID, 0, "Scaled Integer Gridded DEM (through GDAL)"},
     NULL,
     NULL,
     NULL},
    {{"lks", "lks", STREAM, NO_FORMAT, LK_IO_STREAM, LK_IO_STREAM,
      "lodkit progressive stream: a progressive mesh on triangle strips (docs/stream-format.md)"},
     NULL,
     NULL,
     NULL},
};
#define FORMAT_COUNT (sizeof formats / sizeof formats[0])

const lk_format_info *lk_format_info_at(size_t index) { return index < FORMAT_COUNT ? &formats[index].info : NULL; }

static char ascii_lower(char c) { return c >= 'A' && c <= 'Z' ? (char)(c - 'A' + 'a') : c; }

/* True when [extension, extension + len) is one of the space-separated
 * words of `list`, ignoring ASCII case. */
static bool list_has(const char *list, const char *extension, size_t len)
{
    for (const char *word = list; *word;) {
        size_t word_len = strcspn(word, " ");
        if (word_len == len) {
            size_t i = 0;
            while (i < len && ascii_lower(word[i]) == ascii_lower(extension[i])) i++;
            if (i == len) return true;
        }
        word += word_len;
        if (*word == ' ') word++;
    }
    return false;
}

/* The extension of a file name (after the last dot of its last component),
 * or NULL when it has none. */
static const char *extension_of(const char *path)
{
    const char *slash = strrchr(path, '/');
    const char *base = slash ? slash + 1 : path;
    const char *dot = strrchr(base, '.');
    return dot && dot[1] ? dot + 1 : NULL;
}

static const format_row *row_from_path(const char *path)
{
    const char *ext = path ? extension_of(path) : NULL;
    if (!ext) return NULL;
    size_t len = strlen(ext);
    for (size_t i = 0; i < FORMAT_COUNT; i++)
        if (list_has(formats[i].info.extensions, ext, len)) return &formats[i];
    return NULL;
}

const lk_format_info *lk_format_info_from_path(const char *path)
{
    const format_row *row = row_from_path(path);
    return row ? &row->info : NULL;
}

const char *lk_format_kind_name(lk_format_kind kind)
{
    switch (kind) {
    case LK_FORMAT_KIND_MESH: return "mesh";
    case LK_FORMAT_KIND_POINTS: return "point set";
    case LK_FORMAT_KIND_ANIMATION: return "animation";
    case LK_FORMAT_KIND_GRID: return "elevation grid";
    case LK_FORMAT_KIND_STREAM: return "progressive stream";
    }
    return NULL;
}

/* The plural, for messages ("NAME: .lks files hold progressive streams"). */
static const char *kind_plural(lk_format_kind kind)
{
    switch (kind) {
    case LK_FORMAT_KIND_MESH: return "meshes";
    case LK_FORMAT_KIND_POINTS: return "point sets";
    case LK_FORMAT_KIND_ANIMATION: return "animations";
    case LK_FORMAT_KIND_GRID: return "elevation grids";
    case LK_FORMAT_KIND_STREAM: return "progressive streams";
    }
    return "something else";
}

const char *lk_format_name(lk_format format)
{
    if (format == LK_FORMAT_AUTO) return "auto";
    for (size_t i = 0; i < FORMAT_COUNT; i++)
        if (formats[i].info.format == format && format != LK_FORMAT_UNKNOWN) return formats[i].info.name;
    return "unknown";
}

lk_format lk_format_from_path(const char *path)
{
    const format_row *row = row_from_path(path);
    return row ? row->info.format : LK_FORMAT_UNKNOWN;
}

static bool starts_with(const char *data, size_t size, const char *prefix)
{
    size_t n = strlen(prefix);
    return size >= n && memcmp(data, prefix, n) == 0;
}

/* True when every non-blank, non-comment line of the first few KiB holds 3
 * or 6 numbers (an XYZ point file). */
static bool looks_like_xyz(const char *data, size_t size)
{
    const char *p = data, *end = data + (size < 4096 ? size : 4096);
    int lines = 0;
    while (p < end) {
        const char *line_end = lk__skip_line(p, end);
        if (line_end == end && end != data + size) break; /* partial last line */
        const char *q = lk__skip_spaces(p, line_end);
        if (q < line_end && *q != '\n' && *q != '#') {
            int numbers = 0;
            double value;
            while (lk__parse_double(&q, line_end, &value)) numbers++;
            q = lk__skip_spaces(q, line_end);
            if (q < line_end && *q != '\n') return false;
            if (numbers != 3 && numbers != 6) return false;
            lines++;
        }
        p = line_end;
    }
    return lines > 0;
}

lk_format lk_format_sniff(const void *bytes, size_t size)
{
    const char *data = bytes;
    if (starts_with(data, size, "glTF")) return LK_FORMAT_GLTF;
    if (starts_with(data, size, "IDP2")) return LK_FORMAT_MD2;
    if (starts_with(data, size, "kmf 1")) return LK_FORMAT_KMF;
    /* LAS (and LAZ, which the LAS reader refuses with how to decompress it). */
    if (starts_with(data, size, "LASF")) return LK_FORMAT_LAS;
    /* PCD: PCL writes a "# .PCD" comment first; older files start at VERSION. */
    if (starts_with(data, size, "# .PCD") || starts_with(data, size, "VERSION")) return LK_FORMAT_PCD;
    if (starts_with(data, size, "ply\n") || starts_with(data, size, "ply\r\n")) return LK_FORMAT_PLY;
    /* OFF and its variants: [ST][C][N][4][n]OFF on the first line. */
    {
        size_t i = 0;
        while (i < size && i < 8 && data[i] && strchr("STCN4n", data[i])) i++;
        if (starts_with(data + i, size - i, "OFF")) return LK_FORMAT_OFF;
    }
    /* Binary STL: 80-byte header, uint32 count, 50 bytes per triangle. */
    if (size >= 84) {
        uint32_t count;
        memcpy(&count, data + 80, 4);
        if ((uint64_t)84 + (uint64_t)count * 50 == size) return LK_FORMAT_STL;
    }
    if (starts_with(data, size, "solid")) return LK_FORMAT_STL;
    const char *p = lk__skip_spaces(data, data + size);
    if (p < data + size && *p == '{') return LK_FORMAT_GLTF;
    if (looks_like_xyz(data, size)) return LK_FORMAT_XYZ;
    /* OBJ-like keywords at the start of a line. */
    const char *end = data + (size < 65536 ? size : 65536);
    for (p = data; p < end; p = lk__skip_line(p, end)) {
        const char *q = lk__skip_spaces(p, end);
        if (end - q >= 2 && (q[0] == 'v' || q[0] == 'f') && lk__is_space(q[1])) return LK_FORMAT_OBJ;
    }
    return LK_FORMAT_UNKNOWN;
}

/* lk_mesh_read's reader and lk_mesh_write's writer of a format, or NULL. */
static reader_fn reader_for(lk_format format)
{
    for (size_t i = 0; i < FORMAT_COUNT; i++)
        if (formats[i].info.format == format && formats[i].read_mesh) return formats[i].read_mesh;
    return NULL;
}

static const format_row *writer_for(lk_format format)
{
    for (size_t i = 0; i < FORMAT_COUNT; i++)
        if (formats[i].info.format == format && (formats[i].write_mesh || formats[i].write_mesh_at)) return &formats[i];
    return NULL;
}

/* For messages: every extension lk_mesh_read reads ("obj, ply, ... or
 * kmf"), or the usual extension of every format lk_mesh_write writes
 * (".obj .ply ... .stl"). */
static void mesh_extensions(bool writing, char *out, size_t size)
{
    char words[FORMAT_COUNT * 4][16];
    size_t count = 0;
    for (size_t i = 0; i < FORMAT_COUNT; i++) {
        if (writing ? !formats[i].write_mesh && !formats[i].write_mesh_at : !formats[i].read_mesh) continue;
        for (const char *word = formats[i].info.extensions; *word && count < FORMAT_COUNT * 4;) {
            size_t length = strcspn(word, " ");
            snprintf(words[count++], sizeof words[0], "%.*s", (int)length, word);
            word += length;
            if (*word == ' ') word++;
            if (writing) break;
        }
    }
    size_t used = 0;
    out[0] = '\0';
    for (size_t k = 0; k < count && used < size; k++) {
        const char *separator = k == 0 ? "" : writing ? " " : k + 1 == count ? " or " : ", ";
        int n = snprintf(out + used, size - used, "%s%s%s", separator, writing ? "." : "", words[k]);
        if (n < 0) break;
        used += (size_t)n;
    }
}

/* "NAME: .EXT files hold KINDS, not meshes" when the name's extension is a
 * format of another kind (a stream, a grid, ...); false otherwise. */
static bool refuse_other_kind(const char *name, lk_error *error)
{
    const format_row *row = row_from_path(name);
    if (!row || row->read_mesh) return false;
    lk_error_set(error, LK_ERR_UNSUPPORTED, "%s: .%s files hold %s, not meshes", name, extension_of(name),
                 kind_plural(row->info.kind));
    return true;
}

static size_t read_limit(const lk_read_options *options)
{
    return options && options->max_bytes ? options->max_bytes : LK_DEFAULT_MAX_BYTES;
}

/* `budget` holds the input's bytes already. */
static lk_status read_buffer(const char *data, size_t size, const char *name, const char *directory, lk_format format,
                             lk__budget *budget, lk_mesh *mesh, lk_error *error)
{
    lk_mesh_init(mesh);
    if (format == LK_FORMAT_AUTO) {
        format = lk_format_from_path(name);
        /* Extensions lie sometimes (binary STL named .stl starting with
         * "solid"); the readers handle those. Unknown extensions: sniff. */
        if (format == LK_FORMAT_UNKNOWN) format = lk_format_sniff(data, size);
    }
    if (size == 0) return lk_error_set(error, LK_ERR_PARSE, "%s: empty file", name);
    reader_fn reader = reader_for(format);
    if (!reader) {
        if (refuse_other_kind(name, error)) return LK_ERR_UNSUPPORTED;
        char expected[256];
        mesh_extensions(false, expected, sizeof expected);
        return lk_error_set(error, LK_ERR_UNSUPPORTED, "%s: unknown file format (expected %s)", name, expected);
    }
    lk__read_context ctx = {name, directory, budget};
    lk_status status = reader(data, size, &ctx, mesh, error);
    if (status != LK_OK) {
        lk_mesh_free(mesh);
        return status;
    }
    lk_error inner = {0};
    status = lk_mesh_validate(mesh, &inner);
    if (status != LK_OK) {
        lk_mesh_free(mesh);
        return lk_error_set(error, status, "%s: %s", name, inner.message);
    }
    return LK_OK;
}

lk_status lk_mesh_read_memory(const void *data, size_t size, const char *name, lk_format format,
                              const lk_read_options *options, lk_mesh *mesh, lk_error *error)
{
    if (!name) name = "<memory>";
    /* The caller's bytes are held while they are parsed, as a file's are. */
    lk__budget budget = {read_limit(options), 0};
    if (!lk__budget_charge(&budget, size, 1)) {
        lk_mesh_init(mesh);
        return lk__input_too_large(name, size, &budget, error);
    }
    return read_buffer(data, size, name, NULL, format, &budget, mesh, error);
}

lk_status lk__mesh_read_buffer(const void *data, size_t size, const char *name, const char *directory,
                               const lk_read_options *options, lk_mesh *mesh, lk_error *error)
{
    /* The caller's bytes are held while they are parsed, as a file's are. */
    lk__budget budget = {read_limit(options), 0};
    if (!lk__budget_charge(&budget, size, 1)) {
        lk_mesh_init(mesh);
        return lk__input_too_large(name, size, &budget, error);
    }
    return read_buffer(data, size, name, directory, LK_FORMAT_AUTO, &budget, mesh, error);
}

/* The folder of `path` (external references are read below it): "." for
 * a bare name, "/" for a file at the root; NULL when out of memory. */
static char *directory_of(const char *path)
{
    char *directory = malloc(strlen(path) + 2);
    if (!directory) return NULL;
    const char *slash = strrchr(path, '/');
    if (slash) {
        memcpy(directory, path, (size_t)(slash - path));
        directory[slash - path] = '\0';
        if (slash == path) strcpy(directory, "/");
    } else {
        strcpy(directory, ".");
    }
    return directory;
}

lk_status lk__mesh_read_charged(const char *path, lk_format format, lk__budget *budget, lk_mesh *mesh, lk_error *error)
{
    lk_mesh_init(mesh);
    /* The whole file is held in memory while it is parsed. */
    char *data;
    size_t size;
    lk_status status = lk__read_file_charged(path, budget, &data, &size, error);
    if (status != LK_OK) return status;
    /* Directory for external references (glTF buffers). */
    char *directory = directory_of(path);
    if (!directory) {
        free(data);
        lk__budget_release(budget, size, 1);
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    }
    status = read_buffer(data, size, path, directory, format, budget, mesh, error);
    free(directory);
    free(data);
    lk__budget_release(budget, size, 1);
    return status;
}

lk_status lk_mesh_read(const char *path, lk_format format, const lk_read_options *options, lk_mesh *mesh,
                       lk_error *error)
{
    lk__budget budget = {read_limit(options), 0};
    return lk__mesh_read_charged(path, format, &budget, mesh, error);
}

lk_status lk_mesh_write(const char *path, lk_format format, const lk_mesh *mesh, const lk_write_options *options,
                        lk_error *error)
{
    lk_write_options defaults = {0};
    if (!options) options = &defaults;
    if (format == LK_FORMAT_AUTO) format = lk_format_from_path(path);
    const format_row *writer = writer_for(format);
    if (!writer) {
        if (format == LK_FORMAT_MD2 || format == LK_FORMAT_KMF)
            return lk_error_set(error, LK_ERR_UNSUPPORTED,
                                "%s: %s holds animations: write it with lk_animation_write (a one-frame mesh "
                                "cannot be written as a mesh)",
                                path, lk_format_name(format));
        char usual[256];
        mesh_extensions(true, usual, sizeof usual);
        const format_row *row = row_from_path(path);
        if (row && format == LK_FORMAT_UNKNOWN)
            return lk_error_set(error, LK_ERR_UNSUPPORTED, "%s: .%s files hold %s, not meshes (use %s)", path,
                                extension_of(path), kind_plural(row->info.kind), usual);
        return lk_error_set(error, LK_ERR_UNSUPPORTED, "%s: cannot tell the output format from the extension (use %s)",
                            path, usual);
    }
    lk_error inner = {0};
    lk_status status = lk_mesh_validate(mesh, &inner);
    if (status != LK_OK)
        return lk_error_set(error, status, "%s: refusing to write an invalid mesh: %s", path, inner.message);
    lk__atomic_file out;
    status = lk__atomic_open(&out, path, error);
    if (status != LK_OK) return status;
    if (writer->write_mesh_at) {
        /* .glb by the extension (or a .glb row), else .gltf */
        const format_row *named = row_from_path(path);
        bool binary = named && named->info.format == LK_FORMAT_GLTF ? strcmp(named->info.name, "glb") == 0 : false;
        status = writer->write_mesh_at(out.file, path, binary, mesh, options, &inner);
    } else {
        status = writer->write_mesh(out.file, mesh, options, &inner);
    }
    if (status != LK_OK) {
        lk_error_set(error, status, "%s: %s", path, inner.message);
        return lk__atomic_fail(&out, error);
    }
    return lk__atomic_commit(&out, error);
}

lk_status lk_mesh_write_lods(const char *path, const lk_mesh *levels, size_t level_count, const lk_lod_level_info *info,
                             const lk_write_options *options, lk_error *error)
{
    lk_write_options defaults = {0};
    if (!options) options = &defaults;
    if (!path || (!levels && level_count))
        return lk_error_set(error, LK_ERR_INVALID, "lk_mesh_write_lods: NULL argument");
    if (level_count == 0) return lk_error_set(error, LK_ERR_INVALID, "%s: no levels of detail to write", path);
    const format_row *named = row_from_path(path);
    if (!named || named->info.format != LK_FORMAT_GLTF)
        return lk_error_set(error, LK_ERR_UNSUPPORTED,
                            "%s: levels of detail are written as glTF with MSFT_lod: name the output .glb or .gltf",
                            path);
    for (size_t level = 0; level < level_count; level++) {
        lk_error inner = {0};
        lk_status status = lk_mesh_validate(&levels[level], &inner);
        if (status != LK_OK)
            return lk_error_set(error, status, "%s: refusing to write an invalid level %zu: %s", path, level,
                                inner.message);
    }
    lk__atomic_file out;
    lk_status status = lk__atomic_open(&out, path, error);
    if (status != LK_OK) return status;
    lk_error inner = {0};
    status = lk__write_gltf_levels(out.file, path, strcmp(named->info.name, "glb") == 0, levels, level_count, info,
                                   options, &inner);
    if (status != LK_OK) {
        lk_error_set(error, status, "%s: %s", path, inner.message);
        return lk__atomic_fail(&out, error);
    }
    return lk__atomic_commit(&out, error);
}

/* ---- scenes ------------------------------------------------------------------ */

lk_status lk_scene_read(const char *path, const lk_read_options *options, lk_scene *scene, lk_error *error)
{
    if (!path || !scene) return lk_error_set(error, LK_ERR_INVALID, "lk_scene_read: NULL argument");
    lk_scene_init(scene);
    lk_format format = lk_format_from_path(path);
    if (format != LK_FORMAT_GLTF && format != LK_FORMAT_OBJ) {
        lk_mesh mesh;
        lk_status status = lk_mesh_read(path, LK_FORMAT_AUTO, options, &mesh, error);
        if (status != LK_OK) return status;
        status = lk_scene_from_mesh(scene, &mesh, error);
        lk_mesh_free(&mesh);
        return status;
    }
    lk__budget budget = {read_limit(options), 0};
    char *data;
    size_t size;
    lk_status status = lk__read_file_charged(path, &budget, &data, &size, error);
    if (status != LK_OK) return status;
    char *directory = directory_of(path);
    if (!directory) {
        free(data);
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    }
    lk__read_context ctx = {path, directory, &budget};
    status = format == LK_FORMAT_OBJ ? lk__read_obj_scene(data, size, &ctx, scene, error)
                                     : lk__read_gltf_scene(data, size, &ctx, scene, error);
    free(directory);
    free(data);
    return status;
}

lk_status lk_scene_read_memory(const void *data, size_t size, const char *name, const lk_read_options *options,
                               lk_scene *scene, lk_error *error)
{
    if ((!data && size) || !name || !scene)
        return lk_error_set(error, LK_ERR_INVALID, "lk_scene_read_memory: NULL argument");
    lk_scene_init(scene);
    lk_format format = lk_format_from_path(name);
    if (format != LK_FORMAT_GLTF && format != LK_FORMAT_OBJ) {
        lk_mesh mesh;
        lk_status status = lk_mesh_read_memory(data, size, name, LK_FORMAT_AUTO, options, &mesh, error);
        if (status != LK_OK) return status;
        status = lk_scene_from_mesh(scene, &mesh, error);
        lk_mesh_free(&mesh);
        return status;
    }
    lk__budget budget = {read_limit(options), 0};
    if (!lk__budget_charge(&budget, size, 1)) return lk__input_too_large(name, size, &budget, error);
    lk__read_context ctx = {name, NULL, &budget};
    return format == LK_FORMAT_OBJ ? lk__read_obj_scene(data, size, &ctx, scene, error)
                                   : lk__read_gltf_scene(data, size, &ctx, scene, error);
}

lk_status lk_scene_write(const char *path, const lk_scene *scene, const lk_write_options *options, lk_error *error)
{
    lk_write_options defaults = {0};
    if (!options) options = &defaults;
    if (!path || !scene) return lk_error_set(error, LK_ERR_INVALID, "lk_scene_write: NULL argument");
    const format_row *named = row_from_path(path);
    if (!named || named->info.format != LK_FORMAT_GLTF) {
        lk_mesh flat;
        lk_status status = lk_scene_flatten(scene, &flat, error);
        if (status != LK_OK) return status;
        status = lk_mesh_write(path, LK_FORMAT_AUTO, &flat, options, error);
        lk_mesh_free(&flat);
        return status;
    }
    for (size_t m = 0; m < scene->mesh_count; m++)
        for (size_t p = 0; p < scene->meshes[m].primitive_count; p++) {
            lk_error inner = {0};
            lk_status status = lk_mesh_validate(&scene->meshes[m].primitives[p].mesh, &inner);
            if (status != LK_OK)
                return lk_error_set(error, status, "%s: refusing to write an invalid meshes[%zu].primitives[%zu]: %s",
                                    path, m, p, inner.message);
        }
    lk__atomic_file out;
    lk_status status = lk__atomic_open(&out, path, error);
    if (status != LK_OK) return status;
    lk_error inner = {0};
    /* compact output: the animations without keys their neighbours give */
    lk_scene trimmed = *scene;
    trimmed.animations = NULL;
    if (options->gltf_flags & (LK_GLTF_QUANTIZE | LK_GLTF_MESHOPT))
        status = lk__scene_trimmed_animations(scene, &trimmed.animations, &inner);
    if (!trimmed.animations) trimmed.animations = scene->animations;
    if (status == LK_OK)
        status = lk__write_gltf_scene(out.file, path, strcmp(named->info.name, "glb") == 0, &trimmed, options, &inner);
    if (trimmed.animations != scene->animations) lk__scene_animations_free(trimmed.animations, scene->animation_count);
    if (status != LK_OK) {
        lk_error_set(error, status, "%s: %s", path, inner.message);
        return lk__atomic_fail(&out, error);
    }
    return lk__atomic_commit(&out, error);
}
