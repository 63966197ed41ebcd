// main.js: the page `lopcook view CONTAINER.lop` serves (index.html). It streams /asset/scene.lop
// (through the glTF of its materials, /asset/scene.gltf) and draws the model as it refines, with:
//
// * a HUD: bytes received, the per-buffer level of every stored buffer, the LODs drawn, the
//   triangles of the last frame, and when the first image and each level arrived;
// * a bandwidth throttle: the server paces the container at ?rate=B bytes per second; changing it,
//   or "replay", aborts the current load and streams the container again from its first byte;
// * level colours: every vertex coloured by its minimum level (paper Fig. 7, viewer.js);
// * orbit controls (three's OrbitControls).
//
// The page's URL takes ?rate=B (the throttle at start) and ?levels=1 (level colours on).
// window.lopViewer is the page's state for scripts and tests: state(), snapshot() (render now and
// return the state with the canvas as a PNG data URL), replay(), setRate(B), setLevelColours(on).

import * as THREE from 'three';
import {OrbitControls} from 'three/addons/controls/OrbitControls.js';
import {FOV_DEG, boundingSphere, createRenderer, createScene, describe, levelCss, levelMaterial, levelRange, loadModel,
  meteredFetch, placeCamera} from './viewer.js';

const $ = (id) => document.getElementById(id);
const canvas = $('view');
const renderer = createRenderer(canvas, canvas.clientWidth, canvas.clientHeight);
const scene = createScene(renderer);
const camera = new THREE.PerspectiveCamera(FOV_DEG, canvas.clientWidth / canvas.clientHeight, 0.01, 100);
const controls = new OrbitControls(camera, canvas);
const params = new URLSearchParams(location.search);

const view = {
  rate: Math.max(0, parseInt(params.get('rate') || '0', 10) || 0),
  levelColours: params.get('levels') === '1',
  info: null, load: null, framed: false, dirty: true, frames: 0,
};

/** One streaming of the container: its abort controller, bytes so far, events, and the model once renderable. */
function newLoad() {
  return {abort: new AbortController(), bytes: 0, total: view.info ? view.info.bytes : 0, t0: performance.now(),
    firstImage: null, levels: [], complete: false, error: null, root: null, object: null, saved: new Map()};
}

function start() {
  if (view.load) stop(view.load);
  const load = view.load = newLoad();
  const open = (url) => meteredFetch(`${url}?rate=${view.rate}`, {signal: load.abort.signal, cache: 'no-store'},
    (n) => { load.bytes = n; });
  loadModel('/asset/scene.gltf', {open}).then(({root, object}) => {
    if (view.load !== load) { object.dispose(); return; }
    load.root = root;
    load.object = object;
    load.firstImage = {bytes: object.bytes, ms: performance.now() - load.t0, level: object.level};
    load.levels.push([object.level, object.bytes]);
    object.addEventListener('refine', (e) => { load.levels.push([e.level, e.bytes]); view.dirty = true; });
    object.complete.then(() => { load.complete = true; view.dirty = true; },
      (e) => { if (view.load === load && !load.abort.signal.aborted) load.error = String(e.message || e); });
    scene.add(root);
    if (!view.framed) frame(root);
    applyLevelColours(load);
    view.dirty = true;
  }, (e) => { if (view.load === load && !load.abort.signal.aborted) load.error = String(e.message || e); });
}

function stop(load) {
  load.abort.abort();
  if (load.root) scene.remove(load.root);
  if (load.object) load.object.dispose();
}

function frame(root) {
  const {centre, radius} = boundingSphere(root);
  placeCamera(camera, centre, radius, 0.8);
  camera.far = 200 * radius;
  camera.updateProjectionMatrix();
  controls.target.set(...centre);
  controls.update();
  view.framed = true;
}

/** Swap every mesh of the current model between its own material and a level-colour one. */
function applyLevelColours(load) {
  if (!load.root) return;
  const c = load.object.container;
  const [lo, hi] = levelRange(c);
  load.root.traverse((m) => {
    if (!m.isMesh || !m.userData.lop) return;
    let s = load.saved.get(m);
    if (!s) load.saved.set(m, s = {own: m.material, levels: null});
    if (!view.levelColours) { m.material = s.own; return; }
    if (!s.levels) {
      const normals = c.manifest.parts[m.userData.lop.part].attribute_bits.normals != null;
      load.object.setMaterial(m, levelMaterial(lo, hi, {side: s.own.side, normals}));
      s.levels = m.material;
    }
    m.material = s.levels;
  });
  $('legend').style.display = view.levelColours ? 'flex' : 'none';
  $('lo').textContent = String(lo);
  $('hi').textContent = String(hi);
  const stops = Array.from({length: 9}, (_, k) => levelCss(lo + (k / 8) * (hi - lo), lo, hi));
  document.querySelector('#legend .ramp').style.background = `linear-gradient(to right, ${stops.join(', ')})`;
  view.dirty = true;
}

const kb = (n) => (n >= 1 << 20 ? `${(n / (1 << 20)).toFixed(2)} MB` : `${(n / 1024).toFixed(1)} KB`);

/** The state the HUD shows (and window.lopViewer.state() returns). */
function state() {
  const load = view.load;
  const out = {rate: view.rate, levelColours: view.levelColours, bytes: load ? load.bytes : 0,
    fileSize: view.info ? view.info.bytes : 0, renderable: !!(load && load.object), complete: !!(load && load.complete),
    firstImage: load && load.firstImage, levels: load ? load.levels.slice() : [], error: load && load.error,
    frames: view.frames};
  if (load && load.object) Object.assign(out, describe(load.object, load.root, renderer), {bytes: load.bytes});
  return out;
}

function hud() {
  const s = state();
  const pct = s.fileSize ? (100 * s.bytes) / s.fileSize : 0;
  $('bar').firstElementChild.style.width = `${pct.toFixed(1)}%`;
  const lines = [`received ${kb(s.bytes)} of ${kb(s.fileSize)} (${pct.toFixed(1)} %)` +
    `${s.rate ? ` at ${kb(s.rate)}/s` : ''}${s.complete ? ', complete' : ''}`];
  if (s.renderable) {
    lines.push(`first image after ${kb(s.firstImage.bytes)} (${((100 * s.firstImage.bytes) / s.fileSize).toFixed(1)} %), ` +
      `${(s.firstImage.ms / 1000).toFixed(2)} s`);
    lines.push(`level ${s.level}; triangles drawn ${s.triangles.toLocaleString('en')}`);
    lines.push(`LODs drawn: ${Object.entries(s.lodCounts).map(([k, n]) => `LOD ${k} x ${n}`).join(', ') || 'none'}`);
    const shown = s.buffers.slice(0, 12).map((b) => `  ${b.name.slice(0, 24)} LOD ${b.lod}: level ${b.level}`);
    if (s.buffers.length > 12) shown.push(`  ... ${s.buffers.length - 12} more buffers`);
    lines.push(`buffers (${s.buffers.length}):`, ...shown);
  } else if (!s.error) {
    lines.push('waiting for the first renderable state...');
  }
  $('stats').textContent = `\n${lines.join('\n')}`;
  const notes = view.info && view.info.warnings.length ? `\nnote: ${view.info.warnings.join('; ')}` : '';
  $('error').textContent = s.error ? `\nerror: ${s.error}` : notes;
}

function render() {
  const w = canvas.clientWidth, h = canvas.clientHeight;
  if (canvas.width !== w || canvas.height !== h) {
    renderer.setSize(w, h, false);
    camera.aspect = w / h;
    camera.updateProjectionMatrix();
  }
  renderer.render(scene, camera);
  view.frames++;
  view.dirty = false;
}

let lastHud = 0;
function loop(t) {
  if (view.dirty) render();
  if (t - lastHud > 100) { hud(); lastHud = t; }
  requestAnimationFrame(loop);
}

function setRate(rate) {
  view.rate = Math.max(0, Math.floor(rate));
  const sel = $('rate');
  if (![...sel.options].some((o) => Number(o.value) === view.rate)) sel.add(new Option(`${kb(view.rate)}/s`, String(view.rate)));
  sel.value = String(view.rate);
  start();
}

function setLevelColours(on) {
  view.levelColours = !!on;
  $('levels').checked = view.levelColours;
  if (view.load) applyLevelColours(view.load);
}

controls.addEventListener('change', () => { view.dirty = true; });
window.addEventListener('resize', () => { view.dirty = true; });
$('rate').addEventListener('change', (e) => setRate(Number(e.target.value)));
$('replay').addEventListener('click', () => start());
$('levels').addEventListener('change', (e) => setLevelColours(e.target.checked));

window.lopViewer = {
  state,
  snapshot() { render(); return {...state(), image: canvas.toDataURL('image/png')}; },
  replay: start, setRate, setLevelColours,
};

fetch('/asset/info.json').then((r) => r.json()).then((info) => {
  view.info = info;
  document.title = `${info.name} - lopcook view`;
  $('title').textContent = `${info.name}: ${info.parts} parts, ${info.materials} materials`;
  $('levels').checked = view.levelColours;
  setRate(view.rate);
  requestAnimationFrame(loop);
}, (e) => { $('error').textContent = `\nerror: ${e}`; });
