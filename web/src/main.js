// SoftAtlas in the browser: the atlas (atlas.glb) drawn with three.js, deformed by sim/ running in
// WebAssembly in a worker (physics_worker.js), on the desktop (orbit, zoom, hover names, grab and
// pull with the mouse) and in a headset (immersive-vr: controllers grab with the trigger and
// vibrate with the reaction force). docs/web.md.
import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';
import { AtlasFrame } from './frame.js';

const params = new URLSearchParams(location.search);
const TEST = params.get('test') === '1';
const GRAB_RADIUS_M = 0.010;   // the grasped patch (organ metres), as the native viewer's 10 mm
const VR_GRAB_REACH_M = 0.05;  // a controller grabs the nearest organ surface within this (world)
const HAPTIC_FULL_N = 0.5;     // reaction force that vibrates at full intensity
const HAPTIC_PULSE_MS = 40;
// The page's physics step. The organ set's dt (scene.json, 1 ms for data/atlas) is 18x the stable
// explicit step, so sim::step() solves it with implicit Euler (25 CG iterations) whatever dt is;
// one solve per headset frame (1/90 s) instead of per millisecond is what keeps the physics at
// real time in WebAssembly (docs/web.md, docs/performance.md). ?dt=SECONDS overrides it.
const PAGE_DT_S = Number(params.get('dt')) > 0 ? Number(params.get('dt')) : 1 / 90;

const $ = (id) => document.getElementById(id);
const status = (text) => { $('status').textContent = text; };

// ---- renderer, scene, camera ----------------------------------------------------------------
const renderer = new THREE.WebGLRenderer({ antialias: !TEST, powerPreference: 'high-performance' });
renderer.setPixelRatio(TEST ? 1 : Math.min(window.devicePixelRatio, 2));
renderer.setSize(window.innerWidth, window.innerHeight);
renderer.xr.enabled = true;
renderer.xr.setReferenceSpaceType('local-floor');
document.body.appendChild(renderer.domElement);

const scene = new THREE.Scene();
scene.background = new THREE.Color(0x1d2430);
scene.add(new THREE.HemisphereLight(0xffffff, 0x404050, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 1.8);
sun.position.set(0.5, 2.5, 1.5);
scene.add(sun);
const floor = new THREE.Mesh(new THREE.CircleGeometry(2.5, 48), new THREE.MeshLambertMaterial({ color: 0x2b3442 }));
floor.rotation.x = -Math.PI / 2;
floor.material.depthWrite = false;
floor.renderOrder = -1;
scene.add(floor);

const camera = new THREE.PerspectiveCamera(45, window.innerWidth / window.innerHeight, 0.01, 20);
const controls = new OrbitControls(camera, renderer.domElement);
controls.enableDamping = false;
window.addEventListener('resize', () => {
  camera.aspect = window.innerWidth / window.innerHeight;
  camera.updateProjectionMatrix();
  renderer.setSize(window.innerWidth, window.innerHeight);
});

// ---- state ----------------------------------------------------------------------------------
const organs = [];          // {name, mesh, label, index (physics), positions (Float32Array), visible}
let frame = null;          // AtlasFrame: organ-set frame (RAS, m) <-> world
let worker = null;
let latest = null;         // last 'state' message of the worker that was drawn
let pending = null;        // newest 'state' message, drawn at the next frame
let grab = null;           // {organ, anchorWorld, source: 'mouse'|controller}
let hapticPulses = 0;
let xrViewCount = 0;
let ready = false;
const frameTimes = [];

function fps() {
  const now = performance.now();
  while (frameTimes.length && now - frameTimes[0] > 1000) frameTimes.shift();
  if (frameTimes.length < 2) return 0;
  return (frameTimes.length - 1) / ((frameTimes[frameTimes.length - 1] - frameTimes[0]) / 1000);
}

function reactionN() {
  if (!latest || !grab) return 0;
  const r = latest.reaction;
  return Math.hypot(r[0], r[1], r[2]);
}

// ---- loading --------------------------------------------------------------------------------
async function load() {
  status('loading atlas.glb, scene.json and the physics core ...');
  const [gltf, sceneJson, lessons] = await Promise.all([
    new GLTFLoader().loadAsync('atlas.glb'),
    fetch('scene.json').then((r) => { if (!r.ok) throw new Error(`scene.json: HTTP ${r.status}`); return r.json(); }),
    fetch('lessons.json').then((r) => (r.ok ? r.json() : [])).catch(() => []),
  ]);
  worker = new Worker(new URL('./worker.js', import.meta.url), { type: 'module' });
  const readyMsg = await new Promise((resolve, reject) => {
    worker.onmessage = (e) => {
      if (e.data.type === 'ready') resolve(e.data);
      else if (e.data.type === 'error') reject(new Error(e.data.message));
    };
    worker.onerror = (e) => reject(new Error(`physics worker: ${e.message}`));
    const physicsScene = { ...sceneJson, settings: { ...sceneJson.settings, dt_s: PAGE_DT_S } };
    worker.postMessage({ type: 'init', scene: physicsScene });
  });
  // The room frame from the vertices that faces use.
  frame = new AtlasFrame(sceneJson.organs.flatMap((o) => [...new Set(o.faces)].flatMap((v) => o.vertices.slice(3 * v, 3 * v + 3))));
  const group = new THREE.Group();
  group.matrixAutoUpdate = false;
  group.matrix.copy(frame.matrix());
  scene.add(group);

  const meshes = new Map();
  gltf.scene.traverse((n) => { if (n.isMesh) meshes.set(n.name || n.parent.name, n); });
  for (const o of sceneJson.organs) {
    const index = readyMsg.organNames.indexOf(o.name);
    let src = meshes.get(o.name);
    if (!src) for (const [k, m] of meshes) if (k.startsWith(o.name)) src = m;
    if (!src) throw new Error(`atlas.glb: no mesh named '${o.name}'`);
    const geometry = new THREE.BufferGeometry();
    const nv = o.vertices.length / 3;
    if (src.geometry.attributes.position.count !== nv)
      throw new Error(`atlas.glb: mesh '${o.name}' has ${src.geometry.attributes.position.count} vertices, scene.json ${nv}`);
    const positions = Float32Array.from(o.vertices);
    geometry.setAttribute('position', new THREE.BufferAttribute(positions, 3).setUsage(THREE.DynamicDrawUsage));
    geometry.setIndex(src.geometry.index ? src.geometry.index.clone() : null);
    geometry.computeVertexNormals();
    const material = new THREE.MeshLambertMaterial({ color: new THREE.Color(...o.color) });
    const mesh = new THREE.Mesh(geometry, material);
    mesh.name = o.name;
    mesh.frustumCulled = false;
    group.add(mesh);
    const label = makeLabel(o.name.replace(/_/g, ' '));
    scene.add(label);
    const used = Int32Array.from(new Set(o.faces));
    organs.push({ name: o.name, mesh, label, index, positions, used, visible: true, simulated: index >= 0 });
  }
  group.updateMatrixWorld(true);
  for (const o of organs) placeLabel(o);
  buildOrganList();
  buildLessons(lessons);

  worker.onmessage = (e) => {
    const m = e.data;
    if (m.type === 'state') pending = m;
    else if (m.type === 'grabbed' && grab && grab.id === m.id && m.count === 0) grab = null;
    else if (m.type === 'error') status(`physics: ${m.message}`);
  };
  // Desktop view: in front of the patient (anterior), the atlas filling the view.
  controls.target.copy(frame.centreWorld);
  camera.position.copy(frame.centreWorld).add(new THREE.Vector3(0, 0.05, 0.75));
  controls.update();
  ready = true;
  status(`${organs.length} organs · physics: sim/ in WebAssembly, dt ${(readyMsg.dt * 1000).toFixed(2)} ms`);
  const vr = $('vr');
  const noVR = () => { vr.disabled = true; vr.textContent = 'VR not available'; };
  if (navigator.xr) {
    navigator.xr.isSessionSupported('immersive-vr').then((ok) => { if (ok) vr.disabled = false; else noVR(); }).catch(noVR);
  } else noVR();
}

function applyState(m) {
  latest = m;
  for (const o of organs) {
    if (o.index < 0 || !m.positions[o.index]) continue;  // null: the organ did not move
    const attr = o.mesh.geometry.attributes.position;
    attr.array.set(m.positions[o.index]);
    attr.needsUpdate = true;
    o.positions = attr.array;
    o.mesh.geometry.computeVertexNormals();
    o.mesh.geometry.computeBoundingSphere();
  }
}

// ---- labels (sprites face the viewer, in each eye in VR) ------------------------------------
function makeLabel(text) {
  const canvas = document.createElement('canvas');
  const ctx = canvas.getContext('2d');
  ctx.font = 'bold 44px sans-serif';
  const w = Math.ceil(ctx.measureText(text).width) + 32;
  canvas.width = w;
  canvas.height = 64;
  ctx.font = 'bold 44px sans-serif';
  ctx.fillStyle = 'rgba(20, 24, 32, 0.75)';
  ctx.fillRect(0, 0, w, 64);
  ctx.fillStyle = '#ffffff';
  ctx.textBaseline = 'middle';
  ctx.fillText(text, 16, 34);
  const tex = new THREE.CanvasTexture(canvas);
  tex.colorSpace = THREE.SRGBColorSpace;
  const sprite = new THREE.Sprite(new THREE.SpriteMaterial({ map: tex, depthTest: false, transparent: true }));
  sprite.scale.set(0.03 * w / 64, 0.03, 1);
  sprite.renderOrder = 10;
  return sprite;
}

function organCentreWorld(o) {
  return frame.toWorld(frame.centroid(o.positions, o.used));
}

// A label floats in front of its organ (towards the viewer) and a little above its centre.
function placeLabel(o) {
  const front = frame.anteriorPoint(o.positions, o.used);
  const c = organCentreWorld(o);
  o.label.position.set(c.x, c.y + 0.02, front.z + 0.015);
}

// ---- organ list: show / hide / isolate ------------------------------------------------------
function setVisible(o, v) {
  o.visible = v;
  o.mesh.visible = v;
  o.label.visible = v && $('labels').checked;
  const box = document.querySelector(`input[data-organ="${o.name}"]`);
  if (box) box.checked = v;
}

function buildOrganList() {
  const list = $('organs');
  for (const o of organs) {
    const row = document.createElement('div');
    row.className = 'organ';
    const box = document.createElement('input');
    box.type = 'checkbox';
    box.checked = true;
    box.dataset.organ = o.name;
    box.title = 'show / hide';
    box.onchange = () => setVisible(o, box.checked);
    const name = document.createElement('span');
    name.textContent = o.name.replace(/_/g, ' ') + (o.simulated ? '' : ' (static)');
    const iso = document.createElement('button');
    iso.textContent = 'isolate';
    iso.dataset.isolate = o.name;
    iso.onclick = () => { for (const q of organs) setVisible(q, q === o); };
    row.append(box, name, iso);
    list.appendChild(row);
  }
  $('showall').onclick = () => { for (const q of organs) setVisible(q, true); };
  $('labels').onchange = () => { for (const q of organs) q.label.visible = q.visible && $('labels').checked; };
}

const esc = (t) => String(t).replace(/[&<>]/g, (c) => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;' }[c]));
function buildLessons(lessons) {
  const box = $('lessons');
  if (!lessons.length) { box.style.display = 'none'; return; }
  for (const l of lessons) {
    const d = document.createElement('details');
    const s = document.createElement('summary');
    s.textContent = l.lesson || l.file;
    d.appendChild(s);
    for (const step of l.steps || []) {
      const text = step.say || step.hint || '';
      if (!step.title && !text) continue;
      const p = document.createElement('p');
      p.innerHTML = (step.title ? `<b>${esc(step.title)}</b>${text ? ': ' : ''}` : '') + esc(text);
      d.appendChild(p);
    }
    box.appendChild(d);
  }
}

// ---- picking and grabbing -------------------------------------------------------------------
const raycaster = new THREE.Raycaster();
const pointer = new THREE.Vector2();
let grabId = 0;

function pickRay() {
  const targets = organs.filter((o) => o.visible).map((o) => o.mesh);
  const hit = raycaster.intersectObjects(targets, false)[0];
  return hit ? { organ: organs.find((o) => o.mesh === hit.object), point: hit.point } : null;
}

function startGrab(organ, pointWorld, source) {
  if (!organ.simulated) return false;
  const id = ++grabId;
  grab = { id, organ, anchorWorld: pointWorld.clone(), source };
  worker.postMessage({ type: 'grab', id, organ: organ.name, point: frame.toSet(pointWorld), radius: GRAB_RADIUS_M });
  return true;
}

function moveGrab(pointWorld) {
  if (!grab) return;
  worker.postMessage({ type: 'move', offset: frame.dirToSet(pointWorld.clone().sub(grab.anchorWorld)) });
}

function endGrab() {
  if (!grab) return;
  grab = null;
  worker.postMessage({ type: 'release' });
  controls.enabled = true;
}

// Desktop: hover shows the name; left-drag on an organ pulls it in the plane facing the camera;
// left-drag elsewhere orbits, the wheel zooms, right-drag pans.
const dragPlane = new THREE.Plane();
function setPointer(e) {
  const r = renderer.domElement.getBoundingClientRect();
  pointer.set(((e.clientX - r.left) / r.width) * 2 - 1, -((e.clientY - r.top) / r.height) * 2 + 1);
  raycaster.setFromCamera(pointer, camera);
}
renderer.domElement.addEventListener('pointerdown', (e) => {
  if (!ready || e.button !== 0 || renderer.xr.isPresenting) return;
  setPointer(e);
  const hit = pickRay();
  if (!hit || !startGrab(hit.organ, hit.point, 'mouse')) return;
  controls.enabled = false;
  dragPlane.setFromNormalAndCoplanarPoint(camera.getWorldDirection(new THREE.Vector3()).negate(), hit.point);
  renderer.domElement.setPointerCapture(e.pointerId);
}, { capture: true });
renderer.domElement.addEventListener('pointermove', (e) => {
  if (!ready) return;
  setPointer(e);
  if (grab && grab.source === 'mouse') {
    const p = new THREE.Vector3();
    if (raycaster.ray.intersectPlane(dragPlane, p)) moveGrab(p);
    return;
  }
  const hit = pickRay();
  const tip = $('tip');
  if (hit) {
    tip.textContent = hit.organ.name.replace(/_/g, ' ');
    tip.style.left = `${e.clientX + 14}px`;
    tip.style.top = `${e.clientY + 10}px`;
    tip.style.display = 'block';
  } else tip.style.display = 'none';
});
renderer.domElement.addEventListener('pointerup', () => { if (grab && grab.source === 'mouse') endGrab(); });

// ---- immersive VR ---------------------------------------------------------------------------
const controllerList = [0, 1].map((i) => renderer.xr.getController(i));
for (const c of controllerList) {
  const ray = new THREE.Line(new THREE.BufferGeometry().setFromPoints([new THREE.Vector3(), new THREE.Vector3(0, 0, -0.3)]),
    new THREE.LineBasicMaterial({ color: 0x9fd3ff }));
  const tip = new THREE.Mesh(new THREE.SphereGeometry(0.008, 12, 8), new THREE.MeshBasicMaterial({ color: 0xffe08a }));
  c.add(ray, tip);
  c.addEventListener('connected', (e) => { c.userData.inputSource = e.data; });
  c.addEventListener('disconnected', () => { c.userData.inputSource = null; });
  c.addEventListener('selectstart', () => vrGrab(c));
  c.addEventListener('selectend', () => { if (grab && grab.source === c) endGrab(); });
  scene.add(c);
}

// The organ surface nearest to the controller (within reach), else the first organ along its ray.
function vrGrab(c) {
  if (!ready || grab) return;
  const p = c.getWorldPosition(new THREE.Vector3());
  let best = null;
  for (const o of organs) {
    if (!o.visible || !o.simulated) continue;
    const d = frame.nearestWorldDistance(o.positions, o.used, p);
    if (d < VR_GRAB_REACH_M && (!best || d < best.d)) best = { o, d };
  }
  if (best) { startGrab(best.o, p, c); return; }
  const dir = new THREE.Vector3(0, 0, -1).applyQuaternion(c.getWorldQuaternion(new THREE.Quaternion()));
  raycaster.set(p, dir);
  const hit = pickRay();
  if (hit && startGrab(hit.organ, hit.point, c)) grab.rayOffset = hit.point.clone().sub(p);
}

async function enterVR() {
  if (renderer.xr.isPresenting) return true;
  const session = await navigator.xr.requestSession('immersive-vr', { optionalFeatures: ['local-floor'] });
  await renderer.xr.setSession(session);
  session.addEventListener('end', () => { xrViewCount = 0; endGrab(); });
  return true;
}
$('vr').onclick = () => enterVR().catch((e) => status(`VR: ${e.message}`));

function updateVR(xrFrame) {
  const pose = xrFrame.getViewerPose(renderer.xr.getReferenceSpace());
  xrViewCount = pose ? pose.views.length : 0;
  if (!grab || grab.source === 'mouse') return;
  const c = grab.source;
  const p = c.getWorldPosition(new THREE.Vector3());
  if (grab.rayOffset) p.add(grab.rayOffset);
  moveGrab(p);
  // The vibration follows the reaction force of the last physics batch.
  const f = reactionN();
  const gp = c.userData.inputSource && c.userData.inputSource.gamepad;
  const actuator = gp && gp.hapticActuators && gp.hapticActuators[0];
  if (actuator && f > 0) {
    actuator.pulse(Math.min(1, f / HAPTIC_FULL_N), HAPTIC_PULSE_MS);
    hapticPulses++;
  }
}

// ---- frame loop -----------------------------------------------------------------------------
renderer.setAnimationLoop((time, xrFrame) => {
  frameTimes.push(performance.now());
  if (frameTimes.length > 1000) frameTimes.shift();
  const t0 = performance.now();
  if (pending) { applyState(pending); pending = null; }
  if (xrFrame) updateVR(xrFrame);
  if (ready) {
    if ($('labels').checked) for (const o of organs) if (o.visible) placeLabel(o);
    $('force').textContent = grab ? `${grab.organ.name.replace(/_/g, ' ')}: reaction ${reactionN().toFixed(3)} N` : 'reaction: -';
    if (latest) $('rt').textContent = `physics ${(latest.simTime / Math.max(1e-9, latest.wallTime)).toFixed(2)}x real time · ${fps().toFixed(0)} fps`;
  }
  const t1 = performance.now();
  renderer.render(scene, camera);
  const t2 = performance.now();
  frameCost.update += t1 - t0, frameCost.render += t2 - t1, frameCost.frames++;
});
const frameCost = { update: 0, render: 0, frames: 0 };  // main-thread ms, for softatlasView.stats()

// ---- test hook (?test=1) --------------------------------------------------------------------
function organ(name) {
  const o = organs.find((q) => q.name === name);
  if (!o) throw new Error(`no organ '${name}' (have: ${organs.map((q) => q.name).join(', ')})`);
  return o;
}
const toArray = (v) => [v.x, v.y, v.z];
if (TEST) {
  window.softatlasTest = {
    ready: false,
    enterVR,
    xrViews: () => xrViewCount,
    organCentre: (name) => toArray(organCentreWorld(organ(name))),
    organSurfacePoint: (name) => toArray(frame.anteriorPoint(organ(name).positions, organ(name).used)),
    maxDisplacementMm: (name) => {
      const o = organ(name);
      return latest && o.index >= 0 ? 1000 * latest.maxDisplacement[o.index] : 0;
    },
    reactionN,
    hapticPulses: () => hapticPulses,
    fps,
  };
  // For the desktop test only (not part of the hook): where a world point appears on screen.
  window.softatlasView = {
    toScreen: (p) => {
      const v = new THREE.Vector3(...p).project(camera);
      const r = renderer.domElement.getBoundingClientRect();
      return [r.left + (v.x + 1) / 2 * r.width, r.top + (1 - v.y) / 2 * r.height];
    },
    controllers: () => controllerList.map((c) => toArray(c.getWorldPosition(new THREE.Vector3()))),
    stats: () => latest && { simTime: latest.simTime, wallTime: latest.wallTime, behind: latest.behind, steps: latest.steps,
      updateMs: frameCost.update / Math.max(1, frameCost.frames), renderMs: frameCost.render / Math.max(1, frameCost.frames) },
  };
}

load().then(() => { if (TEST) window.softatlasTest.ready = true; })
  .catch((e) => { status(`error: ${e.message}`); console.error(e); });
