/* SPDX-License-Identifier: MIT */
/* Simplification benchmark: lodkit's QEM and clusterings side by side with
 * meshoptimizer (linked) and Open3D (bench/simplify_open3d.py), on the
 * bunny and on a >= 1M-triangle mesh made from it by Loop subdivision, at
 * 50%, 10% and 1% of the triangles.
 *
 *   bench_simplify [--samples DIR] [--out DIR] [--quick] [--clustering]
 *
 * Columns: triangles out, median time of 5 runs on one thread (the
 * linked methods' runs interleaved, see contender), and for
 * lodkit's QEM on the 1.1M-triangle mesh also on two (slow peers
 * stop after 30 s of runs), million input triangles per second, speed
 * relative to meshopt_simplify (>1 = faster), and the symmetric Hausdorff
 * distance and RMS (the larger of the two directions) in % of the bounding
 * box diagonal, measured by lk_metro. --quick: the bunny only, no Open3D.
 * --clustering: only meshopt_simplifySloppy and lodkit's two clusterings,
 * with speeds relative to meshopt_simplifySloppy instead.
 * A CSV copy goes to OUT/simplify.csv.
 *
 * After each table, the same linked methods' first call in a fresh
 * process (what `lodkit simplify` pays: one call per process): the bench
 * runs itself with --first-call METHOD MESH TARGET, RUNS processes per
 * method taking turns, and prints the median time and the page faults of
 * the call (its fresh memory: on this machine's virtual machine a 4 KiB
 * page fault costs 10-20 microseconds, as much as clustering a hundred
 * triangles, and the heap a process has warmed hides that from the
 * interleaved runs above). */
#include <float.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#include "bench_common.h"
#include "lodkit.h"
#ifdef LODKIT_HAVE_MESHOPTIMIZER
#include <meshoptimizer.h>
#endif

#define RUNS 5
#define BUDGET_SECONDS 30.0

typedef struct row {
    const char *method;
    size_t triangles;
    double milliseconds;
    int runs;
    double hausdorff_percent, rms_percent;
    int ok;
} row;

static void measure(const lk_mesh *input, const lk_mesh *output, row *r)
{
    lk_metro_result metro;
    lk_error error = {0};
    r->triangles = output->triangle_count;
    if (output->triangle_count == 0 || lk_metro(input, output, NULL, &metro, NULL, NULL, &error) != LK_OK) {
        r->hausdorff_percent = r->rms_percent = NAN;
        return;
    }
    r->hausdorff_percent = 100 * metro.hausdorff / metro.diagonal;
    r->rms_percent = 100 * fmax(metro.forward.rms, metro.backward.rms) / metro.diagonal;
}

/* One method timed on one mesh and target. The methods linked in (lodkit
 * and meshoptimizer) are timed interleaved, one run of each in turn,
 * starting each round with the next method: a method timed only right
 * after its own runs finds the heap its last run freed and pays no page
 * faults, one timed after another method's runs pays them, and the ratio
 * then measures the order (meshopt_simplifySloppy on the 1.1M-triangle
 * mesh at 10%: 123-177 ms in a fresh process, 58 ms after its own runs). */
typedef struct contender {
    const char *name;
    int meshopt; /* 0 = lodkit, 1 = meshopt_simplify, 2 = meshopt_simplifySloppy */
    lk_simplify_method method;
    unsigned threads;
    double times[RUNS], spent;
    int runs;
    bool failed;
    lk_simplify_result result;  /* lodkit's last result */
    unsigned int *destination;  /* meshopt's last result */
    size_t destination_indices; /* (its index count) */
} contender;

static void contender_free(contender *c)
{
    lk_simplify_result_free(&c->result);
    free(c->destination);
    c->destination = NULL;
}

/* One run of `c`; false when it failed (message printed). */
static bool run_once(contender *c, const lk_mesh *mesh, size_t target)
{
    double start;
    if (c->meshopt) {
#ifdef LODKIT_HAVE_MESHOPTIMIZER
        size_t index_count = 3 * mesh->triangle_count;
        if (!c->destination) c->destination = malloc(index_count * sizeof *c->destination);
        if (!c->destination) return false;
        start = now();
        if (c->meshopt == 2)
            c->destination_indices =
                meshopt_simplifySloppy(c->destination, mesh->indices, index_count, mesh->positions, mesh->vertex_count,
                                       3 * sizeof(float), 3 * target, FLT_MAX, NULL);
        else
            c->destination_indices =
                meshopt_simplify(c->destination, mesh->indices, index_count, mesh->positions, mesh->vertex_count,
                                 3 * sizeof(float), 3 * target, FLT_MAX, 0, NULL);
#else
        return false;
#endif
    } else {
        lk_simplify_options options;
        lk_simplify_options_default(&options);
        options.target_triangles = target;
        options.thread_count = c->threads;
        lk_simplify_result_free(&c->result);
        lk_error error = {0};
        start = now();
        if (lk_simplify(mesh, c->method, &options, &c->result, NULL, NULL, &error) != LK_OK) {
            fprintf(stderr, "bench_simplify: %s: %s\n", c->name, error.message);
            return false;
        }
    }
    c->times[c->runs] = now() - start;
    c->spent += c->times[c->runs++];
    return true;
}

/* Times the contenders interleaved and fills their rows. */
static void run_contenders(contender *contenders, int count, const lk_mesh *mesh, size_t target, row *rows)
{
    for (int round = 0; round < RUNS; round++)
        for (int k = 0; k < count; k++) {
            contender *c = &contenders[(round + k) % count];
            if (c->failed || c->runs == RUNS || c->spent >= BUDGET_SECONDS) continue;
            if (!run_once(c, mesh, target)) c->failed = true;
        }
    for (int k = 0; k < count; k++) {
        contender *c = &contenders[k];
        row *r = &rows[k];
        r->method = c->name;
        r->runs = c->runs;
        if (c->failed || c->runs == 0) continue;
        r->milliseconds = 1000 * median(c->times, c->runs);
        if (c->meshopt) {
            lk_mesh output = *mesh; /* same vertices, new triangles */
            output.normals = output.texcoords = output.colors = NULL;
            output.indices = c->destination;
            output.triangle_count = c->destination_indices / 3;
            measure(mesh, &output, r);
        } else {
            measure(mesh, &c->result.mesh, r);
        }
        r->ok = 1;
    }
}

static void run_open3d(const lk_mesh *mesh, const char *mesh_path, const char *method, size_t target,
                       const char *out_dir, const char *script, row *r)
{
    char output_path[1024], command[4096];
    snprintf(output_path, sizeof output_path, "%s/open3d-%s.ply", out_dir, method);
    snprintf(command, sizeof command,
             "OMP_NUM_THREADS=1 /usr/bin/python3 '%s' '%s' '%s' --method %s --triangles %zu --runs %d --budget %g",
             script, mesh_path, output_path, method, target, RUNS, BUDGET_SECONDS);
    r->method = strcmp(method, "quadric") ? "Open3D vertex_clustering" : "Open3D quadric_decimation";
    FILE *pipe = popen(command, "r");
    if (!pipe) return;
    char line[512] = "";
    if (!fgets(line, sizeof line, pipe)) line[0] = '\0';
    if (pclose(pipe) != 0) {
        fprintf(stderr, "bench_simplify: Open3D %s failed (is python3-open3d installed?)\n", method);
        return;
    }
    const char *ms = strstr(line, "\"median_ms\":"), *runs = strstr(line, "\"runs\":");
    if (!ms || !runs) return;
    r->milliseconds = atof(ms + 12);
    r->runs = atoi(runs + 7);
    lk_mesh output;
    lk_error error = {0};
    if (lk_mesh_read(output_path, LK_FORMAT_AUTO, NULL, &output, &error) != LK_OK) {
        fprintf(stderr, "bench_simplify: %s\n", error.message);
        return;
    }
    measure(mesh, &output, r);
    r->ok = 1;
    lk_mesh_free(&output);
}

static void print_row(FILE *csv, const char *mesh_name, size_t input_triangles, double percent, const row *r,
                      double meshopt_ms)
{
    if (!r->ok) {
        printf("| %-26s | %10s | %12s | %8s | %9s | %8s | %8s |\n", r->method ? r->method : "?", "failed", "", "", "",
               "", "");
        return;
    }
    double throughput = input_triangles / (r->milliseconds * 1e-3) * 1e-6;
    char ratio[32] = "-";
    if (meshopt_ms > 0) snprintf(ratio, sizeof ratio, "%.2f", meshopt_ms / r->milliseconds);
    printf("| %-26s | %10zu | %9.1f (%d) | %8.2f | %9s | %8.3f | %8.4f |\n", r->method, r->triangles, r->milliseconds,
           r->runs, throughput, ratio, r->hausdorff_percent, r->rms_percent);
    fprintf(csv, "%s,%g,%s,%zu,%.3f,%d,%.4f,%s,%.5f,%.5f\n", mesh_name, percent, r->method, r->triangles,
            r->milliseconds, r->runs, throughput, ratio, r->hausdorff_percent, r->rms_percent);
}

static long page_faults(void)
{
    struct rusage usage;
    getrusage(RUSAGE_SELF, &usage);
    return usage.ru_minflt + usage.ru_majflt;
}

/* --first-call METHOD MESH TARGET: one call, timed, in this fresh process;
 * prints "milliseconds page_faults". METHOD: meshopt, sloppy, qem,
 * uniform, floating. */
static int first_call_main(const char *method, const char *mesh_path, size_t target)
{
    lk_mesh mesh;
    lk_error error = {0};
    if (lk_mesh_read(mesh_path, LK_FORMAT_AUTO, NULL, &mesh, &error) != LK_OK) {
        fprintf(stderr, "bench_simplify: %s\n", error.message);
        return 1;
    }
    contender c = {.name = method, .threads = 1};
    if (!strcmp(method, "meshopt"))
        c.meshopt = 1;
    else if (!strcmp(method, "sloppy"))
        c.meshopt = 2;
    else
        c.method = !strcmp(method, "qem")       ? LK_SIMPLIFY_QEM
                   : !strcmp(method, "uniform") ? LK_SIMPLIFY_UNIFORM
                                                : LK_SIMPLIFY_FLOATING;
    /* meshopt's output array exists before the clock starts, as the
     * interleaved runs' does; its pages are fresh, as lodkit's output's. */
    if (c.meshopt && !(c.destination = malloc(3 * mesh.triangle_count * sizeof *c.destination))) return 1;
    long faults = page_faults();
    if (!run_once(&c, &mesh, target)) return 1;
    printf("%.3f %ld\n", 1000 * c.times[0], page_faults() - faults);
    contender_free(&c);
    lk_mesh_free(&mesh);
    return 0;
}

/* The first-call table of one mesh and target (see the file comment). */
static void run_first_calls(const char *mesh_path, size_t target, bool clustering_only)
{
    static const char *const all[] = {"meshopt", "sloppy", "qem", "uniform", "floating"};
    static const char *const labels[] = {"meshopt_simplify", "meshopt_simplifySloppy", "lodkit qem", "lodkit uniform",
                                         "lodkit floating"};
    /* the methods of the table above, one thread each */
    int methods[5], method_count = 0, reference = clustering_only ? 1 : 0;
    for (int m = 0; m < 5; m++) {
#ifndef LODKIT_HAVE_MESHOPTIMIZER
        if (m < 2) continue;
#endif
        if (!clustering_only || (m != 0 && m != 2)) methods[method_count++] = m;
    }
    char self[1024];
    ssize_t length = readlink("/proc/self/exe", self, sizeof self - 1);
    if (length <= 0) return;
    self[length] = '\0';
    double times[5][RUNS];
    long faults[5][RUNS];
    int runs[5] = {0};
    for (int round = 0; round < RUNS; round++)
        for (int k = 0; k < method_count; k++) {
            int m = methods[(round + k) % method_count];
            char command[4096];
            snprintf(command, sizeof command, "'%s' --first-call %s '%s' %zu", self, all[m], mesh_path, target);
            FILE *pipe = popen(command, "r");
            if (!pipe) continue;
            double ms;
            long count;
            int got = fscanf(pipe, "%lf %ld", &ms, &count);
            if (pclose(pipe) == 0 && got == 2) times[m][runs[m]] = ms, faults[m][runs[m]++] = count;
        }
    printf("\nFirst call in a fresh process (median of %d processes each, taking turns)\n\n", RUNS);
    printf("| %-26s | %12s | %11s | %9s |\n|---|---:|---:|---:|\n", "method", "ms (runs)", "page faults",
           clustering_only ? "vs sloppy" : "vs meshopt");
    double reference_ms = runs[reference] ? median(times[reference], runs[reference]) : 0;
    for (int k = 0; k < method_count; k++) {
        int m = methods[k];
        if (!runs[m]) continue;
        double ms = median(times[m], runs[m]), fault_values[RUNS];
        for (int r = 0; r < runs[m]; r++) fault_values[r] = (double)faults[m][r];
        char ratio[32] = "-";
        if (reference_ms > 0) snprintf(ratio, sizeof ratio, "%.2f", reference_ms / ms);
        printf("| %-26s | %9.1f (%d) | %11.0f | %9s |\n", labels[m], ms, runs[m], median(fault_values, runs[m]), ratio);
    }
    fflush(stdout);
}

int main(int argc, char **argv)
{
    if (argc == 5 && !strcmp(argv[1], "--first-call"))
        return first_call_main(argv[2], argv[3], strtoull(argv[4], NULL, 10));
    const char *samples = "data/samples", *out_dir = "bench/out", *script = "bench/simplify_open3d.py";
    int quick = 0, clustering_only = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--samples") && i + 1 < argc)
            samples = argv[++i];
        else if (!strcmp(argv[i], "--out") && i + 1 < argc)
            out_dir = argv[++i];
        else if (!strcmp(argv[i], "--script") && i + 1 < argc)
            script = argv[++i];
        else if (!strcmp(argv[i], "--quick"))
            quick = 1;
        else if (!strcmp(argv[i], "--clustering"))
            clustering_only = 1;
        else {
            fprintf(stderr, "usage: bench_simplify [--samples DIR] [--out DIR] [--script simplify_open3d.py] [--quick] "
                            "[--clustering]\n");
            return 2;
        }
    }
    char path[1024], big_path[1024], csv_path[1024];
    snprintf(path, sizeof path, "%s/bunny.obj", samples);
    snprintf(big_path, sizeof big_path, "%s/bunny-loop2.ply", out_dir);
    snprintf(csv_path, sizeof csv_path, "%s/simplify.csv", out_dir);
    lk_mesh meshes[2];
    lk_error error = {0};
    if (lk_mesh_read(path, LK_FORMAT_AUTO, NULL, &meshes[0], &error) != LK_OK) {
        fprintf(stderr, "bench_simplify: %s\n", error.message);
        return 1;
    }
    int mesh_count = quick ? 1 : 2;
    const char *names[2] = {"bunny", "bunny, Loop x2"};
    const char *paths[2] = {path, big_path};
    if (!quick) {
        if (lk_subdivide(&meshes[0], LK_SUBDIVIDE_LOOP, 2, &meshes[1], &error) != LK_OK ||
            lk_mesh_write(big_path, LK_FORMAT_PLY, &meshes[1], NULL, &error) != LK_OK) {
            fprintf(stderr, "bench_simplify: %s\n", error.message);
            return 1;
        }
    }
    FILE *csv = fopen(csv_path, "w");
    if (!csv) csv = fopen("/dev/null", "w");
    fprintf(csv, "mesh,percent,method,triangles,median_ms,runs,mtri_per_s,speed_vs_meshopt,hausdorff_pct,rms_pct\n");
    static const double percents[3] = {50, 10, 1};
    for (int m = 0; m < mesh_count; m++) {
        const lk_mesh *mesh = &meshes[m];
        for (int p = 0; p < 3; p++) {
            size_t target = (size_t)llround(mesh->triangle_count * percents[p] / 100);
            printf("\n%s (%zu triangles) -> %g%% (%zu triangles)\n\n", names[m], mesh->triangle_count, percents[p],
                   target);
            printf("| %-26s | %10s | %12s | %8s | %9s | %8s | %8s |\n", "method", "triangles", "ms (runs)", "Mtri/s",
                   clustering_only ? "vs sloppy" : "vs meshopt", "haus. %", "rms %");
            printf("|---|---:|---:|---:|---:|---:|---:|\n");
            fflush(stdout);
            row rows[8];
            memset(rows, 0, sizeof rows);
            contender contenders[6];
            memset(contenders, 0, sizeof contenders);
            int count = 0;
#ifdef LODKIT_HAVE_MESHOPTIMIZER
            if (!clustering_only) contenders[count++] = (contender){.name = "meshopt_simplify", .meshopt = 1};
            contenders[count++] = (contender){.name = "meshopt_simplifySloppy", .meshopt = 2};
#endif
            if (!clustering_only) {
                contenders[count++] = (contender){.name = "lodkit qem", .method = LK_SIMPLIFY_QEM, .threads = 1};
                /* both cores where lk_simplify uses them (LK_SIMPLIFY_PARALLEL_MIN) */
                if (mesh->triangle_count >= LK_SIMPLIFY_PARALLEL_MIN)
                    contenders[count++] =
                        (contender){.name = "lodkit qem, 2 threads", .method = LK_SIMPLIFY_QEM, .threads = 2};
            }
            contenders[count++] = (contender){.name = "lodkit uniform", .method = LK_SIMPLIFY_UNIFORM, .threads = 1};
            contenders[count++] = (contender){.name = "lodkit floating", .method = LK_SIMPLIFY_FLOATING, .threads = 1};
            run_contenders(contenders, count, mesh, target, rows);
            for (int k = 0; k < count; k++) contender_free(&contenders[k]);
            /* The reference: meshopt_simplify, or Sloppy with --clustering. */
            double meshopt_ms = 0;
            for (int k = 0; k < count; k++)
                if (contenders[k].meshopt == (clustering_only ? 2 : 1) && rows[k].ok) meshopt_ms = rows[k].milliseconds;
            if (!quick && !clustering_only) {
                run_open3d(mesh, paths[m], "quadric", target, out_dir, script, &rows[count++]);
                run_open3d(mesh, paths[m], "clustering", target, out_dir, script, &rows[count++]);
            }
            for (int i = 0; i < count; i++) {
                print_row(csv, names[m], mesh->triangle_count, percents[p], &rows[i], meshopt_ms);
                fflush(stdout);
            }
            run_first_calls(paths[m], target, clustering_only);
        }
    }
    fclose(csv);
    for (int m = 0; m < mesh_count; m++) lk_mesh_free(&meshes[m]);

    /* The wavelet paper's Table 4: clusterings at 12.5% of the vertices,
     * maximum error in % of the bounding-box diagonal. (The paper
     * re-triangulates every result with Delaunay, so its triangle counts
     * are not comparable with plain clustering's.) */
    static const struct {
        const char *file;
        double paper_uniform, paper_floating;
    } paper[] = {{"bunny.obj", 1.42, 1.03}, {"triceratops.off", 3.10, 3.08}};
    printf("\nClustering at 12.5%% of the vertices vs the wavelet paper (Table 4), max error %% of diagonal\n\n");
    printf("| model | method | vertices | triangles | lodkit haus. %% | paper %% |\n|---|---|---:|---:|---:|---:|\n");
    for (size_t i = 0; i < 2; i++) {
        lk_mesh mesh;
        snprintf(path, sizeof path, "%s/%s", samples, paper[i].file);
        if (lk_mesh_read(path, LK_FORMAT_AUTO, NULL, &mesh, &error) != LK_OK) continue;
        for (int floating = 0; floating < 2; floating++) {
            lk_simplify_options options;
            lk_simplify_options_default(&options);
            options.target_vertices = (size_t)llround(0.125 * mesh.vertex_count);
            lk_simplify_result result;
            row r = {0};
            if (lk_simplify(&mesh, floating ? LK_SIMPLIFY_FLOATING : LK_SIMPLIFY_UNIFORM, &options, &result, NULL, NULL,
                            &error) != LK_OK)
                continue;
            measure(&mesh, &result.mesh, &r);
            printf("| %s | %s | %zu | %zu | %.2f | %.2f |\n", paper[i].file, floating ? "floating" : "uniform",
                   result.mesh.vertex_count, result.mesh.triangle_count, r.hausdorff_percent,
                   floating ? paper[i].paper_floating : paper[i].paper_uniform);
            lk_simplify_result_free(&result);
        }
        lk_mesh_free(&mesh);
    }
    return 0;
}
