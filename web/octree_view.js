// SPDX-License-Identifier: MIT
// Octree view: a point octree (`lodkit octree`, docs/formats.md "Point
// octree") streamed as the camera moves, under a point budget, drawn with
// the splat view's Phong splats (1 or 2 passes) and optional eye-dome
// lighting.
//
// Every redraw chooses nodes as lk_octree_select does (src/octree_select.c):
// from the root, the candidate of largest projected spacing (its spacing /
// distance to its centre, in pixels) is taken next and its children inside
// the view frustum become candidates, until the next would pass the budget
// or its spacing falls below 1 pixel. Missing nodes are fetched, at most
// MAX_REQUESTS at a time, by HTTP Range requests on the data file (any
// static server that honours Range will do) in a worker (web/
// octree_worker.js: CRC-32 check and decoding off the page's thread). The
// points held (uploaded plus in flight) never exceed the budget: nodes the
// selection no longer wants are evicted, least recently wanted first, and
// requests for them aborted, before anything new is asked for.
//
// Splat radii follow Potree's adaptive point size, as the C renderer's
// (lk_octree_load_selection): an inner node drawn alone keeps its points at
// least its spacing, so that it leaves no holes where its children are
// missing, but where its children are drawn too its points shrink to what
// the deepest drawn node there needs. The vertex shader walks the drawn
// nodes (src/shaders/splat_octree.vert.glsl, u_adaptive) in a one-row texture
// rebuilt when the drawn set changes.
//
// URL parameters: budget=N (points, default 1,000,000), passes=1|2,
// up=x|y|z, edl=1, size=F (splat radius scale), minpx=F (the projected
// spacing below which nodes are not refined, default 1; 0 lets the budget
// alone decide, as bench/octree_browser.mjs measures), adaptive=0 (every
// inner node's points at least its spacing, as when drawn alone).

import { SplatView } from './splat_view.js';
import { createProgram } from './gl.js';

const VERTEX_BYTES = 36; // web/octree_worker.js: xyz, normal, radius (float32), rgba (uint8), clip (int8 x 4)
const MAX_REQUESTS = 4;
const DEFAULT_BUDGET = 1000000;
const MIN_SPACING_PIXELS = 1; // lk_octree_select_options_default
const EDL_RADIUS = 1.4; // pixels (Potree's)
const DRAWN_NODES_UNIT = 2; // texture unit of u_drawn_nodes (0: the kernel or EDL colour, 1: EDL depth)

/* C = A * B, column-major 4x4. */
function multiply(a, b) {
  const c = new Float64Array(16);
  for (let col = 0; col < 4; col++)
    for (let row = 0; row < 4; row++) {
      let sum = 0;
      for (let k = 0; k < 4; k++) sum += a[k * 4 + row] * b[col * 4 + k];
      c[col * 4 + row] = sum;
    }
  return c;
}

/* Is the box [lo, hi] at least partly inside the clip matrix's six planes? (as box_in_frustum in C) */
function boxInFrustum(m, lo, hi) {
  for (let plane = 0; plane < 6; plane++) {
    const row = plane >> 1;
    const sign = plane & 1 ? -1 : 1;
    const p = [0, 1, 2, 3].map((col) => m[col * 4 + 3] + sign * m[col * 4 + row]);
    let far = p[3];
    for (let k = 0; k < 3; k++) far += p[k] * (p[k] >= 0 ? hi[k] : lo[k]);
    if (far < 0) return false;
  }
  return true;
}

/* A max-heap of [priority, node index]; ties to the lower index (as in C). */
class Heap {
  constructor() { this.items = []; }
  before(a, b) { return a[0] > b[0] || (a[0] === b[0] && a[1] < b[1]); }
  push(item) {
    const items = this.items;
    let i = items.length;
    items.push(item);
    while (i > 0) {
      const parent = (i - 1) >> 1;
      if (!this.before(item, items[parent])) break;
      items[i] = items[parent];
      i = parent;
    }
    items[i] = item;
  }
  pop() {
    const items = this.items;
    const top = items[0];
    const last = items.pop();
    if (items.length) {
      let i = 0;
      for (;;) {
        let child = 2 * i + 1;
        if (child >= items.length) break;
        if (child + 1 < items.length && this.before(items[child + 1], items[child])) child++;
        if (!this.before(items[child], last)) break;
        items[i] = items[child];
        i = child;
      }
      items[i] = last;
    }
    return top;
  }
  get size() { return this.items.length; }
}

export class OctreeView extends SplatView {
  constructor(app) {
    super(app);
    this.finishEachFrame = false; // never wait for the GPU while nodes stream in
    this.budget = DEFAULT_BUDGET;
    this.edl = false;
    this.nodes = [];
    this.selection = [];
    this.requests = new Map(); // id -> node
    this.nextRequest = 1;
    this.frame = 0;
    this.edlTarget = null;
  }

  async load(model, params) {
    const stats = this.app.resetStats('octree', model.name);
    Object.assign(stats, {
      points: 0, pointsDrawn: 0, pointsHeld: 0, maxPointsHeld: 0, budget: 0, nodes: 0, nodesSelected: 0,
      nodesDrawn: 0, nodesLoaded: 0, nodesEvicted: 0, rangeRequests: 0, partialResponses: 0, bytesReceived: 0,
      firstPointsMs: null, firstPointsNodes: null, firstPointsBytes: null, selectionPoints: 0, passes: 1, splatPath: '', edl: false, upAxis: 'y', radiusScale: 1,
    });
    const budget = Number(params.get('budget'));
    this.budget = Number.isFinite(budget) && budget >= 1 ? Math.floor(budget) : DEFAULT_BUDGET;
    const minPixels = params.get('minpx') === null ? NaN : Number(params.get('minpx'));
    this.minSpacingPixels = Number.isFinite(minPixels) && minPixels >= 0 ? minPixels : MIN_SPACING_PIXELS;
    this.passes = params.get('passes') === '2' ? 2 : 1;
    this.edl = params.get('edl') === '1';
    const size = Number(params.get('size'));
    this.radiusScale = Number.isFinite(size) && size > 0 ? size : 1;
    const up = params.get('up');
    this.camera.upAxis = up === 'z' || up === 'x' ? up : 'y';
    this.forcedTarget = params.get('target');
    Object.assign(stats, { budget: this.budget, edl: this.edl, upAxis: this.camera.upAxis, radiusScale: this.radiusScale });

    const indexUrl = new URL(model.url, location.href);
    const response = await fetch(indexUrl);
    if (!response.ok) throw new Error(`${model.url}: HTTP ${response.status}`);
    const index = await response.json();
    // version 1 stored inner nodes' radii already floored at their spacing; flooring again changes nothing
    if (index.format !== 'lodkit point octree' || !(index.version === 1 || index.version === 2) || !Array.isArray(index.nodes))
      throw new Error(`${model.url}: not a lodkit point octree index (versions 1 and 2 are read)`);
    this.dataUrl = new URL(index.data, indexUrl).href;
    this.readIndex(index);
    stats.totalPoints = index.points;
    stats.nodes = this.nodes.length;

    // the adaptive radii read a texture in the vertex shader
    this.maxTextureSize = this.gl.getParameter(this.gl.MAX_TEXTURE_SIZE);
    this.adaptiveSupported = this.gl.getParameter(this.gl.MAX_VERTEX_TEXTURE_IMAGE_UNITS) > 0;
    this.adaptive = params.get('adaptive') !== '0' && this.adaptiveSupported;
    stats.adaptive = this.adaptive;
    // the walk's program declares a vertex texture; without vertex textures, the plain one
    this.splatVertexShader = this.adaptiveSupported ? 'splat_octree.vert' : 'splat.vert';
    this.buildControls();
    await this.prepare();
    this.pointSizeRange = this.gl.getParameter(this.gl.ALIASED_POINT_SIZE_RANGE);
    stats.pointSizeRange = [this.pointSizeRange[0], this.pointSizeRange[1]];
    if (this.gl.getExtension('WEBGL_depth_texture'))
      this.programs.edl = await createProgram(this.gl, 'fullscreen.vert', 'edl.frag', ['a_position']);
    this.worker = new Worker(new URL('./octree_worker.js', import.meta.url), { type: 'module' });
    this.worker.onmessage = (event) => this.received(event.data);
    this.worker.onerror = (event) => this.app.fail(new Error(`octree worker: ${event.message || 'failed'}`));
    this.app.requestDraw();
  }

  /* Nodes with their cubes (relative to the offset), children and record layout. */
  readIndex(index) {
    const attributes = index.attributes || [];
    let at = 0;
    const layout = { rgb: -1, normal: -1, radius: -1, clip: -1 };
    for (const attribute of attributes) {
      if (attribute.name === 'rgb') layout.rgb = at;
      if (attribute.name === 'normal') layout.normal = at;
      if (attribute.name === 'radius') layout.radius = at;
      if (attribute.name === 'clip') layout.clip = at;
      at += attribute.bytes;
    }
    if (at !== index.stride) throw new Error(`octree index: attributes add up to ${at} bytes, stride says ${index.stride}`);
    if (layout.normal < 0) throw new Error('the octree has no normals, which splats need (lodkit octree --estimate-normals)');
    this.layout = layout;
    this.stride = index.stride;
    this.scale = index.scale;
    this.spacing = index.spacing;
    const byName = new Map();
    this.byName = byName;
    this.nodes = index.nodes.map((entry, i) => {
      let min = [0, 0, 0];
      let size = index.cube_size;
      for (const digit of entry.name.slice(1)) {
        size /= 2;
        const d = Number(digit);
        min = [min[0] + (d & 4 ? size : 0), min[1] + (d & 2 ? size : 0), min[2] + (d & 1 ? size : 0)];
      }
      const node = {
        index: i, name: entry.name, level: entry.name.length - 1, points: entry.points, offset: entry.offset,
        length: entry.length, crc32: entry.crc32, min, max: min.map((v) => v + size), size,
        children: [], childMask: 0, state: 'none', buffer: null, request: 0, wanted: 0, texel: -1,
      };
      byName.set(node.name, node);
      const parent = byName.get(node.name.slice(0, -1));
      if (parent) {
        parent.children.push(node);
        parent.childMask |= 1 << Number(node.name[node.name.length - 1]);
      }
      return node;
    });
    if (!this.nodes.length || this.nodes[0].name !== 'r') throw new Error('octree index: no root node "r"');
    const lo = index.bounds.min.map((v, k) => v - index.offset[k]);
    const hi = index.bounds.max.map((v, k) => v - index.offset[k]);
    this.camera.frame(lo, hi);
  }

  /* lk_octree_select for the camera's current view. */
  select(m, height) {
    const clip = multiply(m.projection, m.view);
    const pixelsPerUnit = (0.5 * height) / Math.tan((0.5 * this.camera.fovY * Math.PI) / 180);
    const priority = (node) => {
      const half = node.size / 2;
      const d = Math.hypot(node.min[0] + half - m.eye[0], node.min[1] + half - m.eye[1], node.min[2] + half - m.eye[2]);
      if (d <= half * Math.sqrt(3)) return Infinity;
      return ((this.spacing / 2 ** node.level) / d) * pixelsPerUnit;
    };
    const heap = new Heap();
    heap.push([priority(this.nodes[0]), 0]);
    const taken = [];
    let points = 0;
    while (heap.size) {
      const [spacingPixels, i] = heap.pop();
      const node = this.nodes[i];
      if (node.level > 0 && spacingPixels < this.minSpacingPixels) continue;
      if (points + node.points > this.budget) break;
      taken.push(node);
      points += node.points;
      for (const child of node.children)
        if (boxInFrustum(clip, child.min, child.max)) heap.push([priority(child), child.index]);
    }
    return { taken, points };
  }

  held() {
    let sum = 0;
    for (const node of this.nodes) if (node.state !== 'none') sum += node.points;
    return sum;
  }

  evict(node) {
    if (node.state === 'loaded' && node.buffer) {
      this.gl.deleteBuffer(node.buffer);
      node.buffer = null;
      this.app.stats.nodesEvicted++;
    } else if (node.state === 'pending') {
      this.worker.postMessage({ abort: node.request });
      this.requests.delete(node.request);
    }
    node.state = 'none';
  }

  /* Chooses, evicts and requests for this frame; the budget bounds what is held. */
  update(m, height) {
    const stats = this.app.stats;
    this.frame++;
    const { taken, points } = this.select(m, height);
    for (const node of taken) node.wanted = this.frame;
    this.selection = taken;
    stats.nodesSelected = taken.length;
    stats.selectionPoints = points;
    this.requestMissing();
  }

  /* Evicts what the selection no longer wants while over the budget, then
   * asks for the selection's missing nodes (largest projected spacing
   * first) while requests and the budget allow. Runs after each selection
   * and after each node arrives, so that a slow frame never starves the
   * requests. */
  requestMissing() {
    const stats = this.app.stats;
    // Unwanted nodes held, least recently wanted first, deepest first among equals.
    const unwanted = this.nodes.filter((node) => node.state !== 'none' && node.wanted !== this.frame)
      .sort((a, b) => a.wanted - b.wanted || b.level - a.level);
    let held = this.held();
    while (held > this.budget && unwanted.length) {
      const node = unwanted.shift();
      held -= node.points;
      this.evict(node);
    }
    for (const node of this.selection) {
      if (node.state !== 'none' || node.failed) continue;
      if (this.requests.size >= MAX_REQUESTS) break;
      while (held + node.points > this.budget && unwanted.length) {
        const old = unwanted.shift();
        held -= old.points;
        this.evict(old);
      }
      if (held + node.points > this.budget) break; // waits for requests of an older view
      if (node.points === 0) {
        node.state = 'loaded'; // nothing to fetch (an upper node whose points all moved down)
        continue;
      }
      held += node.points;
      this.request(node);
    }
    stats.pointsHeld = held;
    stats.maxPointsHeld = Math.max(stats.maxPointsHeld, held);
  }

  request(node) {
    const id = this.nextRequest++;
    node.state = 'pending';
    node.request = id;
    this.requests.set(id, node);
    this.app.stats.rangeRequests++;
    this.worker.postMessage({
      id, url: this.dataUrl, name: node.name, offset: node.offset, length: node.length, points: node.points,
      stride: this.stride, scale: this.scale, layout: this.layout, crc32: node.crc32, spacing: this.spacing / 2 ** node.level,
    });
  }

  received(message) {
    const node = this.requests.get(message.id);
    if (!node) return; // evicted while in flight
    this.requests.delete(message.id);
    if (message.error) {
      node.state = 'none';
      if (!message.aborted) {
        node.failed = true; // not asked for again: the error is shown
        this.app.fail(new Error(message.error));
      }
      this.requestMissing();
      return;
    }
    const gl = this.gl;
    const stats = this.app.stats;
    node.buffer = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, node.buffer);
    gl.bufferData(gl.ARRAY_BUFFER, message.vertices, gl.STATIC_DRAW);
    node.clipped = message.clipped;
    node.state = 'loaded';
    stats.nodesLoaded++;
    stats.bytesReceived += message.bytes;
    if (message.status === 206) stats.partialResponses++;
    this.requestMissing();
    this.app.requestDraw();
  }

  hasPoints() {
    return this.selection.some((node) => node.state === 'loaded' && node.points > 0);
  }

  /* The drawn nodes' texture for the adaptive radii (u_drawn_nodes): one
   * texel per node of the selection that is loaded, children after their
   * parent and contiguous in digit order (breadth first from each drawn node
   * whose parent is not drawn). Returns the texel count, or 0 when the
   * nodes do not fit a row (then every node is drawn with its own floor). */
  updateDrawnNodes() {
    const gl = this.gl;
    const drawn = new Set(this.selection.filter((node) => node.state === 'loaded'));
    const order = [];
    for (const node of this.nodes) node.texel = -1;
    const parentOf = (node) => this.byName.get(node.name.slice(0, -1));
    for (const node of drawn) {
      if (node.level > 0 && drawn.has(parentOf(node))) continue;
      node.texel = order.length;
      order.push(node);
    }
    const firstChild = [];
    for (let i = 0; i < order.length; i++) {
      const node = order[i];
      firstChild[i] = order.length;
      const children = node.children.filter((child) => drawn.has(child))
        .sort((a, b) => (a.name < b.name ? -1 : 1));
      for (const child of children) {
        child.texel = order.length;
        order.push(child);
      }
    }
    const width = order.length;
    if (!width || width > Math.min(65535, this.maxTextureSize)) return 0;
    const texels = new Uint8Array(4 * width);
    order.forEach((node, i) => {
      let drawnMask = 0;
      for (const child of node.children) if (drawn.has(child)) drawnMask |= 1 << Number(child.name[child.name.length - 1]);
      texels[4 * i] = drawnMask;
      texels[4 * i + 1] = node.childMask;
      texels[4 * i + 2] = firstChild[i] >> 8;
      texels[4 * i + 3] = firstChild[i] & 255;
    });
    if (!this.drawnTexture) this.drawnTexture = gl.createTexture();
    gl.activeTexture(gl.TEXTURE0 + DRAWN_NODES_UNIT);
    gl.bindTexture(gl.TEXTURE_2D, this.drawnTexture);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA, width, 1, 0, gl.RGBA, gl.UNSIGNED_BYTE, texels);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    gl.activeTexture(gl.TEXTURE0);
    return width;
  }

  /** Every loaded node of the selection, one draw call each. */
  drawPoints() {
    const gl = this.gl;
    const program = this.program;
    const adaptive = this.drawnWidth > 0; // updateDrawnNodes, once a frame (drawPoints runs once a pass)
    gl.uniform1f(program.uniform('u_adaptive'), adaptive ? 1 : 0);
    if (adaptive) {
      gl.activeTexture(gl.TEXTURE0 + DRAWN_NODES_UNIT);
      gl.bindTexture(gl.TEXTURE_2D, this.drawnTexture);
      gl.activeTexture(gl.TEXTURE0);
      gl.uniform1i(program.uniform('u_drawn_nodes'), DRAWN_NODES_UNIT);
      gl.uniform1f(program.uniform('u_drawn_width'), this.drawnWidth);
    }
    let shrunk = 0;
    let points = 0;
    let nodes = 0;
    let clipped = 0;
    gl.enableVertexAttribArray(0);
    gl.enableVertexAttribArray(1);
    gl.enableVertexAttribArray(2);
    gl.enableVertexAttribArray(3);
    // The nodes' clip lines cut border splats at the border (zeros, which
    // cut nothing, when the octree has none).
    gl.enableVertexAttribArray(4);
    for (const node of this.selection) {
      if (node.state !== 'loaded' || !node.buffer) continue;
      gl.bindBuffer(gl.ARRAY_BUFFER, node.buffer);
      gl.vertexAttribPointer(0, 3, gl.FLOAT, false, VERTEX_BYTES, 0);
      gl.vertexAttribPointer(1, 3, gl.FLOAT, false, VERTEX_BYTES, 12);
      gl.vertexAttribPointer(2, 1, gl.FLOAT, false, VERTEX_BYTES, 24);
      gl.vertexAttribPointer(3, 4, gl.UNSIGNED_BYTE, true, VERTEX_BYTES, 28);
      gl.vertexAttribPointer(4, 4, gl.BYTE, true, VERTEX_BYTES, 32);
      const spacing = this.spacing / 2 ** node.level;
      gl.uniform1f(program.uniform('u_radius_floor'), node.childMask ? spacing : 0);
      if (adaptive) {
        const half = node.size / 2;
        gl.uniform1f(program.uniform('u_node_texel'), node.texel);
        gl.uniform4f(program.uniform('u_node_cube'), node.min[0] + half, node.min[1] + half, node.min[2] + half, half);
        gl.uniform1f(program.uniform('u_node_spacing'), spacing);
        if (node.childMask && node.children.some((child) => child.texel >= 0)) shrunk += node.points;
      }
      gl.drawArrays(gl.POINTS, 0, node.points);
      points += node.points;
      clipped += node.clipped || 0;
      nodes++;
    }
    this.app.stats.clippedPoints = clipped; // drawn with a clip line (border splats)
    // points of drawn nodes with drawn children: their radii may shrink (adaptive)
    this.app.stats.adaptivePoints = shrunk;
    this.app.stats.adaptive = adaptive;
    gl.uniform1f(program.uniform('u_adaptive'), 0);
    gl.uniform1f(program.uniform('u_radius_floor'), 0);
    this.app.stats.pointsDrawn = this.app.stats.points = points;
    this.app.stats.nodesDrawn = nodes;
  }

  /* Colour texture + depth texture of the viewport for eye-dome lighting. */
  chooseEdlTarget(width, height) {
    const gl = this.gl;
    if (this.edlTarget && this.edlTarget.width === width && this.edlTarget.height === height) return this.edlTarget;
    this.deleteEdlTarget();
    const depthExtension = gl.getExtension('WEBGL_depth_texture');
    if (!depthExtension || !this.programs.edl) return null;
    const texture = (format, type) => {
      const t = gl.createTexture();
      gl.bindTexture(gl.TEXTURE_2D, t);
      gl.texImage2D(gl.TEXTURE_2D, 0, format, width, height, 0, format, type, null);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
      return t;
    };
    const color = texture(gl.RGBA, gl.UNSIGNED_BYTE);
    const depth = texture(gl.DEPTH_COMPONENT, gl.UNSIGNED_INT);
    gl.bindTexture(gl.TEXTURE_2D, null);
    const framebuffer = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, framebuffer);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, color, 0);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.DEPTH_ATTACHMENT, gl.TEXTURE_2D, depth, 0);
    const ok = gl.checkFramebufferStatus(gl.FRAMEBUFFER) === gl.FRAMEBUFFER_COMPLETE;
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    this.edlTarget = { color, depth, framebuffer, width, height };
    if (!ok) {
      this.deleteEdlTarget();
      this.edlFailed = true;
    }
    return this.edlTarget;
  }

  deleteEdlTarget() {
    if (!this.edlTarget) return;
    const gl = this.gl;
    gl.deleteFramebuffer(this.edlTarget.framebuffer);
    gl.deleteTexture(this.edlTarget.color);
    gl.deleteTexture(this.edlTarget.depth);
    this.edlTarget = null;
  }

  draw(width, height) {
    const gl = this.gl;
    const stats = this.app.stats;
    if (this.nodes.length) this.update(this.camera.matrices(width, height), height);
    this.drawnWidth = this.adaptive ? this.updateDrawnNodes() : 0;
    const edl = this.edl && !this.edlFailed ? this.chooseEdlTarget(width, height) : null;
    this.outputFramebuffer = edl ? edl.framebuffer : null;
    const drew = super.draw(width, height);
    this.outputFramebuffer = null;
    stats.edl = !!(edl && drew);
    if (!drew) {
      stats.pointsDrawn = stats.points = 0;
      return false;
    }
    if (stats.firstPointsMs === null && stats.pointsDrawn > 0) {
      stats.firstPointsMs = performance.now() - this.app.loadStart;
      stats.firstPointsSinceNavigationMs = performance.now();
      stats.firstPointsNodes = stats.nodesLoaded; // how many nodes had arrived when the first points were drawn
      stats.firstPointsBytes = stats.bytesReceived;
    }
    if (edl) this.drawEyeDome(edl, width, height);
    return true;
  }

  drawEyeDome(edl, width, height) {
    const gl = this.gl;
    const m = this.camera.matrices(width, height);
    if (this.app.stats.passes === 2) {
      // the normalisation pass wrote colour only: lay the splats' depth under it
      gl.bindFramebuffer(gl.FRAMEBUFFER, edl.framebuffer);
      gl.clear(gl.DEPTH_BUFFER_BIT);
      gl.colorMask(false, false, false, false);
      gl.enable(gl.DEPTH_TEST);
      gl.depthFunc(gl.LESS);
      gl.depthMask(true);
      this.setUniforms(this.programs.visibility, m, width, height, 0);
      this.drawPoints();
      this.unbind();
    }
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.viewport(0, 0, width, height);
    gl.disable(gl.DEPTH_TEST);
    gl.disable(gl.BLEND);
    const program = this.programs.edl;
    gl.useProgram(program.program);
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D, edl.color);
    gl.uniform1i(program.uniform('u_color'), 0);
    gl.activeTexture(gl.TEXTURE1);
    gl.bindTexture(gl.TEXTURE_2D, edl.depth);
    gl.uniform1i(program.uniform('u_depth'), 1);
    gl.uniform2f(program.uniform('u_texel'), EDL_RADIUS / width, EDL_RADIUS / height);
    gl.uniform1f(program.uniform('u_near'), m.near);
    gl.uniform1f(program.uniform('u_far'), m.far);
    gl.uniform1f(program.uniform('u_strength'), 1);
    for (let location = 1; location < 5; location++) gl.disableVertexAttribArray(location);
    gl.bindBuffer(gl.ARRAY_BUFFER, this.fullscreen);
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 2, gl.FLOAT, false, 0, 0);
    gl.drawArrays(gl.TRIANGLES, 0, 3);
    gl.bindTexture(gl.TEXTURE_2D, null);
    gl.activeTexture(gl.TEXTURE0);
    this.unbind();
  }

  buildControls() {
    super.buildControls();
    const box = this.app.controls;
    const add = (labelText, input, output) => {
      const label = document.createElement('label');
      label.append(` ${labelText} `, input);
      if (output) label.append(' ', output);
      box.appendChild(label);
    };
    const budget = document.createElement('input');
    budget.style.width = '9em';
    Object.assign(budget, { type: 'range', id: 'budget', min: 100000, max: 5000000, step: 100000, value: this.budget });
    const budgetText = document.createElement('output');
    budgetText.textContent = this.budget.toLocaleString('en-US');
    budget.addEventListener('input', () => {
      this.budget = Number(budget.value);
      this.app.stats.budget = this.budget;
      budgetText.textContent = this.budget.toLocaleString('en-US');
      this.app.requestDraw();
    });
    add('budget', budget, budgetText);
    const size = document.createElement('input');
    size.style.width = '6em';
    Object.assign(size, { type: 'range', id: 'point-size', min: 0.25, max: 4, step: 0.05, value: this.radiusScale });
    size.addEventListener('input', () => {
      this.radiusScale = this.app.stats.radiusScale = Number(size.value);
      this.app.requestDraw();
    });
    add('point size', size);
    const up = document.createElement('select');
    up.id = 'up-axis';
    for (const axis of ['y', 'z', 'x']) up.append(new Option(`${axis} up`, axis, false, axis === this.camera.upAxis));
    up.addEventListener('change', () => {
      this.camera.upAxis = this.app.stats.upAxis = up.value;
      this.app.requestDraw();
    });
    add('', up);
    const edl = document.createElement('input');
    Object.assign(edl, { type: 'checkbox', id: 'edl', checked: this.edl });
    edl.addEventListener('change', () => {
      this.edl = edl.checked;
      this.app.requestDraw();
    });
    add('eye-dome lighting', edl);
    const adaptive = document.createElement('input');
    Object.assign(adaptive, { type: 'checkbox', id: 'adaptive', checked: this.adaptive, disabled: !this.adaptiveSupported });
    adaptive.title = 'shrink the points of nodes whose children are drawn too (Potree\'s adaptive point size)';
    adaptive.addEventListener('change', () => {
      this.adaptive = this.app.stats.adaptive = adaptive.checked;
      this.app.requestDraw();
    });
    add('adaptive size', adaptive);
  }

  overlay() {
    const s = this.app.stats;
    const n = (value) => (value || 0).toLocaleString('en-US');
    return [
      `points ${n(s.pointsDrawn)} drawn, ${n(s.pointsHeld)} held of a ${n(s.budget)} budget (${n(s.totalPoints)} in the octree)`,
      `nodes ${n(s.nodesDrawn)} drawn of ${n(s.nodesSelected)} chosen, ${n(s.rangeRequests)} Range requests, ${(s.bytesReceived / 1048576).toFixed(1)} MiB`,
      `path: ${s.splatPath || '–'}${s.edl ? ', eye-dome lighting' : ''}${s.adaptive ? ', adaptive size' : ''}`,
    ].join('\n');
  }

  dispose() {
    if (this.worker) this.worker.terminate();
    for (const node of this.nodes) if (node.buffer) this.gl.deleteBuffer(node.buffer);
    this.deleteEdlTarget();
    super.dispose();
  }
}
