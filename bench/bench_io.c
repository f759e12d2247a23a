/* SPDX-License-Identifier: MIT */
/* Mesh readers and writers (issue 22): MB/s of lk_mesh_read and
 * lk_mesh_write for OBJ, binary PLY and GLB on one >= 100 MB mesh.
 *
 *   bench_io [--levels N] [--plain] [--runs R] [--python PATH] [--out DIR] [SAMPLES_DIR]
 *
 * The mesh: SAMPLES_DIR/bunny.obj Loop-subdivided N times (default 3: 4.5M
 * triangles, 2.2M vertices) with area-weighted vertex normals (--plain: no
 * normals; N = 4 then makes files of the same order). It is written once
 * per format into DIR (default /tmp; the files are removed at the end),
 * then read R + 1 times (default R = 5) with lk_mesh_read: the first read
 * warms the page cache and is not counted, the median of the others is
 * reported. Only the lk_mesh_read / lk_mesh_write call is timed (the
 * write includes closing and renaming the file, not flushing it to disk).
 * MB = 10^6 bytes of the file. "read CPU s" is the median CPU time
 * (user + system) of the same reads: on a machine shared with other jobs
 * it is what the read would take on a free core. With Open3D in PATH's python (default
 * /usr/bin/python3), its read_triangle_mesh on the same files is timed the
 * same way (median of R reads after one warm-up, the read call only) as a
 * reference. Prints a markdown table. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "bench_common.h"
#include "lodkit.h"

#define MAX_RUNS 31

/* CPU seconds of this process (user + system): what the read costs when
 * the 2 cores are shared with other jobs, which stretch the wall clock. */
static double cpu_now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

/* Area-weighted vertex normals (the cross products summed, then normalised). */
static int add_normals(lk_mesh *mesh)
{
    float *normals = calloc(3 * mesh->vertex_count, sizeof *normals);
    if (!normals) return -1;
    for (size_t t = 0; t < mesh->triangle_count; t++) {
        const uint32_t *corner = mesh->indices + 3 * t;
        const float *a = mesh->positions + 3 * corner[0], *b = mesh->positions + 3 * corner[1],
                    *c = mesh->positions + 3 * corner[2];
        float u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        float n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
        for (int k = 0; k < 3; k++)
            for (int i = 0; i < 3; i++) normals[3 * corner[k] + i] += n[i];
    }
    for (size_t i = 0; i < mesh->vertex_count; i++) {
        float *n = normals + 3 * i;
        float length = sqrtf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        if (length > 0)
            for (int k = 0; k < 3; k++) n[k] /= length;
        else
            n[2] = 1.0f;
    }
    free(mesh->normals);
    mesh->normals = normals;
    return 0;
}

/* Median seconds of Open3D's read_triangle_mesh on `path` (runs after one
 * warm-up), or a negative value when the peer cannot be run. */
static double open3d_read_seconds(const char *python, const char *path, int runs)
{
    char command[2048];
    snprintf(command, sizeof command,
             "'%s' -c \"import sys, time, statistics, open3d as o3d\n"
             "o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)\n"
             "p = sys.argv[1]; o3d.io.read_triangle_mesh(p)\n"
             "t = []\n"
             "for _ in range(int(sys.argv[2])):\n"
             "    s = time.perf_counter(); m = o3d.io.read_triangle_mesh(p); t.append(time.perf_counter() - s)\n"
             "print(statistics.median(t) if len(m.triangles) else -1)\" '%s' %d 2>/dev/null",
             python, path, runs);
    FILE *pipe = popen(command, "r");
    if (!pipe) return -1;
    double seconds = -1;
    if (fscanf(pipe, "%lf", &seconds) != 1) seconds = -1;
    if (pclose(pipe) != 0) return -1;
    return seconds;
}

int main(int argc, char **argv)
{
    const char *samples = "data/samples", *out_dir = "/tmp", *python = "/usr/bin/python3";
    int levels = 3, runs = 5, plain = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--levels") && i + 1 < argc)
            levels = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--runs") && i + 1 < argc)
            runs = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--out") && i + 1 < argc)
            out_dir = argv[++i];
        else if (!strcmp(argv[i], "--python") && i + 1 < argc)
            python = argv[++i];
        else if (!strcmp(argv[i], "--plain"))
            plain = 1;
        else if (argv[i][0] != '-')
            samples = argv[i];
        else {
            fprintf(stderr, "usage: bench_io [--levels N] [--plain] [--runs R] [--python PATH] [--out DIR] "
                            "[SAMPLES_DIR]\n");
            return 2;
        }
    }
    if (levels < 0 || levels > 6 || runs < 1 || runs > MAX_RUNS) {
        fprintf(stderr, "bench_io: --levels must be 0..6 and --runs 1..%d\n", MAX_RUNS);
        return 2;
    }
    char path[1024];
    snprintf(path, sizeof path, "%s/bunny.obj", samples);
    lk_mesh bunny, mesh;
    lk_error error = {0};
    if (lk_mesh_read(path, LK_FORMAT_AUTO, NULL, &bunny, &error) != LK_OK ||
        lk_subdivide(&bunny, LK_SUBDIVIDE_LOOP, (unsigned)levels, &mesh, &error) != LK_OK) {
        fprintf(stderr, "bench_io: %s\n", error.message);
        return 1;
    }
    lk_mesh_free(&bunny);
    if (!plain && add_normals(&mesh) != 0) {
        fprintf(stderr, "bench_io: out of memory\n");
        return 1;
    }
    printf("Bunny, Loop x%d: %zu vertices, %zu triangles%s; lk_mesh_read median of %d reads after a warm-up\n\n",
           levels, mesh.vertex_count, mesh.triangle_count, plain ? "" : ", vertex normals", runs);
    printf("| format | file MB | read s | read MB/s | read CPU s | MB/CPU s | write s | write MB/s | Open3D read s | "
           "Open3D MB/s |\n");
    printf("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    fflush(stdout);
    static const char *const extensions[3] = {"obj", "ply", "glb"};
    static const char *const names[3] = {"OBJ", "PLY (binary)", "GLB"};
    int failed = 0;
    for (int f = 0; f < 3; f++) {
        snprintf(path, sizeof path, "%s/bench_io_%ld.%s", out_dir, (long)getpid(), extensions[f]);
        double start = now();
        lk_status status = lk_mesh_write(path, LK_FORMAT_AUTO, &mesh, NULL, &error);
        double write_seconds = now() - start;
        struct stat info;
        if (status != LK_OK || stat(path, &info) != 0) {
            fprintf(stderr, "bench_io: %s\n", status != LK_OK ? error.message : "cannot stat the written file");
            failed = 1;
            continue;
        }
        double megabytes = (double)info.st_size / 1e6;
        double times[MAX_RUNS + 1], cpu_times[MAX_RUNS + 1];
        int ok = 1;
        for (int r = 0; r <= runs && ok; r++) {
            lk_mesh read_back;
            start = now();
            double cpu_start = cpu_now();
            status = lk_mesh_read(path, LK_FORMAT_AUTO, NULL, &read_back, &error);
            cpu_times[r] = cpu_now() - cpu_start;
            times[r] = now() - start;
            if (status != LK_OK || read_back.triangle_count != mesh.triangle_count) {
                fprintf(stderr, "bench_io: %s: %s\n", path, status != LK_OK ? error.message : "triangles differ");
                ok = 0;
            }
            lk_mesh_free(&read_back);
        }
        if (!ok) {
            failed = 1;
            unlink(path);
            continue;
        }
        double read_seconds = median(times + 1, runs), read_cpu_seconds = median(cpu_times + 1, runs);
        double peer_seconds = open3d_read_seconds(python, path, runs);
        char peer[64] = "-", peer_rate[64] = "-";
        if (peer_seconds > 0) {
            snprintf(peer, sizeof peer, "%.3f", peer_seconds);
            snprintf(peer_rate, sizeof peer_rate, "%.0f", megabytes / peer_seconds);
        }
        printf("| %s | %.1f | %.3f | %.0f | %.3f | %.0f | %.3f | %.0f | %s | %s |\n", names[f], megabytes, read_seconds,
               megabytes / read_seconds, read_cpu_seconds, megabytes / read_cpu_seconds, write_seconds,
               megabytes / write_seconds, peer, peer_rate);
        fflush(stdout);
        unlink(path);
    }
    lk_mesh_free(&mesh);
    return failed;
}
