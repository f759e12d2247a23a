/* SPDX-License-Identifier: MIT */
/* lodkit progressive: a progressive mesh written as a .lks stream: version 2
 * (range-coded vertex splits with attributes) by default, version 1 (the
 * paper's triangle strips) with the bandwidth its strips save. */
#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

const cli_help progressive_help = {
    "IN OUT.lks",
    "Build a progressive mesh (QEM edge collapses down to a base mesh, then the\n"
    "vertex splits back) and write it as a .lks stream (docs/stream-format.md)\n"
    "that a client can draw while it downloads. Version 2 (default) codes the\n"
    "splits and the input's normals, texture coordinates and colours with a range\n"
    "coder; its first frame comes in the first kilobytes. Version 1\n"
    "(--stream-version=1) carries the paper's progressive triangle strips (E-PS\n"
    "updates, DTFS filtering) and reports the bandwidth they save.\n",
    NULL,
};

/* Two ways to average over levels. The paper's figure is the indices sent
 * during the whole transmission (every level drawn once): 1 - sum(DTFS) /
 * sum(PM), the reduction of the mean bandwidth per level. The mean of the
 * per-level ratios weighs the coarse levels, where few triangles are left
 * and DTFS strips cost about as much as independent triangles, as much as
 * the fine ones, so it is lower. Both are reported. */
typedef struct bandwidth_summary {
    size_t level_count;
    double reduction;            /* 1 - sum(filtered) / sum(pm) */
    double unfiltered_reduction; /* 1 - sum(unfiltered) / sum(pm) (negative when strips cost more) */
    double mean_level_reduction; /* mean over levels of 1 - filtered / pm */
} bandwidth_summary;

static lk_status measure_bandwidth(const lk_progressive_strips *strips, const lk_progressive_mesh *pm, size_t sampled,
                                   const char *csv_path, progress_state *progress, bandwidth_summary *summary,
                                   lk_error *error)
{
    size_t level_total = pm->split_count + 1;
    size_t count = sampled == 0 || sampled > level_total ? level_total : sampled;
    size_t *levels = malloc_array(count, sizeof *levels);
    lk_strip_bandwidth *rows = malloc_array(count, sizeof *rows);
    if (!levels || !rows) {
        free(levels), free(rows);
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory for %zu levels", count);
    }
    /* evenly spaced, first and last included */
    for (size_t i = 0; i < count; i++)
        levels[i] =
            count == 1 ? pm->split_count : (size_t)((double)i * (double)pm->split_count / (double)(count - 1) + 0.5);
    lk_status status = lk_progressive_strips_bandwidth(strips, pm, levels, count, rows, progress_draw, progress, error);
    if (status == LK_OK) {
        double pm_sum = 0, filtered_sum = 0, unfiltered_sum = 0, level_reduction = 0;
        for (size_t i = 0; i < count; i++) {
            pm_sum += (double)rows[i].pm_indices;
            filtered_sum += (double)rows[i].filtered_indices;
            unfiltered_sum += (double)rows[i].strip_indices;
            level_reduction += 1 - (double)rows[i].filtered_indices / (double)rows[i].pm_indices;
        }
        summary->level_count = count;
        summary->reduction = 1 - filtered_sum / pm_sum;
        summary->unfiltered_reduction = 1 - unfiltered_sum / pm_sum;
        summary->mean_level_reduction = level_reduction / (double)count;
    }
    if (status == LK_OK && csv_path) {
        lk_output *file;
        status = lk_output_open(csv_path, &file, error);
        if (status == LK_OK) {
            FILE *csv = lk_output_stream(file);
            fprintf(csv, "level,vertices,triangles,pm_indices,strip_indices,dtfs_indices\n");
            for (size_t i = 0; i < count; i++)
                fprintf(csv, "%zu,%zu,%zu,%zu,%zu,%zu\n", rows[i].level, pm->base_vertex_count + rows[i].level,
                        rows[i].triangles, rows[i].pm_indices, rows[i].strip_indices, rows[i].filtered_indices);
            status = lk_output_commit(file, error);
        }
    }
    free(levels);
    free(rows);
    return status;
}

static const char *stripifier_name(lk_stripifier method)
{
    return method == LK_STRIPIFY_LODKIT ? "lodkit" : method == LK_STRIPIFY_MESHOPT ? "meshopt" : "best";
}

int cmd_progressive(int argc, char **argv)
{
    lk_progressive_options pm_options;
    lk_progressive_options_default(&pm_options);
    lk_stream_options stream_options;
    lk_stream_options_default(&stream_options);
    lk_stripifier stripifier = LK_STRIPIFY_BEST;
    size_t sampled_levels = 256, value;
    int placement_given = 0, base_given = 0, order_given = 0;
    /* Version 2 by default: its first frame comes in the first kilobytes and
     * it carries the input's attributes. Version 1 (the paper's strips, E-PS
     * and DTFS) on request; the options below only mean something there. */
    stream_options.version = 2;
    const char *strip_option = NULL; /* the first version-1-only option given */
    const char *bandwidth_path = NULL;
    cli_parser parser;
    cli_parse_begin(&parser, CMD_PROGRESSIVE, argc, argv);
    for (int id; (id = cli_next(&parser)) != CLI_DONE;) {
        const char *arg = parser.value;
        switch (id) {
        case OPT_BASE_RATIO:
            base_given = 1;
            if (!parse_double_option(arg, &pm_options.base_ratio) || pm_options.base_ratio <= 0 ||
                pm_options.base_ratio > 1)
                return usage_error("progressive", "--base-ratio: '%s' is not a number in (0, 1]", arg);
            break;
        case OPT_BASE_TRIANGLES:
            base_given = 1;
            if (!parse_size_option(arg, &pm_options.base_triangles) || !pm_options.base_triangles)
                return usage_error("progressive", "--base-triangles: '%s' is not a positive integer", arg);
            break;
        case OPT_PLACEMENT:
            placement_given = 1;
            if (!strcmp(arg, "endpoint"))
                pm_options.simplify.flags |= LK_SIMPLIFY_ENDPOINTS;
            else if (!strcmp(arg, "optimal"))
                pm_options.simplify.flags &= ~(unsigned)LK_SIMPLIFY_ENDPOINTS;
            else
                return usage_error("progressive", "--placement: '%s' is not optimal or endpoint", arg);
            break;
        case OPT_COLLAPSE_ORDER:
            order_given = 1;
            if (!strcmp(arg, "rounds"))
                pm_options.simplify.flags |= LK_SIMPLIFY_ROUNDS;
            else if (!strcmp(arg, "greedy"))
                pm_options.simplify.flags &= ~(unsigned)LK_SIMPLIFY_ROUNDS;
            else
                return usage_error("progressive", "--collapse-order: '%s' is not rounds or greedy", arg);
            break;
        case OPT_LOCK_BORDER: pm_options.simplify.flags |= LK_SIMPLIFY_LOCK_BORDER; break;
        case OPT_FEATURE_ANGLE:
            if (!parse_double_option(arg, &pm_options.simplify.feature_angle) ||
                pm_options.simplify.feature_angle < 0 || pm_options.simplify.feature_angle > 180)
                return usage_error("progressive", "--feature-angle: '%s' is not an angle in [0, 180]", arg);
            break;
        case OPT_STRIPIFIER:
            if (!strip_option) strip_option = "--stripifier";
            if (!strcmp(arg, "best"))
                stripifier = LK_STRIPIFY_BEST;
            else if (!strcmp(arg, "lodkit"))
                stripifier = LK_STRIPIFY_LODKIT;
            else if (!strcmp(arg, "meshopt"))
                stripifier = LK_STRIPIFY_MESHOPT;
            else
                return usage_error("progressive", "--stripifier: '%s' is not best, lodkit or meshopt", arg);
            break;
        case OPT_BITS:
            if (!parse_size_option(arg, &value) || value < 4 || value > 24)
                return usage_error("progressive", "--bits: '%s' is not a bit count from 4 to 24", arg);
            stream_options.position_bits = (unsigned)value;
            break;
        case OPT_CHUNK_SPLITS:
            if (!parse_size_option(arg, &stream_options.splits_per_chunk) || !stream_options.splits_per_chunk ||
                stream_options.splits_per_chunk > 1000000)
                return usage_error("progressive", "--chunk-splits: '%s' is not a count from 1 to 1000000", arg);
            break;
        case OPT_NO_COMPRESS:
            if (!strip_option) strip_option = "--no-compress";
            stream_options.compress = 0;
            break;
        case OPT_STREAM_VERSION:
            if (!parse_size_option(arg, &value) || value < 1 || value > 2)
                return usage_error("progressive", "--stream-version: '%s' is not 1 or 2", arg);
            stream_options.version = value;
            break;
        case OPT_BANDWIDTH_LEVELS:
            if (!strip_option) strip_option = "--bandwidth-levels";
            if (!parse_size_option(arg, &sampled_levels) || sampled_levels == 1)
                return usage_error("progressive", "--bandwidth-levels: '%s' is not 0 (all) or a count >= 2", arg);
            break;
        case OPT_BANDWIDTH:
            if (!strip_option) strip_option = "--bandwidth";
            bandwidth_path = arg;
            break;
        default: return cli_unhandled(&parser, id);
        }
    }
    int json = parser.json, quiet = parser.quiet;
    if (argc - optind != 2) return usage_error("progressive", "%s", "expected IN and OUT.lks");
    int version2 = stream_options.version == 2;
    if (version2 && strip_option)
        return usage_error("progressive",
                           "%s applies to version-1 streams (triangle strips); add --stream-version=1 (the default "
                           "is version 2)",
                           strip_option);
    /* Version 2 codes one position per split when the kept vertex stays
     * where it was (half the bits of optimal placement), and its first
     * frame should arrive in the first kilobytes. */
    if (version2 && !placement_given) pm_options.simplify.flags |= LK_SIMPLIFY_ENDPOINTS;
    /* Version 2 names a batch's split vertices among the vertices the
     * decoder has: collapses in rounds make batches of about 15% of them
     * instead of about 6%. */
    if (version2 && !order_given) pm_options.simplify.flags |= LK_SIMPLIFY_ROUNDS;
    if (version2 && !base_given) pm_options.base_triangles = LK_STREAM_V2_BASE_TRIANGLES;
    const char *in = argv[optind], *out = argv[optind + 1];

    lk_mesh mesh;
    lk_progressive_mesh pm;
    lk_progressive_strips strips;
    memset(&pm, 0, sizeof pm);
    memset(&strips, 0, sizeof strips);
    unsigned char *bytes = NULL;
    size_t size = 0;
    lk_stream_info info;
    memset(&info, 0, sizeof info);
    lk_stream_chunk_info *chunks = NULL;
    bandwidth_summary bandwidth;
    memset(&bandwidth, 0, sizeof bandwidth);
    lk_error error = {0};
    progress_state progress;
    progress_init(&progress, quiet || json, "progressive");
    double start = now_seconds(), simplify_seconds = 0, strip_seconds = 0, encode_seconds = 0;
    lk_status status = load_mesh(in, &mesh, NULL, NULL, &error);
    if (status == LK_OK) {
        double t = now_seconds();
        status = lk_progressive_mesh_build(&mesh, &pm_options, &pm, progress_draw, &progress, &error);
        simplify_seconds = now_seconds() - t;
    }
    if (status == LK_OK && !version2) {
        double t = now_seconds();
        status = lk_progressive_strips_build_ex(&pm, stripifier, &strips, progress_draw, &progress, &error);
        strip_seconds = now_seconds() - t;
    }
    if (status == LK_OK) {
        double t = now_seconds();
        progress_draw(&progress, 0, "encode"); /* lk_stream_encode reports no progress */
        status = version2 ? lk_stream_encode_with_attributes(&pm, &mesh, &stream_options, &bytes, &size, &error)
                          : lk_stream_encode(&pm, &strips, &stream_options, &bytes, &size, &error);
        encode_seconds = now_seconds() - t;
    }
    if (status == LK_OK) status = lk_stream_inspect(bytes, size, &info, &chunks, &error);
    if (status == LK_OK) status = lk_stream_write_file(out, bytes, size, &error);
    if (status == LK_OK && pm.split_count > 0 && !version2)
        status = measure_bandwidth(&strips, &pm, sampled_levels, bandwidth_path, &progress, &bandwidth, &error);
    progress_done(&progress);
    double seconds = now_seconds() - start;
    int exit_code = EXIT_OK;
    if (status != LK_OK) {
        print_error_for(in, out, &error);
        exit_code = EXIT_BAD_INPUT;
        goto done;
    }
    double bits_per_vertex = 8.0 * (double)size / (double)pm.vertex_count;
    double detail_saving =
        strips.naive_detail_bytes > 0 ? 1 - strips.encoded_detail_bytes / strips.naive_detail_bytes : 0;
    /* The input's attributes: version 2 carries them, version 1 drops them. */
    char attributes[64] = "";
    if (mesh.normals) strcat(attributes, "normals");
    if (mesh.texcoords) strcat(attributes, *attributes ? ", texture coordinates" : "texture coordinates");
    if (mesh.colors) strcat(attributes, *attributes ? ", colours" : "colours");
    const char *dropped = version2 ? "" : attributes, *carried = version2 ? attributes : "";
    size_t first_frame_bytes = info.chunk_count ? (size_t)(chunks[0].offset + chunks[0].size) : 0;
    cJSON *root = NULL;
    if (json) {
        root = cJSON_CreateObject();
        cJSON_AddStringToObject(root, "input", in);
        cJSON_AddStringToObject(root, "output", out);
        cJSON_AddNumberToObject(root, "vertices", (double)pm.vertex_count);
        cJSON_AddNumberToObject(root, "triangles", (double)pm.triangle_count);
        cJSON_AddNumberToObject(root, "base_vertices", (double)pm.base_vertex_count);
        cJSON_AddNumberToObject(root, "base_triangles", (double)pm.base_triangle_count);
        cJSON_AddNumberToObject(root, "splits", (double)pm.split_count);
        cJSON_AddNumberToObject(root, "bytes", (double)size);
        cJSON_AddNumberToObject(root, "bits_per_vertex", bits_per_vertex);
        cJSON_AddNumberToObject(root, "chunks", (double)info.chunk_count);
        cJSON_AddNumberToObject(root, "position_bits", info.position_bits);
        cJSON_AddNumberToObject(root, "quantisation_error_percent",
                                info.diagonal > 0 ? 100 * info.quantisation_error / info.diagonal : 0);
        cJSON_AddNumberToObject(root, "stream_version", version2 ? 2 : 1);
        cJSON_AddNumberToObject(root, "first_frame_bytes", (double)first_frame_bytes);
        cJSON_AddStringToObject(root, "dropped_attributes", dropped);
        cJSON_AddStringToObject(root, "carried_attributes", carried);
    }
    if (json && !version2) {
        cJSON_AddStringToObject(root, "stripifier", stripifier_name(strips.stripifier));
        cJSON_AddNumberToObject(root, "strip_length", (double)strips.strip_length);
        cJSON_AddNumberToObject(root, "lodkit_indices_per_triangle", strips.lodkit_indices_per_triangle);
        cJSON_AddNumberToObject(root, "meshopt_indices_per_triangle", strips.meshopt_indices_per_triangle);
        cJSON_AddNumberToObject(root, "naive_updates_per_split", strips.mean_naive_updates);
        cJSON_AddNumberToObject(root, "encoded_updates_per_split", strips.mean_encoded_updates);
        cJSON_AddNumberToObject(root, "naive_detail_bytes", strips.naive_detail_bytes);
        cJSON_AddNumberToObject(root, "encoded_detail_bytes", strips.encoded_detail_bytes);
        cJSON_AddNumberToObject(root, "levels_measured", (double)bandwidth.level_count);
        cJSON_AddNumberToObject(root, "dtfs_reduction_vs_pm", bandwidth.reduction);
        cJSON_AddNumberToObject(root, "unfiltered_reduction_vs_pm", bandwidth.unfiltered_reduction);
        cJSON_AddNumberToObject(root, "dtfs_mean_level_reduction_vs_pm", bandwidth.mean_level_reduction);
    }
    if (json) {
        cJSON_AddNumberToObject(root, "seconds", seconds);
        print_json(root);
    } else if (!quiet) {
        printf("%s: %s, %s -> base %s, %s + %s\n", in, n_vertices(pm.vertex_count), n_triangles(pm.triangle_count),
               n_vertices(pm.base_vertex_count), n_triangles(pm.base_triangle_count),
               count_noun(pm.split_count, "vertex split", "vertex splits"));
        printf("%s: %s bytes, %.1f bits/vertex, %s, %u-bit positions (error <= %.4f%% of the diagonal)\n", out,
               thousands(size), bits_per_vertex, count_noun(info.chunk_count, "chunk", "chunks"), info.position_bits,
               info.diagonal > 0 ? 100 * info.quantisation_error / info.diagonal : 0);
        printf("first frame after %s bytes (%.1f%% of the stream); carries positions, triangles%s%s%s%s\n",
               thousands(first_frame_bytes), 100.0 * (double)first_frame_bytes / (double)size, *carried ? ", " : "",
               carried, *dropped ? "; drops the input's " : "", dropped);
    }
    if (!json && !quiet && !version2) {
        printf("strips: %.3f indices/triangle (lodkit %.3f, meshopt %.3f; kept %s)\n",
               (double)strips.strip_length / (double)pm.triangle_count, strips.lodkit_indices_per_triangle,
               strips.meshopt_indices_per_triangle, stripifier_name(strips.stripifier));
        printf("strip positions updated per split: naive %.2f, E-PS %.2f (detail %.1f -> %.1f bytes, %.1f%% less)\n",
               strips.mean_naive_updates, strips.mean_encoded_updates, strips.naive_detail_bytes,
               strips.encoded_detail_bytes, 100 * detail_saving);
        if (bandwidth.level_count)
            printf("indices sent to the GPU over %s vs independent triangles: DTFS strips %.1f%% less "
                   "(mean of per-level ratios %.1f%%), unfiltered strips %.1f%% %s\n",
                   count_noun(bandwidth.level_count, "level", "levels"), 100 * bandwidth.reduction,
                   100 * bandwidth.mean_level_reduction, 100 * fabs(bandwidth.unfiltered_reduction),
                   bandwidth.unfiltered_reduction >= 0 ? "less" : "more");
    }
    if (!json && !quiet) {
        if (version2)
            printf("time: %.2f s (simplify %.2f, encode %.2f)\n", seconds, simplify_seconds, encode_seconds);
        else
            printf("time: %.2f s (simplify %.2f, strips %.2f, encode %.2f)\n", seconds, simplify_seconds, strip_seconds,
                   encode_seconds);
    }
done:
    lk_free(chunks);
    lk_free(bytes);
    lk_progressive_strips_free(&strips);
    lk_progressive_mesh_free(&pm);
    lk_mesh_free(&mesh);
    return exit_code;
}
