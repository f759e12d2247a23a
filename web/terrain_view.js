// SPDX-License-Identifier: MIT
// Terrain view: the server evaluates Röttger's quadtree CLOD for the
// current camera (lk_terrain_update with geomorphing and full crack
// elimination) and sends the mesh as LKMB with per-vertex colours; the
// viewer draws it with mesh.vert/mesh.frag. The mesh is re-requested as
// the camera moves: at most one request in flight and at most one every
// REQUEST_INTERVAL ms, always for the latest camera. Keeping the LOD on the
// server keeps one implementation of the crack-free rules (the server
// counts cracks with lk_terrain_count_cracks and reports them).
//
// Fly: W/S or Up/Down forward/back, A/D or Left/Right strafe, Q/E or
// PageDown/PageUp down/up, Shift faster; drag to look around, wheel or
// pinch to move forward/back.

import { createProgram, KEY_LIGHT_DIRECTION, SURFACE_COLOR, parseLkmb, faceAveragedNormals, elementArray } from './gl.js';
import { FlyCamera } from './camera.js';

const REQUEST_INTERVAL = 120;
const KEYS = {
  KeyW: [1, 0, 0], ArrowUp: [1, 0, 0], KeyS: [-1, 0, 0], ArrowDown: [-1, 0, 0],
  KeyD: [0, 1, 0], ArrowRight: [0, 1, 0], KeyA: [0, -1, 0], ArrowLeft: [0, -1, 0],
  KeyE: [0, 0, 1], PageUp: [0, 0, 1], KeyQ: [0, 0, -1], PageDown: [0, 0, -1],
};

export class TerrainView {
  constructor(app) {
    this.app = app;
    this.gl = app.gl;
    this.camera = new FlyCamera();
    this.pressed = new Set();
    this.inFlight = false;
    this.cameraVersion = 0;
    this.requestedVersion = -1;
    this.lastRequest = 0;
    this.mesh = null;
    this.onKeyDown = (event) => {
      if (KEYS[event.code]) {
        this.pressed.add(event.code);
        event.preventDefault();
        this.app.requestDraw();
      }
      this.fast = event.shiftKey;
    };
    this.onKeyUp = (event) => {
      this.pressed.delete(event.code);
      this.fast = event.shiftKey;
    };
    window.addEventListener('keydown', this.onKeyDown);
    window.addEventListener('keyup', this.onKeyUp);
    this.onBlur = () => this.pressed.clear();
    window.addEventListener('blur', this.onBlur);
  }

  async load(model, params) {
    const gl = this.gl;
    const stats = this.app.resetStats('terrain', model.name);
    this.app.background = [0.86, 0.91, 0.97]; // sky
    Object.assign(stats, { triangles: 0, vertices: 0, cracks: null, maxLevel: null, serverMs: null,
      terrainRequests: 0, bytesReceived: 0, lastRequestMs: null });
    this.app.controls.innerHTML = '<span class="hint">fly: WASD / arrows, Q/E down/up, Shift faster; drag to look, wheel to move</span>';
    this.program = await createProgram(gl, 'mesh.vert', 'mesh.frag', ['a_position', 'a_normal', 'a_color']);
    this.buffers = { position: gl.createBuffer(), normal: gl.createBuffer(), color: gl.createBuffer(), index: gl.createBuffer() };
    this.base = model.data || `/api/terrain/${encodeURIComponent(model.name)}`;
    const response = await fetch(`${this.base}/info`);
    if (!response.ok) throw new Error(`${this.base}/info: HTTP ${response.status}`);
    const info = await response.json();
    this.info = info;
    stats.terrainSize = info.size;
    const centre = info.center;
    const radius = info.radius;
    // Start south-west of the centre, above the highest point, looking at it.
    const camera = this.camera;
    camera.position = [centre[0] - 0.9 * radius, centre[1] - 0.9 * radius,
      Math.max(info.max_height, centre[2]) + 0.45 * radius];
    const to = [centre[0] - camera.position[0], centre[1] - camera.position[1], centre[2] - camera.position[2]];
    camera.yaw = (Math.atan2(to[1], to[0]) * 180) / Math.PI;
    camera.pitch = (Math.atan2(to[2], Math.hypot(to[0], to[1])) * 180) / Math.PI;
    camera.speed = 0.25 * radius;
    camera.near = radius * 1e-3;
    camera.far = radius * 6;
    const fov = params.get('fov');
    if (fov) camera.fovY = Number(fov);
    this.cameraVersion++;
    this.app.requestDraw();
  }

  /* Moves the camera for held keys; true while it moves. */
  step(seconds) {
    if (!this.pressed.size) return false;
    const move = [0, 0, 0];
    for (const code of this.pressed) KEYS[code].forEach((value, a) => { move[a] += value; });
    const distance = this.camera.speed * seconds * (this.fast ? 4 : 1);
    if (!(distance > 0) || (!move[0] && !move[1] && !move[2])) return true; // first frame of a key press
    this.camera.move(move[0] * distance, move[1] * distance, move[2] * distance);
    this.cameraVersion++;
    return true;
  }

  /* Asks the server for the mesh of the current view when the camera moved. */
  maybeRequest() {
    if (!this.info || this.inFlight || this.requestedVersion === this.cameraVersion) return;
    const now = performance.now();
    if (now - this.lastRequest < REQUEST_INTERVAL) {
      setTimeout(() => this.app.requestDraw(), REQUEST_INTERVAL - (now - this.lastRequest));
      return;
    }
    const canvas = this.app.canvas;
    const camera = this.camera;
    const f = (values) => values.map((value) => Number(value.toPrecision(9))).join(',');
    const query = `eye=${f(camera.position)}&target=${f(camera.target())}&fov=${camera.fovY}` +
      `&aspect=${(canvas.width / Math.max(canvas.height, 1)).toFixed(4)}&height=${canvas.height}`;
    this.inFlight = true;
    this.lastRequest = now;
    this.requestedVersion = this.cameraVersion;
    const stats = this.app.stats;
    const started = performance.now();
    fetch(`${this.base}?${query}`)
      .then(async (response) => {
        if (!response.ok) {
          let message = `HTTP ${response.status}`;
          try { message = (await response.json()).error || message; } catch { /* not JSON */ }
          throw new Error(`${this.base}: ${message}`);
        }
        const header = response.headers.get('X-Lodkit-Terrain');
        const buffer = await response.arrayBuffer();
        stats.bytesReceived += buffer.byteLength;
        stats.terrainRequests++;
        stats.lastRequestMs = performance.now() - started;
        if (header) {
          try {
            const summary = JSON.parse(header);
            stats.cracks = summary.cracks;
            stats.maxLevel = summary.max_level;
            stats.serverMs = summary.ms;
          } catch { /* informative only */ }
        }
        this.upload(parseLkmb(buffer));
      })
      .catch((error) => { if (!this.disposed) this.app.fail(error); })
      .finally(() => {
        this.inFlight = false;
        this.app.requestDraw();
      });
  }

  upload(mesh) {
    if (this.disposed) return;
    const gl = this.gl;
    const normals = mesh.normals || faceAveragedNormals(mesh.positions, mesh.vertexCount, (visit) => {
      const indices = mesh.indices;
      for (let t = 0; t < mesh.triangleCount; t++) visit(indices[3 * t], indices[3 * t + 1], indices[3 * t + 2]);
    });
    gl.bindBuffer(gl.ARRAY_BUFFER, this.buffers.position);
    gl.bufferData(gl.ARRAY_BUFFER, mesh.positions, gl.DYNAMIC_DRAW);
    gl.bindBuffer(gl.ARRAY_BUFFER, this.buffers.normal);
    gl.bufferData(gl.ARRAY_BUFFER, normals, gl.DYNAMIC_DRAW);
    if (mesh.colors) {
      gl.bindBuffer(gl.ARRAY_BUFFER, this.buffers.color);
      gl.bufferData(gl.ARRAY_BUFFER, mesh.colors, gl.DYNAMIC_DRAW);
    }
    const elements = elementArray(gl, mesh.indices, 3 * mesh.triangleCount, mesh.vertexCount);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, this.buffers.index);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, elements.array, gl.DYNAMIC_DRAW);
    this.mesh = { count: 3 * mesh.triangleCount, type: elements.type, colors: !!mesh.colors };
    Object.assign(this.app.stats, { triangles: mesh.triangleCount, vertices: mesh.vertexCount });
  }

  draw(width, height) {
    const gl = this.gl;
    const background = this.app.background;
    this.maybeRequest();
    gl.clearColor(background[0], background[1], background[2], 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    if (!this.mesh || !this.mesh.count) return false;
    const m = this.camera.matrices(width, height);
    const program = this.program;
    gl.useProgram(program.program);
    gl.uniformMatrix4fv(program.uniform('u_view'), false, m.view);
    gl.uniformMatrix4fv(program.uniform('u_projection'), false, m.projection);
    gl.uniformMatrix3fv(program.uniform('u_normal_matrix'), false, m.normalMatrix);
    gl.uniform1f(program.uniform('u_eye_scale'), 1 / m.far);
    gl.uniform3fv(program.uniform('u_key_direction'), KEY_LIGHT_DIRECTION);
    gl.disable(gl.BLEND);
    gl.disable(gl.CULL_FACE);
    gl.enable(gl.DEPTH_TEST);
    gl.depthFunc(gl.LEQUAL);
    gl.depthMask(true);
    gl.bindBuffer(gl.ARRAY_BUFFER, this.buffers.position);
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 3, gl.FLOAT, false, 0, 0);
    gl.bindBuffer(gl.ARRAY_BUFFER, this.buffers.normal);
    gl.enableVertexAttribArray(1);
    gl.vertexAttribPointer(1, 3, gl.FLOAT, false, 0, 0);
    if (this.mesh.colors) {
      gl.bindBuffer(gl.ARRAY_BUFFER, this.buffers.color);
      gl.enableVertexAttribArray(2);
      gl.vertexAttribPointer(2, 4, gl.UNSIGNED_BYTE, true, 0, 0);
    } else {
      gl.disableVertexAttribArray(2);
      gl.vertexAttrib4f(2, SURFACE_COLOR[0], SURFACE_COLOR[1], SURFACE_COLOR[2], 1);
    }
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, this.buffers.index);
    gl.drawElements(gl.TRIANGLES, this.mesh.count, this.mesh.type, 0);
    for (let location = 0; location < 3; location++) gl.disableVertexAttribArray(location);
    return true;
  }

  drawn() {}

  overlay() {
    const s = this.app.stats;
    const n = (value) => (value === null || value === undefined ? '–' : value.toLocaleString('en-US'));
    const p = this.camera.position.map((value) => value.toFixed(0)).join(', ');
    return [
      `triangles ${n(s.triangles)}   vertices ${n(s.vertices)}   (grid ${n(s.terrainSize)}²)`,
      `server: cracks ${n(s.cracks)}, max level ${n(s.maxLevel)}, ${s.serverMs === null ? '–' : s.serverMs.toFixed(1)} ms; ` +
        `requests ${n(s.terrainRequests)}, last ${s.lastRequestMs === null ? '–' : s.lastRequestMs.toFixed(0)} ms`,
      `eye ${p}`,
    ].join('\n');
  }

  controlsFor() {
    return {
      rotate: (dx, dy) => { this.camera.look(dx, dy); this.cameraVersion++; },
      pan: (dx, dy) => {
        const scale = this.camera.speed / 200;
        this.camera.move(0, -dx * scale, dy * scale);
        this.cameraVersion++;
      },
      zoom: (factor) => {
        this.camera.move(-Math.log(factor) * this.camera.speed, 0, 0);
        this.cameraVersion++;
      },
    };
  }

  dispose() {
    window.removeEventListener('keydown', this.onKeyDown);
    window.removeEventListener('keyup', this.onKeyUp);
    window.removeEventListener('blur', this.onBlur);
    this.disposed = true;
    const gl = this.gl;
    if (this.buffers) Object.values(this.buffers).forEach((buffer) => gl.deleteBuffer(buffer));
    if (this.program) gl.deleteProgram(this.program.program);
  }
}
