// bench.js: the page of `lopcook bench --streaming` (lopcook/bench/streaming.py serves it with the
// viewer's files). For each asset of /bench/jobs.json it draws, with the viewer's scene (viewer.js:
// renderer, RoomEnvironment light, tone mapping, camera placement), from each camera:
//
//   1. the float reference: the source's geometry as float32 glTF with the same materials
//      (reference.glb), posted as /image/<asset>/<camera>/reference;
//   2. the container as it streams in: its bytes are fed to the viewer's loader up to each cut of
//      the job (every section end: the only places the renderable state can change), and after
//      every cut that changed the state (a lop.js event) the model is drawn and posted as
//      /image/<asset>/<camera>/<bytes>.
//
// Images are the canvas's RGBA bytes, rows bottom first (gl.readPixels). The page then posts
// /result: per asset, every drawn cut {bytes, level, events}. A failure posts {error}.

import * as THREE from 'three';
import {FOV_DEG, createRenderer, createScene, loadModel, loadReference, placeCamera} from './viewer.js';

async function post(path, body) {
  const res = await fetch(path, {method: 'POST', body});
  if (!res.ok) throw new Error(`POST ${path}: HTTP ${res.status}`);
}

function pixels(renderer) {
  const gl = renderer.getContext();
  const out = new Uint8Array(gl.drawingBufferWidth * gl.drawingBufferHeight * 4);
  gl.readPixels(0, 0, gl.drawingBufferWidth, gl.drawingBufferHeight, gl.RGBA, gl.UNSIGNED_BYTE, out);
  return out;
}

/** Draw `root` from every camera of the job and post each image under `tag`. */
async function drawAll(renderer, scene, root, job, tag) {
  const camera = new THREE.PerspectiveCamera(FOV_DEG, job.size[0] / job.size[1]);
  scene.add(root);
  for (const cam of job.cameras) {
    placeCamera(camera, job.centre, job.radius, cam.fraction);
    renderer.render(scene, camera);
    await post(`/image/${job.name}/${cam.name}/${tag}`, pixels(renderer));
  }
  scene.remove(root);
}

/**
 * A ReadableStream the caller fills chunk by chunk: `feed(chunk)` resolves once the reader has taken
 * `chunk` and asks for the next (so whatever it does with a chunk, synchronously, is done);
 * `feed(null)` closes the stream. highWaterMark 0: nothing is read ahead.
 */
function feeder(failed) {
  let wanted = null;
  let asked = new Promise((res) => { wanted = res; });
  let give = null;
  const stream = new ReadableStream({
    pull(ctrl) {
      return new Promise((done) => {
        give = (chunk) => { if (chunk) ctrl.enqueue(chunk); else ctrl.close(); done(); };
        wanted();
      });
    },
  }, {highWaterMark: 0});
  async function feed(chunk) {
    await Promise.race([asked, failed]);
    asked = new Promise((res) => { wanted = res; });
    give(chunk);
    if (chunk) await Promise.race([asked, failed]);
  }
  return {stream, feed};
}

/** Feed the container to the viewer's loader cut by cut; draw after each cut that changed its state. */
async function streamJob(renderer, scene, job) {
  const bytes = new Uint8Array(await (await fetch(job.lop)).arrayBuffer());
  if (bytes.length !== job.cuts[job.cuts.length - 1]) throw new Error(`${job.lop}: ${bytes.length} bytes, the job says ${job.cuts.at(-1)}`);
  let fail = null;
  const failed = new Promise((_, rej) => { fail = rej; });
  failed.catch(() => {});
  const f = feeder(failed);
  let events = 0;
  let model = null;
  const loading = loadModel(job.gltf, {open: () => f.stream, onProgress: () => { events++; }})
    .then((m) => { model = m; m.object.complete.catch(fail); }, fail);
  const drawn = [];
  let fed = 0, seen = 0;
  for (const cut of job.cuts) {
    await f.feed(bytes.slice(fed, cut));
    fed = cut;
    if (cut === bytes.length) await f.feed(null);
    // lop.js reports 'manifest' and then 'renderable': from the second event on there is a model
    if (events >= 2 && model === null) await Promise.race([loading, failed]);
    if (model === null || (events === seen && cut !== bytes.length)) continue;
    if (cut === bytes.length) await Promise.race([model.object.complete, failed]);
    seen = events;
    await drawAll(renderer, scene, model.root, job, String(cut));
    drawn.push({bytes: cut, level: model.object.level, events});
  }
  model.object.dispose();
  return drawn;
}

async function main() {
  const jobs = await (await fetch('/bench/jobs.json')).json();
  const canvas = document.createElement('canvas');
  canvas.style.width = `${jobs.size[0]}px`;
  canvas.style.height = `${jobs.size[1]}px`;
  document.body.appendChild(canvas);
  const renderer = createRenderer(canvas, jobs.size[0], jobs.size[1]);
  const out = {assets: []};
  for (const job of jobs.assets) {
    job.size = jobs.size;
    const scene = createScene(renderer);
    await drawAll(renderer, scene, await loadReference(job.reference), job, 'reference');
    const drawn = await streamJob(renderer, scene, job);
    out.assets.push({name: job.name, drawn});
    scene.environment.dispose();
  }
  return out;
}

main().then((res) => post('/result', JSON.stringify(res)),
  (e) => post('/result', JSON.stringify({error: String((e && e.stack) || e)})));
