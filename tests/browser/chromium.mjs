// SPDX-License-Identifier: MIT
// Debian's /usr/bin/chromium as every browser test (and bench/octree_browser.mjs)
// starts it: headless, WebGL through SwiftShader (no GPU), no network of its
// own, in a new empty profile folder (docs: shared/DESIGN.md, "Headless
// rendering here"). Never a downloaded browser.

import { chromium } from 'playwright-core';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';

export const CHROMIUM_ARGS = ['--headless', '--no-sandbox', '--disable-gpu', '--enable-unsafe-swiftshader',
  '--disable-quic', '--no-first-run', '--disable-background-networking', '--disable-component-update', '--disable-sync'];

/** { browser (a persistent context), profile (its folder: remove it when done) } for a viewport. */
export async function launchChromium(viewport) {
  const profile = fs.mkdtempSync(path.join(os.tmpdir(), 'lodkit-chromium-'));
  const browser = await chromium.launchPersistentContext(profile, {
    executablePath: '/usr/bin/chromium',
    headless: true,
    viewport,
    args: CHROMIUM_ARGS,
  });
  return { browser, profile };
}
