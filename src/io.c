/* Format detection and the read/write entry points; the formats themselves
 * live in io_<format>.c. */
#include "internal.h"
#include "anim_io.h"

#include <stdlib.h>
#include <string.h>

#define LK_DEFAULT_MAX_BYTES ((size_t)8 << 30)

const char *lk_format_name(lk_format format)
{
    switch (format) {
    case LK_FORMAT_AUTO: return "auto";
    case LK_FORMAT_OBJ: return "obj";
    case LK_FORMAT_PLY: return "ply";
    case LK_FORMAT_OFF: return "off";
    case LK_FORMAT_SMF: return "smf";
    case LK_FORMAT_XYZ: return "xyz";
    case LK_FORMAT_STL: return "stl";
    case LK_FORMAT_GLTF: return "gltf";
    case LK_FORMAT_MD2: return "md2";
    case LK_FORMAT_KMF: return "kmf";
    case LK_FORMAT_UNKNOWN: break;
    }
    return "unknown";
}

lk_format lk_format_from_path(const char *path)
{
    const char *slash = strrchr(path, '/');
    const char *base = slash ? slash + 1 : path;
    const char *dot = strrchr(base, '.');
    if (!dot || !dot[1]) return LK_FORMAT_UNKNOWN;
    const char *ext = dot + 1;
    size_t len = strlen(ext);
    static const struct { const char *ext; lk_format format; } table[] = {
        {"obj", LK_FORMAT_OBJ}, {"ply", LK_FORMAT_PLY}, {"off", LK_FORMAT_OFF},
        {"smf", LK_FORMAT_SMF}, {"xyz", LK_FORMAT_XYZ}, {"xyzn", LK_FORMAT_XYZ},
        {"pts", LK_FORMAT_XYZ}, {"stl", LK_FORMAT_STL}, {"gltf", LK_FORMAT_GLTF},
        {"glb", LK_FORMAT_GLTF}, {"md2", LK_FORMAT_MD2}, {"kmf", LK_FORMAT_KMF},
    };
    for (size_t i = 0; i < sizeof table / sizeof table[0]; i++)
        if (lk__word_equals(ext, len, table[i].ext)) return table[i].format;
    return LK_FORMAT_UNKNOWN;
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

typedef lk_status (*reader_fn)(const char *, size_t, const lk__read_context *, lk_mesh *, lk_error *);

static reader_fn reader_for(lk_format format)
{
    switch (format) {
    case LK_FORMAT_OBJ: return lk__read_obj;
    case LK_FORMAT_PLY: return lk__read_ply;
    case LK_FORMAT_OFF: return lk__read_off;
    case LK_FORMAT_SMF: return lk__read_smf;
    case LK_FORMAT_XYZ: return lk__read_xyz;
    case LK_FORMAT_STL: return lk__read_stl;
    case LK_FORMAT_GLTF: return lk__read_gltf;
    case LK_FORMAT_MD2: return lk__read_md2;
    case LK_FORMAT_KMF: return lk__read_kmf;
    default: return NULL;
    }
}

static size_t read_limit(const lk_read_options *options)
{
    return options && options->max_bytes ? options->max_bytes : LK_DEFAULT_MAX_BYTES;
}

/* `budget` holds the input's bytes already. */
static lk_status read_buffer(const char *data, size_t size, const char *name, const char *directory,
                             lk_format format, lk__budget *budget, lk_mesh *mesh, lk_error *error)
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
    if (!reader)
        return lk_error_set(error, LK_ERR_UNSUPPORTED,
                            "%s: unknown file format (expected obj, ply, off, smf, xyz, stl, gltf, glb, md2 or kmf)", name);
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

lk_status lk__mesh_read_charged(const char *path, lk_format format, lk__budget *budget, lk_mesh *mesh,
                                lk_error *error)
{
    lk_mesh_init(mesh);
    /* The whole file is held in memory while it is parsed. */
    char *data;
    size_t size;
    lk_status status = lk__read_file_charged(path, budget, &data, &size, error);
    if (status != LK_OK) return status;
    /* Directory for external references (glTF buffers). */
    char *directory = malloc(strlen(path) + 2);
    if (!directory) {
        free(data);
        lk__budget_release(budget, size, 1);
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    }
    const char *slash = strrchr(path, '/');
    if (slash) {
        memcpy(directory, path, (size_t)(slash - path));
        directory[slash - path] = '\0';
        if (slash == path) strcpy(directory, "/");
    } else {
        strcpy(directory, ".");
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
    lk_status (*writer)(FILE *, const lk_mesh *, const lk_write_options *, lk_error *) = NULL;
    switch (format) {
    case LK_FORMAT_OBJ: writer = lk__write_obj; break;
    case LK_FORMAT_PLY: writer = lk__write_ply; break;
    case LK_FORMAT_OFF: writer = lk__write_off; break;
    case LK_FORMAT_SMF: writer = lk__write_smf; break;
    case LK_FORMAT_XYZ: writer = lk__write_xyz; break;
    case LK_FORMAT_STL: writer = lk__write_stl; break;
    case LK_FORMAT_GLTF:
        return lk_error_set(error, LK_ERR_UNSUPPORTED, "%s: writing glTF is not supported (read only)", path);
    case LK_FORMAT_MD2:
    case LK_FORMAT_KMF:
        return lk_error_set(error, LK_ERR_UNSUPPORTED,
                            "%s: %s holds animations: write it with lk_animation_write (a one-frame mesh "
                            "cannot be written as a mesh)", path, lk_format_name(format));
    default:
        return lk_error_set(error, LK_ERR_UNSUPPORTED,
                            "%s: cannot tell the output format from the extension (use .obj .ply .off .smf .xyz .stl)",
                            path);
    }
    lk_error inner = {0};
    lk_status status = lk_mesh_validate(mesh, &inner);
    if (status != LK_OK) return lk_error_set(error, status, "%s: refusing to write an invalid mesh: %s", path, inner.message);
    lk__atomic_file out;
    status = lk__atomic_open(&out, path, error);
    if (status != LK_OK) return status;
    status = writer(out.file, mesh, options, &inner);
    if (status != LK_OK) {
        lk_error_set(error, status, "%s: %s", path, inner.message);
        return lk__atomic_fail(&out, error);
    }
    return lk__atomic_commit(&out, error);
}
