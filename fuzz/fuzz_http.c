/* SPDX-License-Identifier: MIT */
/* libFuzzer target for HTTP request handling (src/serve/): the input is
 * the raw bytes a client sends on one connection (one request, several
 * pipelined ones, or junk). They go through libmicrohttpd's real parser
 * and lodkit's real handler (URL decoding, path checks and resolution,
 * Range / If-None-Match / If-Range / Accept-Encoding, the /api/ queries,
 * simplify-on-demand) in-process: the server is started without a
 * listening socket (lk__server_start_detached) and each input is handed
 * to it over a socketpair (lk__server_exchange), on this thread.
 *
 * The served directory, made once in a temporary directory: a small OBJ
 * mesh (whose stream is built on demand), a progressive stream (.lks), a
 * 5x5 PGM heightmap, an XYZ point set, text files, a subdirectory, a hidden
 * file, and two symlinks that lead out of the directory (to a file and to
 * a directory) where a secret file waits.
 *
 * Any input must be answered or the connection closed in a bounded number
 * of rounds (never a hang), with well-formed responses (status line,
 * headers, exactly Content-Length body bytes, then the next response),
 * never expose the secret (the marker never appears raw in what the
 * server sends), never leak a descriptor, never crash. */
#define _GNU_SOURCE /* nftw, memmem */
#include <ftw.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

#include "lodkit.h"
#include "serve/serve_internal.h"

/* The secret's bytes. Error messages echo parts of the request, but as
 * JSON, where control characters are escaped: raw control bytes around the
 * marker can only come from the file itself. */
#define SECRET_MARKER "\001\002LKFUZZSECRET\003"

static lk_server *server;
static char base_dir[64];
static int descriptor_baseline;

static void put_file(const char *path, const void *bytes, size_t size)
{
    FILE *file = fopen(path, "wb");
    if (!file || fwrite(bytes, 1, size, file) != size || fclose(file) != 0) {
        fprintf(stderr, "fuzz_http: cannot write %s\n", path);
        abort();
    }
}

static void put_text(const char *path, const char *text) { put_file(path, text, strlen(text)); }

static const char *in_base(const char *name)
{
    static char slots[4][256];
    static int next;
    char *out = slots[next];
    next = (next + 1) % 4;
    snprintf(out, sizeof slots[0], "%s/%s", base_dir, name);
    return out;
}

static int remove_entry(const char *path, const struct stat *st, int type, struct FTW *ftw)
{
    (void)st;
    (void)type;
    (void)ftw;
    remove(path);
    return 0;
}

static void cleanup(void)
{
    lk_server_stop(server);
    server = NULL;
    if (base_dir[0]) nftw(base_dir, remove_entry, 16, FTW_DEPTH | FTW_PHYS);
}

/* An octahedron (6 vertices, 8 triangles) as OBJ text. */
static const char octahedron_obj[] = "v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n"
                                     "f 1 3 5\nf 3 2 5\nf 2 4 5\nf 4 1 5\nf 3 1 6\nf 2 3 6\nf 4 2 6\nf 1 4 6\n";

static void make_content(void)
{
    snprintf(base_dir, sizeof base_dir, "/tmp/lkh-XXXXXX");
    if (!mkdtemp(base_dir)) abort();
    atexit(cleanup);
    if (mkdir(in_base("r"), 0755) != 0 || mkdir(in_base("r/sub"), 0755) != 0 || mkdir(in_base("out"), 0755) != 0)
        abort();
    put_text(in_base("out/secret.txt"), SECRET_MARKER " outside the root\n");
    put_text(in_base("out/secret.obj"), "# " SECRET_MARKER "\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    put_text(in_base("r/.hidden"), SECRET_MARKER " hidden\n");
    if (symlink(in_base("out/secret.txt"), in_base("r/leak.txt")) != 0) abort();
    if (symlink(in_base("out"), in_base("r/outdir")) != 0) abort();
    if (symlink("notes.txt", in_base("r/inside.txt")) != 0) abort();
    put_text(in_base("r/notes.txt"), "notes: plain text, long enough to be worth compressing, "
                                     "long enough to be worth compressing, long enough.\n");
    put_text(in_base("r/sub/page.txt"), "inside a subdirectory\n");
    put_text(in_base("r/points.xyz"), "0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 1 0\n1 0 1\n0 1 1\n1 1 1\n");
    put_text(in_base("r/oct.obj"), octahedron_obj); /* no oct.lks: /m/oct.lks is built on demand */
    put_text(in_base("r/broken.obj"), "v 1 2\nf 1 2 3\n");
    /* a 5x5 PGM heightmap (P2): small, so that a terrain request costs
     * about as much as the others */
    char pgm[1024];
    size_t length = (size_t)snprintf(pgm, sizeof pgm, "P2\n5 5\n255\n");
    for (int y = 0; y < 5; y++)
        for (int x = 0; x < 5; x++)
            length += (size_t)snprintf(pgm + length, sizeof pgm - length, "%d ", (x * 29 + y * 13) % 256);
    put_file(in_base("r/hill.pgm"), pgm, length);
    /* a progressive stream of the octahedron */
    lk_mesh mesh;
    lk_error error = {0};
    lk_progressive_options pm_options;
    lk_progressive_options_default(&pm_options);
    lk_progressive_mesh pm;
    lk_progressive_strips strips;
    lk_stream_options stream_options;
    lk_stream_options_default(&stream_options);
    unsigned char *stream = NULL;
    size_t stream_size = 0;
    if (lk_mesh_read_memory(octahedron_obj, sizeof octahedron_obj - 1, "oct.obj", LK_FORMAT_AUTO, NULL, &mesh,
                            &error) != LK_OK ||
        lk_progressive_mesh_build(&mesh, &pm_options, &pm, NULL, NULL, &error) != LK_OK ||
        lk_progressive_strips_build(&pm, LK_STRIPIFY_BEST, &strips, &error) != LK_OK ||
        lk_stream_encode(&pm, &strips, &stream_options, &stream, &stream_size, &error) != LK_OK) {
        fprintf(stderr, "fuzz_http: %s\n", error.message);
        abort();
    }
    put_file(in_base("r/shape.lks"), stream, stream_size);
    lk_free(stream);
    lk_progressive_strips_free(&strips);
    lk_progressive_mesh_free(&pm);
    lk_mesh_free(&mesh);

    lk_server_options options;
    lk_server_options_default(&options);
    options.simplify_on_demand = 1;
    options.cache_dir = in_base("cache");
    /* 16 KiB per connection instead of 64: libmicrohttpd then mallocs the
     * connection's memory pool instead of mapping and zeroing fresh pages
     * for every input (a third of the time per execution), and inputs
     * reach the header limits (414, 431) sooner. */
    options.connection_memory = 16 * 1024;
    if (lk__server_start_detached(in_base("r"), &options, &server, &error) != LK_OK) {
        fprintf(stderr, "fuzz_http: %s\n", error.message);
        abort();
    }
}

/* The checks below use libc's memmem and memchr, not loops of our own:
 * this file is compiled with coverage instrumentation, and byte loops over
 * every response cost more than the server's own work. */
static bool contains(const unsigned char *bytes, size_t size, const char *needle)
{
    return bytes && memmem(bytes, size, needle, strlen(needle)) != NULL;
}

static bool starts_with(const unsigned char *bytes, size_t size, const char *prefix)
{
    size_t length = strlen(prefix);
    return size >= length && memcmp(bytes, prefix, length) == 0;
}

/* Walks the responses: each is a status line and headers, then as many
 * body bytes as Content-Length says (none for 1xx, 204, 304 and, when the
 * request had a HEAD in it, for answers to HEAD), then the next response
 * or the end. Returns false on anything else (a truncated header block, a
 * body of the wrong length, a header block sent twice...). */
static bool well_formed(const unsigned char *bytes, size_t size, bool head_requested)
{
    size_t position = 0;
    while (position < size) {
        const unsigned char *p = bytes + position;
        size_t left = size - position;
        if (!starts_with(p, left, "HTTP/1.") || left < 12) return false;
        const unsigned char *end = memmem(p, left, "\r\n\r\n", 4);
        if (!end) return false;
        end += 4;
        int status = atoi((const char *)p + 9);
        size_t header_end = position + (size_t)(end - p);
        /* libmicrohttpd 0.9.75 sends the status line and headers of the
         * error answers it makes itself while parsing headers (an invalid
         * Content-Length, ...) twice, then the body, then closes. An
         * upstream bug, harmless (its own constant text, a closed
         * connection): the first copy is skipped. */
        size_t block = header_end - position;
        if (status >= 400 && header_end + block <= size && memcmp(bytes + header_end, p, block) == 0 &&
            memmem(p, block, "Connection: close", 17)) {
            position = header_end;
            continue;
        }
        /* Content-Length, if any (header names are case-insensitive) */
        long long length = -1;
        for (const unsigned char *line = p; (line = memchr(line, '\n', (size_t)(end - line))); line++)
            if ((size_t)(end - line) > 16 && strncasecmp((const char *)line + 1, "Content-Length:", 15) == 0)
                length = strtoll((const char *)line + 16, NULL, 10);
        bool no_body = (status >= 100 && status < 200) || status == 204 || status == 304;
        if (no_body || length < 0) {
            position = no_body ? header_end : size;
            continue;
        }
        size_t with_body = header_end + (size_t)length;
        if (with_body == size || (with_body < size && starts_with(bytes + with_body, size - with_body, "HTTP/1.")))
            position = with_body;
        else if (head_requested &&
                 (header_end == size || starts_with(bytes + header_end, size - header_end, "HTTP/1.")))
            position = header_end; /* an answer to HEAD */
        else
            return false;
    }
    return true;
}

/* The lowest free descriptor: grows when descriptors leak. */
static int lowest_free_descriptor(void)
{
    int fd = dup(0);
    if (fd >= 0) close(fd);
    return fd;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (!server) {
        make_content();
        descriptor_baseline = lowest_free_descriptor();
    }
    unsigned char *response = NULL;
    size_t response_size = 0;
    lk_error error = {0};
    if (lk__server_exchange(server, data, size, &response, &response_size, &error) != LK_OK) {
        fprintf(stderr, "fuzz_http: %s\n", error.message);
        abort();
    }
    if (contains(response, response_size, SECRET_MARKER)) {
        fprintf(stderr, "fuzz_http: the response exposes a file outside the served directory:\n%.*s\n",
                (int)(response_size < 2000 ? response_size : 2000), (const char *)response);
        abort();
    }
    if (!well_formed(response, response_size, contains(data, size, "HEAD"))) {
        fprintf(stderr, "fuzz_http: malformed answer (%zu bytes):\n%.*s\n", response_size,
                (int)(response_size < 2000 ? response_size : 2000), (const char *)response);
        abort();
    }
    free(response);
    static unsigned executions;
    if (++executions % 64 == 0 && lowest_free_descriptor() > descriptor_baseline + 4) {
        fprintf(stderr, "fuzz_http: file descriptors leak\n");
        abort();
    }
    return 0;
}
