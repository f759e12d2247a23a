/* SPDX-License-Identifier: MIT */
/* The CRC-32 of stream chunks and headers, by zlib (the browser build of the
 * version-2 decoder, src/wasm/stream2_wasm.c, has its own). */
#include "stream_internal.h"

#include <zlib.h>

uint32_t lk__lks_crc32(const unsigned char *bytes, size_t size)
{
    /* zlib's crc32 takes uInt lengths: feed large buffers in pieces. */
    uLong crc = crc32(0L, Z_NULL, 0);
    while (size > 0) {
        uInt piece = size > (size_t)1 << 30 ? (uInt)1 << 30 : (uInt)size;
        crc = crc32(crc, bytes, piece);
        bytes += piece;
        size -= piece;
    }
    return (uint32_t)crc;
}
