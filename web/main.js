// SPDX-License-Identifier: MIT
// lodkit viewer: model picker, one WebGL 1 context, three views, the stats
// overlay and window.viewerStats (what was drawn, for people and for the
// browser tests: tests/browser/viewer.test.mjs).
//
// URL parameters: model=NAME (from /api/index.json), passes=1|2 (splats),
// level=N (progressive mesh: show level N), rate=BYTES_PER_SECOND (slow the
// stream down to watch it refine), octree=URL (a point octree's index,
// octree.json, from this server or any other that answers Range requests
// and allows this origin: web/octree_view.js reads budget, up, edl, size).

import { MeshView } from './mesh_view.js';
import { SplatView } from './splat_view.js';
import { TerrainView } from './terrain_view.js';
import { OctreeView } from './octree_view.js';
import { attachPointerControls } from './camera.js';

const VIEWS = { stream: MeshView, points: SplatView, terrain: TerrainView, octree: OctreeView };

class App {
  constructor() {
    this.canvas = document.getElementById('view');
    this.overlayElement = document.getElementById('overlay');
    this.controls = document.getElementById('controls');
    this.picker = document.getElementById('model');
    this.background = [1, 1, 1];
    this.view = null;
    this.scheduled = false;
    this.lastFrame = 0;
    this.stats = {};
    this.resetStats('none', null);
    const gl = this.canvas.getContext('webgl', { preserveDrawingBuffer: true, antialias: true, alpha: false });
    if (!gl) throw new Error('this browser has no WebGL 1');
    this.gl = gl;
    // ICU's first use costs 15-40 ms: paid while the page starts, not in
    // the first overlay of a model that is streaming in.
    (0).toLocaleString('en-US');
    const debug = gl.getExtension('WEBGL_debug_renderer_info');
    this.renderer = debug ? gl.getParameter(debug.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER);
    this.canvas.addEventListener('webglcontextlost', (event) => {
      event.preventDefault();
      this.fail(new Error('WebGL context lost'));
    });
    attachPointerControls(this.canvas, {
      rotate: (dx, dy) => this.control('rotate', dx, dy),
      pan: (dx, dy) => this.control('pan', dx, dy),
      zoom: (factor) => this.control('zoom', factor),
    });
    window.addEventListener('resize', () => this.requestDraw());
    this.picker.addEventListener('change', () => this.open(this.picker.value));
  }

  control(what, ...args) {
    if (!this.view) return;
    this.view.controlsFor()[what](...args);
    this.requestDraw();
  }

  resetStats(view, model) {
    this.stats = { view, model, framesDrawn: 0, error: null, renderer: this.renderer || null };
    window.viewerStats = this.stats;
    this.loadStart = performance.now();
    return this.stats;
  }

  fail(error) {
    console.error(error);
    this.stats.error = String(error && error.message ? error.message : error);
    this.updateOverlay();
  }

  async start() {
    const params = new URLSearchParams(location.search);
    const octree = params.get('octree');
    if (octree) {
      // An octree named by its address: no index of this server needed.
      this.models = new Map([[octree, { name: octree, kind: 'octree', url: octree }]]);
      const option = document.createElement('option');
      option.value = option.textContent = octree;
      this.picker.appendChild(option);
      await this.open(octree, params);
      return;
    }
    let models = [];
    try {
      const response = await fetch('/api/index.json');
      if (!response.ok) throw new Error(`/api/index.json: HTTP ${response.status}`);
      models = (await response.json()).models || [];
    } catch (error) {
      this.fail(error);
      return;
    }
    this.models = new Map();
    this.picker.innerHTML = '';
    const groups = { stream: 'progressive meshes', mesh: 'meshes (streamed on demand)', points: 'point sets', octree: 'point octrees', terrain: 'terrains' };
    for (const [kind, title] of Object.entries(groups)) {
      const group = document.createElement('optgroup');
      group.label = title;
      for (const model of models.filter((m) => m.kind === kind)) {
        const option = document.createElement('option');
        option.value = model.name;
        option.textContent = kind === 'octree'
          ? `${model.name}  (${model.points.toLocaleString('en-US')} points)`
          : `${model.name}  (${(model.bytes / 1024).toFixed(0)} KiB)`;
        if (kind === 'mesh' && !model.stream) {
          option.disabled = true;
          option.title = 'start lodkit serve with --simplify-on-demand to stream it';
        }
        group.appendChild(option);
      }
      if (group.children.length) this.picker.appendChild(group);
    }
    // Every model, the unreadable ones too: ?model= shows why one cannot be drawn.
    for (const model of models) this.models.set(model.name, model);
    const wanted = params.get('model');
    if (wanted && !this.models.has(wanted)) {
      // Never another model in its place: the address names one that is not there.
      this.resetStats('none', wanted);
      this.picker.value = '';
      this.fail(new Error(`${wanted}: not in this folder (pick a model from the list)`));
      return;
    }
    const first = models.find((m) => m.kind === 'stream') || models.find((m) => VIEWS[m.kind]);
    const name = wanted || (first && first.name);
    if (!name) {
      this.fail(new Error('no models to show in this directory'));
      return;
    }
    await this.open(name, params);
  }

  async open(name, params = new URLSearchParams(location.search)) {
    let model = this.models.get(name);
    if (!model) return;
    if (model.kind === 'mesh' && model.stream) model = { ...model, kind: 'stream', url: model.stream };
    const View = VIEWS[model.kind];
    this.picker.value = name;
    if (this.view) this.view.dispose();
    this.view = null;
    if (!View) {
      this.resetStats('none', name);
      // The index's messages name the file already.
      this.fail(new Error(model.error || `${name}: cannot show a model of kind "${model.kind}"`));
      return;
    }
    if (params.get('model') !== name && params.get('octree') !== name) {
      params = new URLSearchParams();
      params.set('model', name);
      history.replaceState(null, '', `?${params}`);
    }
    this.background = [1, 1, 1]; // lk_render_options_default; a view may change it
    this.view = new View(this);
    document.body.dataset.view = model.kind;
    try {
      await this.view.load(model, params);
    } catch (error) {
      this.fail(error);
    }
    this.requestDraw();
  }

  resize() {
    const ratio = window.devicePixelRatio || 1;
    const width = Math.max(1, Math.round(this.canvas.clientWidth * ratio));
    const height = Math.max(1, Math.round(this.canvas.clientHeight * ratio));
    if (this.canvas.width !== width || this.canvas.height !== height) {
      this.canvas.width = width;
      this.canvas.height = height;
    }
    this.gl.viewport(0, 0, width, height);
    return [width, height];
  }

  /** Draws now (the base mesh of a stream is drawn before more bytes are read). */
  drawNow() {
    if (!this.view) return;
    const [width, height] = this.resize();
    const started = performance.now();
    try {
      if (this.view.draw(width, height)) {
        // drawMs then counts the GPU's work too; a streaming view opts out
        // (finishEachFrame = false) so that the page's thread never waits
        // for the GPU while it refines.
        if (this.view.finishEachFrame !== false) this.gl.finish();
        this.stats.drawMs = (this.stats.drawMs || 0) + (performance.now() - started);
        this.stats.framesDrawn++;
        this.view.drawn();
      }
    } catch (error) {
      this.fail(error);
    }
    this.updateOverlay();
  }

  requestDraw() {
    if (this.scheduled) return;
    this.scheduled = true;
    requestAnimationFrame((time) => {
      this.scheduled = false;
      const seconds = this.lastFrame ? Math.min(0.1, (time - this.lastFrame) / 1000) : 0;
      this.lastFrame = time;
      const moving = this.view && this.view.step ? this.view.step(seconds) : false;
      this.drawNow();
      if (moving) this.requestDraw();
      else this.lastFrame = 0;
    });
  }

  updateOverlay() {
    if (this.overlayPending) return;
    this.overlayPending = true;
    // At most once per task: the overlay is text, the stats object is live.
    queueMicrotask(() => {
      this.overlayPending = false;
      const lines = [];
      if (this.view) lines.push(this.view.overlay());
      if (this.stats.error) lines.push(`error: ${this.stats.error}`);
      this.overlayElement.textContent = lines.join('\n');
      this.overlayElement.classList.toggle('error', !!this.stats.error);
    });
  }
}

try {
  const app = new App();
  window.viewer = app;
  app.start();
} catch (error) {
  window.viewerStats = { view: 'none', error: String(error.message || error), framesDrawn: 0 };
  document.getElementById('overlay').textContent = `error: ${error.message || error}`;
}
