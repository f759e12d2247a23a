/* SPDX-License-Identifier: MIT */
/* What the server's files (src/serve/) share, private to them: the
 * server's state, a request, an opened file and the source of a response,
 * and what each file offers the files after it. Each layer uses only those
 * before it: cache.c (reference-counted bytes, the memory cache),
 * transport.c (libmicrohttpd's callbacks, connections and the request
 * deadline, paths and opened files, responses with Range, ETag and gzip),
 * models.c (meshes and grids read from opened files, LKMB buffers), the
 * endpoints (endpoint_web.c, endpoint_files.c, endpoint_points.c,
 * endpoint_terrain.c, endpoint_index.c), and server.c (routing, start and
 * stop). serve_internal.h holds the hooks of the tests and the fuzz
 * target. Not installed. */
#ifndef LODKIT_SERVE_SHARED_H
#define LODKIT_SERVE_SHARED_H

#include "internal.h"

#include <cjson/cJSON.h>
#include <limits.h>
#include <microhttpd.h>
#include <pthread.h>
#include <stdatomic.h>
#include <sys/stat.h>

#define SERVE_TERRAIN_SLOTS 4
#define SERVE_VERSION_CHARS 96 /* version_of: five 64-bit numbers in hex */
#define SERVE_MIME_LKMB "application/vnd.lodkit.mesh"
#define SERVE_MIME_LKS "application/vnd.lodkit.stream"
#define SERVE_MIME_JSON "application/json"

typedef struct blob {
    atomic_size_t references;
    size_t size;
    unsigned char *data;
} blob;

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

typedef struct terrain_slot {
    char *key;
    lk_terrain *terrain;
    pthread_mutex_t lock; /* held while the terrain is updated */
    size_t memory;
    int users;
    uint64_t last_used;
    lk_terrain_info info;
} terrain_slot;

/* What the index knows about one file, reused while its version holds. */
typedef struct file_record {
    char *relative;
    char version[SERVE_VERSION_CHARS]; /* version_of the file when it was described */
    cJSON *entry;                      /* the index entry without the "stream" key */
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
    double waiting_since; /* when it began waiting for a request's headers; 0 while one is handled */
    bool dropped;
} connection_state;

struct lk_server {
    struct MHD_Daemon *daemon;
    lk_server_options options;
    bool detached;       /* no socket, no threads (lk__server_start_detached) */
    atomic_int stopping; /* set by lk_server_stop: long work gives up */
    pthread_mutex_t connections_lock;
    pthread_cond_t watchdog_wake;
    connection_state *connections;
    pthread_t watchdog;
    bool watchdog_running, watchdog_stop;
    char *host, *web_dir, *cache_dir; /* owned copies of the option strings */
    char *root;                       /* realpath of the directory */
    size_t root_length;
    size_t cache_trusted_length; /* the part of cache_dir the user named (links followed) */
    char *web_root;              /* realpath of web_dir, or NULL */
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

typedef struct request {
    lk_server *server;
    double start;
    char *uri; /* raw, as received (percent-encoded, with the query) */
    char method[12];
    unsigned status; /* 0 until a response is queued */
    uint64_t bytes;  /* body bytes of the response */
    int responded;
    int headers_seen;
    bool answered_early; /* by uri_logger, before libmicrohttpd parsed the query */
} request;

typedef struct content_type {
    const char *extension;
    const char *type;
    bool text; /* compressible */
} content_type;

/* An opened regular file inside a root. */
typedef struct opened_file {
    int fd;
    struct stat st;
    char *real;       /* resolved absolute path */
    const char *name; /* the path relative to the root (in real), for messages */
} opened_file;

/* Where the bytes of a response come from. */
typedef struct source {
    int fd;                          /* >= 0: a file (the response takes it over) */
    struct stat st;                  /* its fstat when it was opened */
    blob *memory;                    /* or reference-counted bytes (one reference taken over) */
    const unsigned char *persistent; /* or static bytes (compiled in) */
    uint64_t size;
    long long mtime_ns; /* 0: no Last-Modified */
    const char *type;
    bool text;
    char etag[SERVE_VERSION_CHARS + 8]; /* with quotes; empty = none */
    char cache_key[2 * PATH_MAX];       /* gzip cache key: identifies this exact content */
    const char *cache_control;
} source;

/* ---- cache.c ----------------------------------------------------------------- */

/* Takes ownership of data (malloc'ed); one reference for the caller. */
blob *lk__serve_blob_wrap(unsigned char *data, size_t size);
void lk__serve_blob_retain(blob *b);
void lk__serve_blob_release(void *pointer);
/* A new reference to the cached value, or NULL. */
blob *lk__serve_cache_get(memory_cache *cache, const char *key);
/* Stores value under key (the cache takes its own reference); values
 * larger than half the budget are not kept. */
void lk__serve_cache_put(memory_cache *cache, const char *key, blob *value);
void lk__serve_cache_free(memory_cache *cache);

/* ---- transport.c ------------------------------------------------------------- */

/* The request log (options.log), and libmicrohttpd's own messages in it. */
void lk__serve_server_log(const lk_server *server, const char *format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
void lk__serve_mhd_logger(void *user, const char *format, va_list args);

/* libmicrohttpd's callbacks for connections and requests, and the watchdog
 * thread that enforces the request deadline (lk_server_start sets them up). */
void lk__serve_connection_notify(void *user, struct MHD_Connection *connection, void **socket_context,
                                 enum MHD_ConnectionNotificationCode code);
void lk__serve_connection_set_waiting(lk_server *server, struct MHD_Connection *connection, bool waiting);
void *lk__serve_uri_logger(void *user, const char *uri, struct MHD_Connection *connection);
void lk__serve_request_completed(void *user, struct MHD_Connection *connection, void **context,
                                 enum MHD_RequestTerminationCode code);
void *lk__serve_watchdog_main(void *user);

/* Paths: the request's path decoded from the raw URI and checked component
 * by component (NULL with *status 403 or 404), files opened inside the
 * root (0 or an HTTP status with the reason in *why), names and versions. */
char *lk__serve_decode_path(const char *uri);
char *lk__serve_clean_relative_path(const char *path, unsigned *status);
bool lk__serve_inside_root(const char *path, const char *root, size_t root_length);
unsigned lk__serve_open_in_root(const char *root, size_t root_length, const char *relative, opened_file *out,
                                lk_error *why);
void lk__serve_opened_close(opened_file *file);
lk_status lk__serve_read_opened(const opened_file *file, size_t limit, unsigned char **data, size_t *size,
                                lk_error *error);
const char *lk__serve_extension_of(const char *path);
const content_type *lk__serve_content_type_of(const char *path);
char *lk__serve_url_encode_path(const char *path);
void lk__serve_version_of(const struct stat *st, char out[SERVE_VERSION_CHARS]);

/* Responses: every one goes through lk__serve_queue (status and size for
 * the log); errors are JSON {"error": message} with the folders hidden. */
enum MHD_Result lk__serve_queue(struct MHD_Connection *connection, request *r, unsigned status,
                                struct MHD_Response *response, uint64_t body_bytes);
enum MHD_Result lk__serve_respond_json_text(struct MHD_Connection *connection, request *r, unsigned status, char *text);
enum MHD_Result lk__serve_respond_error(struct MHD_Connection *connection, request *r, unsigned status,
                                        const char *format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;
void lk__serve_hide_directories(const lk_server *server, char *message);
unsigned lk__serve_http_status_of(lk_status status);
/* Sends a file or bytes with ETag, Last-Modified, Range and gzip. */
enum MHD_Result lk__serve_send_source(lk_server *server, struct MHD_Connection *connection, request *r, source *s);
void lk__serve_source_from_file(source *s, opened_file *file, const char *type_path);
void lk__serve_source_from_blob(source *s, blob *b, const char *type, bool text, const char *key);

/* ---- models.c ---------------------------------------------------------------- */

/* What the index lists and on-demand streams are built from, by the entry
 * of the file name's extension in the library's format table: a file
 * lk_mesh_read reads (a mesh or point set, frame 0 of an animation), a
 * grid lk_dem_read reads, a .lks stream; the formats whose files a missing
 * NAME.lks is built from (those that hold triangles). */
bool lk__serve_reads_mesh(const char *name);
bool lk__serve_reads_grid(const char *name);
bool lk__serve_is_stream(const char *name);
bool lk__serve_builds_streams_from(const lk_format_info *info);
lk_status lk__serve_read_mesh_opened(lk_server *server, const opened_file *file, lk_mesh *mesh, lk_error *error);
lk_status lk__serve_read_heightfield(lk_server *server, const opened_file *file, lk_heightfield *field,
                                     lk_error *error);
/* Makes an error message start with the file's name (relative to the root). */
void lk__serve_name_in_message(lk_error *error, const char *name);
/* Positions, then normals / colours / radii / clip lines when present, then
 * indices (docs/server.md); clips: NULL or lk_points_estimate_clips's. */
blob *lk__serve_lkmb_encode(const lk_mesh *mesh, bool with_normals, bool with_colors, bool with_radii,
                            const float *clips);

/* ---- the endpoints ----------------------------------------------------------- */

/* Each answers one request for its URL family (server.c routes them). */
enum MHD_Result lk__serve_shader(lk_server *server, struct MHD_Connection *connection, request *r, const char *name);
enum MHD_Result lk__serve_web(lk_server *server, struct MHD_Connection *connection, request *r,
                              const char *relative_raw);
enum MHD_Result lk__serve_content(lk_server *server, struct MHD_Connection *connection, request *r,
                                  const char *relative_raw);
enum MHD_Result lk__serve_points(lk_server *server, struct MHD_Connection *connection, request *r,
                                 const char *relative_raw);
enum MHD_Result lk__serve_terrain(lk_server *server, struct MHD_Connection *connection, request *r,
                                  const char *relative_raw);
void lk__serve_terrain_slot_free(terrain_slot *slot);
void lk__serve_records_free(file_record *records, size_t count);
enum MHD_Result lk__serve_index(lk_server *server, struct MHD_Connection *connection, request *r);

#endif
