// SPDX-License-Identifier: MIT
// Progressive mesh view: a .lks stream fetched incrementally, drawn as soon
// as its base chunk has arrived and refined chunk by chunk, as one
// DTFS-filtered TRIANGLE_STRIP (degenerate joins: WebGL 1 has no primitive
// restart) through mesh.vert/mesh.frag, the C renderer's shaders.
//
// Fetching: a first Range request for the header and chunk table (bytes
// 0-4095, the format's "one round trip" advice), a second for the rest of
// the base chunk, so the first frame is drawn from the base mesh alone; then
// one streamed request (fetch + ReadableStream) for everything after it,
// decoded chunk by chunk as the bytes arrive. A server that ignores Range
// (200) is read as one stream from the start.

import { StreamDecoder } from './stream.js';
import { stripFilter, stripFilterBound, stripTriangleCount } from './strips.js';
import { createProgram, KEY_LIGHT_DIRECTION, SURFACE_COLOR, faceAveragedNormals, elementArray } from './gl.js';
import { OrbitCamera } from './camera.js';

const FIRST_REQUEST_BYTES = 4096;
const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));

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
    this.shownLevel = -1;
    this.wantedLevel = -1; // -1: follow the latest decoded level
    this.aborter = new AbortController();
    this.filtered = null;
    this.framed = false;
  }

  async load(model, params) {
    const gl = this.gl;
    const stats = this.app.resetStats('mesh', model.name);
    Object.assign(stats, { level: 0, levels: 0, triangles: 0, indicesSent: 0, bytesReceived: 0, totalBytes: 0,
      firstFrameBytes: null, firstFrameLevel: null, firstFrameTriangles: null, chunksDecoded: 0, chunkCount: 0,
      done: false, decodeMs: 0, fetchMode: '' });
    this.rate = Number(params.get('rate')) || 0; // bytes per second, 0 = as fast as it comes
    this.program = await createProgram(gl, 'mesh.vert', 'mesh.frag', ['a_position', 'a_normal', 'a_color']);
    this.buffers = { position: gl.createBuffer(), normal: gl.createBuffer(), index: gl.createBuffer() };
    const initialLevel = params.get('level');
    if (initialLevel !== null) this.wantedLevel = Math.max(0, Number(initialLevel) | 0);
    this.buildControls();

    this.decoder = new StreamDecoder({
      onInfo: (decoder) => {
        stats.levels = decoder.info.splitCount;
        stats.chunkCount = decoder.info.chunkCount;
        stats.totalBytes = decoder.info.totalSize;
        stats.vertices = decoder.info.vertexCount;
        stats.fullTriangles = decoder.info.triangleCount;
        stats.baseEnd = decoder.chunkEnd(0);
        this.slider.max = String(decoder.info.splitCount);
      },
      onChunk: (decoder, chunk) => {
        if (this.aborter.signal.aborted) return; // another model is open now
        stats.chunksDecoded = chunk.index + 1;
        stats.decodedLevel = decoder.level;
        (stats.chunkMs = stats.chunkMs || []).push(Math.round(performance.now() - this.app.loadStart));
        stats.decodeMs = decoder.decodeMilliseconds;
        stats.done = decoder.done;
        if (chunk.index === 0) {
          // The base mesh: drawn now, before another byte is read.
          this.rebuild();
          this.app.drawNow();
        } else {
          this.app.requestDraw();
        }
        this.app.updateOverlay();
      },
    });
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
      this.wantedLevel = this.decoder && value >= this.decoder.info.splitCount ? -1 : value;
      this.app.requestDraw();
    });
    label.appendChild(this.slider);
    const follow = document.createElement('button');
    follow.textContent = 'latest';
    follow.title = 'follow the latest decoded level';
    follow.addEventListener('click', () => {
      this.wantedLevel = -1;
      this.app.requestDraw();
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

  /* Rebuilds the GPU buffers for the level to show. */
  rebuild() {
    const gl = this.gl;
    const decoder = this.decoder;
    const stats = this.app.stats;
    if (!decoder || !decoder.state) return;
    const latest = decoder.level;
    const level = this.wantedLevel < 0 ? latest : Math.min(this.wantedLevel, latest);
    if (level === this.shownLevel) return;
    const started = performance.now();
    const geometry = decoder.levelGeometry(level);
    const bound = stripFilterBound(geometry.strip.length);
    if (!this.filtered || this.filtered.length < bound) this.filtered = new Uint32Array(bound);
    const filtered = stripFilter(geometry.strip, geometry.strip.length, this.filtered);
    const indices = this.filtered;
    const length = filtered.length;
    const normals = faceAveragedNormals(geometry.positions, geometry.vertexCount, (visit) => {
      for (let t = 0; t + 2 < length; t++) {
        const a = indices[t], b = indices[t + 1], c = indices[t + 2];
        if (a === b || b === c || a === c) continue;
        if (t & 1) visit(b, a, c);
        else visit(a, b, c);
      }
    });
    if (!this.framed) {
      // Frame the base mesh's box once: the camera stays put while it refines.
      const info = decoder.info;
      const top = 2 ** info.positionBits - 1;
      const min = [0, 1, 2].map((a) => info.quantisationMin[a]);
      const max = [0, 1, 2].map((a) => info.quantisationMin[a] + top * info.quantisationStep[a]);
      this.camera.frame(min, max);
      this.framed = true;
    }
    gl.bindBuffer(gl.ARRAY_BUFFER, this.buffers.position);
    gl.bufferData(gl.ARRAY_BUFFER, geometry.positions, gl.DYNAMIC_DRAW);
    gl.bindBuffer(gl.ARRAY_BUFFER, this.buffers.normal);
    gl.bufferData(gl.ARRAY_BUFFER, normals, gl.DYNAMIC_DRAW);
    const elements = elementArray(gl, indices, length, geometry.vertexCount);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, this.buffers.index);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, elements.array, gl.DYNAMIC_DRAW);
    this.indexType = elements.type;
    this.drawCount = length;
    this.shownLevel = level;
    // Counted on the very indices sent: the non-degenerate triangles of the strip.
    Object.assign(stats, { level, triangles: stripTriangleCount(indices, length), indicesSent: length,
      vertices: geometry.vertexCount });
    stats.rebuildMs = (stats.rebuildMs || 0) + (performance.now() - started);
    if (this.slider && document.activeElement !== this.slider) this.slider.value = String(level);
  }

  draw(width, height) {
    const gl = this.gl;
    this.rebuild();
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
    gl.drawElements(gl.TRIANGLE_STRIP, this.drawCount, this.indexType, 0);
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
    if (stats.done && stats.level === stats.levels && stats.fullFrameMs === undefined)
      stats.fullFrameMs = performance.now() - this.app.loadStart;
  }

  overlay() {
    const s = this.app.stats;
    const pct = (value) => (s.totalBytes ? ((100 * value) / s.totalBytes).toFixed(1) + '%' : '');
    const n = (value) => (value === null || value === undefined ? '–' : value.toLocaleString('en-US'));
    const lines = [
      `level ${n(s.level)} / ${n(s.levels)}  (decoded ${n(s.decodedLevel)}, chunk ${s.chunksDecoded}/${s.chunkCount})`,
      `triangles ${n(s.triangles)}   indices sent ${n(s.indicesSent)}` +
        (s.triangles ? ` (${(s.indicesSent / s.triangles).toFixed(2)}/triangle, DTFS strip)` : ''),
      `bytes received ${n(s.bytesReceived)} / ${n(s.totalBytes)} ${pct(s.bytesReceived)}`,
    ];
    if (s.firstFrameBytes !== null)
      lines.push(`first frame after ${n(s.firstFrameBytes)} bytes (${pct(s.firstFrameBytes)}), ${s.firstFrameMs.toFixed(0)} ms`);
    lines.push(`decode ${s.decodeMs.toFixed(0)} ms${s.done ? ', complete' : ''}${s.fetchMode ? ', fetch: ' + s.fetchMode : ''}`);
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
    const gl = this.gl;
    if (this.buffers) Object.values(this.buffers).forEach((buffer) => gl.deleteBuffer(buffer));
    if (this.program) gl.deleteProgram(this.program.program);
  }
}
