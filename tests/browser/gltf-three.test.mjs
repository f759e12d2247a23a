// SPDX-License-Identifier: MIT
// three.js loads every glTF lodkit writes (issue 20), run by
// tests/cli/test_gltf_three.sh:
//   node gltf-three.test.mjs DIR MANIFEST [SHOTS_DIR]
// MANIFEST is JSON: {"files": [ENTRY, ...]}, each ENTRY a file in DIR and
// what three.js must see in it:
//   file        path inside DIR (.glb, or .gltf with its resources beside it)
//   kind        "mesh" (triangles) or "points" (a THREE.Points, no triangles)
//   meshes      number of meshes / point sets in gltf.scene
//   scene       true: a scene of several primitives (attributes is their union)
//   vertices    sum of their position attribute counts
//   triangles   sum of index count / 3 (position count / 3 without indices)
//   attributes  which of "normal", "uv", "color" exist (the others must not)
//   bbox        {"min": [x,y,z], "max": [x,y,z]}: the world-space bounding box
//               of the decoded vertices must match within 0.1% of its diagonal
//   quantized   true: positions stay unsigned shorts (KHR_mesh_quantization),
//               placed by the node's scale and translation; a skinned mesh's
//               stay floats (its node's transform does not apply)
//   bboxOf      instead of bbox: the box three.js saw for that earlier file
//               (a skinned mesh is posed by its joints, which lodkit's own
//               box, the rest pose placed by the nodes, does not do)
//   meshopt     true: three's MeshoptDecoder decoded the buffer views
//   skinned     number of THREE.SkinnedMesh among the meshes (the others plain)
//   lines       line segments of the THREE.LineSegments among the meshes (their
//               vertices are not in `vertices`)
//   offBox      true: an input (not lodkit's) that three.js draws outside the
//               box it computes for it (a skinned mesh under a transformed
//               parent: GLTFLoader binds it with the parent's matrix, which
//               glTF says does not apply); checked to stay so
//   animations  number of animation clips GLTFLoader must make
//   levels      MSFT_lod: number of levels. three.js ignores the extension:
//               gltf.scene holds level 0 only; the coarser levels are loaded
//               with gltf.parser.getDependency('node', id) for the ids in
//               MSFT_lod, each with the triangle count of its
//               extras.lodkit.triangles
// Each file is also drawn into a 128x128 canvas by a camera framing the
// expected box; the picture must differ from the background (a mesh placed
// wrongly, e.g. with the node's scale ignored, is not drawn there).
// The page (served with three's modules from node_modules through an import
// map by a node http server on 127.0.0.1) runs in Debian's /usr/bin/chromium,
// headless, driven by playwright-core. Prints one line per file (and per
// coarser level) and exits 1 when any check fails.

import { launchChromium } from './chromium.mjs';
import fs from 'node:fs';
import http from 'node:http';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const HARD_TIMEOUT_MS = 50000;
const CANVAS_SIZE = 128;
const MIN_DRAWN_SHARE = 0.02; // of the canvas' pixels
const BBOX_TOLERANCE = 0.001; // of the expected box's diagonal
const LEVEL_BBOX_TOLERANCE = 0.05; // coarser levels move vertices a little

const [dirArgument, manifestPath, shotsDir] = process.argv.slice(2);
if (!dirArgument || !manifestPath) {
  console.error('usage: node gltf-three.test.mjs DIR MANIFEST [SHOTS_DIR]');
  process.exit(2);
}
const dir = path.resolve(dirArgument);
const threeDir = path.join(path.dirname(fileURLToPath(import.meta.url)), 'node_modules', 'three');
const started = Date.now();
const seconds = () => ((Date.now() - started) / 1000).toFixed(1);
let failures = 0;
let checks = 0;
let browser = null;
let profile = null;
let server = null;

const hardTimeout = setTimeout(async () => {
  console.log(`not ok - the three.js tests took more than ${HARD_TIMEOUT_MS / 1000} s`);
  try { if (browser) await browser.close(); } catch { /* exiting anyway */ }
  process.exit(1);
}, HARD_TIMEOUT_MS);

/* One line per file: ok with what was seen, or not ok with every mismatch. */
function report(name, problems, seen) {
  checks++;
  if (problems.length === 0) console.log(`ok - ${name}: ${seen}`);
  else {
    failures++;
    console.log(`not ok - ${name}: ${problems.join('; ')} (seen: ${seen})`);
  }
}

// ---- the http server: the page, three's modules, the files under test -----
const PAGE = `<!doctype html>
<html><head><meta charset="utf-8"><title>lodkit glTF in three.js</title>
<script type="importmap">
{"imports": {"three": "/three/build/three.module.js", "three/examples/jsm/": "/three/examples/jsm/"}}
</script></head>
<body><canvas id="view" width="${CANVAS_SIZE}" height="${CANVAS_SIZE}"></canvas></body></html>
`;
const TYPES = {
  '.js': 'text/javascript', '.glb': 'model/gltf-binary', '.gltf': 'model/gltf+json',
  '.bin': 'application/octet-stream', '.png': 'image/png', '.jpg': 'image/jpeg',
};

/* The file under ROOT that URL path REST names, or null when it leaves ROOT. */
function inside(root, rest) {
  let decoded;
  try { decoded = decodeURIComponent(rest); } catch { return null; }
  const file = path.resolve(root, '.' + path.posix.normalize('/' + decoded));
  return file.startsWith(root + path.sep) ? file : null;
}

function serve(request, response) {
  const url = new URL(request.url, 'http://127.0.0.1');
  let file = null;
  if (url.pathname === '/') {
    response.writeHead(200, { 'Content-Type': 'text/html; charset=utf-8' });
    response.end(PAGE);
    return;
  }
  if (url.pathname === '/favicon.ico') {
    response.writeHead(204);
    response.end();
    return;
  }
  if (url.pathname.startsWith('/three/')) file = inside(threeDir, url.pathname.slice('/three/'.length));
  else if (url.pathname.startsWith('/files/')) file = inside(dir, url.pathname.slice('/files/'.length));
  fs.readFile(file || '', (error, body) => {
    if (!file || error) {
      response.writeHead(404, { 'Content-Type': 'text/plain' });
      response.end(`${url.pathname}: not found\n`);
      return;
    }
    response.writeHead(200, { 'Content-Type': TYPES[path.extname(file)] || 'application/octet-stream' });
    response.end(body);
  });
}

// ---- in the page -------------------------------------------------------------
/* Imports three through the page's import map; one renderer for every file. */
async function setUpPage(canvasSize) {
  const THREE = await import('three');
  const { GLTFLoader } = await import('three/examples/jsm/loaders/GLTFLoader.js');
  const { MeshoptDecoder } = await import('three/examples/jsm/libs/meshopt_decoder.module.js');
  const canvas = document.getElementById('view');
  const renderer = new THREE.WebGLRenderer({ canvas, preserveDrawingBuffer: true, antialias: false });
  renderer.setPixelRatio(1);
  renderer.setSize(canvasSize, canvasSize, false);
  renderer.setClearColor(0x708090, 1); // glTF's default material is metallic: black without an environment
  // Counts the views three's decoder decodes (GLTFLoader calls this one).
  const decoder = {
    supported: MeshoptDecoder.supported,
    ready: MeshoptDecoder.ready,
    decodeGltfBufferAsync(...args) {
      window.lodkitThree.decodedViews++;
      return MeshoptDecoder.decodeGltfBufferAsync(...args);
    },
  };
  const loader = new GLTFLoader().setMeshoptDecoder(decoder);
  const gl = renderer.getContext();
  const pixels = new Uint8Array(4 * canvasSize * canvasSize);
  const read = () => {
    gl.readPixels(0, 0, canvasSize, canvasSize, gl.RGBA, gl.UNSIGNED_BYTE, pixels);
    return pixels;
  };
  const camera = new THREE.PerspectiveCamera(40, 1, 0.01, 100);
  renderer.render(new THREE.Scene(), camera);
  const background = Array.from(read().subarray(0, 3));
  window.lodkitThree = { THREE, loader, renderer, camera, read, background, decodedViews: 0, revision: THREE.REVISION };
  return { revision: THREE.REVISION, meshoptSupported: MeshoptDecoder.supported, background };
}

/* Loads URL, and returns what three.js made of it (compared in node). */
async function inspectInPage({ url, box, picture }) {
  const { THREE, loader, renderer, camera, read, background } = window.lodkitThree;
  window.lodkitThree.decodedViews = 0;
  const vector = (v) => [v.x, v.y, v.z];

  const describe = (root) => {
    root.updateMatrixWorld(true);
    const meshes = [];
    root.traverse((object) => {
      if (!object.isMesh && !object.isPoints && !object.isLineSegments) return;
      const geometry = object.geometry;
      const position = geometry.getAttribute('position');
      const index = geometry.getIndex();
      const corners = index ? index.count : position ? position.count : 0;
      meshes.push({
        type: object.isPoints ? 'Points' : object.isMesh ? 'Mesh' : object.isLineSegments ? 'LineSegments' : object.type,
        skinned: Boolean(object.isSkinnedMesh),
        vertices: position ? position.count : 0,
        triangles: object.isMesh ? corners / 3 : 0,
        lines: object.isLineSegments ? corners / 2 : 0,
        attributes: Object.keys(geometry.attributes).sort(),
        positionType: position ? position.array.constructor.name : 'none',
        morphTargets: (geometry.morphAttributes.position || []).length,
      });
    });
    const bounds = new THREE.Box3().setFromObject(root, true);
    return { meshes, bbox: bounds.isEmpty() ? null : { min: vector(bounds.min), max: vector(bounds.max) } };
  };

  // The share of pixels that differ from the background, ROOT drawn by a
  // camera framing the expected box (not the box three computed).
  const draw = (root) => {
    const min = new THREE.Vector3(...box.min);
    const max = new THREE.Vector3(...box.max);
    const centre = min.clone().add(max).multiplyScalar(0.5);
    const radius = Math.max(1e-9, 0.5 * min.distanceTo(max));
    const distance = radius / Math.sin(THREE.MathUtils.degToRad(camera.fov / 2));
    camera.position.copy(centre).add(new THREE.Vector3(0.55, 0.35, 0.75).normalize().multiplyScalar(distance));
    camera.near = distance / 100;
    camera.far = distance * 4;
    camera.lookAt(centre);
    camera.updateProjectionMatrix();
    const scene = new THREE.Scene();
    scene.add(new THREE.HemisphereLight(0xffffff, 0x404040, 3));
    const parent = root.parent;
    scene.add(root);
    renderer.render(scene, camera);
    const pixels = read();
    let differing = 0;
    for (let i = 0; i < pixels.length; i += 4) {
      if (Math.abs(pixels[i] - background[0]) > 24 || Math.abs(pixels[i + 1] - background[1]) > 24 ||
          Math.abs(pixels[i + 2] - background[2]) > 24) differing++;
    }
    const image = picture ? renderer.domElement.toDataURL('image/png') : null;
    scene.remove(root);
    if (parent) parent.add(root);
    return { drawn: differing / (pixels.length / 4), image };
  };

  let gltf;
  try {
    gltf = await loader.loadAsync(url);
  } catch (error) {
    return { error: String(error && error.message ? error.message : error) };
  }
  const json = gltf.parser.json;
  const declared = {
    morphTargets: (json.meshes || []).reduce((sum, mesh) => sum + mesh.primitives.reduce((n, p) => n + (p.targets || []).length, 0), 0),
    animations: (json.animations || []).length,
  };
  const result = { ...describe(gltf.scene), declared, animations: gltf.animations.length, levels: null };
  Object.assign(result, draw(gltf.scene));
  const sceneNodes = (json.scenes && json.scenes[json.scene || 0] && json.scenes[json.scene || 0].nodes) || [];
  const lod = sceneNodes.length === 1 && json.nodes[sceneNodes[0]].extensions && json.nodes[sceneNodes[0]].extensions.MSFT_lod;
  if (lod) {
    result.levels = [];
    const levelNodes = [sceneNodes[0], ...lod.ids];
    for (let level = 0; level < levelNodes.length; level++) {
      const id = levelNodes[level];
      const extras = (json.nodes[id].extras && json.nodes[id].extras.lodkit) || {};
      // level 0 is the scene's node: the object in gltf.scene, as loaded
      const node = await gltf.parser.getDependency('node', id);
      const seen = describe(node);
      const { drawn } = draw(node);
      result.levels.push({ node: id, declaredLevel: extras.level, declaredTriangles: extras.triangles, ...seen, drawn,
        inScene: gltf.scene.getObjectById(node.id) !== undefined });
    }
  }
  result.decodedViews = window.lodkitThree.decodedViews;
  return result;
}

// ---- in node: compare ----------------------------------------------------------
const sum = (meshes, key) => meshes.reduce((total, mesh) => total + mesh[key], 0);

/* How far the corners of box SEEN are from those of EXPECTED, in parts of
 * the expected diagonal. */
function boxDistance(seen, expected) {
  const diagonal = Math.hypot(...expected.max.map((value, a) => value - expected.min[a]));
  let worst = 0;
  for (let a = 0; a < 3; a++) {
    worst = Math.max(worst, Math.abs(seen.min[a] - expected.min[a]), Math.abs(seen.max[a] - expected.max[a]));
  }
  return diagonal > 0 ? worst / diagonal : worst;
}

function boxProblem(seen, expected, tolerance) {
  if (!seen) return 'no bounding box (nothing decoded)';
  const share = boxDistance(seen, expected);
  return share <= tolerance ? null :
    `bbox [${seen.min.map((v) => v.toPrecision(6))}]..[${seen.max.map((v) => v.toPrecision(6))}] is off by ` +
    `${(100 * share).toPrecision(3)}% of the diagonal (expected [${expected.min}]..[${expected.max}], ` +
    `tolerance ${100 * tolerance}%)`;
}

function compare(entry, seen) {
  const problems = [];
  if (seen.error) return { problems: [`GLTFLoader failed: ${seen.error}`], summary: 'nothing' };
  const meshes = seen.meshes;
  // line primitives (THREE.LineSegments) count as meshes of the scene; their
  // vertices are not lodkit's mesh's, their segments are checked apart
  const drawn = meshes.filter((mesh) => mesh.type !== 'LineSegments');
  const vertices = sum(drawn, 'vertices');
  const triangles = sum(drawn, 'triangles');
  const lines = sum(meshes, 'lines');
  const expectType = entry.kind === 'points' ? 'Points' : 'Mesh';
  if (meshes.length !== entry.meshes) problems.push(`${meshes.length} meshes in the scene, expected ${entry.meshes}`);
  if (lines !== (entry.lines || 0)) problems.push(`${lines} line segments, expected ${entry.lines || 0}`);
  const wrongType = drawn.filter((mesh) => mesh.type !== expectType);
  if (wrongType.length) problems.push(`${wrongType.map((mesh) => mesh.type).join(',')} where a THREE.${expectType} was expected`);
  if (vertices !== entry.vertices) problems.push(`${vertices} vertices, expected ${entry.vertices}`);
  if (triangles !== entry.triangles) problems.push(`${triangles} triangles, expected ${entry.triangles}`);
  for (const name of ['normal', 'uv', 'color']) {
    const wanted = entry.attributes.includes(name);
    // a scene's primitives may differ: then some mesh must have each listed
    // attribute and none an unlisted one
    const missing = entry.scene
      ? (wanted ? (meshes.some((mesh) => mesh.attributes.includes(name)) ? [] : meshes) : meshes.filter((mesh) => mesh.attributes.includes(name)))
      : meshes.filter((mesh) => mesh.attributes.includes(name) !== wanted);
    if (missing.length) problems.push(wanted ? `no ${name} attribute` : `an unexpected ${name} attribute`);
  }
  if (entry.bbox) {
    const problem = boxProblem(seen.bbox, entry.bbox, BBOX_TOLERANCE);
    if (problem) problems.push(problem);
  }
  const positionTypes = [...new Set(meshes.map((mesh) => mesh.positionType))];
  // meshes with morph targets keep float positions (a skinned mesh's grid
  // is in its skin's inverse bind matrices)
  const wantPositions = (mesh) => (entry.quantized && !mesh.morphTargets ? 'Uint16Array' : 'Float32Array');
  if (meshes.some((mesh) => mesh.positionType !== wantPositions(mesh))) {
    problems.push(`positions in ${positionTypes}, expected ${[...new Set(meshes.map(wantPositions))]}`);
  }
  if (Boolean(entry.meshopt) !== seen.decodedViews > 0) {
    problems.push(`MeshoptDecoder decoded ${seen.decodedViews} buffer views, expected ${entry.meshopt ? 'some' : 'none'}`);
  }
  if (sum(meshes, 'morphTargets') !== seen.declared.morphTargets) {
    problems.push(`${sum(meshes, 'morphTargets')} morph targets, the file has ${seen.declared.morphTargets}`);
  }
  if (entry.morph !== undefined && sum(meshes, 'morphTargets') !== entry.morph) {
    problems.push(`${sum(meshes, 'morphTargets')} morph targets (morphAttributes.position), expected ${entry.morph}`);
  }
  if (seen.animations !== seen.declared.animations) problems.push(`${seen.animations} animations, the file has ${seen.declared.animations}`);
  const skinned = meshes.filter((mesh) => mesh.skinned).length;
  if (skinned !== (entry.skinned || 0)) problems.push(`${skinned} SkinnedMesh, expected ${entry.skinned || 0}`);
  if (entry.animations !== undefined && seen.animations !== entry.animations) {
    problems.push(`${seen.animations} animation clips, expected ${entry.animations}`);
  }
  if (entry.offBox) {
    // an input three.js is known to draw away from the box it computes
    if (seen.drawn >= MIN_DRAWN_SHARE) problems.push(`drawn in its box (${(100 * seen.drawn).toFixed(1)}%): offBox no longer holds`);
  } else if (!(seen.drawn >= MIN_DRAWN_SHARE)) {
    problems.push(`not drawn: ${(100 * seen.drawn).toFixed(1)}% of the picture differs from the background (at least ${100 * MIN_DRAWN_SHARE}% expected)`);
  }
  const levelCount = seen.levels ? seen.levels.length : 0;
  if ((entry.levels || 0) !== levelCount) problems.push(`${levelCount} MSFT_lod levels, expected ${entry.levels || 0}`);
  if (seen.levels && seen.levels[0] && seen.levels[0].declaredTriangles !== entry.triangles) {
    problems.push(`level 0 declares ${seen.levels[0].declaredTriangles} triangles in extras.lodkit, expected ${entry.triangles}`);
  }
  const summary = `${meshes.length} ${[...new Set(meshes.map((mesh) => mesh.type))].join(',') || 'meshes'}, ${vertices} vertices, ${triangles} triangles, ` +
    `attributes ${['normal', 'uv', 'color'].filter((name) => meshes.some((mesh) => mesh.attributes.includes(name))).join(',') || 'none'}, ` +
    `positions ${positionTypes}, ${seen.decodedViews} views meshopt-decoded, ${(100 * seen.drawn).toFixed(0)}% drawn` +
    (entry.bbox && seen.bbox ? `, bbox within ${(100 * boxDistance(seen.bbox, entry.bbox)).toPrecision(2)}% of the diagonal` : '') +
    (seen.declared.morphTargets ? `, ${seen.declared.morphTargets} morph targets` : '') +
    (skinned ? `, ${skinned} skinned` : '') + (seen.animations ? `, ${seen.animations} animations` : '') + (levelCount ? `, ${levelCount} MSFT_lod levels` : '');
  return { problems, summary };
}

/* The coarser MSFT_lod levels: loaded apart from the scene, each one mesh
 * of its declared triangle count, in place and drawn. */
function compareLevel(entry, level, index) {
  const problems = [];
  const triangles = sum(level.meshes, 'triangles');
  const vertices = sum(level.meshes, 'vertices');
  if (level.inScene) problems.push('it is in gltf.scene (only level 0 should be)');
  if (level.declaredLevel !== index) problems.push(`extras.lodkit.level is ${level.declaredLevel}`);
  if (level.meshes.length !== 1) problems.push(`${level.meshes.length} meshes, expected 1`);
  if (!(level.declaredTriangles > 0)) problems.push(`extras.lodkit.triangles is ${level.declaredTriangles}`);
  if (triangles !== level.declaredTriangles) problems.push(`${triangles} triangles, extras.lodkit.triangles says ${level.declaredTriangles}`);
  if (entry.bbox) {
    const problem = boxProblem(level.bbox, entry.bbox, LEVEL_BBOX_TOLERANCE);
    if (problem) problems.push(problem);
  }
  if (!(level.drawn >= MIN_DRAWN_SHARE)) problems.push(`not drawn: ${(100 * level.drawn).toFixed(1)}% of the picture differs`);
  return { problems, summary: `node ${level.node}, ${vertices} vertices, ${triangles} triangles, ${(100 * level.drawn).toFixed(0)}% drawn` };
}

async function main() {
  const manifest = JSON.parse(fs.readFileSync(manifestPath, 'utf8'));
  if (!Array.isArray(manifest.files) || manifest.files.length === 0) throw new Error(`${manifestPath}: no "files"`);
  if (!fs.existsSync(path.join(threeDir, 'build', 'three.module.js'))) throw new Error(`${threeDir}: three is not installed`);

  server = http.createServer(serve);
  await new Promise((resolve, reject) => {
    server.once('error', reject);
    server.listen(0, '127.0.0.1', resolve);
  });
  const base = `http://127.0.0.1:${server.address().port}`;

  ({ browser, profile } = await launchChromium({ width: 320, height: 240 }));
  const page = browser.pages()[0] || (await browser.newPage());
  let messages = [];
  page.on('pageerror', (error) => messages.push(`page error: ${error.message}`));
  page.on('console', (message) => {
    // every error, and three's warnings (not the GL driver's notes on readPixels)
    if (message.type() === 'error' || (message.type() === 'warning' && /THREE\./.test(message.text()))) {
      messages.push(`console ${message.type()}: ${message.text()}`);
    }
  });
  await page.goto(`${base}/`);
  const setup = await page.evaluate(setUpPage, CANVAS_SIZE);
  console.log(`# three.js r${setup.revision}, MeshoptDecoder supported: ${setup.meshoptSupported}, chromium started and page set up at ${seconds()} s`);
  if (!setup.meshoptSupported) throw new Error('three\'s MeshoptDecoder is not supported in this browser (no WebAssembly)');
  if (messages.length) throw new Error(`setting up the page: ${messages.join(' | ')}`);

  const boxes = {};
  for (const entry of manifest.files) {
    messages = [];
    if (entry.bboxOf) entry.bbox = boxes[entry.bboxOf];
    const url = `/files/${entry.file.split('/').map(encodeURIComponent).join('/')}`;
    const seen = await page.evaluate(inspectInPage, { url, box: entry.bbox || { min: [-1, -1, -1], max: [1, 1, 1] }, picture: Boolean(shotsDir) });
    boxes[entry.file] = seen.bbox;
    const { problems, summary } = compare(entry, seen);
    if (entry.bboxOf && !entry.bbox) problems.push(`no box seen for ${entry.bboxOf}`);
    // three's warnings name what it could not use (an unknown required
    // extension, an attribute it dropped): each is a failure here.
    problems.push(...messages);
    report(entry.file, problems, summary);
    for (let i = 1; i < (seen.levels || []).length; i++) {
      const level = compareLevel(entry, seen.levels[i], i);
      report(`${entry.file} MSFT_lod level ${i}`, level.problems, level.summary);
    }
    if (shotsDir && seen.image) {
      fs.mkdirSync(shotsDir, { recursive: true });
      fs.writeFileSync(path.join(shotsDir, `${entry.file.replace(/[^A-Za-z0-9._-]/g, '_')}.png`),
        Buffer.from(seen.image.replace(/^data:image\/png;base64,/, ''), 'base64'));
    }
  }
}

try {
  await main();
} catch (error) {
  checks++;
  failures++;
  console.log(`not ok - the test ran to its end (${error.stack || error})`);
}
if (browser) await browser.close().catch(() => {});
if (server) server.close();
if (profile) fs.rmSync(profile, { recursive: true, force: true });
clearTimeout(hardTimeout);
console.log(`${checks} checks, ${failures} failed, ${seconds()} s`);
process.exit(failures ? 1 : 0);
