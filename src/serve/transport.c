/* SPDX-License-Identifier: MIT */
/* The server's HTTP transport over libmicrohttpd: the request log,
 * connections and the request deadline (the watchdog against slow
 * clients), a request's life, paths decoded and checked, files opened
 * inside the root, content types, and responses: JSON errors, files and
 * bytes with ETag, Range and gzip, file bodies read with pread (server.c
 * has the design notes). */
#define _XOPEN_SOURCE 700 /* realpath */
#include "serve_shared.h"

#include <ctype.h>
#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/socket.h>
#include <sys/types.h>
#include <time.h>
#include <unistd.h>
#include <zlib.h>

#include <arpa/inet.h>
#include <netinet/in.h>

/* ---- the request log ----------------------------------------------------- */

void lk__serve_server_log(const lk_server *server, const char *format, ...)
{
    if (!server->options.log) return;
    char line[1024];
    va_list args;
    va_start(args, format);
    vsnprintf(line, sizeof line, format, args);
    va_end(args);
    server->options.log(server->options.log_user, line);
}

void lk__serve_mhd_logger(void *user, const char *format, va_list args)
{
    const lk_server *server = user;
    if (!server->options.log) return;
    char text[900];
    vsnprintf(text, sizeof text, format, args);
    size_t length = strlen(text);
    while (length && (text[length - 1] == '\n' || text[length - 1] == '\r')) text[--length] = '\0';
    lk__serve_server_log(server, "libmicrohttpd: %s", text);
}

/* ---- connections and the request deadline -------------------------------- */

struct request;
static void request_free(struct request *r);
static bool request_answered_early(const struct request *r);
static void log_request(const lk_server *server, struct MHD_Connection *connection, const struct request *r,
                        const char *note);

void lk__serve_connection_notify(void *user, struct MHD_Connection *connection, void **socket_context,
                                 enum MHD_ConnectionNotificationCode code)
{
    lk_server *server = user;
    if (code == MHD_CONNECTION_NOTIFY_STARTED) {
        /* Out of memory here only means this connection has no deadline
         * beyond libmicrohttpd's inactivity timeout. */
        connection_state *state = calloc(1, sizeof *state);
        if (!state) return;
        const union MHD_ConnectionInfo *info = MHD_get_connection_info(connection, MHD_CONNECTION_INFO_CONNECTION_FD);
        state->fd = info ? info->connect_fd : -1;
        state->waiting_since = lk__now();
        pthread_mutex_lock(&server->connections_lock);
        state->next = server->connections;
        if (state->next) state->next->previous = state;
        server->connections = state;
        pthread_mutex_unlock(&server->connections_lock);
        *socket_context = state;
    } else if (code == MHD_CONNECTION_NOTIFY_CLOSED) {
        connection_state *state = *socket_context;
        if (!state) return;
        pthread_mutex_lock(&server->connections_lock);
        if (state->previous)
            state->previous->next = state->next;
        else
            server->connections = state->next;
        if (state->next) state->next->previous = state->previous;
        pthread_mutex_unlock(&server->connections_lock);
        if (state->pending && request_answered_early(state->pending))
            log_request(server, connection, state->pending, " (answered before libmicrohttpd parsed it)");
        request_free(state->pending);
        free(state);
        *socket_context = NULL;
    }
}

/* A request's headers are complete (waiting = false), or its response is
 * done and the connection waits for the next one (waiting = true). */
void lk__serve_connection_set_waiting(lk_server *server, struct MHD_Connection *connection, bool waiting)
{
    const union MHD_ConnectionInfo *info = MHD_get_connection_info(connection, MHD_CONNECTION_INFO_SOCKET_CONTEXT);
    connection_state *state = info ? info->socket_context : NULL;
    if (!state) return;
    pthread_mutex_lock(&server->connections_lock);
    state->waiting_since = waiting ? lk__now() : 0;
    pthread_mutex_unlock(&server->connections_lock);
}

/* Drops connections that have waited too long for a complete request.
 * shutdown() wakes the connection's thread, which then closes it the
 * ordinary way (libmicrohttpd still owns the descriptor). */
void *lk__serve_watchdog_main(void *user)
{
    lk_server *server = user;
    double timeout = (double)server->options.timeout_seconds;
    long period_ms = server->options.timeout_seconds >= 4 ? 1000 : 250 * (long)server->options.timeout_seconds;
    pthread_mutex_lock(&server->connections_lock);
    while (!server->watchdog_stop) {
        double now = lk__now();
        size_t dropped = 0;
        for (connection_state *state = server->connections; state; state = state->next)
            if (!state->dropped && state->waiting_since > 0 && now - state->waiting_since > timeout && state->fd >= 0) {
                shutdown(state->fd, SHUT_RDWR);
                state->dropped = true;
                dropped++;
            }
        if (dropped) {
            pthread_mutex_unlock(&server->connections_lock);
            lk__serve_server_log(server, "dropped %zu connection%s without a complete request after %u s", dropped,
                                 dropped == 1 ? "" : "s", server->options.timeout_seconds);
            pthread_mutex_lock(&server->connections_lock);
            continue;
        }
        struct timespec deadline;
        clock_gettime(CLOCK_MONOTONIC, &deadline);
        deadline.tv_nsec += period_ms % 1000 * 1000000L;
        deadline.tv_sec += period_ms / 1000 + deadline.tv_nsec / 1000000000L;
        deadline.tv_nsec %= 1000000000L;
        pthread_cond_timedwait(&server->watchdog_wake, &server->connections_lock, &deadline);
    }
    pthread_mutex_unlock(&server->connections_lock);
    return NULL;
}

/* ---- per request --------------------------------------------------------- */

static bool request_answered_early(const struct request *r) { return r->answered_early; }

static void request_free(struct request *r)
{
    if (!r) return;
    free(r->uri);
    free(r);
}

static connection_state *state_of(struct MHD_Connection *connection)
{
    const union MHD_ConnectionInfo *info = MHD_get_connection_info(connection, MHD_CONNECTION_INFO_SOCKET_CONTEXT);
    return info ? info->socket_context : NULL;
}

/* Does libmicrohttpd have room for the query's parameters? It keeps one
 * record of 64 bytes per parameter (measured with 0.9.75: a request line
 * of L bytes leaves room for (connection_memory - L - ~360) / 64 of them)
 * in the connection's memory, which also holds the request line; when
 * they do not fit it logs a 431 but sends nothing and closes the
 * connection, so the client gets an empty reply. Estimated with margins
 * (72 bytes each, 4 KiB for the read buffer's growth steps and the
 * headers): a request refused here could sometimes have fit. */
static bool query_fits(const lk_server *server, const char *uri)
{
    const char *query = strchr(uri, '?');
    if (!query) return true;
    size_t parameters = 1;
    for (const char *p = query + 1; *p; p++) parameters += *p == '&' || *p == ';';
    size_t line = strlen(uri) + 32; /* method, version, CRLF */
    return line + 72 * (parameters + 1) + 4096 <= server->options.connection_memory;
}

static void http_date(time_t when, char *out, size_t size);

/* Answers 414 on the connection's socket itself, before libmicrohttpd
 * parses the query (it cannot answer once out of memory). libmicrohttpd
 * then either fails on the query and closes the connection without
 * sending anything, or has room after all and calls handle_request,
 * which closes it (answered_early). The socket is not shut down here:
 * libmicrohttpd 0.9.75 sometimes crashes on a connection whose sending
 * side was shut down behind its back. */
static void answer_early(connection_state *state, request *r)
{
    static const char body[] = "{\"error\":\"the request target has too many query parameters\"}";
    char date[64], answer[512];
    http_date(time(NULL), date, sizeof date);
    int length = snprintf(answer, sizeof answer,
                          "HTTP/1.1 414 URI Too Long\r\nDate: %s\r\nContent-Type: " SERVE_MIME_JSON "\r\n"
                          "Content-Length: %zu\r\nCache-Control: no-store\r\nConnection: close\r\n\r\n%s",
                          date, sizeof body - 1, body);
    size_t sent = 0;
    while (sent < (size_t)length) {
        ssize_t n = send(state->fd, answer + sent, (size_t)length - sent, MSG_NOSIGNAL | MSG_DONTWAIT);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) break; /* a client that does not read: it gets what fitted */
        sent += (size_t)n;
    }
    r->answered_early = true;
    r->responded = 1;
    r->status = 414;
    r->bytes = sizeof body - 1;
}

void *lk__serve_uri_logger(void *user, const char *uri, struct MHD_Connection *connection)
{
    const lk_server *server = user;
    request *r = calloc(1, sizeof *r);
    if (!r) return NULL;
    r->server = user;
    r->start = lk__now();
    r->uri = strdup(uri ? uri : "");
    connection_state *state = state_of(connection);
    if (state) {
        request_free(state->pending); /* never completed: see connection_state */
        state->pending = r;
        if (uri && state->fd >= 0 && !query_fits(server, uri)) answer_early(state, r);
    }
    return r;
}

/* One line per request in the log: client, request, status, bytes, time. */
static void log_request(const lk_server *server, struct MHD_Connection *connection, const request *r, const char *note)
{
    if (!server->options.log) return;
    char client[INET6_ADDRSTRLEN] = "-";
    const union MHD_ConnectionInfo *info = MHD_get_connection_info(connection, MHD_CONNECTION_INFO_CLIENT_ADDRESS);
    if (info && info->client_addr) {
        const struct sockaddr *address = info->client_addr;
        if (address->sa_family == AF_INET)
            inet_ntop(AF_INET, &((const struct sockaddr_in *)(const void *)address)->sin_addr, client, sizeof client);
        else if (address->sa_family == AF_INET6)
            inet_ntop(AF_INET6, &((const struct sockaddr_in6 *)(const void *)address)->sin6_addr, client,
                      sizeof client);
    }
    /* The URI is the client's text: keep control characters out of the log. */
    char uri[512];
    size_t o = 0;
    for (const char *p = r->uri; p && *p && o + 1 < sizeof uri; p++)
        uri[o++] = (unsigned char)*p < 0x20 || *p == 0x7f || *p == '"' ? '?' : *p;
    uri[o] = '\0';
    double milliseconds = (lk__now() - r->start) * 1000.0;
    lk__serve_server_log(server, "%s \"%s %s\" %03u %llu bytes %.1f ms%s", client, r->method[0] ? r->method : "-", uri,
                         r->status, (unsigned long long)r->bytes, milliseconds, note);
}

void lk__serve_request_completed(void *user, struct MHD_Connection *connection, void **context,
                                 enum MHD_RequestTerminationCode code)
{
    lk_server *server = user;
    lk__serve_connection_set_waiting(server, connection, true);
    request *r = *context;
    if (!r) return;
    *context = NULL;
    connection_state *state = state_of(connection);
    if (state && state->pending == r) state->pending = NULL;
    const char *note = code == MHD_REQUEST_TERMINATED_COMPLETED_OK      ? ""
                       : code == MHD_REQUEST_TERMINATED_TIMEOUT_REACHED ? " (timed out)"
                       : code == MHD_REQUEST_TERMINATED_DAEMON_SHUTDOWN ? " (server stopping)"
                       : code == MHD_REQUEST_TERMINATED_CLIENT_ABORT    ? " (client closed)"
                                                                        : " (connection error)";
    log_request(server, connection, r, note);
    request_free(r);
}

/* ---- small helpers ------------------------------------------------------- */

const char *lk__serve_extension_of(const char *path)
{
    const char *slash = strrchr(path, '/');
    const char *dot = strrchr(path, '.');
    if (!dot || (slash && dot < slash) || dot == path || (slash && dot == slash + 1)) return "";
    return dot + 1;
}

static const content_type content_types[] = {
    {"lks", SERVE_MIME_LKS, false},
    {"lkmb", SERVE_MIME_LKMB, false},
    {"html", "text/html; charset=utf-8", true},
    {"htm", "text/html; charset=utf-8", true},
    {"js", "text/javascript; charset=utf-8", true},
    {"mjs", "text/javascript; charset=utf-8", true},
    {"css", "text/css; charset=utf-8", true},
    {"json", SERVE_MIME_JSON, true},
    {"map", SERVE_MIME_JSON, true},
    {"glsl", "text/plain; charset=utf-8", true},
    {"vert", "text/plain; charset=utf-8", true},
    {"frag", "text/plain; charset=utf-8", true},
    {"txt", "text/plain; charset=utf-8", true},
    {"md", "text/markdown; charset=utf-8", true},
    {"csv", "text/csv; charset=utf-8", true},
    {"svg", "image/svg+xml", true},
    {"obj", "model/obj", true},
    {"mtl", "model/mtl", true},
    {"off", "text/plain; charset=utf-8", true},
    {"smf", "text/plain; charset=utf-8", true},
    {"xyz", "text/plain; charset=utf-8", true},
    {"asc", "text/plain; charset=utf-8", true},
    {"ply", "application/octet-stream", false}, /* ASCII PLY is sniffed below */
    {"stl", "model/stl", false},
    {"gltf", "model/gltf+json", true},
    {"glb", "model/gltf-binary", false},
    {"png", "image/png", false},
    {"jpg", "image/jpeg", false},
    {"jpeg", "image/jpeg", false},
    {"ico", "image/vnd.microsoft.icon", false},
    {"tif", "image/tiff", false},
    {"tiff", "image/tiff", false},
    {"pgm", "image/x-portable-graymap", false},
    {"wasm", "application/wasm", true}, /* compressible: stream2.wasm, 63 KB, gzips to 27 */
    {NULL, "application/octet-stream", false}};

const content_type *lk__serve_content_type_of(const char *path)
{
    const char *extension = lk__serve_extension_of(path);
    size_t i = 0;
    for (; content_types[i].extension; i++)
        if (strcasecmp(extension, content_types[i].extension) == 0) break;
    return &content_types[i];
}

/* "Sun, 06 Nov 1994 08:49:37 GMT", independent of the locale. */
static void http_date(time_t when, char *out, size_t size)
{
    static const char days[7][4] = {"Sun", "Mon", "Tue", "Wed", "Thu", "Fri", "Sat"};
    static const char months[12][4] = {"Jan", "Feb", "Mar", "Apr", "May", "Jun",
                                       "Jul", "Aug", "Sep", "Oct", "Nov", "Dec"};
    struct tm t;
    if (!gmtime_r(&when, &t)) {
        snprintf(out, size, "Thu, 01 Jan 1970 00:00:00 GMT");
        return;
    }
    snprintf(out, size, "%s, %02d %s %04d %02d:%02d:%02d GMT", days[t.tm_wday % 7], t.tm_mday, months[t.tm_mon % 12],
             t.tm_year + 1900, t.tm_hour, t.tm_min, t.tm_sec);
}

static long long mtime_ns_of(const struct stat *st)
{
    return (long long)st->st_mtim.tv_sec * 1000000000LL + st->st_mtim.tv_nsec;
}

/* One version of a file, for every cache here (simplify-on-demand streams,
 * point buffers, terrains, gzip results, index entries) and for ETags:
 * device, inode, size, modification and change times. The modification
 * time alone misses a file replaced by an older one (rsync -t, cp -p,
 * tar x): the inode changes when it is replaced by a rename, the change
 * time (which nobody can set) when it is rewritten in place. */
void lk__serve_version_of(const struct stat *st, char out[SERVE_VERSION_CHARS])
{
    long long ctime_ns = (long long)st->st_ctim.tv_sec * 1000000000LL + st->st_ctim.tv_nsec;
    snprintf(out, SERVE_VERSION_CHARS, "%llx-%llx-%llx-%llx-%llx", (unsigned long long)st->st_dev,
             (unsigned long long)st->st_ino, (unsigned long long)st->st_size, (unsigned long long)mtime_ns_of(st),
             (unsigned long long)ctime_ns);
}

/* Percent-encodes a relative path for a URL (keeps unreserved characters and '/'). */
char *lk__serve_url_encode_path(const char *path)
{
    size_t length = strlen(path);
    char *out = lk__malloc_array(length, 3);
    if (!out) return NULL;
    size_t o = 0;
    for (const unsigned char *p = (const unsigned char *)path; *p; p++) {
        if (isalnum(*p) || *p == '-' || *p == '_' || *p == '.' || *p == '~' || *p == '/') {
            out[o++] = (char)*p;
        } else {
            static const char hex[] = "0123456789ABCDEF";
            out[o++] = '%';
            out[o++] = hex[*p >> 4];
            out[o++] = hex[*p & 15];
        }
    }
    out[o] = '\0';
    return out;
}

static int hex_value(char c)
{
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

/* Decodes the path part of a raw URI (up to '?' or '#'). Returns NULL for
 * a malformed escape or an encoded NUL. */
char *lk__serve_decode_path(const char *uri)
{
    size_t length = strcspn(uri, "?#");
    char *out = malloc(length + 1);
    if (!out) return NULL;
    size_t o = 0;
    for (size_t i = 0; i < length; i++) {
        if (uri[i] == '%') {
            if (i + 2 >= length) {
                free(out);
                return NULL;
            }
            int a = hex_value(uri[i + 1]), b = a >= 0 ? hex_value(uri[i + 2]) : -1;
            if (a < 0 || b < 0 || (a == 0 && b == 0)) {
                free(out);
                return NULL;
            }
            out[o++] = (char)(a * 16 + b);
            i += 2;
        } else {
            out[o++] = uri[i];
        }
    }
    out[o] = '\0';
    return out;
}

/* Checks a decoded relative path and returns a normalised copy (empty
 * components dropped), or NULL with *status 403 (traversal, hidden
 * component, backslash, control character) or 404 (empty). */
char *lk__serve_clean_relative_path(const char *path, unsigned *status)
{
    size_t length = strlen(path);
    char *out = malloc(length + 1);
    if (!out) {
        *status = 500;
        return NULL;
    }
    size_t o = 0;
    const char *p = path;
    while (*p) {
        while (*p == '/') p++;
        if (!*p) break;
        const char *end = p + strcspn(p, "/");
        /* "." and ".." and every hidden name (.git, .lodkit-cache, ...) */
        if (*p == '.') {
            free(out);
            *status = 403;
            return NULL;
        }
        for (const char *q = p; q < end; q++)
            if (*q == '\\' || (unsigned char)*q < 0x20 || *q == 0x7f) {
                free(out);
                *status = 403;
                return NULL;
            }
        if (o) out[o++] = '/';
        memcpy(out + o, p, (size_t)(end - p));
        o += (size_t)(end - p);
        p = end;
    }
    out[o] = '\0';
    if (!o) {
        free(out);
        *status = 404;
        return NULL;
    }
    return out;
}

bool lk__serve_inside_root(const char *path, const char *root, size_t root_length)
{
    if (strncmp(path, root, root_length) != 0) return false;
    if (root_length == 1) return true; /* root is "/" */
    return path[root_length] == '\0' || path[root_length] == '/';
}

void lk__serve_opened_close(opened_file *file)
{
    if (file->fd >= 0) close(file->fd);
    free(file->real);
    file->fd = -1;
    file->real = NULL;
    file->name = NULL;
}

/* Opens root/relative (already cleaned). Returns 0, or an HTTP status with
 * the reason in *why (names relative to the root): 404 missing, a
 * directory; 403 outside the root, or refused (a FIFO, socket or device:
 * lk__open_input never blocks on one nor reads one). */
unsigned lk__serve_open_in_root(const char *root, size_t root_length, const char *relative, opened_file *out,
                                lk_error *why)
{
    out->fd = -1;
    out->real = NULL;
    out->name = NULL;
    size_t length = root_length + 1 + strlen(relative) + 1;
    char *joined = malloc(length);
    if (!joined) {
        lk_error_set(why, LK_ERR_NOMEM, "out of memory");
        return 500;
    }
    snprintf(joined, length, "%s/%s", root, relative);
    char *real = realpath(joined, NULL);
    int saved = errno;
    free(joined);
    if (!real) {
        if (saved == EACCES || saved == ELOOP)
            lk_error_set(why, LK_ERR_IO, "forbidden path");
        else if (saved == ENOMEM)
            lk_error_set(why, LK_ERR_NOMEM, "out of memory");
        else
            lk_error_set(why, LK_ERR_IO, "%s: not found", relative);
        return saved == EACCES || saved == ELOOP ? 403 : saved == ENOMEM ? 500 : 404;
    }
    if (!lk__serve_inside_root(real, root, root_length)) {
        free(real);
        lk_error_set(why, LK_ERR_IO, "forbidden path");
        return 403;
    }
    if (strcmp(real, root) == 0) { /* a link to the root itself */
        free(real);
        lk_error_set(why, LK_ERR_IO, "%s: is a directory, not a regular file", relative);
        return 404;
    }
    /* realpath resolved every link; walking the resolved path from the
     * root without following links refuses one swapped in since. */
    const char *below = real + (root_length == 1 ? 1 : root_length + 1);
    int fd;
    if (lk__open_input(root, below, &fd, &out->st, why) != LK_OK) {
        saved = errno;
        free(real);
        if (saved == ENOENT) lk_error_set(why, LK_ERR_IO, "%s: not found", relative);
        return saved == ENOENT || saved == ENOTDIR || saved == EISDIR ? 404 : 403;
    }
    /* What was opened, whatever happened to the directories on the way
     * (one moved out of the root during the walk). */
    char link[64], opened[PATH_MAX + 1];
    snprintf(link, sizeof link, "/proc/self/fd/%d", fd);
    ssize_t n = readlink(link, opened, PATH_MAX);
    if (n > 0) {
        opened[n] = '\0';
        if (!lk__serve_inside_root(opened, root, root_length)) {
            close(fd);
            free(real);
            lk_error_set(why, LK_ERR_IO, "forbidden path");
            return 403;
        }
    }
    out->fd = fd;
    out->real = real;
    out->name = below;
    return 0;
}

/* Reads a whole opened file (at most `limit` bytes) into memory. */
lk_status lk__serve_read_opened(const opened_file *file, size_t limit, unsigned char **data, size_t *size,
                                lk_error *error)
{
    char *bytes = NULL;
    lk_status status = lk__read_opened(file->fd, &file->st, file->name, limit, &bytes, size, error);
    *data = (unsigned char *)bytes;
    return status;
}

/* ---- responses ----------------------------------------------------------- */

enum MHD_Result lk__serve_queue(struct MHD_Connection *connection, request *r, unsigned status,
                                struct MHD_Response *response, uint64_t body_bytes)
{
    if (!response) return MHD_NO;
    r->status = status;
    r->bytes = strcmp(r->method, "HEAD") == 0 ? 0 : body_bytes;
    r->responded = 1;
    enum MHD_Result result = MHD_queue_response(connection, status, response);
    MHD_destroy_response(response);
    return result;
}

enum MHD_Result lk__serve_respond_json_text(struct MHD_Connection *connection, request *r, unsigned status, char *text)
{
    if (!text) return MHD_NO;
    size_t length = strlen(text);
    struct MHD_Response *response = MHD_create_response_from_buffer(length, text, MHD_RESPMEM_MUST_FREE);
    if (!response) {
        free(text);
        return MHD_NO;
    }
    MHD_add_response_header(response, MHD_HTTP_HEADER_CONTENT_TYPE, SERVE_MIME_JSON);
    MHD_add_response_header(response, MHD_HTTP_HEADER_CACHE_CONTROL, "no-store");
    return lk__serve_queue(connection, r, status, response, length);
}

/* Removes `directory` from a message: "DIRECTORY/x" becomes "x", the
 * directory alone ".", and one cut off at the end of a truncated message
 * goes too. */
static void remove_directory(char *message, const char *directory)
{
    size_t length = strlen(directory);
    if (length < 2) return; /* the root "/": nothing to hide */
    for (char *p = message; (p = strstr(p, directory));) {
        if (p[length] == '/')
            memmove(p, p + length + 1, strlen(p + length + 1) + 1);
        else if (isalnum((unsigned char)p[length]) || p[length] == '_' || p[length] == '-' || p[length] == '.')
            p++;
        else {
            *p = '.';
            memmove(p + 1, p + length, strlen(p + length) + 1);
            p++;
        }
    }
    size_t total = strlen(message);
    for (size_t k = length < total ? length : total; k >= 5; k--)
        if (memcmp(message + total - k, directory, k) == 0) {
            message[total - k] = '\0';
            break;
        }
}

/* Messages the server sends name files relative to the served folder: a
 * reader's or GDAL's message may carry the absolute path, which says where
 * the files are on the machine (the log on stderr keeps it). This is the
 * one place every error body and the index's "error" fields go through. */
void lk__serve_hide_directories(const lk_server *server, char *message)
{
    /* The default cache lies in the served folder: named from there
     * (".lodkit-cache/..."); a --cache folder elsewhere is hidden whole. */
    bool cache_inside = server->cache_dir && server->root &&
                        strncmp(server->cache_dir, server->root, server->root_length) == 0 &&
                        server->cache_dir[server->root_length] == '/';
    if (server->cache_dir && !cache_inside) remove_directory(message, server->cache_dir);
    if (server->root) remove_directory(message, server->root);
    if (server->web_root) remove_directory(message, server->web_root);
}

enum MHD_Result lk__serve_respond_error(struct MHD_Connection *connection, request *r, unsigned status,
                                        const char *format, ...)
{
    char message[600];
    va_list args;
    va_start(args, format);
    vsnprintf(message, sizeof message, format, args);
    va_end(args);
    lk__serve_hide_directories(r->server, message);
    cJSON *root = cJSON_CreateObject();
    if (!root) return MHD_NO;
    cJSON_AddStringToObject(root, "error", message);
    char *text = cJSON_PrintUnformatted(root);
    cJSON_Delete(root);
    if (!text) return MHD_NO;
    /* MHD_RESPMEM_MUST_FREE frees with free(); cJSON allocates with malloc by default. */
    return lk__serve_respond_json_text(connection, r, status, text);
}

/* The status of a library error met while serving a valid request: the
 * request itself (path, query, percent-encoding) is checked, and answered
 * 400, before any file is read, so what the library refuses here is the
 * file (a mesh whose triangles are all degenerate cannot become a stream:
 * LK_ERR_INVALID), a server fault (500), or over a limit. */
unsigned lk__serve_http_status_of(lk_status status)
{
    switch (status) {
    case LK_ERR_LIMIT: return 413;
    case LK_ERR_NOMEM: return 503;
    default: return 500;
    }
}

static void source_release(source *s)
{
    if (s->fd >= 0) close(s->fd);
    s->fd = -1;
    if (s->memory) lk__serve_blob_release(s->memory);
    s->memory = NULL;
}

/* A file body being sent: [offset, offset + length) of fd. */
typedef struct file_body {
    int fd;
    uint64_t offset, length;
} file_body;

/* libmicrohttpd asks for the bytes at `position` of the body. A file that
 * has shrunk since its size was announced gives a short read: the
 * response ends with an error and the connection is closed, so the client
 * sees fewer bytes than Content-Length (a cut transfer), never bytes that
 * are not the file's. */
static ssize_t file_body_read(void *user, uint64_t position, char *buffer, size_t max)
{
    file_body *body = user;
    if (position >= body->length) return MHD_CONTENT_READER_END_OF_STREAM;
    uint64_t left = body->length - position;
    size_t want = left < max ? (size_t)left : max;
    if (want > SSIZE_MAX) want = SSIZE_MAX;
    for (;;) {
        ssize_t n = pread(body->fd, buffer, want, (off_t)(body->offset + position));
        if (n < 0 && errno == EINTR) continue;
        return n > 0 ? n : MHD_CONTENT_READER_END_WITH_ERROR;
    }
}

static void file_body_free(void *user)
{
    file_body *body = user;
    close(body->fd);
    free(body);
}

/* Body [offset, offset + length) of a source as a response (takes the
 * source's descriptor or reference). */
static struct MHD_Response *source_response(source *s, uint64_t offset, uint64_t length)
{
    struct MHD_Response *response = NULL;
    if (s->fd >= 0) {
        file_body *body = malloc(sizeof *body);
        if (!body) return NULL;
        *body = (file_body){s->fd, offset, length};
        /* libmicrohttpd allocates a buffer of the block size per response:
         * 64 KiB blocks for large files, no more than the file for small ones */
        size_t block = length < 64 * 1024 ? (size_t)length + 1 : 64 * 1024;
        response = MHD_create_response_from_callback(length, block, file_body_read, body, file_body_free);
        if (response)
            s->fd = -1;
        else
            free(body);
    } else if (s->memory) {
        response = MHD_create_response_from_buffer_with_free_callback_cls((size_t)length, s->memory->data + offset,
                                                                          lk__serve_blob_release, s->memory);
        if (response) s->memory = NULL;
    } else {
        response = MHD_create_response_from_buffer((size_t)length, (void *)(uintptr_t)(s->persistent + offset),
                                                   MHD_RESPMEM_PERSISTENT);
    }
    return response;
}

/* Does an If-None-Match list name this entity tag? (weak comparison) */
static bool etag_matches(const char *header, const char *etag)
{
    if (!header || !etag[0]) return false;
    const char *p = header;
    while (*p) {
        while (*p == ' ' || *p == '\t' || *p == ',') p++;
        if (!*p) break;
        if (*p == '*') return true;
        if (strncmp(p, "W/", 2) == 0) p += 2;
        const char *end = p + strcspn(p, ",");
        const char *trim = end;
        while (trim > p && (trim[-1] == ' ' || trim[-1] == '\t')) trim--;
        size_t length = (size_t)(trim - p);
        if (length == strlen(etag) && strncmp(p, etag, length) == 0) return true;
        p = end;
    }
    return false;
}

/* Accept-Encoding: is gzip accepted with q > 0? */
static bool accepts_gzip(const char *header)
{
    if (!header) return false;
    const char *p = header;
    while (*p) {
        while (*p == ' ' || *p == '\t' || *p == ',') p++;
        if (!*p) break;
        const char *end = p + strcspn(p, ",");
        size_t name = strcspn(p, ";, \t");
        bool is_gzip = (name == 4 && strncasecmp(p, "gzip", 4) == 0) || (name == 1 && *p == '*');
        if (is_gzip) {
            const char *q = strstr(p, ";");
            double weight = 1.0;
            if (q && q < end) {
                const char *w = q + 1;
                while (*w == ' ') w++;
                if ((w[0] == 'q' || w[0] == 'Q') && w[1] == '=') weight = strtod(w + 2, NULL);
            }
            if (weight > 0) return true;
        }
        p = end;
    }
    return false;
}

/* Reads the decimal digits at *p (at least one), saturating at
 * UINT64_MAX: a position too large to represent is still a position (past
 * any file), not a malformed header. */
static bool parse_position(const char **p, uint64_t *value)
{
    const char *q = *p;
    if (!isdigit((unsigned char)*q)) return false;
    uint64_t v = 0;
    for (; isdigit((unsigned char)*q); q++) {
        unsigned digit = (unsigned)(*q - '0');
        v = v > (UINT64_MAX - digit) / 10 ? UINT64_MAX : v * 10 + digit;
    }
    *p = q;
    *value = v;
    return true;
}

/* Parses a single "bytes=a-b" / "a-" / "-n" range (RFC 9110 14.1.2).
 * Returns 0 when there is no usable Range (absent, another unit,
 * malformed, a > b, or several ranges: the whole body is sent, as RFC 9110
 * allows), 1 with [first, last] set (last clamped to the end), -1 when
 * unsatisfiable (a at or past the end, "-0", or any range of an empty body). */
static int parse_range(const char *header, uint64_t size, uint64_t *first, uint64_t *last)
{
    if (!header) return 0;
    while (*header == ' ' || *header == '\t') header++;
    if (strncasecmp(header, "bytes=", 6) != 0) return 0;
    const char *p = header + 6;
    while (*p == ' ' || *p == '\t') p++;
    if (strchr(p, ',')) return 0;
    uint64_t a = 0, b = UINT64_MAX;
    bool suffix = *p == '-';
    if (suffix)
        p++;
    else if (!parse_position(&p, &a))
        return 0;
    while (*p == ' ' || *p == '\t') p++;
    if (!suffix) {
        if (*p != '-') return 0;
        p++;
        while (*p == ' ' || *p == '\t') p++;
    }
    if (*p) {
        if (!parse_position(&p, &b)) return 0;
        while (*p == ' ' || *p == '\t') p++;
        if (*p) return 0;
    } else if (suffix) {
        return 0; /* "bytes=-" */
    }
    if (suffix) {
        if (b == 0 || size == 0) return -1;
        *first = b >= size ? 0 : size - b;
        *last = size - 1;
        return 1;
    }
    if (b < a) return 0;
    if (a >= size) return -1;
    *first = a;
    *last = b >= size ? size - 1 : b;
    return 1;
}

static blob *gzip_bytes(const unsigned char *data, size_t size)
{
    z_stream z;
    memset(&z, 0, sizeof z);
    if (deflateInit2(&z, 6, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK) return NULL;
    uLong bound = deflateBound(&z, (uLong)size) + 32;
    unsigned char *out = malloc(bound);
    if (!out) {
        deflateEnd(&z);
        return NULL;
    }
    z.next_in = (Bytef *)(uintptr_t)data;
    z.avail_in = (uInt)size;
    z.next_out = out;
    z.avail_out = (uInt)bound;
    int result = deflate(&z, Z_FINISH);
    size_t produced = z.total_out;
    deflateEnd(&z);
    if (result != Z_STREAM_END) {
        free(out);
        return NULL;
    }
    blob *b = lk__serve_blob_wrap(out, produced);
    if (!b) free(out);
    return b;
}

/* The gzip form of a source (cached), or NULL when not worth it. */
static blob *gzip_source(lk_server *server, const source *s)
{
    char key[sizeof s->cache_key + 8];
    snprintf(key, sizeof key, "gz:%s", s->cache_key);
    blob *compressed = lk__serve_cache_get(&server->cache, key);
    if (compressed) return compressed;
    const unsigned char *data = NULL;
    unsigned char *owned = NULL;
    if (s->fd >= 0) {
        /* A file changing under the read is not compressed (nor cached
         * under this version): it is sent as it is, and cut if it shrank. */
        owned = malloc(s->size ? (size_t)s->size : 1);
        lk_error error = {0};
        if (!owned || lk__read_prefix(s->fd, &s->st, "gzip", (size_t)s->size, owned, &error) != LK_OK) {
            free(owned);
            return NULL;
        }
        data = owned;
    } else {
        data = s->memory ? s->memory->data : s->persistent;
    }
    compressed = gzip_bytes(data, (size_t)s->size);
    free(owned);
    if (!compressed) return NULL;
    lk__serve_cache_put(&server->cache, key, compressed);
    return compressed;
}

/* Sends a source with conditional requests, ranges and gzip. Consumes it. */
enum MHD_Result lk__serve_send_source(lk_server *server, struct MHD_Connection *connection, request *r, source *s)
{
    const char *if_none_match = MHD_lookup_connection_value(connection, MHD_HEADER_KIND, MHD_HTTP_HEADER_IF_NONE_MATCH);
    const char *range_header = MHD_lookup_connection_value(connection, MHD_HEADER_KIND, MHD_HTTP_HEADER_RANGE);
    const char *if_range = MHD_lookup_connection_value(connection, MHD_HEADER_KIND, MHD_HTTP_HEADER_IF_RANGE);
    const char *encoding = MHD_lookup_connection_value(connection, MHD_HEADER_KIND, MHD_HTTP_HEADER_ACCEPT_ENCODING);
    char last_modified[64] = "";
    if (s->mtime_ns) http_date((time_t)(s->mtime_ns / 1000000000LL), last_modified, sizeof last_modified);

    uint64_t first = 0, last = 0;
    int range = parse_range(range_header, s->size, &first, &last);
    /* If-Range with another validator: the client's copy is stale, send it all. */
    if (range && if_range && strcmp(if_range, s->etag) != 0 && strcmp(if_range, last_modified) != 0) range = 0;
    bool use_gzip =
        s->text && range == 0 && s->size > 0 && s->size <= server->options.gzip_max_bytes && accepts_gzip(encoding);
    blob *compressed = use_gzip ? gzip_source(server, s) : NULL;
    if (compressed && compressed->size >= s->size) {
        lk__serve_blob_release(compressed);
        compressed = NULL;
    }
    char etag[sizeof s->etag + 4];
    snprintf(etag, sizeof etag, "%s", s->etag);
    if (compressed && etag[0]) {
        size_t length = strlen(etag);
        if (length >= 2 && length + 3 < sizeof etag) memcpy(etag + length - 1, "-gz\"", 5);
    }

    struct MHD_Response *response = NULL;
    unsigned status;
    uint64_t body = 0;
    char content_range[96] = "";
    if (etag[0] && etag_matches(if_none_match, etag)) {
        if (compressed) lk__serve_blob_release(compressed);
        source_release(s);
        response = MHD_create_response_from_buffer(0, (void *)"", MHD_RESPMEM_PERSISTENT);
        status = MHD_HTTP_NOT_MODIFIED;
    } else if (range < 0) {
        source_release(s);
        snprintf(content_range, sizeof content_range, "bytes */%llu", (unsigned long long)s->size);
        cJSON *root = cJSON_CreateObject();
        cJSON_AddStringToObject(root, "error", "range not satisfiable");
        char *text = root ? cJSON_PrintUnformatted(root) : NULL;
        cJSON_Delete(root);
        if (!text) return MHD_NO;
        body = strlen(text);
        response = MHD_create_response_from_buffer((size_t)body, text, MHD_RESPMEM_MUST_FREE);
        if (!response) free(text);
        status = MHD_HTTP_RANGE_NOT_SATISFIABLE;
        if (response) {
            MHD_add_response_header(response, MHD_HTTP_HEADER_CONTENT_RANGE, content_range);
            MHD_add_response_header(response, MHD_HTTP_HEADER_CONTENT_TYPE, SERVE_MIME_JSON);
            MHD_add_response_header(response, MHD_HTTP_HEADER_ACCEPT_RANGES, "bytes");
        }
        return lk__serve_queue(connection, r, status, response, body);
    } else if (range > 0) {
        body = last - first + 1;
        snprintf(content_range, sizeof content_range, "bytes %llu-%llu/%llu", (unsigned long long)first,
                 (unsigned long long)last, (unsigned long long)s->size);
        response = source_response(s, first, body);
        source_release(s);
        status = MHD_HTTP_PARTIAL_CONTENT;
    } else if (compressed) {
        source_release(s);
        body = compressed->size;
        response = MHD_create_response_from_buffer_with_free_callback_cls((size_t)body, compressed->data,
                                                                          lk__serve_blob_release, compressed);
        if (!response) lk__serve_blob_release(compressed);
        status = MHD_HTTP_OK;
    } else {
        body = s->size;
        response = source_response(s, 0, body);
        source_release(s);
        status = MHD_HTTP_OK;
    }
    if (!response) return MHD_NO;
    MHD_add_response_header(response, MHD_HTTP_HEADER_ACCEPT_RANGES, "bytes");
    MHD_add_response_header(response, MHD_HTTP_HEADER_CONTENT_TYPE, s->type);
    if (etag[0]) MHD_add_response_header(response, MHD_HTTP_HEADER_ETAG, etag);
    if (last_modified[0]) MHD_add_response_header(response, MHD_HTTP_HEADER_LAST_MODIFIED, last_modified);
    if (s->text) MHD_add_response_header(response, MHD_HTTP_HEADER_VARY, "Accept-Encoding");
    if (compressed) MHD_add_response_header(response, MHD_HTTP_HEADER_CONTENT_ENCODING, "gzip");
    if (content_range[0]) MHD_add_response_header(response, MHD_HTTP_HEADER_CONTENT_RANGE, content_range);
    MHD_add_response_header(response, MHD_HTTP_HEADER_CACHE_CONTROL, s->cache_control ? s->cache_control : "no-cache");
    return lk__serve_queue(connection, r, status, response, body);
}

/* A source for an opened file (takes its descriptor). */
void lk__serve_source_from_file(source *s, opened_file *file, const char *type_path)
{
    memset(s, 0, sizeof *s);
    s->fd = file->fd;
    file->fd = -1;
    s->size = (uint64_t)file->st.st_size;
    s->mtime_ns = mtime_ns_of(&file->st);
    const content_type *type = lk__serve_content_type_of(type_path);
    s->type = type->type;
    s->text = type->text;
    if (strcasecmp(lk__serve_extension_of(type_path), "ply") == 0) {
        /* ASCII PLY compresses well; binary PLY hardly at all. */
        char head[128] = {0};
        ssize_t n = pread(s->fd, head, sizeof head - 1, 0);
        if (n > 0 && strstr(head, "format ascii")) {
            s->text = true;
            s->type = "text/plain; charset=utf-8";
        }
    }
    char version[SERVE_VERSION_CHARS];
    lk__serve_version_of(&file->st, version);
    snprintf(s->etag, sizeof s->etag, "\"%s\"", version);
    snprintf(s->cache_key, sizeof s->cache_key, "%s|%s", file->real, version);
    s->st = file->st;
}

/* A source for bytes in memory (takes the reference); the ETag is their CRC. */
void lk__serve_source_from_blob(source *s, blob *b, const char *type, bool text, const char *key)
{
    memset(s, 0, sizeof *s);
    s->fd = -1;
    s->memory = b;
    s->size = b->size;
    s->type = type;
    s->text = text;
    unsigned long crc = crc32(0L, b->data, (uInt)b->size);
    snprintf(s->etag, sizeof s->etag, "\"m%lx-%zx\"", crc, b->size);
    snprintf(s->cache_key, sizeof s->cache_key, "%s|%lx|%zu", key, crc, b->size);
}
