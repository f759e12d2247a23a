#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Lays PNG pictures (8-bit RGB or RGBA, as `lodkit render` writes them) side
by side into one sheet: png-sheet.py OUT.png COLUMNS IN.png... Standard
library only; used for the before/after sheets in docs/images."""
import struct
import sys
import zlib


def read_png(path):
    data = open(path, "rb").read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        sys.exit(f"{path}: not a PNG")
    pos, idat, header = 8, b"", None
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    width, height, depth, colour, _, _, interlace = header
    if depth != 8 or colour not in (2, 6) or interlace:
        sys.exit(f"{path}: only 8-bit RGB/RGBA, non-interlaced PNGs")
    channels = 3 if colour == 2 else 4
    raw, stride, rows, previous = zlib.decompress(idat), width * channels, [], bytearray(width * channels)
    for y in range(height):
        kind, line = raw[y * (stride + 1)], bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for x in range(stride):
            left = line[x - channels] if x >= channels else 0
            up, corner = previous[x], previous[x - channels] if x >= channels else 0
            if kind == 1:
                line[x] = (line[x] + left) & 255
            elif kind == 2:
                line[x] = (line[x] + up) & 255
            elif kind == 3:
                line[x] = (line[x] + (left + up) // 2) & 255
            elif kind == 4:
                p = left + up - corner
                pa, pb, pc = abs(p - left), abs(p - up), abs(p - corner)
                line[x] = (line[x] + (left if pa <= pb and pa <= pc else up if pb <= pc else corner)) & 255
        # keep RGB on white (transparent pixels become white)
        rgb = bytearray()
        for x in range(width):
            px = line[x * channels:(x + 1) * channels]
            a = px[3] if channels == 4 else 255
            rgb += bytes((c * a + 255 * (255 - a)) // 255 for c in px[:3])
        rows.append(rgb)
        previous = line
    return width, height, rows


def main():
    out, columns, paths = sys.argv[1], int(sys.argv[2]), sys.argv[3:]
    pictures = [read_png(p) for p in paths]
    cell_w, cell_h = max(p[0] for p in pictures), max(p[1] for p in pictures)
    rows_n = (len(pictures) + columns - 1) // columns
    sheet = [bytearray(b"\xff" * (3 * cell_w * columns)) for _ in range(cell_h * rows_n)]
    for i, (w, h, rows) in enumerate(pictures):
        ox, oy = (i % columns) * cell_w, (i // columns) * cell_h
        for y in range(h):
            sheet[oy + y][3 * ox:3 * (ox + w)] = rows[y]
    raw = b"".join(b"\x00" + bytes(r) for r in sheet)
    chunk = lambda kind, body: struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", cell_w * columns, cell_h * rows_n, 8, 2, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b"")
    open(out + ".tmp", "wb").write(png)
    import os
    os.replace(out + ".tmp", out)


main()
