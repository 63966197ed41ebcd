// three.js renders for tests/runtime/test_three_loader.py. For each job, the web glTF (`lopcook web`)
// is loaded with GLTFLoader + LOPGLTFPlugin (LOPLoader capped at the job's level), and two images
// are posted (RGBA, rows bottom first, as gl.readPixels gives them):
//   /image/<name>/harness  every mesh drawn by a ShaderMaterial with the render harness's Phong
//                          shading (lopcook/verify/glsl.py FS, its mvp, eye, light and parameters),
//                          base colour from the glTF material's map (texel values as they are) or the
//                          harness's grey, sides as the glTF material says; positions, normals and
//                          UVs decoded by three-lop in the vertex shader
//   /image/<name>/pbr      the glTF materials as GLTFLoader built them (RoomEnvironment light)
// and a streaming job reads a container in 20 timed chunks: the image after the first onLoad and
// after the last refine, against a whole-file parse.
import * as THREE from 'three';
import {GLTFLoader} from 'three/addons/loaders/GLTFLoader.js';
import {RoomEnvironment} from 'three/addons/environments/RoomEnvironment.js';
import {LOPLoader, LOPGLTFPlugin} from '/runtime/js/three-lop.js';

const VS = `
uniform mat4 u_mvp;
varying vec3 v_pos;
varying vec3 v_normal;
varying vec2 v_uv;
void main() {
#include <beginnormal_vertex>
#include <begin_vertex>
  v_pos = transformed;
  v_normal = normalize(objectNormal);
  v_uv = lop_v_uv;
  gl_Position = u_mvp * vec4(transformed, 1.0);
}`;
const FS = `
varying vec3 v_pos;
varying vec3 v_normal;
varying vec2 v_uv;
uniform vec3 u_eye;
uniform vec3 u_light;
uniform vec4 u_phong;
uniform vec3 u_base;
uniform int u_has_texture;
uniform sampler2D u_texture;
void main() {
  vec3 V = normalize(u_eye - v_pos);
  vec3 N;
  float len = length(v_normal);
  if (len > 1e-12) {
    N = v_normal / len;
  } else {
    N = normalize(cross(dFdx(v_pos), dFdy(v_pos)));
    N = dot(N, V) < 0.0 ? -N : N;
  }
  vec3 base = u_has_texture != 0 ? texture2D(u_texture, v_uv).rgb : u_base;
  float nl = dot(N, u_light);
  vec3 R = reflect(-u_light, N);
  float spec = nl > 0.0 ? u_phong.z * pow(max(dot(R, V), 0.0), u_phong.w) : 0.0;
  vec3 c = base * (u_phong.x + u_phong.y * max(nl, 0.0)) + vec3(spec);
  gl_FragColor = vec4(clamp(c, 0.0, 1.0), 1.0);
}`;

function harnessMaterial(source, job) {
  let map = source.map || null;
  if (map) { // texel values as they are, as the harness samples them
    map = map.clone();
    map.colorSpace = THREE.NoColorSpace;
    map.minFilter = THREE.LinearMipmapLinearFilter;
    map.magFilter = THREE.LinearFilter;
    map.wrapS = map.wrapT = THREE.RepeatWrapping;
    map.needsUpdate = true;
  }
  return new THREE.ShaderMaterial({
    vertexShader: VS, fragmentShader: FS, side: source.side,
    uniforms: {
      u_mvp: {value: new THREE.Matrix4().fromArray(job.mvp)}, u_eye: {value: new THREE.Vector3(...job.eye)},
      u_light: {value: new THREE.Vector3(...job.light)}, u_phong: {value: new THREE.Vector4(...job.phong)},
      u_base: {value: new THREE.Vector3(job.base, job.base, job.base)}, u_has_texture: {value: map ? 1 : 0},
      u_texture: {value: map},
    },
  });
}

function pixels(renderer) {
  const gl = renderer.getContext();
  const {width, height} = renderer.domElement;
  const out = new Uint8Array(width * height * 4);
  gl.readPixels(0, 0, width, height, gl.RGBA, gl.UNSIGNED_BYTE, out);
  return out;
}

async function post(path, body) {
  await fetch(path, {method: 'POST', body});
}

function renderer(size) {
  const r = new THREE.WebGLRenderer({antialias: true, alpha: true, premultipliedAlpha: false, preserveDrawingBuffer: true});
  r.setPixelRatio(1);
  r.setSize(size, size);
  r.setClearColor(0x000000, 0);
  document.body.appendChild(r.domElement);
  return r;
}

function jobCamera(job) {
  const cam = new THREE.PerspectiveCamera();
  cam.projectionMatrix.fromArray(job.projection);
  cam.projectionMatrixInverse.copy(cam.projectionMatrix).invert();
  cam.matrixAutoUpdate = false;
  cam.matrixWorldAutoUpdate = false;
  cam.matrixWorld.fromArray(job.view).invert();
  cam.matrixWorldInverse.fromArray(job.view);
  return cam;
}

async function renderJob(r, job) {
  const lopLoader = new LOPLoader().setMaxLevel(job.level);
  const loader = new GLTFLoader();
  loader.register((parser) => new LOPGLTFPlugin(parser, lopLoader));
  const gltf = await loader.loadAsync(job.gltf);
  const object = gltf.userData.lop;
  await object.complete;
  const scene = new THREE.Scene();
  scene.add(gltf.scene);
  const cam = jobCamera(job);
  // the glTF materials
  scene.environment = new THREE.PMREMGenerator(r).fromScene(new RoomEnvironment(), 0.04).texture;
  r.toneMapping = THREE.NeutralToneMapping;
  r.render(scene, cam);
  await post(`/image/${job.name}/pbr`, pixels(r));
  // the harness's shading
  r.toneMapping = THREE.NoToneMapping;
  scene.environment = null;
  let meshes = 0, textured = 0;
  gltf.scene.traverse((m) => {
    if (!m.isMesh) return;
    meshes++;
    if (m.material.map) textured++;
    gltf.userData.lop.setMaterial(m, harnessMaterial(m.material, job));
    m.frustumCulled = false;
  });
  r.render(scene, cam);
  await post(`/image/${job.name}/harness`, pixels(r));
  return {name: job.name, level: object.level, meshes, textured, bytes: object.bytes, fileSize: object.fileSize};
}

/** Stream a container in `chunks` timed pieces; images at the first onLoad and at the end, and a
 * whole-file parse's image for comparison. */
async function streamJob(r, job) {
  const bytes = new Uint8Array(await (await fetch(job.lop)).arrayBuffer());
  const n = job.chunks;
  const stream = new ReadableStream({
    async start(ctrl) {
      for (let k = 0; k < n; k++) {
        ctrl.enqueue(bytes.slice(Math.floor((k * bytes.length) / n), Math.floor(((k + 1) * bytes.length) / n)));
        await new Promise((res) => setTimeout(res, 30));
      }
      ctrl.close();
    },
  });
  const cam = jobCamera(job);
  const scene = new THREE.Scene();
  scene.add(new THREE.HemisphereLight(0xffffff, 0x444444, 2.5));
  const refines = [];
  const object = await new LOPLoader().loadFrom(new Response(stream));
  const first = {level: object.level, bytes: object.bytes};
  object.addEventListener('refine', (e) => refines.push([e.level, e.bytes, e.stage === undefined ? null : e.stage]));
  scene.add(object);
  r.render(scene, cam);
  await post(`/image/${job.name}/first`, pixels(r));
  await object.complete;
  r.render(scene, cam);
  await post(`/image/${job.name}/last`, pixels(r));
  scene.remove(object);
  const whole = new LOPLoader().parse(bytes);
  scene.add(whole);
  r.render(scene, cam);
  await post(`/image/${job.name}/whole`, pixels(r));
  return {name: job.name, first, refines, level: object.level, wholeLevel: whole.level, fileSize: bytes.length,
    stageLevels: object.container.stageLevels};
}

const messages = []; // console errors and warnings (three reports shader compile errors there)
for (const level of ['error', 'warn']) {
  const original = console[level].bind(console);
  console[level] = (...args) => { messages.push(`${level}: ${args.map(String).join(' ')}`.slice(0, 2000)); original(...args); };
}

async function main() {
  const jobs = await (await fetch('/jobs.json')).json();
  const r = renderer(jobs.size);
  const out = {renders: [], streams: []};
  for (const job of jobs.renders) out.renders.push(await renderJob(r, job));
  for (const job of jobs.streams) out.streams.push(await streamJob(r, job));
  out.console = messages;
  return out;
}

main().then((res) => post('/result', JSON.stringify(res)),
  (e) => post('/result', JSON.stringify({error: String(e && e.stack || e)})));
