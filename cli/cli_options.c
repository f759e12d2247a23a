/* SPDX-License-Identifier: MIT */
/* The options of every lodkit command, each declared once (long name,
 * short letter, argument, commands, help), the getopt_long parser built
 * from that table, the --help texts generated from it, and the strict
 * parsers of option values. */
#include <ctype.h>
#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

/* Command bits of the table below. */
enum {
    INFO = 1u << CMD_INFO,
    CONVERT = 1u << CMD_CONVERT,
    METRO = 1u << CMD_METRO,
    SIMPLIFY = 1u << CMD_SIMPLIFY,
    LOD = 1u << CMD_LOD,
    SUBDIVIDE = 1u << CMD_SUBDIVIDE,
    PROGRESSIVE = 1u << CMD_PROGRESSIVE,
    UNPACK = 1u << CMD_UNPACK,
    INSPECT = 1u << CMD_INSPECT,
    RENDER = 1u << CMD_RENDER,
    SAMPLE = 1u << CMD_SAMPLE,
    SPLAT = 1u << CMD_SPLAT,
    OCTREE = 1u << CMD_OCTREE,
    TERRAIN = 1u << CMD_TERRAIN,
    SLICES = 1u << CMD_SLICES,
    ANIMATE = 1u << CMD_ANIMATE,
    SERVE = 1u << CMD_SERVE,
    FORMATS = 1u << CMD_FORMATS,
    MAIN = 1u << CMD_MAIN,
    EVERY_COMMAND = (1u << CMD_MAIN) - 1,
    /* the commands that read meshes (and so take --weld) */
    MESH_READERS = INFO | CONVERT | METRO | SIMPLIFY | LOD | SUBDIVIDE | PROGRESSIVE | RENDER | SAMPLE | SPLAT | SLICES,
    /* the commands that draw a model (and so take --up and the camera) */
    DRAWERS = RENDER | SPLAT
};

const cli_option cli_options[OPT_ID_COUNT] = {
    [OPT_OUTPUT] = {"output", 'o', "OUT.png", RENDER | SPLAT, "image to write (required)"},
    [OPT_METHOD] = {"method", 'm', "M", SIMPLIFY,
                    "qem (Garland-Heckbert quadrics, default), uniform (uniform-grid clustering), floating "
                    "(floating-cell clustering) or wavelet (planar slices + CDF 9/7 contour wavelets; closed input: a "
                    "few holes are closed first)"},
    [OPT_SCHEME] = {"scheme", 0, "S", SUBDIVIDE | ANIMATE, NULL /* per command, below */},

    [OPT_RATIO] = {"ratio", 'r', "R", SIMPLIFY | LOD | UNPACK | SLICES | ANIMATE, NULL /* per command, below */},
    [OPT_TRIANGLES] = {"triangles", 't', "N", SIMPLIFY, "keep N triangles"},
    [OPT_VERTICES] = {"vertices", 0, "N", SIMPLIFY | SLICES, "keep N vertices"},
    [OPT_MAX_ERROR] = {"max-error", 'e', "E", SIMPLIFY | SLICES,
                       "an error bound in % of the bounding-box diagonal: qem stops before a collapse's error exceeds "
                       "it; wavelet bounds the in-plane contour error by it (see --criterion)"},
    [OPT_CELL_SIZE] = {"cell-size", 0, "P", SIMPLIFY,
                       "uniform and floating clustering: the cell size (cube side; floating: ball diameter) in % of "
                       "the diagonal"},
    [OPT_LEVEL] = {"level", 'l', "K", UNPACK,
                   "apply K vertex splits to the base mesh, 0 to the stream's split count (default: all)"},
    [OPT_LEVELS] = {"levels", 0, "N", ANIMATE | LOD, NULL /* per command, below */},
    [OPT_SEPARATE] = {"separate", 0, NULL, LOD,
                      "one file per level, named after OUT: STEM_lod0.EXT, STEM_lod1.EXT, ... (any mesh format)"},
    [OPT_BYTES] = {"bytes", 0, "N", UNPACK, "read only the first N bytes, as if the download stopped there"},
    [OPT_FRAME] = {"frame", 'f', "K", ANIMATE, "the frame of --scheme frame (default 0)"},
    [OPT_POINTS] = {"points", 'n', "N", SAMPLE | SPLAT, "points to draw on a mesh (default 100000)"},
    [OPT_POISSON] = {"poisson", 0, NULL, SAMPLE,
                     "Poisson-disk (blue-noise) points: an even spacing, drawn as the best-spread N of 5N uniform "
                     "samples (sample elimination)"},
    [OPT_ITERATIONS] = {"iterations", 0, "N", SUBDIVIDE, "how many times (default 1)"},

    [OPT_BASE_RATIO] = {"base-ratio", 'b', "R", PROGRESSIVE,
                        "base mesh triangles / input triangles (default: 200 triangles in version 2, 0.05 in "
                        "version 1)"},
    [OPT_BASE_TRIANGLES] = {"base-triangles", 0, "N", PROGRESSIVE, "base mesh of N triangles (overrides --base-ratio)"},
    [OPT_PLACEMENT] = {"placement", 0, "P", PROGRESSIVE,
                       "optimal (QEM optimum; version 1's default) or endpoint (half-edge collapses: coarse levels a "
                       "little worse, stream smaller; version 2's default)"},
    [OPT_COLLAPSE_ORDER] = {"collapse-order", 0, "O", PROGRESSIVE,
                            "rounds (independent collapses in rounds: a version-2 stream 5-15% smaller; version "
                            "2's default) or greedy (cheapest first; version 1's default)"},
    [OPT_PAIR_DISTANCE] = {"pair-distance", 0, "T", SIMPLIFY,
                           "qem: also contract vertex pairs closer than T % of the diagonal"},
    [OPT_FEATURE_ANGLE] = {"feature-angle", 0, "A", SIMPLIFY | PROGRESSIVE,
                           "qem: creases are edges sharper than A degrees (default 40)"},
    [OPT_FEATURE_WEIGHT] = {"feature-weight", 0, "W", SIMPLIFY,
                            "qem: weight of border and crease constraints (default 1)"},
    [OPT_NO_FEATURES] = {"no-features", 0, NULL, SIMPLIFY,
                         "qem: do not detect creases and corners (glTF scenes: by default QEM runs with and without "
                         "them and keeps the result closer to the input)"},
    [OPT_LOCK_BORDER] = {"lock-border", 0, NULL, SIMPLIFY | PROGRESSIVE,
                         "qem: border vertices neither move nor vanish"},
    [OPT_ATTRIBUTES] = {"attributes", 0, NULL, SIMPLIFY | LOD,
                        "qem: keep normals, texture coordinates and colours faithful"},

    [OPT_SLICES] = {"slices", 0, "N", SIMPLIFY | SLICES, NULL /* per command, below */},
    [OPT_AXIS] = {"axis", 0, "A", SIMPLIFY | SLICES,
                  "wavelet: slice perpendicular to x, y, z or auto (the shortest side, default)"},
    [OPT_CRITERION] = {"criterion", 0, "C", SIMPLIFY | SLICES,
                       "wavelet: a contour's level by energy (the paper's sum of dropped c^2, default) or distance "
                       "(largest in-plane distance)"},
    [OPT_NO_REFINE] = {"no-refine", 0, NULL, SIMPLIFY,
                       "wavelet: no vertices between the planes (the paper's pipeline only; by default 8% of a "
                       "vertex target refines the tiling)"},
    [OPT_COUNT] = {"count", 'c', "K", SLICES, "slices drawn, spread evenly (default 4, at most 16)"},
    [OPT_WIDTH] = {"width", 0, "W", SLICES, "image width in pixels (default 1200; the height follows from the panels)"},

    [OPT_STRIPIFIER] = {"stripifier", 0, "S", PROGRESSIVE,
                        "version 1: best (default: both, keep the shorter), lodkit or meshopt"},
    [OPT_BITS] = {"bits", 0, "B", PROGRESSIVE,
                  "position quantisation bits per coordinate, 4..24 (default: the fewest keeping every position "
                  "within 0.01% of the diagonal)"},
    [OPT_CHUNK_SPLITS] = {"chunk-splits", 0, "N", PROGRESSIVE, "vertex splits per chunk (default 1024)"},
    [OPT_NO_COMPRESS] = {"no-compress", 0, NULL, PROGRESSIVE, "version 1: do not deflate chunk payloads"},
    [OPT_STREAM_VERSION] = {"stream-version", 0, "V", PROGRESSIVE,
                            "2 (default: range-coded vertex splits with the input's normals, texture coordinates and "
                            "colours; endpoint placement, collapses in rounds, a 200-triangle base unless given) or 1 "
                            "(the paper's triangle strips with E-PS updates and DTFS filtering, positions only)"},
    [OPT_BANDWIDTH_LEVELS] = {"bandwidth-levels", 0, "N", PROGRESSIVE,
                              "version 1: levels sampled for the bandwidth figures (default 256, 0 = all)"},
    [OPT_BANDWIDTH] = {"bandwidth", 0, "F.csv", PROGRESSIVE,
                       "version 1: write the indices sent to the GPU per sampled level: PM (3 per triangle), "
                       "unfiltered strips, DTFS-filtered strips"},

    [OPT_SAMPLES_PER_FACE] = {"samples-per-face", 0, "N", METRO | ANIMATE,
                              "Metro face samples per triangle, on average (default 10)"},
    [OPT_SAMPLES] = {"samples", 0, "N", METRO, "total face samples per surface (overrides --samples-per-face)"},
    [OPT_NO_VERTEX_SAMPLES] = {"no-vertex-samples", 0, NULL, METRO, "do not sample vertices"},
    [OPT_NO_EDGE_SAMPLES] = {"no-edge-samples", 0, NULL, METRO, "do not sample edges"},
    [OPT_SEED] = {"seed", 0, "S", METRO | SAMPLE, "random seed (default 1); the results are deterministic"},
    [OPT_THREADS] = {"threads", 0, "T", METRO | OCTREE | SIMPLIFY,
                     "worker threads (default: all cores; simplify: QEM on meshes of 200K triangles or more, whose "
                     "result depends on T)"},
    [OPT_MEASURE] = {"measure", 0, NULL, SIMPLIFY | LOD, "measure the result with lodkit metro against the input"},

    [OPT_STRICT] = {"strict", 0, NULL, ANIMATE,
                    "refuse every contraction that folds a triangle in any frame, even when that stops short of a "
                    "level (default: below that point check the reference frame only, and say where)"},
    [OPT_KEEP_SEAMS] = {"keep-seams", 0, NULL, ANIMATE,
                        "keep vertices split by texture seams apart (default: merge vertices that coincide in every "
                        "frame while simplifying)"},
    [OPT_LOST_SURFACE] = {"lost-surface", 0, "W", ANIMATE,
                          "weight of the lost-surface term (default 300): each frame's cost also counts how far the "
                          "input vertices merged so far end up from the new triangles, which the quadrics miss on "
                          "thin parts; 0: the paper's cost, quadrics alone (~50x faster)"},
    [OPT_METRO_STEP] = {"metro-step", 0, "N", ANIMATE, "measure every N-th frame (default 1: all)"},
    [OPT_NO_METRO] = {"no-metro", 0, NULL, ANIMATE, "write the levels only"},

    [OPT_NEIGHBOURS] = {"neighbours", 'k', "K", SAMPLE | OCTREE,
                        "k of the k-nearest-neighbour radius and of the normal estimation, 1..256 (default 8; also "
                        "--neighbors)"},
    [OPT_RADIUS_SCALE] = {"radius-scale", 0, "F", SAMPLE | SPLAT, "multiply every splat radius by F > 0 (default 1)"},
    [OPT_ESTIMATE_NORMALS] = {"estimate-normals", 0, NULL, SAMPLE | OCTREE,
                              "point sets: estimate normals by local PCA, oriented consistently (replaces the "
                              "file's normals); needed when the input has none"},

    [OPT_SPACING] = {"spacing", 0, "S", OCTREE,
                     "root spacing in model units: level l keeps points S / 2^l apart (default: the root cube's "
                     "side / 2^L, L <= 7 the largest whose grid has at most an eighth of the points' count of "
                     "occupied cells: side / 128 for large clouds, coarser for small ones)"},
    [OPT_NODE_POINTS] = {"node-points", 0, "N", OCTREE,
                         "a node with at most N points is a leaf and keeps them all (default 20000, or an eighth "
                         "of the points when fewer)"},
    [OPT_CHUNK_POINTS] = {"chunk-points", 0, "N", OCTREE,
                          "points built in memory at once per thread (default 2000000; about 120 bytes each)"},
    [OPT_TEMP_DIR] = {"temp-dir", 0, "DIR", OCTREE,
                      "where the spill files go (default OUTDIR; about 28 bytes a point)"},
    [OPT_NO_RADII] = {"no-radii", 0, NULL, OCTREE,
                      "splat radius = the node's spacing (skip the nearest-neighbour density estimate)"},
    [OPT_BUDGET] = {"budget", 0, "N", SPLAT,
                    "when IN is an octree: draw at most N points, the nodes of largest projected size first "
                    "(default 1000000)"},

    [OPT_SIZE] = {"size", 's', "WxH", DRAWERS, "image size in pixels, 1..8192 a side (default 800x800)"},
    [OPT_VIEW] = {"view", 0, "A,E,D", DRAWERS,
                  "azimuth and elevation in degrees, distance in bounding-sphere radii (0 frames the model; "
                  "default 30,20,0)"},
    [OPT_UP] = {"up", 0, "x|y|z", DRAWERS,
                "the model's up axis: the camera orbits around it and the elevation is measured from the plane "
                "across it (default y)"},
    [OPT_BACKGROUND] = {"background", 0, "R,G,B", DRAWERS, "background colour, 0..1 (or 0..255) each (default white)"},
    [OPT_WIREFRAME] = {"wireframe", 0, NULL, RENDER, "meshes: draw the edges over the surface"},
    [OPT_STRIPS] = {"strips", 0, NULL, RENDER,
                    "meshes: draw one triangle strip (lodkit's stripifiers) instead of indexed triangles"},
    [OPT_PASSES] = {"passes", 0, "1|2", DRAWERS,
                    "point sets: 1: Gaussian splats alpha-blended in one pass (default); 2: visibility + "
                    "accumulation + normalisation (no brightening where splats overlap)"},
    [OPT_NO_CULLING] = {"no-culling", 0, NULL, DRAWERS, "point sets: keep back-facing splats"},
    [OPT_NO_CLIP] = {"no-clip", 0, NULL, DRAWERS | OCTREE,
                     "point sets: whole discs at the borders (by default a border point's splat is cut at the "
                     "border, so that a scan's outline and gaps stay sharp); octree: store no clip lines"},
    [OPT_FLAT_POINTS] = {"flat-points", 0, NULL, DRAWERS,
                         "point sets: plain square points, unlit, unblended (the baseline; also --flat)"},

    [OPT_FLIGHT] = {"flight", 0, "N", TERRAIN, "frames to fly (default 500)"},
    [OPT_CRACKS] = {"cracks", 0, "MODE", TERRAIN,
                    "none: each leaf morphs its own points with its own blend; midpoint: + shared edge midpoints "
                    "use the smaller blend (Röttger); paper: + the paper's corner rules as written; full: one "
                    "height per vertex, top-down (default)"},
    [OPT_ERROR_SCALE] = {"error-scale", 0, "c", TERRAIN,
                         "error scale c of f = l / (d C max(c d2, 1)) (default 50; also --error)"},
    [OPT_RESOLUTION] = {"resolution", 0, "C", TERRAIN, "minimum global resolution C (default 8)"},
    [OPT_NO_MORPH] = {"no-morph", 0, NULL, TERRAIN, "no geomorphing: points jump to their true heights"},
    [OPT_NO_FRUSTUM_CULLING] = {"no-frustum-culling", 0, NULL, TERRAIN, "no view-frustum culling"},
    [OPT_SPEED] = {"speed", 0, "S", TERRAIN, "flight speed in grid spacings per frame (default 0.5)"},
    [OPT_GRID_SIZE] = {"grid-size", 0, "S", TERRAIN,
                       "resample the grid to S x S samples (S = 2^n + 1; default: the smallest such size holding "
                       "the grid, when it is not one)"},
    [OPT_PROBES] = {"probes", 0, "P", TERRAIN, "popping probes per side (default 257)"},
    [OPT_PNG] = {"png", 0, "DIR", TERRAIN,
                 "write pictures of 5 frames into DIR: map_NNNN.png (top-down relief, quadtree, eye, cracks ringed "
                 "in red) and view_NNNN.png (3-D, colour ramp + hillshade, triangle edges)"},
    [OPT_CSV] = {"csv", 0, "FILE", TERRAIN, "per-frame numbers as CSV"},

    [OPT_ASCII] = {"ascii", 0, NULL, CONVERT | SAMPLE, "PLY/STL: write text instead of binary"},
    [OPT_BIG_ENDIAN] = {"big-endian", 0, NULL, CONVERT, "PLY: write binary big-endian"},
    [OPT_CLEAN] = {"clean", 0, NULL, CONVERT, "remove degenerate and duplicate triangles and unused vertices"},
    [OPT_TRANSLATE] = {"translate", 0, "X,Y,Z", CONVERT, "move the mesh by (X,Y,Z) model units"},
    [OPT_TRANSLATE_DIAGONAL] = {"translate-diagonal", 0, "X,Y,Z", CONVERT,
                                "move the mesh by (X,Y,Z) times its bounding-box diagonal"},
    [OPT_NO_NORMALS] = {"no-normals", 0, NULL, CONVERT | OCTREE, "drop the normals"},
    [OPT_NO_TEXCOORDS] = {"no-texcoords", 0, NULL, CONVERT, "drop the texture coordinates"},
    [OPT_NO_COLORS] = {"no-colors", 0, NULL, CONVERT, "drop the colours"},
    [OPT_QUANTIZE] = {"quantize", 0, NULL, CONVERT | SIMPLIFY | LOD,
                      "glTF: KHR_mesh_quantization (14-bit positions, 8-bit normals, 12-bit texture coordinates)"},
    [OPT_MESHOPT] = {"meshopt", 0, NULL, CONVERT | SIMPLIFY | LOD,
                     "glTF: EXT_meshopt_compression on top of --quantize (meshoptimizer's codecs)"},
    [OPT_EXTERNAL_IMAGES] = {"external-images", 0, NULL, CONVERT | SIMPLIFY | LOD,
                             ".gltf: write each texture image as a file next to it (STEM_N.png, ...) "
                             "instead of inside the .bin"},

    [OPT_PORT] = {"port", 'p', "N", SERVE, "TCP port (default 8080; 0 = any free port)"},
    [OPT_HOST] = {"host", 0, "ADDR", SERVE,
                  "address to listen on (default 127.0.0.1; 0.0.0.0 = every interface: anyone who can reach it "
                  "can read DIR)"},
    [OPT_SIMPLIFY_ON_DEMAND] = {"simplify-on-demand", 0, NULL, SERVE,
                                "/m/NAME.lks where only a mesh NAME.obj|ply|off|stl|smf|gltf|glb exists: build the "
                                "stream (lodkit progressive's defaults) on the first request and cache it on disk"},
    [OPT_CACHE] = {"cache", 0, "DIR2", SERVE, "where those streams go (default DIR/.lodkit-cache)"},
    [OPT_WEB] = {"web", 0, "WEBDIR", SERVE, "serve the viewer from WEBDIR instead (development)"},
    [OPT_MAX_CONNECTIONS] = {"max-connections", 0, "N", SERVE, "concurrent connections (default 256)"},
    [OPT_TIMEOUT] = {"timeout", 0, "S", SERVE, "close idle or stalled connections after S seconds (default 30)"},

    [OPT_WELD] = {"weld", 0, "[TOL]", MESH_READERS,
                  "merge vertices closer than TOL after reading (model units; default 0: identical positions)"},
    [OPT_JSON] = {"json", 0, NULL, EVERY_COMMAND & ~(CONVERT | SUBDIVIDE | SLICES | SERVE), "print one JSON object"},
    [OPT_QUIET] = {"quiet", 'q', NULL, EVERY_COMMAND & ~(INSPECT | FORMATS),
                   "print nothing but errors (no progress bar either)"},
    [OPT_MAX_MEMORY] = {"max-memory", 0, "SIZE", (EVERY_COMMAND & ~FORMATS) | MAIN,
                        "memory budget for input data, e.g. 512M or 2G (default: min(8G, half the RAM); env "
                        "LODKIT_MAX_MEMORY); inputs that need more are refused. Before or after COMMAND."},
    [OPT_HELP] = {"help", 'h', NULL, EVERY_COMMAND | MAIN, "show this help"},
    [OPT_VERSION] = {"version", 'V', NULL, MAIN, "print the version"},
};

/* Where an option's values differ between commands (same meaning, other
 * things to choose from), the command's own help. */
static const struct {
    cli_option_id id;
    cli_command_id command;
    const char *help;
} command_help[] = {
    {OPT_SCHEME, CMD_SUBDIVIDE, "loop (smooth, default) or midpoint (flat, exact area)"},
    {OPT_SCHEME, CMD_ANIMATE, "max, avg, frame, or a comma list of them, or all (default max)"},
    {OPT_RATIO, CMD_SIMPLIFY, "keep this fraction of the triangles, 0 < R <= 1"},
    {OPT_RATIO, CMD_LOD, "each level keeps R of the previous one's triangles, 0 < R < 1 (default 0.5)"},
    {OPT_LEVELS, CMD_LOD, "levels of detail including the input, 1..32 (default 4)"},
    {OPT_LEVELS, CMD_ANIMATE, "N levels keeping 1/N, 2/N, ... N/N of the triangles (default 10)"},
    {OPT_RATIO, CMD_UNPACK, "the level with R x the full vertex count, 0 <= R <= 1"},
    {OPT_RATIO, CMD_SLICES, "keep this fraction of the sampled points (default 0.125)"},
    {OPT_RATIO, CMD_ANIMATE,
     "one simplified animation keeping R of the triangles instead of a level set (written as STEM-SCHEME.EXT)"},
    {OPT_SLICES, CMD_SIMPLIFY,
     "wavelet: N slicing planes (default: 150 with --max-error, else the count in 16..150 balancing contour error "
     "and spacing)"},
    {OPT_SLICES, CMD_SLICES, "slicing planes (default 150, the paper's)"},
    {OPT_VERTICES, CMD_SLICES, "keep N points in all"},
    {OPT_MAX_ERROR, CMD_SLICES, "contour threshold in % of the diagonal (see --criterion)"},
    {OPT_POINTS, CMD_SPLAT, "when IN is a mesh: sample N points (default 100000)"},
    {OPT_THREADS, CMD_OCTREE, "chunks built at once (default: all cores)"},
    {OPT_NEIGHBOURS, CMD_OCTREE, "k of the splat radii and normal estimation, 1..256 (default 8)"},
    {OPT_ESTIMATE_NORMALS, CMD_OCTREE, "estimate normals by local PCA per chunk (~4 us a point; replaces the file's)"},
    {OPT_NO_NORMALS, CMD_OCTREE, "write no normals (default: keep the inputs' when all have them)"},
    {OPT_JSON, CMD_INFO, "one JSON object per file (one per line)"},
    {OPT_QUIET, CMD_INFO, "no progress bar (the report is still printed)"},
    {OPT_QUIET, CMD_METRO, "no progress bar (the report is still printed)"},
    {OPT_QUIET, CMD_SERVE, "no request log"},
};

/* Other spellings that keep working (they are not shown in the help). */
static const struct {
    const char *name;
    cli_option_id id;
} aliases[] = {
    {"neighbors", OPT_NEIGHBOURS}, /* American spelling */
    {"flat", OPT_FLAT_POINTS},     /* splat's name until issue 18 */
    {"error", OPT_ERROR_SCALE},    /* terrain's name until issue 18 */
};

/* Spellings that meant something else in these commands before issue 18:
 * refused with a pointer to the new one, never taken for another option. */
static const struct {
    const char *spelling; /* "-v" or "--levels" */
    unsigned commands;
    int takes_argument;
    const char *message;
} retired[] = {
    {"-v", SIMPLIFY | SLICES, 1, "-v is not --vertices any more: write --vertices=N"},
    {"-n", SUBDIVIDE, 1, "-n is --points now (of sample and splat): write --iterations=N"},
    {"-n", SLICES, 1, "-n is --points now (of sample and splat): write --slices=N"},
    {"-s", SUBDIVIDE | ANIMATE, 1, "-s is --size now (of images): write --scheme=S"},
    {"-l", ANIMATE, 1, "-l is --level now (of unpack): write --levels=N"},
    {"-b", UNPACK, 1, "-b is --base-ratio now (of progressive): write --bytes=N"},
    {"--levels", PROGRESSIVE, 1,
     "--levels is the number of levels of animate now: the levels sampled for the bandwidth figures are "
     "--bandwidth-levels=N"},
    {"--samples", ANIMATE, 1, "--samples is metro's total count: Metro samples per triangle are --samples-per-face=N"},
    {"--size", TERRAIN, 1, "--size is the size of an image (render, splat): write --grid-size=S"},
    {"--no-culling", TERRAIN, 0, "--no-culling keeps back-facing splats (render, splat): write --no-frustum-culling"},
};

enum {
    RETIRED_COUNT = sizeof retired / sizeof retired[0],
    ALIAS_COUNT = sizeof aliases / sizeof aliases[0],
    /* getopt_long's values: options are 256 + id, retired spellings after them */
    VALUE_OPTION = 256,
    VALUE_RETIRED = VALUE_OPTION + OPT_ID_COUNT,
};

int cli_takes(cli_command_id command, cli_option_id id) { return (cli_options[id].commands >> command) & 1u; }

static int retired_applies(int index, cli_command_id command) { return (retired[index].commands >> command) & 1u; }

static const char *option_help(cli_option_id id, cli_command_id command)
{
    for (size_t i = 0; i < sizeof command_help / sizeof command_help[0]; i++)
        if (command_help[i].id == id && command_help[i].command == command) return command_help[i].help;
    return cli_options[id].help ? cli_options[id].help : "";
}

static int has_argument(cli_option_id id)
{
    const char *argument = cli_options[id].argument;
    return !argument ? no_argument : argument[0] == '[' ? optional_argument : required_argument;
}

/* ---- parsing ------------------------------------------------------------ */

/* getopt_long's tables for the command being parsed (one at a time). */
static struct option long_options[OPT_ID_COUNT + ALIAS_COUNT + RETIRED_COUNT + 1];
static char short_options[3 * (OPT_ID_COUNT + RETIRED_COUNT) + 2];
static int id_of_letter[128];      /* option id + 1, or 0 */
static int retired_of_letter[128]; /* retired index + 1, or 0 */

static const char *command_name(cli_command_id command)
{
    return command == CMD_MAIN ? NULL : cli_commands[command].name;
}

void cli_parse_begin(cli_parser *parser, cli_command_id command, int argc, char **argv)
{
    memset(parser, 0, sizeof *parser);
    parser->command = command;
    parser->argc = argc;
    parser->argv = argv;
    size_t longs = 0, shorts = 0;
    short_options[shorts++] = ':'; /* a missing argument is told apart from an unknown option */
    memset(id_of_letter, 0, sizeof id_of_letter);
    memset(retired_of_letter, 0, sizeof retired_of_letter);
    for (int id = 0; id < OPT_ID_COUNT; id++) {
        if (!cli_takes(command, id) || id == OPT_MAX_MEMORY) continue; /* main took --max-memory out */
        long_options[longs++] = (struct option){cli_options[id].name, has_argument(id), NULL, VALUE_OPTION + id};
        char letter = cli_options[id].letter;
        if (letter) {
            short_options[shorts++] = letter;
            if (has_argument(id) != no_argument) short_options[shorts++] = ':';
            if (has_argument(id) == optional_argument) short_options[shorts++] = ':';
            id_of_letter[(unsigned char)letter] = id + 1;
        }
    }
    for (size_t i = 0; i < ALIAS_COUNT; i++)
        if (cli_takes(command, aliases[i].id))
            long_options[longs++] =
                (struct option){aliases[i].name, has_argument(aliases[i].id), NULL, VALUE_OPTION + (int)aliases[i].id};
    for (int i = 0; i < RETIRED_COUNT; i++) {
        if (!retired_applies(i, command)) continue;
        const char *spelling = retired[i].spelling;
        if (spelling[1] == '-') {
            long_options[longs++] = (struct option){
                spelling + 2, retired[i].takes_argument ? optional_argument : no_argument, NULL, VALUE_RETIRED + i};
        } else {
            short_options[shorts++] = spelling[1];
            if (retired[i].takes_argument) short_options[shorts++] = ':', short_options[shorts++] = ':';
            retired_of_letter[(unsigned char)spelling[1]] = i + 1;
        }
    }
    long_options[longs] = (struct option){0};
    short_options[shorts] = '\0';
    optind = 1;
    opterr = 0;
}

/* Prints the usage error; returns CLI_EXIT. */
static int parse_failed(cli_parser *parser, const char *format, const char *detail)
{
    parser->exit_code = usage_error(command_name(parser->command), format, detail);
    return CLI_EXIT;
}

/* The long option `--text` (up to a '=') was not recognised: unknown or ambiguous. */
static int unknown_long_option(cli_parser *parser, const char *text)
{
    char name[64];
    size_t length = strcspn(text + 2, "=");
    snprintf(name, sizeof name, "%.*s", (int)(length < 60 ? length : 60), text + 2);
    char candidates[256] = "";
    int matches = 0;
    for (const struct option *o = long_options; o->name; o++) {
        if (strncmp(o->name, name, length) != 0 || o->val >= VALUE_RETIRED) continue;
        size_t used = strlen(candidates);
        snprintf(candidates + used, sizeof candidates - used, "%s--%s", matches++ ? ", " : "", o->name);
    }
    if (matches > 1) {
        char message[400];
        snprintf(message, sizeof message, "option '--%s' is ambiguous: %s?", name, candidates);
        return parse_failed(parser, "%s", message);
    }
    return parse_failed(parser, "unknown option '%s'", text);
}

int cli_next(cli_parser *parser)
{
    for (;;) {
        int previous = optind;
        int value = getopt_long(parser->argc, parser->argv, short_options, long_options, NULL);
        parser->value = optarg;
        if (value == -1) return CLI_DONE;
        if (value == ':') {
            char spelling[80];
            if (optopt >= VALUE_OPTION && optopt < VALUE_RETIRED)
                snprintf(spelling, sizeof spelling, "--%s", cli_options[optopt - VALUE_OPTION].name);
            else
                snprintf(spelling, sizeof spelling, "-%c", optopt);
            int id = optopt >= VALUE_OPTION && optopt < VALUE_RETIRED     ? optopt - VALUE_OPTION
                     : optopt > 0 && optopt < 128 && id_of_letter[optopt] ? id_of_letter[optopt] - 1
                                                                          : -1;
            char message[200];
            snprintf(message, sizeof message, "option '%s' needs an argument (%s)", spelling,
                     id >= 0 && cli_options[id].argument ? cli_options[id].argument : "a value");
            return parse_failed(parser, "%s", message);
        }
        if (value == '?') {
            if (optopt >= VALUE_OPTION && optopt < VALUE_RETIRED)
                return parse_failed(parser, "option '--%s' takes no argument", cli_options[optopt - VALUE_OPTION].name);
            if (optopt > 0 && optopt < 256) {
                char spelling[3] = {'-', (char)optopt, '\0'};
                return parse_failed(parser, "unknown option '%s'", spelling);
            }
            return unknown_long_option(parser, parser->argv[optind - 1 > 0 ? optind - 1 : previous]);
        }
        if (value < 128 && retired_of_letter[value]) value = VALUE_RETIRED + retired_of_letter[value] - 1;
        if (value >= VALUE_RETIRED) return parse_failed(parser, "%s", retired[value - VALUE_RETIRED].message);
        int id = value >= VALUE_OPTION                ? value - VALUE_OPTION
                 : value < 128 && id_of_letter[value] ? id_of_letter[value] - 1
                                                      : -1;
        switch (id) {
        case OPT_HELP:
            cli_print_help(stdout, parser->command);
            parser->exit_code = EXIT_OK;
            return CLI_EXIT;
        case OPT_JSON: parser->json = 1; continue;
        case OPT_QUIET: parser->quiet = 1; continue;
        case OPT_WELD:
            cli_weld = 1;
            cli_weld_tolerance = 0;
            if (optarg && (!parse_double_option(optarg, &cli_weld_tolerance) || cli_weld_tolerance < 0))
                return parse_failed(parser, "--weld: '%s' is not a tolerance >= 0", optarg);
            continue;
        default: return id;
        }
    }
}

int cli_unhandled(cli_parser *parser, int id)
{
    if (id == CLI_EXIT) return parser->exit_code;
    char message[120];
    snprintf(message, sizeof message, "internal error: option %d is declared for %s but not handled", id,
             parser->command == CMD_MAIN ? "lodkit" : cli_commands[parser->command].name);
    return usage_error(command_name(parser->command), "%s", message);
}

/* ---- help --------------------------------------------------------------- */

enum { HELP_WIDTH = 79, HELP_COLUMN = 26 };

/* Writes `text` from column `column` on, wrapping words at HELP_WIDTH with
 * continuation lines indented to `indent`; a '\n' in text breaks the line. */
void print_wrapped(FILE *out, const char *text, int column, int indent)
{
    while (*text) {
        if (*text == '\n') {
            fprintf(out, "\n%*s", indent, "");
            column = indent;
            text++;
            continue;
        }
        size_t word = strcspn(text, " \n");
        if (column > indent && column + 1 + (int)word > HELP_WIDTH) {
            fprintf(out, "\n%*s", indent, "");
            column = indent;
        } else if (column > indent) {
            fputc(' ', out);
            column++;
        }
        fwrite(text, 1, word, out);
        column += (int)word;
        text += word;
        while (*text == ' ') text++;
    }
    fputc('\n', out);
}

static void print_option(FILE *out, cli_option_id id, cli_command_id command)
{
    const cli_option *o = &cli_options[id];
    char spelling[80];
    int length;
    const char *argument = o->argument;
    if (!argument)
        length = snprintf(spelling, sizeof spelling, "  %c%c%s--%s", o->letter ? '-' : ' ', o->letter ? o->letter : ' ',
                          o->letter ? ", " : "  ", o->name);
    else if (argument[0] == '[') /* optional: --weld[=TOL] */
        length = snprintf(spelling, sizeof spelling, "  %c%c%s--%s[=%.*s]", o->letter ? '-' : ' ',
                          o->letter ? o->letter : ' ', o->letter ? ", " : "  ", o->name, (int)strlen(argument) - 2,
                          argument + 1);
    else
        length = snprintf(spelling, sizeof spelling, "  %c%c%s--%s=%s", o->letter ? '-' : ' ',
                          o->letter ? o->letter : ' ', o->letter ? ", " : "  ", o->name, argument);
    fputs(spelling, out);
    if (length + 2 > HELP_COLUMN) {
        fprintf(out, "\n%*s", HELP_COLUMN, "");
    } else {
        fprintf(out, "%*s", HELP_COLUMN - length, "");
    }
    print_wrapped(out, option_help(id, command), HELP_COLUMN, HELP_COLUMN);
}

/* A format list in a help text, wrapped within HELP_WIDTH from `column`;
 * `tail` characters follow it on its last line (")."). Returns the column
 * after it. */
static int print_format_list(FILE *out, const char *list, int column, int tail)
{
    for (const char *word = list; *word;) {
        int length = (int)strcspn(word, " ");
        int last = word[length] == '\0';
        if (word != list) {
            if (column + 1 + length + (last ? tail : 0) > HELP_WIDTH) {
                fputc('\n', out);
                column = 0;
            } else {
                fputc(' ', out);
                column++;
            }
        }
        fwrite(word, 1, (size_t)length, out);
        column += length;
        word += length;
        if (*word == ' ') word++;
    }
    return column;
}

/* Help texts name the file formats through {mesh-read}, {mesh-write},
 * {triangle-write}, {animation-read} and {grid}, so that the lists come
 * from the library's format table (format_list). */
static void print_text(FILE *out, const char *text)
{
    static const struct {
        const char *key;
        cli_format_list list;
    } keys[] = {{"{mesh-read}", FORMATS_MESH_READ},
                {"{mesh-write}", FORMATS_MESH_WRITE},
                {"{triangle-write}", FORMATS_TRIANGLE_WRITE},
                {"{animation-read}", FORMATS_ANIMATION_READ},
                {"{grid}", FORMATS_GRID}};
    int column = 0;
    while (*text) {
        size_t plain = strcspn(text, "{");
        fwrite(text, 1, plain, out);
        for (size_t i = 0; i < plain; i++) column = text[i] == '\n' ? 0 : column + 1;
        text += plain;
        if (!*text) return;
        size_t k = 0, count = sizeof keys / sizeof keys[0];
        while (k < count && strncmp(text, keys[k].key, strlen(keys[k].key)) != 0) k++;
        if (k < count) {
            text += strlen(keys[k].key);
            column = print_format_list(out, format_list(keys[k].list, 0), column, (int)strcspn(text, " \n"));
        } else {
            fputc('{', out);
            column++;
            text++;
        }
    }
}

void cli_print_help(FILE *out, cli_command_id command)
{
    const cli_help *help = command == CMD_MAIN ? &main_help : cli_commands[command].help;
    if (command == CMD_MAIN) {
        fprintf(out, "Usage: %s %s\n", program, help->operands);
        print_text(out, help->description);
        fputs("\nCommands:\n", out);
        for (int c = 0; c < CMD_MAIN; c++) {
            int length = fprintf(out, "  %s", cli_commands[c].name);
            fprintf(out, "%*s", length < 15 ? 15 - length : 1, "");
            print_wrapped(out, cli_commands[c].summary, 15, 15);
        }
        fprintf(out, "\nRun '%s COMMAND --help' for a command's options.\n", program);
    } else {
        fprintf(out, "Usage: %s %s [options]%s%s\n", program, cli_commands[command].name, help->operands[0] ? " " : "",
                help->operands);
        print_text(out, help->description);
        fputc('\n', out);
    }
    for (int id = 0; id < OPT_ID_COUNT; id++)
        if (cli_takes(command, id)) print_option(out, id, command);
    if (help->notes) {
        fputc('\n', out);
        print_text(out, help->notes);
    }
}

/* ---- option values -------------------------------------------------------- */

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

int parse_axis_letter(const char *text, int *axis)
{
    if (!text[0] || text[1]) return 0;
    switch (tolower((unsigned char)text[0])) {
    case 'x': *axis = LK_AXIS_X; return 1;
    case 'y': *axis = LK_AXIS_Y; return 1;
    case 'z': *axis = LK_AXIS_Z; return 1;
    default: return 0;
    }
}

int gltf_flag_option(int id, uint64_t *gltf_flags)
{
    if (id == OPT_QUANTIZE)
        *gltf_flags |= LK_GLTF_QUANTIZE;
    else if (id == OPT_MESHOPT)
        *gltf_flags |= LK_GLTF_QUANTIZE | LK_GLTF_MESHOPT;
    else if (id == OPT_EXTERNAL_IMAGES)
        *gltf_flags |= LK_GLTF_EXTERNAL_IMAGES;
    else
        return 0;
    return 1;
}

int check_gltf_flags(const char *command, const char *out, uint64_t gltf_flags)
{
    const lk_format_info *named = lk_format_info_from_path(out);
    if ((gltf_flags & ~(uint64_t)LK_GLTF_EXTERNAL_IMAGES) && (!named || named->format != LK_FORMAT_GLTF))
        return usage_error(command, "%s: --quantize and --meshopt are for glTF output (.glb or .gltf)", out);
    if ((gltf_flags & LK_GLTF_EXTERNAL_IMAGES) && (!named || strcmp(named->name, "gltf") != 0))
        return usage_error(command, "%s: --external-images is for .gltf output (a .glb holds its images)", out);
    return 0;
}
