/* SPDX-License-Identifier: MIT */
/* Inputs: the memory budget (--max-memory), reading meshes and files
 * within it, --weld, the file formats the commands read and write, and
 * checked allocation and timing for the commands. */
#include <errno.h>
#include <fcntl.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cli.h"

void *malloc_array(size_t count, size_t size)
{
    if (size && count > SIZE_MAX / size) return NULL;
    return malloc(count && size ? count * size : 1);
}

void *calloc_array(size_t count, size_t size)
{
    if (size && count > SIZE_MAX / size) return NULL;
    return count && size ? calloc(count, size) : calloc(1, 1);
}

double now_seconds(void)
{
    struct timespec now;
    clock_gettime(CLOCK_MONOTONIC, &now);
    return (double)now.tv_sec + (double)now.tv_nsec * 1e-9;
}

/* ---- memory budget ------------------------------------------------------ */

size_t cli_max_memory = (size_t)8 << 30;

size_t cli_default_max_memory(void)
{
    size_t budget = (size_t)8 << 30;
    long pages = sysconf(_SC_PHYS_PAGES), page_size = sysconf(_SC_PAGESIZE);
    if (pages > 0 && page_size > 0) {
        unsigned long long half = (unsigned long long)pages * (unsigned long long)page_size / 2;
        if (half < budget) budget = (size_t)half;
    }
    return budget;
}

int parse_memory_size(const char *text, size_t *bytes)
{
    if (!text || text[0] < '0' || text[0] > '9') return 0;
    char *end;
    errno = 0;
    unsigned long long value = strtoull(text, &end, 10);
    if (errno) return 0;
    unsigned shift = 0;
    switch (*end) {
    case 'k':
    case 'K':
        shift = 10;
        end++;
        break;
    case 'm':
    case 'M':
        shift = 20;
        end++;
        break;
    case 'g':
    case 'G':
        shift = 30;
        end++;
        break;
    case 't':
    case 'T':
        shift = 40;
        end++;
        break;
    default: break;
    }
    if (shift && (*end == 'i' || *end == 'I') && (end[1] == 'b' || end[1] == 'B'))
        end += 2;
    else if (*end == 'b' || *end == 'B')
        end++;
    if (*end != '\0' || value == 0) return 0;
    if (value > (unsigned long long)SIZE_MAX >> shift) return 0;
    *bytes = (size_t)(value << shift);
    return 1;
}

int cli_take_global_options(int *argc, char **argv)
{
    const char *given = NULL;
    int out = 1;
    bool after_dashes = false;
    for (int i = 1; i < *argc; i++) {
        const char *arg = argv[i];
        if (!after_dashes && strcmp(arg, "--") == 0) after_dashes = true;
        if (!after_dashes && strcmp(arg, "--max-memory") == 0) {
            if (i + 1 >= *argc) return usage_error(NULL, "%s", "--max-memory needs a SIZE (e.g. 512M or 2G)");
            given = argv[++i];
            continue;
        }
        if (!after_dashes && strncmp(arg, "--max-memory=", 13) == 0) {
            given = arg + 13;
            continue;
        }
        argv[out++] = argv[i];
    }
    argv[out] = NULL;
    *argc = out;
    if (given) {
        if (!parse_memory_size(given, &cli_max_memory))
            return usage_error(NULL, "--max-memory: '%s' is not a size such as 1048576, 512K, 64M or 2G", given);
        return -1;
    }
    const char *environment = getenv("LODKIT_MAX_MEMORY");
    if (environment && environment[0]) {
        if (!parse_memory_size(environment, &cli_max_memory))
            return usage_error(NULL, "LODKIT_MAX_MEMORY: '%s' is not a size such as 1048576, 512K, 64M or 2G",
                               environment);
        return -1;
    }
    cli_max_memory = cli_default_max_memory();
    return -1;
}

lk_status read_input_file(const char *path, unsigned char **data, size_t *size, lk_error *error)
{
    return lk_file_read(path, cli_max_memory, data, size, error);
}

int cli_weld = 0;
double cli_weld_tolerance = 0;

/* The first bytes of every .lks stream (docs/stream-format.md). */
static const unsigned char stream_magic[8] = {0x89, 'L', 'K', 'S', '\r', '\n', 0x1a, '\n'};

static int is_stream(const char *path)
{
    const lk_format_info *info = lk_format_info_from_path(path);
    if (info && info->kind == LK_FORMAT_KIND_STREAM) return 1;
    unsigned char head[8] = {0};
    FILE *file = fopen(path, "rb");
    size_t got = file ? fread(head, 1, sizeof head, file) : 0;
    if (file) fclose(file);
    return got == sizeof head && memcmp(head, stream_magic, sizeof head) == 0;
}

int looks_like_grid(const char *path)
{
    /* The grid readers check the size a grid claims before they read its
     * samples: with room for 4 samples, any real grid stops there (or is
     * read, if it is 2x2), cheaply. */
    lk_dem_options options;
    lk_dem_options_default(&options);
    options.max_samples = 4;
    lk_heightfield field;
    lk_error error = {0};
    lk_status status = lk_dem_read(path, &options, &field, &error);
    if (status == LK_OK) lk_heightfield_free(&field);
    return status == LK_OK || status == LK_ERR_LIMIT;
}

lk_status load_mesh(const char *path, lk_mesh *mesh, double *seconds, size_t *welded, lk_error *error)
{
    double start = now_seconds();
    lk_read_options options = {.max_bytes = cli_max_memory};
    lk_status status = lk_mesh_read(path, LK_FORMAT_AUTO, &options, mesh, error);
    /* Files no mesh reader knows may still be lodkit's: say which command reads them. */
    if (status == LK_ERR_UNSUPPORTED && lk_format_from_path(path) == LK_FORMAT_UNKNOWN) {
        if (is_stream(path))
            status = lk_error_set(error, LK_ERR_UNSUPPORTED,
                                  "%s: a progressive stream, not a mesh: 'lodkit inspect' describes it and "
                                  "'lodkit unpack' decodes a level of it into a mesh",
                                  path);
        else if (looks_like_grid(path))
            status = lk_error_set(error, LK_ERR_UNSUPPORTED,
                                  "%s: an elevation grid, not a mesh: 'lodkit info' describes it and "
                                  "'lodkit terrain' flies over it",
                                  path);
    }
    size_t merged = 0;
    if (status == LK_OK && cli_weld) status = lk_mesh_weld(mesh, cli_weld_tolerance, &merged, error);
    if (welded) *welded = merged;
    if (seconds) *seconds = now_seconds() - start;
    return status;
}

/* ---- file formats ----------------------------------------------------------
 * The commands' help texts and messages take the format lists from the
 * library's format table (lk_format_info_at), so a format added there is
 * named everywhere without a list here. */
int format_in_list(const lk_format_info *info, cli_format_list list)
{
    switch (list) {
    case FORMATS_MESH_READ: return (info->read & LK_IO_MESH) != 0;
    case FORMATS_MESH_WRITE: return (info->write & LK_IO_MESH) != 0;
    case FORMATS_TRIANGLE_WRITE: return (info->write & LK_IO_MESH) && info->kind != LK_FORMAT_KIND_POINTS;
    case FORMATS_ANIMATION_READ: return (info->read & LK_IO_ANIMATION) != 0;
    case FORMATS_GRID: return (info->read & LK_IO_GRID) != 0;
    }
    return 0;
}

const char *format_list(cli_format_list list, int dotted)
{
    static char text[1024];
    size_t count = 0, used = 0, written = 0;
    const lk_format_info *info;
    for (size_t i = 0; (info = lk_format_info_at(i)); i++)
        if (format_in_list(info, list))
            for (const char *word = info->extensions; *word; word += strspn(word, " ")) {
                word += strcspn(word, " ");
                count++;
            }
    text[0] = '\0';
    for (size_t i = 0; (info = lk_format_info_at(i)); i++) {
        if (!format_in_list(info, list)) continue;
        for (const char *word = info->extensions; *word;) {
            int length = (int)strcspn(word, " ");
            int is_last = dotted && written + 1 == count && written > 0;
            int n = snprintf(text + used, sizeof text - used, "%s%s%s%.*s", written ? " " : "", is_last ? "or " : "",
                             dotted ? "." : "", length, word);
            if (n < 0 || (size_t)n >= sizeof text - used) return text; /* cannot happen: a few dozen words */
            used += (size_t)n;
            written++;
            word += length;
            word += strspn(word, " ");
        }
    }
    return text;
}

lk_format output_mesh_format(const char *command, const char *path, int points_too)
{
    const lk_format_info *info = lk_format_info_from_path(path);
    char message[1200];
    if (info && info->kind == LK_FORMAT_KIND_ANIMATION && (info->write & LK_IO_ANIMATION)) {
        snprintf(message, sizeof message,
                 "cannot write '%s': %s holds animations, which 'lodkit animate' simplifies and writes; %s writes %s",
                 path, info->name, command, format_list(points_too ? FORMATS_MESH_WRITE : FORMATS_TRIANGLE_WRITE, 1));
        usage_error(command, "%s", message);
        return LK_FORMAT_UNKNOWN;
    }
    if (!info || !format_in_list(info, points_too ? FORMATS_MESH_WRITE : FORMATS_TRIANGLE_WRITE)) {
        if (points_too)
            snprintf(message, sizeof message, "cannot write '%s': use %s", path, format_list(FORMATS_MESH_WRITE, 1));
        else
            snprintf(message, sizeof message, "cannot write a mesh to '%s': use %s", path,
                     format_list(FORMATS_TRIANGLE_WRITE, 1));
        usage_error(command, "%s", message);
        return LK_FORMAT_UNKNOWN;
    }
    return info->format;
}

int is_gltf_path(const char *path) { return lk_format_from_path(path) == LK_FORMAT_GLTF; }

lk_status load_scene(const char *path, lk_scene *scene, lk_error *error)
{
    lk_read_options options = {.max_bytes = cli_max_memory};
    return lk_scene_read(path, &options, scene, error);
}

/* Whether a line of the OBJ file starts with `usemtl` (read in chunks: a
 * file without materials is read as a mesh, as before). */
static int obj_uses_materials(const char *path)
{
    /* Regular files only, opened without blocking (a FIFO, /dev/zero): the
     * reader refuses the others with a message. */
    struct stat info;
    if (stat(path, &info) != 0 || !S_ISREG(info.st_mode)) return 0;
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
    if (fd < 0) return 0;
    if (fstat(fd, &info) != 0 || !S_ISREG(info.st_mode)) {
        close(fd);
        return 0;
    }
    FILE *file = fdopen(fd, "rb");
    if (!file) {
        close(fd);
        return 0;
    }
    static const char keyword[] = "usemtl";
    unsigned char chunk[65536];
    int matched = 0, found = 0; /* characters of keyword matched at the start of the line; -1: none */
    size_t length, offset = 0;
    while (!found && (length = fread(chunk, 1, sizeof chunk, file)) > 0) {
        size_t i = 0;
        if (offset == 0 && length >= 3 && memcmp(chunk, "\xEF\xBB\xBF", 3) == 0) i = 3; /* byte order mark */
        offset += length;
        for (; i < length && !found; i++) {
            unsigned char c = chunk[i];
            if (matched < 0) {
                const unsigned char *newline = memchr(chunk + i, '\n', length - i);
                if (!newline) break;
                i = (size_t)(newline - chunk);
                matched = 0;
            } else if (c == '\n') {
                found = matched == 6;
                matched = 0;
            } else if (matched == 6) {
                found = c == ' ' || c == '\t' || c == '\r';
                matched = -1;
            } else if (c == (unsigned char)keyword[matched]) {
                matched++;
            } else if (!(matched == 0 && (c == ' ' || c == '\t' || c == '\r'))) {
                matched = -1;
            }
        }
    }
    fclose(file);
    return found || matched == 6;
}

int reads_as_scene(const char *path)
{
    lk_format format = lk_format_from_path(path);
    return format == LK_FORMAT_GLTF || (format == LK_FORMAT_OBJ && obj_uses_materials(path));
}

void print_scene_notes(const lk_scene *scene)
{
    for (const char *line = scene->notes; line && *line;) {
        const char *end = strchr(line, '\n');
        int length = end ? (int)(end - line) : (int)strlen(line);
        printf("note: %.*s\n", length, line);
        line += length + (end ? 1 : 0);
    }
}

const char *scene_summary(const lk_scene *scene)
{
    static char text[384];
    size_t primitives = 0, vertices = 0, lines = 0;
    for (size_t m = 0; m < scene->mesh_count; m++) {
        primitives += scene->meshes[m].primitive_count;
        for (size_t p = 0; p < scene->meshes[m].primitive_count; p++) {
            vertices += scene->meshes[m].primitives[p].mesh.vertex_count;
            lines += scene->meshes[m].primitives[p].line_count;
        }
    }
    char part[4][64];
    snprintf(part[0], sizeof part[0], "%s", count_noun(scene->node_count, "node", "nodes"));
    snprintf(part[1], sizeof part[1], "%s", count_noun(primitives, "primitive", "primitives"));
    snprintf(part[2], sizeof part[2], "%s", count_noun(scene->material_count, "material", "materials"));
    snprintf(part[3], sizeof part[3], "%s", count_noun(scene->texture_count, "texture", "textures"));
    int length = snprintf(text, sizeof text, "%s, %s, %s, %s, %s, %s", part[0], part[1], n_vertices(vertices),
                          n_triangles(lk_scene_triangle_count(scene)), part[2], part[3]);
    if (lines && length > 0 && (size_t)length < sizeof text)
        length += snprintf(text + length, sizeof text - (size_t)length, ", %s", count_noun(lines, "line", "lines"));
    if (scene->skin_count && length > 0 && (size_t)length < sizeof text)
        length += snprintf(text + length, sizeof text - (size_t)length, ", %s",
                           count_noun(scene->skin_count, "skin", "skins"));
    size_t targets = 0;
    for (size_t m = 0; m < scene->mesh_count; m++) targets += scene->meshes[m].target_count;
    if (targets && length > 0 && (size_t)length < sizeof text)
        length += snprintf(text + length, sizeof text - (size_t)length, ", %s",
                           count_noun(targets, "morph target", "morph targets"));
    if (scene->animation_count && length > 0 && (size_t)length < sizeof text)
        snprintf(text + length, sizeof text - (size_t)length, ", %s",
                 count_noun(scene->animation_count, "animation", "animations"));
    return text;
}
