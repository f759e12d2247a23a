/* HTTP server for a directory of content and the WebGL viewer
 * (libmicrohttpd). The protocol is described in docs/server.md; this file
 * only wires the library's readers, progressive streams, point sets and
 * terrains to URLs.
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
#include "bytes.h"
#include "internal.h"
#include "serve_internal.h"

#include <cjson/cJSON.h>
#include <ctype.h>
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <microhttpd.h>
#include <netdb.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <time.h>
#include <unistd.h>
#include <zlib.h>

#include <arpa/inet.h>
#include <netinet/in.h>

/* Generated at build time (cmake/embed_shaders.cmake, cmake/embed_web.cmake). */
const char *lk__shader_source(const char *name);
const unsigned char *lk__web_file(const char *name, size_t *size);

#define SERVE_TERRAIN_SLOTS 4
#define SERVE_MAX_INDEX_FILES 10000
#define SERVE_MAX_INDEX_DEPTH 8
#define SERVE_VERSION_CHARS 96 /* version_of: five 64-bit numbers in hex */
#define SERVE_MIME_LKMB "application/vnd.lodkit.mesh"
#define SERVE_MIME_LKS "application/vnd.lodkit.stream"
#define SERVE_MIME_JSON "application/json"

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

/* ---- reference-counted bytes and the memory cache ---------------------- */

typedef struct blob {
    atomic_size_t references;
    size_t size;
    unsigned char *data;
} blob;

/* Takes ownership of data (malloc'ed). One reference for the caller. */
static blob *blob_wrap(unsigned char *data, size_t size)
{
    blob *b = malloc(sizeof *b);
    if (!b) return NULL;
    atomic_init(&b->references, 1);
    b->size = size;
    b->data = data;
    return b;
}

static void blob_retain(blob *b) { atomic_fetch_add(&b->references, 1); }

static void blob_release(void *pointer)
{
    blob *b = pointer;
    if (b && atomic_fetch_sub(&b->references, 1) == 1) {
        free(b->data);
        free(b);
    }
}

typedef struct cache_entry {
    char *key;
    blob *value;
    uint64_t last_used;
} cache_entry;

typedef struct memory_cache {
    pthread_mutex_t lock;
    cache_entry *entries;
    size_t count, capacity;
    size_t bytes, budget;
    uint64_t clock;
} memory_cache;

/* A new reference to the cached value, or NULL. */
static blob *cache_get(memory_cache *cache, const char *key)
{
    blob *found = NULL;
    pthread_mutex_lock(&cache->lock);
    for (size_t i = 0; i < cache->count; i++)
        if (strcmp(cache->entries[i].key, key) == 0) {
            found = cache->entries[i].value;
            cache->entries[i].last_used = ++cache->clock;
            blob_retain(found);
            break;
        }
    pthread_mutex_unlock(&cache->lock);
    return found;
}

static void cache_remove_at(memory_cache *cache, size_t i)
{
    cache->bytes -= cache->entries[i].value->size;
    blob_release(cache->entries[i].value);
    free(cache->entries[i].key);
    cache->entries[i] = cache->entries[--cache->count];
}

/* Stores value under key (the cache takes its own reference); values
 * larger than half the budget are not kept. Failures only mean no caching. */
static void cache_put(memory_cache *cache, const char *key, blob *value)
{
    if (value->size > cache->budget / 2) return;
    pthread_mutex_lock(&cache->lock);
    for (size_t i = 0; i < cache->count; i++)
        if (strcmp(cache->entries[i].key, key) == 0) {
            cache_remove_at(cache, i);
            break;
        }
    while (cache->count && cache->bytes + value->size > cache->budget) {
        size_t oldest = 0;
        for (size_t i = 1; i < cache->count; i++)
            if (cache->entries[i].last_used < cache->entries[oldest].last_used) oldest = i;
        cache_remove_at(cache, oldest);
    }
    if (cache->count == cache->capacity) {
        size_t capacity = cache->capacity ? 2 * cache->capacity : 16;
        cache_entry *grown = lk__realloc_array(cache->entries, capacity, sizeof *grown);
        if (!grown) goto done;
        cache->entries = grown;
        cache->capacity = capacity;
    }
    char *key_copy = strdup(key);
    if (!key_copy) goto done;
    blob_retain(value);
    cache->entries[cache->count++] = (cache_entry){key_copy, value, ++cache->clock};
    cache->bytes += value->size;
done:
    pthread_mutex_unlock(&cache->lock);
}

static void cache_free(memory_cache *cache)
{
    while (cache->count) cache_remove_at(cache, cache->count - 1);
    free(cache->entries);
    pthread_mutex_destroy(&cache->lock);
}

/* ---- the server --------------------------------------------------------- */

typedef struct terrain_slot {
    char *key;
    lk_terrain *terrain;
    pthread_mutex_t lock;      /* held while the terrain is updated */
    size_t memory;
    int users;
    uint64_t last_used;
    lk_terrain_info info;
} terrain_slot;

/* What the index knows about one file, reused while its version holds. */
typedef struct file_record {
    char *relative;
    char version[SERVE_VERSION_CHARS]; /* version_of the file when it was described */
    cJSON *entry;              /* the index entry without the "stream" key */
} file_record;

/* One open connection, for the request deadline (slowloris). Created and
 * freed by libmicrohttpd's connection notifications; libmicrohttpd closes
 * the socket only after the "closed" notification, so under
 * connections_lock the descriptor is still this connection's. */
typedef struct connection_state {
    struct connection_state *previous, *next;
    /* The request whose URI arrived but which has not completed yet. When
     * libmicrohttpd refuses a request itself after logging its URI (e.g.
     * headers over the connection's memory), it never reports it as
     * completed: the request is freed when the connection closes. */
    struct request *pending;
    int fd;
    double waiting_since;      /* when it began waiting for a request's headers; 0 while one is handled */
    bool dropped;
} connection_state;

struct lk_server {
    struct MHD_Daemon *daemon;
    lk_server_options options;
    bool detached;             /* no socket, no threads (lk__server_start_detached) */
    atomic_int stopping;       /* set by lk_server_stop: long work gives up */
    pthread_mutex_t connections_lock;
    pthread_cond_t watchdog_wake;
    connection_state *connections;
    pthread_t watchdog;
    bool watchdog_running, watchdog_stop;
    char *host, *web_dir, *cache_dir; /* owned copies of the option strings */
    char *root;                /* realpath of the directory */
    size_t root_length;
    size_t cache_trusted_length; /* the part of cache_dir the user named (links followed) */
    char *web_root;            /* realpath of web_dir, or NULL */
    size_t web_root_length;
    unsigned port;
    memory_cache cache;
    pthread_mutex_t build_lock;   /* one simplify-on-demand build at a time */
    pthread_mutex_t terrain_lock; /* guards the slots array (not the terrains) */
    terrain_slot *terrains[SERVE_TERRAIN_SLOTS];
    size_t terrain_memory;
    uint64_t terrain_clock;
    pthread_mutex_t index_lock;
    file_record *records;
    size_t record_count;
    uint64_t index_signature;
    blob *index_json;
};

static void server_log(const lk_server *server, const char *format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
static void server_log(const lk_server *server, const char *format, ...)
{
    if (!server->options.log) return;
    char line[1024];
    va_list args;
    va_start(args, format);
    vsnprintf(line, sizeof line, format, args);
    va_end(args);
    server->options.log(server->options.log_user, line);
}

static void mhd_logger(void *user, const char *format, va_list args)
{
    const lk_server *server = user;
    if (!server->options.log) return;
    char text[900];
    vsnprintf(text, sizeof text, format, args);
    size_t length = strlen(text);
    while (length && (text[length - 1] == '\n' || text[length - 1] == '\r')) text[--length] = '\0';
    server_log(server, "libmicrohttpd: %s", text);
}

/* ---- connections and the request deadline -------------------------------- */

struct request;
static void request_free(struct request *r);
static bool request_answered_early(const struct request *r);
static void log_request(const lk_server *server, struct MHD_Connection *connection, const struct request *r,
                        const char *note);

static void connection_notify(void *user, struct MHD_Connection *connection, void **socket_context,
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
        if (state->previous) state->previous->next = state->next;
        else server->connections = state->next;
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
static void connection_set_waiting(lk_server *server, struct MHD_Connection *connection, bool waiting)
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
static void *watchdog_main(void *user)
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
            server_log(server, "dropped %zu connection%s without a complete request after %u s", dropped,
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

typedef struct request {
    lk_server *server;
    double start;
    char *uri;                 /* raw, as received (percent-encoded, with the query) */
    char method[12];
    unsigned status;           /* 0 until a response is queued */
    uint64_t bytes;            /* body bytes of the response */
    int responded;
    int headers_seen;
    bool answered_early;       /* by uri_logger, before libmicrohttpd parsed the query */
} request;

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

static void *uri_logger(void *user, const char *uri, struct MHD_Connection *connection)
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
static void log_request(const lk_server *server, struct MHD_Connection *connection, const request *r,
                        const char *note)
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
    server_log(server, "%s \"%s %s\" %03u %llu bytes %.1f ms%s", client, r->method[0] ? r->method : "-", uri,
               r->status, (unsigned long long)r->bytes, milliseconds, note);
}

static void request_completed(void *user, struct MHD_Connection *connection, void **context,
                              enum MHD_RequestTerminationCode code)
{
    lk_server *server = user;
    connection_set_waiting(server, connection, true);
    request *r = *context;
    if (!r) return;
    *context = NULL;
    connection_state *state = state_of(connection);
    if (state && state->pending == r) state->pending = NULL;
    const char *note = code == MHD_REQUEST_TERMINATED_COMPLETED_OK ? ""
                       : code == MHD_REQUEST_TERMINATED_TIMEOUT_REACHED ? " (timed out)"
                       : code == MHD_REQUEST_TERMINATED_DAEMON_SHUTDOWN ? " (server stopping)"
                       : code == MHD_REQUEST_TERMINATED_CLIENT_ABORT ? " (client closed)"
                                                                      : " (connection error)";
    log_request(server, connection, r, note);
    request_free(r);
}

/* ---- small helpers ------------------------------------------------------- */

static const char *extension_of(const char *path)
{
    const char *slash = strrchr(path, '/');
    const char *dot = strrchr(path, '.');
    if (!dot || (slash && dot < slash) || dot == path || (slash && dot == slash + 1)) return "";
    return dot + 1;
}

static bool has_extension(const char *path, const char *const *list)
{
    const char *extension = extension_of(path);
    for (size_t i = 0; list[i]; i++)
        if (strcasecmp(extension, list[i]) == 0) return true;
    return false;
}

static const char *const mesh_extensions[] = {"obj", "ply", "off", "smf", "stl", "gltf", "glb", "xyz", NULL};
static const char *const triangle_extensions[] = {"obj", "ply", "off", "stl", "smf", "gltf", "glb", NULL};
static const char *const terrain_extensions[] = {"tif", "tiff", "pgm", "png", "npz", "cdf", "nc", "asc",
                                                 "hgt", "dem", "bil", "flt", "img", "ddf", NULL};

typedef struct content_type {
    const char *extension;
    const char *type;
    bool text;                 /* compressible */
} content_type;

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
    {"wasm", "application/wasm", false},
    {NULL, "application/octet-stream", false}};

static const content_type *content_type_of(const char *path)
{
    const char *extension = extension_of(path);
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
static void version_of(const struct stat *st, char out[SERVE_VERSION_CHARS])
{
    long long ctime_ns = (long long)st->st_ctim.tv_sec * 1000000000LL + st->st_ctim.tv_nsec;
    snprintf(out, SERVE_VERSION_CHARS, "%llx-%llx-%llx-%llx-%llx", (unsigned long long)st->st_dev,
             (unsigned long long)st->st_ino, (unsigned long long)st->st_size, (unsigned long long)mtime_ns_of(st),
             (unsigned long long)ctime_ns);
}

/* Percent-encodes a relative path for a URL (keeps unreserved characters and '/'). */
static char *url_encode_path(const char *path)
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
static char *decode_path(const char *uri)
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
static char *clean_relative_path(const char *path, unsigned *status)
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

static bool inside_root(const char *path, const char *root, size_t root_length)
{
    if (strncmp(path, root, root_length) != 0) return false;
    if (root_length == 1) return true; /* root is "/" */
    return path[root_length] == '\0' || path[root_length] == '/';
}

/* An opened regular file inside a root. */
typedef struct opened_file {
    int fd;
    struct stat st;
    char *real;                /* resolved absolute path */
    const char *name;          /* the path relative to the root (in real), for messages */
} opened_file;

static void opened_close(opened_file *file)
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
static unsigned open_in_root(const char *root, size_t root_length, const char *relative, opened_file *out,
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
        if (saved == EACCES || saved == ELOOP) lk_error_set(why, LK_ERR_IO, "forbidden path");
        else if (saved == ENOMEM) lk_error_set(why, LK_ERR_NOMEM, "out of memory");
        else lk_error_set(why, LK_ERR_IO, "%s: not found", relative);
        return saved == EACCES || saved == ELOOP ? 403 : saved == ENOMEM ? 500 : 404;
    }
    if (!inside_root(real, root, root_length)) {
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
        if (!inside_root(opened, root, root_length)) {
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
static lk_status read_opened(const opened_file *file, size_t limit, unsigned char **data, size_t *size,
                             lk_error *error)
{
    char *bytes = NULL;
    lk_status status = lk__read_opened(file->fd, &file->st, file->name, limit, &bytes, size, error);
    *data = (unsigned char *)bytes;
    return status;
}

/* ---- responses ----------------------------------------------------------- */

static enum MHD_Result queue(struct MHD_Connection *connection, request *r, unsigned status,
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

static enum MHD_Result respond_json_text(struct MHD_Connection *connection, request *r, unsigned status,
                                         char *text)
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
    return queue(connection, r, status, response, length);
}

/* Removes `directory` from a message: "DIRECTORY/x" becomes "x", the
 * directory alone ".", and one cut off at the end of a truncated message
 * goes too. */
static void remove_directory(char *message, const char *directory)
{
    size_t length = strlen(directory);
    if (length < 2) return; /* the root "/": nothing to hide */
    for (char *p = message; (p = strstr(p, directory));) {
        if (p[length] == '/') memmove(p, p + length + 1, strlen(p + length + 1) + 1);
        else if (isalnum((unsigned char)p[length]) || p[length] == '_' || p[length] == '-' || p[length] == '.') p++;
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
static void hide_directories(const lk_server *server, char *message)
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

static enum MHD_Result respond_error(struct MHD_Connection *connection, request *r, unsigned status,
                                     const char *format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;
static enum MHD_Result respond_error(struct MHD_Connection *connection, request *r, unsigned status,
                                     const char *format, ...)
{
    char message[600];
    va_list args;
    va_start(args, format);
    vsnprintf(message, sizeof message, format, args);
    va_end(args);
    hide_directories(r->server, message);
    cJSON *root = cJSON_CreateObject();
    if (!root) return MHD_NO;
    cJSON_AddStringToObject(root, "error", message);
    char *text = cJSON_PrintUnformatted(root);
    cJSON_Delete(root);
    if (!text) return MHD_NO;
    /* MHD_RESPMEM_MUST_FREE frees with free(); cJSON allocates with malloc by default. */
    return respond_json_text(connection, r, status, text);
}

/* The status of a library error met while serving a valid request: the
 * request itself (path, query, percent-encoding) is checked, and answered
 * 400, before any file is read, so what the library refuses here is the
 * file (a mesh whose triangles are all degenerate cannot become a stream:
 * LK_ERR_INVALID), a server fault (500), or over a limit. */
static unsigned http_status_of(lk_status status)
{
    switch (status) {
    case LK_ERR_LIMIT: return 413;
    case LK_ERR_NOMEM: return 503;
    default: return 500;
    }
}

/* Where the bytes of a response come from. */
typedef struct source {
    int fd;                    /* >= 0: a file (the response takes it over) */
    struct stat st;            /* its fstat when it was opened */
    blob *memory;              /* or reference-counted bytes (one reference taken over) */
    const unsigned char *persistent; /* or static bytes (compiled in) */
    uint64_t size;
    long long mtime_ns;        /* 0: no Last-Modified */
    const char *type;
    bool text;
    char etag[SERVE_VERSION_CHARS + 8]; /* with quotes; empty = none */
    char cache_key[2 * PATH_MAX]; /* gzip cache key: identifies this exact content */
    const char *cache_control;
} source;

static void source_release(source *s)
{
    if (s->fd >= 0) close(s->fd);
    s->fd = -1;
    if (s->memory) blob_release(s->memory);
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
        if (response) s->fd = -1;
        else free(body);
    } else if (s->memory) {
        response = MHD_create_response_from_buffer_with_free_callback_cls(
            (size_t)length, s->memory->data + offset, blob_release, s->memory);
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
    if (suffix) p++;
    else if (!parse_position(&p, &a)) return 0;
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
    blob *b = blob_wrap(out, produced);
    if (!b) free(out);
    return b;
}

/* The gzip form of a source (cached), or NULL when not worth it. */
static blob *gzip_source(lk_server *server, const source *s)
{
    char key[sizeof s->cache_key + 8];
    snprintf(key, sizeof key, "gz:%s", s->cache_key);
    blob *compressed = cache_get(&server->cache, key);
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
    cache_put(&server->cache, key, compressed);
    return compressed;
}

/* Sends a source with conditional requests, ranges and gzip. Consumes it. */
static enum MHD_Result send_source(lk_server *server, struct MHD_Connection *connection, request *r, source *s)
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
    bool use_gzip = s->text && range == 0 && s->size > 0 && s->size <= server->options.gzip_max_bytes &&
                    accepts_gzip(encoding);
    blob *compressed = use_gzip ? gzip_source(server, s) : NULL;
    if (compressed && compressed->size >= s->size) {
        blob_release(compressed);
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
        if (compressed) blob_release(compressed);
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
        return queue(connection, r, status, response, body);
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
                                                                          blob_release, compressed);
        if (!response) blob_release(compressed);
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
    return queue(connection, r, status, response, body);
}

/* A source for an opened file (takes its descriptor). */
static void source_from_file(source *s, opened_file *file, const char *type_path)
{
    memset(s, 0, sizeof *s);
    s->fd = file->fd;
    file->fd = -1;
    s->size = (uint64_t)file->st.st_size;
    s->mtime_ns = mtime_ns_of(&file->st);
    const content_type *type = content_type_of(type_path);
    s->type = type->type;
    s->text = type->text;
    if (strcasecmp(extension_of(type_path), "ply") == 0) {
        /* ASCII PLY compresses well; binary PLY hardly at all. */
        char head[128] = {0};
        ssize_t n = pread(s->fd, head, sizeof head - 1, 0);
        if (n > 0 && strstr(head, "format ascii")) {
            s->text = true;
            s->type = "text/plain; charset=utf-8";
        }
    }
    char version[SERVE_VERSION_CHARS];
    version_of(&file->st, version);
    snprintf(s->etag, sizeof s->etag, "\"%s\"", version);
    snprintf(s->cache_key, sizeof s->cache_key, "%s|%s", file->real, version);
    s->st = file->st;
}

/* A source for bytes in memory (takes the reference); the ETag is their CRC. */
static void source_from_blob(source *s, blob *b, const char *type, bool text, const char *key)
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

/* ---- the viewer and the shaders ------------------------------------------ */

static enum MHD_Result serve_web(lk_server *server, struct MHD_Connection *connection, request *r,
                                 const char *relative_raw)
{
    unsigned status = 0;
    char *relative = clean_relative_path(relative_raw, &status);
    if (!relative) return respond_error(connection, r, status, status == 403 ? "forbidden path" : "not found");
    source s;
    if (server->web_root) {
        opened_file file;
        lk_error why = {0};
        status = open_in_root(server->web_root, server->web_root_length, relative, &file, &why);
        if (status) {
            free(relative);
            return respond_error(connection, r, status, "%s", why.message);
        }
        source_from_file(&s, &file, relative);
        opened_close(&file);
    } else {
        size_t size = 0;
        const unsigned char *bytes = lk__web_file(relative, &size);
        if (!bytes) {
            enum MHD_Result result = respond_error(connection, r, 404, "%s: not in the viewer", relative);
            free(relative);
            return result;
        }
        memset(&s, 0, sizeof s);
        s.fd = -1;
        s.persistent = bytes;
        s.size = size;
        const content_type *type = content_type_of(relative);
        s.type = type->type;
        s.text = type->text;
        unsigned long crc = crc32(0L, bytes, (uInt)size);
        snprintf(s.etag, sizeof s.etag, "\"w%lx-%zx\"", crc, size);
        snprintf(s.cache_key, sizeof s.cache_key, "web:%s|%lx|%zu", relative, crc, size);
    }
    free(relative);
    return send_source(server, connection, r, &s);
}

static enum MHD_Result serve_shader(lk_server *server, struct MHD_Connection *connection, request *r,
                                    const char *name)
{
    if (strchr(name, '/') || name[0] == '.' || !*name) return respond_error(connection, r, 404, "no such shader");
    const char *text = lk__shader_source(name);
    if (!text) return respond_error(connection, r, 404, "%s: no such shader", name);
    source s;
    memset(&s, 0, sizeof s);
    s.fd = -1;
    s.persistent = (const unsigned char *)text;
    s.size = strlen(text);
    s.type = "text/plain; charset=utf-8";
    s.text = true;
    unsigned long crc = crc32(0L, (const Bytef *)text, (uInt)s.size);
    snprintf(s.etag, sizeof s.etag, "\"s%lx-%llx\"", crc, (unsigned long long)s.size);
    snprintf(s.cache_key, sizeof s.cache_key, "shader:%s|%lx", name, crc);
    return send_source(server, connection, r, &s);
}

/* ---- simplify on demand ---------------------------------------------------- */

/* Creates the folders of `path` (below the cache folder). The first
 * `trusted` bytes are a path the user gave (--cache DIR, or the served
 * folder): symbolic links there are followed. Below that, an existing
 * component must be a real folder, never a link: a link planted in the
 * served folder (.lodkit-cache -> /elsewhere) must not make the server
 * write streams outside it. */
static lk_status make_directories(const char *path, size_t trusted, lk_error *error)
{
    char *copy = strdup(path);
    if (!copy) return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    size_t length = strlen(copy);
    for (size_t i = 1; i <= length; i++) {
        if (copy[i] != '/' && copy[i] != '\0') continue;
        char saved_char = copy[i];
        copy[i] = '\0';
        struct stat st;
        int failure = 0;
        if (i > trusted && lstat(copy, &st) == 0) {
            if (!S_ISDIR(st.st_mode)) failure = S_ISLNK(st.st_mode) ? ELOOP : ENOTDIR;
        } else if (mkdir(copy, 0755) != 0 && errno != EEXIST) {
            failure = errno;
        }
        if (failure) {
            lk_error_set(error, LK_ERR_IO, "%s: cannot create directory: %s", copy,
                         failure == ELOOP ? "a symbolic link (the cache follows none)" : strerror(failure));
            free(copy);
            return LK_ERR_IO;
        }
        copy[i] = saved_char;
    }
    free(copy);
    return LK_OK;
}

/* Reads a mesh from an opened file: the bytes of that descriptor, named by
 * the path relative to the root; a glTF's external buffers are opened
 * below the file's own (resolved) directory without following links. */
static lk_status read_mesh_opened(lk_server *server, const opened_file *file, lk_mesh *mesh, lk_error *error)
{
    lk_mesh_init(mesh);
    lk_read_options read_options = {.max_bytes = server->options.max_memory};
    unsigned char *data = NULL;
    size_t size = 0;
    lk_status status = read_opened(file, server->options.max_file_bytes, &data, &size, error);
    if (status != LK_OK) return status;
    char *directory = strdup(file->real);
    if (!directory) {
        free(data);
        return lk_error_set(error, LK_ERR_NOMEM, "out of memory");
    }
    char *slash = strrchr(directory, '/');
    if (slash == directory) slash[1] = '\0'; /* a file right under "/" */
    else if (slash) *slash = '\0';
    status = lk__mesh_read_buffer(data, size, file->name, directory, &read_options, mesh, error);
    free(directory);
    free(data);
    return status;
}

/* Makes an error message start with the file's name (relative to the root). */
static void name_in_message(lk_error *error, const char *name)
{
    size_t length = strlen(name);
    if (strncmp(error->message, name, length) == 0 && error->message[length] == ':') return;
    char message[sizeof error->message];
    snprintf(message, sizeof message, "%.200s: %.300s", name, error->message);
    memcpy(error->message, message, sizeof message);
}

/* Progress callback of long builds: cancels them once the server stops. */
static int cancel_when_stopping(void *user, double fraction, const char *stage)
{
    (void)fraction;
    (void)stage;
    lk_server *server = user;
    return atomic_load(&server->stopping);
}

static lk_status build_stream(lk_server *server, const opened_file *input, const char *output, lk_error *error)
{
    lk_mesh mesh;
    lk_progressive_mesh pm;
    lk_progressive_strips strips;
    memset(&pm, 0, sizeof pm);
    memset(&strips, 0, sizeof strips);
    unsigned char *bytes = NULL;
    size_t size = 0;
    lk_progressive_options pm_options;
    lk_progressive_options_default(&pm_options);
    lk_stream_options stream_options;
    lk_stream_options_default(&stream_options);
    lk_status status = read_mesh_opened(server, input, &mesh, error);
    if (status == LK_OK) status = lk_progressive_mesh_build(&mesh, &pm_options, &pm, cancel_when_stopping, server, error);
    if (status == LK_OK) status = lk_progressive_strips_build(&pm, LK_STRIPIFY_BEST, &strips, error);
    if (status == LK_OK) status = lk_stream_encode(&pm, &strips, &stream_options, &bytes, &size, error);
    if (status == LK_OK) {
        char *directory = strdup(output);
        if (!directory) status = lk_error_set(error, LK_ERR_NOMEM, "out of memory");
        else {
            char *slash = strrchr(directory, '/');
            if (slash && slash != directory) {
                *slash = '\0';
                status = make_directories(directory, server->cache_trusted_length, error);
            }
            free(directory);
        }
    }
    if (status == LK_OK) status = lk_stream_write_file(output, bytes, size, error);
    free(bytes);
    lk_progressive_strips_free(&strips);
    lk_progressive_mesh_free(&pm);
    lk_mesh_free(&mesh);
    return status;
}

/* The source mesh of a missing NAME.lks, or 404. */
static unsigned find_stream_source(lk_server *server, const char *relative, opened_file *file, lk_error *why)
{
    size_t length = strlen(relative);
    if (length < 5 || strcasecmp(relative + length - 4, ".lks") != 0) return 404;
    char *candidate = malloc(length + 8);
    if (!candidate) return 500;
    unsigned status = 404;
    for (size_t i = 0; triangle_extensions[i] && status; i++) {
        memcpy(candidate, relative, length - 3);
        strcpy(candidate + length - 3, triangle_extensions[i]);
        status = open_in_root(server->root, server->root_length, candidate, file, why);
        if (status == 403) break;
    }
    free(candidate);
    return status;
}

/* What a cached stream was built from, kept next to it as NAME.lks.source:
 * this lodkit (another version may build other streams) and the source
 * file's name and version (version_of). Any difference rebuilds. */
static void stream_key(const opened_file *input, char *out, size_t size)
{
    char version[SERVE_VERSION_CHARS];
    version_of(&input->st, version);
    snprintf(out, size, "lodkit %s\nsource %s\nversion %s\n", LK_VERSION_STRING, input->name, version);
}

/* Is the cached stream there (non-empty) with this key? Both are opened
 * below the cache directory without following links. */
static bool cached_stream_fresh(const lk_server *server, const char *relative, const char *key_relative,
                                const char *key)
{
    int fd;
    struct stat st;
    lk_error ignored = {0};
    if (lk__open_input(server->cache_dir, relative, &fd, &st, &ignored) != LK_OK) return false;
    close(fd);
    if (st.st_size == 0 || lk__open_input(server->cache_dir, key_relative, &fd, &st, &ignored) != LK_OK) return false;
    char *text = NULL;
    size_t size = 0;
    bool same = lk__read_opened(fd, &st, key_relative, 4096, &text, &size, &ignored) == LK_OK && strcmp(text, key) == 0;
    close(fd);
    free(text);
    return same;
}

static lk_status write_stream_key(const char *path, const char *key, lk_error *error)
{
    lk__atomic_file out;
    lk_status status = lk__atomic_open(&out, path, error);
    if (status != LK_OK) return status;
    if (fputs(key, out.file) == EOF) {
        lk__atomic_abort(&out);
        return lk_error_set(error, LK_ERR_IO, "%s: write error", path);
    }
    return lk__atomic_commit(&out, error);
}

/* Opens (building it first when needed) the cached stream for `relative`.
 * Returns 0 or an HTTP status with a message in error. */
static unsigned open_on_demand_stream(lk_server *server, const char *relative, opened_file *out, lk_error *error)
{
    opened_file input;
    unsigned status = find_stream_source(server, relative, &input, error);
    if (status) return status;
    size_t length = strlen(server->cache_dir) + strlen(relative) + 16;
    char *cached = malloc(length), *key_path = malloc(length);
    char key[PATH_MAX + 256];
    stream_key(&input, key, sizeof key);
    if (!cached || !key_path) {
        free(cached);
        free(key_path);
        opened_close(&input);
        lk_error_set(error, LK_ERR_NOMEM, "out of memory");
        return 500;
    }
    snprintf(cached, length, "%s/%s", server->cache_dir, relative);
    snprintf(key_path, length, "%s.source", cached);
    const char *key_relative = key_path + strlen(server->cache_dir) + 1;
    pthread_mutex_lock(&server->build_lock);
    /* Checked again under the lock: an earlier request may just have built it. */
    if (!cached_stream_fresh(server, relative, key_relative, key)) {
        double start = lk__now();
        lk_status built = build_stream(server, &input, cached, error);
        if (built == LK_OK) built = write_stream_key(key_path, key, error);
        if (built != LK_OK) {
            status = atomic_load(&server->stopping) ? 503 : http_status_of(built);
            name_in_message(error, input.name);
        } else {
            server_log(server, "simplify-on-demand: built %s from %s (%.2f s)", relative, input.name,
                       lk__now() - start);
        }
    }
    pthread_mutex_unlock(&server->build_lock);
    opened_close(&input);
    free(key_path);
    if (status == 0) {
        if (lk__open_input(server->cache_dir, relative, &out->fd, &out->st, error) != LK_OK) {
            lk_error_set(error, LK_ERR_IO, "%s: cannot open the cached stream", relative);
            status = 500;
        } else {
            out->real = cached;
            out->name = cached + strlen(server->cache_dir) + 1;
            cached = NULL;
        }
    }
    free(cached);
    return status;
}

static enum MHD_Result serve_content(lk_server *server, struct MHD_Connection *connection, request *r,
                                     const char *relative_raw)
{
    unsigned status = 0;
    char *relative = clean_relative_path(relative_raw, &status);
    if (!relative) return respond_error(connection, r, status, status == 403 ? "forbidden path" : "not found");
    opened_file file;
    lk_error why = {0};
    status = open_in_root(server->root, server->root_length, relative, &file, &why);
    if (status == 404 && server->options.simplify_on_demand) {
        lk_error build_error = {0};
        unsigned built = open_on_demand_stream(server, relative, &file, &build_error);
        if (built != 404) {
            status = built;
            why = build_error;
        }
    }
    if (status) {
        enum MHD_Result result = respond_error(connection, r, status, "%s", why.message[0] ? why.message : "error");
        free(relative);
        return result;
    }
    source s;
    source_from_file(&s, &file, relative);
    opened_close(&file);
    free(relative);
    return send_source(server, connection, r, &s);
}

/* ---- LKMB buffers ------------------------------------------------------------ */

/* Positions, then normals / colours / radii when present, then indices. */
static blob *lkmb_encode(const lk_mesh *mesh, bool with_normals, bool with_colors, bool with_radii)
{
    size_t v = mesh->vertex_count, t = mesh->triangle_count;
    uint32_t flags = (with_normals && mesh->normals ? 1u : 0u) | (with_colors && mesh->colors ? 2u : 0u) |
                     (with_radii && mesh->radii ? 4u : 0u);
    size_t size = 24 + 12 * v + ((flags & 1) ? 12 * v : 0) + ((flags & 2) ? 4 * v : 0) + ((flags & 4) ? 4 * v : 0) +
                  12 * t;
    unsigned char *data = malloc(size);
    if (!data) return NULL;
    unsigned char *p = data;
    memcpy(p, "LKMB", 4);
    lk__store_u32le(p + 4, 1);
    lk__store_u32le(p + 8, (uint32_t)v);
    lk__store_u32le(p + 12, (uint32_t)t);
    lk__store_u32le(p + 16, flags);
    lk__store_u32le(p + 20, 0);
    p += 24;
    for (size_t i = 0; i < 3 * v; i++, p += 4) lk__store_f32le(p, mesh->positions[i]);
    if (flags & 1)
        for (size_t i = 0; i < 3 * v; i++, p += 4) lk__store_f32le(p, mesh->normals[i]);
    if (flags & 2)
        for (size_t i = 0; i < 4 * v; i++) {
            float c = mesh->colors[i];
            c = c != c ? 0.0f : c < 0 ? 0.0f : c > 1 ? 1.0f : c;
            *p++ = (unsigned char)lrintf(c * 255.0f);
        }
    if (flags & 4)
        for (size_t i = 0; i < v; i++, p += 4) lk__store_f32le(p, mesh->radii[i]);
    for (size_t i = 0; i < 3 * t; i++, p += 4) lk__store_u32le(p, mesh->indices[i]);
    blob *b = blob_wrap(data, size);
    if (!b) free(data);
    return b;
}

/* ---- point sets ---------------------------------------------------------------- */

/* Keeps `keep` of the points, evenly spread over the file order
 * (deterministic); drops the triangles. */
static lk_status subsample_points(lk_mesh *points, size_t keep, lk_error *error)
{
    size_t count = points->vertex_count;
    unsigned flags = (points->normals ? LK_ATTR_NORMALS : 0u) | (points->colors ? LK_ATTR_COLORS : 0u) |
                     (points->radii ? LK_ATTR_RADII : 0u);
    lk_mesh out;
    lk_status status = lk_mesh_alloc(&out, keep, 0, flags, error);
    if (status != LK_OK) return status;
    for (size_t k = 0; k < keep; k++) {
        size_t i = (size_t)((unsigned long long)k * count / keep);
        memcpy(out.positions + 3 * k, points->positions + 3 * i, 3 * sizeof(float));
        if (out.normals) memcpy(out.normals + 3 * k, points->normals + 3 * i, 3 * sizeof(float));
        if (out.colors) memcpy(out.colors + 4 * k, points->colors + 4 * i, 4 * sizeof(float));
        if (out.radii) out.radii[k] = points->radii[i];
    }
    lk_mesh_free(points);
    *points = out;
    return LK_OK;
}

static lk_status point_buffer(lk_server *server, const opened_file *file, size_t max_points, blob **out,
                              lk_error *error)
{
    lk_mesh points;
    lk_status status = read_mesh_opened(server, file, &points, error);
    if (status != LK_OK) return status;
    if (points.vertex_count == 0) {
        lk_mesh_free(&points);
        return lk_error_set(error, LK_ERR_PARSE, "no points");
    }
    /* Points are the vertices; triangles (if any) are not part of a point set. */
    free(points.indices);
    points.indices = NULL;
    points.triangle_count = 0;
    free(points.texcoords);
    points.texcoords = NULL;
    if (points.vertex_count > max_points) status = subsample_points(&points, max_points, error);
    if (status == LK_OK && !points.normals && points.vertex_count >= 3)
        status = lk_points_estimate_normals(&points, 12, error);
    if (status == LK_OK && !points.radii && points.vertex_count >= 2)
        status = lk_points_estimate_radii(&points, 8, 1.0, error);
    if (status == LK_OK) {
        *out = lkmb_encode(&points, true, true, true);
        if (!*out) status = lk_error_set(error, LK_ERR_NOMEM, "out of memory for the point buffer");
    }
    lk_mesh_free(&points);
    return status;
}

static enum MHD_Result serve_points(lk_server *server, struct MHD_Connection *connection, request *r,
                                    const char *relative_raw)
{
    size_t max_points = server->options.max_points;
    const char *max_text = MHD_lookup_connection_value(connection, MHD_GET_ARGUMENT_KIND, "max");
    if (max_text) {
        char *end;
        errno = 0;
        unsigned long long value = strtoull(max_text, &end, 10);
        if (errno || end == max_text || *end || value == 0 || max_text[0] == '-' || value > LK_MAX_ELEMENTS)
            return respond_error(connection, r, 400, "max: '%s' is not a positive count", max_text);
        max_points = (size_t)value;
    }
    unsigned status = 0;
    char *relative = clean_relative_path(relative_raw, &status);
    if (!relative) return respond_error(connection, r, status, status == 403 ? "forbidden path" : "not found");
    opened_file file;
    lk_error why = {0};
    status = open_in_root(server->root, server->root_length, relative, &file, &why);
    if (status) {
        enum MHD_Result result = respond_error(connection, r, status, "%s", why.message);
        free(relative);
        return result;
    }
    char key[PATH_MAX + 160];
    char version[SERVE_VERSION_CHARS];
    version_of(&file.st, version);
    snprintf(key, sizeof key, "points:%s|%s|%zu", file.real, version, max_points);
    blob *buffer = cache_get(&server->cache, key);
    lk_error error = {0};
    if (!buffer) {
        lk_status built = point_buffer(server, &file, max_points, &buffer, &error);
        if (built != LK_OK) {
            name_in_message(&error, file.name);
            enum MHD_Result result = respond_error(connection, r, http_status_of(built), "%s", error.message);
            opened_close(&file);
            free(relative);
            return result;
        }
        cache_put(&server->cache, key, buffer);
    }
    opened_close(&file);
    free(relative);
    source s;
    source_from_blob(&s, buffer, SERVE_MIME_LKMB, false, key);
    return send_source(server, connection, r, &s);
}

/* ---- terrains ---------------------------------------------------------------------- */

/* A grid from the opened, checked descriptor (GDAL formats: GDAL opens the
 * path, which must still be that file), named relative to the root. */
static lk_status read_heightfield(lk_server *server, const opened_file *file, lk_heightfield *field, lk_error *error)
{
    memset(field, 0, sizeof *field);
    lk_dem_options dem_options;
    lk_dem_options_default(&dem_options);
    size_t budget_samples = server->options.max_memory / LK_DEM_BYTES_PER_SAMPLE;
    if (budget_samples < dem_options.max_samples) dem_options.max_samples = budget_samples ? budget_samples : 1;
    return lk__dem_read_opened(file->fd, &file->st, file->real, file->name, &dem_options, field, error);
}

static void terrain_slot_free(terrain_slot *slot)
{
    if (!slot) return;
    lk_terrain_free(slot->terrain);
    pthread_mutex_destroy(&slot->lock);
    free(slot->key);
    free(slot);
}

static void terrain_release(lk_server *server, terrain_slot *slot)
{
    pthread_mutex_lock(&server->terrain_lock);
    slot->users--;
    pthread_mutex_unlock(&server->terrain_lock);
}

/* The cached terrain for a file and options, creating it when needed.
 * Returns 0 or an HTTP status (503 beyond the memory budget) with error set. */
static unsigned terrain_acquire(lk_server *server, const opened_file *file, const lk_terrain_options *options,
                                terrain_slot **out, lk_error *error)
{
    char key[PATH_MAX + 240];
    char version[SERVE_VERSION_CHARS];
    version_of(&file->st, version);
    snprintf(key, sizeof key, "%s|%s|%g|%g|%d", file->real, version, options->resolution, options->error_scale,
             options->morph);
    pthread_mutex_lock(&server->terrain_lock);
    for (int i = 0; i < SERVE_TERRAIN_SLOTS; i++) {
        terrain_slot *slot = server->terrains[i];
        if (slot && strcmp(slot->key, key) == 0) {
            slot->users++;
            slot->last_used = ++server->terrain_clock;
            pthread_mutex_unlock(&server->terrain_lock);
            *out = slot;
            return 0;
        }
    }
    pthread_mutex_unlock(&server->terrain_lock);

    /* Build outside the lock: reading and resampling a grid takes a while. */
    lk_heightfield field, square;
    memset(&square, 0, sizeof square);
    lk_status status = read_heightfield(server, file, &field, error);
    if (status != LK_OK) return http_status_of(status);
    size_t largest = field.width > field.height ? field.width : field.height;
    size_t side = 2;
    while (side < largest) side = 2 * (side - 1) + 1;
    /* about 22 bytes per sample (lk_terrain_create), plus the copies made here */
    double estimate = 24.0 * (double)side * (double)side;
    if (estimate > (double)server->options.terrain_bytes) {
        lk_heightfield_free(&field);
        lk_error_set(error, LK_ERR_LIMIT, "a %zux%zu terrain needs about %.0f MiB, over the %.0f MiB budget", side, side,
                     estimate / 1048576.0, (double)server->options.terrain_bytes / 1048576.0);
        return 503;
    }
    const lk_heightfield *input = &field;
    if (field.width != side || field.height != side) {
        status = lk_heightfield_resample(&field, side, &square, error);
        input = &square;
    }
    lk_terrain *terrain = NULL;
    if (status == LK_OK) status = lk_terrain_create(input, options, &terrain, error);
    lk_heightfield_free(&field);
    lk_heightfield_free(&square);
    if (status != LK_OK) return http_status_of(status);
    terrain_slot *slot = calloc(1, sizeof *slot);
    if (slot) slot->key = strdup(key);
    if (!slot || !slot->key) {
        free(slot);
        lk_terrain_free(terrain);
        lk_error_set(error, LK_ERR_NOMEM, "out of memory");
        return 503;
    }
    pthread_mutex_init(&slot->lock, NULL);
    slot->terrain = terrain;
    lk_terrain_get_info(terrain, &slot->info);
    slot->memory = slot->info.memory_bytes;

    pthread_mutex_lock(&server->terrain_lock);
    for (int i = 0; i < SERVE_TERRAIN_SLOTS; i++) { /* built meanwhile by another request? */
        terrain_slot *other = server->terrains[i];
        if (other && strcmp(other->key, key) == 0) {
            other->users++;
            other->last_used = ++server->terrain_clock;
            pthread_mutex_unlock(&server->terrain_lock);
            terrain_slot_free(slot);
            *out = other;
            return 0;
        }
    }
    /* Evict idle terrains, least recently used first, until it fits. */
    for (;;) {
        int free_index = -1, oldest = -1;
        for (int i = 0; i < SERVE_TERRAIN_SLOTS; i++) {
            terrain_slot *s = server->terrains[i];
            if (!s) free_index = free_index < 0 ? i : free_index;
            else if (s->users == 0 && (oldest < 0 || s->last_used < server->terrains[oldest]->last_used)) oldest = i;
        }
        bool fits = server->terrain_memory + slot->memory <= server->options.terrain_bytes;
        if (fits && free_index >= 0) {
            slot->users = 1;
            slot->last_used = ++server->terrain_clock;
            server->terrains[free_index] = slot;
            server->terrain_memory += slot->memory;
            pthread_mutex_unlock(&server->terrain_lock);
            *out = slot;
            return 0;
        }
        if (oldest < 0) break;
        server->terrain_memory -= server->terrains[oldest]->memory;
        terrain_slot_free(server->terrains[oldest]);
        server->terrains[oldest] = NULL;
    }
    pthread_mutex_unlock(&server->terrain_lock);
    terrain_slot_free(slot);
    lk_error_set(error, LK_ERR_LIMIT, "every terrain slot is busy or the %.0f MiB terrain budget is used",
                 (double)server->options.terrain_bytes / 1048576.0);
    return 503;
}

static bool query_number(struct MHD_Connection *connection, const char *name, double fallback, double *value)
{
    const char *text = MHD_lookup_connection_value(connection, MHD_GET_ARGUMENT_KIND, name);
    if (!text) {
        *value = fallback;
        return true;
    }
    char *end;
    errno = 0;
    *value = strtod(text, &end);
    return !errno && end != text && *end == '\0' && isfinite(*value);
}

static bool query_vector(struct MHD_Connection *connection, const char *name, double out[3])
{
    const char *text = MHD_lookup_connection_value(connection, MHD_GET_ARGUMENT_KIND, name);
    if (!text) return false;
    const char *p = text;
    for (int k = 0; k < 3; k++) {
        char *end;
        errno = 0;
        out[k] = strtod(p, &end);
        if (errno || end == p || !isfinite(out[k])) return false;
        if (k < 2 && *end != ',') return false;
        p = end + 1;
        if (k == 2 && *end) return false;
    }
    return true;
}

static enum MHD_Result serve_terrain(lk_server *server, struct MHD_Connection *connection, request *r,
                                     const char *relative_raw)
{
    size_t length = strlen(relative_raw);
    bool info_only = length > 5 && strcmp(relative_raw + length - 5, "/info") == 0;
    char *trimmed = strdup(relative_raw);
    if (!trimmed) return MHD_NO;
    if (info_only) trimmed[length - 5] = '\0';
    unsigned status = 0;
    char *relative = clean_relative_path(trimmed, &status);
    free(trimmed);
    if (!relative) return respond_error(connection, r, status, status == 403 ? "forbidden path" : "not found");

    lk_terrain_options options;
    lk_terrain_options_default(&options);
    lk_terrain_view view;
    memset(&view, 0, sizeof view);
    double morph = 1;
    enum MHD_Result result;
    if (!query_number(connection, "c", options.error_scale, &options.error_scale) || !(options.error_scale > 0) ||
        !query_number(connection, "C", options.resolution, &options.resolution) || !(options.resolution > 0) ||
        !query_number(connection, "morph", 1, &morph) || (morph != 0 && morph != 1)) {
        free(relative);
        return respond_error(connection, r, 400, "c and C must be positive numbers, morph 0 or 1");
    }
    options.morph = morph != 0;
    if (!info_only) {
        if (!query_vector(connection, "eye", view.eye) || !query_vector(connection, "target", view.target) ||
            !query_number(connection, "fov", 60, &view.fov_y) || !(view.fov_y > 0 && view.fov_y < 180) ||
            !query_number(connection, "aspect", 1.5, &view.aspect) || !(view.aspect > 0) ||
            !query_number(connection, "height", 720, &view.viewport_height) || !(view.viewport_height > 0) ||
            (view.eye[0] == view.target[0] && view.eye[1] == view.target[1] && view.eye[2] == view.target[2])) {
            free(relative);
            return respond_error(connection, r, 400,
                                 "need eye=x,y,z and target=x,y,z (different points); fov in (0,180), "
                                 "aspect > 0, height > 0");
        }
    }
    opened_file file;
    lk_error why = {0};
    status = open_in_root(server->root, server->root_length, relative, &file, &why);
    if (status) {
        result = respond_error(connection, r, status, "%s", why.message);
        free(relative);
        return result;
    }
    lk_error error = {0};
    terrain_slot *slot = NULL;
    status = terrain_acquire(server, &file, &options, &slot, &error);
    if (status) name_in_message(&error, file.name);
    opened_close(&file);
    if (status) {
        result = respond_error(connection, r, status, "%s", error.message);
        free(relative);
        return result;
    }
    free(relative);
    const lk_terrain_info *info = &slot->info;
    if (info_only) {
        double extent_x = (double)(info->size - 1) * info->spacing_x, extent_y = (double)(info->size - 1) * info->spacing_y;
        double relief = info->max_height - info->min_height;
        cJSON *root = cJSON_CreateObject();
        cJSON_AddNumberToObject(root, "size", (double)info->size);
        cJSON_AddNumberToObject(root, "levels", info->levels);
        cJSON_AddNumberToObject(root, "spacing_x", info->spacing_x);
        cJSON_AddNumberToObject(root, "spacing_y", info->spacing_y);
        cJSON_AddNumberToObject(root, "origin_x", info->origin_x);
        cJSON_AddNumberToObject(root, "origin_y", info->origin_y);
        cJSON_AddNumberToObject(root, "min_height", info->min_height);
        cJSON_AddNumberToObject(root, "max_height", info->max_height);
        double center[3] = {info->origin_x + 0.5 * extent_x, info->origin_y + 0.5 * extent_y,
                            0.5 * (info->min_height + info->max_height)};
        cJSON_AddItemToObject(root, "center", cJSON_CreateDoubleArray(center, 3));
        cJSON_AddNumberToObject(root, "radius", 0.5 * sqrt(extent_x * extent_x + extent_y * extent_y + relief * relief));
        char *text = cJSON_PrintUnformatted(root);
        cJSON_Delete(root);
        terrain_release(server, slot);
        return text ? respond_json_text(connection, r, 200, text) : MHD_NO;
    }

    lk_mesh mesh;
    lk_mesh_init(&mesh);
    lk_terrain_stats stats;
    lk_terrain_crack_stats cracks;
    memset(&cracks, 0, sizeof cracks);
    pthread_mutex_lock(&slot->lock);
    lk_status built = lk_terrain_update(slot->terrain, &view, &mesh, &stats, &error);
    if (built == LK_OK) built = lk_terrain_color_mesh(slot->terrain, &mesh, &error);
    if (built == LK_OK) built = lk_terrain_count_cracks(slot->terrain, &mesh, 0, &cracks, &error);
    pthread_mutex_unlock(&slot->lock);
    terrain_release(server, slot);
    blob *buffer = NULL;
    if (built == LK_OK) {
        buffer = lkmb_encode(&mesh, false, true, false);
        if (!buffer) built = lk_error_set(&error, LK_ERR_NOMEM, "out of memory for the terrain mesh");
    }
    lk_mesh_free(&mesh);
    if (built != LK_OK) return respond_error(connection, r, http_status_of(built), "terrain: %s", error.message);
    char header[256];
    snprintf(header, sizeof header, "{\"triangles\":%zu,\"vertices\":%zu,\"cracks\":%zu,\"max_level\":%u,\"ms\":%.3f}",
             stats.triangles, stats.vertices, cracks.cracks, stats.max_level, stats.milliseconds);
    struct MHD_Response *response =
        MHD_create_response_from_buffer_with_free_callback_cls(buffer->size, buffer->data, blob_release, buffer);
    if (!response) {
        blob_release(buffer);
        return MHD_NO;
    }
    MHD_add_response_header(response, MHD_HTTP_HEADER_CONTENT_TYPE, SERVE_MIME_LKMB);
    MHD_add_response_header(response, MHD_HTTP_HEADER_CACHE_CONTROL, "no-store");
    MHD_add_response_header(response, "X-Lodkit-Terrain", header);
    MHD_add_response_header(response, "Access-Control-Expose-Headers", "X-Lodkit-Terrain");
    return queue(connection, r, 200, response, buffer->size);
}

/* ---- the index ------------------------------------------------------------------------ */

typedef struct scanned_file {
    char *relative;
    long long size;
    char version[SERVE_VERSION_CHARS];
} scanned_file;

typedef struct scan_state {
    scanned_file *files;
    size_t count, capacity;
} scan_state;

static bool is_model_name(const char *name)
{
    return has_extension(name, mesh_extensions) || has_extension(name, terrain_extensions) ||
           strcasecmp(extension_of(name), "lks") == 0;
}

static void scan_directory(lk_server *server, const char *relative, unsigned depth, scan_state *state)
{
    size_t length = server->root_length + strlen(relative) + 2;
    char *path = malloc(length);
    if (!path) return;
    snprintf(path, length, "%s%s%s", server->root, relative[0] ? "/" : "", relative);
    DIR *directory = opendir(path);
    free(path);
    if (!directory) return;
    struct dirent *entry;
    while ((entry = readdir(directory)) && state->count < SERVE_MAX_INDEX_FILES) {
        if (entry->d_name[0] == '.') continue;
        size_t child_length = strlen(relative) + strlen(entry->d_name) + 2;
        char *child = malloc(child_length);
        if (!child) break;
        snprintf(child, child_length, "%s%s%s", relative, relative[0] ? "/" : "", entry->d_name);
        struct stat st;
        size_t full_length = server->root_length + child_length + 1;
        char *full = malloc(full_length);
        bool keep = false;
        if (full) {
            snprintf(full, full_length, "%s/%s", server->root, child);
            struct stat link_st;
            if (lstat(full, &link_st) == 0 && stat(full, &st) == 0) {
                if (S_ISLNK(link_st.st_mode)) { /* a link must stay inside the root */
                    char *real = realpath(full, NULL);
                    bool inside = real && inside_root(real, server->root, server->root_length);
                    free(real);
                    if (!inside) st.st_mode = 0;
                }
                if (S_ISDIR(st.st_mode) && depth < SERVE_MAX_INDEX_DEPTH) scan_directory(server, child, depth + 1, state);
                else if (S_ISREG(st.st_mode) && is_model_name(entry->d_name)) keep = true;
            }
            free(full);
        }
        if (keep && state->count == state->capacity) {
            size_t capacity = state->capacity ? 2 * state->capacity : 64;
            scanned_file *grown = lk__realloc_array(state->files, capacity, sizeof *grown);
            if (!grown) keep = false;
            else {
                state->files = grown;
                state->capacity = capacity;
            }
        }
        if (keep) {
            scanned_file *scanned = &state->files[state->count++];
            scanned->relative = child;
            scanned->size = (long long)st.st_size;
            version_of(&st, scanned->version);
        }
        else free(child);
    }
    closedir(directory);
}

static int compare_scanned(const void *a, const void *b)
{
    return strcmp(((const scanned_file *)a)->relative, ((const scanned_file *)b)->relative);
}

/* The index entry of one file (without "stream"), parsing it. */
static cJSON *describe_file(lk_server *server, const scanned_file *scanned)
{
    cJSON *entry = cJSON_CreateObject();
    if (!entry) return NULL;
    const char *slash = strrchr(scanned->relative, '/');
    cJSON_AddStringToObject(entry, "name", slash ? slash + 1 : scanned->relative);
    if (slash) cJSON_AddStringToObject(entry, "path", scanned->relative);
    char *encoded = url_encode_path(scanned->relative);
    char url[PATH_MAX * 3 + 32];
    snprintf(url, sizeof url, "/m/%s", encoded ? encoded : "");
    cJSON_AddStringToObject(entry, "url", url);
    cJSON_AddNumberToObject(entry, "bytes", (double)scanned->size);
    opened_file file;
    lk_error error = {0};
    unsigned status = open_in_root(server->root, server->root_length, scanned->relative, &file, &error);
    if (status) {
        if (!error.message[0]) lk_error_set(&error, LK_ERR_IO, "cannot open (HTTP %u)", status);
    } else if (strcasecmp(extension_of(scanned->relative), "lks") == 0) {
        unsigned char *bytes = NULL;
        size_t size = 0;
        lk_stream_info info;
        lk_stream_chunk_info *chunks = NULL;
        if (read_opened(&file, server->options.max_file_bytes, &bytes, &size, &error) == LK_OK &&
            lk_stream_inspect(bytes, size, &info, &chunks, &error) == LK_OK) {
            cJSON_AddStringToObject(entry, "kind", "stream");
            cJSON_AddNumberToObject(entry, "vertices", (double)info.vertex_count);
            cJSON_AddNumberToObject(entry, "triangles", (double)info.triangle_count);
            cJSON_AddNumberToObject(entry, "base_vertices", (double)info.base_vertex_count);
            cJSON_AddNumberToObject(entry, "base_triangles", (double)info.base_triangle_count);
            cJSON_AddNumberToObject(entry, "splits", (double)info.split_count);
            cJSON_AddNumberToObject(entry, "chunks", (double)info.chunk_count);
        }
        free(chunks);
        free(bytes);
    } else if (has_extension(scanned->relative, mesh_extensions)) {
        lk_mesh mesh;
        if (read_mesh_opened(server, &file, &mesh, &error) == LK_OK) {
            if (mesh.triangle_count > 0) {
                cJSON_AddStringToObject(entry, "kind", "mesh");
                cJSON_AddNumberToObject(entry, "vertices", (double)mesh.vertex_count);
                cJSON_AddNumberToObject(entry, "triangles", (double)mesh.triangle_count);
            } else if (mesh.vertex_count > 0) {
                cJSON_AddStringToObject(entry, "kind", "points");
                cJSON_AddNumberToObject(entry, "points", (double)mesh.vertex_count);
                cJSON_AddBoolToObject(entry, "normals", mesh.normals != NULL);
                cJSON_AddBoolToObject(entry, "radii", mesh.radii != NULL);
                snprintf(url, sizeof url, "/api/points/%s", encoded ? encoded : "");
                cJSON_AddStringToObject(entry, "data", url);
            } else {
                lk_error_set(&error, LK_ERR_PARSE, "no vertices");
            }
            lk_mesh_free(&mesh);
        }
    } else {
        lk_heightfield field;
        if (read_heightfield(server, &file, &field, &error) == LK_OK) {
            cJSON_AddStringToObject(entry, "kind", "terrain");
            cJSON_AddNumberToObject(entry, "width", (double)field.width);
            cJSON_AddNumberToObject(entry, "height", (double)field.height);
            cJSON_AddNumberToObject(entry, "min_height", field.min_height);
            cJSON_AddNumberToObject(entry, "max_height", field.max_height);
            snprintf(url, sizeof url, "/api/terrain/%s", encoded ? encoded : "");
            cJSON_AddStringToObject(entry, "data", url);
            lk_heightfield_free(&field);
        }
    }
    if (!cJSON_GetObjectItemCaseSensitive(entry, "kind")) {
        cJSON_AddStringToObject(entry, "kind", "unknown");
        hide_directories(server, error.message);
        cJSON_AddStringToObject(entry, "error", error.message[0] ? error.message : "unreadable");
    }
    opened_close(&file);
    free(encoded);
    return entry;
}

static void records_free(file_record *records, size_t count)
{
    for (size_t i = 0; i < count; i++) {
        free(records[i].relative);
        cJSON_Delete(records[i].entry);
    }
    free(records);
}

/* The index JSON (a new reference), rebuilt when any listed file changed. */
static blob *index_json(lk_server *server, lk_error *error)
{
    scan_state state = {0};
    scan_directory(server, "", 0, &state);
    qsort(state.files, state.count, sizeof *state.files, compare_scanned);
    /* A signature of what was listed: names and versions. */
    uint64_t signature = 1469598103934665603ull ^ (uint64_t)server->options.simplify_on_demand;
    for (size_t i = 0; i < state.count; i++) {
        for (const char *p = state.files[i].relative; *p; p++) signature = (signature ^ (unsigned char)*p) * 1099511628211ull;
        signature = lk__mix64(signature ^ 0xff);
        for (const char *p = state.files[i].version; *p; p++) signature = (signature ^ (unsigned char)*p) * 1099511628211ull;
        signature = lk__mix64(signature);
    }
    pthread_mutex_lock(&server->index_lock);
    blob *result = NULL;
    if (server->index_json && server->index_signature == signature) {
        result = server->index_json;
        blob_retain(result);
        goto done;
    }
    file_record *records = lk__calloc_array(state.count ? state.count : 1, sizeof *records);
    cJSON *root = cJSON_CreateObject();
    cJSON *models = root ? cJSON_AddArrayToObject(root, "models") : NULL;
    if (!records || !models) {
        free(records);
        cJSON_Delete(root);
        lk_error_set(error, LK_ERR_NOMEM, "out of memory for the index");
        goto done;
    }
    for (size_t i = 0; i < state.count; i++) {
        const scanned_file *f = &state.files[i];
        cJSON *entry = NULL;
        for (size_t k = 0; k < server->record_count && !entry; k++)
            if (strcmp(server->records[k].version, f->version) == 0 &&
                strcmp(server->records[k].relative, f->relative) == 0) {
                entry = server->records[k].entry;
                server->records[k].entry = NULL;
            }
        if (!entry) entry = describe_file(server, f);
        records[i].relative = f->relative;
        memcpy(records[i].version, f->version, sizeof records[i].version);
        records[i].entry = entry;
        state.files[i].relative = NULL; /* moved into records[i] */
        if (!entry) continue;
        cJSON *copy = cJSON_Duplicate(entry, 1);
        if (!copy) continue;
        const cJSON *kind = cJSON_GetObjectItemCaseSensitive(copy, "kind");
        if (cJSON_IsString(kind) && strcmp(kind->valuestring, "mesh") == 0) {
            /* Where the stream of this mesh is: a NAME.lks next to it, or built on demand. */
            const char *relative = records[i].relative;
            size_t length = strlen(relative);
            const char *dot = strrchr(relative, '.');
            size_t stem = dot ? (size_t)(dot - relative) : length;
            char *stream = malloc(stem + 5);
            if (stream) {
                memcpy(stream, relative, stem);
                memcpy(stream + stem, ".lks", 5);
                bool exists = false;
                for (size_t k = 0; k < state.count && !exists; k++) {
                    /* names before i have moved into records already */
                    const char *other = k < i ? records[k].relative : k > i ? state.files[k].relative : NULL;
                    exists = other && strcmp(other, stream) == 0;
                }
                if (exists || server->options.simplify_on_demand) {
                    char *encoded = url_encode_path(stream);
                    if (encoded) {
                        char url[PATH_MAX * 3 + 8];
                        snprintf(url, sizeof url, "/m/%s", encoded);
                        cJSON_AddStringToObject(copy, "stream", url);
                        free(encoded);
                    }
                }
                free(stream);
            }
        }
        cJSON_AddItemToArray(models, copy);
    }
    records_free(server->records, server->record_count);
    server->records = records;
    server->record_count = state.count;
    char *text = cJSON_PrintUnformatted(root);
    cJSON_Delete(root);
    if (!text) {
        lk_error_set(error, LK_ERR_NOMEM, "out of memory for the index");
        goto done;
    }
    blob *fresh = blob_wrap((unsigned char *)text, strlen(text));
    if (!fresh) {
        free(text);
        lk_error_set(error, LK_ERR_NOMEM, "out of memory for the index");
        goto done;
    }
    if (server->index_json) blob_release(server->index_json);
    server->index_json = fresh;
    server->index_signature = signature;
    result = fresh;
    blob_retain(result);
done:
    pthread_mutex_unlock(&server->index_lock);
    for (size_t i = 0; i < state.count; i++) free(state.files[i].relative);
    free(state.files);
    return result;
}

static enum MHD_Result serve_index(lk_server *server, struct MHD_Connection *connection, request *r)
{
    lk_error error = {0};
    blob *json = index_json(server, &error);
    if (!json) return respond_error(connection, r, 503, "index: %s", error.message);
    source s;
    source_from_blob(&s, json, SERVE_MIME_JSON, true, "index");
    return send_source(server, connection, r, &s);
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
    if (!r) return MHD_NO; /* out of memory in uri_logger */
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
        connection_set_waiting(server, connection, false); /* the request deadline is met */
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
            return respond_error(connection, r, 400, "an HTTP/1.1 request needs a Host header");
        }
        if (get_or_head && has_body) {
            snprintf(r->method, sizeof r->method, "%s", method);
            return respond_error(connection, r, 400, "a %s request has no body", method);
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
        return queue(connection, r, 405, response, length);
    }
    if (!r->uri || r->uri[0] != '/') return respond_error(connection, r, 400, "bad request target");
    char *path = decode_path(r->uri);
    if (!path) return respond_error(connection, r, 400, "bad percent-encoding in the path");
    enum MHD_Result result;
    if (strcmp(path, "/") == 0 || strcmp(path, "/index.html") == 0) result = serve_web(server, connection, r, "index.html");
    else if (strncmp(path, "/web/", 5) == 0) result = serve_web(server, connection, r, path + 5);
    else if (strncmp(path, "/shaders/", 9) == 0) result = serve_shader(server, connection, r, path + 9);
    else if (strncmp(path, "/m/", 3) == 0) result = serve_content(server, connection, r, path + 3);
    else if (strcmp(path, "/api/index.json") == 0) result = serve_index(server, connection, r);
    else if (strncmp(path, "/api/points/", 12) == 0) result = serve_points(server, connection, r, path + 12);
    else if (strncmp(path, "/api/terrain/", 13) == 0) result = serve_terrain(server, connection, r, path + 13);
    else if (strstr(path, "/../") || strstr(path, "/./") || (strlen(path) >= 3 && strcmp(path + strlen(path) - 3, "/..") == 0))
        result = respond_error(connection, r, 403, "forbidden path");
    else result = respond_error(connection, r, 404, "no such URL");
    free(path);
    return result;
}

/* ---- start and stop ---------------------------------------------------------------------- */

static void server_free(lk_server *server)
{
    if (!server) return;
    cache_free(&server->cache);
    for (int i = 0; i < SERVE_TERRAIN_SLOTS; i++) terrain_slot_free(server->terrains[i]);
    records_free(server->records, server->record_count);
    if (server->index_json) blob_release(server->index_json);
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
        status = lk_error_set(error, LK_ERR_IO, "%s: cannot resolve the address: %s", server->host, gai_strerror(lookup));
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
        mhd_logger, server, MHD_OPTION_SOCK_ADDR, (struct sockaddr *)&address, MHD_OPTION_CONNECTION_LIMIT,
        (unsigned int)server->options.max_connections, MHD_OPTION_PER_IP_CONNECTION_LIMIT,
        (unsigned int)server->options.max_connections_per_ip, MHD_OPTION_CONNECTION_TIMEOUT,
        (unsigned int)server->options.timeout_seconds, MHD_OPTION_CONNECTION_MEMORY_LIMIT,
        (size_t)server->options.connection_memory, MHD_OPTION_URI_LOG_CALLBACK, uri_logger, server,
        MHD_OPTION_NOTIFY_COMPLETED, request_completed, server, MHD_OPTION_NOTIFY_CONNECTION, connection_notify,
        server, MHD_OPTION_END);
    if (!server->daemon) {
        status = lk_error_set(error, LK_ERR_IO, "cannot listen on %s port %u (in use, or not an address of this machine)",
                              server->host, server->options.port);
        goto fail;
    }
    const union MHD_DaemonInfo *info = MHD_get_daemon_info(server->daemon, MHD_DAEMON_INFO_BIND_PORT);
    server->port = info ? info->port : server->options.port;
    if (pthread_create(&server->watchdog, NULL, watchdog_main, server) != 0) {
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
        MHD_USE_NO_LISTEN_SOCKET | MHD_USE_ERROR_LOG, 0, NULL, NULL, handle_request, server,
        MHD_OPTION_EXTERNAL_LOGGER, mhd_logger, server, MHD_OPTION_CONNECTION_LIMIT,
        (unsigned int)server->options.max_connections, MHD_OPTION_CONNECTION_TIMEOUT,
        (unsigned int)server->options.timeout_seconds, MHD_OPTION_CONNECTION_MEMORY_LIMIT,
        (size_t)server->options.connection_memory, MHD_OPTION_URI_LOG_CALLBACK, uri_logger, server,
        MHD_OPTION_NOTIFY_COMPLETED, request_completed, server, MHD_OPTION_NOTIFY_CONNECTION, connection_notify,
        server, MHD_OPTION_END);
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
            if (n > 0) sent += (size_t)n;
            else if (n < 0 && errno == EINTR) continue;
            else if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) break;
            else sent = size; /* the server closed: the rest is never read */
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
