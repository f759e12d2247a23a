// SPDX-License-Identifier: MIT
// Splat view: an oriented point set (LKMB from /api/points/...) drawn as
// Phong splats with the C renderer's shaders and passes (src/gl/splat.c):
//   1 pass:  splat.vert + splat.frag, Gaussian alpha blended "over",
//            depth test LEQUAL with depth writes.
//   2 passes: visibility (splat_visibility.frag, depth only, splats pushed
//            back by one radius), accumulation (splat_accumulate.frag,
//            additive, no depth writes) into an offscreen target, and
//            normalisation (fullscreen.vert + splat_normalize.frag).
// WebGL 1 offers the 2-pass target through extensions: half floats
// (OES_texture_half_float + EXT_color_buffer_half_float), else floats
// (OES_texture_float + WEBGL_color_buffer_float + EXT_float_blend), else
// RGBA8 with weights / 16 (as the C fallback); 1 pass when even that fails.

import { createProgram, KEY_LIGHT_DIRECTION, SURFACE_COLOR, parseLkmb, bounds } from './gl.js';
import { OrbitCamera } from './camera.js';

const KERNEL_SIZE = 32;
const KERNEL_SIGMA = 0.7;
const RGBA8_WEIGHT_SCALE = 1 / 16;
const SPLAT_ATTRIBUTES = ['a_position', 'a_normal', 'a_radius', 'a_color', 'a_clip'];

export class SplatView {
  constructor(app) {
    this.app = app;
    this.gl = app.gl;
    this.camera = new OrbitCamera();
    this.camera.fovY = 35;
    this.passes = 1;
    this.target = null; // { kind, name, texture, framebuffer, depth, width, height }
    this.targetFailed = false;
    this.points = null;
    this.radiusScale = 1; // the point-size control of the octree view
    this.outputFramebuffer = null; // where the picture goes (the octree view's eye-dome lighting input)
  }

  async load(model, params) {
    const gl = this.gl;
    const stats = this.app.resetStats('splat', model.name);
    Object.assign(stats, { points: 0, passes: 1, splatPath: '', bytesReceived: 0, totalBytes: 0 });
    this.passes = params.get('passes') === '2' ? 2 : 1;
    // Test hook: restrict the 2-pass target to one kind (half, float, rgba8)
    // or none, to see the fallbacks on a browser that offers more.
    this.forcedTarget = params.get('target');
    this.buildControls();
    await this.prepare();
    const url = model.data || `/api/points/${encodeURIComponent(model.name)}`;
    const response = await fetch(url);
    if (!response.ok) {
      let message = `HTTP ${response.status}`;
      try { message = (await response.json()).error || message; } catch { /* not JSON */ }
      throw new Error(`${url}: ${message}`);
    }
    const buffer = await response.arrayBuffer();
    stats.bytesReceived = stats.totalBytes = buffer.byteLength;
    const points = parseLkmb(buffer);
    if (!points.normals) throw new Error(`${url}: the points have no normals, which splats need`);
    let radii = points.radii;
    const box = bounds(points.positions, points.vertexCount);
    if (!radii) {
      // No radii: a uniform spacing guess from the box and the count.
      const diagonal = Math.hypot(box.max[0] - box.min[0], box.max[1] - box.min[1], box.max[2] - box.min[2]);
      radii = new Float32Array(points.vertexCount).fill((1.5 * diagonal) / Math.sqrt(points.vertexCount));
    }
    this.camera.frame(box.min, box.max);
    this.buffers = {};
    const upload = (name, array) => {
      this.buffers[name] = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, this.buffers[name]);
      gl.bufferData(gl.ARRAY_BUFFER, array, gl.STATIC_DRAW);
    };
    upload('position', points.positions);
    upload('normal', points.normals);
    upload('radius', radii);
    if (points.colors) upload('color', points.colors);
    // Clip lines (lodkit serve sends them with radii): border splats stop at the border.
    if (points.clips && points.radii) upload('clip', points.clips);
    this.points = points;
    stats.points = points.vertexCount;
    stats.clippedPoints = 0;
    if (points.clips && points.radii)
      for (let i = 0; i < points.vertexCount; i++)
        if (points.clips[4 * i] || points.clips[4 * i + 1] || points.clips[4 * i + 2]) stats.clippedPoints++;
    this.pointSizeRange = gl.getParameter(gl.ALIASED_POINT_SIZE_RANGE);
    stats.pointSizeRange = [this.pointSizeRange[0], this.pointSizeRange[1]];
    this.app.requestDraw();
  }

  /** The splat programs (vertex stage: this.splatVertexShader, default splat.vert), the kernel texture and the full-screen triangle. */
  async prepare() {
    const gl = this.gl;
    const vertex = this.splatVertexShader || 'splat.vert';
    const [one, visibility, accumulate, normalize] = await Promise.all([
      createProgram(gl, vertex, 'splat.frag', SPLAT_ATTRIBUTES),
      createProgram(gl, vertex, 'splat_visibility.frag', SPLAT_ATTRIBUTES),
      createProgram(gl, vertex, 'splat_accumulate.frag', SPLAT_ATTRIBUTES),
      createProgram(gl, 'fullscreen.vert', 'splat_normalize.frag', ['a_position']),
    ]);
    this.programs = { one, visibility, accumulate, normalize };
    this.kernel = this.createKernel();
    this.fullscreen = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, this.fullscreen);
    gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 3, -1, -1, 3]), gl.STATIC_DRAW);
  }

  buildControls() {
    const box = this.app.controls;
    box.innerHTML = '';
    for (const passes of [1, 2]) {
      const label = document.createElement('label');
      const radio = document.createElement('input');
      radio.type = 'radio';
      radio.name = 'passes';
      radio.id = `passes-${passes}`;
      radio.checked = this.passes === passes;
      radio.addEventListener('change', () => {
        this.passes = passes;
        this.app.requestDraw();
      });
      label.append(radio, ` ${passes} pass${passes > 1 ? 'es' : ''}`);
      box.appendChild(label);
    }
  }

  /* The Gaussian of the paper's Fig. 1 in the alpha channel (as splat.c). */
  createKernel() {
    const gl = this.gl;
    const texels = new Uint8Array(KERNEL_SIZE * KERNEL_SIZE);
    for (let row = 0; row < KERNEL_SIZE; row++)
      for (let col = 0; col < KERNEL_SIZE; col++) {
        const x = (2 * (col + 0.5)) / KERNEL_SIZE - 1;
        const y = (2 * (row + 0.5)) / KERNEL_SIZE - 1;
        texels[row * KERNEL_SIZE + col] = Math.round(255 * Math.exp(-(x * x + y * y) / (2 * KERNEL_SIGMA * KERNEL_SIGMA)));
      }
    const texture = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, texture);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.ALPHA, KERNEL_SIZE, KERNEL_SIZE, 0, gl.ALPHA, gl.UNSIGNED_BYTE, texels);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.LINEAR);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.LINEAR);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    gl.bindTexture(gl.TEXTURE_2D, null);
    return texture;
  }

  deleteTarget() {
    const gl = this.gl;
    if (!this.target) return;
    gl.deleteFramebuffer(this.target.framebuffer);
    gl.deleteTexture(this.target.texture);
    gl.deleteRenderbuffer(this.target.depth);
    this.target = null;
  }

  /* One accumulation format: colour texture + depth renderbuffer, complete? */
  tryTarget(kind, name, type, width, height) {
    const gl = this.gl;
    while (gl.getError() !== gl.NO_ERROR) { /* clear */ }
    const texture = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, texture);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA, width, height, 0, gl.RGBA, type, null);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    gl.bindTexture(gl.TEXTURE_2D, null);
    const depth = gl.createRenderbuffer();
    gl.bindRenderbuffer(gl.RENDERBUFFER, depth);
    gl.renderbufferStorage(gl.RENDERBUFFER, gl.DEPTH_COMPONENT16, width, height);
    gl.bindRenderbuffer(gl.RENDERBUFFER, null);
    const framebuffer = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, framebuffer);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, texture, 0);
    gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.DEPTH_ATTACHMENT, gl.RENDERBUFFER, depth);
    const ok = gl.getError() === gl.NO_ERROR && gl.checkFramebufferStatus(gl.FRAMEBUFFER) === gl.FRAMEBUFFER_COMPLETE;
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    if (!ok) {
      gl.deleteFramebuffer(framebuffer);
      gl.deleteTexture(texture);
      gl.deleteRenderbuffer(depth);
      return false;
    }
    this.target = { kind, name, texture, framebuffer, depth, width, height };
    return true;
  }

  /* The most precise renderable + blendable 2-pass target, or null. */
  chooseTarget(width, height) {
    const gl = this.gl;
    if (this.target && this.target.width === width && this.target.height === height) return this.target;
    this.deleteTarget();
    if (this.targetFailed) return null;
    const allowed = (kind) => !this.forcedTarget || this.forcedTarget === kind;
    const half = gl.getExtension('OES_texture_half_float');
    const halfBuffer = gl.getExtension('EXT_color_buffer_half_float');
    if (allowed('half') && half && halfBuffer &&
        this.tryTarget('half', 'RGBA16F (half float)', half.HALF_FLOAT_OES, width, height)) return this.target;
    const float = gl.getExtension('OES_texture_float');
    const floatBuffer = gl.getExtension('WEBGL_color_buffer_float');
    const floatBlend = gl.getExtension('EXT_float_blend');
    if (allowed('float') && float && floatBuffer && floatBlend &&
        this.tryTarget('float', 'RGBA32F (float)', gl.FLOAT, width, height)) return this.target;
    if (allowed('rgba8') && this.tryTarget('rgba8', 'RGBA8 (weights / 16)', gl.UNSIGNED_BYTE, width, height)) return this.target;
    this.targetFailed = true;
    return null;
  }

  setUniforms(program, m, width, height, depthOffset) {
    const gl = this.gl;
    gl.useProgram(program.program);
    this.program = program; // drawPoints sets per-draw uniforms on it (web/octree_view.js)
    gl.uniformMatrix4fv(program.uniform('u_view'), false, m.view);
    gl.uniformMatrix4fv(program.uniform('u_projection'), false, m.projection);
    gl.uniformMatrix3fv(program.uniform('u_normal_matrix'), false, m.normalMatrix);
    gl.uniform1f(program.uniform('u_eye_scale'), 1 / m.far);
    // eq. 1 of the paper: sprite size = 2 r * n h_vp / (t - b) / z_eye
    gl.uniform1f(program.uniform('u_size_scale'), (m.near * height) / (2 * m.top));
    gl.uniform1f(program.uniform('u_radius_scale'), this.radiusScale);
    gl.uniform2f(program.uniform('u_point_size_range'), this.pointSizeRange[0], this.pointSizeRange[1]);
    gl.uniform1f(program.uniform('u_culling'), 1);
    gl.uniform1f(program.uniform('u_depth_offset'), depthOffset);
    const kernel = program.uniform('u_kernel');
    if (kernel) gl.uniform1i(kernel, 0);
    const key = program.uniform('u_key_direction');
    if (key) gl.uniform3fv(key, KEY_LIGHT_DIRECTION);
  }

  bindPoints() {
    const gl = this.gl;
    const attribute = (location, name, size, type, normalized) => {
      gl.bindBuffer(gl.ARRAY_BUFFER, this.buffers[name]);
      gl.enableVertexAttribArray(location);
      gl.vertexAttribPointer(location, size, type, normalized, 0, 0);
    };
    attribute(0, 'position', 3, gl.FLOAT, false);
    attribute(1, 'normal', 3, gl.FLOAT, false);
    attribute(2, 'radius', 1, gl.FLOAT, false);
    if (this.buffers.color) attribute(3, 'color', 4, gl.UNSIGNED_BYTE, true);
    else {
      gl.disableVertexAttribArray(3);
      gl.vertexAttrib4f(3, SURFACE_COLOR[0], SURFACE_COLOR[1], SURFACE_COLOR[2], 1);
    }
    if (this.buffers.clip) attribute(4, 'clip', 4, gl.BYTE, true);
    else {
      gl.disableVertexAttribArray(4);
      gl.vertexAttrib4f(4, 0, 0, 0, 0);
    }
  }

  hasPoints() {
    return !!this.points;
  }

  /** Binds and draws every point with the program in use (a view of several buffers overrides it). */
  drawPoints() {
    this.bindPoints();
    this.gl.drawArrays(this.gl.POINTS, 0, this.points.vertexCount);
  }

  unbind() {
    const gl = this.gl;
    for (let location = 0; location < 5; location++) gl.disableVertexAttribArray(location);
    gl.vertexAttrib4f(4, 0, 0, 0, 0); // views drawing with these programs and no clip lines cut nothing
    gl.disable(gl.BLEND);
    gl.depthMask(true);
    gl.colorMask(true, true, true, true);
    gl.bindTexture(gl.TEXTURE_2D, null);
  }

  draw(width, height) {
    const gl = this.gl;
    const stats = this.app.stats;
    const background = this.app.background;
    if (!this.hasPoints()) {
      gl.bindFramebuffer(gl.FRAMEBUFFER, null);
      gl.clearColor(background[0], background[1], background[2], 1);
      gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
      return false;
    }
    const m = this.camera.matrices(width, height);
    gl.disable(gl.CULL_FACE);
    gl.activeTexture(gl.TEXTURE0);
    let target = null;
    if (this.passes === 2) target = this.chooseTarget(width, height);
    if (target) {
      gl.bindFramebuffer(gl.FRAMEBUFFER, target.framebuffer);
      gl.viewport(0, 0, width, height);
      gl.clearColor(0, 0, 0, 0);
      gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
      // 1: visibility, depth only, splats pushed back by one radius
      gl.colorMask(false, false, false, false);
      gl.enable(gl.DEPTH_TEST);
      gl.depthFunc(gl.LESS);
      gl.depthMask(true);
      gl.disable(gl.BLEND);
      this.setUniforms(this.programs.visibility, m, width, height, 1.0);
      this.drawPoints();
      // 2: accumulation of the splats in front of that depth
      gl.colorMask(true, true, true, true);
      gl.depthFunc(gl.LEQUAL);
      gl.depthMask(false);
      gl.enable(gl.BLEND);
      gl.blendFunc(gl.ONE, gl.ONE);
      this.setUniforms(this.programs.accumulate, m, width, height, 0);
      gl.uniform1f(this.programs.accumulate.uniform('u_weight_scale'), target.kind === 'rgba8' ? RGBA8_WEIGHT_SCALE : 1);
      gl.bindTexture(gl.TEXTURE_2D, this.kernel);
      this.drawPoints();
      // 3: normalisation over the background
      gl.bindFramebuffer(gl.FRAMEBUFFER, this.outputFramebuffer);
      gl.clearColor(background[0], background[1], background[2], 1);
      gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
      gl.disable(gl.BLEND);
      gl.disable(gl.DEPTH_TEST);
      gl.depthMask(true);
      for (let location = 1; location < 5; location++) gl.disableVertexAttribArray(location);
      gl.useProgram(this.programs.normalize.program);
      gl.uniform1i(this.programs.normalize.uniform('u_accumulated'), 0);
      gl.bindTexture(gl.TEXTURE_2D, target.texture);
      gl.bindBuffer(gl.ARRAY_BUFFER, this.fullscreen);
      gl.enableVertexAttribArray(0);
      gl.vertexAttribPointer(0, 2, gl.FLOAT, false, 0, 0);
      gl.drawArrays(gl.TRIANGLES, 0, 3);
      stats.passes = 2;
      stats.splatPath = `2 passes, accumulation target ${target.name}`;
    } else {
      gl.bindFramebuffer(gl.FRAMEBUFFER, this.outputFramebuffer);
      gl.clearColor(background[0], background[1], background[2], 1);
      gl.colorMask(true, true, true, true);
      gl.depthMask(true);
      gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
      this.setUniforms(this.programs.one, m, width, height, 0);
      gl.enable(gl.DEPTH_TEST);
      gl.depthFunc(gl.LEQUAL);
      gl.enable(gl.BLEND);
      gl.blendFuncSeparate(gl.SRC_ALPHA, gl.ONE_MINUS_SRC_ALPHA, gl.ONE, gl.ONE_MINUS_SRC_ALPHA);
      gl.bindTexture(gl.TEXTURE_2D, this.kernel);
      this.drawPoints();
      stats.passes = 1;
      stats.splatPath = this.passes === 2
        ? '1 pass (2 passes asked, but no renderable accumulation target here)'
        : '1 pass, alpha-blended Gaussian splats';
    }
    this.unbind();
    return true;
  }

  drawn() {}

  overlay() {
    const s = this.app.stats;
    return [
      `points ${s.points.toLocaleString('en-US')}   (${(s.bytesReceived / 1024).toFixed(0)} KiB LKMB)`,
      `path: ${s.splatPath || '–'}`,
      s.pointSizeRange ? `point sizes ${s.pointSizeRange[0]}..${s.pointSizeRange[1]} px` : '',
    ].filter(Boolean).join('\n');
  }

  controlsFor() {
    return {
      rotate: (dx, dy) => this.camera.rotate(dx, dy),
      pan: (dx, dy) => this.camera.panBy(dx, dy, this.app.canvas.clientWidth, this.app.canvas.clientHeight),
      zoom: (factor) => this.camera.zoomBy(factor),
    };
  }

  dispose() {
    const gl = this.gl;
    this.deleteTarget();
    if (this.buffers) Object.values(this.buffers).forEach((buffer) => gl.deleteBuffer(buffer));
    if (this.fullscreen) gl.deleteBuffer(this.fullscreen);
    if (this.kernel) gl.deleteTexture(this.kernel);
    if (this.programs) Object.values(this.programs).forEach((program) => gl.deleteProgram(program.program));
  }
}
