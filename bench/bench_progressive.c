/* SPDX-License-Identifier: MIT */
/* Progressive meshes and strips benchmark (the progressive-strips paper,
 * tables 2-3 and Fig. 4), and the .lks stream against Draco.
 *
 *   bench_progressive [--samples DIR] [--out DIR] [--quick]
 *
 * Prints markdown tables:
 *   1. PM build: base mesh and vertex splits per model (paper table 2);
 *   2. stripifiers: indices per triangle, lodkit's own and meshoptimizer's;
 *   3. strip positions rewritten per split, naive PS vs E-PS, and detail
 *      bytes with 24-byte positions and 2-byte indices (paper table 3);
 *   4. indices sent to the GPU at every level, PM vs unfiltered vs DTFS
 *      strips, mean reduction vs PM (paper Fig. 4; CSV per model in OUT for
 *      the plot drawn by bench/run.sh);
 *   5. stream size in bits per vertex vs Draco (draco_encoder on PATH) and
 *      the uncompressed mesh;
 *   6. error of stream prefixes (lodkit metro against the full mesh).
 * --quick: cow and bunny only, every 8th level. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include "lodkit.h"

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

static void die(const char *what, const lk_error *error)
{
    fprintf(stderr, "bench_progressive: %s: %s\n", what, error->message);
    exit(1);
}

typedef struct model {
    const char *file;
    const char *name;
    /* the paper's numbers (table 2 and 3), 0 when the paper has no such model */
    double paper_naive, paper_encoded;
    lk_mesh mesh;
    lk_progressive_mesh pm;
    lk_progressive_strips strips;
    double pm_seconds, strips_seconds;
} model;

static long file_size(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0 ? (long)st.st_size : -1;
}

/* Draco at 11-bit positions (its default) and compression level `level`
 * (7 is its default, 10 the best). draco_encoder reads OBJ and PLY only, so
 * the mesh goes through a binary PLY first. */
static long draco_size(const lk_mesh *mesh, const char *out_dir, const char *name, int level)
{
    char input[1024], output[1024], command[4096];
    snprintf(input, sizeof input, "%s/%s-positions.ply", out_dir, name);
    snprintf(output, sizeof output, "%s/%s.drc", out_dir, name);
    lk_mesh positions = *mesh; /* positions and triangles only, like the stream */
    positions.normals = positions.texcoords = positions.colors = NULL;
    lk_error error = {0};
    if (lk_mesh_write(input, LK_FORMAT_PLY, &positions, NULL, &error) != LK_OK) return -1;
    snprintf(command, sizeof command, "draco_encoder -i '%s' -o '%s' -qp 11 -cl %d >/dev/null 2>&1", input, output,
             level);
    if (system(command) != 0) return -1;
    return file_size(output);
}

static void stream_bytes(const model *m, unsigned bits, int endpoint, size_t *size, double *error_percent)
{
    lk_error error = {0};
    lk_progressive_mesh pm_endpoint;
    const lk_progressive_mesh *pm = &m->pm;
    lk_progressive_strips strips_endpoint;
    const lk_progressive_strips *strips = &m->strips;
    if (endpoint) {
        lk_progressive_options options;
        lk_progressive_options_default(&options);
        options.simplify.flags |= LK_SIMPLIFY_ENDPOINTS;
        if (lk_progressive_mesh_build(&m->mesh, &options, &pm_endpoint, NULL, NULL, &error)) die(m->name, &error);
        if (lk_progressive_strips_build(&pm_endpoint, LK_STRIPIFY_BEST, &strips_endpoint, &error)) die(m->name, &error);
        pm = &pm_endpoint;
        strips = &strips_endpoint;
    }
    lk_stream_options options;
    lk_stream_options_default(&options);
    options.position_bits = bits;
    unsigned char *bytes;
    if (lk_stream_encode(pm, strips, &options, &bytes, size, &error)) die(m->name, &error);
    lk_stream_info info;
    lk_stream_chunk_info *chunks;
    if (lk_stream_inspect(bytes, *size, &info, &chunks, &error)) die(m->name, &error);
    *error_percent = 100 * info.quantisation_error / info.diagonal;
    lk_free(chunks);
    lk_free(bytes);
    if (endpoint) {
        lk_progressive_strips_free(&strips_endpoint);
        lk_progressive_mesh_free(&pm_endpoint);
    }
}

int main(int argc, char **argv)
{
    const char *samples = "data/samples", *out_dir = "bench/out";
    int quick = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--samples") && i + 1 < argc)
            samples = argv[++i];
        else if (!strcmp(argv[i], "--out") && i + 1 < argc)
            out_dir = argv[++i];
        else if (!strcmp(argv[i], "--quick"))
            quick = 1;
        else {
            fprintf(stderr, "usage: bench_progressive [--samples DIR] [--out DIR] [--quick]\n");
            return 2;
        }
    }
    model models[] = {{.file = "cow.off", .name = "cow", .paper_naive = 6.6, .paper_encoded = 3.0},
                      {.file = "bunny.obj", .name = "bunny", .paper_naive = 5.9, .paper_encoded = 3.0},
                      {.file = "triceratops.off", .name = "triceratops"},
                      {.file = "fandisk.off", .name = "fandisk"}};
    size_t model_count = quick ? 2 : sizeof models / sizeof models[0];
    lk_error error = {0};
    for (size_t i = 0; i < model_count; i++) {
        model *m = &models[i];
        char path[1024];
        snprintf(path, sizeof path, "%s/%s", samples, m->file);
        if (lk_mesh_read(path, LK_FORMAT_AUTO, NULL, &m->mesh, &error)) die(path, &error);
        double t = now();
        if (lk_progressive_mesh_build(&m->mesh, NULL, &m->pm, NULL, NULL, &error)) die(path, &error);
        m->pm_seconds = now() - t;
        t = now();
        if (lk_progressive_strips_build(&m->pm, LK_STRIPIFY_BEST, &m->strips, &error)) die(path, &error);
        m->strips_seconds = now() - t;
    }

    printf("### Progressive meshes: QEM collapses to a 5%% base mesh (paper table 2)\n\n");
    printf("| model | vertices | triangles | base vertices | base triangles | vertex splits | build s | strips s |\n");
    printf("|---|---:|---:|---:|---:|---:|---:|---:|\n");
    for (size_t i = 0; i < model_count; i++) {
        const model *m = &models[i];
        printf("| %s | %zu | %zu | %zu | %zu | %zu | %.2f | %.2f |\n", m->name, m->pm.vertex_count,
               m->pm.triangle_count, m->pm.base_vertex_count, m->pm.base_triangle_count, m->pm.split_count,
               m->pm_seconds, m->strips_seconds);
    }
    printf("\nPaper: cow 5.8K triangles -> 254 (2,722 splits), bunny 69.5K -> 3,471 (33,077 splits).\n\n");

    printf("### Stripifiers: indices per triangle of one strip joined by degenerate triangles\n\n");
    printf("| model | lodkit | meshoptimizer 0.18 | kept |\n|---|---:|---:|---|\n");
    for (size_t i = 0; i < model_count; i++) {
        const model *m = &models[i];
        printf("| %s | %.3f | %.3f | %s |\n", m->name, m->strips.lodkit_indices_per_triangle,
               m->strips.meshopt_indices_per_triangle,
               m->strips.stripifier == LK_STRIPIFY_LODKIT ? "lodkit" : "meshopt");
    }

    printf("\n### Strip positions rewritten per vertex split (paper table 3)\n\n");
    printf("| model | naive PS | E-PS | reduction | paper naive / E-PS | detail bytes naive | E-PS | saving |\n");
    printf("|---|---:|---:|---:|---|---:|---:|---:|\n");
    for (size_t i = 0; i < model_count; i++) {
        const model *m = &models[i];
        char paper[64] = "-";
        if (m->paper_naive > 0) snprintf(paper, sizeof paper, "%.1f / %.1f", m->paper_naive, m->paper_encoded);
        printf("| %s | %.2f | %.2f | %.1f%% | %s | %.1f | %.1f | %.1f%% |\n", m->name, m->strips.mean_naive_updates,
               m->strips.mean_encoded_updates,
               100 * (1 - m->strips.mean_encoded_updates / m->strips.mean_naive_updates), paper,
               m->strips.naive_detail_bytes, m->strips.encoded_detail_bytes,
               100 * (1 - m->strips.encoded_detail_bytes / m->strips.naive_detail_bytes));
    }
    printf("\nPaper: 49.9-55.2%% fewer positions, detail 17.9%% smaller on average.\n");

    printf("\n### Indices sent to the GPU per level, base to full (paper Fig. 4)\n\n");
    printf("| model | levels | PM mean | unfiltered PS mean | DTFS mean | DTFS vs PM | unfiltered vs PM | mean of "
           "per-level DTFS/PM | DTFS at base | DTFS at full |\n");
    printf("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for (size_t i = 0; i < 2 && i < model_count; i++) {
        const model *m = &models[i];
        size_t step = quick ? 8 : 1, count = m->pm.split_count / step + 1;
        size_t *levels = malloc(count * sizeof *levels);
        lk_strip_bandwidth *rows = malloc(count * sizeof *rows);
        if (!levels || !rows) return 1;
        for (size_t k = 0; k < count; k++) levels[k] = k * step;
        double t = now();
        if (lk_progressive_strips_bandwidth(&m->strips, &m->pm, levels, count, rows, NULL, NULL, &error))
            die(m->name, &error);
        t = now() - t;
        double pm_sum = 0, strip_sum = 0, dtfs_sum = 0, level_reduction = 0;
        char csv_path[1024];
        snprintf(csv_path, sizeof csv_path, "%s/bandwidth-%s.csv", out_dir, m->name);
        FILE *csv = fopen(csv_path, "w");
        if (csv) fprintf(csv, "level,triangles,pm,ps,dtfs\n");
        for (size_t k = 0; k < count; k++) {
            pm_sum += (double)rows[k].pm_indices;
            strip_sum += (double)rows[k].strip_indices;
            dtfs_sum += (double)rows[k].filtered_indices;
            level_reduction += 1 - (double)rows[k].filtered_indices / (double)rows[k].pm_indices;
            if (csv)
                fprintf(csv, "%zu,%zu,%zu,%zu,%zu\n", rows[k].level, rows[k].triangles, rows[k].pm_indices,
                        rows[k].strip_indices, rows[k].filtered_indices);
        }
        if (csv) fclose(csv);
        printf(
            "| %s | %zu (%.1f s) | %.0f | %.0f | %.0f | %.1f%% less | %+.1f%% | %.1f%% less | %.2f/tri | %.2f/tri |\n",
            m->name, count, t, pm_sum / (double)count, strip_sum / (double)count, dtfs_sum / (double)count,
            100 * (1 - dtfs_sum / pm_sum), 100 * (strip_sum / pm_sum - 1), 100 * level_reduction / (double)count,
            (double)rows[0].filtered_indices / (double)rows[0].triangles,
            (double)rows[count - 1].filtered_indices / (double)rows[count - 1].triangles);
        free(levels);
        free(rows);
    }
    printf("\nDTFS vs PM: indices over the whole transmission (every level drawn once), 1 - sum(DTFS) / sum(PM);\n"
           "the mean of the per-level ratios weighs the coarse levels (3.0-3.5 indices per triangle left) as much\n"
           "as the fine ones. Paper: DTFS 40.5-45.6%% less than PM during transmission.\n");

    printf("\n### Stream size (whole stream, bits per vertex) vs Draco and the plain mesh\n\n");
    printf("| model | lks default bits | lks 11 bits | lks 11 bits, endpoint placement | Draco 11 bits, -cl 7 / -cl 10 "
           "| float32 + uint32 mesh |\n");
    printf("|---|---:|---:|---:|---:|---:|\n");
    for (size_t i = 0; i < model_count; i++) {
        const model *m = &models[i];
        size_t size_default, size_11, size_endpoint;
        double error_default, error_11, error_endpoint;
        stream_bytes(m, 0, 0, &size_default, &error_default);
        stream_bytes(m, 11, 0, &size_11, &error_11);
        stream_bytes(m, 11, 1, &size_endpoint, &error_endpoint);
        long draco7 = draco_size(&m->mesh, out_dir, m->name, 7), draco10 = draco_size(&m->mesh, out_dir, m->name, 10);
        double vertices = (double)m->pm.vertex_count;
        char draco_text[64] = "(draco_encoder missing)";
        if (draco7 > 0 && draco10 > 0)
            snprintf(draco_text, sizeof draco_text, "%.1f / %.1f", 8.0 * (double)draco7 / vertices,
                     8.0 * (double)draco10 / vertices);
        printf("| %s | %.1f (error %.4f%%) | %.1f (%.3f%%) | %.1f | %s | %.0f |\n", m->name,
               8.0 * (double)size_default / vertices, error_default, 8.0 * (double)size_11 / vertices, error_11,
               8.0 * (double)size_endpoint / vertices, draco_text,
               8.0 * (12.0 * vertices + 12.0 * (double)m->pm.triangle_count) / vertices);
    }
    printf("\nDraco is single-rate (nothing to draw before the last byte); a .lks stream can be drawn from its\n"
           "first chunk on and carries every level. Error: largest quantisation error in %% of the diagonal.\n");

    printf("\n### Error of stream prefixes (bunny, default options; lodkit metro vs the full mesh)\n\n");
    printf("| bytes received | share | level | triangles | Hausdorff %% | RMS %% |\n|---:|---:|---:|---:|---:|---:|\n");
    {
        const model *m = &models[1];
        unsigned char *bytes;
        size_t size;
        if (lk_stream_encode(&m->pm, &m->strips, NULL, &bytes, &size, &error)) die("bunny", &error);
        lk_stream_info info;
        lk_stream_chunk_info *chunks;
        if (lk_stream_inspect(bytes, size, &info, &chunks, &error)) die("bunny", &error);
        size_t picks[8], pick_count = 0;
        size_t wanted[] = {0,
                           info.chunk_count / 16,
                           info.chunk_count / 8,
                           info.chunk_count / 4,
                           info.chunk_count / 2,
                           info.chunk_count - 1};
        for (size_t w = 0; w < sizeof wanted / sizeof wanted[0]; w++)
            if (pick_count == 0 || wanted[w] > picks[pick_count - 1]) picks[pick_count++] = wanted[w];
        for (size_t p = 0; p < pick_count; p++) {
            size_t end = (size_t)(chunks[picks[p]].offset + chunks[picks[p]].size);
            lk_stream_decoder *decoder;
            if (lk_stream_decoder_create(SIZE_MAX, &decoder, &error)) die("decoder", &error);
            if (lk_stream_decoder_feed(decoder, bytes, end, &error)) die("decoder", &error);
            lk_mesh level;
            if (lk_stream_decoder_mesh(decoder, &level, &error)) die("decoder", &error);
            lk_metro_result metro;
            if (lk_metro(&m->mesh, &level, NULL, &metro, NULL, NULL, &error)) die("metro", &error);
            double rms = metro.forward.rms > metro.backward.rms ? metro.forward.rms : metro.backward.rms;
            printf("| %zu | %.1f%% | %zu | %zu | %.4f | %.4f |\n", end, 100.0 * (double)end / (double)size,
                   lk_stream_decoder_level(decoder), level.triangle_count, 100 * metro.hausdorff / info.diagonal,
                   100 * rms / info.diagonal);
            lk_mesh_free(&level);
            lk_stream_decoder_free(decoder);
        }
        lk_free(chunks);
        lk_free(bytes);
    }
    for (size_t i = 0; i < model_count; i++) {
        lk_progressive_strips_free(&models[i].strips);
        lk_progressive_mesh_free(&models[i].pm);
        lk_mesh_free(&models[i].mesh);
    }
    return 0;
}
