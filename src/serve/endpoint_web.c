/* SPDX-License-Identifier: MIT */
/* The viewer (web/, compiled in, or --web DIR) and the GLSL ES shaders
 * the renderer uses too. */
#include "serve_shared.h"

#include <stdlib.h>
#include <string.h>
#include <zlib.h>

/* Generated at build time (cmake/embed_shaders.cmake, cmake/embed_web.cmake). */
const char *lk__serve_shader_source(const char *name);
const unsigned char *lk__web_file(const char *name, size_t *size);

/* ---- the viewer and the shaders ------------------------------------------ */

enum MHD_Result lk__serve_web(lk_server *server, struct MHD_Connection *connection, request *r,
                              const char *relative_raw)
{
    unsigned status = 0;
    char *relative = lk__serve_clean_relative_path(relative_raw, &status);
    if (!relative)
        return lk__serve_respond_error(connection, r, status, status == 403 ? "forbidden path" : "not found");
    source s;
    bool embedded = !server->web_root;
    if (server->web_root) {
        opened_file file;
        lk_error why = {0};
        status = lk__serve_open_in_root(server->web_root, server->web_root_length, relative, &file, &why);
        size_t size = 0;
        if (status == 404 && strcmp(relative, "stream2.wasm") == 0 && lk__web_file(relative, &size)) {
            /* made by the build, not a file of web/: the compiled-in copy */
            embedded = true;
        } else if (status) {
            free(relative);
            return lk__serve_respond_error(connection, r, status, "%s", why.message);
        } else {
            lk__serve_source_from_file(&s, &file, relative);
            lk__serve_opened_close(&file);
        }
    }
    if (embedded) {
        size_t size = 0;
        const unsigned char *bytes = lk__web_file(relative, &size);
        if (!bytes) {
            enum MHD_Result result = lk__serve_respond_error(connection, r, 404, "%s: not in the viewer", relative);
            free(relative);
            return result;
        }
        memset(&s, 0, sizeof s);
        s.fd = -1;
        s.persistent = bytes;
        s.size = size;
        const content_type *type = lk__serve_content_type_of(relative);
        s.type = type->type;
        s.text = type->text;
        unsigned long crc = crc32(0L, bytes, (uInt)size);
        snprintf(s.etag, sizeof s.etag, "\"w%lx-%zx\"", crc, size);
        snprintf(s.cache_key, sizeof s.cache_key, "web:%s|%lx|%zu", relative, crc, size);
    }
    free(relative);
    return lk__serve_send_source(server, connection, r, &s);
}

enum MHD_Result lk__serve_shader(lk_server *server, struct MHD_Connection *connection, request *r, const char *name)
{
    if (strchr(name, '/') || name[0] == '.' || !*name)
        return lk__serve_respond_error(connection, r, 404, "no such shader");
    const char *text = lk__serve_shader_source(name);
    if (!text) return lk__serve_respond_error(connection, r, 404, "%s: no such shader", name);
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
    return lk__serve_send_source(server, connection, r, &s);
}
