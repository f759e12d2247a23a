/* SPDX-License-Identifier: MIT */
/* Point octree build (lk_octree_build through `lodkit octree`): throughput
 * and peak memory on large clouds; then drawing the largest octree under a
 * point budget (lk_render_octree: selection, loading, 1-pass splats on the
 * C renderer, Mesa llvmpipe without a GPU): frame time and memory at
 * budgets of 0.5M, 1M and 2M points.
 *
 *   bench_octree [--100m] [--no-radii] [--threads T] [--out DIR] [--lodkit PATH]
 *                [--render-only] [--side PIXELS] [SAMPLES_DIR]
 *
 * The clouds: the bunny (SAMPLES_DIR/bunny.obj) Loop-subdivided once, then
 * sampled (lk_mesh_sample_points, uniform, 2M points per batch with its own
 * seed) into 1M and 10M points (and 100M with --100m: about 2.6 GB of LAS
 * and 2.4 GB of spill files; the free space of DIR is printed first),
 * written as LAS 1.2 point format 2 (scale 1e-6, RGB from the normal) into
 * DIR (default /tmp; files already there with the right size are reused).
 * Each cloud is then built by a child process `lodkit octree -q --json
 * --threads T` (default 2) into DIR/octree_N, timed by the wall clock, its
 * peak RSS from wait4's ru_maxrss, its CPU time (user + system) from
 * ru_utime and ru_stime: on a machine shared with other work the wall
 * clock says little, CPU seconds / T is the time T free cores would take
 * (the passes over the input run on one thread: an upper bound on speed).
 * --no-radii passes --no-radii on. Prints a markdown table.
 *
 * Drawing: each budget in a child process (its peak RSS from wait4, less
 * the peak of a child that only makes the GL context: the driver's own),
 * the 10M cloud built again with --estimate-normals (the LAS carries none;
 * splats need them) into DIR/bench_octree_10000000_normals (reused), framed
 * whole in a SIDE x SIDE image (default 1024), min_spacing_pixels 0 so that
 * the budget, not the 1 px rule, decides how much is drawn. Three frames
 * per budget; each selects, loads (read, CRC-32, decode) and draws, and
 * the table gives the medians. "draw" is the GPU time to glFinish: the
 * frame time of a viewer whose nodes are loaded. The paper's Table 1 (Kim
 * 2010, iPhone 3GS) is the reference line: 35K-544K points in 28-40 MB.
 *
 * Reference (not measured here): Schütz, Ohrhallinger, Wimmer, "Fast
 * Out-of-Core Octree Generation for Massive Point Clouds" (TU Wien
 * TR-193-02-2020-3, PotreeConverter 2.0) report "up to around 6 million
 * points per second for the blue-noise approach" on modern SSDs
 * (https://www.cg.tuwien.ac.at/research/publications/2020/SCHUETZ-2020-MPC/). */
#define _DEFAULT_SOURCE /* wait4 */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <sys/time.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "bench_common.h"
#include "lodkit.h"

/* What one child reports about drawing under one budget. */
typedef struct frame_report {
    int ok;
    lk_error error; /* why not ok */
    uint64_t points;
    size_t nodes;
    double select_ms, load_ms, draw_ms; /* medians */
} frame_report;

static double rusage_mib(const struct rusage *usage) { return usage->ru_maxrss / 1024.0; }

/* In a child: draws `octree_dir` under `budget` (0: only make the context)
 * three times and writes a frame_report to `fd`. */
static void draw_in_child(const char *octree_dir, uint64_t budget, unsigned side, int fd)
{
    frame_report report;
    memset(&report, 0, sizeof report);
    lk_error error = {0};
    lk_octree *octree = NULL;
    lk_renderer *renderer = NULL;
    lk_status status = lk_renderer_create(side, side, &renderer, &error);
    if (status == LK_OK && budget > 0) status = lk_octree_open(octree_dir, &octree, &error);
    double select_ms[3], load_ms[3], draw_ms[3];
    for (int run = 0; status == LK_OK && budget > 0 && run < 3; run++) {
        lk_octree_select_options select;
        lk_octree_select_options_default(&select);
        select.point_budget = budget;
        select.min_spacing_pixels = 0;
        lk_render_octree_stats stats;
        status = lk_render_octree(renderer, octree, NULL, &select, &stats, &error);
        select_ms[run] = stats.select_milliseconds;
        load_ms[run] = stats.load_milliseconds;
        draw_ms[run] = stats.draw_milliseconds;
        report.points = stats.points;
        report.nodes = stats.nodes;
    }
    if (status == LK_OK && budget > 0) {
        report.select_ms = median(select_ms, 3);
        report.load_ms = median(load_ms, 3);
        report.draw_ms = median(draw_ms, 3);
    }
    report.ok = status == LK_OK;
    report.error = error;
    lk_octree_close(octree);
    lk_renderer_free(renderer);
    if (write(fd, &report, sizeof report) != (ssize_t)sizeof report) _exit(1);
    _exit(0);
}

/* Forks a child for draw_in_child; its report and peak RSS (MiB). */
static int draw_budget(const char *octree_dir, uint64_t budget, unsigned side, frame_report *report, double *peak_mib)
{
    int fds[2];
    if (pipe(fds) != 0) return -1;
    fflush(stdout);
    pid_t child = fork();
    if (child == 0) {
        close(fds[0]);
        draw_in_child(octree_dir, budget, side, fds[1]);
    }
    close(fds[1]);
    ssize_t got = child > 0 ? read(fds[0], report, sizeof *report) : -1;
    close(fds[0]);
    int status;
    struct rusage usage;
    if (child < 0 || wait4(child, &status, 0, &usage) != child || got != (ssize_t)sizeof *report) return -1;
    *peak_mib = rusage_mib(&usage);
    return 0;
}

/* Builds DIR/bench_octree_N_normals from the LAS with estimated normals
 * unless it is there. */
static int ensure_normals_octree(const char *lodkit, const char *out, size_t count, const char *threads, char *dir,
                                 size_t dir_size)
{
    char las[4096], index[4200];
    snprintf(las, sizeof las, "%s/bench_octree_%zu.las", out, count);
    snprintf(dir, dir_size, "%s/bench_octree_%zu_normals", out, count);
    snprintf(index, sizeof index, "%s/octree.json", dir);
    struct stat info;
    if (stat(index, &info) == 0) return 0;
    if (stat(las, &info) != 0) return fprintf(stderr, "%s: missing (run without --render-only first)\n", las), -1;
    fprintf(stderr, "building %s (normals estimated)\n", dir);
    fflush(stdout);
    pid_t child = fork();
    if (child == 0) {
        execl(lodkit, lodkit, "octree", "-q", "--estimate-normals", "--threads", threads, las, dir, (char *)NULL);
        _exit(127);
    }
    int status;
    if (child < 0 || waitpid(child, &status, 0) != child || !WIFEXITED(status) || WEXITSTATUS(status) != 0)
        return fprintf(stderr, "%s octree --estimate-normals %s failed\n", lodkit, las), -1;
    return 0;
}

static int render_table(const char *octree_dir, unsigned side)
{
    static const uint64_t budgets[] = {500000, 1000000, 2000000};
    frame_report report;
    double context_mib;
    if (draw_budget(octree_dir, 0, side, &report, &context_mib) != 0 || !report.ok)
        return fprintf(stderr, "no GL context: %s\n", report.error.message), 1;
    printf("\n%s drawn whole at %ux%u, 1-pass splats (%s); GL context alone: peak RSS %.0f MiB.\n"
           "Reference: Kim 2010, Table 1 (iPhone 3GS): 35K-544K points in 28-40 MB.\n\n",
           octree_dir, side, side, "lk_render_octree, min_spacing_pixels 0", context_mib);
    printf("| budget | points drawn | nodes | select ms | load ms | draw ms (frame) | frames/s | peak RSS (MiB) | "
           "over the context (MiB) | bytes/point |\n"
           "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for (size_t b = 0; b < sizeof budgets / sizeof *budgets; b++) {
        double peak;
        if (draw_budget(octree_dir, budgets[b], side, &report, &peak) != 0 || !report.ok)
            return fprintf(stderr, "budget %llu: %s\n", (unsigned long long)budgets[b], report.error.message), 1;
        double over = peak - context_mib;
        printf("| %llu | %llu | %zu | %.2f | %.0f | %.0f | %.2f | %.0f | %.0f | %.0f |\n",
               (unsigned long long)budgets[b], (unsigned long long)report.points, report.nodes, report.select_ms,
               report.load_ms, report.draw_ms, 1000.0 / report.draw_ms, peak, over,
               over * 1048576.0 / (double)report.points);
        fflush(stdout);
    }
    return 0;
}

static void put16(unsigned char *p, unsigned v)
{
    p[0] = (unsigned char)v;
    p[1] = (unsigned char)(v >> 8);
}
static void put32(unsigned char *p, uint32_t v)
{
    for (int i = 0; i < 4; i++) p[i] = (unsigned char)(v >> (8 * i));
}
static void put64d(unsigned char *p, double v)
{
    uint64_t bits;
    memcpy(&bits, &v, 8);
    for (int i = 0; i < 8; i++) p[i] = (unsigned char)(bits >> (8 * i));
}

enum { HEADER = 227, RECORD = 26 };

/* Writes `count` points sampled on `mesh` as LAS 1.2 format 2. */
static int write_las(const lk_mesh *mesh, size_t count, const char *path)
{
    FILE *file = fopen(path, "wb");
    if (!file) return fprintf(stderr, "%s: %s\n", path, strerror(errno)), -1;
    unsigned char header[HEADER];
    memset(header, 0, sizeof header);
    fwrite(header, 1, HEADER, file); /* rewritten at the end */
    float lo[3], hi[3];
    lk_mesh_bounds(mesh, lo, hi);
    double scale = 1e-6, offset[3] = {lo[0], lo[1], lo[2]};
    double min[3] = {INFINITY, INFINITY, INFINITY}, max[3] = {-INFINITY, -INFINITY, -INFINITY};
    unsigned char *records = malloc((size_t)2000000 * RECORD);
    size_t done = 0;
    for (uint64_t batch = 1; done < count; batch++) {
        lk_sample_options options;
        lk_sample_options_default(&options);
        options.point_count = count - done < 2000000 ? count - done : 2000000;
        options.seed = batch;
        lk_mesh points;
        lk_error error = {0};
        if (lk_mesh_sample_points(mesh, &options, &points, NULL, NULL, &error) != LK_OK)
            return fprintf(stderr, "sampling: %s\n", error.message), -1;
        for (size_t i = 0; i < points.vertex_count; i++) {
            unsigned char *r = records + i * RECORD;
            memset(r, 0, RECORD);
            for (int k = 0; k < 3; k++) {
                double v = points.positions[3 * i + (size_t)k];
                int32_t steps = (int32_t)floor((v - offset[k]) / scale + 0.5);
                put32(r + 4 * k, (uint32_t)steps);
                double back = offset[k] + steps * scale;
                if (back < min[k]) min[k] = back;
                if (back > max[k]) max[k] = back;
                put16(r + 20 + 2 * k, (unsigned)((points.normals[3 * i + (size_t)k] * 0.5f + 0.5f) * 65535.0f));
            }
        }
        fwrite(records, RECORD, points.vertex_count, file);
        done += points.vertex_count;
        lk_mesh_free(&points);
        fprintf(stderr, "\rwriting %s: %zu points", path, done);
    }
    fprintf(stderr, "\n");
    free(records);
    memcpy(header, "LASF", 4);
    header[24] = 1;
    header[25] = 2;
    memcpy(header + 26, "lodkit bench_octree", 19);
    put16(header + 94, HEADER);
    put32(header + 96, HEADER);
    header[104] = 2;
    put16(header + 105, RECORD);
    put32(header + 107, (uint32_t)count);
    put32(header + 111, (uint32_t)count);
    for (int k = 0; k < 3; k++) {
        put64d(header + 131 + 8 * k, scale);
        put64d(header + 155 + 8 * k, offset[k]);
        put64d(header + 179 + 16 * k, max[k]);
        put64d(header + 187 + 16 * k, min[k]);
    }
    fseek(file, 0, SEEK_SET);
    fwrite(header, 1, HEADER, file);
    return fclose(file) == 0 ? 0 : -1;
}

int main(int argc, char **argv)
{
    const char *out = "/tmp", *samples = "data/samples", *threads = "2";
    char lodkit[4096];
    snprintf(lodkit, sizeof lodkit, "%s", argv[0]);
    char *slash = strrchr(lodkit, '/');
    if (slash)
        strcpy(slash + 1, "lodkit");
    else
        strcpy(lodkit, "./lodkit");
    int hundred = 0, no_radii = 0, render_only = 0;
    unsigned side = 1024;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--100m"))
            hundred = 1;
        else if (!strcmp(argv[i], "--no-radii"))
            no_radii = 1;
        else if (!strcmp(argv[i], "--render-only"))
            render_only = 1;
        else if (!strcmp(argv[i], "--side") && i + 1 < argc)
            side = (unsigned)atoi(argv[++i]);
        else if (!strcmp(argv[i], "--out") && i + 1 < argc)
            out = argv[++i];
        else if (!strcmp(argv[i], "--threads") && i + 1 < argc)
            threads = argv[++i];
        else if (!strcmp(argv[i], "--lodkit") && i + 1 < argc)
            snprintf(lodkit, sizeof lodkit, "%s", argv[++i]);
        else if (argv[i][0] != '-')
            samples = argv[i];
        else
            return fprintf(stderr,
                           "usage: bench_octree [--100m] [--no-radii] [--threads T] [--out DIR] [--lodkit PATH] "
                           "[--render-only] [--side PIXELS] [SAMPLES_DIR]\n"),
                   2;
    }
    if (side < 16 || side > 8192) return fprintf(stderr, "--side: 16 to 8192 pixels\n"), 2;
    char rendered[4096];
    if (render_only)
        return ensure_normals_octree(lodkit, out, 10000000, threads, rendered, sizeof rendered) != 0
                   ? 1
                   : render_table(rendered, side);
    struct statvfs fs;
    if (statvfs(out, &fs) == 0) printf("%s: %.1f GB free\n\n", out, (double)fs.f_bavail * (double)fs.f_frsize / 1e9);
    char path[4096];
    snprintf(path, sizeof path, "%s/bunny.obj", samples);
    lk_mesh bunny, smooth;
    lk_error error = {0};
    if (lk_mesh_read(path, LK_FORMAT_AUTO, NULL, &bunny, &error) != LK_OK)
        return fprintf(stderr, "%s\n", error.message), 1;
    if (lk_subdivide(&bunny, LK_SUBDIVIDE_LOOP, 1, &smooth, &error) != LK_OK)
        return fprintf(stderr, "%s\n", error.message), 1;
    lk_mesh_free(&bunny);
    size_t counts[3] = {1000000, 10000000, 100000000};
    int cases = hundred ? 3 : 2;
    printf("reference: PotreeConverter 2.0, up to ~6M points/s (blue noise), Schuetz et al. 2020, TU Wien "
           "TR-193-02-2020-3\n\n");
    printf("| points | wall s | points/s (wall) | CPU s | points/s (CPU s / %s) | peak RSS (MiB) | output (MB) |\n"
           "|---:|---:|---:|---:|---:|---:|---:|\n",
           threads);
    fflush(stdout);
    for (int c = 0; c < cases; c++) {
        size_t count = counts[c];
        char las[4096], dir[4096];
        snprintf(las, sizeof las, "%s/bench_octree_%zu.las", out, count);
        snprintf(dir, sizeof dir, "%s/bench_octree_%zu", out, count);
        struct stat info;
        if (stat(las, &info) != 0 || (size_t)info.st_size != HEADER + count * RECORD)
            if (write_las(&smooth, count, las) != 0) return 1;
        double start = now();
        pid_t child = fork();
        if (child == 0) {
            int devnull = open("/dev/null", O_WRONLY);
            if (devnull >= 0) dup2(devnull, 1);
            if (no_radii)
                execl(lodkit, lodkit, "octree", "-q", "--no-radii", "--threads", threads, las, dir, (char *)NULL);
            else
                execl(lodkit, lodkit, "octree", "-q", "--threads", threads, las, dir, (char *)NULL);
            _exit(127);
        }
        int status;
        struct rusage usage;
        if (child < 0 || wait4(child, &status, 0, &usage) != child || !WIFEXITED(status) || WEXITSTATUS(status) != 0)
            return fprintf(stderr, "%s octree %s failed\n", lodkit, las), 1;
        double seconds = now() - start;
        char bin[4200];
        snprintf(bin, sizeof bin, "%s/octree.bin", dir);
        double megabytes = stat(bin, &info) == 0 ? (double)info.st_size / 1e6 : 0;
        double cpu = (double)usage.ru_utime.tv_sec + usage.ru_utime.tv_usec * 1e-6 + (double)usage.ru_stime.tv_sec +
                     usage.ru_stime.tv_usec * 1e-6;
        printf("| %zu | %.2f | %.0f | %.2f | %.0f | %.0f | %.0f |\n", count, seconds, (double)count / seconds, cpu,
               (double)count / (cpu / atof(threads)), usage.ru_maxrss / 1024.0, megabytes);
        fflush(stdout);
    }
    lk_mesh_free(&smooth);
    if (ensure_normals_octree(lodkit, out, counts[1], threads, rendered, sizeof rendered) != 0) return 1;
    return render_table(rendered, side);
}
