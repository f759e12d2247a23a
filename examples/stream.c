/* SPDX-License-Identifier: MIT */
/* Build a progressive stream (.lks) from a mesh, cut it as a slow network
 * would, and decode what arrived: every prefix of a stream is drawable.
 *
 *   stream IN [PERCENT]     e.g. stream bunny.ply 25
 *
 * Prints the stream's size, then the triangles decoded from the first
 * PERCENT % of its bytes (default 25) and from the whole stream. */
#include <lodkit.h>

#include <stdio.h>
#include <stdlib.h>

/* Feeds the first `size` bytes of the stream to a new decoder and prints
 * the mesh they give. */
static int decode_prefix(const unsigned char *bytes, size_t size, size_t total)
{
    lk_error error = {0};
    lk_stream_decoder *decoder = NULL;
    if (lk_stream_decoder_create(SIZE_MAX, &decoder, &error) != LK_OK) {
        fprintf(stderr, "%s\n", error.message);
        return 1;
    }
    int status = 1;
    if (lk_stream_decoder_feed(decoder, bytes, size, &error) == LK_OK) {
        /* A cut stream ends with LK_ERR_TRUNCATED; the levels so far stay usable. */
        lk_status finished = lk_stream_decoder_finish(decoder, &error);
        lk_mesh mesh;
        if ((finished == LK_OK || finished == LK_ERR_TRUNCATED) &&
            lk_stream_decoder_mesh(decoder, &mesh, &error) == LK_OK) {
            printf("%zu of %zu bytes: %zu vertices, %zu triangles (%s)\n", size, total, mesh.vertex_count,
                   mesh.triangle_count, finished == LK_OK ? "complete" : "cut");
            lk_mesh_free(&mesh);
            status = 0;
        }
    }
    if (status != 0) fprintf(stderr, "%s\n", error.message);
    lk_stream_decoder_free(decoder);
    return status;
}

int main(int argc, char **argv)
{
    if (argc < 2 || argc > 3) {
        fprintf(stderr, "usage: %s IN [PERCENT]\n", argv[0]);
        return 2;
    }
    double percent = argc == 3 ? atof(argv[2]) : 25.0;
    lk_error error = {0};
    lk_mesh mesh;
    if (lk_mesh_read(argv[1], LK_FORMAT_AUTO, NULL, &mesh, &error) != LK_OK) {
        fprintf(stderr, "%s\n", error.message);
        return 1;
    }
    /* The progressive mesh (QEM collapses down to a 5% base), its
     * progressive strips, then the stream. */
    lk_progressive_options options;
    lk_progressive_options_default(&options);
    lk_progressive_mesh pm;
    lk_progressive_strips strips;
    unsigned char *bytes = NULL;
    size_t size = 0;
    int status = 1;
    if (lk_progressive_mesh_build(&mesh, &options, &pm, NULL, NULL, &error) == LK_OK) {
        if (lk_progressive_strips_build(&pm, LK_STRIPIFY_BEST, &strips, &error) == LK_OK) {
            if (lk_stream_encode(&pm, &strips, NULL, &bytes, &size, &error) == LK_OK) status = 0;
            lk_progressive_strips_free(&strips);
        }
        lk_progressive_mesh_free(&pm);
    }
    lk_mesh_free(&mesh);
    if (status != 0) {
        fprintf(stderr, "%s\n", error.message);
        return 1;
    }
    printf("stream: %zu bytes\n", size);
    size_t cut = (size_t)((double)size * percent / 100.0);
    status = decode_prefix(bytes, cut, size) || decode_prefix(bytes, size, size);
    lk_free(bytes);
    return status;
}
