/* SPDX-License-Identifier: MIT */
/* Errors and checked allocation: what every part of the library needs and
 * nothing else, so that the stream decoder can be built without the rest
 * (src/wasm/stream2_wasm.c, for the browser). The other shared helpers are
 * in util.c. */
#include "internal.h"

#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

void lk_error_clear(lk_error *error)
{
    if (!error) return;
    error->status = LK_OK;
    error->message[0] = '\0';
}

lk_status lk_error_set(lk_error *error, lk_status status, const char *format, ...)
{
    if (error) {
        va_list args;
        va_start(args, format);
        vsnprintf(error->message, sizeof error->message, format, args);
        va_end(args);
        error->status = status;
    }
    return status;
}

const char *lk_status_string(lk_status status)
{
    switch (status) {
    case LK_OK: return "ok";
    case LK_ERR_IO: return "i/o error";
    case LK_ERR_PARSE: return "parse error";
    case LK_ERR_RANGE: return "value out of range";
    case LK_ERR_LIMIT: return "size limit exceeded";
    case LK_ERR_NOMEM: return "out of memory";
    case LK_ERR_INVALID: return "invalid argument";
    case LK_ERR_UNSUPPORTED: return "unsupported";
    case LK_ERR_TRUNCATED: return "truncated input";
    }
    return "unknown error";
}

/* ---- allocation -------------------------------------------------------- */

/* The buffers lodkit hands to its caller come from malloc; releasing them
 * here, in the library, keeps that true when the program uses another
 * allocator or C runtime. */
void lk_free(void *pointer) { free(pointer); }

void *lk__malloc_array(size_t count, size_t size)
{
    if (size && count > SIZE_MAX / size) return NULL;
    size_t bytes = count * size;
    return malloc(bytes ? bytes : 1);
}

void *lk__calloc_array(size_t count, size_t size)
{
    if (size && count > SIZE_MAX / size) return NULL;
    if (count == 0 || size == 0) return calloc(1, 1);
    return calloc(count, size);
}

void *lk__realloc_array(void *ptr, size_t count, size_t size)
{
    if (size && count > SIZE_MAX / size) return NULL;
    size_t bytes = count * size;
    return realloc(ptr, bytes ? bytes : 1);
}
