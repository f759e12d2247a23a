/* SPDX-License-Identifier: MIT */
/* HTTP server for a directory of content and the WebGL viewer
 * (libmicrohttpd). The protocol is described in docs/server.md; the files
 * of src/serve/ only wire the library's readers, progressive streams,
 * point sets and terrains to URLs (serve_shared.h says which file does
 * what). This one routes the requests, starts and stops the server.
 *
 * Design notes:
 *   - one thread per connection, bounded by max_connections: some requests
 *     (the first /api/terrain of a file, a simplify-on-demand build, normals
 *     of a large point set) take seconds, and in a small thread pool they
 *     would stall every connection sharing that thread;
 *   - files are opened with lk__open_input (the resolved path walked from
 *     the root without following links; only regular files: a FIFO never
 *     blocks a request), fstat'ed and sent from the descriptor, so a file
 *     swapped or truncated while it is sent never exposes another file,
 *     and a large file never sits in memory; what is parsed (meshes,
 *     grids, streams) is read from that descriptor too, and a glTF's
 *     buffers are opened below its own folder without following links;
 *   - messages sent to clients name files relative to the root
 *     (hide_directories): never where the root is on the machine;
 *   - the request path is decoded here from the raw URI (libmicrohttpd's
 *     own decoding turns %00 into a terminator that would hide the rest of
 *     the path), then checked component by component, then resolved with
 *     realpath and checked against the root, and the opened descriptor is
 *     checked once more through /proc/self/fd (no window between the check
 *     and the open);
 *   - file bodies are read with pread from that descriptor by our own
 *     reader, not libmicrohttpd's sendfile path: when a file shrinks under
 *     a transfer, sendfile returns 0 and libmicrohttpd 0.9.75 retries
 *     forever (a connection thread spinning at 100% CPU, a client that
 *     never sees the end); our reader ends the response with an error
 *     instead, so the client sees a cut connection;
 *   - slow clients: libmicrohttpd's timeout only measures inactivity, so a
 *     client sending one header byte every few hundred milliseconds would
 *     hold its connection forever (slowloris). A watchdog thread drops
 *     every connection whose request headers have not all arrived within
 *     timeout_seconds of the connection (or of its previous response);
 *   - lk_server_stop cancels simplify-on-demand builds (their progress
 *     callback reads the stopping flag), so stopping waits at most for one
 *     terrain or point-set computation, never for a whole stream build;
 *   - memory caches (gzip results, the index, point buffers) share one
 *     byte budget with least-recently-used eviction; cached bytes are
 *     reference counted so eviction never frees bytes a response is still
 *     sending. */
#define _XOPEN_SOURCE 700 /* realpath */
#include "serve_internal.h"
#include "serve_shared.h"

#include <errno.h>
#include <netdb.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/types.h>
#include <unistd.h>

#include <arpa/inet.h>
#include <netinet/in.h>

void lk_server_options_default(lk_server_options *options)
{
    if (!options) return;
    memset(options, 0, sizeof *options);
    options->host = "127.0.0.1";
    options->port = 8080;
    options->max_connections = 256;
    options->max_connections_per_ip = 128;
    options->timeout_seconds = 30;
    options->connection_memory = 64 * 1024;
    options->gzip_max_bytes = 8u << 20;
    options->cache_bytes = 128u << 20;
    options->terrain_bytes = 512u << 20;
    options->max_points = 1000000;
    options->max_file_bytes = (size_t)1 << 30;
    options->max_memory = (size_t)1 << 30;
}

/* ---- routing ------------------------------------------------------------------------------ */

static enum MHD_Result handle_request(void *user, struct MHD_Connection *connection, const char *url,
                                      const char *method, const char *version, const char *upload_data,
                                      size_t *upload_data_size, void **context)
{
    (void)url;
    (void)upload_data;
    lk_server *server = user;
    request *r = *context;
    if (!r) return MHD_NO;                /* out of memory in uri_logger */
    if (r->answered_early) return MHD_NO; /* libmicrohttpd had room after all: close */
    if (r->responded) {
        *upload_data_size = 0; /* a body nobody asked for */
        return MHD_YES;
    }
    /* The first call comes when the headers have arrived: answering then
     * is an "early" response after which libmicrohttpd closes the
     * connection, so GET and HEAD are answered on the second call (keep-alive). */
    bool get_or_head = strcmp(method, "GET") == 0 || strcmp(method, "HEAD") == 0;
    if (!r->headers_seen) {
        r->headers_seen = 1;
        lk__serve_connection_set_waiting(server, connection, false); /* the request deadline is met */
        /* A GET or HEAD with a body (an absurd Content-Length, a chunked
         * upload) is answered at once, before any body byte is read: the
         * connection is then closed instead of waiting for bytes nobody needs. */
        const char *length = MHD_lookup_connection_value(connection, MHD_HEADER_KIND, MHD_HTTP_HEADER_CONTENT_LENGTH);
        const char *transfer =
            MHD_lookup_connection_value(connection, MHD_HEADER_KIND, MHD_HTTP_HEADER_TRANSFER_ENCODING);
        bool has_body = transfer || (length && strspn(length, "0 \t") != strlen(length));
        /* RFC 9112 3.2: an HTTP/1.1 request without Host gets 400. (Not
         * libmicrohttpd's MHD_OPTION_STRICT_FOR_CLIENT: in 0.9.75 its 400
         * for this case sends the status line and headers twice.) */
        if (version && strcmp(version, MHD_HTTP_VERSION_1_1) == 0 &&
            !MHD_lookup_connection_value(connection, MHD_HEADER_KIND, MHD_HTTP_HEADER_HOST)) {
            snprintf(r->method, sizeof r->method, "%s", method);
            return lk__serve_respond_error(connection, r, 400, "an HTTP/1.1 request needs a Host header");
        }
        if (get_or_head && has_body) {
            snprintf(r->method, sizeof r->method, "%s", method);
            return lk__serve_respond_error(connection, r, 400, "a %s request has no body", method);
        }
        if (get_or_head) return MHD_YES;
    }
    snprintf(r->method, sizeof r->method, "%s", method);
    if (strcmp(method, "GET") != 0 && strcmp(method, "HEAD") != 0) {
        char *text = strdup("{\"error\":\"only GET and HEAD\"}");
        if (!text) return MHD_NO;
        size_t length = strlen(text);
        struct MHD_Response *response = MHD_create_response_from_buffer(length, text, MHD_RESPMEM_MUST_FREE);
        if (!response) {
            free(text);
            return MHD_NO;
        }
        MHD_add_response_header(response, MHD_HTTP_HEADER_ALLOW, "GET, HEAD");
        MHD_add_response_header(response, MHD_HTTP_HEADER_CONTENT_TYPE, SERVE_MIME_JSON);
        return lk__serve_queue(connection, r, 405, response, length);
    }
    if (!r->uri || r->uri[0] != '/') return lk__serve_respond_error(connection, r, 400, "bad request target");
    char *path = lk__serve_decode_path(r->uri);
    if (!path) return lk__serve_respond_error(connection, r, 400, "bad percent-encoding in the path");
    enum MHD_Result result;
    if (strcmp(path, "/") == 0 || strcmp(path, "/index.html") == 0)
        result = lk__serve_web(server, connection, r, "index.html");
    else if (strncmp(path, "/web/", 5) == 0)
        result = lk__serve_web(server, connection, r, path + 5);
    else if (strncmp(path, "/shaders/", 9) == 0)
        result = lk__serve_shader(server, connection, r, path + 9);
    else if (strncmp(path, "/m/", 3) == 0)
        result = lk__serve_content(server, connection, r, path + 3);
    else if (strcmp(path, "/api/index.json") == 0)
        result = lk__serve_index(server, connection, r);
    else if (strncmp(path, "/api/points/", 12) == 0)
        result = lk__serve_points(server, connection, r, path + 12);
    else if (strncmp(path, "/api/terrain/", 13) == 0)
        result = lk__serve_terrain(server, connection, r, path + 13);
    else if (strstr(path, "/../") || strstr(path, "/./") ||
             (strlen(path) >= 3 && strcmp(path + strlen(path) - 3, "/..") == 0))
        result = lk__serve_respond_error(connection, r, 403, "forbidden path");
    else
        result = lk__serve_respond_error(connection, r, 404, "no such URL");
    free(path);
    return result;
}

/* ---- start and stop ---------------------------------------------------------------------- */

static void server_free(lk_server *server)
{
    if (!server) return;
    lk__serve_cache_free(&server->cache);
    for (int i = 0; i < SERVE_TERRAIN_SLOTS; i++) lk__serve_terrain_slot_free(server->terrains[i]);
    lk__serve_records_free(server->records, server->record_count);
    if (server->index_json) lk__serve_blob_release(server->index_json);
    while (server->connections) { /* none after MHD_stop_daemon; kept for failed starts */
        connection_state *next = server->connections->next;
        free(server->connections);
        server->connections = next;
    }
    pthread_mutex_destroy(&server->build_lock);
    pthread_mutex_destroy(&server->terrain_lock);
    pthread_mutex_destroy(&server->index_lock);
    pthread_mutex_destroy(&server->connections_lock);
    pthread_cond_destroy(&server->watchdog_wake);
    free(server->host);
    free(server->web_dir);
    free(server->cache_dir);
    free(server->root);
    free(server->web_root);
    free(server);
}

/* Everything but the daemon: options, directories, locks. */
static lk_status server_create(const char *directory, const lk_server_options *options, lk_server **out,
                               lk_error *error)
{
    if (!out) return lk_error_set(error, LK_ERR_INVALID, "lk_server_start: out is NULL");
    *out = NULL;
    if (!directory) return lk_error_set(error, LK_ERR_INVALID, "lk_server_start: directory is NULL");
    lk_server_options defaults;
    lk_server_options_default(&defaults);
    if (!options) options = &defaults;
    if (options->port > 65535) return lk_error_set(error, LK_ERR_INVALID, "port %u is not in 0..65535", options->port);
    if (options->max_connections == 0 || options->timeout_seconds == 0)
        return lk_error_set(error, LK_ERR_INVALID, "max_connections and timeout_seconds must be positive");

    lk_server *server = calloc(1, sizeof *server);
    if (!server) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    server->options = *options;
    if (!server->options.host) server->options.host = defaults.host;
    if (!server->options.max_connections_per_ip) server->options.max_connections_per_ip = options->max_connections;
    if (!server->options.connection_memory) server->options.connection_memory = defaults.connection_memory;
    if (!server->options.cache_bytes) server->options.cache_bytes = defaults.cache_bytes;
    if (!server->options.terrain_bytes) server->options.terrain_bytes = defaults.terrain_bytes;
    if (!server->options.max_points) server->options.max_points = defaults.max_points;
    if (!server->options.max_file_bytes) server->options.max_file_bytes = defaults.max_file_bytes;
    if (!server->options.max_memory) server->options.max_memory = defaults.max_memory;
    atomic_init(&server->stopping, 0);
    pthread_mutex_init(&server->cache.lock, NULL);
    server->cache.budget = server->options.cache_bytes;
    pthread_mutex_init(&server->build_lock, NULL);
    pthread_mutex_init(&server->terrain_lock, NULL);
    pthread_mutex_init(&server->index_lock, NULL);
    pthread_mutex_init(&server->connections_lock, NULL);
    pthread_condattr_t condition_attributes;
    pthread_condattr_init(&condition_attributes);
    pthread_condattr_setclock(&condition_attributes, CLOCK_MONOTONIC); /* the watchdog's deadlines */
    pthread_cond_init(&server->watchdog_wake, &condition_attributes);
    pthread_condattr_destroy(&condition_attributes);

    lk_status status = LK_OK;
    struct stat st;
    errno = 0;
    server->root = realpath(directory, NULL);
    if (!server->root || stat(server->root, &st) != 0 || !S_ISDIR(st.st_mode)) {
        int saved = server->root ? ENOTDIR : errno;
        status = lk_error_set(error, LK_ERR_IO, "%s: not a directory%s%s", directory, saved ? ": " : "",
                              saved ? strerror(saved) : "");
        goto fail;
    }
    server->root_length = strlen(server->root);
    if (options->web_dir) {
        server->web_root = realpath(options->web_dir, NULL);
        if (!server->web_root || stat(server->web_root, &st) != 0 || !S_ISDIR(st.st_mode)) {
            status = lk_error_set(error, LK_ERR_IO, "%s: not a directory (--web)", options->web_dir);
            goto fail;
        }
        server->web_root_length = strlen(server->web_root);
    }
    if (options->cache_dir) {
        server->cache_dir = strdup(options->cache_dir);
        server->cache_trusted_length = strlen(options->cache_dir);
    } else {
        size_t length = server->root_length + 32;
        server->cache_dir = malloc(length);
        if (server->cache_dir) snprintf(server->cache_dir, length, "%s/.lodkit-cache", server->root);
        server->cache_trusted_length = server->root_length;
    }
    server->host = strdup(server->options.host);
    if (!server->cache_dir || !server->host) {
        status = lk_error_set(error, LK_ERR_NOMEM, "out of memory");
        goto fail;
    }
    server->options.host = server->host;
    server->options.cache_dir = server->cache_dir;
    server->options.web_dir = server->web_root;
    *out = server;
    return LK_OK;
fail:
    server_free(server);
    return status;
}

lk_status lk_server_start(const char *directory, const lk_server_options *options, lk_server **out, lk_error *error)
{
    lk_server *server = NULL;
    lk_status status = server_create(directory, options, &server, error);
    if (status != LK_OK) return status;

    /* The listening address. */
    struct addrinfo hints, *addresses = NULL;
    memset(&hints, 0, sizeof hints);
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = AI_PASSIVE;
    char port_text[16];
    snprintf(port_text, sizeof port_text, "%u", server->options.port);
    int lookup = getaddrinfo(server->host, port_text, &hints, &addresses);
    if (lookup != 0 || !addresses) {
        status =
            lk_error_set(error, LK_ERR_IO, "%s: cannot resolve the address: %s", server->host, gai_strerror(lookup));
        goto fail;
    }
    /* MHD_USE_ITC: a connection thread that ends wakes the listening
     * thread at once, so its slot (max_connections, the per-address
     * limit) is free for the next client immediately, and stopping never
     * depends on the listening socket's shutdown waking poll(). */
    unsigned flags = MHD_USE_THREAD_PER_CONNECTION | MHD_USE_INTERNAL_POLLING_THREAD | MHD_USE_POLL |
                     MHD_USE_ERROR_LOG | MHD_USE_ITC;
    if (addresses->ai_family == AF_INET6) flags |= MHD_USE_IPv6;
    struct sockaddr_storage address;
    memset(&address, 0, sizeof address);
    memcpy(&address, addresses->ai_addr, addresses->ai_addrlen);
    freeaddrinfo(addresses);
    server->daemon = MHD_start_daemon(
        flags, (uint16_t)server->options.port, NULL, NULL, handle_request, server, MHD_OPTION_EXTERNAL_LOGGER,
        lk__serve_mhd_logger, server, MHD_OPTION_SOCK_ADDR, (struct sockaddr *)&address, MHD_OPTION_CONNECTION_LIMIT,
        (unsigned int)server->options.max_connections, MHD_OPTION_PER_IP_CONNECTION_LIMIT,
        (unsigned int)server->options.max_connections_per_ip, MHD_OPTION_CONNECTION_TIMEOUT,
        (unsigned int)server->options.timeout_seconds, MHD_OPTION_CONNECTION_MEMORY_LIMIT,
        (size_t)server->options.connection_memory, MHD_OPTION_URI_LOG_CALLBACK, lk__serve_uri_logger, server,
        MHD_OPTION_NOTIFY_COMPLETED, lk__serve_request_completed, server, MHD_OPTION_NOTIFY_CONNECTION,
        lk__serve_connection_notify, server, MHD_OPTION_END);
    if (!server->daemon) {
        status =
            lk_error_set(error, LK_ERR_IO, "cannot listen on %s port %u (in use, or not an address of this machine)",
                         server->host, server->options.port);
        goto fail;
    }
    const union MHD_DaemonInfo *info = MHD_get_daemon_info(server->daemon, MHD_DAEMON_INFO_BIND_PORT);
    server->port = info ? info->port : server->options.port;
    if (pthread_create(&server->watchdog, NULL, lk__serve_watchdog_main, server) != 0) {
        status = lk_error_set(error, LK_ERR_NOMEM, "cannot start the connection watchdog thread");
        goto fail;
    }
    server->watchdog_running = true;
    *out = server;
    return LK_OK;
fail:
    if (server->daemon) MHD_stop_daemon(server->daemon);
    server_free(server);
    return status;
}

unsigned lk_server_port(const lk_server *server) { return server ? server->port : 0; }

void lk_server_stop(lk_server *server)
{
    if (!server) return;
    /* First make long work give up (simplify-on-demand builds poll this),
     * then stop the watchdog, then let libmicrohttpd close the listening
     * socket, shut every connection down and join its thread. */
    atomic_store(&server->stopping, 1);
    if (server->watchdog_running) {
        pthread_mutex_lock(&server->connections_lock);
        server->watchdog_stop = true;
        pthread_cond_signal(&server->watchdog_wake);
        pthread_mutex_unlock(&server->connections_lock);
        pthread_join(server->watchdog, NULL);
    }
    if (server->daemon) MHD_stop_daemon(server->daemon);
    server_free(server);
}

/* ---- in-process requests (the HTTP fuzz target) ---------------------------------------- */

lk_status lk__server_start_detached(const char *directory, const lk_server_options *options, lk_server **out,
                                    lk_error *error)
{
    lk_server *server = NULL;
    lk_status status = server_create(directory, options, &server, error);
    if (status != LK_OK) return status;
    server->detached = true;
    /* No listening socket and no internal thread: lk__server_exchange hands
     * connections to libmicrohttpd and drives it with MHD_run. */
    server->daemon = MHD_start_daemon(
        MHD_USE_NO_LISTEN_SOCKET | MHD_USE_ERROR_LOG, 0, NULL, NULL, handle_request, server, MHD_OPTION_EXTERNAL_LOGGER,
        lk__serve_mhd_logger, server, MHD_OPTION_CONNECTION_LIMIT, (unsigned int)server->options.max_connections,
        MHD_OPTION_CONNECTION_TIMEOUT, (unsigned int)server->options.timeout_seconds,
        MHD_OPTION_CONNECTION_MEMORY_LIMIT, (size_t)server->options.connection_memory, MHD_OPTION_URI_LOG_CALLBACK,
        lk__serve_uri_logger, server, MHD_OPTION_NOTIFY_COMPLETED, lk__serve_request_completed, server,
        MHD_OPTION_NOTIFY_CONNECTION, lk__serve_connection_notify, server, MHD_OPTION_END);
    if (!server->daemon) {
        server_free(server);
        return lk_error_set(error, LK_ERR_IO, "cannot start an in-process HTTP daemon");
    }
    *out = server;
    return LK_OK;
}

#define SERVE_EXCHANGE_MAX_ROUNDS 100000
#define SERVE_EXCHANGE_MAX_KEPT ((size_t)64 << 20)

lk_status lk__server_exchange(lk_server *server, const void *request_bytes, size_t size, unsigned char **response,
                              size_t *response_size, lk_error *error)
{
    if (response) *response = NULL;
    if (response_size) *response_size = 0;
    if (!server || !server->detached)
        return lk_error_set(error, LK_ERR_INVALID, "lk__server_exchange: the server was not started detached");
    int pair[2];
    if (socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0, pair) != 0)
        return lk_error_set(error, LK_ERR_IO, "socketpair: %s", strerror(errno));
    /* The server's end (pair[0]) goes to libmicrohttpd, which closes it
     * even when it refuses it; the address is what the log shows. */
    struct sockaddr_in address;
    memset(&address, 0, sizeof address);
    address.sin_family = AF_INET;
    address.sin_port = htons(1);
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (MHD_add_connection(server->daemon, pair[0], (struct sockaddr *)&address, sizeof address) != MHD_YES) {
        close(pair[1]);
        return lk_error_set(error, LK_ERR_IO, "libmicrohttpd refused the connection");
    }
    lk__buffer received = {0};
    const unsigned char *bytes = request_bytes;
    size_t sent = 0;
    bool write_closed = false, closed = false, overflow = false;
    lk_status status = LK_OK;
    for (unsigned round = 0; round < SERVE_EXCHANGE_MAX_ROUNDS && !closed; round++) {
        while (sent < size) {
            ssize_t n = send(pair[1], bytes + sent, size - sent, MSG_NOSIGNAL | MSG_DONTWAIT);
            if (n > 0)
                sent += (size_t)n;
            else if (n < 0 && errno == EINTR)
                continue;
            else if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK))
                break;
            else
                sent = size; /* the server closed: the rest is never read */
        }
        if (sent == size && !write_closed) {
            shutdown(pair[1], SHUT_WR);
            write_closed = true;
        }
        MHD_run(server->daemon);
        for (;;) {
            unsigned char chunk[16384];
            ssize_t n = recv(pair[1], chunk, sizeof chunk, MSG_DONTWAIT);
            if (n > 0) {
                if (!response || overflow) continue;
                if (received.size + (size_t)n > SERVE_EXCHANGE_MAX_KEPT ||
                    !lk__buffer_append(&received, chunk, (size_t)n))
                    overflow = true;
                continue;
            }
            if (n == 0 || (errno != EINTR && errno != EAGAIN && errno != EWOULDBLOCK)) closed = true;
            if (n < 0 && errno == EINTR) continue;
            break;
        }
    }
    close(pair[1]);
    /* Let libmicrohttpd notice the closed socket and free the connection. */
    for (unsigned round = 0; round < 1000; round++) {
        const union MHD_DaemonInfo *info = MHD_get_daemon_info(server->daemon, MHD_DAEMON_INFO_CURRENT_CONNECTIONS);
        if (!info || info->num_connections == 0) break;
        MHD_run(server->daemon);
    }
    if (!closed) status = lk_error_set(error, LK_ERR_LIMIT, "the server neither answered nor closed the connection");
    if (status == LK_OK && response) {
        if (!lk__buffer_append(&received, "", 1)) {
            status = lk_error_set(error, LK_ERR_NOMEM, "out of memory for the response");
        } else {
            size_t kept = received.size - 1;
            *response = lk__buffer_take(&received);
            if (response_size) *response_size = kept;
        }
    }
    lk__buffer_free(&received);
    return status;
}
