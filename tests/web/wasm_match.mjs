// N steps of sim/ in WebAssembly (the exported page's softatlas_sim.wasm, fed the exported
// scene.json) against the same steps natively (web_native_steps_nofma: sim/ without FMA
// contraction, as WebAssembly computes): positions and the tool reaction must agree within 1e-9
// relative (the contract), displacements within 1e-8 of the largest one. The solid model's
// 4 local/global iterations end unconverged at the 1e-11 m level, where wasm's and x86's vector
// summation orders differ (about 2.8e-11 m after the first steps, then constant): 3.7e-11 of the
// positions, 1.9e-9 of a 15 mm displacement (at dt 8 ms, the solid atlas's own step). The
// difference to the project's -march=native build (FMA) is reported.
// Run by ctest (tests/web/CMakeLists.txt):
//   node --no-experimental-fetch tests/web/wasm_match.mjs SITE NATIVE_NOFMA NATIVE [ORGAN PULL FREE]
import { execFileSync } from 'node:child_process';
import { readFileSync } from 'node:fs';
import { createRequire } from 'node:module';
import path from 'node:path';
import { pathToFileURL } from 'node:url';

const [site, nativeBin, nativeFma, organ = 'liver', pull = '300', free = '200'] = process.argv.slice(2);
if (!site || !nativeBin || !nativeFma) {
  console.error('usage: wasm_match.mjs SITE NATIVE_NOFMA NATIVE [ORGAN PULL FREE]');
  process.exit(2);
}
// Emscripten 3.1.6's ES6 glue calls require() and __dirname when it runs under node.
globalThis.require = createRequire(import.meta.url);
globalThis.__dirname = path.resolve(site);

const sceneFile = path.join(site, 'scene.json');
const runNative = (bin) => JSON.parse(execFileSync(bin, [sceneFile, organ, pull, free], { maxBuffer: 1 << 28 }).toString());
const native = runNative(nativeBin);
const nativeFmaOut = runNative(nativeFma);

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
const c0 = process.cpuUsage();
const grabbed = physics.grab(i, point, 0.010);
physics.move([0, 0.020, 0]);
physics.step(Number(pull));
const reaction = physics.reaction();
physics.release();
physics.step(Number(free));
const cpu = process.cpuUsage(c0);
const tWasm = (cpu.user + cpu.system) / 1000;

let fails = 0;
const check = (what, ok, detail) => {
  console.log(`${ok ? 'ok  ' : 'FAIL'} ${what}: ${detail}`);
  if (!ok) fails++;
};
check('same grasp point', point.every((v, k) => v === native.point[k]), `${point.map((v) => (v * 1000).toFixed(3))} mm`);
check('same grasped vertices', grabbed === native.grabbed, `${grabbed} (native ${native.grabbed})`);
// Largest |a - b| over all coordinates, relative to the largest coordinate and to the largest
// displacement from the rest shape (b: the reference).
function compare(a, b) {
  let worst = 0, maxDisp = 0, scale = 0;
  for (const [name, ref] of Object.entries(b.organs)) {
    const w = a[name];
    const rest = sceneJson.organs.find((q) => q.name === name).vertices;
    if (w.length !== ref.length) throw new Error(`${name}: ${w.length} vs ${ref.length} coordinates`);
    for (let k = 0; k < w.length; ++k) {
      scale = Math.max(scale, Math.abs(ref[k]));
      worst = Math.max(worst, Math.abs(w[k] - ref[k]));
      maxDisp = Math.max(maxDisp, Math.abs(ref[k] - rest[k]));
    }
  }
  return { worst, maxDisp, relPos: worst / scale, relDisp: worst / Math.max(maxDisp, 1e-300) };
}
const wasm = Object.fromEntries(physics.organNames.map((n, k) => [n, physics.positions(k)]));
const { worst: worstPos, maxDisp, relPos, relDisp } = compare(wasm, native);
const fma = compare(wasm, nativeFmaOut);
check('moved', maxDisp > 0.005, `largest displacement ${(maxDisp * 1000).toFixed(2)} mm after ${pull} + ${free} steps`);
check('positions within 1e-9 relative', relPos <= 1e-9, `max |wasm - native| = ${worstPos.toExponential(3)} m, / max |x| = ${relPos.toExponential(3)}`);
check('displacements within 1e-8 relative', relDisp <= 1e-8, `max |wasm - native| / max displacement = ${relDisp.toExponential(3)}`);
const relF = Math.hypot(...reaction.map((v, k) => v - native.reaction[k])) / Math.max(1e-300, Math.hypot(...native.reaction));
check('tool reaction within 1e-9 relative', relF <= 1e-9, `|F| = ${Math.hypot(...reaction).toFixed(6)} N, rel diff ${relF.toExponential(3)}`);
const steps = Number(pull) + Number(free);
console.log(`info wasm against the -march=native build (FMA): max diff ${fma.worst.toExponential(3)} m, ${fma.relDisp.toExponential(3)} of the largest displacement`);
console.log(JSON.stringify({ steps, wasm_cpu_us_per_step: +((1000 * tWasm) / steps).toFixed(1), max_abs_diff_m: worstPos, rel_diff: relPos,
  rel_disp_diff: relDisp, fma_build_rel_disp_diff: fma.relDisp }));
process.exit(fails ? 1 : 0);
