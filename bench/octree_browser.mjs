// SPDX-License-Identifier: MIT
// Frame time and memory of the viewer's octree view (web/octree_view.js) in
// headless Chromium (Debian's /usr/bin/chromium, SwiftShader WebGL, no GPU)
// at point budgets of 0.5M, 1M and 2M: the browser half of issue 23's
// "frame time at budgets" (bench_octree gives the C renderer's).
//
//   node bench/octree_browser.mjs BASE_URL MODEL [SIDE]
//
// BASE_URL is a `lodkit serve` whose folder holds the octree MODEL (the
// index's name: its folder). For each budget: a new page of SIDE x SIDE
// (default 1024) opens ?model=MODEL&budget=B&minpx=0 (the budget alone
// decides), waits until every chosen node is drawn (the load time), then
// times 5 frames drawn and read back (one pixel, which waits for the GPU
// process) one after another: the median is the frame time; then flies the
// camera in, around and out (1.5 s a step, not waiting for the view to
// settle) and reports the most points the viewer held at any moment and
// the nodes it evicted. "first points ms": from the view opening to its
// first points drawn (the viewer's firstPointsMs). "adaptive size off": the
// same frames with every inner node's points at least its spacing (no walk
// of the drawn nodes in the vertex shader). Memory: the viewer's vertex buffers (36 bytes a
// point held) and the resident size of all Chromium processes (ps). Uses
// tests/browser/chromium.mjs (playwright-core: `npm ci` in tests/browser).

import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath, pathToFileURL } from 'node:url';

const [baseUrl, model, sideText] = process.argv.slice(2);
if (!baseUrl || !model) {
  console.error('usage: node bench/octree_browser.mjs BASE_URL MODEL [SIDE]');
  process.exit(2);
}
const side = Number(sideText || 1024);
const here = path.dirname(fileURLToPath(import.meta.url));
const { launchChromium } = await import(pathToFileURL(path.join(here, '..', 'tests', 'browser', 'chromium.mjs')).href);

/* Resident MiB of a process and all its descendants. */
function treeRssMiB(pid) {
  const table = execFileSync('ps', ['-eo', 'pid=,ppid=,rss='], { encoding: 'utf8' }).trim().split('\n')
    .map((line) => line.trim().split(/\s+/).map(Number));
  const keep = new Set([pid]);
  for (let grown = true; grown;) {
    grown = false;
    for (const [p, parent] of table) if (keep.has(parent) && !keep.has(p)) { keep.add(p); grown = true; }
  }
  return table.filter(([p]) => keep.has(p)).reduce((sum, [, , rss]) => sum + rss, 0) / 1024;
}

// the camera path of the flight (tests/browser/octree.test.mjs flies the same)
const flight = [['zoom', 0.6], ['zoom', 0.6], ['zoom', 0.6], ['rotate', 120, 0], ['rotate', 0, -40], ['zoom', 0.6],
  ['pan', 80, 40], ['zoom', 4], ['rotate', -200, 30], ['zoom', 0.3]];

const median = (values) => [...values].sort((a, b) => a - b)[Math.floor(values.length / 2)];

// the header above the canvas takes ~140 px
const { browser, profile } = await launchChromium({ width: side, height: side + 140 });
/* The browser process (the one started with our profile, not a --type= child) and its children. */
function chromiumRssMiB() {
  const table = execFileSync('ps', ['-eo', 'pid=,args='], { encoding: 'utf8' }).trim().split('\n');
  const root = table.map((line) => line.trim()).find((line) => line.includes(profile) && !line.includes('--type='));
  return root ? treeRssMiB(Number(root.split(/\s+/)[0])) : NaN;
}

const blank = await browser.newPage();
await blank.goto('about:blank');
const idleMiB = chromiumRssMiB();
await blank.close();
console.log(`Headless Chromium (${side}x${side} canvas, SwiftShader), ${model} from ${baseUrl}, 1-pass splats, ` +
  `minpx=0; Chromium with a blank page: ${idleMiB.toFixed(0)} MiB resident.\n`);
console.log('| budget | first points ms | points drawn | nodes | load s (first frame to all chosen drawn) | frame ms (median of 5) | frames/s | frame ms, adaptive size off | vertex buffers (MiB) | Chromium RSS (MiB) | flight: most points held | nodes evicted |');
console.log('|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|');
for (const budget of [500000, 1000000, 2000000]) {
  const page = await browser.newPage();
  const started = Date.now();
  await page.goto(`${baseUrl.replace(/\/$/, '')}/?model=${encodeURIComponent(model)}&budget=${budget}&minpx=0`);
  await page.waitForFunction(() => {
    const view = window.viewer && window.viewer.view;
    const s = window.viewerStats;
    return view && view.requests && view.requests.size === 0 && s.framesDrawn > 0 && s.pointsDrawn > 0 &&
      s.nodesDrawn === s.nodesSelected - view.selection.filter((node) => node.points === 0).length;
  }, null, { timeout: 300000, polling: 100 });
  const loadSeconds = (Date.now() - started) / 1000;
  const timeFrames = (adaptive) => page.evaluate((on) => {
    const view = window.viewer.view;
    view.adaptive = on && view.adaptiveSupported;
    const times = [];
    for (let i = 0; i < 5; i++) {
      const t = performance.now();
      window.viewer.drawNow();
      // one pixel read back: waits for the GPU process to finish the frame (gl.finish alone does not)
      window.viewer.gl.readPixels(0, 0, 1, 1, window.viewer.gl.RGBA, window.viewer.gl.UNSIGNED_BYTE, new Uint8Array(4));
      times.push(performance.now() - t);
    }
    return times;
  }, adaptive);
  const fixedFrame = median(await timeFrames(false));
  const frame = median(await timeFrames(true));
  const s = await page.evaluate(() => JSON.parse(JSON.stringify(window.viewerStats)));
  const rss = chromiumRssMiB();
  // Fly in, around and out without waiting for the view to settle (1.5 s a
  // step): nodes are fetched, drawn and evicted under way; the viewer's own
  // running maximum of the points held (uploaded + in flight) must stay
  // within the budget.
  for (const [what, ...args] of flight) {
    await page.evaluate(([w, a]) => { window.viewer.control(w, ...a); window.viewer.requestDraw(); }, [what, args]);
    await new Promise((resolve) => setTimeout(resolve, 1500));
  }
  const flown = await page.evaluate(() => JSON.parse(JSON.stringify(window.viewerStats)));
  console.log(`| ${budget} | ${s.firstPointsMs.toFixed(0)} | ${s.pointsDrawn} | ${s.nodesDrawn} | ${loadSeconds.toFixed(1)} | ` +
    `${frame.toFixed(0)} | ${(1000 / frame).toFixed(2)} | ${fixedFrame.toFixed(0)} | ${((s.pointsHeld * 36) / 1048576).toFixed(0)} | ${rss.toFixed(0)} | ` +
    `${flown.maxPointsHeld}${flown.maxPointsHeld > budget ? ' (over the budget)' : ''} | ${flown.nodesEvicted} |`);
  await page.close();
}
await browser.close();
fs.rmSync(profile, { recursive: true, force: true });
