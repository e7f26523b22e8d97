// The page in immersive-vr: Debian's Chromium + IWER emulating a Quest 3 with stereo on. Enter VR,
// two eye views; the right controller at organSurfacePoint('liver') grabs the liver with the
// trigger and pulls it 3 cm towards the user: the liver moves >= 10 mm, the reaction is > 0 and
// the controller was asked to vibrate. Screenshots: the stereo pair and the pulled liver.
// Prints the page's fps() with the physics running (docs/performance.md).
//   node tests/web/xr_test.mjs SITE SCREENSHOT_DIR
import { mkdirSync } from 'node:fs';
import path from 'node:path';
import { SKIP, checker, chromiumPath, openPage, sleep } from './browser.mjs';

const [site, shots = 'screenshots'] = process.argv.slice(2);
if (!site) { console.error('usage: xr_test.mjs SITE [SCREENSHOT_DIR]'); process.exit(2); }
if (!chromiumPath()) { console.log('SKIP: chromium not installed (apt-get install chromium; see docs/web.md)'); process.exit(SKIP); }
mkdirSync(shots, { recursive: true });
const { check, failed } = checker();
const { browser, page, server, errors } = await openPage(site, { xr: true });
const T = 'window.softatlasTest';
try {
  await page.evaluate(`${T}.enterVR()`);
  await page.waitForFunction(`${T}.xrViews() > 0`, null, { timeout: 30000 });
  await sleep(500);
  const views = await page.evaluate(`${T}.xrViews()`);
  check('two eye views', views === 2, `${views} views in the XR frame`);
  await page.screenshot({ path: path.join(shots, 'xr_stereo.png') });

  const surface = await page.evaluate(`${T}.organSurfacePoint('liver')`);
  const centre = await page.evaluate(`${T}.organCentre('liver')`);
  check('liver in front of the user', centre[2] < -0.1 && centre[1] > 0.8 && centre[1] < 1.8,
    `centre (${centre.map((v) => v.toFixed(3))}) m, surface point (${surface.map((v) => v.toFixed(3))}) m`);
  // The right controller to the liver's anterior surface (IWER's global space is local-floor).
  const setRight = (p) => page.evaluate(([x, y, z]) => window.iwerDevice.controllers.right.position.set(x, y, z), p);
  await setRight(surface);
  await sleep(300);
  const at = (await page.evaluate('window.softatlasView.controllers()'))[1] || [];
  const rest = await page.evaluate(`${T}.maxDisplacementMm('liver')`);
  await page.evaluate(() => window.iwerDevice.controllers.right.updateButtonValue('trigger', 1));
  await sleep(300);
  // Pull 3 cm towards the user (+Z, the patient's anterior) over half a second, then hold.
  const fps = [];
  for (let k = 1; k <= 10; ++k) {
    await setRight([surface[0], surface[1], surface[2] + 0.003 * k]);
    await sleep(50);
  }
  for (let k = 0; k < 6; ++k) { await sleep(500); fps.push(await page.evaluate(`${T}.fps()`)); }
  // On a loaded machine the physics worker may lag behind real time: wait (up to 60 s) until it
  // has caught up with the controller rather than reading the state at a fixed time.
  await page.waitForFunction(`${T}.maxDisplacementMm('liver') >= 10`, null, { timeout: 60000, polling: 200 }).catch(() => {});
  const moved = await page.evaluate(`${T}.maxDisplacementMm('liver')`);
  const reaction = await page.evaluate(`${T}.reactionN()`);
  const pulses = await page.evaluate(`${T}.hapticPulses()`);
  const stats = await page.evaluate('window.softatlasView.stats()');
  await page.screenshot({ path: path.join(shots, 'xr_liver_pulled.png') });
  check('liver pulled', moved >= 10, `max displacement ${moved.toFixed(2)} mm (before the grab ${rest.toFixed(2)} mm; controller at ${at.map((v) => v.toFixed(3))})`);
  check('reaction force', reaction > 0, `${reaction.toFixed(4)} N`);
  check('haptic pulses', pulses >= 1, `${pulses} pulses requested`);
  await page.evaluate(() => window.iwerDevice.controllers.right.updateButtonValue('trigger', 0));
  await sleep(300);
  const released = await page.evaluate(`${T}.reactionN()`);
  check('released', released === 0, `reaction after the trigger is let go: ${released} N`);
  check('no page errors', errors.length === 0, errors.join(' | ') || 'none');
  const realTime = stats ? stats.simTime / stats.wallTime : 0;
  console.log(JSON.stringify({ mode: 'immersive-vr', fps_samples: fps.map((v) => +v.toFixed(1)),
    fps_median: +fps.slice().sort((a, b) => a - b)[fps.length >> 1].toFixed(1), physics_real_time_factor: +realTime.toFixed(3),
    physics_steps: stats && stats.steps, main_update_ms: stats && +stats.updateMs.toFixed(2), main_render_ms: stats && +stats.renderMs.toFixed(2), moved_mm: +moved.toFixed(2), reaction_N: +reaction.toFixed(4), haptic_pulses: pulses }));
} finally {
  await browser.close();
  server.close();
}
process.exit(failed() ? 1 : 0);
