// Shared by the browser tests: a static server for the exported folder, Debian's Chromium driven
// by playwright-core (no browser download), and IWER (Meta's Immersive Web Emulation Runtime)
// emulating a Quest 3 with stereo on, injected before the page's scripts.
import { existsSync, mkdirSync, readFileSync } from 'node:fs';
import http from 'node:http';
import { createRequire } from 'node:module';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const ROOT = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '../..');
const require = createRequire(path.join(ROOT, 'web/package.json'));  // web/node_modules

export const SKIP = 77;  // ctest SKIP_RETURN_CODE

export function chromiumPath() {
  for (const p of [process.env.CHROMIUM, '/usr/bin/chromium', '/usr/bin/chromium-browser'])
    if (p && existsSync(p)) return p;
  return null;
}

const TYPES = { '.html': 'text/html', '.js': 'text/javascript', '.mjs': 'text/javascript', '.wasm': 'application/wasm',
  '.json': 'application/json', '.glb': 'model/gltf-binary', '.png': 'image/png' };

// Serves `dir` on 127.0.0.1 (a free port); resolves to {url, close}.
export function serve(dir) {
  const server = http.createServer((req, res) => {
    const rel = decodeURIComponent(new URL(req.url, 'http://x').pathname).replace(/^\/+/, '') || 'index.html';
    const file = path.resolve(dir, rel);
    if (!file.startsWith(path.resolve(dir)) || !existsSync(file)) { res.writeHead(404); res.end(); return; }
    res.writeHead(200, { 'Content-Type': TYPES[path.extname(file)] || 'application/octet-stream' });
    res.end(readFileSync(file));
  });
  return new Promise((resolve) => server.listen(0, '127.0.0.1', () =>
    resolve({ url: `http://127.0.0.1:${server.address().port}/`, close: () => server.close() })));
}

// IWER as one classic script for addInitScript: a Quest 3 with both controllers, stereo on,
// installed over Chromium's own navigator.xr (forceInstall), reachable as window.iwerDevice.
function iwerScript() {
  const esbuild = require('esbuild');
  const out = esbuild.buildSync({
    stdin: {
      contents: `import { XRDevice, metaQuest3 } from 'iwer';
        const device = new XRDevice(metaQuest3, { stereoEnabled: true });
        device.stereoEnabled = true;
        device.installRuntime({ forceInstall: true });
        window.iwerDevice = device;`,
      resolveDir: path.join(ROOT, 'web'),
    },
    bundle: true, format: 'iife', write: false, target: 'es2020', logLevel: 'error',
  });
  return out.outputFiles[0].text;
}

// Launches Chromium headless with software GL and opens SITE/index.html?test=1; waits for
// window.softatlasTest.ready. Returns {browser, page, server}.
export async function openPage(site, { xr = false, width = 1280, height = 720 } = {}) {
  const { chromium } = require('playwright-core');
  const userDir = path.join(os.tmpdir(), `softatlas-chromium-${process.pid}-${Date.now()}`);
  mkdirSync(userDir, { recursive: true });
  const server = await serve(site);
  // A fresh profile (--user-data-dir) each run.
  const browser = await chromium.launchPersistentContext(userDir, {
    executablePath: chromiumPath(),
    headless: true,
    viewport: { width, height },
    args: ['--no-sandbox', '--disable-gpu', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
      '--ignore-gpu-blocklist', '--disable-background-networking', '--disable-component-update', '--disable-sync',
      '--no-first-run',
      // Frames as fast as the page can make them (fps() then measures the capacity; a headset's
      // compositor sets the real rate): no 60 Hz headless begin-frame cap, no vsync.
      '--disable-frame-rate-limit', '--disable-gpu-vsync'],
  });
  const page = browser.pages()[0] || await browser.newPage();
  const errors = [];
  page.on('pageerror', (e) => errors.push(String(e)));
  page.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
  if (xr) await page.addInitScript({ content: iwerScript() });
  await page.goto(`${server.url}index.html?test=1`);
  try {
    await page.waitForFunction(() => window.softatlasTest && window.softatlasTest.ready === true, null, { timeout: 120000 });
  } catch (e) {
    const text = await page.evaluate(() => document.getElementById('status')?.textContent).catch(() => '');
    throw new Error(`page not ready: ${text} ${errors.join(' | ')}`);
  }
  return { browser, page, server, errors };
}

// Counts checks; prints one line per check.
export function checker() {
  let fails = 0;
  const check = (what, ok, detail) => {
    console.log(`${ok ? 'ok  ' : 'FAIL'} ${what}: ${detail}`);
    if (!ok) fails++;
  };
  return { check, failed: () => fails };
}

export const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
