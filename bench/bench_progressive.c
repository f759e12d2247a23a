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
 *   6. error of stream prefixes (lodkit metro against the full mesh);
 *   7. stream version 2 at 11 and 13 bits against Draco -cl 7 / -cl 10 at
 *      the same bits (positions and connectivity), with encode and decode
 *      speed;
 *   8. version 2 against what users send instead, a discrete LOD chain
 *      (meshopt_simplify at 1/32 .. 1/2 of the triangles and the full mesh,
 *      each Draco -cl 10 at 11 bits, coarsest first): at each byte count
 *      where the chain completes a level, the stream prefix of as many
 *      bytes (bunny, cow, fandisk; CSV per model in OUT for the
 *      rate-distortion plot drawn by bench/run.sh).
 * --quick: cow and bunny only, every 8th level. */
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include <meshoptimizer.h>

#include "bench_common.h"
#include "lodkit.h"

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
static long draco_size_bits(const lk_mesh *mesh, const char *out_dir, const char *name, int level, int bits)
{
    char input[1024], output[1024], command[4096];
    snprintf(input, sizeof input, "%s/%s-positions.ply", out_dir, name);
    snprintf(output, sizeof output, "%s/%s.drc", out_dir, name);
    lk_mesh positions = *mesh; /* positions and triangles only, like the stream */
    positions.normals = positions.texcoords = positions.colors = NULL;
    lk_error error = {0};
    if (lk_mesh_write(input, LK_FORMAT_PLY, &positions, NULL, &error) != LK_OK) return -1;
    snprintf(command, sizeof command, "draco_encoder -i '%s' -o '%s' -qp %d -cl %d >/dev/null 2>&1", input, output,
             bits, level);
    if (system(command) != 0) return -1;
    return file_size(output);
}

static long draco_size(const lk_mesh *mesh, const char *out_dir, const char *name, int level)
{
    return draco_size_bits(mesh, out_dir, name, level, 11);
}

/* Draco -cl 10 at 11-bit positions with the mesh's attributes at the
 * version-2 defaults (normals 10 bits, texture coordinates 12, colours 8),
 * through OBJ (normals, texture coordinates) or PLY (colours). */
static long draco_size_attributes(const lk_mesh *mesh, const char *out_dir, const char *name)
{
    char input[1024], output[1024], command[4096];
    snprintf(input, sizeof input, "%s/%s-attributes.%s", out_dir, name, mesh->colors ? "ply" : "obj");
    snprintf(output, sizeof output, "%s/%s-attributes.drc", out_dir, name);
    lk_error error = {0};
    if (lk_mesh_write(input, mesh->colors ? LK_FORMAT_PLY : LK_FORMAT_OBJ, mesh, NULL, &error) != LK_OK) return -1;
    snprintf(command, sizeof command, "draco_encoder -i '%s' -o '%s' -qp 11 -qn 10 -qt 12 -qg 8 -cl 10 >/dev/null 2>&1",
             input, output);
    if (system(command) != 0) return -1;
    return file_size(output);
}

/* Decodes OUT/NAME.drc (the last draco_size_bits output) into a mesh. */
static int draco_decode(const char *out_dir, const char *name, lk_mesh *out)
{
    char input[1024], output[1024], command[4096];
    snprintf(input, sizeof input, "%s/%s.drc", out_dir, name);
    snprintf(output, sizeof output, "%s/%s-decoded.ply", out_dir, name);
    snprintf(command, sizeof command, "draco_decoder -i '%s' -o '%s' >/dev/null 2>&1", input, output);
    if (system(command) != 0) return -1;
    lk_error error = {0};
    return lk_mesh_read(output, LK_FORMAT_PLY, NULL, out, &error) == LK_OK ? 0 : -1;
}

/* A version-2 stream as `lodkit progressive --stream-version 2 --bits B`
 * writes it: endpoint placement, collapses in rounds (greedy order when
 * `greedy`), a 200-triangle base; with the mesh's attributes when
 * `attributes`. */
static unsigned char *stream_v2_ordered(const lk_mesh *mesh, unsigned bits, int attributes, int greedy, size_t *size,
                                        double *encode_seconds)
{
    lk_error error = {0};
    lk_progressive_options options;
    lk_progressive_options_default(&options);
    options.base_triangles = 200;
    options.simplify.flags |= LK_SIMPLIFY_ENDPOINTS | (greedy ? 0 : LK_SIMPLIFY_ROUNDS);
    lk_progressive_mesh pm;
    double t = now();
    if (lk_progressive_mesh_build(mesh, &options, &pm, NULL, NULL, &error)) die("v2 progressive mesh", &error);
    double built = now();
    lk_stream_options stream_options;
    lk_stream_options_default(&stream_options);
    stream_options.position_bits = bits;
    stream_options.version = 2;
    unsigned char *bytes;
    lk_status status = attributes ? lk_stream_encode_with_attributes(&pm, mesh, &stream_options, &bytes, size, &error)
                                  : lk_stream_encode(&pm, NULL, &stream_options, &bytes, size, &error);
    if (status) die("v2 encode", &error);
    if (encode_seconds) *encode_seconds = now() - built;
    (void)t;
    lk_progressive_mesh_free(&pm);
    return bytes;
}

static unsigned char *stream_v2_with(const lk_mesh *mesh, unsigned bits, int attributes, size_t *size,
                                     double *encode_seconds)
{
    return stream_v2_ordered(mesh, bits, attributes, 0, size, encode_seconds);
}

static unsigned char *stream_v2(const lk_mesh *mesh, unsigned bits, size_t *size, double *encode_seconds)
{
    return stream_v2_with(mesh, bits, 0, size, encode_seconds);
}

/* Table 7b: a model with its attributes, against Draco with the same. */
static void attributes_row(const lk_mesh *mesh, const char *name, const char *out_dir)
{
    size_t with_size, bare_size;
    unsigned char *with = stream_v2_with(mesh, 11, 1, &with_size, NULL);
    unsigned char *bare = stream_v2_with(mesh, 11, 0, &bare_size, NULL);
    long draco = draco_size_attributes(mesh, out_dir, name);
    char attributes[64] = "";
    if (mesh->normals) strcat(attributes, "normals ");
    if (mesh->texcoords) strcat(attributes, "texcoords ");
    if (mesh->colors) strcat(attributes, "colours ");
    double vertices = (double)mesh->vertex_count;
    char draco_text[64] = "(draco_encoder missing)", ratio[32] = "-";
    if (draco > 0) {
        snprintf(draco_text, sizeof draco_text, "%.1f", 8.0 * (double)draco / vertices);
        snprintf(ratio, sizeof ratio, "%.2f", (double)with_size / (double)draco);
    }
    printf("| %s | %.0f | %s| %.1f | %.1f | %s | %s |\n", name, vertices, attributes,
           8.0 * (double)bare_size / vertices, 8.0 * (double)with_size / vertices, draco_text, ratio);
    lk_free(with);
    lk_free(bare);
}

/* Seconds to decode a whole stream (best of 5). */
static double decode_seconds(const unsigned char *bytes, size_t size)
{
    double best = 1e30;
    lk_error error = {0};
    for (int run = 0; run < 5; run++) {
        lk_stream_decoder *decoder;
        if (lk_stream_decoder_create(SIZE_MAX, &decoder, &error)) die("decoder", &error);
        double t = now();
        if (lk_stream_decoder_feed(decoder, bytes, size, &error)) die("decode", &error);
        t = now() - t;
        if (t < best) best = t;
        lk_stream_decoder_free(decoder);
    }
    return best;
}

/* Hausdorff and RMS distance (% of the diagonal) of the stream's prefix of
 * `bytes` bytes (the whole chunks in it) from the input. */
static void prefix_error(const lk_mesh *input, const unsigned char *stream, size_t bytes, double diagonal,
                         size_t *triangles, double *hausdorff, double *rms)
{
    lk_error error = {0};
    lk_stream_decoder *decoder;
    if (lk_stream_decoder_create(SIZE_MAX, &decoder, &error)) die("decoder", &error);
    if (lk_stream_decoder_feed(decoder, stream, bytes, &error)) die("prefix", &error);
    lk_mesh level;
    if (lk_stream_decoder_mesh(decoder, &level, &error)) {
        *triangles = 0;
        *hausdorff = *rms = INFINITY; /* nothing drawable yet */
        lk_stream_decoder_free(decoder);
        return;
    }
    lk_metro_result metro;
    if (lk_metro(input, &level, NULL, &metro, NULL, NULL, &error)) die("metro", &error);
    *triangles = level.triangle_count;
    *hausdorff = 100 * metro.hausdorff / diagonal;
    *rms = 100 * (metro.forward.rms > metro.backward.rms ? metro.forward.rms : metro.backward.rms) / diagonal;
    lk_mesh_free(&level);
    lk_stream_decoder_free(decoder);
}

/* Table 8 for one model: the LOD chain against the version-2 prefix. */
static void chain_against_prefix(const lk_mesh *mesh, const char *name, const char *out_dir, int *wins, int *points)
{
    static const double ratios[] = {1.0 / 32, 1.0 / 16, 1.0 / 8, 1.0 / 4, 1.0 / 2, 1.0};
    size_t size;
    unsigned char *stream = stream_v2(mesh, 11, &size, NULL);
    lk_stream_info info;
    lk_stream_chunk_info *chunks;
    lk_error error = {0};
    if (lk_stream_inspect(stream, size, &info, &chunks, &error)) die(name, &error);
    double diagonal = info.diagonal;
    char csv_path[1024];
    snprintf(csv_path, sizeof csv_path, "%s/rd-%s.csv", out_dir, name);
    FILE *csv = fopen(csv_path, "w");
    if (csv) {
        fprintf(csv, "kind,bytes,triangles,hausdorff_percent,rms_percent\n");
        for (size_t c = 0; c < info.chunk_count; c++) {
            size_t end = (size_t)(chunks[c].offset + chunks[c].size), triangles;
            double hausdorff, rms;
            prefix_error(mesh, stream, end, diagonal, &triangles, &hausdorff, &rms);
            fprintf(csv, "stream,%zu,%zu,%.5f,%.5f\n", end, triangles, hausdorff, rms);
        }
    }
    size_t cumulative = 0;
    for (size_t r = 0; r < sizeof ratios / sizeof ratios[0]; r++) {
        lk_mesh level = *mesh;
        level.normals = level.texcoords = level.colors = NULL;
        uint32_t *indices = NULL;
        if (ratios[r] < 1) {
            size_t index_count = 3 * mesh->triangle_count;
            indices = malloc(index_count * sizeof *indices);
            if (!indices) return;
            size_t target = 3 * (size_t)((double)mesh->triangle_count * ratios[r]);
            level.triangle_count = meshopt_simplify(indices, mesh->indices, index_count, mesh->positions,
                                                    mesh->vertex_count, 3 * sizeof(float), target, FLT_MAX, 0, NULL) /
                                   3;
            level.indices = indices;
        }
        lk_mesh compact;
        if (lk_mesh_copy(&compact, &level, &error)) die("copy", &error);
        if (lk_mesh_remove_unused_vertices(&compact, NULL, &error)) die("compact", &error);
        char level_name[256];
        snprintf(level_name, sizeof level_name, "%s-chain-%zu", name, r);
        long drc = draco_size_bits(&compact, out_dir, level_name, 10, 11);
        lk_mesh decoded;
        if (drc <= 0 || draco_decode(out_dir, level_name, &decoded)) {
            printf("| %s | 1/%.0f | (draco_encoder/draco_decoder missing) | | | | | |\n", name, 1 / ratios[r]);
            lk_mesh_free(&compact);
            free(indices);
            continue;
        }
        cumulative += (size_t)drc;
        lk_metro_result metro;
        if (lk_metro(mesh, &decoded, NULL, &metro, NULL, NULL, &error)) die("metro", &error);
        double chain_hausdorff = 100 * metro.hausdorff / diagonal;
        size_t prefix = cumulative < size ? cumulative : size, triangles;
        double hausdorff, rms;
        prefix_error(mesh, stream, prefix, diagonal, &triangles, &hausdorff, &rms);
        int win = hausdorff <= chain_hausdorff;
        char label[16] = "full";
        if (ratios[r] < 1) snprintf(label, sizeof label, "1/%.0f", 1 / ratios[r]);
        *wins += win;
        *points += 1;
        printf("| %s | %s | %zu | %zu | %.4f | %zu | %.4f | %s |\n", name, label, cumulative, compact.triangle_count,
               chain_hausdorff, triangles, hausdorff, win ? "stream" : "chain");
        if (csv) fprintf(csv, "chain,%zu,%zu,%.5f,\n", cumulative, compact.triangle_count, chain_hausdorff);
        lk_mesh_free(&decoded);
        lk_mesh_free(&compact);
        free(indices);
    }
    if (csv) fclose(csv);
    lk_free(chunks);
    lk_free(stream);
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
    printf("\n### Stream version 2 (`--stream-version 2`: endpoint placement, collapses in rounds, 200-triangle "
           "base) vs Draco\n\n");
    printf(
        "| model | vertices | v2 11 bits | v2 11 bits, greedy order | Draco -cl 7 / -cl 10, 11 bits | v2 / Draco -cl "
        "10 | v2 13 bits | Draco -cl 7 / -cl 10, 13 bits | v2 / Draco -cl 10 | first frame (11 bits) | encode s | "
        "decode ms (M vertices/s) |\n");
    printf("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    {
        lk_mesh dragon = {0};
        char dragon_path[1024];
        snprintf(dragon_path, sizeof dragon_path, "%s/ChineseDragon-10kv.off", samples);
        int have_dragon = !quick && lk_mesh_read(dragon_path, LK_FORMAT_AUTO, NULL, &dragon, &error) == LK_OK;
        for (size_t i = 0; i < model_count + (size_t)have_dragon; i++) {
            const lk_mesh *mesh = i < model_count ? &models[i].mesh : &dragon;
            const char *name = i < model_count ? models[i].name : "Chinese dragon";
            double vertices = (double)mesh->vertex_count, encode_seconds;
            size_t size11, size13;
            unsigned char *v2_11 = stream_v2(mesh, 11, &size11, &encode_seconds);
            unsigned char *v2_13 = stream_v2(mesh, 13, &size13, NULL);
            size_t greedy_size;
            lk_free(stream_v2_ordered(mesh, 11, 0, 1, &greedy_size, NULL));
            double decode = decode_seconds(v2_11, size11);
            lk_stream_info info;
            lk_stream_chunk_info *chunks;
            if (lk_stream_inspect(v2_11, size11, &info, &chunks, &error)) die(name, &error);
            size_t first = (size_t)(chunks[0].offset + chunks[0].size);
            char draco11[64] = "-", draco13[64] = "-", ratio11[32] = "-", ratio13[32] = "-";
            long d7 = draco_size_bits(mesh, out_dir, "v2-draco", 7, 11),
                 d10 = draco_size_bits(mesh, out_dir, "v2-draco", 10, 11);
            if (d7 > 0 && d10 > 0) {
                snprintf(draco11, sizeof draco11, "%.1f / %.1f", 8.0 * (double)d7 / vertices,
                         8.0 * (double)d10 / vertices);
                snprintf(ratio11, sizeof ratio11, "%.2f", (double)size11 / (double)d10);
            }
            d7 = draco_size_bits(mesh, out_dir, "v2-draco", 7, 13);
            d10 = draco_size_bits(mesh, out_dir, "v2-draco", 10, 13);
            if (d7 > 0 && d10 > 0) {
                snprintf(draco13, sizeof draco13, "%.1f / %.1f", 8.0 * (double)d7 / vertices,
                         8.0 * (double)d10 / vertices);
                snprintf(ratio13, sizeof ratio13, "%.2f", (double)size13 / (double)d10);
            }
            printf("| %s | %.0f | %.1f | %.1f | %s | %s | %.1f | %s | %s | %zu B (%.1f%%) | %.3f | %.1f (%.2f) |\n",
                   name, vertices, 8.0 * (double)size11 / vertices, 8.0 * (double)greedy_size / vertices, draco11,
                   ratio11, 8.0 * (double)size13 / vertices, draco13, ratio13, first,
                   100.0 * (double)first / (double)size11, encode_seconds, 1000 * decode, vertices / decode / 1e6);
            lk_free(chunks);
            lk_free(v2_11);
            lk_free(v2_13);
        }
        if (have_dragon) lk_mesh_free(&dragon);
    }
    printf("\nBits per vertex of the whole stream; Draco codes positions and connectivity, single-rate. Issue 19's\n"
           "target: v2 <= 1.3x Draco -cl 10 at the same bits. Encode: the stream from the progressive mesh.\n");

    printf("\n### Stream version 2 with attributes vs Draco with the same (11-bit positions, normals 10, texture "
           "coordinates 12, colours 8 bits)\n\n");
    printf("| model | vertices | attributes | v2 positions only | v2 with attributes | Draco -cl 10 with attributes | "
           "v2 / Draco |\n|---|---:|---|---:|---:|---:|---:|\n");
    {
        lk_mesh spider = {0};
        char spider_path[1024];
        snprintf(spider_path, sizeof spider_path, "%s/assimp/OBJ/spider.obj", samples);
        if (lk_mesh_read(spider_path, LK_FORMAT_AUTO, NULL, &spider, &error) == LK_OK) {
            attributes_row(&spider, "spider (assimp)", out_dir);
            lk_mesh_free(&spider);
        }
        /* The cow with a colour per vertex from its position (RGB = the box coordinates). */
        const lk_mesh *cow = &models[0].mesh;
        lk_mesh coloured;
        if (lk_mesh_alloc(&coloured, cow->vertex_count, cow->triangle_count, LK_ATTR_COLORS, &error))
            die("cow", &error);
        memcpy(coloured.positions, cow->positions, 3 * cow->vertex_count * sizeof(float));
        memcpy(coloured.indices, cow->indices, 3 * cow->triangle_count * sizeof(uint32_t));
        float low[3] = {INFINITY, INFINITY, INFINITY}, high[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (size_t v = 0; v < cow->vertex_count; v++)
            for (int a = 0; a < 3; a++) {
                low[a] = fminf(low[a], cow->positions[3 * v + a]);
                high[a] = fmaxf(high[a], cow->positions[3 * v + a]);
            }
        for (size_t v = 0; v < cow->vertex_count; v++) {
            for (int a = 0; a < 3; a++)
                coloured.colors[4 * v + a] = (cow->positions[3 * v + a] - low[a]) / (high[a] - low[a]);
            coloured.colors[4 * v + 3] = 1;
        }
        attributes_row(&coloured, "cow, coloured by position", out_dir);
        lk_mesh_free(&coloured);
    }

    printf("\n### Version 2 against a discrete LOD chain (Draco -cl 10, 11 bits, coarsest first)\n\n");
    printf("| model | chain level | chain bytes so far | level triangles | level Hausdorff %% | stream prefix "
           "triangles | prefix Hausdorff %% | closer |\n");
    printf("|---|---|---:|---:|---:|---:|---:|---|\n");
    {
        int wins = 0, points = 0;
        for (size_t i = 0; i < model_count; i++)
            if (!strcmp(models[i].name, "bunny") || !strcmp(models[i].name, "cow") ||
                !strcmp(models[i].name, "fandisk"))
                chain_against_prefix(&models[i].mesh, models[i].name, out_dir, &wins, &points);
        printf("\nThe stream prefix is as close as the chain's level or closer at %d of %d points (Hausdorff of\n"
               "the prefix's whole chunks; the chain's level after Draco's quantisation). Issue 19's target: all.\n",
               wins, points);
    }

    for (size_t i = 0; i < model_count; i++) {
        lk_progressive_strips_free(&models[i].strips);
        lk_progressive_mesh_free(&models[i].pm);
        lk_mesh_free(&models[i].mesh);
    }
    return 0;
}
