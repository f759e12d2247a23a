/* Helpers shared by the lodkit subcommands: messages, progress bars,
 * option parsing, loading. */
#include <cjson/cJSON.h>
#include <errno.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "cli.h"


const char *program = "lodkit";

/* ---- output helpers ---------------------------------------------------- */

/* Does MESSAGE start with PATH, as "PATH:" or "PATH/..." (a file in it)? */
static bool names_file(const char *message, const char *path)
{
    size_t length = path ? strlen(path) : 0;
    return length && strncmp(message, path, length) == 0 && (message[length] == ':' || message[length] == '/');
}

void print_error_for(const char *input, const char *output, const lk_error *error)
{
    const char *message = error->message[0] ? error->message : lk_status_string(error->status);
    /* Say how to raise a budget the library refused against. */
    bool budget = error->status == LK_ERR_LIMIT && strstr(message, "memory budget") && !strstr(message, "--max-memory");
    bool named = !input || names_file(message, input) || names_file(message, output);
    fprintf(stderr, "%s: %s%s%s%s\n", program, named ? "" : input, named ? "" : ": ", message,
            budget ? " (--max-memory)" : "");
}

void print_error(const lk_error *error) { print_error_for(NULL, NULL, error); }

int usage_error(const char *command, const char *format, const char *detail)
{
    fprintf(stderr, "%s%s%s: ", program, command ? " " : "", command ? command : "");
    fprintf(stderr, format, detail);
    fprintf(stderr, "\nTry '%s %s%s--help' for more information.\n", program, command ? command : "", command ? " " : "");
    if (command) fputc('\n', stderr);
    return EXIT_USAGE;
}

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

/* 1234567 -> "1,234,567" in a rotating static buffer. */
const char *thousands(unsigned long long value)
{
    static char slots[8][32];
    static int next;
    char *out = slots[next];
    next = (next + 1) % 8;
    char digits[32];
    int length = snprintf(digits, sizeof digits, "%llu", value);
    int o = 0;
    for (int i = 0; i < length; i++) {
        if (i > 0 && (length - i) % 3 == 0) out[o++] = ',';
        out[o++] = digits[i];
    }
    out[o] = '\0';
    return out;
}

void print_json(cJSON *root)
{
    char *text = cJSON_PrintUnformatted(root);
    if (text) {
        puts(text);
        free(text);
    }
    cJSON_Delete(root);
}

/* Progress bar on a terminal's stderr; silent otherwise or with --quiet. */

int progress_draw(void *user, double fraction, const char *stage)
{
    progress_state *state = user;
    if (!state->enabled) return 0;
    int permille = (int)(fraction * 1000);
    if (permille == state->last_permille) return 0;
    state->last_permille = permille;
    int filled = (int)(fraction * 30);
    fprintf(stderr, "\r%s %-10s [", state->label, stage ? stage : "");
    for (int i = 0; i < 30; i++) fputc(i < filled ? '#' : ' ', stderr);
    fprintf(stderr, "] %5.1f%%", fraction * 100);
    if (fraction >= 1.0) fprintf(stderr, "\r\033[K");
    fflush(stderr);
    return 0;
}

void progress_init(progress_state *state, int quiet, const char *label)
{
    state->enabled = !quiet && isatty(STDERR_FILENO);
    state->last_permille = -1;
    state->label = label;
}

void progress_done(progress_state *state)
{
    if (state->enabled && state->last_permille >= 0) fprintf(stderr, "\r\033[K");
}

int parse_double_option(const char *text, double *value)
{
    char *end;
    errno = 0;
    *value = strtod(text, &end);
    return errno == 0 && end != text && *end == '\0' && isfinite(*value);
}

int parse_size_option(const char *text, size_t *value)
{
    char *end;
    errno = 0;
    if (text[0] == '-') return 0;
    unsigned long long parsed = strtoull(text, &end, 10);
    if (errno || end == text || *end != '\0') return 0;
    *value = (size_t)parsed;
    return 1;
}

/* Parses "x,y,z" into three doubles. */
int parse_vector3(const char *text, double out[3])
{
    char *end;
    const char *p = text;
    for (int k = 0; k < 3; k++) {
        errno = 0;
        out[k] = strtod(p, &end);
        if (errno || end == p || !isfinite(out[k])) return 0;
        if (k < 2) {
            if (*end != ',') return 0;
            p = end + 1;
        }
    }
    return *end == '\0';
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
    case 'k': case 'K': shift = 10; end++; break;
    case 'm': case 'M': shift = 20; end++; break;
    case 'g': case 'G': shift = 30; end++; break;
    case 't': case 'T': shift = 40; end++; break;
    default: break;
    }
    if (shift && (*end == 'i' || *end == 'I') && (end[1] == 'b' || end[1] == 'B')) end += 2;
    else if (*end == 'b' || *end == 'B') end++;
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

lk_status load_mesh(const char *path, lk_mesh *mesh, double *seconds, lk_error *error)
{
    double start = now_seconds();
    lk_read_options options = {cli_max_memory};
    lk_status status = lk_mesh_read(path, LK_FORMAT_AUTO, &options, mesh, error);
    if (seconds) *seconds = now_seconds() - start;
    return status;
}

/* Output format for commands that produce triangles: LK_FORMAT_UNKNOWN when
 * the extension names no writable triangle format (glTF is read-only, XYZ
 * holds points only). */
lk_format triangle_output_format(const char *path)
{
    lk_format format = lk_format_from_path(path);
    return format == LK_FORMAT_GLTF || format == LK_FORMAT_XYZ ? LK_FORMAT_UNKNOWN : format;
}

cJSON *distance_json(const lk_distance_stats *stats)
{
    cJSON *object = cJSON_CreateObject();
    cJSON_AddNumberToObject(object, "max", stats->max);
    cJSON_AddNumberToObject(object, "mean", stats->mean);
    cJSON_AddNumberToObject(object, "rms", stats->rms);
    cJSON_AddNumberToObject(object, "samples", (double)stats->sample_count);
    return object;
}

/* ---- pictures ---------------------------------------------------------- */

/* "800x600" -> 800, 600 (each 1..8192). */
int parse_image_size(const char *text, unsigned *width, unsigned *height)
{
    char *end;
    errno = 0;
    if (text[0] < '0' || text[0] > '9') return 0;
    unsigned long w = strtoul(text, &end, 10);
    if (errno || (*end != 'x' && *end != 'X')) return 0;
    const char *rest = end + 1;
    if (rest[0] < '0' || rest[0] > '9') return 0;
    unsigned long h = strtoul(rest, &end, 10);
    if (errno || *end != '\0' || w < 1 || h < 1 || w > 8192 || h > 8192) return 0;
    *width = (unsigned)w;
    *height = (unsigned)h;
    return 1;
}

int parse_view_option(const char *text, lk_render_options *options)
{
    double view[3];
    if (!parse_vector3(text, view) || view[2] < 0) return 0;
    options->azimuth = view[0];
    options->elevation = view[1];
    options->distance = view[2];
    return 1;
}

lk_status render_to_png(const lk_mesh *mesh, int points, unsigned width, unsigned height,
                        const lk_render_options *options, const char *path, lk_render_stats *stats,
                        char *renderer_name, size_t renderer_name_size, lk_error *error)
{
    lk_renderer *renderer = NULL;
    unsigned char *pixels = NULL;
    lk_status status = lk_renderer_create(width, height, &renderer, error);
    if (status == LK_OK && renderer_name)
        snprintf(renderer_name, renderer_name_size, "%s", lk_renderer_description(renderer));
    if (status == LK_OK)
        status = points ? lk_render_points(renderer, mesh, options, stats, error)
                        : lk_render_mesh(renderer, mesh, options, stats, error);
    if (status == LK_OK) {
        pixels = malloc_array((size_t)width * height, 4);
        if (!pixels) status = lk_error_set(error, LK_ERR_NOMEM, "out of memory for a %ux%u image", width, height);
    }
    if (status == LK_OK) status = lk_renderer_read_pixels(renderer, pixels, error);
    if (status == LK_OK) status = lk_image_write_png(path, pixels, width, height, error);
    free(pixels);
    lk_renderer_free(renderer);
    return status;
}
