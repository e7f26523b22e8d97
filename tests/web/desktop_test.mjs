// The page on the desktop (headless Chromium, software GL): hover names, grab the liver with the
// mouse and drag it, force readout, the organ list (isolate / show all). Screenshots: the atlas and
// the liver pulled. Prints fps() while the physics runs (docs/performance.md).
//   node tests/web/desktop_test.mjs SITE SCREENSHOT_DIR
import { mkdirSync } from 'node:fs';
import path from 'node:path';
import { SKIP, checker, chromiumPath, openPage, sleep } from './browser.mjs';

const [site, shots = 'screenshots'] = process.argv.slice(2);
if (!site) { console.error('usage: desktop_test.mjs SITE [SCREENSHOT_DIR]'); process.exit(2); }
if (!chromiumPath()) { console.log('SKIP: chromium not installed (apt-get install chromium; see docs/web.md)'); process.exit(SKIP); }
mkdirSync(shots, { recursive: true });
const { check, failed } = checker();
const { browser, page, server, errors } = await openPage(site);
const T = 'window.softatlasTest';
try {
  await sleep(1000);
  await page.screenshot({ path: path.join(shots, 'desktop_atlas.png') });
  const idle = [];
  for (let k = 0; k < 3; ++k) { await sleep(500); idle.push(await page.evaluate(`${T}.fps()`)); }
  const p = await page.evaluate(`${T}.organSurfacePoint('liver')`);
  const [x, y] = await page.evaluate((q) => window.softatlasView.toScreen(q), p);
  await page.mouse.move(x, y);
  await sleep(200);
  const tip = await page.textContent('#tip');
  check('hover name', tip === 'liver', `tooltip '${tip}' at (${x.toFixed(0)}, ${y.toFixed(0)})`);
  await page.mouse.down();
  await sleep(200);
  for (let k = 1; k <= 10; ++k) { await page.mouse.move(x, y + 6 * k); await sleep(40); }
  const fps = [];
  for (let k = 0; k < 4; ++k) { await sleep(500); fps.push(await page.evaluate(`${T}.fps()`)); }
  // The physics worker may lag on a loaded machine: wait (up to 60 s) until it caught up.
  await page.waitForFunction(`${T}.maxDisplacementMm('liver') >= 10`, null, { timeout: 60000, polling: 200 }).catch(() => {});
  const moved = await page.evaluate(`${T}.maxDisplacementMm('liver')`);
  const reaction = await page.evaluate(`${T}.reactionN()`);
  const readout = await page.textContent('#force');
  await page.screenshot({ path: path.join(shots, 'desktop_liver_pulled.png') });
  await page.mouse.up();
  check('liver dragged', moved >= 10, `max displacement ${moved.toFixed(2)} mm after a 60 px drag`);
  check('reaction force', reaction > 0, `${reaction.toFixed(4)} N`);
  check('force readout', /liver: reaction [0-9.]+ N/.test(readout), `'${readout}'`);
  await sleep(200);
  check('released', (await page.evaluate(`${T}.reactionN()`)) === 0, 'no reaction after the mouse button is up');
  // Organ list: isolate the liver, then show all.
  await page.click('button[data-isolate="liver"]');
  const shown = await page.$$eval('input[data-organ]', (b) => b.filter((x) => x.checked).map((x) => x.dataset.organ));
  check('isolate', shown.length === 1 && shown[0] === 'liver', `shown after isolate: ${shown.join(', ')}`);
  await sleep(300);
  await page.screenshot({ path: path.join(shots, 'desktop_isolated.png') });
  await page.click('#showall');
  const all = await page.$$eval('input[data-organ]', (b) => b.filter((x) => x.checked).length);
  check('show all', all >= 4, `${all} organs shown`);
  // Orbit: a drag on the background turns the view (the liver's screen position changes).
  await page.mouse.move(60, 650);
  await page.mouse.down();
  await page.mouse.move(260, 650, { steps: 8 });
  await page.mouse.up();
  await sleep(200);
  const [x2] = await page.evaluate((q) => window.softatlasView.toScreen(q), p);
  check('orbit', Math.abs(x2 - x) > 20, `liver point moved ${(x2 - x).toFixed(0)} px on screen`);
  check('no page errors', errors.length === 0, errors.join(' | ') || 'none');
  const stats = await page.evaluate('window.softatlasView.stats()');
  const med = (a) => +a.slice().sort((u, v) => u - v)[a.length >> 1].toFixed(1);
  console.log(JSON.stringify({ mode: 'desktop', fps_idle: idle.map((v) => +v.toFixed(1)), fps_pulling: fps.map((v) => +v.toFixed(1)),
    fps_pulling_median: med(fps), physics_real_time_factor: stats && +(stats.simTime / stats.wallTime).toFixed(3),
    main_update_ms: stats && +stats.updateMs.toFixed(2), main_render_ms: stats && +stats.renderMs.toFixed(2), moved_mm: +moved.toFixed(2) }));
} finally {
  await browser.close();
  server.close();
}
process.exit(failed() ? 1 : 0);
