// SPDX-License-Identifier: MIT
// The progressive-stream decoder off the page's thread: a module Worker that
// runs web/stream.js (versions 1 and 2) on the bytes the page fetches and
// posts back, after each chunk (or the latest of chunks decoded back to
// back), the geometry to draw, every array in a
// transferable ArrayBuffer (moved, not copied): positions, face-averaged
// normals, and the indices (version 2: triangles; version 1: the
// DTFS-filtered strip), 16-bit when the vertices allow it. The page's thread
// only uploads them, so refinement never blocks it (web/mesh_view.js).
//
// Messages in:  {type: 'bytes', id, bytes: Uint8Array}  the next bytes of the stream
//               {type: 'level', level}                  the level to show (-1: the latest)
// Messages out: {type: 'info', info, chunks}            header and chunk table
//               {type: 'fed', id, state}  /  {type: 'failed', id, message, state}
//               {type: 'geometry', state, chunk, geometry}  after a chunk (at most every
//                                                         100 ms while chunks decode back to back) or a level request

import { StreamDecoder } from './stream.js';
import { Stream2State } from './stream2.js';
import { loadStream2Wasm, Stream2Wasm } from './stream2_wasm.js';
import { stripFilter, stripFilterBound, stripTriangleCount } from './strips.js';
import { faceAveragedNormals } from './gl.js';

// Version-2 payloads are decoded by lodkit's C decoder built as WebAssembly
// (stream2.wasm, which `lodkit serve` serves beside this file), compiled
// here while the first bytes are on their way: a stream is decoded once, and
// JavaScript would spend most of that run before its JIT has optimised the
// decoder. web/stream2.js decodes instead where WebAssembly or the module is
// missing, when the worker's URL asks for it (?decoder=js), or when the
// module is not ready WASM_WAIT_MILLISECONDS after the stream's first bytes:
// on a slow link its 27 KB (gzipped) would delay the first frame, and there
// JavaScript keeps up with the bytes anyway (?decoder=wasm waits for it).
const WASM_WAIT_MILLISECONDS = 100;
const wantedDecoder = new URL(import.meta.url).searchParams.get('decoder');
const wantsJs = wantedDecoder === 'js';
let wasm = null;
let wasmDecided = false; // the first bytes came: this stream's decoder is chosen
const wasmReady = wantsJs || typeof WebAssembly !== 'object' ? Promise.resolve(null)
  : loadStream2Wasm(new URL('./stream2.wasm', import.meta.url)).catch(() => null);

let wanted = -1; // -1: follow the latest decoded level
let shown = -1;  // the level last posted
let busyMilliseconds = 0; // everything this worker did: checks, inflating, decoding, geometry
let geometryMilliseconds = 0;
let filtered = new Uint32Array(0);

// Intermediate levels at most this often while chunks decode back to back
// (a fast link: several chunks per message): each costs a pass over the
// whole mesh here (normals, indices) and an upload on the page's thread.
// The base level, the last one and the level reached when a message's bytes
// are used up are always posted, so a slow link still sees every chunk.
const REFRESH_MILLISECONDS = 100;
let lastPost = -Infinity;

/* The latest level, or the one asked for once it has arrived. */
const levelToShow = (d) => (wanted < 0 ? d.level : Math.min(wanted, d.level));

const decoder = new StreamDecoder({
  createStream2: (info, headerBytes) => (wasm ? new Stream2Wasm(wasm, info, headerBytes) : new Stream2State(info)),
  onInfo: (d) => {
    self.postMessage({ type: 'info', info: d.info, chunks: d.chunks });
  },
  onChunk: (d, chunk) => {
    const level = levelToShow(d);
    if (level === shown) return;
    if (chunk.index === 0 || d.done || performance.now() - lastPost >= REFRESH_MILLISECONDS) post(level, chunk.index);
  },
});

function snapshot() {
  return {
    received: decoder.received,
    level: decoder.level,
    done: decoder.done,
    version: decoder.version,
    chunksDecoded: decoder.nextChunk,
    decoder: decoder.version === 2 ? (wasm ? 'wasm' : 'js') : decoder.version ? 'js' : '',
    decodeMs: decoder.decodeMilliseconds,
    geometryMs: geometryMilliseconds,
    workerMs: busyMilliseconds,
  };
}

/* Indices in the narrowest type WebGL 1 draws without an extension when it can. */
function narrowed(indices, length, vertexCount) {
  if (vertexCount > 65536) return indices.slice(0, length);
  const out = new Uint16Array(length);
  for (let i = 0; i < length; i++) out[i] = indices[i];
  return out;
}

/* The geometry of `level`, built here and moved to the page. */
function post(level, chunkIndex) {
  const started = performance.now();
  const g = decoder.levelGeometry(level);
  let indices, triangles, mode;
  if (g.triangles) {
    mode = 'triangles';
    triangles = g.triangles.length / 3;
    const t = g.triangles;
    const normals = faceAveragedNormals(g.positions, g.vertexCount, (visit) => {
      for (let i = 0; i < t.length; i += 3) visit(t[i], t[i + 1], t[i + 2]);
    });
    indices = narrowed(t, t.length, g.vertexCount);
    g.normals = normals;
  } else {
    mode = 'strip';
    const bound = stripFilterBound(g.strip.length);
    if (filtered.length < bound) filtered = new Uint32Array(bound);
    const length = stripFilter(g.strip, g.strip.length, filtered).length;
    const strip = filtered;
    triangles = stripTriangleCount(strip, length);
    g.normals = faceAveragedNormals(g.positions, g.vertexCount, (visit) => {
      for (let t = 0; t + 2 < length; t++) {
        const a = strip[t], b = strip[t + 1], c = strip[t + 2];
        if (a === b || b === c || a === c) continue;
        if (t & 1) visit(b, a, c);
        else visit(a, b, c);
      }
    });
    indices = narrowed(strip, length, g.vertexCount);
  }
  geometryMilliseconds += performance.now() - started;
  shown = g.level;
  lastPost = performance.now();
  const geometry = { level: g.level, vertexCount: g.vertexCount, mode, triangles, indexCount: indices.length,
    positions: g.positions, normals: g.normals, indices };
  self.postMessage({ type: 'geometry', chunk: chunkIndex, state: snapshot(), geometry },
    [g.positions.buffer, g.normals.buffer, indices.buffer]);
}

/* The level to show, if the last one posted is another (chunks decoded within REFRESH_MILLISECONDS of a post). */
function postLatest() {
  if (decoder.state && levelToShow(decoder) !== shown) post(levelToShow(decoder), decoder.nextChunk - 1);
}

async function handle(message) {
  if (message.type === 'level') {
    const started = performance.now();
    wanted = message.level;
    if (decoder.state && levelToShow(decoder) !== shown) post(levelToShow(decoder), -1);
    busyMilliseconds += performance.now() - started;
    return;
  }
  if (message.type === 'bytes') {
    if (!wasmDecided) {
      const late = new Promise((resolve) => setTimeout(() => resolve(null), WASM_WAIT_MILLISECONDS));
      wasm = await (wantedDecoder === 'wasm' ? wasmReady : Promise.race([wasmReady, late]));
      wasmDecided = true;
    }
    const started = performance.now();
    try {
      await decoder.feed(message.bytes);
      postLatest();
      busyMilliseconds += performance.now() - started;
      self.postMessage({ type: 'fed', id: message.id, state: snapshot() });
    } catch (error) {
      postLatest(); // the good chunks before the failed one
      busyMilliseconds += performance.now() - started;
      self.postMessage({ type: 'failed', id: message.id, message: error.message, state: snapshot() });
    }
  }
}

// One message at a time, in order: feed() is async (inflating v1 chunks).
let queue = Promise.resolve();
self.onmessage = (event) => {
  queue = queue.then(() => handle(event.data));
};
