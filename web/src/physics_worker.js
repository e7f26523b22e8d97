// The physics thread of the page: sim/ in WebAssembly, stepped at real time (dt of scene.json)
// in a worker so that rendering keeps the headset's frame rate. It posts the organs' positions
// (organ-set frame, metres) after each batch of steps; the page sends grab / move / release.
import createSoftAtlasSim from './softatlas_sim.mjs';
import { Physics } from './physics.js';

let physics = null;
let t0 = 0;          // wall clock (ms) of simulated time 0
let simStart = 0;    // simulated time (s) at t0
let behind = 0;      // wall time dropped because the physics could not keep up (s)
let stepsDone = 0;
let lastPost = 0;
const MAX_STEPS_PER_TICK = 8;  // then grab / move messages are handled (8 x 1/90 s of physics)

// Positions of the organs that moved since the last post (null for the others; all when forced).
let lastSteps = -1;
function post(force) {
  const now = performance.now();
  if (!force && (now - lastPost < 8 || stepsDone === lastSteps)) return;
  lastPost = now;
  lastSteps = stepsDone;
  const positions = physics.organNames.map((_, i) => {
    if (!force && !physics.awake(i)) return null;
    const out = new Float32Array(3 * physics.vertexCounts[i]);
    physics.positions(i, out);
    return out;
  });
  const wall = (now - t0) / 1000;
  self.postMessage({
    type: 'state',
    positions,
    reaction: physics.reaction(),
    maxDisplacement: physics.organNames.map((_, i) => physics.maxDisplacement(i)),
    simTime: physics.time(),
    wallTime: wall + behind,
    behind,
    steps: stepsDone,
  }, positions.filter((p) => p).map((p) => p.buffer));
}

function tick() {
  if (!physics) return;
  const now = performance.now();
  const due = Math.floor(((now - t0) / 1000 + simStart - physics.time()) / physics.dt);
  const n = Math.min(Math.max(due, 0), MAX_STEPS_PER_TICK);
  if (n > 0) {
    physics.step(n);
    stepsDone += n;
  }
  if (due > 4 * MAX_STEPS_PER_TICK) {
    // Far behind (a slow machine, a paused tab): let real time go on without the physics.
    const lag = (due - n) * physics.dt;
    simStart -= lag;
    behind += lag;
  }
  post(false);
  setTimeout(tick, 1);
}

self.onmessage = async (e) => {
  const msg = e.data;
  try {
    if (msg.type === 'init') {
      const module = await createSoftAtlasSim();
      physics = new Physics(module, msg.scene);
      self.postMessage({ type: 'ready', organNames: physics.organNames, vertexCounts: physics.vertexCounts, dt: physics.dt });
      t0 = performance.now();
      simStart = physics.time();
      post(true);
      tick();
    } else if (msg.type === 'grab') {
      const i = physics.organIndex(msg.organ);
      const count = i >= 0 ? physics.grab(i, msg.point, msg.radius) : 0;
      self.postMessage({ type: 'grabbed', id: msg.id, organ: msg.organ, count });
    } else if (msg.type === 'move') {
      physics.move(msg.offset);
    } else if (msg.type === 'release') {
      physics.release();
    }
  } catch (err) {
    self.postMessage({ type: 'error', message: String(err && err.message ? err.message : err) });
  }
};
