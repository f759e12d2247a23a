// SPDX-License-Identifier: MIT
// Browser tests of the lodkit WebGL viewer, run by tests/cli/test_browser.sh
// against `lodkit serve DIR`:
//   node viewer.test.mjs BASE_URL DIR [SHOTS_DIR]
// DIR holds bunny.lks (a progressive stream of data/samples/bunny.obj),
// bunny-v2.lks (the same mesh as a version-2 stream, decoded in the
// viewer's worker),
// bunny-points.ply (`lodkit sample`), jacksboro.npz (a DEM) and broken.obj
// (a mesh the reader refuses). Outside DIR:
// DIR/../secret.txt, which the server must never hand out, and
// DIR/../cow-raw.lks (an uncompressed stream) for the decoder checks in node.
// Debian's /usr/bin/chromium, headless with SwiftShader WebGL, driven by
// playwright-core (never a downloaded browser). Prints one line per check
// and exits 1 when any fails; the whole run is bounded by HARD_TIMEOUT_MS.

import { chromium } from 'playwright-core';
import { launchChromium } from './chromium.mjs';
import fs from 'node:fs';
import http from 'node:http';
import path from 'node:path';
import { StreamDecoder, crc32 } from '../../web/stream.js';
import { stripFilter, stripFilterBound, stripTriangleCount } from '../../web/strips.js';

const HARD_TIMEOUT_MS = 55000;
const [baseUrl, dir, shotsDir] = process.argv.slice(2);
if (!baseUrl || !dir) {
  console.error('usage: node viewer.test.mjs BASE_URL DIR [SHOTS_DIR]');
  process.exit(2);
}
const base = baseUrl.replace(/\/$/, '');
const started = Date.now();
let failures = 0;
let checks = 0;
let browser = null;
let profile = null;

const hardTimeout = setTimeout(async () => {
  console.log(`not ok - the browser tests took more than ${HARD_TIMEOUT_MS / 1000} s`);
  try { if (browser) await browser.close(); } catch { /* exiting anyway */ }
  process.exit(1);
}, HARD_TIMEOUT_MS);

function check(description, condition, detail = '') {
  checks++;
  if (condition) console.log(`ok - ${description}${detail ? ` (${detail})` : ''}`);
  else {
    failures++;
    console.log(`not ok - ${description}${detail ? ` (${detail})` : ''}`);
  }
  return condition;
}
const seconds = () => ((Date.now() - started) / 1000).toFixed(1);

/* Raw HTTP GET (node's http keeps the path exactly as given: no ../ folding). */
function get(requestPath, headers = {}) {
  const url = new URL(base);
  return new Promise((resolve, reject) => {
    const request = http.request({ host: url.hostname, port: url.port, path: requestPath, method: 'GET', headers }, (response) => {
      const parts = [];
      response.on('data', (part) => parts.push(part));
      response.on('end', () => resolve({ status: response.statusCode, headers: response.headers, body: Buffer.concat(parts) }));
    });
    request.on('error', reject);
    request.setTimeout(10000, () => request.destroy(new Error(`GET ${requestPath}: timed out`)));
    request.end();
  });
}

/* Share of pixels in the centre box (a fifth of each side) that differ from
 * the background by more than 24 in some channel, read back from the WebGL
 * canvas (preserveDrawingBuffer keeps the last frame readable). */
async function centreCoverage(page) {
  return page.evaluate(() => {
    const canvas = document.getElementById('view');
    const copy = document.createElement('canvas');
    copy.width = canvas.width;
    copy.height = canvas.height;
    const context = copy.getContext('2d');
    context.drawImage(canvas, 0, 0);
    const w = Math.max(1, Math.floor(canvas.width / 5));
    const h = Math.max(1, Math.floor(canvas.height / 5));
    const pixels = context.getImageData(Math.floor((canvas.width - w) / 2), Math.floor((canvas.height - h) / 2), w, h).data;
    const background = window.viewer.background.map((value) => Math.round(255 * value));
    let differing = 0;
    for (let i = 0; i < pixels.length; i += 4) {
      if (Math.abs(pixels[i] - background[0]) > 24 || Math.abs(pixels[i + 1] - background[1]) > 24 ||
          Math.abs(pixels[i + 2] - background[2]) > 24) differing++;
    }
    return differing / (w * h);
  });
}

const stats = (page) => page.evaluate(() => JSON.parse(JSON.stringify(window.viewerStats || null)));

async function waitFor(page, predicate, argument, timeout, what) {
  try {
    await page.waitForFunction(predicate, argument, { timeout, polling: 50 });
    return true;
  } catch {
    const s = await stats(page).catch(() => null);
    check(`${what} within ${timeout / 1000} s`, false, JSON.stringify(s));
    return false;
  }
}

async function shot(page, name) {
  if (!shotsDir) return;
  fs.mkdirSync(shotsDir, { recursive: true });
  await page.screenshot({ path: path.join(shotsDir, name) });
}

async function main() {
  const index = JSON.parse((await get('/api/index.json')).body.toString());
  const byName = new Map(index.models.map((model) => [model.name, model]));
  const stream = byName.get('bunny.lks');
  const stream2 = byName.get('bunny-v2.lks');
  const points = byName.get('bunny-points.ply');
  const terrain = byName.get('jacksboro.npz');
  check('index lists the stream, the point set and the terrain',
    stream && stream.kind === 'stream' && points && points.kind === 'points' && terrain && terrain.kind === 'terrain',
    index.models.map((model) => `${model.name}:${model.kind}`).join(' '));
  check('index lists the version-2 stream with its counts', stream2 && stream2.kind === 'stream' &&
    stream2.triangles === 69666 && stream2.splits > 0, JSON.stringify(stream2));
  const file = fs.readFileSync(path.join(dir, 'bunny.lks'));

  // ---- the viewer's decoder in node (web/stream.js, web/strips.js) --------
  check('crc32("123456789") = cbf43926', crc32(new TextEncoder().encode('123456789')) === 0xcbf43926);
  {
    const levels = [];
    const decoder = new StreamDecoder({ onChunk: (d) => levels.push(d.level) });
    for (let offset = 0; offset < file.length; offset += 777) await decoder.feed(file.subarray(offset, offset + 777));
    const g = decoder.levelGeometry(decoder.level);
    const out = new Uint32Array(stripFilterBound(g.strip.length));
    const filtered = stripFilter(g.strip, g.strip.length, out);
    check('node: the stream decodes in 777-byte pieces to 69,666 triangles',
      decoder.done && stripTriangleCount(g.strip, g.strip.length) === 69666 &&
        stripTriangleCount(out, filtered.length) === 69666 && filtered.triangles === 69666,
      `${levels.length} chunks, filtered strip ${filtered.length} indices`);
    const base = decoder.levelGeometry(0);
    check('node: level 0 rebuilt from the full state is the base mesh',
      stripTriangleCount(base.strip, base.strip.length) === decoder.chunks[0].triangleCount);
    // a flipped byte in chunk 3's payload: refused by its CRC, level of chunk 2 kept
    const corrupt = Buffer.from(file);
    corrupt[decoder.chunks[3].offset + 20] ^= 0x40;
    const broken = new StreamDecoder();
    let message = '';
    try { await broken.feed(corrupt); } catch (error) { message = error.message; }
    check('node: a corrupt chunk is refused and the earlier levels stay',
      /^chunk 3 at byte \d+: CRC-32 mismatch/.test(message) && broken.level === decoder.chunks[2].firstSplit + decoder.chunks[2].splitCount,
      message);
  }
  {
    // An uncompressed stream whose chunk 2 has a changed mask byte and
    // matching CRCs: the split fails half-way and the chunk is rolled back.
    const raw = Buffer.from(fs.readFileSync(path.join(dir, '..', 'cow-raw.lks')));
    const probe = new StreamDecoder();
    await probe.feed(raw.subarray(0, 4096));
    const chunks = probe.chunks;
    const chunk = chunks[2];
    const payload = chunk.offset + 8;
    let at = payload;
    const varint = () => { let value = 0, scale = 1, byte; do { byte = raw[at++]; value += (byte & 127) * scale; scale *= 128; } while (byte & 128); return value; };
    const pBytes = varint();
    varint();
    raw[at + pBytes] ^= 0x01; // first mask byte: split 0 moves other entries
    const crc = crc32(raw.subarray(payload, chunk.offset + chunk.size));
    raw.writeUInt32LE(crc, chunk.offset + 4);
    raw.writeUInt32LE(crc, 96 + 32 * 2 + 28);
    raw.writeUInt32LE(crc32(raw.subarray(96, 96 + 32 * chunks.length)), 96 + 32 * chunks.length);
    const broken = new StreamDecoder();
    let message = '';
    try { await broken.feed(raw); } catch (error) { message = error.message; }
    const state = broken.state;
    const clean = new StreamDecoder();
    await clean.feed(fs.readFileSync(path.join(dir, '..', 'cow-raw.lks')).subarray(0, chunk.offset));
    const same = Buffer.from(state.resolved.buffer).equals(Buffer.from(clean.state.resolved.buffer)) &&
      state.present === clean.state.present &&
      state.quantised.subarray(0, 3 * state.present).every((value, i) => value === clean.state.quantised[i]);
    check('node: the rolled-back strip and positions equal those of the chunk before', same);
    check('node: a chunk failing half-way is rolled back to the level before it',
      /^chunk 2 at byte \d+: /.test(message) && !/CRC/.test(message) && broken.level === chunks[1].firstSplit + chunks[1].splitCount &&
        state.triangles === chunks[1].triangleCount && stripTriangleCount(state.resolved, state.length) === chunks[1].triangleCount,
      message);
  }

  // ---- HTTP: Range, 404, path traversal ----------------------------------
  const range = await get('/m/bunny.lks', { Range: 'bytes=1000-1999' });
  check('Range bytes=1000-1999 is 206 with those bytes',
    range.status === 206 && range.body.equals(file.subarray(1000, 2000)) &&
      range.headers['content-range'] === `bytes 1000-1999/${file.length}`,
    `status ${range.status}, ${range.body.length} bytes, Content-Range ${range.headers['content-range']}`);
  const suffix = await get('/m/bunny.lks', { Range: 'bytes=-100' });
  check('Range bytes=-100 is the last 100 bytes', suffix.status === 206 && suffix.body.equals(file.subarray(file.length - 100)),
    `status ${suffix.status}`);
  const whole = await get('/m/bunny.lks');
  check('GET of the stream is 200 with the file, never gzipped',
    whole.status === 200 && whole.body.equals(file) && !whole.headers['content-encoding'], `status ${whole.status}`);
  const missing = await get('/m/no-such-model.lks');
  check('a missing file is 404', missing.status === 404, `status ${missing.status}`);
  const secret = fs.readFileSync(path.join(dir, '..', 'secret.txt'));
  for (const attempt of ['/m/../secret.txt', '/m/%2e%2e/secret.txt', '/m/bunny/../../secret.txt', '/m/..%2fsecret.txt']) {
    const response = await get(attempt);
    check(`path traversal ${attempt} is refused`,
      response.status >= 400 && response.status < 500 && !response.body.includes(secret), `status ${response.status}`);
  }
  const dotdot = await get('/m/../secret.txt');
  check('`..` is 403 (server contract)', dotdot.status === 403, `status ${dotdot.status}`);

  // ---- the browser ---------------------------------------------------------
  ({ browser, profile } = await launchChromium({ width: 800, height: 600 }));
  const page = browser.pages()[0] || (await browser.newPage());
  console.log(`# chromium started at ${seconds()} s`);
  const pageErrors = [];
  page.on('pageerror', (error) => pageErrors.push(error.message));
  page.on('console', (message) => {
    if (message.type() === 'error' && !/favicon/.test(message.text())) pageErrors.push(message.text());
  });

  // ---- progressive mesh ------------------------------------------------------
  let t = Date.now();
  await page.goto(`${base}/?model=bunny.lks`);
  const full = 69666;
  if (await waitFor(page, (n) => {
    const s = window.viewerStats;
    return s && (s.error || (s.view === 'mesh' && s.done && s.triangles === n && s.fullFrameMs !== undefined));
  }, full, 30000, 'the bunny stream refines to its full level')) {
    const s = await stats(page);
    const loadMs = Date.now() - t;
    check('no viewer error', !s.error, s.error || '');
    check('the first frame showed the base level', s.firstFrameLevel === 0 &&
      s.firstFrameTriangles === (stream.base_triangles ?? s.firstFrameTriangles) && s.firstFrameTriangles < full,
      `level ${s.firstFrameLevel}, ${s.firstFrameTriangles} triangles`);
    check('refined to every split', s.level === s.levels && s.levels === (stream.splits ?? s.levels) && s.chunksDecoded === s.chunkCount,
      `level ${s.level} of ${s.levels}, ${s.chunksDecoded}/${s.chunkCount} chunks`);
    check('drawn triangles == the mesh\'s 69,666', s.triangles === full && (stream.triangles ?? full) === full, `${s.triangles}`);
    check('bytes received == the file size', s.bytesReceived === file.length && s.totalBytes === file.length,
      `${s.bytesReceived} of ${file.length}`);
    const share = s.firstFrameBytes / s.totalBytes;
    check('first frame after <= 10% of the stream', share <= 0.10,
      `${s.firstFrameBytes} bytes = ${(100 * share).toFixed(2)}% (base chunk ends at byte ${s.baseEnd})`);
    check('DTFS strip: fewer indices than triangles * 1.5', s.indicesSent > 0 && s.indicesSent < 1.5 * s.triangles &&
      s.version === 1 && s.drawMode === 'strip', `${s.indicesSent} indices, ${(s.indicesSent / s.triangles).toFixed(3)} per triangle`);
    const overlay = await page.evaluate(() => document.getElementById('overlay').textContent);
    check('the overlay says version 1, drawn as a DTFS strip', /stream version 1 \(DTFS strip\)/.test(overlay), overlay.split('\n')[0]);
    console.log(`# mesh: first frame ${s.firstFrameMs.toFixed(0)} ms, full level drawn ${s.fullFrameMs.toFixed(0)} ms ` +
      `after load start (decode ${s.decodeMs.toFixed(0)} ms), page ${loadMs} ms, ${s.framesDrawn} frames`);
    const coverage = await centreCoverage(page);
    check('the bunny covers the centre of the picture', coverage > 0.5, `${(100 * coverage).toFixed(0)}% of the centre box`);
    await shot(page, 'mesh.png');

    // the slider: back to the base level, and to the full level again
    const frames = s.framesDrawn;
    await page.evaluate(() => {
      const slider = document.getElementById('level');
      slider.value = '0';
      slider.dispatchEvent(new Event('input'));
    });
    if (await waitFor(page, (n) => window.viewerStats.framesDrawn > n && window.viewerStats.level === 0, frames, 5000, 'slider to level 0')) {
      const low = await stats(page);
      check('slider at 0 draws the base mesh', low.triangles === s.firstFrameTriangles, `${low.triangles} triangles`);
    }
    await page.evaluate((levels) => {
      const slider = document.getElementById('level');
      slider.value = String(levels);
      slider.dispatchEvent(new Event('input'));
    }, s.levels);
    if (await waitFor(page, (n) => window.viewerStats.level === n, s.levels, 5000, 'slider back to the full level'))
      check('slider at the top draws every triangle', (await stats(page)).triangles === full);
  }
  {
    // camera controls: mouse drag rotates, shift-drag pans, wheel zooms,
    // two touch pointers pinch (synthetic pointer events of type touch)
    const camera = () => page.evaluate(() => {
      const c = window.viewer.view.camera;
      return { azimuth: c.azimuth, elevation: c.elevation, zoom: c.zoom, pan: [...c.pan] };
    });
    const before = await camera();
    await page.mouse.move(400, 300);
    await page.mouse.down();
    await page.mouse.move(460, 330, { steps: 4 });
    await page.mouse.up();
    const rotated = await camera();
    await page.keyboard.down('Shift');
    await page.mouse.move(400, 300);
    await page.mouse.down();
    await page.mouse.move(440, 300, { steps: 4 });
    await page.mouse.up();
    await page.keyboard.up('Shift');
    const panned = await camera();
    await page.mouse.wheel(0, -300);
    await page.waitForTimeout(50);
    const zoomed = await camera();
    await page.evaluate(() => {
      const canvas = document.getElementById('view');
      const fire = (type, id, x, y) => canvas.dispatchEvent(new PointerEvent(type, { pointerId: id, pointerType: 'touch',
        clientX: x, clientY: y, isPrimary: id === 11, bubbles: true, buttons: type === 'pointerup' ? 0 : 1 }));
      fire('pointerdown', 11, 380, 300);
      fire('pointerdown', 12, 420, 300);
      fire('pointermove', 11, 340, 300);
      fire('pointermove', 12, 460, 300);
      fire('pointerup', 11, 340, 300);
      fire('pointerup', 12, 460, 300);
    });
    const pinched = await camera();
    check('mouse drag rotates, shift-drag pans, wheel and pinch zoom in',
      rotated.azimuth !== before.azimuth && rotated.elevation !== before.elevation &&
        panned.azimuth === rotated.azimuth && panned.pan.some((value, a) => value !== rotated.pan[a]) &&
        zoomed.zoom < panned.zoom && pinched.zoom < zoomed.zoom,
      `azimuth ${before.azimuth}->${rotated.azimuth}, zoom ${panned.zoom.toFixed(3)}->${zoomed.zoom.toFixed(3)}->${pinched.zoom.toFixed(3)}`);
  }
  // ---- progressive mesh, version 2: decoded in the worker -------------------
  // In a browser of its own with GPU compositing (on SwiftShader): under
  // --disable-gpu the software compositor reads every WebGL frame back on
  // the page's thread (GLES2::ReadPixels in Commit, waiting for SwiftShader
  // to finish drawing), 50-200 ms per frame of the full bunny on a loaded
  // machine, which a page with a GPU never pays and no page can avoid.
  const gpuBrowser = await chromium.launch({
    executablePath: '/usr/bin/chromium',
    headless: true,
    args: ['--headless', '--no-sandbox', '--enable-unsafe-swiftshader', '--use-angle=swiftshader', '--ignore-gpu-blocklist',
      '--disable-quic', '--no-first-run', '--disable-background-networking', '--disable-component-update', '--disable-sync'],
  });
  const page2 = await gpuBrowser.newPage({ viewport: { width: 800, height: 600 } });
  page2.on('pageerror', (error) => pageErrors.push(error.message));
  page2.on('console', (message) => {
    if (message.type() === 'error' && !/favicon/.test(message.text())) pageErrors.push(message.text());
  });
  // Main-thread tasks over 50 ms, from the page's first script on.
  await page2.addInitScript(() => {
    window.longTasks = [];
    try {
      new PerformanceObserver((list) => {
        for (const entry of list.getEntries()) window.longTasks.push({ start: entry.startTime, duration: entry.duration });
      }).observe({ type: 'longtask' });
    } catch { window.longTasks = null; }
  });
  t = Date.now();
  // with stream2.wasm in the build, the worker waits for it (?decoder=wasm): by default it
  // takes JavaScript when the module is not ready 100 ms after the first bytes
  await page2.goto(`${base}/?model=bunny-v2.lks${process.env.LK_STREAM2_WASM ? '&decoder=wasm' : ''}`);
  if (await waitFor(page2, (n) => {
    const s = window.viewerStats;
    return s && (s.error || (s.view === 'mesh' && s.done && s.triangles === n && s.fullFrameMs !== undefined));
  }, full, 30000, 'the version-2 bunny refines to its full level')) {
    const s = await stats(page2);
    const loadMs = Date.now() - t;
    check('v2: no viewer error', !s.error, s.error || '');
    check('v2: the first frame showed the base level', s.firstFrameLevel === 0 && s.framesDrawn > 0 &&
      s.firstFrameTriangles === stream2.base_triangles && s.firstFrameTriangles < full,
      `level ${s.firstFrameLevel}, ${s.firstFrameTriangles} triangles`);
    const share = s.baseEnd / s.totalBytes;
    check('v2: the base chunk ends within the first 2% of the stream, and the first frame came with the first request',
      share <= 0.02 && s.firstFrameBytes <= Math.max(4096, s.baseEnd),
      `base chunk ends at byte ${s.baseEnd} of ${s.totalBytes} = ${(100 * share).toFixed(2)}%, drawn after ${s.firstFrameBytes} bytes`);
    check('v2: every split, all 69,666 triangles, drawn as indexed triangles', s.version === 2 && s.level === s.levels &&
      s.levels === stream2.splits && s.chunksDecoded === s.chunkCount && s.triangles === full &&
      s.drawMode === 'triangles' && s.indicesSent === 3 * full && s.bytesReceived === s.totalBytes,
      `version ${s.version}, level ${s.level} of ${s.levels}, ${s.triangles} triangles, ${s.indicesSent} indices (${s.drawMode})`);
    // The build made stream2.wasm (CTest's LK_STREAM2_WASM) and the server serves it: the worker decoded with it.
    const expectedDecoder = process.env.LK_STREAM2_WASM ? 'wasm' : 'js';
    check(`v2: the worker decoded with the ${expectedDecoder === 'wasm' ? 'C decoder built as WebAssembly' : 'JavaScript decoder'}`,
      s.decoder === expectedDecoder, `decoder ${s.decoder}`);
    const overlay = await page2.evaluate(() => document.getElementById('overlay').textContent);
    check('v2: the overlay says version 2, drawn as indexed triangles', /stream version 2 \(indexed triangles\)/.test(overlay),
      overlay.split('\n')[0]);
    // Tasks begun from the first request of the stream (streamStart) to the
    // full level drawn. The page's own start comes before: modules, the
    // WebGL context, shader compilation (whose task ends by sending the
    // first request), the drawing buffer's allocation.
    const allTasks = await page2.evaluate(() => window.longTasks);
    const streaming = (allTasks || []).filter((task) => task.start >= s.streamStart && task.start < s.fullFrameAt);
    const longest = streaming.length ? Math.max(...streaming.map((task) => task.duration)) : 0;
    // The page must not freeze. How long its tasks are is a speed, measured
    // by bench/stream_browser.mjs (here, on 2 cores shared with the other
    // tests, one upload took 69-249 ms under load); the test holds what keeps
    // them short: the whole stream was decoded in the worker, and the page's
    // thread only uploaded the buffers it was sent.
    check('v2: the stream was decoded in the Web Worker, the page\'s thread only uploaded buffers',
      s.decodeMs > 0 && s.workerMs >= s.decodeMs && s.uploadMs > 0 && Array.isArray(allTasks),
      `worker decode ${s.decodeMs.toFixed(0)} ms (busy ${s.workerMs.toFixed(0)} ms), uploads ${(s.uploadMs || 0).toFixed(0)} ms; ` +
      `${streaming.length} long tasks in ${(s.fullFrameAt - s.streamStart).toFixed(0)} ms of streaming` +
      `${streaming.length ? `, longest ${longest.toFixed(0)} ms` : ''}; before the stream (page start): ` +
      `${(allTasks || []).filter((task) => task.start < s.streamStart).map((task) => task.duration.toFixed(0) + ' ms').join(', ') || 'none'}`);
    console.log(`# v2 mesh: worker decode ${s.decodeMs.toFixed(0)} ms for the whole bunny (worker busy ${s.workerMs.toFixed(0)} ms, ` +
      `geometry ${s.geometryMs.toFixed(0)} ms; issue 19's target: decode <= 250 ms), main thread: uploads ${s.uploadMs.toFixed(0)} ms, ` +
      `draws ${s.drawMs.toFixed(0)} ms in ${s.framesDrawn} frames, longest task ${longest ? longest.toFixed(0) + ' ms' : 'under 50 ms'}; ` +
      `first frame ${s.firstFrameMs.toFixed(0)} ms, full level ${s.fullFrameMs.toFixed(0)} ms after load start, page ${loadMs} ms`);
    const coverage = await centreCoverage(page2);
    check('v2: the bunny covers the centre of the picture', coverage > 0.5, `${(100 * coverage).toFixed(0)}% of the centre box`);
    await shot(page2, 'mesh-v2.png');
    const frames = s.framesDrawn;
    await page2.evaluate(() => {
      const slider = document.getElementById('level');
      slider.value = '0';
      slider.dispatchEvent(new Event('input'));
    });
    if (await waitFor(page2, (n) => window.viewerStats.framesDrawn > n && window.viewerStats.level === 0, frames, 5000, 'v2: slider to level 0')) {
      const low = await stats(page2);
      check('v2: slider at 0 draws the base mesh (rebuilt from the split log)', low.triangles === s.firstFrameTriangles,
        `${low.triangles} triangles`);
    }
    await page2.evaluate((levels) => {
      const slider = document.getElementById('level');
      slider.value = String(levels);
      slider.dispatchEvent(new Event('input'));
    }, s.levels);
    if (await waitFor(page2, (n) => window.viewerStats.level === n, s.levels, 5000, 'v2: slider back to the full level'))
      check('v2: slider at the top draws every triangle', (await stats(page2)).triangles === full);
  }
  await gpuBrowser.close();
  console.log(`# mesh view done at ${seconds()} s`);
  console.log(`# ${seconds()} s`);

  // ---- splats -------------------------------------------------------------
  t = Date.now();
  await page.goto(`${base}/?model=bunny-points.ply`);
  if (await waitFor(page, () => window.viewerStats && (window.viewerStats.error ||
      (window.viewerStats.view === 'splat' && window.viewerStats.framesDrawn > 0 && window.viewerStats.points > 0)),
    null, 20000, 'the splat view draws')) {
    const s = await stats(page);
    check('splats: no error, every point drawn', !s.error && s.points === (points.points ?? s.points) && s.points > 1000,
      s.error || `${s.points} points, ${s.splatPath}, ${Date.now() - t} ms`);
    // The server's clip lines arrive (flag 8 of LKMB); a closed surface has hardly a border point.
    check('splats: clip lines parsed, few on a closed surface',
      Number.isInteger(s.clippedPoints) && s.clippedPoints < s.points / 100, `${s.clippedPoints} of ${s.points} clipped`);
    const coverage = await centreCoverage(page);
    check('1-pass splats cover the centre', coverage > 0.5, `${(100 * coverage).toFixed(0)}%`);
    await page.click('#passes-2');
    await waitFor(page, () => window.viewerStats.passes === 2 || /asked/.test(window.viewerStats.splatPath), null, 10000, '2-pass splats');
    const two = await stats(page);
    check('2-pass path reported', /^2 passes, accumulation target |^1 pass \(2 passes asked/.test(two.splatPath), two.splatPath);
    const coverage2 = await centreCoverage(page);
    check('2-pass splats cover the centre', coverage2 > 0.5, `${(100 * coverage2).toFixed(0)}%`);
    await shot(page, 'splat.png');
    // the fallbacks: RGBA8 accumulation, and 1 pass when no target renders
    for (const [target, expected] of [['rgba8', /^2 passes, accumulation target RGBA8/], ['none', /^1 pass \(2 passes asked/]]) {
      await page.goto(`${base}/?model=bunny-points.ply&passes=2&target=${target}`);
      if (await waitFor(page, () => window.viewerStats && (window.viewerStats.error ||
          (window.viewerStats.view === 'splat' && window.viewerStats.framesDrawn > 0)), null, 10000, `splats with target=${target}`)) {
        const fallback = await stats(page);
        const cover = await centreCoverage(page);
        check(`2 passes forced to target=${target}: ${expected}`, !fallback.error && expected.test(fallback.splatPath) && cover > 0.5,
          `${fallback.error || fallback.splatPath}, ${(100 * cover).toFixed(0)}% of the centre`);
      }
    }
  }
  console.log(`# ${seconds()} s`);

  // ---- terrain ---------------------------------------------------------------
  t = Date.now();
  await page.goto(`${base}/?model=jacksboro.npz`);
  if (await waitFor(page, () => window.viewerStats && (window.viewerStats.error ||
      (window.viewerStats.view === 'terrain' && window.viewerStats.triangles > 0 && window.viewerStats.framesDrawn > 0)),
    null, 20000, 'the terrain view draws')) {
    const s = await stats(page);
    check('terrain: no error, a CLOD mesh drawn', !s.error && s.triangles > 100,
      s.error || `${s.triangles} triangles, ${s.vertices} vertices, server ${s.serverMs} ms, ${Date.now() - t} ms`);
    check('terrain: no cracks', s.cracks === 0, `cracks ${s.cracks}`);
    const coverage = await centreCoverage(page);
    check('terrain covers the centre', coverage > 0.5, `${(100 * coverage).toFixed(0)}%`);
    await shot(page, 'terrain.png');
    // flying forward asks for a new mesh
    await page.focus('#view');
    await page.keyboard.down('KeyW');
    await page.waitForTimeout(600);
    await page.keyboard.up('KeyW');
    if (await waitFor(page, (n) => window.viewerStats.terrainRequests > n, s.terrainRequests, 5000, 'a new terrain mesh after flying')) {
      const after = await stats(page);
      check('terrain re-requested as the camera moves', !after.error && after.terrainRequests > s.terrainRequests && after.cracks === 0,
        `${after.terrainRequests} requests, ${after.triangles} triangles, cracks ${after.cracks}`);
    }
  }
  check('no page errors', pageErrors.length === 0, pageErrors.slice(0, 3).join(' | '));
  console.log(`# ${seconds()} s`);

  // ---- models the viewer cannot show (errors expected from here on) ----------
  // A model that is not in the folder: said so, and no other model opened.
  await page.goto(`${base}/?model=missing.lks`);
  if (await waitFor(page, () => window.viewerStats && (window.viewerStats.error || window.viewerStats.framesDrawn > 0),
    null, 10000, 'the viewer answers ?model=missing.lks')) {
    const s = await stats(page);
    const search = await page.evaluate(() => location.search);
    const picked = await page.evaluate(() => document.getElementById('model').value);
    check('?model=missing.lks: says the model is not there',
      /^missing\.lks: /.test(s.error || '') && /not/.test(s.error || ''), s.error || `${s.view} drawn instead`);
    check('?model=missing.lks: opens no other model', s.view === 'none' && s.framesDrawn === 0 &&
      search === '?model=missing.lks' && picked === '', `view ${s.view}, ${s.framesDrawn} frames, ${search}, picker "${picked}"`);
  }
  // A file the index could not read: its message, naming the file once.
  const broken = byName.get('broken.obj');
  await page.goto(`${base}/?model=broken.obj`);
  if (await waitFor(page, () => window.viewerStats && window.viewerStats.error, null, 10000, 'the viewer answers ?model=broken.obj')) {
    const s = await stats(page);
    check('broken.obj: the index\'s message, the name once', broken && broken.kind === 'unknown' &&
      s.error === broken.error && /^broken\.obj:1: /.test(s.error) && !/broken\.obj.*broken\.obj/.test(s.error),
      `${s.error} (index: ${broken && broken.error})`);
  }
}

try {
  await main();
} catch (error) {
  check('the test ran to its end', false, error.stack || String(error));
}
if (browser) await browser.close().catch(() => {});
if (profile) fs.rmSync(profile, { recursive: true, force: true });
clearTimeout(hardTimeout);
console.log(`${checks} checks, ${failures} failed, ${seconds()} s`);
process.exit(failures ? 1 : 0);
