// SPDX-License-Identifier: MIT
// The version-2 payload decoder as WebAssembly: lodkit's own C decoder
// (src/stream2_decode.c, src/stream2_mesh.c, exported by
// src/wasm/stream2_wasm.c, built into stream2.wasm beside these files).
// Stream2Wasm has Stream2State's interface (web/stream2.js), so web/stream.js
// takes either; the two decode every stream to the same meshes
// (tests/browser/stream2.test.mjs). Why both: a stream is decoded once, and
// JavaScript spends most of that first run before its JIT has optimised the
// decoder (the bunny: 300-500 ms in a Chromium worker on two busy cores,
// against 60-90 ms once warm), while WebAssembly is compiled before the first
// byte arrives (docs/benchmarks.md, "Version 2 in the browser").
// Stream2State stays the reference written from docs/stream-format.md and
// the fallback where WebAssembly or the module is missing.

import { PayloadError, dequantisedPositions } from './stream2.js';

const FIXED_HEADER_SIZE = 96;
const ENOSYS = 52; // WASI's "not supported": the module never does I/O, but C's stdio links the calls

/**
 * Compiles and instantiates the module from `source` (a URL, a Response, or
 * the module's bytes). Resolves to its exports.
 */
export async function loadStream2Wasm(source) {
  let bytes = source;
  if (typeof source === 'string' || source instanceof URL) source = await fetch(source);
  if (typeof Response !== 'undefined' && source instanceof Response) {
    if (!source.ok) throw new Error(`stream2.wasm: HTTP ${source.status}`);
    bytes = await source.arrayBuffer();
  }
  const unsupported = () => ENOSYS;
  const imports = { wasi_snapshot_preview1: new Proxy({}, { get: () => unsupported }) };
  const { instance } = await WebAssembly.instantiate(bytes, imports);
  const exports = instance.exports;
  if (exports._initialize) exports._initialize();
  return exports;
}

/* The NUL-terminated string at `pointer` in the module's memory. */
function cString(exports, pointer) {
  const memory = new Uint8Array(exports.memory.buffer);
  let end = pointer;
  while (memory[end] !== 0) end++;
  return new TextDecoder().decode(memory.subarray(pointer, end));
}

/** A version-2 decoder state running in the module `exports` (loadStream2Wasm). */
export class Stream2Wasm {
  /* `info`: web/stream.js's parsed header; `headerBytes`: its 96 bytes. */
  constructor(exports, info, headerBytes) {
    this.exports = exports;
    this.info = info;
    this.base = info.baseVertexCount;
    const pointer = exports.lkw_alloc(FIXED_HEADER_SIZE);
    new Uint8Array(exports.memory.buffer, pointer, FIXED_HEADER_SIZE).set(headerBytes.subarray(0, FIXED_HEADER_SIZE));
    this.handle = exports.lkw_create(pointer);
    exports.lkw_free(pointer);
    if (!this.handle) throw new PayloadError(cString(exports, exports.lkw_create_error()));
  }

  get level() {
    return this.exports.lkw_level(this.handle);
  }

  /* Decodes one chunk's payload; throws PayloadError (the chunk taken back). */
  decode(payload, chunk) {
    const e = this.exports;
    const pointer = e.lkw_alloc(payload.length);
    if (!pointer) throw new PayloadError(`out of memory for a payload of ${payload.length} bytes`);
    new Uint8Array(e.memory.buffer, pointer, payload.length).set(payload);
    const status = e.lkw_chunk(this.handle, chunk.index, chunk.offset, chunk.index === 0 ? 1 : 0, chunk.splitCount,
      chunk.triangleCount, pointer, payload.length);
    e.lkw_free(pointer);
    if (status !== 0) {
      // web/stream.js names the chunk itself
      const message = cString(e, e.lkw_error(this.handle)).replace(/^chunk \d+ at byte \d+: /, '');
      throw new PayloadError(message);
    }
  }

  decodeBase(payload, chunk) {
    this.decode(payload, chunk);
  }

  applyChunk(payload, chunk) {
    this.decode(payload, chunk);
  }

  /** As Stream2State.levelGeometry: the mesh at `level`, arrays of its own. */
  levelGeometry(level) {
    const e = this.exports;
    const current = this.level;
    if (level > current) level = current;
    if (level < 0) level = 0;
    const triangleCount = e.lkw_build_level(this.handle, level);
    if (triangleCount < 0) throw new PayloadError(`out of memory for level ${level}`);
    const n = this.base + level;
    const memory = e.memory.buffer;
    const quantised = new Int32Array(memory, e.lkw_level_quantised(this.handle), 3 * n).slice();
    const triangles = new Uint32Array(memory, e.lkw_level_corners(this.handle), 3 * triangleCount).slice();
    return { level, vertexCount: n, positions: dequantisedPositions(quantised, n, this.info), triangles, quantised };
  }

  /** Frees the module's memory for this stream. */
  dispose() {
    if (this.handle) this.exports.lkw_destroy(this.handle);
    this.handle = 0;
  }
}
