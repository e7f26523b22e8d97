// N steps of sim/ in WebAssembly (the exported page's softatlas_sim.wasm, fed the exported
// scene.json) against the same steps natively (web_native_steps on the organ set): positions must
// agree within 1e-9 relative. Run by ctest (tests/web/CMakeLists.txt):
//   node --no-experimental-fetch tests/web/wasm_match.mjs SITE NATIVE_BIN SET [ORGAN PULL FREE]
import { execFileSync } from 'node:child_process';
import { readFileSync } from 'node:fs';
import { createRequire } from 'node:module';
import path from 'node:path';
import { pathToFileURL } from 'node:url';

const [site, nativeBin, set, organ = 'liver', pull = '300', free = '200'] = process.argv.slice(2);
if (!site || !nativeBin || !set) {
  console.error('usage: wasm_match.mjs SITE NATIVE_BIN SET [ORGAN PULL FREE]');
  process.exit(2);
}
// Emscripten 3.1.6's ES6 glue calls require() and __dirname when it runs under node.
globalThis.require = createRequire(import.meta.url);
globalThis.__dirname = path.resolve(site);

const t0 = performance.now();
const native = JSON.parse(execFileSync(nativeBin, [set, organ, pull, free], { maxBuffer: 1 << 28 }).toString());
const tNative = performance.now() - t0;

const { default: createSoftAtlasSim } = await import(pathToFileURL(path.resolve(site, 'softatlas_sim.mjs')).href);
const { Physics } = await import(pathToFileURL(path.resolve(path.dirname(new URL(import.meta.url).pathname), '../../web/src/physics.js')).href);
const sceneJson = JSON.parse(readFileSync(path.join(site, 'scene.json'), 'utf8'));
const module = await createSoftAtlasSim({ locateFile: (f) => path.resolve(site, f) });
const physics = new Physics(module, sceneJson);
const i = physics.organIndex(organ);
// The most anterior vertex of the organ's rest shape (vertices used by a face), as natively.
const o = sceneJson.organs.find((q) => q.name === organ);
const used = new Set(o.faces);
let front = -1;
for (const v of used) if (front < 0 || o.vertices[3 * v + 1] > o.vertices[3 * front + 1]) front = v;
const point = [0, 1, 2].map((k) => o.vertices[3 * front + k]);
const t1 = performance.now();
const grabbed = physics.grab(i, point, 0.010);
physics.move([0, 0.020, 0]);
physics.step(Number(pull));
const reaction = physics.reaction();
physics.release();
physics.step(Number(free));
const tWasm = performance.now() - t1;

let fails = 0;
const check = (what, ok, detail) => {
  console.log(`${ok ? 'ok  ' : 'FAIL'} ${what}: ${detail}`);
  if (!ok) fails++;
};
check('same grasp point', point.every((v, k) => v === native.point[k]), `${point.map((v) => (v * 1000).toFixed(3))} mm`);
check('same grasped vertices', grabbed === native.grabbed, `${grabbed} (native ${native.grabbed})`);
let worstPos = 0, worstDisp = 0, maxDisp = 0, scale = 0;
for (const [name, nat] of Object.entries(native.organs)) {
  const w = physics.positions(physics.organIndex(name));
  const rest = sceneJson.organs.find((q) => q.name === name).vertices;
  if (w.length !== nat.length) { check(`${name} size`, false, `${w.length} vs ${nat.length}`); continue; }
  for (let k = 0; k < w.length; ++k) {
    scale = Math.max(scale, Math.abs(nat[k]));
    worstPos = Math.max(worstPos, Math.abs(w[k] - nat[k]));
    maxDisp = Math.max(maxDisp, Math.abs(nat[k] - rest[k]));
  }
}
worstDisp = worstPos;
const relPos = worstPos / scale, relDisp = worstDisp / Math.max(maxDisp, 1e-300);
check('moved', maxDisp > 0.005, `largest displacement ${(maxDisp * 1000).toFixed(2)} mm after ${pull} + ${free} steps`);
check('positions within 1e-9 relative', relPos <= 1e-9, `max |wasm - native| = ${worstPos.toExponential(3)} m, / max |x| = ${relPos.toExponential(3)}`);
check('displacements within 1e-9 relative', relDisp <= 1e-9, `max |wasm - native| / max displacement = ${relDisp.toExponential(3)}`);
const relF = Math.hypot(...reaction.map((v, k) => v - native.reaction[k])) / Math.max(1e-300, Math.hypot(...native.reaction));
check('tool reaction within 1e-9 relative', relF <= 1e-9, `|F| = ${Math.hypot(...reaction).toFixed(6)} N, rel diff ${relF.toExponential(3)}`);
const steps = Number(pull) + Number(free);
console.log(JSON.stringify({ steps, wasm_us_per_step: (1000 * tWasm) / steps, native_process_ms: tNative, max_abs_diff_m: worstPos, rel_diff: relPos, rel_disp_diff: relDisp }));
process.exit(fails ? 1 : 0);
