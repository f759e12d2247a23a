// SPDX-License-Identifier: MIT
// Progressive mesh view: a .lks stream fetched incrementally, drawn as soon
// as its base chunk has arrived and refined chunk by chunk through
// mesh.vert/mesh.frag, the C renderer's shaders: version 1 as one
// DTFS-filtered TRIANGLE_STRIP (degenerate joins: WebGL 1 has no primitive
// restart), version 2 as indexed TRIANGLES (it carries no strip).
//
// Decoding runs in a Worker (web/stream_worker.js): this thread posts it the
// fetched bytes and gets back, after each chunk, positions, normals and
// indices in transferred ArrayBuffers, which it only uploads.
//
// Fetching: a first Range request for the header and chunk table (bytes
// 0-4095, the format's "one round trip" advice), a second for the rest of
// the base chunk, so the first frame is drawn from the base mesh alone; then
// one streamed request (fetch + ReadableStream) for everything after it,
// decoded chunk by chunk as the bytes arrive. A server that ignores Range
// (200) is read as one stream from the start.

import { createProgram, KEY_LIGHT_DIRECTION, SURFACE_COLOR } from './gl.js';
import { OrbitCamera } from './camera.js';

const FIRST_REQUEST_BYTES = 4096;
const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));

/**
 * The stream decoder of web/stream_worker.js, seen from this thread: what
 * web/stream.js's StreamDecoder tells its caller (info, chunks, received,
 * level, done, error, chunkEnd), kept up to date from the worker's
 * messages. feed() resolves once the worker has taken the bytes (and
 * decoded every chunk they complete); it rejects when the stream is bad.
 */
class WorkerDecoder {
  /* decoder: 'js' to decode version-2 streams in JavaScript (web/stream2.js) rather than WebAssembly,
   * 'wasm' to wait for the WebAssembly module however long it takes (web/stream_worker.js). */
  constructor({ onInfo, onState, onGeometry, decoder = '' }) {
    this.onInfo = onInfo;
    this.onState = onState;
    this.onGeometry = onGeometry;
    this.info = null;
    this.chunks = null;
    this.received = 0;
    this.level = 0;
    this.done = false;
    this.version = 0;
    this.error = null;
    this.state = null;
    this.waiting = new Map(); // feed id -> { resolve, reject }
    this.nextId = 0;
    const url = new URL('./stream_worker.js', import.meta.url);
    if (decoder === 'js' || decoder === 'wasm') url.searchParams.set('decoder', decoder);
    this.worker = new Worker(url, { type: 'module' });
    this.worker.onmessage = (event) => this.receive(event.data);
    this.worker.onerror = (event) => {
      event.preventDefault();
      this.fail(new Error(`stream worker: ${event.message || 'failed to start'}`));
    };
  }

  receive(message) {
    if (message.state) {
      const state = message.state;
      this.state = state;
      this.received = state.received;
      this.level = state.level;
      this.done = state.done;
      this.version = state.version;
      this.onState(this);
    }
    if (message.type === 'info') {
      this.info = message.info;
      this.chunks = message.chunks;
      this.onInfo(this);
    } else if (message.type === 'geometry') {
      this.onGeometry(this, message.geometry, message.chunk);
    } else if (message.type === 'fed') {
      const waiting = this.waiting.get(message.id);
      this.waiting.delete(message.id);
      if (waiting) waiting.resolve();
    } else if (message.type === 'failed') {
      this.fail(new Error(message.message));
    }
  }

  fail(error) {
    if (!this.error) this.error = error;
    for (const waiting of this.waiting.values()) waiting.reject(this.error);
    this.waiting.clear();
  }

  feed(bytes) {
    if (this.error) return Promise.reject(this.error);
    const id = ++this.nextId;
    const copy = bytes.slice(); // its own buffer, moved to the worker
    return new Promise((resolve, reject) => {
      this.waiting.set(id, { resolve, reject });
      this.worker.postMessage({ type: 'bytes', id, bytes: copy }, [copy.buffer]);
    });
  }

  /** Asks for the geometry of `level` (-1: follow the latest decoded level). */
  showLevel(level) {
    this.worker.postMessage({ type: 'level', level });
  }

  chunkEnd(index) {
    const chunk = this.chunks[index];
    return chunk.offset + chunk.size;
  }

  terminate() {
    this.worker.terminate();
    this.fail(new DOMException('view closed', 'AbortError'));
  }
}

export class MeshView {
  constructor(app) {
    this.app = app;
    this.gl = app.gl;
    this.camera = new OrbitCamera();
    this.decoder = null;
    this.program = null;
    this.buffers = null;
    this.drawCount = 0;
    this.indexType = 0;
    this.drawMode = 0;
    this.shownLevel = -1;
    this.wantedLevel = -1; // -1: follow the latest decoded level
    this.aborter = new AbortController();
    this.framed = false;
    // Never wait for the GPU on this thread (App.drawNow): in SwiftShader a
    // frame of the full bunny takes 50-200 ms, its first draw compiles the
    // shaders, and glFinish would block the page for all of it.
    this.finishEachFrame = false;
  }

  async load(model, params) {
    const gl = this.gl;
    const stats = this.app.resetStats('mesh', model.name);
    Object.assign(stats, { level: 0, levels: 0, triangles: 0, indicesSent: 0, bytesReceived: 0, totalBytes: 0,
      firstFrameBytes: null, firstFrameLevel: null, firstFrameTriangles: null, chunksDecoded: 0, chunkCount: 0,
      done: false, decodeMs: 0, decoder: '', workerMs: 0, fetchMode: '', version: 0 });
    this.rate = Number(params.get('rate')) || 0; // bytes per second, 0 = as fast as it comes
    this.program = await createProgram(gl, 'mesh.vert', 'mesh.frag', ['a_position', 'a_normal', 'a_color']);
    this.buffers = { position: gl.createBuffer(), normal: gl.createBuffer(), index: gl.createBuffer() };
    const initialLevel = params.get('level');
    if (initialLevel !== null) this.wantedLevel = Math.max(0, Number(initialLevel) | 0);
    this.buildControls();
    // An empty frame now, with the controls in place: the canvas takes its
    // final size and its drawing buffer is (re)allocated before the stream
    // starts, not in its first frame (80-180 ms in SwiftShader).
    this.app.drawNow();

    this.decoder = new WorkerDecoder({
      decoder: params.get('decoder') || '',
      onInfo: (decoder) => {
        stats.version = decoder.info.version;
        stats.levels = decoder.info.splitCount;
        stats.chunkCount = decoder.info.chunkCount;
        stats.totalBytes = decoder.info.totalSize;
        stats.vertices = decoder.info.vertexCount;
        stats.fullTriangles = decoder.info.triangleCount;
        stats.baseEnd = decoder.chunkEnd(0);
        this.slider.max = String(decoder.info.splitCount);
      },
      onState: (decoder) => {
        if (this.aborter.signal.aborted) return; // another model is open now
        const state = decoder.state;
        if (state.chunksDecoded > stats.chunksDecoded) {
          stats.chunksDecoded = state.chunksDecoded;
          (stats.chunkMs = stats.chunkMs || []).push(Math.round(performance.now() - this.app.loadStart));
        }
        stats.decodedLevel = state.level;
        stats.decodeMs = state.decodeMs;
        stats.decoder = state.decoder;
        stats.workerMs = state.workerMs;
        stats.geometryMs = state.geometryMs;
        stats.done = state.done;
        this.app.updateOverlay();
      },
      onGeometry: (decoder, geometry, chunkIndex) => {
        if (this.aborter.signal.aborted) return;
        try {
          this.upload(geometry);
        } catch (error) {
          this.app.fail(error);
          return;
        }
        if (chunkIndex === 0) this.app.drawNow(); // the base mesh: drawn now, before another byte is read
        else this.app.requestDraw();
      },
    });
    if (this.wantedLevel >= 0) this.decoder.showLevel(this.wantedLevel);
    this.fetchStream(model.url).catch((error) => {
      if (error.name !== 'AbortError') this.app.fail(error);
    });
  }

  buildControls() {
    const box = this.app.controls;
    box.innerHTML = '';
    const label = document.createElement('label');
    label.textContent = 'level ';
    this.slider = document.createElement('input');
    this.slider.type = 'range';
    this.slider.min = '0';
    this.slider.max = '0';
    this.slider.value = '0';
    this.slider.id = 'level';
    this.slider.title = 'vertex splits applied (any level up to what has arrived)';
    this.slider.addEventListener('input', () => {
      const value = Number(this.slider.value);
      this.wantedLevel = this.decoder && this.decoder.info && value >= this.decoder.info.splitCount ? -1 : value;
      this.decoder.showLevel(this.wantedLevel);
    });
    label.appendChild(this.slider);
    const follow = document.createElement('button');
    follow.textContent = 'latest';
    follow.title = 'follow the latest decoded level';
    follow.addEventListener('click', () => {
      this.wantedLevel = -1;
      this.decoder.showLevel(-1);
    });
    box.append(label, follow);
  }

  /* Feeds a Response body to the decoder, skipping `skip` bytes first (a
   * 200 answer to a Range request), at most `rate` bytes per second. */
  async pump(response, skip) {
    const stats = this.app.stats;
    const reader = response.body.getReader();
    for (;;) {
      const { value, done } = await reader.read();
      if (done) break;
      let piece = value;
      if (skip > 0) {
        const dropped = Math.min(skip, piece.length);
        skip -= dropped;
        piece = piece.subarray(dropped);
      }
      while (piece.length > 0) {
        const size = this.rate > 0 ? Math.min(piece.length, Math.max(1024, Math.round(this.rate / 20))) : piece.length;
        const part = piece.subarray(0, size);
        piece = piece.subarray(size);
        if (this.rate > 0) await sleep((1000 * size) / this.rate);
        if (this.aborter.signal.aborted) throw new DOMException('view closed', 'AbortError');
        stats.bytesReceived += part.length;
        this.app.updateOverlay();
        await this.decoder.feed(part);
      }
    }
  }

  /* Requests bytes [start, end] (end null: to the end of the file). */
  async fetchRange(url, start, end) {
    const range = `bytes=${start}-${end === null ? '' : end}`;
    const headers = { Range: range };
    // The later ranges must come from the same file: If-Range turns a
    // replaced file into a 200 instead of bytes of another version.
    if (this.etag && start > 0) headers['If-Range'] = this.etag;
    const response = await fetch(url, { headers, signal: this.aborter.signal, cache: 'no-store' });
    if (start === 0) this.etag = response.headers.get('ETag');
    if (response.status === 200 && headers['If-Range'] && this.decoder.received > 0)
      throw new Error(`${url} changed on the server while it was loading: reload the page`);
    if (response.status === 206) {
      const match = /^bytes (\d+)-(\d+)\/(\d+|\*)$/.exec(response.headers.get('Content-Range') || '');
      if (!match || Number(match[1]) !== start) throw new Error(`${url}: the server answered ${range} with ${response.headers.get('Content-Range')}`);
      this.app.stats.fetchMode = 'range';
      await this.pump(response, 0);
      return true;
    }
    if (response.status === 200) {
      // No Range support: read the whole file, skipping what we have.
      this.app.stats.fetchMode = 'whole file (no Range support)';
      await this.pump(response, start);
      return false;
    }
    if (response.status === 416 && start > 0) return true;
    let message = `HTTP ${response.status}`;
    try {
      message = (await response.json()).error || message;
    } catch { /* not JSON */ }
    throw new Error(`${url}: ${message}`);
  }

  async fetchStream(url) {
    const decoder = this.decoder;
    this.app.stats.streamStart = performance.now(); // the first request goes out now
    // 1. header + chunk table (+ usually the start of the base chunk)
    if (!(await this.fetchRange(url, 0, FIRST_REQUEST_BYTES - 1))) return this.finish();
    // 2. the rest of the table when it is longer than the first request
    if (!decoder.chunks && !decoder.error) {
      const headerSize = decoder.info ? decoder.info.headerSize : null;
      if (headerSize === null) throw new Error(`${url}: shorter than a stream header`);
      if (!(await this.fetchRange(url, decoder.received, headerSize - 1))) return this.finish();
    }
    // 3. the rest of the base chunk: the first frame
    const baseEnd = decoder.chunkEnd(0);
    if (decoder.received < baseEnd && !(await this.fetchRange(url, decoder.received, baseEnd - 1))) return this.finish();
    // 4. every split chunk, streamed and decoded as it arrives
    if (decoder.received < decoder.info.totalSize) await this.fetchRange(url, decoder.received, null);
    return this.finish();
  }

  finish() {
    if (this.aborter.signal.aborted) return;
    const decoder = this.decoder;
    const stats = this.app.stats;
    if (!decoder.done && !decoder.error)
      this.app.fail(new Error(`stream truncated: ${decoder.received} of ${decoder.info ? decoder.info.totalSize : '?'} bytes, level ${decoder.level}`));
    stats.done = decoder.done;
    this.app.requestDraw();
  }

  /* Uploads a level's geometry, built by the worker. */
  upload(geometry) {
    const gl = this.gl;
    const stats = this.app.stats;
    const started = performance.now();
    const decoder = this.decoder;
    if (!this.framed) {
      // Frame the quantisation box once: the camera stays put while it refines.
      const info = decoder.info;
      const top = 2 ** info.positionBits - 1;
      const min = [0, 1, 2].map((a) => info.quantisationMin[a]);
      const max = [0, 1, 2].map((a) => info.quantisationMin[a] + top * info.quantisationStep[a]);
      this.camera.frame(min, max);
      this.framed = true;
    }
    if (geometry.indices instanceof Uint32Array && !gl.getExtension('OES_element_index_uint'))
      throw new Error(`${geometry.vertexCount} vertices need 32-bit indices (OES_element_index_uint), which this WebGL lacks`);
    gl.bindBuffer(gl.ARRAY_BUFFER, this.buffers.position);
    gl.bufferData(gl.ARRAY_BUFFER, geometry.positions, gl.DYNAMIC_DRAW);
    gl.bindBuffer(gl.ARRAY_BUFFER, this.buffers.normal);
    gl.bufferData(gl.ARRAY_BUFFER, geometry.normals, gl.DYNAMIC_DRAW);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, this.buffers.index);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, geometry.indices, gl.DYNAMIC_DRAW);
    this.indexType = geometry.indices instanceof Uint32Array ? gl.UNSIGNED_INT : gl.UNSIGNED_SHORT;
    this.drawMode = geometry.mode === 'triangles' ? gl.TRIANGLES : gl.TRIANGLE_STRIP;
    this.drawCount = geometry.indexCount;
    this.shownLevel = geometry.level;
    // Counted by the worker on the very indices sent (v1: the strip's non-degenerate triangles).
    Object.assign(stats, { level: geometry.level, triangles: geometry.triangles, indicesSent: geometry.indexCount,
      vertices: geometry.vertexCount, drawMode: geometry.mode });
    stats.uploadMs = (stats.uploadMs || 0) + (performance.now() - started);
    if (this.slider && document.activeElement !== this.slider) this.slider.value = String(geometry.level);
  }

  draw(width, height) {
    const gl = this.gl;
    const background = this.app.background;
    gl.clearColor(background[0], background[1], background[2], 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    if (!this.drawCount) return false;
    const m = this.camera.matrices(width, height);
    const program = this.program;
    gl.useProgram(program.program);
    gl.uniformMatrix4fv(program.uniform('u_view'), false, m.view);
    gl.uniformMatrix4fv(program.uniform('u_projection'), false, m.projection);
    gl.uniformMatrix3fv(program.uniform('u_normal_matrix'), false, m.normalMatrix);
    gl.uniform1f(program.uniform('u_eye_scale'), 1 / m.far);
    gl.uniform3fv(program.uniform('u_key_direction'), KEY_LIGHT_DIRECTION);
    gl.disable(gl.BLEND);
    gl.disable(gl.CULL_FACE); // two-sided lighting: back faces are drawn
    gl.enable(gl.DEPTH_TEST);
    gl.depthFunc(gl.LEQUAL);
    gl.depthMask(true);
    gl.bindBuffer(gl.ARRAY_BUFFER, this.buffers.position);
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 3, gl.FLOAT, false, 0, 0);
    gl.bindBuffer(gl.ARRAY_BUFFER, this.buffers.normal);
    gl.enableVertexAttribArray(1);
    gl.vertexAttribPointer(1, 3, gl.FLOAT, false, 0, 0);
    gl.disableVertexAttribArray(2);
    gl.vertexAttrib4f(2, SURFACE_COLOR[0], SURFACE_COLOR[1], SURFACE_COLOR[2], 1);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, this.buffers.index);
    gl.drawElements(this.drawMode, this.drawCount, this.indexType, 0);
    gl.disableVertexAttribArray(0);
    gl.disableVertexAttribArray(1);
    return true;
  }

  /* The level drawn: first frame bookkeeping for the stats. */
  drawn() {
    const stats = this.app.stats;
    if (stats.firstFrameBytes === null) {
      stats.firstFrameBytes = stats.bytesReceived;
      stats.firstFrameLevel = stats.level;
      stats.firstFrameTriangles = stats.triangles;
      stats.firstFrameMs = performance.now() - this.app.loadStart;
    }
    if (stats.done && stats.level === stats.levels && stats.fullFrameMs === undefined) {
      stats.fullFrameMs = performance.now() - this.app.loadStart;
      stats.fullFrameAt = performance.now();
    }
  }

  overlay() {
    const s = this.app.stats;
    const pct = (value) => (s.totalBytes ? ((100 * value) / s.totalBytes).toFixed(1) + '%' : '');
    const n = (value) => (value === null || value === undefined ? '–' : value.toLocaleString('en-US'));
    const drawn = s.version === 2 ? 'indexed triangles' : 'DTFS strip';
    const lines = [
      `stream version ${s.version || '?'} (${drawn})`,
      `level ${n(s.level)} / ${n(s.levels)}  (decoded ${n(s.decodedLevel)}, chunk ${s.chunksDecoded}/${s.chunkCount})`,
      `triangles ${n(s.triangles)}   indices sent ${n(s.indicesSent)}` +
        (s.triangles ? ` (${(s.indicesSent / s.triangles).toFixed(2)}/triangle, ${drawn})` : ''),
      `bytes received ${n(s.bytesReceived)} / ${n(s.totalBytes)} ${pct(s.bytesReceived)}`,
    ];
    if (s.firstFrameBytes !== null)
      lines.push(`first frame after ${n(s.firstFrameBytes)} bytes (${pct(s.firstFrameBytes)}), ${s.firstFrameMs.toFixed(0)} ms`);
    const decoder = s.decoder === 'wasm' ? 'a WebAssembly' : s.decoder === 'js' ? 'a JavaScript' : 'a';
    lines.push(`decode ${s.decodeMs.toFixed(0)} ms in ${decoder} worker (busy ${s.workerMs.toFixed(0)} ms)${s.done ? ', complete' : ''}` +
      `${s.fetchMode ? ', fetch: ' + s.fetchMode : ''}`);
    return lines.join('\n');
  }

  controlsFor() {
    return {
      rotate: (dx, dy) => this.camera.rotate(dx, dy),
      pan: (dx, dy) => this.camera.panBy(dx, dy, this.app.canvas.clientWidth, this.app.canvas.clientHeight),
      zoom: (factor) => this.camera.zoomBy(factor),
    };
  }

  dispose() {
    this.aborter.abort();
    if (this.decoder) this.decoder.terminate();
    const gl = this.gl;
    if (this.buffers) Object.values(this.buffers).forEach((buffer) => gl.deleteBuffer(buffer));
    if (this.program) gl.deleteProgram(this.program.program);
  }
}
