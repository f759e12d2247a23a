/* SPDX-License-Identifier: MIT */
/* lodkit inspect: the header and chunk table of a .lks stream, every chunk
 * checked. */
#include <cjson/cJSON.h>
#include <stdio.h>
#include <stdlib.h>
#include <stdbool.h>
#include <string.h>

#include "cli.h"

const cli_help inspect_help = {
    "IN.lks",
    "Print a progressive stream's header and chunk table, checking every chunk.\n",
    NULL,
};

int cmd_inspect(int argc, char **argv)
{
    cli_parser parser;
    cli_parse_begin(&parser, CMD_INSPECT, argc, argv);
    for (int id; (id = cli_next(&parser)) != CLI_DONE;) return cli_unhandled(&parser, id);
    int json = parser.json;
    if (argc - optind != 1) return usage_error("inspect", "%s", "expected IN.lks");
    const char *in = argv[optind];
    unsigned char *data = NULL;
    size_t size = 0;
    lk_error error = {0};
    lk_status status = read_input_file(in, &data, &size, &error);
    if (status != LK_OK) {
        print_error_for(in, NULL, &error);
        return EXIT_BAD_INPUT;
    }
    lk_stream_info info;
    lk_stream_chunk_info *chunks = NULL;
    memset(&info, 0, sizeof info);
    status = lk_stream_inspect(data, size, &info, &chunks, &error);
    /* version 2, whole: where the bits go (one decode) */
    lk_stream_bits bits;
    lk_error bits_error = {0};
    bool have_bits =
        status == LK_OK && info.version == 2 && lk_stream_bits_by_part(data, size, &bits, &bits_error) == LK_OK;
    lk_free(data);
    if (status != LK_OK && status != LK_ERR_TRUNCATED) {
        print_error_for(in, NULL, &error);
        lk_free(chunks);
        return EXIT_BAD_INPUT;
    }
    size_t present = 0;
    for (size_t i = 0; chunks && i < info.chunk_count; i++)
        if (chunks[i].offset + chunks[i].size <= size) present++;
    if (json) {
        cJSON *root = cJSON_CreateObject();
        cJSON_AddStringToObject(root, "input", in);
        cJSON_AddNumberToObject(root, "version", info.version);
        cJSON_AddNumberToObject(root, "bytes", (double)size);
        cJSON_AddNumberToObject(root, "vertices", (double)info.vertex_count);
        cJSON_AddNumberToObject(root, "triangles", (double)info.triangle_count);
        cJSON_AddNumberToObject(root, "base_vertices", (double)info.base_vertex_count);
        cJSON_AddNumberToObject(root, "base_triangles", (double)info.base_triangle_count);
        cJSON_AddNumberToObject(root, "splits", (double)info.split_count);
        cJSON_AddNumberToObject(root, "strip_length", (double)info.strip_length);
        cJSON_AddNumberToObject(root, "position_bits", info.position_bits);
        cJSON_AddNumberToObject(root, "quantisation_error", info.quantisation_error);
        cJSON_AddNumberToObject(root, "diagonal", info.diagonal);
        cJSON_AddNumberToObject(root, "bits_per_vertex",
                                info.vertex_count ? 8.0 * (double)info.total_size / (double)info.vertex_count : 0);
        cJSON_AddNumberToObject(root, "header_bytes", (double)info.header_size);
        if (have_bits) {
            cJSON *parts = cJSON_AddObjectToObject(root, "bits_per_vertex_by_part");
            cJSON_AddNumberToObject(parts, "base", bits.base);
            cJSON_AddNumberToObject(parts, "split_vertices", bits.split_vertices);
            cJSON_AddNumberToObject(parts, "moves", bits.moves);
            cJSON_AddNumberToObject(parts, "restored", bits.restored);
            cJSON_AddNumberToObject(parts, "positions", bits.positions);
            cJSON_AddNumberToObject(parts, "normals", bits.normals);
            cJSON_AddNumberToObject(parts, "texcoords", bits.texcoords);
            cJSON_AddNumberToObject(parts, "colors", bits.colors);
            cJSON_AddNumberToObject(parts, "framing", bits.framing);
        }
        cJSON *list = cJSON_AddArrayToObject(root, "chunks");
        for (size_t i = 0; i < present; i++) {
            cJSON *chunk = cJSON_CreateObject();
            cJSON_AddNumberToObject(chunk, "offset", (double)chunks[i].offset);
            cJSON_AddNumberToObject(chunk, "bytes", chunks[i].size);
            cJSON_AddNumberToObject(chunk, "raw_bytes", chunks[i].raw_size);
            cJSON_AddNumberToObject(chunk, "first_split", chunks[i].first_split);
            cJSON_AddNumberToObject(chunk, "splits", chunks[i].split_count);
            cJSON_AddNumberToObject(chunk, "triangles", chunks[i].triangle_count);
            cJSON_AddBoolToObject(chunk, "compressed", chunks[i].compressed);
            cJSON_AddItemToArray(list, chunk);
        }
        cJSON_AddBoolToObject(root, "complete", status == LK_OK);
        if (status != LK_OK) cJSON_AddStringToObject(root, "stopped", error.message);
        print_json(root);
    } else {
        printf("%s: lodkit progressive stream, version %u, %s bytes\n", in, info.version, thousands(size));
        printf("  full mesh   %s, %s, %.2f bits/vertex\n", n_vertices(info.vertex_count),
               n_triangles(info.triangle_count),
               info.vertex_count ? 8.0 * (double)info.total_size / (double)info.vertex_count : 0);
        if (info.version == 1)
            printf("  base mesh   %s, %s; %s; strip of %s\n", n_vertices(info.base_vertex_count),
                   n_triangles(info.base_triangle_count), count_noun(info.split_count, "vertex split", "vertex splits"),
                   count_noun(info.strip_length, "index", "indices"));
        else
            printf("  base mesh   %s, %s; %s in range-coded batches\n", n_vertices(info.base_vertex_count),
                   n_triangles(info.base_triangle_count),
                   count_noun(info.split_count, "vertex split", "vertex splits"));
        if (have_bits) {
            /* connectivity first, then geometry, then what the splits' attributes cost */
            printf("  bits/vertex split vertices %.2f, moves %.2f, restored %.2f, positions %.2f", bits.split_vertices,
                   bits.moves, bits.restored, bits.positions);
            if (bits.normals > 0) printf(", normals %.2f", bits.normals);
            if (bits.texcoords > 0) printf(", texcoords %.2f", bits.texcoords);
            if (bits.colors > 0) printf(", colours %.2f", bits.colors);
            printf(", base %.2f, framing %.2f\n", bits.base, bits.framing);
        } else if (info.version == 2 && status == LK_OK) {
            printf("  bits/vertex not measured: %s\n", bits_error.message);
        }
        printf("  positions   %u bits per coordinate, error <= %.3g (%.4f%% of the diagonal %.4g)\n",
               info.position_bits, info.quantisation_error,
               info.diagonal > 0 ? 100 * info.quantisation_error / info.diagonal : 0, info.diagonal);
        printf("  header      %s bytes (header and chunk table)\n", thousands(info.header_size));
        printf("  %5s %10s %9s %9s %5s %13s %11s %8s\n", "chunk", "offset", "bytes", "raw", "zip", "splits",
               "triangles", "bits/vx");
        for (size_t i = 0; i < present; i++) {
            size_t new_vertices = chunks[i].is_base ? info.base_vertex_count : chunks[i].split_count;
            printf("  %5zu %10llu %9s %9s %5s %6s..%-6s %11s %8.1f\n", i, (unsigned long long)chunks[i].offset,
                   thousands(chunks[i].size), thousands(chunks[i].raw_size), chunks[i].compressed ? "yes" : "no",
                   thousands(chunks[i].first_split), thousands(chunks[i].first_split + chunks[i].split_count),
                   thousands(chunks[i].triangle_count),
                   new_vertices ? 8.0 * chunks[i].size / (double)new_vertices : 0.0);
        }
        if (status == LK_OK && info.chunk_count == 1)
            printf("  the one chunk present, its CRC matches\n");
        else if (status == LK_OK)
            printf("  all %zu chunks present, CRCs match\n", info.chunk_count);
        else
            printf("  %s\n", error.message);
    }
    lk_free(chunks);
    return status == LK_OK ? EXIT_OK : EXIT_BAD_INPUT;
}
