/* SPDX-License-Identifier: MIT */
/* Benchmark of lk_metro, and helpers for the independent check with Open3D
 * (bench/metro_open3d.py).
 *
 *   bench_metro [--threads N] [SAMPLES_DIR]
 *       For each sample model (default data/samples): lk_metro of the model
 *       against itself and against a copy translated by 1% of its diagonal
 *       along x, best of 3, as a table. Speed is forward + backward samples
 *       per wall-clock second, index building included.
 *   bench_metro --write-perturbed OUT [SAMPLES_DIR]
 *       Writes the bunny with every vertex moved along a pseudo-random
 *       direction by up to 0.5% of the diagonal (deterministic).
 *   bench_metro --pair A B [--samples-per-face N] [--threads N]
 *       lk_metro of two files, printed as JSON with the keys that
 *       metro_open3d.py prints.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "lodkit.h"

static const char *const models[] = {"bunny.obj", "cow.off", "triceratops.off", "fandisk.off",
                                     "ChineseDragon-10kv.off"};

static int load(const char *path, lk_mesh *mesh)
{
    lk_error error = {0};
    if (lk_mesh_read(path, LK_FORMAT_AUTO, NULL, mesh, &error) != LK_OK) {
        fprintf(stderr, "bench_metro: %s\n", error.message);
        return 1;
    }
    return 0;
}

/* Best (shortest) of three runs; the results are identical each time. */
static int best_of_three(const lk_mesh *a, const lk_mesh *b, const lk_metro_options *options, lk_metro_result *best)
{
    for (int run = 0; run < 3; run++) {
        lk_metro_result result;
        lk_error error = {0};
        if (lk_metro(a, b, options, &result, NULL, NULL, &error) != LK_OK) {
            fprintf(stderr, "bench_metro: %s\n", error.message);
            return 1;
        }
        if (run == 0 || result.seconds < best->seconds) *best = result;
    }
    return 0;
}

static void print_row(const char *model, const char *against, size_t triangles, const lk_metro_result *r)
{
    printf("%-24s %-12s %10zu %10zu %9.3f %11.2f %12.6f\n", model, against, triangles, r->sample_count, r->seconds,
           (double)r->sample_count / r->seconds / 1e6, 100.0 * r->hausdorff / r->diagonal);
}

static int run_table(const char *samples_dir, int threads)
{
    lk_metro_options options;
    lk_metro_options_default(&options);
    options.thread_count = threads;
    printf("%-24s %-12s %10s %10s %9s %11s %12s\n", "model", "against", "triangles", "samples", "seconds", "Msamples/s",
           "hausdorff %");
    for (size_t i = 0; i < sizeof models / sizeof models[0]; i++) {
        char path[4096];
        snprintf(path, sizeof path, "%s/%s", samples_dir, models[i]);
        lk_mesh mesh, moved;
        if (load(path, &mesh)) return 1;
        lk_error error = {0};
        if (lk_mesh_copy(&moved, &mesh, &error) != LK_OK) {
            fprintf(stderr, "bench_metro: %s\n", error.message);
            lk_mesh_free(&mesh);
            return 1;
        }
        lk_mesh_translate(&moved, 0.01 * lk_mesh_bounds(&mesh, NULL, NULL), 0, 0);
        lk_metro_result self, translated;
        int failed =
            best_of_three(&mesh, &mesh, &options, &self) || best_of_three(&mesh, &moved, &options, &translated);
        if (!failed) {
            print_row(models[i], "itself", mesh.triangle_count, &self);
            print_row(models[i], "moved 1%", mesh.triangle_count, &translated);
        }
        lk_mesh_free(&mesh);
        lk_mesh_free(&moved);
        if (failed) return 1;
    }
    return 0;
}

/* splitmix64, for a deterministic perturbation independent of the library. */
static uint64_t next_random(uint64_t *state)
{
    uint64_t x = (*state += 0x9E3779B97F4A7C15ull);
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
    x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
    return x ^ (x >> 31);
}

static double next_unit(uint64_t *state) { return (double)(next_random(state) >> 11) / 9007199254740992.0; }

static int write_perturbed(const char *out, const char *samples_dir)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/bunny.obj", samples_dir);
    lk_mesh mesh;
    if (load(path, &mesh)) return 1;
    double reach = 0.005 * lk_mesh_bounds(&mesh, NULL, NULL);
    uint64_t state = 2024;
    for (size_t v = 0; v < mesh.vertex_count; v++) {
        /* uniform direction on the sphere, uniform length in [0, reach] */
        double z = 2 * next_unit(&state) - 1, angle = 6.283185307179586 * next_unit(&state);
        double ring = sqrt(1 - z * z), length = reach * next_unit(&state);
        float *p = mesh.positions + 3 * v;
        p[0] = (float)(p[0] + length * ring * cos(angle));
        p[1] = (float)(p[1] + length * ring * sin(angle));
        p[2] = (float)(p[2] + length * z);
    }
    lk_error error = {0};
    int failed = lk_mesh_write(out, LK_FORMAT_AUTO, &mesh, NULL, &error) != LK_OK;
    if (failed)
        fprintf(stderr, "bench_metro: %s\n", error.message);
    else
        printf("wrote %s: bunny with vertices moved by up to 0.5%% of the diagonal\n", out);
    lk_mesh_free(&mesh);
    return failed;
}

static void print_stats(const char *name, const lk_distance_stats *s, const char *after)
{
    printf("  \"%s\": {\"max\": %.9g, \"mean\": %.9g, \"rms\": %.9g, \"samples\": %zu}%s\n", name, s->max, s->mean,
           s->rms, s->sample_count, after);
}

static int run_pair(const char *path_a, const char *path_b, double samples_per_face, int threads)
{
    lk_mesh a, b;
    if (load(path_a, &a)) return 1;
    if (load(path_b, &b)) {
        lk_mesh_free(&a);
        return 1;
    }
    lk_metro_options options;
    lk_metro_options_default(&options);
    options.samples_per_face = samples_per_face;
    options.thread_count = threads;
    lk_metro_result r;
    lk_error error = {0};
    int failed = lk_metro(&a, &b, &options, &r, NULL, NULL, &error) != LK_OK;
    if (failed) {
        fprintf(stderr, "bench_metro: %s\n", error.message);
    } else {
        printf("{\n");
        print_stats("forward", &r.forward, ",");
        print_stats("backward", &r.backward, ",");
        printf("  \"hausdorff\": %.9g,\n  \"diagonal\": %.9g,\n  \"seconds\": %.4f\n}\n", r.hausdorff, r.diagonal,
               r.seconds);
    }
    lk_mesh_free(&a);
    lk_mesh_free(&b);
    return failed;
}

static int usage(void)
{
    fprintf(stderr, "usage: bench_metro [--threads N] [SAMPLES_DIR]\n"
                    "       bench_metro --write-perturbed OUT [SAMPLES_DIR]\n"
                    "       bench_metro --pair A B [--samples-per-face N] [--threads N]\n");
    return 2;
}

int main(int argc, char **argv)
{
    const char *samples_dir = "data/samples", *perturbed = NULL, *pair[2] = {NULL, NULL};
    double samples_per_face = 10;
    int threads = 0;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--threads") == 0 && i + 1 < argc) {
            threads = atoi(argv[++i]);
        } else if (strcmp(argv[i], "--samples-per-face") == 0 && i + 1 < argc) {
            samples_per_face = atof(argv[++i]);
        } else if (strcmp(argv[i], "--write-perturbed") == 0 && i + 1 < argc) {
            perturbed = argv[++i];
        } else if (strcmp(argv[i], "--pair") == 0 && i + 2 < argc) {
            pair[0] = argv[++i];
            pair[1] = argv[++i];
        } else if (argv[i][0] == '-') {
            return usage();
        } else {
            samples_dir = argv[i];
        }
    }
    if (perturbed) return write_perturbed(perturbed, samples_dir);
    if (pair[0]) return run_pair(pair[0], pair[1], samples_per_face, threads);
    return run_table(samples_dir, threads);
}
