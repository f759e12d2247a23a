/* SPDX-License-Identifier: MIT */
/* Shared by the lodkit commands (the files in cli/): the command table, the
 * option declarations and their parser, and the helpers every command uses
 * (errors, progress, JSON, inputs, pictures). Only the public API
 * (lodkit.h) lies beneath. */
#ifndef LODKIT_CLI_H
#define LODKIT_CLI_H

#include <cjson/cJSON.h>
#include <getopt.h> /* optind: the operands follow the options */
#include <stdio.h>

#include "lodkit.h"

enum { EXIT_OK = 0, EXIT_BAD_INPUT = 1, EXIT_USAGE = 2 };

extern const char *program;

/* ---- commands (main.c) --------------------------------------------------- */

/* In the order of `lodkit --help`. CMD_MAIN is `lodkit` itself (its
 * options: --help, --version, --max-memory). */
typedef enum cli_command_id {
    CMD_INFO,
    CMD_CONVERT,
    CMD_METRO,
    CMD_SIMPLIFY,
    CMD_LOD,
    CMD_SUBDIVIDE,
    CMD_PROGRESSIVE,
    CMD_UNPACK,
    CMD_INSPECT,
    CMD_RENDER,
    CMD_SAMPLE,
    CMD_SPLAT,
    CMD_OCTREE,
    CMD_TERRAIN,
    CMD_SLICES,
    CMD_ANIMATE,
    CMD_SERVE,
    CMD_FORMATS,
    CMD_MAIN,
    CMD_COUNT
} cli_command_id;

/* What `lodkit NAME --help` says besides the options. */
typedef struct cli_help {
    const char *operands;    /* the usage line after "[options]", e.g. "IN OUT" */
    const char *description; /* above the options (lines end in \n) */
    const char *notes;       /* below them, or NULL */
} cli_help;

typedef struct cli_command {
    const char *name;
    const char *summary; /* its line in `lodkit --help` */
    int (*run)(int argc, char **argv);
    const cli_help *help; /* in cmd_NAME.c */
} cli_command;

extern const cli_command cli_commands[CMD_COUNT];

int cmd_info(int argc, char **argv);
int cmd_convert(int argc, char **argv);
int cmd_metro(int argc, char **argv);
int cmd_simplify(int argc, char **argv);
int cmd_lod(int argc, char **argv);
int cmd_subdivide(int argc, char **argv);
int cmd_progressive(int argc, char **argv);
int cmd_unpack(int argc, char **argv);
int cmd_inspect(int argc, char **argv);
int cmd_render(int argc, char **argv);
int cmd_sample(int argc, char **argv);
int cmd_splat(int argc, char **argv);
int cmd_octree(int argc, char **argv);
int cmd_terrain(int argc, char **argv);
int cmd_slices(int argc, char **argv);
int cmd_animate(int argc, char **argv);
int cmd_serve(int argc, char **argv);
int cmd_formats(int argc, char **argv);
extern const cli_help info_help, convert_help, metro_help, simplify_help, lod_help, subdivide_help, progressive_help,
    unpack_help, inspect_help, render_help, sample_help, splat_help, octree_help, terrain_help, slices_help,
    animate_help, serve_help, formats_help, main_help;

/* ---- options (cli_options.c) ------------------------------------------------
 * Every option is declared once, in cli_options.c: long name, short letter,
 * argument name, help text, and the commands that take it. The getopt_long
 * tables and every --help are generated from that table, so a letter or a
 * name means one thing in every command. In the order of the help texts. */
typedef enum cli_option_id {
    OPT_OUTPUT,
    OPT_METHOD,
    OPT_SCHEME,
    /* what to keep */
    OPT_RATIO,
    OPT_TRIANGLES,
    OPT_VERTICES,
    OPT_MAX_ERROR,
    OPT_CELL_SIZE,
    OPT_LEVEL,
    OPT_LEVELS,
    OPT_SEPARATE,
    OPT_BYTES,
    OPT_FRAME,
    OPT_POINTS,
    OPT_POISSON,
    OPT_ITERATIONS,
    /* progressive meshes and QEM */
    OPT_BASE_RATIO,
    OPT_BASE_TRIANGLES,
    OPT_PLACEMENT,
    OPT_COLLAPSE_ORDER,
    OPT_PAIR_DISTANCE,
    OPT_FEATURE_ANGLE,
    OPT_FEATURE_WEIGHT,
    OPT_NO_FEATURES,
    OPT_LOCK_BORDER,
    OPT_ATTRIBUTES,
    /* wavelets and slices */
    OPT_SLICES,
    OPT_AXIS,
    OPT_CRITERION,
    OPT_NO_REFINE,
    OPT_COUNT,
    OPT_WIDTH,
    /* streams */
    OPT_STRIPIFIER,
    OPT_BITS,
    OPT_CHUNK_SPLITS,
    OPT_NO_COMPRESS,
    OPT_STREAM_VERSION,
    OPT_BANDWIDTH_LEVELS,
    OPT_BANDWIDTH,
    /* measuring */
    OPT_SAMPLES_PER_FACE,
    OPT_SAMPLES,
    OPT_NO_VERTEX_SAMPLES,
    OPT_NO_EDGE_SAMPLES,
    OPT_SEED,
    OPT_THREADS,
    OPT_MEASURE,
    /* animations */
    OPT_STRICT,
    OPT_KEEP_SEAMS,
    OPT_LOST_SURFACE,
    OPT_METRO_STEP,
    OPT_NO_METRO,
    /* point sets */
    OPT_NEIGHBOURS,
    OPT_RADIUS_SCALE,
    OPT_ESTIMATE_NORMALS,
    /* point octrees */
    OPT_SPACING,
    OPT_NODE_POINTS,
    OPT_CHUNK_POINTS,
    OPT_TEMP_DIR,
    OPT_NO_RADII,
    OPT_BUDGET,
    /* pictures */
    OPT_SIZE,
    OPT_VIEW,
    OPT_UP,
    OPT_BACKGROUND,
    OPT_WIREFRAME,
    OPT_STRIPS,
    OPT_PASSES,
    OPT_NO_CULLING,
    OPT_NO_CLIP,
    OPT_FLAT_POINTS,
    /* terrains */
    OPT_FLIGHT,
    OPT_CRACKS,
    OPT_ERROR_SCALE,
    OPT_RESOLUTION,
    OPT_NO_MORPH,
    OPT_NO_FRUSTUM_CULLING,
    OPT_SPEED,
    OPT_GRID_SIZE,
    OPT_PROBES,
    OPT_PNG,
    OPT_CSV,
    /* writing meshes */
    OPT_ASCII,
    OPT_BIG_ENDIAN,
    OPT_CLEAN,
    OPT_TRANSLATE,
    OPT_TRANSLATE_DIAGONAL,
    OPT_NO_NORMALS,
    OPT_NO_TEXCOORDS,
    OPT_NO_COLORS,
    OPT_QUANTIZE,
    OPT_MESHOPT,
    OPT_EXTERNAL_IMAGES,
    /* the server */
    OPT_PORT,
    OPT_HOST,
    OPT_SIMPLIFY_ON_DEMAND,
    OPT_CACHE,
    OPT_WEB,
    OPT_MAX_CONNECTIONS,
    OPT_TIMEOUT,
    /* every command that reads meshes / prints results */
    OPT_WELD,
    OPT_JSON,
    OPT_QUIET,
    OPT_MAX_MEMORY,
    OPT_HELP,
    OPT_VERSION,
    OPT_ID_COUNT
} cli_option_id;

typedef struct cli_option {
    const char *name;     /* long name, without "--" */
    char letter;          /* short letter, or 0 */
    const char *argument; /* argument name ("N", "WxH"); "[TOL]" when optional; NULL: none */
    unsigned commands;    /* bit (1u << cli_command_id) of each command that takes it */
    const char *help;     /* one paragraph, wrapped when printed */
} cli_option;

extern const cli_option cli_options[OPT_ID_COUNT];

/* Whether COMMAND takes option ID. */
int cli_takes(cli_command_id command, cli_option_id id);

/* The options of one command line, in order:
 *     cli_parser parser;
 *     cli_parse_begin(&parser, CMD_SIMPLIFY, argc, argv);
 *     for (int id; (id = cli_next(&parser)) != CLI_DONE;)
 *         switch (id) { case OPT_RATIO: ... parser.value ...; case CLI_EXIT: return parser.exit_code; }
 * then the operands are argv[optind .. argc). cli_next handles --help
 * (prints it: CLI_EXIT, exit 0), every usage error (prints it with a hint:
 * CLI_EXIT, exit 2), --weld (for load_mesh), --json and --quiet (in
 * parser.json, parser.quiet); every other option is returned with its
 * argument in parser.value (NULL when it takes none). */
enum { CLI_DONE = -1, CLI_EXIT = -2 };
typedef struct cli_parser {
    cli_command_id command;
    int argc;
    char **argv;
    const char *value; /* the argument of the option returned */
    int json, quiet;   /* --json, -q/--quiet seen */
    int exit_code;     /* after CLI_EXIT */
} cli_parser;
void cli_parse_begin(cli_parser *parser, cli_command_id command, int argc, char **argv);
int cli_next(cli_parser *parser);
/* For a `default:` of a command's switch: an option declared for the
 * command that it does not handle (a programming error) is a usage error. */
int cli_unhandled(cli_parser *parser, int id);
/* Prints text from `column`, its words wrapped within 79 columns, every
 * further line indented by `indent`, then a newline. */
void print_wrapped(FILE *out, const char *text, int column, int indent);
/* Writes `lodkit COMMAND --help` (CMD_MAIN: `lodkit --help`). */
void cli_print_help(FILE *out, cli_command_id command);

/* Strict parsers: the whole text must be a finite number / a non-negative integer / "x,y,z". */
int parse_double_option(const char *text, double *value);
int parse_size_option(const char *text, size_t *value);
int parse_vector3(const char *text, double out[3]);
/* "x", "y" or "z" (either case) -> LK_AXIS_X.. ; 0 when it is none of them. */
int parse_axis_letter(const char *text, int *axis);

/* ---- errors (cli_errors.c) -------------------------------------------------- */

/* "lodkit: message" on stderr. */
void print_error(const lk_error *error);
/* The same for an error met while a command works on INPUT (and writes
 * OUTPUT, may be NULL): every message names its file. The library's readers
 * and writers start their messages with the path they were given; messages
 * of the algorithms (a mesh in memory has no name) get "INPUT: " in front. */
void print_error_for(const char *input, const char *output, const lk_error *error);
/* Prints "lodkit COMMAND: <format with detail>" and a hint; returns EXIT_USAGE. */
int usage_error(const char *command, const char *format, const char *detail);

/* ---- printing results (cli_print.c) ----------------------------------------- */

/* 1234567 -> "1,234,567" in a rotating static buffer (8 slots). */
const char *thousands(unsigned long long value);
/* count_noun(1, "vertex", "vertices") -> "1 vertex", 1234 -> "1,234
 * vertices", in the same rotating buffers as thousands. */
const char *count_noun(unsigned long long value, const char *one, const char *many);
/* The two counts printed most: "1 vertex", "2 vertices"; "1 triangle", "2 triangles". */
const char *n_vertices(unsigned long long value);
const char *n_triangles(unsigned long long value);
/* Prints the JSON on one line and deletes it. */
void print_json(cJSON *root);
cJSON *distance_json(const lk_distance_stats *stats);

/* ---- progress (cli_progress.c) ---------------------------------------------- */

/* Progress bar on a terminal's stderr; silent otherwise or with --quiet. */
typedef struct progress_state {
    int enabled;
    int last_permille;
    const char *last_stage;
    const char *label;
} progress_state;
int progress_draw(void *user, double fraction, const char *stage); /* an lk_progress_fn */
void progress_init(progress_state *state, int quiet, const char *label);
void progress_done(progress_state *state);

/* ---- inputs and memory (cli_input.c) ----------------------------------------- */

/* malloc/calloc of count * size bytes; NULL when that overflows or the
 * allocation fails (count 0 gives a valid 1-byte block). */
void *malloc_array(size_t count, size_t size);
void *calloc_array(size_t count, size_t size);
/* Monotonic wall clock in seconds, for timings. */
double now_seconds(void);

/* The memory budget (--max-memory SIZE, env LODKIT_MAX_MEMORY) for what
 * lodkit allocates for input data (mesh arrays, animation frames, DEM
 * samples, decoded streams, glTF buffers, and the bytes of the input files
 * themselves). Set by main before a command runs; every reader call of the
 * CLI passes it on. */
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
/* Reads a whole input file after checking its size against cli_max_memory. */
lk_status read_input_file(const char *path, unsigned char **data, size_t *size, lk_error *error);

/* --weld[=TOL]: load_mesh merges vertices closer than tolerance. */
extern int cli_weld;
extern double cli_weld_tolerance;
/* Reads a mesh or point set within cli_max_memory, welded when --weld was
 * given (*welded, may be NULL, gets how many vertices merged); seconds (may
 * be NULL) gets the time taken. A progressive stream (.lks) or an
 * elevation grid is refused with a message naming the command that reads it. */
lk_status load_mesh(const char *path, lk_mesh *mesh, double *seconds, size_t *welded, lk_error *error);
/* Scenes (glTF in and out keep nodes, primitives and materials). */
int is_gltf_path(const char *path);
/* glTF, or OBJ with materials (a `usemtl` line): read with lk_scene_read
 * when a scene is kept (a glTF output, render, info). An OBJ without
 * materials is one mesh, read as before. */
int reads_as_scene(const char *path);
/* lk_scene_read within --max-memory (as load_mesh reads meshes). */
lk_status load_scene(const char *path, lk_scene *scene, lk_error *error);
/* Prints each of the scene's notes (what reading dropped) as "note: ...". */
void print_scene_notes(const lk_scene *scene);
/* "N nodes, N primitives, N vertices, N triangles, N materials, N textures"
 * (a static buffer, overwritten by the next call). */
const char *scene_summary(const lk_scene *scene);
/* Whether lk_dem_read reads PATH (checked cheaply: the header only). */
int looks_like_grid(const char *path);

/* Lists of file extensions for the help texts and the messages, drawn
 * from the library's format table (lk_format_info_at). */
typedef enum cli_format_list {
    FORMATS_MESH_READ,      /* what lk_mesh_read reads */
    FORMATS_MESH_WRITE,     /* what lk_mesh_write writes */
    FORMATS_TRIANGLE_WRITE, /* the writable formats that hold triangles */
    FORMATS_ANIMATION_READ, /* what lk_animation_read reads */
    FORMATS_GRID            /* elevation grids (lk_dem_read) */
} cli_format_list;
/* Whether a format's extensions belong to a list. */
int format_in_list(const lk_format_info *info, cli_format_list list);
/* "obj ply off ..." (or ".obj .ply .off ... or .stl" with dotted set): every
 * extension of the list's formats, in the table's order, in a static buffer. */
const char *format_list(cli_format_list list, int dotted);
/* The format a command that writes triangles writes to `path`, or
 * LK_FORMAT_UNKNOWN after printing a usage error that says which formats
 * it writes (and that md2/kmf hold animations: lodkit animate).
 * points_too: .xyz (a point set) is accepted. */
lk_format output_mesh_format(const char *command, const char *path, int points_too);
/* --quantize / --meshopt / --external-images into *gltf_flags; 0 when `id` is none of them. */
int gltf_flag_option(int id, uint64_t *gltf_flags);
/* Usage error (EXIT_USAGE) when gltf_flags are set and OUT is not .glb/.gltf; 0 otherwise. */
int check_gltf_flags(const char *command, const char *out, uint64_t gltf_flags);

/* ---- pictures (cli_picture.c) ------------------------------------------------ */

/* "800x600" -> 800, 600 (each 1..8192); 0 when malformed. */
int parse_image_size(const char *text, unsigned *width, unsigned *height);
/* "azimuth,elevation,distance" (degrees, degrees, radii >= 0) into options. */
int parse_view_option(const char *text, lk_render_options *options);
/* "r,g,b" in 0..1 (or 0..255 when a channel is > 1) into options->background:
 * 1; 0 when malformed, -1 when a channel is out of range. */
int parse_background_option(const char *text, lk_render_options *options);
/* The options of the drawing commands (render, splat) that set the image
 * size and render options: 1 when ID is one of them; *exit_code gets -1,
 * or the exit code of a usage error when its value is refused. */
int camera_option(cli_parser *parser, int id, lk_render_options *options, unsigned *width, unsigned *height,
                  int *exit_code);
/* Offscreen render of a mesh (or, with points set, a point set) written to
 * path as PNG; renderer_name (may be NULL) receives the GL renderer. */
lk_status render_to_png(const lk_mesh *mesh, int points, unsigned width, unsigned height,
                        const lk_render_options *options, const char *path, lk_render_stats *stats, char *renderer_name,
                        size_t renderer_name_size, lk_error *error);
/* The same for a scene (mesh unused) with its materials and textures. */
lk_status render_any_to_png(const lk_mesh *mesh, const lk_scene *scene, int points, unsigned width, unsigned height,
                            const lk_render_options *options, const char *path, lk_render_stats *stats,
                            lk_render_scene_info *info, char *renderer_name, size_t renderer_name_size,
                            lk_error *error);
/* Reads the renderer's framebuffer and writes it to path as PNG. */
lk_status write_framebuffer_png(const lk_renderer *renderer, const char *path, lk_error *error);

#endif
