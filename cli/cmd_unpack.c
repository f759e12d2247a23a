/* SPDX-License-Identifier: MIT */
/* lodkit unpack: a .lks stream decoded up to a level into a mesh. */
#include <cjson/cJSON.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

const cli_help unpack_help = {
    "IN.lks OUT",
    "Decode a progressive stream up to a level and write that mesh\n"
    "({triangle-write}; vertices in progressive order).\n",
    "A stream that is cut short or has a corrupt chunk still gives the last level\n"
    "decoded before the damage: it is written and the exit status is 1.\n",
};

int cmd_unpack(int argc, char **argv)
{
    size_t level = SIZE_MAX, byte_limit = SIZE_MAX;
    double ratio = -1;
    cli_parser parser;
    cli_parse_begin(&parser, CMD_UNPACK, argc, argv);
    for (int id; (id = cli_next(&parser)) != CLI_DONE;) {
        const char *arg = parser.value;
        switch (id) {
        case OPT_LEVEL:
            if (!parse_size_option(arg, &level)) return usage_error("unpack", "--level: '%s' is not a count", arg);
            break;
        case OPT_RATIO:
            if (!parse_double_option(arg, &ratio) || ratio < 0 || ratio > 1)
                return usage_error("unpack", "--ratio: '%s' is not a number in [0, 1]", arg);
            break;
        case OPT_BYTES:
            if (!parse_size_option(arg, &byte_limit))
                return usage_error("unpack", "--bytes: '%s' is not a byte count", arg);
            break;
        default: return cli_unhandled(&parser, id);
        }
    }
    int json = parser.json, quiet = parser.quiet;
    if (argc - optind != 2) return usage_error("unpack", "%s", "expected IN.lks and OUT");
    if (level != SIZE_MAX && ratio >= 0) return usage_error("unpack", "%s", "give --level or --ratio, not both");
    const char *in = argv[optind], *out = argv[optind + 1];
    lk_format out_format = output_mesh_format("unpack", out, 0);
    if (out_format == LK_FORMAT_UNKNOWN) return EXIT_USAGE;

    unsigned char *data = NULL;
    size_t size = 0;
    lk_error error = {0}, stream_error = {0};
    lk_stream_decoder *decoder = NULL;
    lk_mesh mesh;
    lk_mesh_init(&mesh);
    int exit_code = EXIT_OK;
    lk_status status = read_input_file(in, &data, &size, &error);
    if (status != LK_OK) {
        print_error_for(in, out, &error);
        return EXIT_BAD_INPUT;
    }
    size_t available = size < byte_limit ? size : byte_limit;
    /* The level is known only once the header has arrived, so --ratio
     * decodes the header first (a decoder with no limit) to learn the counts. */
    if (ratio >= 0) {
        lk_stream_info info;
        lk_stream_chunk_info *chunks = NULL;
        status = lk_stream_inspect(data, available, &info, &chunks, &error);
        lk_free(chunks);
        if (status == LK_OK || status == LK_ERR_TRUNCATED) {
            double wanted = ratio * (double)info.vertex_count - (double)info.base_vertex_count;
            level = wanted <= 0 ? 0 : (size_t)(wanted + 0.5);
            status = LK_OK;
        } else {
            print_error_for(in, out, &error);
            lk_free(data);
            return EXIT_BAD_INPUT;
        }
    }
    /* A level past the last one would be clamped by the decoder: refuse it
     * and say which levels the stream has. */
    if (level != SIZE_MAX && ratio < 0) {
        lk_stream_info info;
        lk_stream_chunk_info *chunks = NULL;
        lk_error header_error = {0};
        lk_status header = lk_stream_inspect(data, available, &info, &chunks, &header_error);
        lk_free(chunks);
        if ((header == LK_OK || header == LK_ERR_TRUNCATED) && level > info.split_count) {
            char message[600];
            snprintf(message, sizeof message, "--level %s: %s has %s, levels 0 to %s", thousands(level), in,
                     count_noun(info.split_count, "vertex split", "vertex splits"), thousands(info.split_count));
            lk_free(data);
            return usage_error("unpack", "%s", message);
        }
    }
    status = lk_stream_decoder_create(level, &decoder, &error);
    /* The file's bytes are held while it is decoded: the decoder gets what
     * the budget has left (read_input_file made sure the file fits). */
    size_t decoder_budget = cli_max_memory > size ? cli_max_memory - size : 1;
    if (status == LK_OK) status = lk_stream_decoder_set_max_bytes(decoder, decoder_budget, &error);
    /* feed in network-sized pieces, as a client would */
    lk_status stream_status = LK_OK;
    for (size_t offset = 0; status == LK_OK && stream_status == LK_OK && offset < available; offset += 65536) {
        size_t piece = available - offset < 65536 ? available - offset : 65536;
        stream_status = lk_stream_decoder_feed(decoder, data + offset, piece, &stream_error);
    }
    if (status == LK_OK && stream_status == LK_OK) stream_status = lk_stream_decoder_finish(decoder, &stream_error);
    if (stream_status == LK_ERR_LIMIT && size > 0) {
        size_t length = strlen(stream_error.message);
        snprintf(stream_error.message + length, sizeof stream_error.message - length,
                 ": what --max-memory leaves beside the file's %zu bytes", size);
    }
    /* A cut or damaged stream still yields the levels before the damage. */
    lk_status mesh_status = status == LK_OK ? lk_stream_decoder_mesh(decoder, &mesh, &error) : status;
    status = mesh_status;
    if (status == LK_OK) status = lk_mesh_write(out, out_format, &mesh, NULL, &error);
    if (status != LK_OK) {
        if (stream_status != LK_OK) print_error_for(in, out, &stream_error);
        /* "no mesh yet" only repeats the stream's error */
        if (stream_status == LK_OK || mesh_status == LK_OK) print_error_for(in, out, &error);
        exit_code = EXIT_BAD_INPUT;
        goto done;
    }
    const lk_stream_info *info = lk_stream_decoder_info(decoder);
    int expected_cut = stream_status == LK_ERR_TRUNCATED && byte_limit < size;
    if (stream_status != LK_OK && !expected_cut) {
        print_error_for(in, out, &stream_error);
        fprintf(stderr, "%s: %s: wrote the level decoded before that: %zu of %s, %s\n", program, out,
                lk_stream_decoder_level(decoder), count_noun(info ? info->split_count : 0, "split", "splits"),
                n_triangles(mesh.triangle_count));
        exit_code = EXIT_BAD_INPUT;
    }
    if (json) {
        cJSON *root = cJSON_CreateObject();
        cJSON_AddStringToObject(root, "input", in);
        cJSON_AddStringToObject(root, "output", out);
        cJSON_AddNumberToObject(root, "level", (double)lk_stream_decoder_level(decoder));
        cJSON_AddNumberToObject(root, "splits", info ? (double)info->split_count : 0);
        cJSON_AddNumberToObject(root, "vertices", (double)mesh.vertex_count);
        cJSON_AddNumberToObject(root, "triangles", (double)mesh.triangle_count);
        cJSON_AddNumberToObject(root, "bytes_read", (double)available);
        cJSON_AddNumberToObject(root, "bytes_decoded", (double)lk_stream_decoder_bytes(decoder));
        cJSON_AddNumberToObject(root, "chunks_decoded", (double)lk_stream_decoder_chunks(decoder));
        cJSON_AddBoolToObject(root, "complete", stream_status == LK_OK);
        if (stream_status != LK_OK) cJSON_AddStringToObject(root, "stopped", stream_error.message);
        print_json(root);
    } else if (!quiet) {
        printf("%s: level %s of %s (%s, %s) from %s of %s bytes, %s -> %s\n", in,
               thousands(lk_stream_decoder_level(decoder)), thousands(info ? info->split_count : 0),
               n_vertices(mesh.vertex_count), n_triangles(mesh.triangle_count),
               thousands(lk_stream_decoder_bytes(decoder)), thousands(size),
               count_noun(lk_stream_decoder_chunks(decoder), "chunk", "chunks"), out);
        if (expected_cut) printf("note: %s\n", stream_error.message);
    }
done:
    lk_stream_decoder_free(decoder);
    lk_mesh_free(&mesh);
    lk_free(data);
    return exit_code;
}
