// SPDX-License-Identifier: MIT
// The viewer's progressive mesh view (web/mesh_view.js, decoding in
// web/stream_worker.js) in headless Chromium: how soon the first frame and
// the full level come, how long the worker decodes, and the longest task on
// the page's thread while the stream refines (issue 19's "decode speed in
// the browser worker"; the page must never freeze). Speeds are measured
// here, not in tests/browser/viewer.test.mjs, which checks that the stream
// decodes in the worker and draws every level.
//
//   node bench/stream_browser.mjs BASE_URL MODEL [RUNS]
//
// BASE_URL is a `lodkit serve` whose folder holds MODEL (a .lks of version
// 2, the index's name). Each of RUNS (default 3) rounds loads it twice: as
// a user would (the worker decodes with stream2.wasm, the C decoder built as
// WebAssembly, when the server has it and it is ready in time; the table's
// decoder column says which ran), then with web/stream2.js
// (`&decoder=js`). Each load is a new page in a
// browser with GPU compositing on SwiftShader (as the viewer test starts
// it: under --disable-gpu the software compositor reads every WebGL frame
// back on the page's thread, which a page with a GPU never pays). Long
// tasks: PerformanceObserver 'longtask' (tasks over 50 ms) begun between the
// stream's first request and the full level's frame. Uses playwright-core
// from tests/browser (`npm ci` there).

import path from 'node:path';
import { createRequire } from 'node:module';
import { fileURLToPath } from 'node:url';

const [baseUrl, model, runsText] = process.argv.slice(2);
if (!baseUrl || !model) {
  console.error('usage: node bench/stream_browser.mjs BASE_URL MODEL [RUNS]');
  process.exit(2);
}
const runs = Number(runsText || 3);
const here = path.dirname(fileURLToPath(import.meta.url));
const require = createRequire(path.join(here, '..', 'tests', 'browser', 'package.json'));
const { chromium } = require('playwright-core');

const browser = await chromium.launch({
  executablePath: '/usr/bin/chromium',
  headless: true,
  args: ['--headless', '--no-sandbox', '--enable-unsafe-swiftshader', '--use-angle=swiftshader', '--ignore-gpu-blocklist',
    '--disable-quic', '--no-first-run', '--disable-background-networking', '--disable-component-update', '--disable-sync'],
});
console.log(`Headless Chromium (800x600, SwiftShader, GPU compositing), ${model} from ${baseUrl}, ${runs} load${runs === 1 ? '' : 's'}, each a new page.\n`);
console.log('Each round loads it twice: as a user would (the worker decodes with stream2.wasm, the C decoder as WebAssembly, when the module is ready within 100 ms of the first bytes; the decoder column says which ran), then with web/stream2.js (`&decoder=js`).\n');
console.log('| load | decoder | bytes | triangles | first frame ms | full level ms | worker decode ms (busy) | main-thread uploads ms | long tasks while streaming | longest task ms |');
console.log('|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|');
let failed = false;
for (let load = 0; load < 2 * runs; load++) {
  const run = (load >> 1) + 1;
  const forceJs = load % 2 === 1;
  const page = await browser.newPage({ viewport: { width: 800, height: 600 } });
  await page.addInitScript(() => {
    window.longTasks = [];
    new PerformanceObserver((list) => {
      for (const entry of list.getEntries()) window.longTasks.push({ start: entry.startTime, duration: entry.duration });
    }).observe({ type: 'longtask' });
  });
  await page.goto(`${baseUrl.replace(/\/$/, '')}/?model=${encodeURIComponent(model)}${forceJs ? '&decoder=js' : ''}`);
  try {
    await page.waitForFunction(() => {
      const s = window.viewerStats;
      return s && (s.error || (s.view === 'mesh' && s.done && s.level === s.levels && s.fullFrameMs !== undefined));
    }, null, { timeout: 120000, polling: 50 });
  } catch {
    console.log(`| ${run} | ${forceJs ? 'js' : ''} | the stream did not reach its full level in 120 s | | | | | | | |`);
    failed = true;
    await page.close();
    continue;
  }
  const { s, tasks } = await page.evaluate(() => ({ s: JSON.parse(JSON.stringify(window.viewerStats)), tasks: window.longTasks }));
  if (s.error) {
    console.log(`| ${run} | ${s.decoder} | viewer error: ${s.error} | | | | | | | |`);
    failed = true;
  } else {
    const streaming = tasks.filter((task) => task.start >= s.streamStart && task.start < s.fullFrameAt);
    const longest = streaming.reduce((most, task) => Math.max(most, task.duration), 0);
    console.log(`| ${run} | ${s.decoder} | ${s.totalBytes} | ${s.triangles} | ${s.firstFrameMs.toFixed(0)} | ${s.fullFrameMs.toFixed(0)} | ` +
      `${s.decodeMs.toFixed(0)} (${s.workerMs.toFixed(0)}) | ${(s.uploadMs || 0).toFixed(0)} | ${streaming.length} | ` +
      `${streaming.length ? longest.toFixed(0) : 'none over 50'} |`);
  }
  await page.close();
}
await browser.close();
process.exit(failed ? 1 : 0);
