/* SPDX-License-Identifier: MIT */
/* Internal hooks of the HTTP server (src/serve/server.c) for the HTTP fuzz target
 * (fuzz/fuzz_http.c) and the server tests: a server without a listening
 * socket or threads, driven one raw request at a time through
 * libmicrohttpd's real parser and lodkit's real request handler. Not part
 * of the public API. */
#ifndef LODKIT_SERVE_INTERNAL_H
#define LODKIT_SERVE_INTERNAL_H

#include "lodkit.h"

#include <stddef.h>

/* Like lk_server_start, but nothing listens and no thread runs: requests
 * only arrive through lk__server_exchange, on the caller's thread.
 * options->host and options->port are ignored. Stop with lk_server_stop. */
lk_status lk__server_start_detached(const char *directory, const lk_server_options *options, lk_server **out,
                                    lk_error *error);

/* Sends the `size` bytes of request_bytes as one client connection (then
 * half-closes it, as a client that has nothing more to say), runs the
 * server until it closes the connection, and returns everything it
 * answered (every response of pipelined requests, status lines and
 * headers included) in *response (malloc'ed, NUL-terminated; NULL to
 * discard; at most 64 MiB are kept). Fails with LK_ERR_LIMIT when the
 * server neither answers nor closes within a bounded number of rounds (a
 * hang), LK_ERR_IO on socket errors, LK_ERR_INVALID for a server not
 * started detached. */
lk_status lk__server_exchange(lk_server *server, const void *request_bytes, size_t size, unsigned char **response,
                              size_t *response_size, lk_error *error);

#endif
