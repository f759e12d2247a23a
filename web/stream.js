// SPDX-License-Identifier: MIT
// Incremental decoder of lodkit progressive streams (.lks versions 1 and 2),
// written from docs/stream-format.md (the specification) and checked against
// the C decoder (src/stream_decode.c): the same levels, strips, triangles
// and quantised positions. Version 2 payloads are decoded by ./stream2.js;
// this file reads the container both versions share.
//
// Bytes go in with feed() in pieces of any size; every time a chunk is
// complete it is checked (chunk header against the table, CRC-32), inflated
// when stored < raw (a zlib stream: DecompressionStream('deflate'), the
// format the encoder's deflateInit2(..., 15, ...) writes) and applied whole:
// a chunk that fails half-way is rolled back, as in the C decoder.
//
// The decoder keeps the resolved strip r[0..L) (the vertex present at the
// current level that each full-level strip entry stands for) and, per
// present vertex, the list of its entries (head/next threaded through the
// strip, in increasing position), so a split costs the size of its mask.
// Version 2 keeps triangles instead (see ./stream2.js).

import { Stream2State } from './stream2.js';

const MAGIC = [0x89, 0x4c, 0x4b, 0x53, 0x0d, 0x0a, 0x1a, 0x0a];
const FIXED_HEADER_SIZE = 96;
const TABLE_ENTRY_SIZE = 32;
const CHUNK_HEADER_SIZE = 8;
const MAX_DEFLATE_RATIO = 1032;
const MIN_SPLIT_BYTES = 4;
// Version 2: no symbol costs less than about 0.011 bits, so a byte holds
// fewer than 64 splits or base vertices.
const V2_SYMBOLS_PER_BYTE = 64;
const V2_MAX_TRIANGLES_PER_SPLIT = 8;
const MAX_ELEMENTS = 0xfffffff0;
const NONE = 0xffffffff;
const RECENT_SIZE = 32;
const TOKEN_LITERAL = 2 + RECENT_SIZE;

export class StreamError extends Error {
  constructor(message) {
    super(message);
    this.name = 'StreamError';
  }
}

const CRC_TABLE = (() => {
  const table = new Uint32Array(256);
  for (let n = 0; n < 256; n++) {
    let c = n;
    for (let k = 0; k < 8; k++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
    table[n] = c >>> 0;
  }
  return table;
})();

/** zlib's crc32() (ISO-HDLC): crc32("123456789") = 0xcbf43926. */
export function crc32(bytes) {
  let crc = 0xffffffff;
  for (let i = 0; i < bytes.length; i++) crc = CRC_TABLE[(crc ^ bytes[i]) & 0xff] ^ (crc >>> 8);
  return (crc ^ 0xffffffff) >>> 0;
}

const u16 = (b, o) => b[o] | (b[o + 1] << 8);
const u32 = (b, o) => (b[o] | (b[o + 1] << 8) | (b[o + 2] << 16) | (b[o + 3] << 24)) >>> 0;
const u64 = (b, o) => u32(b, o) + u32(b, o + 4) * 4294967296;
const hex = (value) => value.toString(16).padStart(8, '0');

/* Unsigned LEB128. Values above 2^53 cannot be held exactly by a Number:
 * none of the format's fields can be that large, so they are refused. */
function readVarint(bytes, reader, what) {
  let value = 0;
  let scale = 1;
  for (let i = 0; ; i++) {
    if (reader.position >= reader.end) throw new StreamError(`${what} runs past the end of its section`);
    const byte = bytes[reader.position++];
    if (i === 9 && byte > 1) throw new StreamError(`${what} is longer than 64 bits`);
    value += (byte & 0x7f) * scale;
    scale *= 128;
    if (!(byte & 0x80)) break;
  }
  if (value > Number.MAX_SAFE_INTEGER) throw new StreamError(`${what} is too large`);
  return value;
}

const unzigzag = (value) => (value % 2 ? -(value + 1) / 2 : value / 2);

/* floor(numerator / denominator) for non-negative integers below 2^53,
 * exact even where the floating-point quotient rounds up to an integer. */
function floorDiv(numerator, denominator) {
  let quotient = Math.floor(numerator / denominator);
  if (quotient * denominator > numerator) quotient--;
  else if ((quotient + 1) * denominator <= numerator) quotient++;
  return quotient;
}

/** Parses and checks the fixed header (96 bytes). */
export function parseHeader(bytes) {
  for (let i = 0; i < 8; i++)
    if (bytes[i] !== MAGIC[i]) throw new StreamError('header at byte 0: not a lodkit stream (bad magic)');
  const version = u16(bytes, 8);
  if (version !== 1 && version !== 2)
    throw new StreamError(`header at byte 8: unsupported version ${version} (this decoder reads 1 and 2)`);
  const v2 = version === 2;
  const storedCrc = u32(bytes, 92);
  const crc = crc32(bytes.subarray(0, 92));
  if (crc !== storedCrc)
    throw new StreamError(`header at byte 92: CRC-32 mismatch (stored ${hex(storedCrc)}, computed ${hex(crc)})`);
  // Version 2: bits 0..2 name the attributes each vertex carries (normals, texture coordinates, colours);
  // bit 3 says split positions are coded in their ring's frame.
  const flags = u16(bytes, 10);
  if (flags & (v2 ? ~15 : ~0)) throw new StreamError(`header at byte 10: unknown flags 0x${flags.toString(16)}`);
  const view = new DataView(bytes.buffer, bytes.byteOffset, FIXED_HEADER_SIZE);
  const info = {
    version,
    flags: v2 ? flags & 15 : 0,
    headerSize: u32(bytes, 12),
    totalSize: u64(bytes, 16),
    vertexCount: u32(bytes, 24),
    triangleCount: u32(bytes, 28),
    baseVertexCount: u32(bytes, 32),
    baseTriangleCount: u32(bytes, 36),
    splitCount: u32(bytes, 40),
    stripLength: u32(bytes, 44),
    chunkCount: u32(bytes, 48),
    splitsPerChunk: u32(bytes, 52),
    positionBits: bytes[56],
    quantisationMin: [0, 1, 2].map((a) => view.getFloat32(60 + 4 * a, true)),
    quantisationStep: [0, 1, 2].map((a) => view.getFloat32(72 + 4 * a, true)),
    diagonal: view.getFloat64(84, true),
  };
  if (bytes[57] || bytes[58] || bytes[59]) throw new StreamError('header at byte 57: reserved bytes are not zero');
  for (const field of ['vertexCount', 'triangleCount', 'baseVertexCount', 'baseTriangleCount', 'splitCount', 'stripLength'])
    if (info[field] > MAX_ELEMENTS) throw new StreamError(`header: ${field} ${info[field]} is too large`);
  if (info.vertexCount !== info.baseVertexCount + info.splitCount)
    throw new StreamError(`header at byte 24: vertex count ${info.vertexCount} is not base + splits`);
  if (v2 && info.stripLength !== 0)
    throw new StreamError(`header at byte 44: a version-2 stream has no strip (length ${info.stripLength})`);
  const mostTriangles = v2 ? info.baseTriangleCount + V2_MAX_TRIANGLES_PER_SPLIT * info.splitCount
    : Math.max(0, info.stripLength - 2);
  if (info.triangleCount > mostTriangles)
    throw new StreamError(v2 ? 'header at byte 28: more triangles than the base and the splits can make'
      : 'header at byte 28: more triangles than the strip can draw');
  if (info.baseTriangleCount > info.triangleCount)
    throw new StreamError('header at byte 36: base triangle count exceeds the full count');
  if (info.positionBits < 4 || info.positionBits > 24)
    throw new StreamError(`header at byte 56: position bits ${info.positionBits} outside 4..24`);
  if (info.chunkCount < 1) throw new StreamError('header at byte 48: no chunks (the base chunk is required)');
  if (info.headerSize !== FIXED_HEADER_SIZE + TABLE_ENTRY_SIZE * info.chunkCount + 4)
    throw new StreamError(`header at byte 12: header size ${info.headerSize} does not match ${info.chunkCount} chunks`);
  if (info.totalSize < info.headerSize + info.chunkCount * (CHUNK_HEADER_SIZE + 1))
    throw new StreamError('header at byte 16: total size cannot hold the header and the chunks');
  const rawCapacity = info.totalSize * (v2 ? V2_SYMBOLS_PER_BYTE : MAX_DEFLATE_RATIO);
  if (info.splitCount * (v2 ? 1 : MIN_SPLIT_BYTES) > rawCapacity || info.stripLength > rawCapacity ||
      info.baseVertexCount * (v2 ? 1 : 3) > rawCapacity)
    throw new StreamError('header at byte 32: the counts cannot fit in a stream of this size');
  const top = 2 ** info.positionBits - 1;
  for (let a = 0; a < 3; a++) {
    const min = info.quantisationMin[a];
    const step = info.quantisationStep[a];
    if (!Number.isFinite(min) || !Number.isFinite(step) || step < 0 || !Number.isFinite(Math.fround(min + top * step)))
      throw new StreamError(`header at byte ${60 + 4 * a}: quantisation box of axis ${a} is not finite`);
  }
  if (!Number.isFinite(info.diagonal) || info.diagonal < 0)
    throw new StreamError(`header at byte 84: diagonal ${info.diagonal} is not a finite length`);
  info.quantisedMax = top;
  return info;
}

/** Parses and checks the chunk table (its bytes and its CRC). */
export function parseTable(bytes, info) {
  const tableSize = info.chunkCount * TABLE_ENTRY_SIZE;
  const storedCrc = u32(bytes, tableSize);
  const crc = crc32(bytes.subarray(0, tableSize));
  if (crc !== storedCrc)
    throw new StreamError(`chunk table at byte ${FIXED_HEADER_SIZE + tableSize}: CRC-32 mismatch (stored ${hex(storedCrc)}, computed ${hex(crc)})`);
  const chunks = [];
  let expectedOffset = info.headerSize;
  let splits = 0;
  let trianglesBefore = 0;
  for (let i = 0; i < info.chunkCount; i++) {
    const e = i * TABLE_ENTRY_SIZE;
    const where = `chunk table entry ${i} at byte ${FIXED_HEADER_SIZE + e}`;
    const chunk = {
      index: i,
      offset: u64(bytes, e),
      size: u32(bytes, e + 8),
      rawSize: u32(bytes, e + 12),
      firstSplit: u32(bytes, e + 16),
      splitCount: u32(bytes, e + 20),
      triangleCount: u32(bytes, e + 24),
      crc32: u32(bytes, e + 28),
    };
    if (chunk.offset !== expectedOffset) throw new StreamError(`${where}: offset ${chunk.offset}, expected ${expectedOffset}`);
    if (chunk.size <= CHUNK_HEADER_SIZE || chunk.size > info.totalSize - chunk.offset)
      throw new StreamError(`${where}: size ${chunk.size} does not fit in the stream`);
    const stored = chunk.size - CHUNK_HEADER_SIZE;
    if (chunk.rawSize < stored || chunk.rawSize > stored * MAX_DEFLATE_RATIO)
      throw new StreamError(`${where}: raw size ${chunk.rawSize} is impossible for ${stored} stored bytes`);
    if (info.version === 2 && chunk.rawSize !== stored)
      throw new StreamError(`${where}: raw size ${chunk.rawSize}, but version-2 chunks are stored as they are (${stored} bytes)`);
    chunk.compressed = chunk.rawSize > stored;
    if (i === 0) {
      if (chunk.firstSplit !== 0 || chunk.splitCount !== 0) throw new StreamError(`${where}: the base chunk claims splits`);
      if (chunk.triangleCount !== info.baseTriangleCount) throw new StreamError(`${where}: base triangle count disagrees with the header`);
      if (info.version === 1 && info.stripLength + 3 * info.baseVertexCount > chunk.rawSize)
        throw new StreamError(`${where}: raw size cannot hold the base vertices and the strip`);
    } else {
      if (chunk.firstSplit !== splits) throw new StreamError(`${where}: first split ${chunk.firstSplit}, expected ${splits}`);
      if (chunk.splitCount === 0 || chunk.splitCount > info.splitCount - splits)
        throw new StreamError(`${where}: ${chunk.splitCount} splits, but ${info.splitCount - splits} remain`);
      if (info.version === 1 ? chunk.splitCount * MIN_SPLIT_BYTES > chunk.rawSize : chunk.splitCount > V2_SYMBOLS_PER_BYTE * chunk.rawSize)
        throw new StreamError(`${where}: raw size cannot hold its splits`);
      if (chunk.triangleCount < trianglesBefore || chunk.triangleCount > info.triangleCount)
        throw new StreamError(`${where}: ${chunk.triangleCount} triangles is out of order`);
    }
    splits += chunk.splitCount;
    trianglesBefore = chunk.triangleCount;
    expectedOffset = chunk.offset + chunk.size;
    chunks.push(chunk);
  }
  if (expectedOffset !== info.totalSize) throw new StreamError(`chunk table: chunks end at byte ${expectedOffset}, the stream has ${info.totalSize}`);
  if (splits !== info.splitCount) throw new StreamError(`chunk table: chunks hold ${splits} splits, not ${info.splitCount}`);
  if (trianglesBefore !== info.triangleCount) throw new StreamError('chunk table: the last chunk does not reach the full triangle count');
  return chunks;
}

/** Inflates a zlib stream (RFC 1950) of exactly rawSize bytes. */
async function inflate(stored, rawSize) {
  // Written straight into the DecompressionStream: a Blob's stream() would
  // cost a round trip to the browser's blob store per chunk (~0.25 s each in
  // headless Chromium).
  const inflater = new DecompressionStream('deflate');
  const writer = inflater.writable.getWriter();
  const written = writer.write(stored).then(() => writer.close());
  written.catch(() => {}); // errors surface on the reading side
  const out = new Uint8Array(rawSize);
  let length = 0;
  const reader = inflater.readable.getReader();
  for (;;) {
    const { value, done } = await reader.read();
    if (done) break;
    if (length + value.length > rawSize) throw new StreamError(`deflated payload inflates to more than ${rawSize} bytes`);
    out.set(value, length);
    length += value.length;
  }
  if (length !== rawSize) throw new StreamError(`deflated payload inflates to ${length} bytes, not ${rawSize}`);
  return out;
}

/** The decoding state: present vertices, quantised positions, resolved strip. */
class State {
  constructor(info) {
    this.info = info;
    this.base = info.baseVertexCount;
    this.present = 0;
    this.length = info.stripLength;
    this.max = info.quantisedMax;
    this.quantised = null; // Int32Array(3 * vertexCount)
    this.head = null;      // Uint32Array(vertexCount)
    this.count = null;     // Uint32Array(vertexCount)
    this.resolved = null;  // Uint32Array(L)
    this.next = null;      // Uint32Array(L)
    this.triangles = 0;
    this.kept = null;      // p of every applied split
    this.oldPosition = null; // p's position before every applied split (for undo and lower levels)
  }

  drawn(t) {
    const r = this.resolved;
    return r[t] !== r[t + 1] && r[t + 1] !== r[t + 2] && r[t] !== r[t + 2];
  }

  /* r[j] = value, keeping the non-degenerate triangle count exact. */
  setEntry(j, value) {
    if (this.length < 3) {
      this.resolved[j] = value;
      return;
    }
    const first = j >= 2 ? j - 2 : 0;
    const last = j < this.length - 3 ? j : this.length - 3;
    let before = 0;
    let after = 0;
    for (let t = first; t <= last; t++) before += this.drawn(t);
    this.resolved[j] = value;
    for (let t = first; t <= last; t++) after += this.drawn(t);
    this.triangles += after - before;
  }

  decodeBase(payload) {
    const info = this.info;
    const base = this.base;
    const length = this.length;
    const reader = { position: 0, end: payload.length };
    const positionBytes = readVarint(payload, reader, 'position section length');
    if (positionBytes > payload.length - reader.position) throw new StreamError('position section overruns the payload');
    const positions = { position: reader.position, end: reader.position + positionBytes };
    const tokens = { position: positions.end, end: payload.length };
    if (3 * base > positionBytes) throw new StreamError(`${base} base vertices cannot fit in ${positionBytes} position bytes`);
    if (length > tokens.end - tokens.position) throw new StreamError(`a strip of ${length} entries cannot fit in the token bytes`);

    const vertexCount = info.vertexCount;
    this.quantised = new Int32Array(3 * vertexCount);
    this.head = new Uint32Array(vertexCount).fill(NONE);
    this.count = new Uint32Array(vertexCount);
    this.resolved = new Uint32Array(length);
    this.next = new Uint32Array(length);
    this.kept = new Uint32Array(info.splitCount);
    this.oldPosition = new Int32Array(3 * info.splitCount);
    const q = this.quantised;
    const previous = [0, 0, 0];
    for (let v = 0; v < base; v++) {
      for (let a = 0; a < 3; a++) {
        const delta = unzigzag(readVarint(payload, positions, `base vertex ${v}: position varint`));
        const value = previous[a] + delta;
        if (value < 0 || value > this.max) throw new StreamError(`base vertex ${v}: position leaves the quantisation range`);
        q[3 * v + a] = value;
        previous[a] = value;
      }
    }
    if (positions.position !== positions.end) throw new StreamError('unused bytes after the base positions');

    const r = this.resolved;
    const recent = [];
    let literal = 0;
    for (let j = 0; j < length; j++) {
      const token = readVarint(payload, tokens, `strip entry ${j}: token`);
      let v;
      if (token === 0) {
        if (j < 1) throw new StreamError('strip entry 0: token 0 needs a previous entry');
        v = r[j - 1];
      } else if (token === 1) {
        if (j < 2) throw new StreamError(`strip entry ${j}: token 1 needs two previous entries`);
        v = r[j - 2];
      } else {
        if (token < TOKEN_LITERAL) {
          const index = token - 2;
          if (index >= recent.length) throw new StreamError(`strip entry ${j}: recent-list token ${token} names no vertex`);
          v = recent[index];
        } else {
          v = literal + unzigzag(token - TOKEN_LITERAL);
          if (v < 0 || v >= base) throw new StreamError(`strip entry ${j}: literal ${v} is not a base vertex`);
          literal = v;
        }
        // move to front (insert, dropping the oldest when full)
        const at = recent.indexOf(v);
        if (at >= 0) recent.splice(at, 1);
        else if (recent.length === RECENT_SIZE) recent.pop();
        recent.unshift(v);
      }
      r[j] = v;
    }
    if (tokens.position !== tokens.end) throw new StreamError('unused bytes after the base strip');
    for (let j = length - 1; j >= 0; j--) {
      const v = r[j];
      this.next[j] = this.head[v];
      this.head[v] = j;
      this.count[v]++;
    }
    let triangles = 0;
    for (let t = 0; t + 2 < length; t++) triangles += this.drawn(t);
    this.triangles = triangles;
    this.present = base;
  }

  /* Moves the entries of p picked by the mask to q = present. */
  splitEntries(kept, mask, maskOffset) {
    const q = this.present;
    const candidates = this.count[kept];
    const next = this.next;
    let pTail = -1; // -1: head[kept], else next[pTail]
    let qTail = -1;
    let entry = this.head[kept];
    let moved = 0;
    for (let bit = 0; bit < candidates; bit++) {
      const following = next[entry];
      if ((mask[maskOffset + (bit >> 3)] >> (bit & 7)) & 1) {
        if (qTail < 0) this.head[q] = entry;
        else next[qTail] = entry;
        qTail = entry;
        this.setEntry(entry, q);
        moved++;
      } else {
        if (pTail < 0) this.head[kept] = entry;
        else next[pTail] = entry;
        pTail = entry;
      }
      entry = following;
    }
    if (pTail < 0) this.head[kept] = NONE;
    else next[pTail] = NONE;
    if (qTail < 0) this.head[q] = NONE;
    else next[qTail] = NONE;
    this.count[kept] = candidates - moved;
    this.count[q] = moved;
    this.present++;
  }

  /* Takes back the last split: q's entries merge into p's list again. */
  undoSplit(kept, oldPosition) {
    const q = this.present - 1;
    const next = this.next;
    let a = this.head[kept];
    let b = this.head[q];
    let tail = -1;
    const link = (entry) => {
      if (tail < 0) this.head[kept] = entry;
      else next[tail] = entry;
      tail = entry;
    };
    while (a !== NONE || b !== NONE) {
      if (b === NONE || (a !== NONE && a < b)) {
        link(a);
        a = next[a];
      } else {
        const following = next[b];
        link(b);
        this.setEntry(b, kept);
        b = following;
      }
    }
    if (tail < 0) this.head[kept] = NONE;
    else next[tail] = NONE;
    this.count[kept] += this.count[q];
    this.count[q] = 0;
    this.head[q] = NONE;
    for (let a2 = 0; a2 < 3; a2++) this.quantised[3 * kept + a2] = oldPosition[a2];
    this.present--;
  }

  /* Mean of the other corners of the triangles drawn around v, rounded half up. */
  ringCentroid(v, fallbackVertex, out) {
    let s0 = 0, s1 = 0, s2 = 0, corners = 0;
    const length = this.length;
    const r = this.resolved;
    const q = this.quantised;
    if (length >= 3) {
      for (let j = this.head[v]; j !== NONE; j = this.next[j]) {
        const first = j >= 2 ? j - 2 : 0;
        const last = j < length - 3 ? j : length - 3;
        for (let t = first; t <= last; t++) {
          if (!this.drawn(t)) continue;
          for (let c = t; c < t + 3; c++) {
            const w = r[c];
            if (w === v) continue;
            s0 += q[3 * w];
            s1 += q[3 * w + 1];
            s2 += q[3 * w + 2];
            corners++;
          }
        }
      }
    }
    if (corners) {
      out[0] = floorDiv(2 * s0 + corners, 2 * corners);
      out[1] = floorDiv(2 * s1 + corners, 2 * corners);
      out[2] = floorDiv(2 * s2 + corners, 2 * corners);
    } else {
      out[0] = q[3 * fallbackVertex];
      out[1] = q[3 * fallbackVertex + 1];
      out[2] = q[3 * fallbackVertex + 2];
    }
  }

  readPosition(payload, reader, predicted, split, what, target) {
    for (let a = 0; a < 3; a++) {
      const delta = unzigzag(readVarint(payload, reader, `split ${split}: ${what} position varint`));
      const value = predicted[a] + delta;
      if (value < 0 || value > this.max)
        throw new StreamError(`split ${split}: ${what} position delta ${delta} leaves the quantisation range 0..${this.max}`);
      target[a] = value;
    }
  }

  /* Applies one split chunk whole, or rolls it back and throws. */
  applyChunk(payload, chunk) {
    const level = this.present - this.base;
    if (level !== chunk.firstSplit) throw new StreamError(`starts at split ${chunk.firstSplit} but the decoder is at level ${level}`);
    const trianglesBefore = this.triangles;
    let applied = 0;
    try {
      const reader = { position: 0, end: payload.length };
      const pBytes = readVarint(payload, reader, 'section length');
      const maskBytes = readVarint(payload, reader, 'section length');
      const rest = payload.length - reader.position;
      if (pBytes > rest || maskBytes > rest - pBytes) throw new StreamError('sections overrun the payload');
      const pReader = { position: reader.position, end: reader.position + pBytes };
      const maskReader = { position: pReader.end, end: pReader.end + maskBytes };
      const positionReader = { position: maskReader.end, end: payload.length };
      const predicted = [0, 0, 0];
      const ring = [0, 0, 0];
      const position = [0, 0, 0];
      const q = this.quantised;
      for (let i = 0; i < chunk.splitCount; i++) {
        const split = level + i;
        const code = readVarint(payload, pReader, `split ${split}: p varint`);
        const kept = Math.floor(code / 2);
        const moved = code % 2 === 1;
        if (kept >= this.present) throw new StreamError(`split ${split}: p = ${kept} is not a present vertex (${this.present} present)`);
        const candidates = this.count[kept];
        const maskLength = (candidates + 7) >> 3;
        if (maskLength > maskReader.end - maskReader.position) throw new StreamError(`split ${split}: the mask runs past the mask section`);
        const maskOffset = maskReader.position;
        if ((candidates & 7) && (payload[maskOffset + maskLength - 1] >> (candidates & 7)))
          throw new StreamError(`split ${split}: padding bits of the mask are not zero`);
        maskReader.position += maskLength;

        const newVertex = this.present;
        this.kept[split] = kept;
        for (let a = 0; a < 3; a++) this.oldPosition[3 * split + a] = q[3 * kept + a];
        this.splitEntries(kept, payload, maskOffset);
        applied = i + 1;

        // q: (3 ring(q) + p + 2) / 4, p still at its old position
        this.ringCentroid(newVertex, kept, ring);
        for (let a = 0; a < 3; a++) predicted[a] = Math.floor((3 * ring[a] + q[3 * kept + a] + 2) / 4);
        this.readPosition(payload, positionReader, predicted, split, 'q', position);
        for (let a = 0; a < 3; a++) q[3 * newVertex + a] = position[a];
        if (moved) {
          // p: (3 p + ring(p) + 2) / 4, once q has its position
          this.ringCentroid(kept, kept, ring);
          for (let a = 0; a < 3; a++) predicted[a] = Math.floor((3 * q[3 * kept + a] + ring[a] + 2) / 4);
          this.readPosition(payload, positionReader, predicted, split, 'p', position);
          for (let a = 0; a < 3; a++) q[3 * kept + a] = position[a];
        }
      }
      if (pReader.position !== pReader.end || maskReader.position !== maskReader.end || positionReader.position !== positionReader.end)
        throw new StreamError('unused bytes after the last split');
      if (this.triangles !== chunk.triangleCount)
        throw new StreamError(`the strip draws ${this.triangles} triangles after the chunk, the table says ${chunk.triangleCount}`);
    } catch (error) {
      for (let i = applied; i-- > 0;) {
        const split = level + i;
        this.undoSplit(this.kept[split], this.oldPosition.subarray(3 * split, 3 * split + 3));
      }
      this.triangles = trianglesBefore;
      throw error;
    }
  }
}

/**
 * The incremental decoder. `onChunk(decoder, chunk)` runs after every chunk
 * is applied (chunk.index 0 = the base mesh); it may be async.
 */
export class StreamDecoder {
  /*
   * onInfo(decoder) once the header and chunk table are in, onChunk(decoder,
   * chunk) after each chunk; createStream2(info, headerBytes), when given,
   * makes the version-2 decoder state (web/stream2_wasm.js's Stream2Wasm)
   * instead of web/stream2.js's Stream2State.
   */
  constructor({ onInfo = null, onChunk = null, createStream2 = null } = {}) {
    this.onInfo = onInfo;
    this.onChunk = onChunk;
    this.createStream2 = createStream2;
    this.headerBytes = null;
    this.phase = 'header';
    this.pending = new Uint8Array(0);
    this.pendingLength = 0;
    this.received = 0;
    this.info = null;
    this.chunks = null;
    this.nextChunk = 0;
    this.state = null;
    this.error = null;
    this.decodeMilliseconds = 0;
  }

  get level() {
    if (!this.state) return 0;
    if (this.info.version === 2) return this.state.level;
    return this.state.present ? this.state.present - this.state.base : 0;
  }

  /** The stream's version (1 or 2), 0 before the header has arrived. */
  get version() {
    return this.info ? this.info.version : 0;
  }

  get done() {
    return this.phase === 'done';
  }

  /* Bytes of the unit being waited for. */
  unitSize() {
    if (this.phase === 'header') return FIXED_HEADER_SIZE;
    if (this.phase === 'table') return this.info.headerSize - FIXED_HEADER_SIZE;
    if (this.phase === 'chunks') return this.chunks[this.nextChunk].size;
    return 0;
  }

  /** Feeds the next bytes of the stream (any size). */
  async feed(bytes) {
    if (this.error) throw this.error;
    try {
      let offset = 0;
      while (offset < bytes.length) {
        if (this.phase === 'done') throw new StreamError(`byte ${this.received}: data after the end of the stream`);
        const unit = this.unitSize();
        const take = Math.min(unit - this.pendingLength, bytes.length - offset);
        let unitBytes;
        if (this.pendingLength === 0 && take === unit) {
          unitBytes = bytes.subarray(offset, offset + take);
        } else {
          if (this.pending.length < unit) {
            const grown = new Uint8Array(Math.max(unit, 2 * this.pending.length));
            grown.set(this.pending.subarray(0, this.pendingLength));
            this.pending = grown;
          }
          this.pending.set(bytes.subarray(offset, offset + take), this.pendingLength);
          this.pendingLength += take;
          unitBytes = this.pending.subarray(0, this.pendingLength);
        }
        this.received += take;
        offset += take;
        if (this.phase === 'header') {
          const known = Math.min(unitBytes.length, 8);
          for (let i = 0; i < known; i++)
            if (unitBytes[i] !== MAGIC[i]) throw new StreamError('header at byte 0: not a lodkit stream (bad magic)');
        }
        if (unitBytes.length < unit) break;
        // The unit is complete: copy it if it lives in the pending buffer,
        // which the next unit reuses while an async step is under way.
        const complete = unitBytes.buffer === this.pending.buffer ? unitBytes.slice() : unitBytes;
        this.pendingLength = 0;
        await this.processUnit(complete);
      }
    } catch (error) {
      this.error = error instanceof StreamError ? error : new StreamError(String(error && error.message || error));
      this.phase = 'failed';
      throw this.error;
    }
  }

  async processUnit(bytes) {
    if (this.phase === 'header') {
      this.info = parseHeader(bytes);
      this.headerBytes = bytes.slice(0, FIXED_HEADER_SIZE);
      this.phase = 'table';
      return;
    }
    if (this.phase === 'table') {
      this.chunks = parseTable(bytes, this.info);
      this.phase = 'chunks';
      if (this.onInfo) await this.onInfo(this);
      return;
    }
    const chunk = this.chunks[this.nextChunk];
    const where = `chunk ${chunk.index} at byte ${chunk.offset}`;
    try {
      const stored = bytes.length - CHUNK_HEADER_SIZE;
      if (u32(bytes, 0) !== stored || u32(bytes, 4) !== chunk.crc32)
        throw new StreamError('chunk header disagrees with the table');
      const data = bytes.subarray(CHUNK_HEADER_SIZE);
      const crc = crc32(data);
      if (crc !== chunk.crc32) throw new StreamError(`CRC-32 mismatch (stored ${hex(chunk.crc32)}, computed ${hex(crc)})`);
      let payload = data;
      if (chunk.compressed) {
        try {
          payload = await inflate(data, chunk.rawSize);
        } catch (error) {
          throw new StreamError(`deflated payload is corrupt (${error.message})`);
        }
      }
      const start = performance.now();
      if (this.info.version === 2) {
        if (chunk.index === 0) {
          const state = this.createStream2 ? this.createStream2(this.info, this.headerBytes) : new Stream2State(this.info);
          try {
            state.decodeBase(payload, chunk);
          } catch (error) {
            if (state.dispose) state.dispose(); // the module's memory for it
            throw error;
          }
          this.state = state;
        } else {
          this.state.applyChunk(payload, chunk);
        }
      } else if (chunk.index === 0) {
        const state = new State(this.info);
        state.decodeBase(payload);
        if (state.triangles !== chunk.triangleCount)
          throw new StreamError(`the base strip draws ${state.triangles} triangles, the table says ${chunk.triangleCount}`);
        this.state = state;
      } else {
        this.state.applyChunk(payload, chunk);
      }
      this.decodeMilliseconds += performance.now() - start;
    } catch (error) {
      throw new StreamError(`${where}: ${error.message}`);
    }
    this.nextChunk++;
    if (this.nextChunk === this.info.chunkCount) this.phase = 'done';
    if (this.onChunk) await this.onChunk(this, chunk);
  }

  /** Releases the decoder state's memory (the WebAssembly module's, for Stream2Wasm); the decoder is spent. */
  dispose() {
    if (this.state && this.state.dispose) this.state.dispose();
    this.state = null;
    this.error = this.error || new StreamError('the decoder was disposed');
    this.phase = 'failed';
  }

  /** Bytes of the stream up to the end of chunk `index` (the base: 0). */
  chunkEnd(index) {
    const chunk = this.chunks[index];
    return chunk.offset + chunk.size;
  }

  /**
   * The mesh at `level` (<= the decoded level): dequantised positions of its
   * n = base + level vertices (Float32Array) and, for version 1, its
   * resolved strip (`strip`: Uint32Array, full length, entries < n), for
   * version 2 its triangles (`triangles`: Uint32Array, 3 corners each).
   * Lower levels undo the later splits: each entry maps to its ancestor,
   * moved p's get their old places (version 2: from the split log).
   */
  levelGeometry(level) {
    const state = this.state;
    if (this.info.version === 2) return state.levelGeometry(level);
    const info = this.info;
    const current = state.present - state.base;
    if (level > current) level = current;
    if (level < 0) level = 0;
    const n = state.base + level;
    const quantised = state.quantised.slice(0, 3 * state.present);
    for (let split = current - 1; split >= level; split--) {
      const p = state.kept[split];
      for (let a = 0; a < 3; a++) quantised[3 * p + a] = state.oldPosition[3 * split + a];
    }
    let strip = state.resolved;
    if (level < current) {
      const ancestor = new Uint32Array(state.present);
      for (let v = 0; v < n; v++) ancestor[v] = v;
      for (let v = n; v < state.present; v++) ancestor[v] = ancestor[state.kept[v - state.base]];
      strip = new Uint32Array(state.length);
      for (let j = 0; j < state.length; j++) strip[j] = ancestor[state.resolved[j]];
    }
    const positions = new Float32Array(3 * n);
    const min = info.quantisationMin;
    const step = info.quantisationStep;
    for (let v = 0; v < n; v++)
      for (let a = 0; a < 3; a++) positions[3 * v + a] = Math.fround(min[a] + quantised[3 * v + a] * step[a]);
    return { level, vertexCount: n, positions, strip, quantised: quantised.subarray(0, 3 * n) };
  }
}
