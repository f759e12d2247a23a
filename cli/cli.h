/* Shared by the lodkit commands (the files in cli/). */
#ifndef LODKIT_CLI_H
#define LODKIT_CLI_H

#include <cjson/cJSON.h>

#include "lodkit.h"

enum { EXIT_OK = 0, EXIT_BAD_INPUT = 1, EXIT_USAGE = 2 };

extern const char *program;

/* "lodkit: message" on stderr. */
void print_error(const lk_error *error);
/* The same for an error met while a command works on INPUT (and writes
 * OUTPUT, may be NULL): every message names its file. The library's readers
 * and writers start their messages with the path they were given; messages
 * of the algorithms (a mesh in memory has no name) get "INPUT: " in front. */
void print_error_for(const char *input, const char *output, const lk_error *error);
/* Prints "lodkit COMMAND: <format with detail>" and a hint; returns EXIT_USAGE. */
int usage_error(const char *command, const char *format, const char *detail);
/* malloc/calloc of count * size bytes; NULL when that overflows or the
 * allocation fails (count 0 gives a valid 1-byte block). */
void *malloc_array(size_t count, size_t size);
void *calloc_array(size_t count, size_t size);
/* Monotonic wall clock in seconds, for timings. */
double now_seconds(void);
/* 1234567 -> "1,234,567" in a rotating static buffer (8 slots). */
const char *thousands(unsigned long long value);
/* Prints the JSON on one line and deletes it. */
void print_json(cJSON *root);

/* Progress bar on a terminal's stderr; silent otherwise or with --quiet. */
typedef struct progress_state {
    int enabled;
    int last_permille;
    const char *label;
} progress_state;
int progress_draw(void *user, double fraction, const char *stage); /* an lk_progress_fn */
void progress_init(progress_state *state, int quiet, const char *label);
void progress_done(progress_state *state);

/* Strict parsers: the whole text must be a finite number / a non-negative integer / "x,y,z". */
int parse_double_option(const char *text, double *value);
int parse_size_option(const char *text, size_t *value);
int parse_vector3(const char *text, double out[3]);

/* ---- memory budget (--max-memory SIZE, env LODKIT_MAX_MEMORY) ----------
 * The budget for what lodkit allocates for input data (mesh arrays,
 * animation frames, DEM samples, decoded streams, glTF buffers, and the
 * bytes of the input files themselves). Set by main before a command
 * runs; every reader call of the CLI passes it on. */
extern size_t cli_max_memory;
/* min(8 GiB, half the physical memory). */
size_t cli_default_max_memory(void);
/* "1048576", "512K", "64M", "2G", "1T" (binary multiples, case-insensitive,
 * optional trailing "B" or "iB"); > 0. Returns 0 when malformed. */
int parse_memory_size(const char *text, size_t *bytes);
/* Takes --max-memory SIZE / --max-memory=SIZE out of argv (anywhere before
 * a "--"), then applies LODKIT_MAX_MEMORY or the default when the option is
 * absent. Returns -1 on success, else the exit code of a usage error. */
int cli_take_global_options(int *argc, char **argv);
/* The line every --help shows. */
#define CLI_MEMORY_HELP                                                                                             \
    "      --max-memory=SIZE  memory budget for input data, e.g. 512M or 2G (default: min(8G, half the RAM);\n"    \
    "                         env LODKIT_MAX_MEMORY); inputs that need more are refused\n"
/* Reads a whole input file after checking its size against cli_max_memory. */
lk_status read_input_file(const char *path, unsigned char **data, size_t *size, lk_error *error);

lk_status load_mesh(const char *path, lk_mesh *mesh, double *seconds, lk_error *error);
/* LK_FORMAT_UNKNOWN when the extension names no writable triangle format. */
lk_format triangle_output_format(const char *path);
cJSON *distance_json(const lk_distance_stats *stats);

/* "800x600" -> 800, 600 (each 1..8192); 0 when malformed. */
int parse_image_size(const char *text, unsigned *width, unsigned *height);
/* "azimuth,elevation,distance" (degrees, degrees, radii >= 0) into options. */
int parse_view_option(const char *text, lk_render_options *options);
/* Offscreen render of a mesh (or, with points set, a point set) written to
 * path as PNG; renderer_name (may be NULL) receives the GL renderer. */
lk_status render_to_png(const lk_mesh *mesh, int points, unsigned width, unsigned height,
                        const lk_render_options *options, const char *path, lk_render_stats *stats,
                        char *renderer_name, size_t renderer_name_size, lk_error *error);

/* The commands, one per cmd_NAME.c. */
int command_info(int argc, char **argv);
int command_convert(int argc, char **argv);
int command_metro(int argc, char **argv);
int command_simplify(int argc, char **argv);
int command_subdivide(int argc, char **argv);
int command_progressive(int argc, char **argv);
int command_unpack(int argc, char **argv);
int command_inspect(int argc, char **argv);
int command_render(int argc, char **argv);
int command_splat(int argc, char **argv);
int command_sample(int argc, char **argv);
int command_terrain(int argc, char **argv);
int command_slices(int argc, char **argv);
int command_animate(int argc, char **argv);
int command_serve(int argc, char **argv);

#endif
