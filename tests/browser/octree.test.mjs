// SPDX-License-Identifier: MIT
// The viewer's octree view (web/octree_view.js) in headless Chromium against
// `lodkit serve`, run by tests/cli/test_browser_octree.sh:
//   node octree.test.mjs BASE_URL NAME POINTS [SHOTS_DIR]
// NAME is the octree's folder in the served directory (its index lists it
// as kind "octree"), POINTS its point count. Checks: the first points are
// drawn with the first nodes to arrive (the time is printed; the bench
// measures it, tests do not time); the nodes' clip lines arrive; every node
// arrives by a Range request (206) and is CRC-checked; the points held
// (uploaded + in flight) never pass the budget while the camera flies in,
// around and out (nodes are evicted); the budget slider, point size, up
// axis, 2 passes and eye-dome lighting change the picture without errors;
// ?octree=URL opens the same octree without the server's index; nodes
// whose children are drawn shrink their points (adaptive size), and with
// every node of NAME_small (a smaller octree in the same folder) drawn the
// adaptive picture covers less than the fixed floors' and nothing outside.

import { launchChromium } from './chromium.mjs';
import fs from 'node:fs';
import path from 'node:path';

const HARD_TIMEOUT_MS = 100000;
const [baseUrl, name, totalText, shotsDir] = process.argv.slice(2);
if (!baseUrl || !name || !totalText) {
  console.error('usage: node octree.test.mjs BASE_URL NAME POINTS [SHOTS_DIR]');
  process.exit(2);
}
const base = baseUrl.replace(/\/$/, '');
const total = Number(totalText);
let failures = 0;
let checks = 0;
let browser = null;
let profile = null;

const hardTimeout = setTimeout(async () => {
  console.log(`not ok - the octree browser tests took more than ${HARD_TIMEOUT_MS / 1000} s`);
  try { if (browser) await browser.close(); } catch { /* exiting anyway */ }
  process.exit(1);
}, HARD_TIMEOUT_MS);

function check(description, condition, detail = '') {
  checks++;
  if (!condition) failures++;
  console.log(`${condition ? 'ok' : 'not ok'} - ${description}${detail ? ` (${detail})` : ''}`);
  return condition;
}

const stats = (page) => page.evaluate(() => JSON.parse(JSON.stringify(window.viewerStats || null)));

/* Waits until no node is in flight and every chosen node is drawn (the view settled). */
async function settled(page, what, timeout = 20000) {
  try {
    await page.waitForFunction(() => {
      const view = window.viewer && window.viewer.view;
      const s = window.viewerStats;
      return view && view.requests && view.requests.size === 0 && s.framesDrawn > 0 &&
        s.nodesDrawn === s.nodesSelected - view.selection.filter((node) => node.points === 0).length;
    }, null, { timeout, polling: 50 });
    return true;
  } catch {
    check(`${what}: settled within ${timeout / 1000} s`, false, JSON.stringify(await stats(page)));
    return false;
  }
}

/* A hash of the canvas's pixels (to see that a control changed the picture) and the share not background
 * (and, with withMask, which pixels: one byte each). */
async function picture(page, withMask = false) {
  return page.evaluate((wantMask) => {
    const canvas = document.getElementById('view');
    const copy = document.createElement('canvas');
    copy.width = canvas.width;
    copy.height = canvas.height;
    const context = copy.getContext('2d');
    context.drawImage(canvas, 0, 0);
    const pixels = context.getImageData(0, 0, canvas.width, canvas.height).data;
    let hash = 2166136261;
    let covered = 0;
    const mask = wantMask ? [] : null;
    for (let i = 0; i < pixels.length; i += 4) {
      hash = Math.imul(hash ^ pixels[i] ^ (pixels[i + 1] << 8) ^ (pixels[i + 2] << 16), 16777619) >>> 0;
      const on = pixels[i] < 230 || pixels[i + 1] < 230 || pixels[i + 2] < 230;
      if (on) covered++;
      if (mask) mask.push(on ? 1 : 0);
    }
    return { hash, covered: covered / (canvas.width * canvas.height), mask };
  }, withMask);
}

/* Waits for the octree view's first points. The page's first stats object
 * (the app's, before the view resets it) has no firstPointsMs at all: only
 * a number from the octree view counts (a regression: `!== null` passed on
 * that first object and read the stats before any point was drawn). */
async function firstPoints(page) {
  await page.waitForFunction(() => window.viewerStats && window.viewerStats.view === 'octree' &&
    typeof window.viewerStats.firstPointsMs === 'number', null, { timeout: 20000 }).catch(() => {});
}

async function shot(page, file) {
  if (!shotsDir) return;
  fs.mkdirSync(shotsDir, { recursive: true });
  await page.screenshot({ path: path.join(shotsDir, file) });
}

async function redraw(page) {
  await page.evaluate(() => new Promise((resolve) => {
    window.viewer.requestDraw();
    requestAnimationFrame(() => requestAnimationFrame(resolve));
  }));
}

async function main() {
  const index = await (await fetch(`${base}/api/index.json`)).json();
  const model = index.models.find((m) => m.name === name);
  check('the index lists the octree by its folder', model && model.kind === 'octree' && model.points === total &&
    model.normals === true, JSON.stringify(model));

  ({ browser, profile } = await launchChromium({ width: 800, height: 600 }));
  const page = browser.pages()[0] || (await browser.newPage());
  const pageErrors = [];
  page.on('pageerror', (error) => pageErrors.push(error.message));
  page.on('console', (message) => {
    if (message.type() === 'error' && !/favicon/.test(message.text())) pageErrors.push(message.text());
  });
  const rangeRequests = [];
  page.on('request', (request) => {
    if (request.url().endsWith('/octree.bin')) rangeRequests.push(request.headers().range || '');
  });
  const budget = 60000;
  await page.goto(`${base}/?model=${encodeURIComponent(name)}&budget=${budget}`);
  await firstPoints(page);
  const atFirstPoints = await stats(page);
  await settled(page, 'first view');
  let s = await stats(page);
  // How soon is a speed, measured by bench/octree_browser.mjs (issue 23: within
  // 1 s on the loopback server), not here: on 2 cores shared with the other
  // tests it swings 0.5-1.3 s. What the test holds is why it is soon: the
  // viewer draws with the first nodes it gets, not after the whole view.
  check('the first points are drawn with the first view\'s own nodes as they arrive (nothing else fetched first)',
    typeof atFirstPoints.firstPointsMs === 'number' && atFirstPoints.firstPointsNodes >= 1 &&
    atFirstPoints.firstPointsNodes <= s.nodesLoaded && atFirstPoints.firstPointsBytes <= s.bytesReceived,
    `${atFirstPoints.firstPointsNodes} of the first view's ${s.nodesLoaded} nodes, ${atFirstPoints.firstPointsBytes} of ` +
    `${s.bytesReceived} bytes`);
  console.log(`# first points ${atFirstPoints.firstPointsMs && atFirstPoints.firstPointsMs.toFixed(0)} ms after the view ` +
    `opened, ${atFirstPoints.firstPointsSinceNavigationMs && atFirstPoints.firstPointsSinceNavigationMs.toFixed(0)} ms after navigation`);
  await shot(page, 'octree-first.png');
  const first = await picture(page);
  check('the first view draws the cloud', s.pointsDrawn > 0 && first.covered > 0.1,
    `${s.pointsDrawn} points in ${s.nodesDrawn} nodes, ${(100 * first.covered).toFixed(1)}% of the canvas`);
  // The bunny's holes underneath are borders: 0.3% of its points carry a
  // clip line (src/octree.c, chunk_clips), which the worker passes on.
  check('the nodes bring their clip lines (border splats cut)', s.clippedPoints > 0 &&
    s.clippedPoints < 0.02 * s.pointsDrawn, `${s.clippedPoints} of ${s.pointsDrawn} points drawn`);
  check('the budget binds in the first view and holds', s.selectionPoints <= budget && s.maxPointsHeld <= budget &&
    s.pointsDrawn <= budget && s.selectionPoints > budget / 2, JSON.stringify({ selection: s.selectionPoints,
    held: s.pointsHeld, maxHeld: s.maxPointsHeld, drawn: s.pointsDrawn }));
  // Adaptive radii (Potree's adaptive point size, as lk_octree_load_selection): where a node's children
  // are drawn too, its points shrink to what the deepest drawn node needs.
  check('points of nodes whose children are drawn may shrink', s.adaptive === true && s.adaptivePoints > 0 &&
    s.adaptivePoints < s.pointsDrawn, `${s.adaptivePoints} of ${s.pointsDrawn} points`);
  check('every node came by a Range request answered 206', s.rangeRequests > 0 && rangeRequests.length === s.rangeRequests &&
    rangeRequests.every((range) => /^bytes=\d+-\d+$/.test(range)) && s.partialResponses === s.nodesLoaded,
    `${s.rangeRequests} requests, ${s.partialResponses} answered 206, ${(s.bytesReceived / 1024).toFixed(0)} KiB`);

  // Fly: in, around, out, in again; the held points never pass the budget.
  const steps = [['zoom', 0.6], ['zoom', 0.6], ['zoom', 0.6], ['rotate', 120, 0], ['rotate', 0, -40], ['zoom', 0.6],
    ['pan', 80, 40], ['zoom', 4], ['rotate', -200, 30], ['zoom', 0.3]];
  let deepest = 0;
  let worst = 0;
  for (const [what, ...args] of steps) {
    await page.evaluate(([w, a]) => window.viewer.control(w, ...a), [what, args]);
    await redraw(page);
    await settled(page, `after ${what} ${args}`);
    s = await stats(page);
    worst = Math.max(worst, s.maxPointsHeld);
    deepest = Math.max(deepest, await page.evaluate(() => Math.max(...window.viewer.view.selection.map((n) => n.level))));
  }
  await shot(page, 'octree-flown.png');
  check('flying: the points held never passed the budget', worst <= budget && s.pointsHeld <= budget,
    `most held ${worst}, budget ${budget}`);
  check('flying: nodes were evicted and deeper ones fetched', s.nodesEvicted > 0 && deepest >= 3,
    `${s.nodesEvicted} evicted, deepest level ${deepest}, ${s.rangeRequests} Range requests`);

  // The controls.
  await page.evaluate(() => {
    const slider = document.getElementById('budget');
    slider.value = '200000';
    slider.dispatchEvent(new Event('input'));
  });
  await redraw(page);
  await settled(page, 'budget 200,000');
  s = await stats(page);
  check('the budget slider sets the budget', s.budget === 200000 && s.maxPointsHeld <= 200000 && s.selectionPoints > budget,
    `${s.selectionPoints} points chosen`);
  let before = await picture(page);
  await page.evaluate(() => {
    const slider = document.getElementById('point-size');
    slider.value = '2';
    slider.dispatchEvent(new Event('input'));
  });
  await redraw(page);
  let after = await picture(page);
  check('point size 2 covers more of the canvas', after.covered > before.covered,
    `${(100 * before.covered).toFixed(1)}% -> ${(100 * after.covered).toFixed(1)}%`);
  before = after;
  await page.selectOption('#up-axis', 'z');
  await redraw(page);
  await settled(page, 'z up');
  after = await picture(page);
  s = await stats(page);
  check('z up turns the view', s.upAxis === 'z' && after.hash !== before.hash && after.covered > 0.02);
  await shot(page, 'octree-z-up.png');
  before = after;
  await page.check('#edl');
  await redraw(page);
  after = await picture(page);
  s = await stats(page);
  check('eye-dome lighting changes the picture', s.edl === true && after.hash !== before.hash && after.covered > 0.02,
    `${(100 * after.covered).toFixed(1)}% covered`);
  await shot(page, 'octree-edl.png');
  await page.check('#passes-2');
  await redraw(page);
  s = await stats(page);
  after = await picture(page);
  check('2 passes with eye-dome lighting draw', s.passes === 2 && s.edl === true && after.covered > 0.02, s.splatPath);

  // Any static server: the octree named by its address, no index needed.
  const address = `/m/${name}/octree.json`;
  await page.goto(`${base}/?octree=${encodeURIComponent(address)}&budget=100000&up=z&edl=1`);
  await firstPoints(page);
  await settled(page, '?octree=');
  s = await stats(page);
  check('?octree=URL opens the octree with its parameters', s.view === 'octree' && s.pointsDrawn > 0 &&
    s.budget === 100000 && s.upAxis === 'z' && s.edl === true && s.maxPointsHeld <= 100000,
    `first points ${s.firstPointsMs && s.firstPointsMs.toFixed(0)} ms`);
  // With every node drawn (a smaller octree, the whole budget, no spacing limit) each point is at its
  // own radius, never above the fixed floors' (the "adaptive size" box off: every inner node's points
  // at least its spacing), so the adaptive picture covers no pixel the fixed one does not (up to
  // highlights read as background) and fewer. Splats three times their radius (size=3) make the
  // difference pixels wide.
  const small = index.models.find((m) => m.name === `${name}_small`);
  check(`the index lists ${name}_small`, !!small);
  if (small) {
    await page.goto(`${base}/?model=${encodeURIComponent(small.name)}&budget=${small.points}&minpx=0&size=3`);
    await firstPoints(page);
    await settled(page, `${small.name}, every node`);
    const adaptive = await picture(page, true);
    const adaptiveStats = await stats(page);
    await page.evaluate(() => {
      const box = document.getElementById('adaptive');
      box.checked = false;
      box.dispatchEvent(new Event('change'));
    });
    await redraw(page);
    const fixed = await picture(page, true);
    const fixedStats = await stats(page);
    let onlyAdaptive = 0;
    let onlyFixed = 0;
    for (let i = 0; i < adaptive.mask.length; i++) {
      if (adaptive.mask[i] && !fixed.mask[i]) onlyAdaptive++;
      if (fixed.mask[i] && !adaptive.mask[i]) onlyFixed++;
    }
    check('every node drawn: adaptive radii cover less than fixed floors and nothing outside them',
      adaptiveStats.adaptive === true && fixedStats.adaptive === false && adaptiveStats.pointsDrawn === small.points &&
      fixedStats.pointsDrawn === small.points && adaptiveStats.adaptivePoints > 0 && onlyFixed > 10 * onlyAdaptive &&
      onlyAdaptive <= 0.001 * adaptive.mask.length,
      `${(100 * adaptive.covered).toFixed(2)}% vs ${(100 * fixed.covered).toFixed(2)}% of the canvas; pixels only ` +
      `adaptive ${onlyAdaptive}, only fixed ${onlyFixed}`);
  }
  check('no page errors', pageErrors.length === 0, pageErrors.slice(0, 3).join(' | '));
}

main()
  .catch((error) => check('octree browser test ran', false, error.stack || String(error)))
  .finally(async () => {
    try { if (browser) await browser.close(); } catch { /* closing anyway */ }
    if (profile) fs.rmSync(profile, { recursive: true, force: true });
    clearTimeout(hardTimeout);
    console.log(`${checks} checks, ${failures} failed`);
    process.exit(failures ? 1 : 0);
  });
