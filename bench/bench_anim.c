/* SPDX-License-Identifier: MIT */
/* Deformation-sensitive simplification (issue 6, the paper's Fig. 8): the
 * max, avg and single-frame (frame 0) schemes on real key-frame animations,
 * 10 levels (level k keeps 10k% of the triangles) x every frame, Metro
 * between each simplified frame and the original frame.
 *
 *   bench_anim [--out DIR] [--metro-step N] [SAMPLES_DIR]
 *
 * Models: faerie.md2 and sydney.md2 (Quake II, 198 frames each), the
 * skinned glTF simple_skin (reported, but only if it has enough vertices to
 * be meaningful) and Khronos' skinned RiggedFigure (every animation at
 * 30 fps; fetched for the bench only). Prints, per model, the simplification time and per-frame
 * memory of each scheme, the fold floor (where every contraction would fold
 * a triangle in some frame; below it only frame 0 is checked), and per
 * level the worst-frame RMS and the mean RMS over frames of each scheme
 * (% of the diagonal of all frames; RMS = the larger of the two Metro
 * directions). Writes DIR/anim_<model>_<scheme>.csv (the columns of
 * `lodkit animate`) and DIR/anim_<model>_<scheme>_rms.png (heat map level x
 * frame, one colour scale per model). A last table repeats faerie with
 * texture seams kept apart (lk_anim_simplify_options.keep_seams), and one
 * more compares max with the single-frame scheme for other frames K than
 * 0 at 50%, 20% and 10% (is frame 0 a typical choice?). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include "lodkit.h"

#define LEVELS 10
#define SCHEMES 3

static const lk_anim_scheme schemes[SCHEMES] = {LK_ANIM_SCHEME_MAX, LK_ANIM_SCHEME_AVG, LK_ANIM_SCHEME_FRAME};
static const char *const scheme_labels[SCHEMES] = {"max", "avg", "frame0"};

typedef struct scheme_run {
    lk_anim_simplify_result levels[LEVELS];
    double *rms; /* LEVELS * frame_count, % of the diagonal */
    double worst[LEVELS], mean[LEVELS];
    size_t worst_frame[LEVELS];
    size_t strict_floor; /* triangles left at 10% without folds */
    double seconds;
} scheme_run;

static int fail(const char *what, const lk_error *error)
{
    fprintf(stderr, "bench_anim: %s: %s\n", what, error->message);
    return 1;
}

static int write_csv(const char *path, const double *ratios, const size_t *frames, size_t frame_count,
                     const scheme_run *run, const lk_metro_result *metro, double diagonal)
{
    FILE *file = fopen(path, "w");
    if (!file) return 0;
    fprintf(file, "level,ratio,frame,triangles,mean,rms,max,rms_forward,rms_backward,rms_percent\n");
    for (size_t l = 0; l < LEVELS; l++)
        for (size_t k = 0; k < frame_count; k++) {
            const lk_metro_result *m = &metro[l * frame_count + k];
            double rms = fmax(m->forward.rms, m->backward.rms);
            fprintf(file, "%zu,%.4g,%zu,%zu,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g\n", l + 1, ratios[l], frames[k],
                    run->levels[l].animation.mesh.triangle_count, fmax(m->forward.mean, m->backward.mean), rms,
                    m->hausdorff, m->forward.rms, m->backward.rms, 100 * rms / diagonal);
        }
    return fclose(file) == 0;
}

/* Simplifies with every scheme, measures, prints, writes. */
static int bench_model(const char *path, const char *name, const char *out_dir, size_t metro_step, int keep_seams,
                       int brief)
{
    lk_error error = {0};
    lk_animation original;
    lk_animation_init(&original);
    /* glTF exporters such as COLLADA2GLTF write one animation per joint:
     * play them all, sampled at 30 frames per second. */
    lk_animation_read_options read_options;
    memset(&read_options, 0, sizeof read_options);
    const char *dot = strrchr(path, '.');
    if (dot && !strcmp(dot, ".gltf")) {
        read_options.all_animations = 1;
        read_options.frames_per_second = 30;
    }
    if (lk_animation_read_ex(path, &read_options, &original, NULL, &error) != LK_OK) {
        printf("%s: not measured (%s)\n\n", name, error.message);
        return 0;
    }
    if (original.mesh.vertex_count < 100 || original.frame_count < 2) {
        printf("%s: %zu vertices, %zu triangles, %zu frames: too small to be meaningful, skipped\n\n", name,
               original.mesh.vertex_count, original.mesh.triangle_count, original.frame_count);
        lk_animation_free(&original);
        return 0;
    }
    double ratios[LEVELS];
    for (size_t l = 0; l < LEVELS; l++) ratios[l] = (double)(l + 1) / LEVELS;
    size_t frame_count = (original.frame_count + metro_step - 1) / metro_step;
    size_t *frames = malloc(frame_count * sizeof *frames);
    lk_metro_result *metro = malloc(LEVELS * frame_count * sizeof *metro);
    scheme_run *runs = calloc(SCHEMES, sizeof *runs);
    if (!frames || !metro || !runs) {
        fprintf(stderr, "bench_anim: out of memory\n");
        return 1;
    }
    for (size_t k = 0; k < frame_count; k++) frames[k] = k * metro_step;
    lk_metro_options metro_options;
    lk_metro_options_default(&metro_options);
    double diagonal = 0;
    int status = 0;
    for (int s = 0; s < SCHEMES && !status; s++) {
        scheme_run *run = &runs[s];
        lk_anim_simplify_options options;
        lk_anim_simplify_options_default(&options);
        options.scheme = schemes[s];
        options.frame = 0;
        options.keep_seams = keep_seams;
        /* the fold floor: strict, down to 10% */
        lk_anim_simplify_result strict;
        options.simplify.target_ratio = 0.1;
        if (lk_animation_simplify(&original, &options, &strict, NULL, NULL, &error) != LK_OK)
            return fail("strict", &error);
        run->strict_floor = strict.animation.mesh.triangle_count;
        lk_anim_simplify_result_free(&strict);
        options.simplify.target_ratio = 0;
        options.allow_folds = 1;
        if (lk_animation_simplify_levels(&original, &options, ratios, LEVELS, run->levels, NULL, NULL, &error) != LK_OK)
            return fail("levels", &error);
        run->seconds = run->levels[0].seconds; /* the smallest level is taken last */
        diagonal = run->levels[0].diagonal;
        run->rms = malloc(LEVELS * frame_count * sizeof(double));
        if (!run->rms) return fail("rms", &error);
        for (size_t l = 0; l < LEVELS; l++) {
            lk_metro_result *rows = metro + l * frame_count;
            if (lk_animation_metro(&run->levels[l].animation, &original, frames, frame_count, &metro_options, rows,
                                   NULL, NULL, &error) != LK_OK)
                return fail("metro", &error);
            run->worst[l] = -1, run->mean[l] = 0;
            for (size_t k = 0; k < frame_count; k++) {
                double rms = 100 * fmax(rows[k].forward.rms, rows[k].backward.rms) / diagonal;
                run->rms[l * frame_count + k] = rms;
                if (rms > run->worst[l]) run->worst[l] = rms, run->worst_frame[l] = frames[k];
                run->mean[l] += rms / (double)frame_count;
            }
        }
        if (out_dir && !brief) {
            char file[4096];
            snprintf(file, sizeof file, "%s/anim_%s_%s.csv", out_dir, name, scheme_labels[s]);
            if (!write_csv(file, ratios, frames, frame_count, run, metro, diagonal))
                fprintf(stderr, "bench_anim: cannot write %s\n", file);
        }
    }
    if (!brief) {
        printf("### %s: %zu vertices, %zu triangles, %zu frames (%zu measured), diagonal %.4g\n\n", name,
               original.mesh.vertex_count, original.mesh.triangle_count, original.frame_count, frame_count, diagonal);
        printf(
            "| scheme | seconds (10 levels) | per-frame quadrics | strict floor (triangles, no fold in any frame) |\n");
        printf("|---|---:|---:|---:|\n");
        for (int s = 0; s < SCHEMES; s++)
            printf("| %s | %.3f | %.1f MB | %zu (%.0f%%) |\n", scheme_labels[s], runs[s].seconds,
                   runs[s].levels[0].working_bytes / 1e6, runs[s].strict_floor,
                   100.0 * (double)runs[s].strict_floor / (double)original.mesh.triangle_count);
        printf("\nWorst-frame RMS and mean RMS over frames, %% of the diagonal (lower is better; * = best of the "
               "three; triangles max/avg/frame0; f = folds allowed at this level):\n\n");
        printf("| level | triangles | worst max | worst avg | worst frame0 | mean max | mean avg | mean frame0 | max "
               "vs avg (worst) |\n");
        printf("|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    } else {
        printf("| level | triangles | worst max | worst avg | worst frame0 | mean max | mean avg | mean frame0 | max "
               "vs avg (worst) |\n");
        printf("|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    }
    for (size_t l = 0; l + 1 < LEVELS; l++) {
        char worst[SCHEMES][32], mean[SCHEMES][32];
        double best_worst = INFINITY, best_mean = INFINITY;
        for (int s = 0; s < SCHEMES; s++) {
            best_worst = fmin(best_worst, runs[s].worst[l]);
            best_mean = fmin(best_mean, runs[s].mean[l]);
        }
        for (int s = 0; s < SCHEMES; s++) {
            snprintf(worst[s], sizeof worst[s], "%.4f%s", runs[s].worst[l], runs[s].worst[l] == best_worst ? "*" : "");
            snprintf(mean[s], sizeof mean[s], "%.4f%s", runs[s].mean[l], runs[s].mean[l] == best_mean ? "*" : "");
        }
        char triangles[64];
        snprintf(triangles, sizeof triangles, "%zu%s/%zu%s/%zu%s", runs[0].levels[l].animation.mesh.triangle_count,
                 runs[0].levels[l].folds_from_triangles ? "f" : "", runs[1].levels[l].animation.mesh.triangle_count,
                 runs[1].levels[l].folds_from_triangles ? "f" : "", runs[2].levels[l].animation.mesh.triangle_count,
                 runs[2].levels[l].folds_from_triangles ? "f" : "");
        printf("| %zu (%zu%%) | %s | %s | %s | %s | %s | %s | %s | %+.1f%% |\n", l + 1, (l + 1) * 10, triangles,
               worst[0], worst[1], worst[2], mean[0], mean[1], mean[2],
               100 * (runs[0].worst[l] / runs[1].worst[l] - 1));
    }
    printf("\n");
    /* heat maps on one colour scale per model */
    if (out_dir && !brief) {
        double low = INFINITY, high = 0;
        for (int s = 0; s < SCHEMES; s++)
            for (size_t i = 0; i < LEVELS * frame_count; i++)
                if (runs[s].rms[i] > 0) low = fmin(low, runs[s].rms[i]), high = fmax(high, runs[s].rms[i]);
        low = fmax(low, high * 1e-3);
        for (int s = 0; s < SCHEMES; s++) {
            char title[256], file[4096];
            snprintf(title, sizeof title, "%s, scheme %s: RMS distance to the original frame", name, scheme_labels[s]);
            unsigned char *rgba = NULL;
            unsigned width, height;
            snprintf(file, sizeof file, "%s/anim_%s_%s_rms.png", out_dir, name, scheme_labels[s]);
            if (lk_anim_error_map(runs[s].rms, LEVELS, frame_count, ratios, frames, low, high, title, "RMS %", &rgba,
                                  &width, &height, &error) != LK_OK ||
                lk_image_write_png(file, rgba, width, height, &error) != LK_OK)
                fprintf(stderr, "bench_anim: %s: %s\n", file, error.message);
            lk_free(rgba);
        }
    }
    for (int s = 0; s < SCHEMES; s++) {
        for (size_t l = 0; l < LEVELS; l++) lk_anim_simplify_result_free(&runs[s].levels[l]);
        free(runs[s].rms);
    }
    free(runs), free(frames), free(metro);
    lk_animation_free(&original);
    return status;
}

/* Worst-frame RMS (% of the diagonal) of each level of `levels`. */
static int worst_of_levels(const lk_animation *original, const lk_anim_simplify_result *levels, size_t level_count,
                           size_t metro_step, double *worst)
{
    size_t frame_count = (original->frame_count + metro_step - 1) / metro_step;
    size_t *frames = malloc(frame_count * sizeof *frames);
    lk_metro_result *rows = malloc(frame_count * sizeof *rows);
    if (!frames || !rows) {
        free(frames), free(rows);
        fprintf(stderr, "bench_anim: out of memory\n");
        return 1;
    }
    for (size_t k = 0; k < frame_count; k++) frames[k] = k * metro_step;
    lk_metro_options metro_options;
    lk_metro_options_default(&metro_options);
    lk_error error = {0};
    for (size_t l = 0; l < level_count; l++) {
        if (lk_animation_metro(&levels[l].animation, original, frames, frame_count, &metro_options, rows, NULL, NULL,
                               &error) != LK_OK) {
            free(frames), free(rows);
            return fail("metro", &error);
        }
        worst[l] = 0;
        for (size_t k = 0; k < frame_count; k++)
            worst[l] = fmax(worst[l], 100 * fmax(rows[k].forward.rms, rows[k].backward.rms) / levels[l].diagonal);
    }
    free(frames), free(rows);
    return 0;
}

/* The levels of the two tables below: 50%, 20% and 10% of the triangles. */
static const double three_ratios[3] = {0.5, 0.2, 0.1};

/* Reads an animation for a table; 0 (and a line saying why) when it cannot. */
static int read_for_table(const char *path, const char *name, lk_animation *original)
{
    lk_error error = {0};
    lk_animation_init(original);
    if (lk_animation_read(path, original, &error) == LK_OK) return 1;
    printf("%s: not measured (%s)\n\n", name, error.message);
    return 0;
}

/* Max against the single-frame scheme for several frames K: worst-frame
 * RMS at 50%, 20% and 10% (folds allowed, as in the tables above). */
static int bench_frames_k(const char *path, const char *name, size_t metro_step)
{
    enum { K_LEVELS = 3 };
    const double *ratios = three_ratios;
    lk_error error = {0};
    lk_animation original;
    if (!read_for_table(path, name, &original)) return 0;
    printf("### %s: max against the single-frame scheme for other frames K (worst-frame RMS, %% of the diagonal)\n\n",
           name);
    printf("| scheme | 50%% | 20%% | 10%% | triangles |\n|---|---:|---:|---:|---:|\n");
    /* frames K = 0, 20, 40, ... and the last; the max scheme first */
    size_t ks[64], k_count = 0;
    for (size_t k = 0; k < original.frame_count && k_count + 1 < 64; k += 20) ks[k_count++] = k;
    if (ks[k_count - 1] != original.frame_count - 1) ks[k_count++] = original.frame_count - 1;
    double max_worst[K_LEVELS] = {0};
    size_t beaten[K_LEVELS] = {0};
    int status = 0;
    for (size_t run = 0; run <= k_count && !status; run++) {
        lk_anim_simplify_options options;
        lk_anim_simplify_options_default(&options);
        options.allow_folds = 1;
        options.scheme = run == 0 ? LK_ANIM_SCHEME_MAX : LK_ANIM_SCHEME_FRAME;
        options.frame = run == 0 ? 0 : ks[run - 1];
        lk_anim_simplify_result levels[K_LEVELS];
        if (lk_animation_simplify_levels(&original, &options, ratios, K_LEVELS, levels, NULL, NULL, &error) != LK_OK) {
            lk_animation_free(&original);
            return fail("levels", &error);
        }
        double worst[K_LEVELS];
        status = worst_of_levels(&original, levels, K_LEVELS, metro_step, worst);
        if (!status) {
            char label[32];
            if (run == 0)
                snprintf(label, sizeof label, "max");
            else
                snprintf(label, sizeof label, "frame %zu", options.frame);
            printf("| %s | %.4f | %.4f | %.4f | %zu/%zu/%zu |\n", label, worst[0], worst[1], worst[2],
                   levels[0].animation.mesh.triangle_count, levels[1].animation.mesh.triangle_count,
                   levels[2].animation.mesh.triangle_count);
            for (int l = 0; l < K_LEVELS; l++) {
                if (run == 0)
                    max_worst[l] = worst[l];
                else
                    beaten[l] += max_worst[l] < worst[l];
            }
        }
        for (int l = 0; l < K_LEVELS; l++) lk_anim_simplify_result_free(&levels[l]);
    }
    if (!status)
        printf("\nmax is below the single-frame scheme for %zu / %zu / %zu of %zu frames K at 50%% / 20%% / 10%%\n\n",
               beaten[0], beaten[1], beaten[2], k_count);
    lk_animation_free(&original);
    return status;
}

/* The lost-surface term's weight (0: the paper's cost, quadrics alone):
 * worst-frame RMS of the three schemes at 50 / 20 / 10%. */
static int bench_lost_surface(const char *path, const char *name, size_t metro_step)
{
    enum { L_LEVELS = 3, WEIGHTS = 4 };
    const double *ratios = three_ratios;
    const double weights[WEIGHTS] = {0, 100, LK_ANIM_LOST_SURFACE_DEFAULT, 1000};
    lk_error error = {0};
    lk_animation original;
    if (!read_for_table(path, name, &original)) return 0;
    printf("### %s: the lost-surface weight (worst-frame RMS, %% of the diagonal; 0 = the paper's cost; "
           "* = best scheme of the row's weight and level)\n\n",
           name);
    printf("| weight | scheme | 50%% | 20%% | 10%% | triangles | seconds |\n|---:|---|---:|---:|---:|---:|---:|\n");
    int status = 0;
    for (int w = 0; w < WEIGHTS && !status; w++) {
        double worst[3][L_LEVELS], seconds[3];
        size_t triangles[3][L_LEVELS];
        for (int s = 0; s < 3 && !status; s++) {
            lk_anim_simplify_options options;
            lk_anim_simplify_options_default(&options);
            options.allow_folds = 1;
            options.scheme = schemes[s];
            options.lost_surface = weights[w];
            lk_anim_simplify_result levels[L_LEVELS];
            if (lk_animation_simplify_levels(&original, &options, ratios, L_LEVELS, levels, NULL, NULL, &error) !=
                LK_OK) {
                lk_animation_free(&original);
                return fail("levels", &error);
            }
            seconds[s] = levels[L_LEVELS - 1].seconds;
            status = worst_of_levels(&original, levels, L_LEVELS, metro_step, worst[s]);
            for (int l = 0; l < L_LEVELS; l++) {
                triangles[s][l] = levels[l].animation.mesh.triangle_count;
                lk_anim_simplify_result_free(&levels[l]);
            }
        }
        for (int s = 0; s < 3 && !status; s++) {
            printf("| %g | %s |", weights[w], s == 2 ? "frame0" : lk_anim_scheme_name(schemes[s]));
            for (int l = 0; l < L_LEVELS; l++) {
                int best = worst[s][l] <= worst[0][l] && worst[s][l] <= worst[1][l] && worst[s][l] <= worst[2][l];
                printf(" %.4f%s |", worst[s][l], best ? "*" : "");
            }
            printf(" %zu/%zu/%zu | %.3f |\n", triangles[s][0], triangles[s][1], triangles[s][2], seconds[s]);
        }
    }
    printf("\n");
    lk_animation_free(&original);
    return status;
}

int main(int argc, char **argv)
{
    const char *samples = "data/samples", *out_dir = NULL;
    size_t metro_step = 1;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--out") && i + 1 < argc)
            out_dir = argv[++i];
        else if (!strcmp(argv[i], "--metro-step") && i + 1 < argc)
            metro_step = (size_t)strtoul(argv[++i], NULL, 10);
        else if (argv[i][0] == '-') {
            fprintf(stderr, "usage: bench_anim [--out DIR] [--metro-step N] [SAMPLES_DIR]\n");
            return 2;
        } else
            samples = argv[i];
    }
    if (metro_step < 1) metro_step = 1;
    if (out_dir) mkdir(out_dir, 0777);
    char path[4096];
    int status = 0;
    struct {
        const char *file, *name;
    } models[] = {
        {"faerie.md2", "faerie"},
        {"assimp/MD2/sydney.md2", "sydney"},
        {"assimp/glTF2/simple_skin/simple_skin.gltf", "simple_skin"},
        /* fetched by `scripts/fetch-samples.sh --bench` (make bench) */
        {"RiggedFigure/RiggedFigure.gltf", "RiggedFigure"},
    };
    for (size_t m = 0; m < sizeof models / sizeof models[0] && !status; m++) {
        snprintf(path, sizeof path, "%s/%s", samples, models[m].file);
        status = bench_model(path, models[m].name, out_dir, metro_step, 0, 0);
    }
    if (!status) {
        printf("### faerie with texture seams kept apart (keep_seams: seams are borders, copies may move apart)\n\n");
        snprintf(path, sizeof path, "%s/%s", samples, models[0].file);
        status = bench_model(path, "faerie_seams", out_dir, metro_step, 1, 1);
    }
    if (!status) {
        snprintf(path, sizeof path, "%s/%s", samples, models[0].file);
        status = bench_frames_k(path, "faerie", metro_step);
    }
    for (size_t m = 0; m < 2 && !status; m++) {
        snprintf(path, sizeof path, "%s/%s", samples, models[m].file);
        status = bench_lost_surface(path, models[m].name, metro_step);
    }
    return status;
}
