/* lodkit animate: deformation-sensitive simplification of an animation into
 * a level set, measured frame by frame like the paper's Fig. 8. */
#include <cjson/cJSON.h>
#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cli.h"
#include "internal.h"

static const char animate_help[] =
    "Usage: lodkit animate [options] IN OUTDIR\n"
    "Simplify an animation (MD2, KMF, glTF morph targets or skins, Acclaim) with one\n"
    "connectivity for all frames: per-frame quadrics, the merged vertex placed per\n"
    "frame, pairs ranked by the worst frame (max, the paper's), the mean over frames\n"
    "(avg) or one frame (frame). Writes, into OUTDIR (created if missing):\n"
    "  STEM-SCHEME-LKK.EXT  level KK of the level set (KK/N of the triangles), in the\n"
    "                       input's format (.md2, .kmf; glTF and Acclaim input: .gltf)\n"
    "  STEM-SCHEME.csv      per level and frame, Metro distances between the simplified\n"
    "                       and the original frame (model units), columns:\n"
    "                       level,ratio,frame,triangles,mean,rms,max,rms_forward,\n"
    "                       rms_backward,rms_percent  (mean/rms: the larger of the two\n"
    "                       directions; max: the Hausdorff distance; rms_percent: rms in\n"
    "                       % of the diagonal of all original frames)\n"
    "  STEM-SCHEME-rms.png  heat map level x frame -> rms_percent (one colour scale for\n"
    "                       all schemes of the run)\n"
    "SCHEME is max, avg or frameK.\n"
    "\n"
    "  -s, --scheme=S         max, avg, frame, or a comma list, or all (default max)\n"
    "  -f, --frame=K          the frame of --scheme frame (default 0)\n"
    "  -l, --levels=N         N levels keeping 1/N, 2/N, ... N/N of the triangles (default 10)\n"
    "  -r, --ratio=R          one simplified animation keeping R of the triangles instead\n"
    "                         of a level set (written as STEM-SCHEME.EXT)\n"
    "      --strict           refuse every contraction that folds a triangle in any frame,\n"
    "                         even when that stops short of a level (default: below that\n"
    "                         point check the reference frame only, and say where)\n"
    "      --keep-seams       keep vertices split by texture seams apart (default: merge\n"
    "                         vertices that coincide in every frame while simplifying)\n"
    "      --lost-surface=W   weight of the lost-surface term (default 300): each frame's\n"
    "                         cost also counts how far the input vertices merged so far\n"
    "                         end up from the new triangles, which the quadrics miss on\n"
    "                         thin parts; 0: the paper's cost, quadrics alone (~50x faster)\n"
    "      --metro-step=N     measure every N-th frame (default 1: all)\n"
    "      --samples=N        Metro face samples per triangle (default 10)\n"
    "      --no-metro         write the levels only\n"
    "      --json             print one JSON object\n"
    "  -q, --quiet            print nothing but errors\n"
    "  -h, --help             show this help\n"
    CLI_MEMORY_HELP;

typedef struct level_summary {
    size_t triangles;
    size_t folds_from;
    double worst_rms;   /* % of the diagonal */
    size_t worst_frame;
    double mean_rms;    /* % of the diagonal, mean over measured frames */
} level_summary;

/* "faerie" from "dir/faerie.md2". */
static void path_stem(const char *path, char *stem, size_t size)
{
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    snprintf(stem, size, "%s", base);
    char *dot = strrchr(stem, '.');
    if (dot && dot != stem) *dot = '\0';
}

/* The extension lk_animation_write should use for an input path. */
static const char *output_extension(const char *path)
{
    const char *dot = strrchr(path, '.');
    if (dot && !strcasecmp(dot, ".md2")) return "md2";
    if (dot && !strcasecmp(dot, ".kmf")) return "kmf";
    return "gltf";
}

/* The output set is written as a whole: every file goes first to a hidden
 * OUTDIR/.pending-NAME (each one atomically, by the library's writers) and
 * only when all of them are complete are they renamed to their names. An
 * error half-way leaves the previous set untouched; a kill -9 can only
 * leave .pending-* files behind (safe to delete) or, during the renames,
 * a mix of two complete runs. */
typedef struct pending_set {
    char **final_paths;
    char **pending_paths;
    size_t count, capacity;
} pending_set;

/* Writes into `path` the hidden name to write NAME to, and remembers it. */
static int pending_add(pending_set *set, const char *outdir, const char *name, char *path, size_t size)
{
    if (set->count == set->capacity) {
        size_t capacity = set->capacity ? 2 * set->capacity : 16;
        char **finals = realloc(set->final_paths, capacity * sizeof *finals);
        if (!finals) return 0;
        set->final_paths = finals;
        char **pendings = realloc(set->pending_paths, capacity * sizeof *pendings);
        if (!pendings) return 0;
        set->pending_paths = pendings;
        set->capacity = capacity;
    }
    char final_path[4096];
    if (snprintf(final_path, sizeof final_path, "%s/%s", outdir, name) >= (int)sizeof final_path ||
        snprintf(path, size, "%s/.pending-%s", outdir, name) >= (int)size)
        return 0;
    char *final_copy = strdup(final_path), *pending_copy = strdup(path);
    if (!final_copy || !pending_copy) {
        free(final_copy);
        free(pending_copy);
        return 0;
    }
    set->final_paths[set->count] = final_copy;
    set->pending_paths[set->count++] = pending_copy;
    return 1;
}

/* commit: rename every pending file to its name; otherwise remove them. */
static lk_status pending_finish(pending_set *set, int commit, lk_error *error)
{
    lk_status status = LK_OK;
    for (size_t i = 0; i < set->count; i++) {
        if (commit && status == LK_OK && rename(set->pending_paths[i], set->final_paths[i]) != 0)
            status = lk_error_set(error, LK_ERR_IO, "%s: cannot rename into place: %s", set->final_paths[i],
                                  strerror(errno));
        if (!commit || status != LK_OK) unlink(set->pending_paths[i]);
        free(set->pending_paths[i]);
        free(set->final_paths[i]);
    }
    free(set->pending_paths);
    free(set->final_paths);
    memset(set, 0, sizeof *set);
    return status;
}

static int parse_schemes(const char *text, lk_anim_scheme *schemes, size_t *count)
{
    *count = 0;
    if (!strcmp(text, "all")) {
        schemes[0] = LK_ANIM_SCHEME_MAX, schemes[1] = LK_ANIM_SCHEME_AVG, schemes[2] = LK_ANIM_SCHEME_FRAME;
        *count = 3;
        return 1;
    }
    char buffer[64];
    snprintf(buffer, sizeof buffer, "%s", text);
    for (char *token = strtok(buffer, ","); token; token = strtok(NULL, ",")) {
        lk_anim_scheme scheme;
        if (lk_anim_scheme_parse(token, &scheme) != 0 || *count == 3) return 0;
        for (size_t i = 0; i < *count; i++)
            if (schemes[i] == scheme) return 0;
        schemes[(*count)++] = scheme;
    }
    return *count > 0;
}

static void scheme_label(lk_anim_scheme scheme, size_t frame, char *out, size_t size)
{
    if (scheme == LK_ANIM_SCHEME_FRAME) snprintf(out, size, "frame%zu", frame);
    else snprintf(out, size, "%s", lk_anim_scheme_name(scheme));
}

static lk_status write_csv(const char *path, const double *ratios, size_t level_count, const size_t *frames,
                           size_t frame_count, const lk_anim_simplify_result *results, const lk_metro_result *metro,
                           double diagonal, lk_error *error)
{
    lk__atomic_file file;
    lk_status status = lk__atomic_open(&file, path, error);
    if (status != LK_OK) return status;
    fprintf(file.file, "level,ratio,frame,triangles,mean,rms,max,rms_forward,rms_backward,rms_percent\n");
    for (size_t l = 0; l < level_count; l++)
        for (size_t k = 0; k < frame_count; k++) {
            const lk_metro_result *m = &metro[l * frame_count + k];
            double mean = fmax(m->forward.mean, m->backward.mean), rms = fmax(m->forward.rms, m->backward.rms);
            fprintf(file.file, "%zu,%.4g,%zu,%zu,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g\n", l + 1, ratios[l], frames[k],
                    results[l].animation.mesh.triangle_count, mean, rms, m->hausdorff, m->forward.rms, m->backward.rms,
                    diagonal > 0 ? 100 * rms / diagonal : 0);
        }
    return lk__atomic_commit(&file, error);
}

int command_animate(int argc, char **argv)
{
    enum { OPT_STRICT = 256, OPT_KEEP_SEAMS, OPT_METRO_STEP, OPT_SAMPLES, OPT_NO_METRO, OPT_JSON, OPT_LOST_SURFACE };
    static const struct option options[] = {
        {"scheme", required_argument, NULL, 's'},       {"frame", required_argument, NULL, 'f'},
        {"levels", required_argument, NULL, 'l'},       {"ratio", required_argument, NULL, 'r'},
        {"strict", no_argument, NULL, OPT_STRICT},      {"keep-seams", no_argument, NULL, OPT_KEEP_SEAMS},
        {"metro-step", required_argument, NULL, OPT_METRO_STEP},
        {"samples", required_argument, NULL, OPT_SAMPLES}, {"no-metro", no_argument, NULL, OPT_NO_METRO},
        {"lost-surface", required_argument, NULL, OPT_LOST_SURFACE},
        {"json", no_argument, NULL, OPT_JSON},          {"quiet", no_argument, NULL, 'q'},
        {"help", no_argument, NULL, 'h'},               {0}};
    lk_anim_scheme schemes[3] = {LK_ANIM_SCHEME_MAX};
    size_t scheme_count = 1, frame = 0, level_count = 10, metro_step = 1, samples = 10;
    double ratio = 0, lost_surface = LK_ANIM_LOST_SURFACE_DEFAULT;
    int strict = 0, keep_seams = 0, no_metro = 0, json = 0, quiet = 0, option;
    optind = 1;
    while ((option = getopt_long(argc, argv, "s:f:l:r:qh", options, NULL)) != -1) {
        switch (option) {
        case 's':
            if (!parse_schemes(optarg, schemes, &scheme_count))
                return usage_error("animate", "--scheme: '%s' is not max, avg, frame, a comma list of them or all",
                                   optarg);
            break;
        case 'f':
            if (!parse_size_option(optarg, &frame))
                return usage_error("animate", "--frame: '%s' is not a frame number", optarg);
            break;
        case 'l':
            if (!parse_size_option(optarg, &level_count) || level_count < 1 || level_count > 1000)
                return usage_error("animate", "--levels: '%s' is not a number of levels in 1..1000", optarg);
            break;
        case 'r':
            if (!parse_double_option(optarg, &ratio) || !(ratio > 0 && ratio <= 1))
                return usage_error("animate", "--ratio: '%s' is not a number in (0, 1]", optarg);
            break;
        case OPT_STRICT: strict = 1; break;
        case OPT_KEEP_SEAMS: keep_seams = 1; break;
        case OPT_METRO_STEP:
            if (!parse_size_option(optarg, &metro_step) || metro_step < 1)
                return usage_error("animate", "--metro-step: '%s' is not a positive integer", optarg);
            break;
        case OPT_SAMPLES:
            if (!parse_size_option(optarg, &samples) || samples < 1 || samples > 100000)
                return usage_error("animate", "--samples: '%s' is not a number in 1..100000", optarg);
            break;
        case OPT_LOST_SURFACE:
            if (!parse_double_option(optarg, &lost_surface) || !(lost_surface >= 0 && lost_surface <= 1e12))
                return usage_error("animate", "--lost-surface: '%s' is not a weight in [0, 1e12]", optarg);
            break;
        case OPT_NO_METRO: no_metro = 1; break;
        case OPT_JSON: json = 1; break;
        case 'q': quiet = 1; break;
        case 'h': fputs(animate_help, stdout); return EXIT_OK;
        default: return usage_error("animate", "%s", "unknown option");
        }
    }
    if (argc - optind != 2) return usage_error("animate", "%s", "expected IN and OUTDIR");
    const char *input = argv[optind], *outdir = argv[optind + 1];
    if (ratio > 0) level_count = 1;

    lk_error error = {0};
    lk_animation original;
    lk_animation_init(&original);
    lk_animation_read_options read_options;
    memset(&read_options, 0, sizeof read_options);
    read_options.max_bytes = cli_max_memory;
    if (lk_animation_read_ex(input, &read_options, &original, NULL, &error) != LK_OK) {
        print_error(&error);
        return EXIT_BAD_INPUT;
    }
    for (size_t i = 0; i < scheme_count; i++)
        if (schemes[i] == LK_ANIM_SCHEME_FRAME && frame >= original.frame_count) {
            fprintf(stderr, "lodkit animate: --frame %zu: %s has %zu frames\n", frame, input, original.frame_count);
            lk_animation_free(&original);
            return EXIT_USAGE;
        }
    if (mkdir(outdir, 0777) != 0 && errno != EEXIST) {
        fprintf(stderr, "lodkit: %s: cannot create the directory: %s\n", outdir, strerror(errno));
        lk_animation_free(&original);
        return EXIT_BAD_INPUT;
    }
    char stem[200];
    path_stem(input, stem, sizeof stem);
    const char *extension = output_extension(input);

    double *ratios = lk__malloc_array(level_count, sizeof(double));
    size_t frame_count = (original.frame_count + metro_step - 1) / metro_step;
    size_t *frames = lk__malloc_array(frame_count, sizeof(size_t));
    lk_anim_simplify_result *results = lk__calloc_array(scheme_count * level_count, sizeof *results);
    lk_metro_result *metro = no_metro ? NULL : lk__malloc_array(scheme_count * level_count * frame_count,
                                                                sizeof(lk_metro_result));
    double *values = no_metro ? NULL : lk__malloc_array(scheme_count * level_count * frame_count, sizeof(double));
    level_summary *summaries = lk__calloc_array(scheme_count * level_count, sizeof *summaries);
    int exit_code = EXIT_OK;
    pending_set pending = {0};
    if (!ratios || !frames || !results || (!no_metro && (!metro || !values)) || !summaries) {
        lk_error_set(&error, LK_ERR_NOMEM, "out of memory for %zu levels x %zu frames", level_count, frame_count);
        print_error(&error);
        exit_code = EXIT_BAD_INPUT;
        goto done;
    }
    for (size_t l = 0; l < level_count; l++) ratios[l] = ratio > 0 ? ratio : (double)(l + 1) / (double)level_count;
    for (size_t k = 0; k < frame_count; k++) frames[k] = k * metro_step;

    lk_metro_options metro_options;
    lk_metro_options_default(&metro_options);
    metro_options.samples_per_face = (double)samples;
    double diagonal = 0;
    for (size_t i = 0; i < scheme_count && exit_code == EXIT_OK; i++) {
        char label[64], path[4096];
        scheme_label(schemes[i], frame, label, sizeof label);
        lk_anim_simplify_options simplify_options;
        lk_anim_simplify_options_default(&simplify_options);
        simplify_options.scheme = schemes[i];
        simplify_options.frame = frame;
        simplify_options.allow_folds = !strict;
        simplify_options.keep_seams = keep_seams;
        simplify_options.lost_surface = lost_surface;
        progress_state progress;
        progress_init(&progress, quiet || json, label);
        lk_anim_simplify_result *level_results = results + i * level_count;
        lk_status status = lk_animation_simplify_levels(&original, &simplify_options, ratios, level_count,
                                                        level_results, progress_draw, &progress, &error);
        progress_done(&progress);
        for (size_t l = 0; l < level_count && status == LK_OK; l++) {
            char name[512];
            if (ratio > 0) snprintf(name, sizeof name, "%s-%s.%s", stem, label, extension);
            else snprintf(name, sizeof name, "%s-%s-L%02zu.%s", stem, label, l + 1, extension);
            if (!pending_add(&pending, outdir, name, path, sizeof path))
                status = lk_error_set(&error, LK_ERR_NOMEM, "%s/%s: path too long or out of memory", outdir, name);
            else
                status = lk_animation_write(path, &level_results[l].animation, &error);
            level_summary *summary = &summaries[i * level_count + l];
            summary->triangles = level_results[l].animation.mesh.triangle_count;
            summary->folds_from = level_results[l].folds_from_triangles;
            diagonal = level_results[l].diagonal;
        }
        if (status == LK_OK && !no_metro) {
            progress_init(&progress, quiet || json, "metro");
            for (size_t l = 0; l < level_count && status == LK_OK; l++) {
                lk_metro_result *rows = metro + (i * level_count + l) * frame_count;
                status = lk_animation_metro(&level_results[l].animation, &original, frames, frame_count,
                                            &metro_options, rows, NULL, NULL, &error);
                level_summary *summary = &summaries[i * level_count + l];
                for (size_t k = 0; k < frame_count && status == LK_OK; k++) {
                    double rms = fmax(rows[k].forward.rms, rows[k].backward.rms);
                    double percent = diagonal > 0 ? 100 * rms / diagonal : 0;
                    values[(i * level_count + l) * frame_count + k] = percent;
                    if (k == 0 || percent > summary->worst_rms) summary->worst_rms = percent, summary->worst_frame = frames[k];
                    summary->mean_rms += percent / (double)frame_count;
                }
                progress_draw(&progress, (double)(l + 1) / (double)level_count, "metro");
            }
            progress_done(&progress);
            char name[512];
            snprintf(name, sizeof name, "%s-%s.csv", stem, label);
            if (status == LK_OK && !pending_add(&pending, outdir, name, path, sizeof path))
                status = lk_error_set(&error, LK_ERR_NOMEM, "%s/%s: path too long or out of memory", outdir, name);
            if (status == LK_OK)
                status = write_csv(path, ratios, level_count, frames, frame_count, level_results,
                                   metro + i * level_count * frame_count, diagonal, &error);
        }
        if (status != LK_OK) {
            print_error(&error);
            exit_code = EXIT_BAD_INPUT;
        }
    }
    /* heat maps on one colour scale */
    if (exit_code == EXIT_OK && !no_metro) {
        double low = INFINITY, high = 0;
        for (size_t i = 0; i < scheme_count * level_count * frame_count; i++)
            if (values[i] > 0) low = fmin(low, values[i]), high = fmax(high, values[i]);
        for (size_t i = 0; i < scheme_count && exit_code == EXIT_OK; i++) {
            char label[64], title[512], path[4096];
            scheme_label(schemes[i], frame, label, sizeof label);
            snprintf(title, sizeof title, "%s, scheme %s: RMS distance to the original frame", stem, label);
            unsigned char *rgba = NULL;
            unsigned width = 0, height = 0;
            /* three decades at most: rounding noise (1e-16 at 100%) must not stretch the scale */
            double scale_low = isfinite(low) ? fmax(low, high * 1e-3) : 0;
            lk_status status = lk_anim_error_map(values + i * level_count * frame_count, level_count, frame_count,
                                                 ratios, frames, scale_low, high, title, "RMS %",
                                                 &rgba, &width, &height, &error);
            char name[512];
            snprintf(name, sizeof name, "%s-%s-rms.png", stem, label);
            if (status == LK_OK && !pending_add(&pending, outdir, name, path, sizeof path))
                status = lk_error_set(&error, LK_ERR_NOMEM, "%s/%s: path too long or out of memory", outdir, name);
            if (status == LK_OK) status = lk_image_write_png(path, rgba, width, height, &error);
            free(rgba);
            if (status != LK_OK) {
                print_error(&error);
                exit_code = EXIT_BAD_INPUT;
            }
        }
    }
    {
        lk_status status = pending_finish(&pending, exit_code == EXIT_OK, &error);
        if (status != LK_OK) {
            print_error(&error);
            exit_code = EXIT_BAD_INPUT;
        }
    }
    if (exit_code == EXIT_OK && json) {
        cJSON *root = cJSON_CreateObject();
        cJSON_AddStringToObject(root, "input", input);
        cJSON_AddNumberToObject(root, "vertices", (double)original.mesh.vertex_count);
        cJSON_AddNumberToObject(root, "triangles", (double)original.mesh.triangle_count);
        cJSON_AddNumberToObject(root, "frames", (double)original.frame_count);
        cJSON_AddNumberToObject(root, "diagonal", diagonal);
        cJSON *list = cJSON_AddArrayToObject(root, "schemes");
        for (size_t i = 0; i < scheme_count; i++) {
            char label[64];
            scheme_label(schemes[i], frame, label, sizeof label);
            cJSON *entry = cJSON_CreateObject();
            cJSON_AddStringToObject(entry, "scheme", label);
            cJSON_AddNumberToObject(entry, "seconds", results[i * level_count + 0].seconds);
            cJSON_AddNumberToObject(entry, "working_bytes", (double)results[i * level_count].working_bytes);
            cJSON *levels = cJSON_AddArrayToObject(entry, "levels");
            for (size_t l = 0; l < level_count; l++) {
                const level_summary *summary = &summaries[i * level_count + l];
                cJSON *level = cJSON_CreateObject();
                cJSON_AddNumberToObject(level, "ratio", ratios[l]);
                cJSON_AddNumberToObject(level, "triangles", (double)summary->triangles);
                cJSON_AddBoolToObject(level, "target_reached", results[i * level_count + l].target_reached);
                cJSON_AddNumberToObject(level, "folds_from_triangles", (double)summary->folds_from);
                if (!no_metro) {
                    cJSON_AddNumberToObject(level, "worst_rms_percent", summary->worst_rms);
                    cJSON_AddNumberToObject(level, "worst_frame", (double)summary->worst_frame);
                    cJSON_AddNumberToObject(level, "mean_rms_percent", summary->mean_rms);
                }
                cJSON_AddItemToArray(levels, level);
            }
            cJSON_AddItemToArray(list, entry);
        }
        print_json(root);
    } else if (exit_code == EXIT_OK && !quiet) {
        printf("%s: %s vertices, %s triangles, %zu frames; diagonal %.6g\n", input,
               thousands(original.mesh.vertex_count), thousands(original.mesh.triangle_count), original.frame_count,
               diagonal);
        for (size_t i = 0; i < scheme_count; i++) {
            char label[64];
            scheme_label(schemes[i], frame, label, sizeof label);
            const lk_anim_simplify_result *last = &results[i * level_count + level_count - 1];
            printf("\nscheme %s: %.3f s for %zu levels, %s bytes of per-frame quadrics\n", label, last->seconds,
                   level_count, thousands(last->working_bytes));
            printf("| level | kept | triangles | worst-frame RMS %% | (frame) | mean RMS %% | note |\n");
            printf("|---:|---:|---:|---:|---:|---:|---|\n");
            for (size_t l = 0; l < level_count; l++) {
                const level_summary *summary = &summaries[i * level_count + l];
                const lk_anim_simplify_result *result = &results[i * level_count + l];
                char note[96] = "";
                if (!result->target_reached) snprintf(note, sizeof note, "target not reached (folds)");
                else if (summary->folds_from)
                    snprintf(note, sizeof note, "folds allowed below %zu triangles", summary->folds_from);
                if (no_metro)
                    printf("| %zu | %g%% | %zu | - | - | - | %s |\n", l + 1, 100 * ratios[l], summary->triangles, note);
                else
                    printf("| %zu | %g%% | %zu | %.4f | %zu | %.4f | %s |\n", l + 1, 100 * ratios[l], summary->triangles,
                           summary->worst_rms, summary->worst_frame, summary->mean_rms, note);
            }
        }
    }
done:
    pending_finish(&pending, 0, NULL);
    if (results)
        for (size_t i = 0; i < scheme_count * level_count; i++) lk_anim_simplify_result_free(&results[i]);
    free(results), free(ratios), free(frames), free(metro), free(values), free(summaries);
    lk_animation_free(&original);
    return exit_code;
}
