/* SPDX-License-Identifier: MIT */
/* Point splatting: memory and frame time, like Table 1 of Kim's paper, and
 * the cost of Phong splats relative to plain flat points.
 *
 *   bench_splat [--frames N] [--size S] [--out DIR] [SAMPLES_DIR]
 *
 * Cases: the sample point sets (kitten.xyz, hippo1.ply) and the bunny
 * sampled at 100k, 500k and 1M points. As in the paper, sampling happens on
 * the "server": a child process samples the mesh and writes a binary PLY
 * (points, normals, radii) into DIR (default /tmp); another child then
 * loads that file and renders it, so its peak RSS is what a viewer of the
 * point set needs (the renderer, llvmpipe's buffers and the points), not
 * the sampler's. Each render child draws every mode once to warm up, then
 * N rounds (default 10) of one S x S frame (default 1024) per mode in turn,
 * and reports each mode's median frame time (draw + glFinish, upload
 * excluded) and its peak RSS (VmHWM). Modes: flat points, 1-pass splats,
 * 2-pass splats (all with back-face culling) and 1-pass without culling. A first child that only creates the renderer gives the
 * baseline memory of the viewer. Prints a markdown table. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include "bench_common.h"
#include "lodkit.h"

enum { MODE_FLAT, MODE_ONE_PASS, MODE_TWO_PASS, MODE_ONE_PASS_NO_CULLING, MODE_COUNT };

typedef struct case_result {
    int ok;
    size_t points;
    double peak_mib;                     /* after flat, 1-pass and 2-pass frames, culling on */
    double peak_no_culling_mib;          /* after the frames without culling too */
    double milliseconds[MODE_COUNT + 1]; /* the last: 1-pass culled, alternating with no culling */
    char message[512];
} case_result;

typedef struct settings {
    unsigned frames;
    unsigned size;
    const char *samples_dir;
    const char *out_dir;
} settings;

/* Peak resident set size of this process (VmHWM), in MiB. */
static double peak_rss_mib(void)
{
    FILE *file = fopen("/proc/self/status", "r");
    if (!file) return -1;
    char line[256];
    double kib = -1;
    while (fgets(line, sizeof line, file))
        if (strncmp(line, "VmHWM:", 6) == 0) {
            kib = strtod(line + 6, NULL);
            break;
        }
    fclose(file);
    return kib < 0 ? -1 : kib / 1024.0;
}

/* Child: loads `path` (NULL: no points, renderer only) and measures. */
static void render_case(const settings *s, const char *path, case_result *result)
{
    lk_error error = {0};
    lk_mesh points;
    lk_mesh_init(&points);
    lk_renderer *renderer = NULL;
    double *times = calloc((size_t)s->frames * (MODE_COUNT + 1), sizeof *times);
    if (!times) {
        snprintf(result->message, sizeof result->message, "out of memory");
        return;
    }
    lk_status status = path ? lk_mesh_read(path, LK_FORMAT_AUTO, NULL, &points, &error) : LK_OK;
    if (status == LK_OK) status = lk_renderer_create(s->size, s->size, &renderer, &error);
    result->points = points.vertex_count;
    lk_render_options options[MODE_COUNT];
    for (int mode = 0; mode < MODE_COUNT; mode++) {
        lk_render_options_default(&options[mode]);
        options[mode].flat_points = mode == MODE_FLAT;
        options[mode].passes = mode == MODE_TWO_PASS ? 2 : 1;
        options[mode].backface_culling = mode != MODE_ONE_PASS_NO_CULLING;
    }
    /* Phase 1: flat, 1-pass and 2-pass, all culled, frames round-robin over
     * the modes so that load from other processes slows every mode alike
     * and the ratios stay meaningful; then the peak RSS. Phase 2: 1-pass
     * without and with culling, alternately (without culling llvmpipe bins
     * twice the primitives, which shows in the RSS: hence last). Frame 0 of
     * each phase is the warm-up (llvmpipe compiles shader variants on first
     * use). */
    static const int phases[2][3] = {{MODE_FLAT, MODE_ONE_PASS, MODE_TWO_PASS},
                                     {MODE_ONE_PASS_NO_CULLING, MODE_ONE_PASS, -1}};
    double *culled_again = times + MODE_COUNT * s->frames;
    lk_render_stats stats;
    for (int phase = 0; phase < 2; phase++) {
        for (unsigned frame = 0; path && status == LK_OK && frame <= s->frames; frame++)
            for (int i = 0; status == LK_OK && i < 3 && phases[phase][i] >= 0; i++) {
                int mode = phases[phase][i];
                status = lk_render_points(renderer, &points, &options[mode], &stats, &error);
                if (frame == 0) continue;
                if (phase == 1 && mode == MODE_ONE_PASS)
                    culled_again[frame - 1] = stats.milliseconds;
                else
                    times[mode * s->frames + frame - 1] = stats.milliseconds;
            }
        if (phase == 0) result->peak_mib = peak_rss_mib();
    }
    result->peak_no_culling_mib = peak_rss_mib();
    for (int mode = 0; path && status == LK_OK && mode <= MODE_COUNT; mode++)
        result->milliseconds[mode] = median(times + mode * s->frames, s->frames);
    if (status == LK_OK) {
        if (!path) result->peak_mib = peak_rss_mib();
        result->ok = 1;
    } else {
        snprintf(result->message, sizeof result->message, "%s", error.message);
    }
    lk_renderer_free(renderer);
    lk_mesh_free(&points);
    free(times);
}

/* Child: samples the bunny into `path`. */
static void sample_case(const settings *s, size_t point_count, const char *path, case_result *result)
{
    char mesh_path[4096];
    snprintf(mesh_path, sizeof mesh_path, "%s/bunny.obj", s->samples_dir);
    lk_error error = {0};
    lk_mesh mesh, points;
    lk_mesh_init(&points);
    lk_status status = lk_mesh_read(mesh_path, LK_FORMAT_AUTO, NULL, &mesh, &error);
    if (status == LK_OK) {
        lk_sample_options options;
        lk_sample_options_default(&options);
        options.point_count = point_count;
        status = lk_mesh_sample_points(&mesh, &options, &points, NULL, NULL, &error);
        lk_mesh_free(&mesh);
    }
    if (status == LK_OK) status = lk_mesh_write(path, LK_FORMAT_PLY, &points, NULL, &error);
    lk_mesh_free(&points);
    if (status == LK_OK)
        result->ok = 1;
    else
        snprintf(result->message, sizeof result->message, "%s", error.message);
}

/* Runs `job` in a forked child and copies its result back through a pipe. */
static int in_child(const settings *s, const char *path, size_t point_count, int sampling, case_result *result)
{
    memset(result, 0, sizeof *result);
    int fds[2];
    if (pipe(fds) != 0) return -1;
    fflush(stdout);
    pid_t pid = fork();
    if (pid < 0) return -1;
    if (pid == 0) {
        close(fds[0]);
        case_result mine;
        memset(&mine, 0, sizeof mine);
        if (sampling)
            sample_case(s, point_count, path, &mine);
        else
            render_case(s, path, &mine);
        ssize_t written = write(fds[1], &mine, sizeof mine);
        _exit(written == (ssize_t)sizeof mine ? 0 : 1);
    }
    close(fds[1]);
    size_t got = 0;
    while (got < sizeof *result) {
        ssize_t n = read(fds[0], (char *)result + got, sizeof *result - got);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) break;
        got += (size_t)n;
    }
    close(fds[0]);
    int child_status = 0;
    waitpid(pid, &child_status, 0);
    if (got != sizeof *result) {
        memset(result, 0, sizeof *result);
        snprintf(result->message, sizeof result->message, "child died (status %d)", child_status);
    }
    return 0;
}

static void print_row(const char *name, const case_result *r)
{
    if (!r->ok) {
        printf("| %s | failed: %s |||||||||\n", name, r->message);
        return;
    }
    const double *ms = r->milliseconds;
    printf("| %s | %zu | %.0f | %.0f | %.1f | %.1f | %.1f | %.2f | %.2f | %.1f | %.2f |\n", name, r->points,
           r->peak_mib, r->peak_no_culling_mib, ms[MODE_FLAT], ms[MODE_ONE_PASS], ms[MODE_TWO_PASS],
           ms[MODE_ONE_PASS] / ms[MODE_FLAT], ms[MODE_TWO_PASS] / ms[MODE_FLAT], ms[MODE_ONE_PASS_NO_CULLING],
           ms[MODE_ONE_PASS_NO_CULLING] / ms[MODE_COUNT]);
}

int main(int argc, char **argv)
{
    settings s = {10, 1024, "data/samples", "/tmp"};
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--frames") && i + 1 < argc)
            s.frames = (unsigned)atoi(argv[++i]);
        else if (!strcmp(argv[i], "--size") && i + 1 < argc)
            s.size = (unsigned)atoi(argv[++i]);
        else if (!strcmp(argv[i], "--out") && i + 1 < argc)
            s.out_dir = argv[++i];
        else if (argv[i][0] != '-')
            s.samples_dir = argv[i];
        else {
            fprintf(stderr, "usage: bench_splat [--frames N] [--size S] [--out DIR] [SAMPLES_DIR]\n");
            return 2;
        }
    }
    if (s.frames < 1 || s.size < 16 || s.size > 8192) {
        fprintf(stderr, "bench_splat: --frames must be >= 1 and --size 16..8192\n");
        return 2;
    }

    case_result base;
    in_child(&s, NULL, 0, 0, &base);
    if (!base.ok) {
        fprintf(stderr, "bench_splat: no renderer: %s\n", base.message);
        return 1;
    }
    printf("Point splatting, %ux%u, median of %u frames (draw + glFinish; upload excluded); peak RSS of a\n"
           "process that loads the point set and renders it (a renderer alone: %.1f MiB).\n\n",
           s.size, s.size, s.frames, base.peak_mib);
    printf("| point set | points | peak RSS MiB | peak RSS, no culling too | flat ms | 1-pass ms | 2-pass ms |"
           " 1-pass / flat | 2-pass / flat | 1-pass no culling ms | no culling / culling |\n");
    printf("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    static const char *const files[] = {"kitten.xyz", "hippo1.ply"};
    for (size_t i = 0; i < sizeof files / sizeof files[0]; i++) {
        char path[4096];
        snprintf(path, sizeof path, "%s/%s", s.samples_dir, files[i]);
        case_result r;
        in_child(&s, path, 0, 0, &r);
        print_row(files[i], &r);
    }
    static const size_t counts[] = {100000, 500000, 1000000};
    for (size_t i = 0; i < sizeof counts / sizeof counts[0]; i++) {
        char path[4096], name[64];
        snprintf(path, sizeof path, "%s/bench_splat_bunny_%zu.ply", s.out_dir, counts[i]);
        snprintf(name, sizeof name, "bunny sampled, %zuk", counts[i] / 1000);
        case_result r;
        in_child(&s, path, counts[i], 1, &r);
        if (r.ok) in_child(&s, path, 0, 0, &r);
        print_row(name, &r);
        remove(path);
    }
    return 0;
}
