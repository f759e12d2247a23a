/* SPDX-License-Identifier: MIT */
/* Helpers for lodkit's cmocka unit tests. Include after cmocka's headers. */
#ifndef LODKIT_TESTUTIL_H
#define LODKIT_TESTUTIL_H

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "lodkit.h"

/* Absolute path of a sample model (data/samples/NAME) or a test file
 * (tests/data/NAME). Returned pointer is to a static buffer per call slot;
 * copy it if you need more than four at once. */
const char *lk_test_sample(const char *name);
const char *lk_test_data(const char *name);
/* A fresh temporary directory for this test process (created once). */
const char *lk_test_tmpdir(void);
/* tmpdir + "/" + name in a static buffer slot. */
const char *lk_test_tmpfile(const char *name);
/* directory + "/" + name in a static buffer slot (the same four slots as
 * the functions above: use the result before the fifth call). */
const char *lk_test_path(const char *directory, const char *name);

/* The whole file in a malloc'ed buffer (one spare byte); fails the test
 * when it cannot be read. */
unsigned char *lk_test_read_file(const char *path, size_t *size);
/* Standard base64 (with '=' padding) of size bytes into out, which holds at
 * least 4 * ceil(size / 3) + 1 characters (test-built data: URIs). */
void lk_test_base64(const unsigned char *bytes, size_t size, char *out);

/* Writes size bytes to path; fails the test when it cannot. */
void lk_test_write_file(const char *path, const void *bytes, size_t size);

/* Monotonic clock in seconds, and a sleep in milliseconds. */
double lk_test_now(void);
void lk_test_sleep_ms(long milliseconds);

/* An lk_server_log_fn that appends each line to one process-wide buffer
 * (64 KiB, thread-safe; user is ignored), and how many times needle occurs
 * in what was logged so far. */
void lk_test_log_line(void *user, const char *line);
size_t lk_test_log_count(const char *needle);

/* A TCP connection to 127.0.0.1:port, optionally from the local address
 * source (NULL = any; -2 when it cannot be bound) with a receive buffer of
 * receive_buffer bytes (0 = default) and a receive timeout in seconds
 * (0 = none); sends time out after 10 s. -1 when the connection fails. */
int lk_test_connect(unsigned port, const char *source, int receive_buffer, int receive_timeout_seconds);
/* Sends all bytes (retrying on EINTR); false when the peer stopped taking
 * them (a server that closes early makes the rest unsendable). */
_Bool lk_test_send_all(int fd, const void *bytes, size_t length);

/* The value of header `name` (case-insensitive) in an HTTP response head
 * of `length` bytes (status line first, NUL-terminated after it), in a
 * buffer of the calling thread, valid until its next call; NULL when absent. */
const char *lk_test_http_header(const char *head, size_t length, const char *name);

/* A minimal glTF at path: one triangle whose three float positions (36
 * bytes) are buffers[0], the external file `uri` (not escaped). */
void lk_test_write_gltf_triangle(const char *path, const char *uri);
/* 36 bytes (nine floats) that appear nowhere else: the content of a file
 * a test must never see served or read. */
const unsigned char *lk_test_secret_floats(void);
/* Creates a Unix-domain socket file at path (bound, then closed: the file
 * stays); fails the test when it cannot. */
void lk_test_make_socket(const char *path);

/* Loads a mesh and fails the test with the library's message on error. */
void lk_test_load(const char *path, lk_mesh *mesh);
/* Reads from memory with format; returns status, fills error. */
lk_status lk_test_read_string(const char *text, const char *name, lk_format format, lk_mesh *mesh, lk_error *error);

/* Small shapes with known answers (the test fails on allocation failure).
 * lk_test_make_mesh copies the arrays; the cube is the closed unit cube
 * [0,1]^3 (8 v, 12 t, outward); the torus an n x m wrapped grid (genus 1);
 * the grid an open (n+1)^2-vertex grid on [0,n]^2 at z = 0. */
void lk_test_make_mesh(lk_mesh *mesh, const float *positions, size_t vertex_count, const uint32_t *indices,
                       size_t triangle_count);
void lk_test_make_cube(lk_mesh *mesh);
void lk_test_make_torus(lk_mesh *mesh, uint32_t n, uint32_t m);
void lk_test_make_grid(lk_mesh *mesh, uint32_t n);

/* Fails unless the error message contains `needle`. */
#define lk_assert_message_contains(error, needle)                                                                      \
    do {                                                                                                               \
        if (!strstr((error).message, (needle)))                                                                        \
            fail_msg("error message \"%s\" lacks \"%s\"", (error).message, (needle));                                  \
    } while (0)

/* Oriented triangles, each rotated to start at its smallest vertex (which
 * keeps its orientation), optionally mapped through `map`, sorted: equal
 * meshes give equal arrays. Caller frees. */
uint32_t *lk_test_canonical_triangles(const uint32_t *indices, size_t triangle_count, const uint32_t *map);
/* A stream decoder stopping at max_level (fails the test on error). */
lk_stream_decoder *lk_test_stream_decoder(size_t max_level);
/* The decoder's current mesh (fails the test on error). */
void lk_test_stream_mesh(const lk_stream_decoder *decoder, lk_mesh *mesh);

#endif
