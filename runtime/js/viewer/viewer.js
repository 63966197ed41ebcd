// viewer.js: the scene of lopcook's streaming viewer, shared by its page (main.js, `lopcook view`)
// and by `lopcook bench --streaming` (bench.js), so the bench measures what the viewer draws.
//
// A model is the glTF `lopcook web` writes (the source's materials; its primitives' geometry is a
// .lop container, LOPCOOK_lop_geometry), loaded by three's GLTFLoader with three-lop.js's plugin;
// the container's bytes come from a source the caller opens (a fetch the server paces, or a
// stream the bench feeds), and the meshes refine in place as they arrive.
//
// Rendering: WebGL2, 4x MSAA, transparent background (alpha 0), three's RoomEnvironment as the
// only light (PMREM), NeutralToneMapping, sRGB output; a PerspectiveCamera of FOV_DEG vertical
// field of view placed by placeCamera (the bounding sphere spanning a fraction of the viewport height).
//
// Level colours (Meyer et al. 2011, Fig. 7): each vertex coloured by its minimum level m_v (the bin
// it lies in: lop_bin_start of the WebGL2 decoder, + 1) on the ramp of lopcook's report
// (lopcook.verify.baselines.level_colours: a Turbo polynomial over [0.1, 0.9], lowest level of the
// scene's LOD 0 blue, highest red), lit by a headlight.

import * as THREE from 'three';
import {GLTFLoader} from 'three/addons/loaders/GLTFLoader.js';
import {RoomEnvironment} from 'three/addons/environments/RoomEnvironment.js';
import {LOPLoader, LOPGLTFPlugin, LOP_GLTF_EXTENSION} from '../three-lop.js';

/** Vertical field of view of the viewer's camera, degrees. */
export const FOV_DEG = 45;
/** Direction from the model's centre to the camera (normalised by placeCamera): front, right, above. */
export const VIEW_DIRECTION = Object.freeze([0.55, 0.45, 1.0]);

/** A WebGL2 renderer on `canvas` (w x h CSS pixels at device pixel ratio 1), background alpha 0. */
export function createRenderer(canvas, width, height) {
  const r = new THREE.WebGLRenderer({canvas, antialias: true, alpha: true, premultipliedAlpha: false,
    preserveDrawingBuffer: true});
  r.setPixelRatio(1);
  r.setSize(width, height, false);
  r.setClearColor(0x000000, 0);
  r.toneMapping = THREE.NeutralToneMapping;
  return r;
}

/** A scene lit by three's RoomEnvironment (image-based light through PMREM). */
export function createScene(renderer) {
  const scene = new THREE.Scene();
  const pmrem = new THREE.PMREMGenerator(renderer);
  scene.environment = pmrem.fromScene(new RoomEnvironment(), 0.04).texture;
  pmrem.dispose();
  return scene;
}

/**
 * The distance at which a sphere of `radius` spans `fraction` of the viewport height seen with a
 * vertical field of view of `fovDeg`: its angular radius asin(r / d) has tangent
 * fraction * tan(fov / 2).
 */
export function frameDistance(radius, fraction, fovDeg = FOV_DEG) {
  const t = fraction * Math.tan(THREE.MathUtils.degToRad(fovDeg) / 2);
  return radius / Math.sin(Math.atan(t));
}

/** Put `camera` on `direction` from `centre` at frameDistance(radius, fraction), looking at the
 * centre, with near radius / 100 and far 100 radius beyond it. */
export function placeCamera(camera, centre, radius, fraction, direction = VIEW_DIRECTION) {
  const c = new THREE.Vector3(...centre);
  const d = frameDistance(radius, fraction, camera.fov);
  camera.position.copy(c).addScaledVector(new THREE.Vector3(...direction).normalize(), d);
  camera.near = radius / 100;
  camera.far = d + 100 * radius;
  camera.lookAt(c);
  camera.updateProjectionMatrix();
  camera.updateMatrixWorld();
  return camera;
}

/** The bounding sphere `{centre: [x, y, z], radius}` of an object's box (the LOD meshes' boxes
 * hold every finer decode, three-lop.js). */
export function boundingSphere(object) {
  const box = new THREE.Box3().setFromObject(object);
  const c = box.getCenter(new THREE.Vector3());
  return {centre: [c.x, c.y, c.z], radius: Math.max(box.getSize(new THREE.Vector3()).length() / 2, 1e-9)};
}

/** LOPGLTFPlugin reading the container from `open(url)` (a Response, a promise of one or a
 * ReadableStream) instead of its own fetch; `onProgress` gets three-lop's progress events. */
class StreamingPlugin extends LOPGLTFPlugin {
  constructor(parser, loader, open, onProgress) {
    super(parser, loader);
    this._open = open;
    this._onProgress = onProgress;
  }

  lopObject() {
    const ext = (this.parser.json.extensions || {})[LOP_GLTF_EXTENSION];
    if (this._object === null && ext && typeof ext.uri === 'string' && this._open) {
      const url = THREE.LoaderUtils.resolveURL(decodeURIComponent(ext.uri), this.parser.options.path);
      this._object = this.loader.loadFrom(this._open(url), {path: url, onProgress: this._onProgress});
    }
    return super.lopObject();
  }
}

/**
 * Load the model of the glTF at `gltfUrl`: resolves at the container's first renderable state with
 * `{root, object}` (root: the glTF scene to add; object: three-lop's LOPObject, which refines in
 * place, dispatches 'refine' and has a `complete` promise). `open(url)` gives the container's bytes
 * (default: fetch).
 */
export async function loadModel(gltfUrl, {open = null, onProgress = null} = {}) {
  const lopLoader = new LOPLoader().setMaterial((c, part) => defaultMaterial(c.manifest.parts[part].attribute_bits.colors != null));
  const loader = new GLTFLoader();
  loader.register((parser) => new StreamingPlugin(parser, lopLoader, open, onProgress));
  const gltf = await loader.loadAsync(gltfUrl);
  return {root: gltf.scene, object: gltf.userData.lop};
}

/** The material of a primitive the glTF gives none (three-lop's default, for the container and the
 * float reference alike): grey, dielectric, roughness 0.6; `vertexColors` when the mesh has colours. */
export function defaultMaterial(vertexColors = false) {
  return new THREE.MeshStandardMaterial({color: 0xcccccc, roughness: 0.6, metalness: 0, vertexColors});
}

/** A plain glTF (the bench's float reference) loaded as the viewer draws a model: primitives without
 * a material get defaultMaterial, as the container's do. Resolves with the glTF scene. */
export async function loadReference(url) {
  const gltf = await new GLTFLoader().loadAsync(url);
  gltf.scene.traverse((m) => {
    const own = m.isMesh && gltf.parser.associations.get(m.material);
    if (m.isMesh && !(own && own.materials !== undefined)) m.material = defaultMaterial(!!m.geometry.attributes.color);
  });
  return gltf.scene;
}

/** `fetch(url, init)` whose body reports every chunk: `onBytes(total so far)`. */
export async function meteredFetch(url, init, onBytes) {
  const res = await fetch(url, init);
  if (!res.ok || !res.body) return res;
  let n = 0;
  const counter = new TransformStream({transform(chunk, ctrl) { n += chunk.byteLength; onBytes(n); ctrl.enqueue(chunk); }});
  return new Response(res.body.pipeThrough(counter), {status: res.status, statusText: res.statusText, headers: res.headers});
}

/** The lowest and highest minimum level of the vertices of LOD 0 of every stored buffer: the ends
 * of the level-colour ramp (as lopcook report's level image). */
export function levelRange(container) {
  let lo = 24, hi = 1;
  container.manifest.parts.forEach((p, i) => {
    if (container.owner(i) !== i) return;
    const vid = p.lods[0].vertex_id;
    for (let k = 1; k <= 24; k++) {
      if (vid[k] > vid[k - 1]) { lo = Math.min(lo, k); hi = Math.max(hi, k); }
    }
  });
  return hi >= lo ? [lo, hi] : [1, 24];
}

/** CSS colour of `level` on the level ramp [lo, hi] (the shader's lop_turbo, for the legend). */
export function levelCss(level, lo, hi) {
  const t = 0.1 + 0.8 * Math.min(Math.max((level - lo) / Math.max(hi - lo, 1), 0), 1);
  const poly = (c) => c.reduceRight((acc, k) => acc * t + k, 0);
  const ch = (c) => Math.round(255 * Math.min(Math.max(poly(c), 0), 1));
  return `rgb(${ch(TURBO[0])}, ${ch(TURBO[1])}, ${ch(TURBO[2])})`;
}

// Mikhailov's polynomial fit of Turbo, r, g, b coefficients of t^0..t^5 (lopcook.verify.baselines).
const TURBO = [[0.13572138, 4.61539260, -42.66032258, 132.13108234, -152.94239396, 59.28637943],
  [0.09140261, 2.19418839, 4.84296658, -14.18503333, 4.27729857, 2.82956604],
  [0.10667330, 12.64194608, -60.58204836, 110.36276771, -89.90310912, 27.34824973]];
// c0 + t * (c1 + t * (... + t * c5)) as GLSL
const glslPoly = (c) => c.slice(0, -1).reduceRight((acc, k) => `${k.toFixed(8)} + t * (${acc})`, c[c.length - 1].toFixed(8));

const LEVEL_VS = `
uniform vec2 lop_level_range;
varying vec3 v_colour;
varying vec3 v_view;
varying vec3 v_normal;
vec3 lop_turbo(float level) {
  float t = 0.1 + 0.8 * clamp((level - lop_level_range.x) / max(lop_level_range.y - lop_level_range.x, 1.0), 0.0, 1.0);
  return clamp(vec3(${glslPoly(TURBO[0])}, ${glslPoly(TURBO[1])}, ${glslPoly(TURBO[2])}), 0.0, 1.0);
}
void main() {
#include <beginnormal_vertex>
#include <defaultnormal_vertex>
#include <begin_vertex>
#include <project_vertex>
  v_view = -mvPosition.xyz;
  v_normal = transformedNormal;
  v_colour = lop_turbo(float(lop_bin_start(uint(gl_VertexID)) + 1u));
}`;

const LEVEL_FS = `
varying vec3 v_colour;
varying vec3 v_view;
varying vec3 v_normal;
void main() {
#ifdef LOP_LEVEL_NORMALS
  vec3 n = normalize(v_normal);
#else
  vec3 n = normalize(cross(dFdx(v_view), dFdy(v_view)));
#endif
  float headlight = abs(dot(n, normalize(v_view)));
  gl_FragColor = vec4(v_colour * (0.35 + 0.65 * headlight), 1.0);  // the ramp's display values, as the report shows them
}`;

/** A material drawing a three-lop mesh in level colours over [lo, hi] (give it to
 * LOPObject.setMaterial, which adds the decoder); `normals`: the part has normals (else the
 * faces' own, from screen-space derivatives). */
export function levelMaterial(lo, hi, {side = THREE.FrontSide, normals = true} = {}) {
  return new THREE.ShaderMaterial({
    vertexShader: LEVEL_VS, fragmentShader: LEVEL_FS, side, defines: normals ? {LOP_LEVEL_NORMALS: ''} : {},
    uniforms: {lop_level_range: {value: new THREE.Vector2(lo, hi)}},
  });
}

/**
 * What the HUD shows, now: `{bytes, fileSize, level, complete, buffers: [{part, name, lod, level}],
 * drawn: [{part, lod}], lodCounts: {lod: meshes drawn}, triangles}` (triangles: the last render's,
 * from renderer.info).
 */
export function describe(object, root, renderer) {
  const c = object.container;
  const buffers = [];
  c.manifest.parts.forEach((p, i) => {
    if (c.owner(i) !== i) return;
    p.lods.forEach((_, k) => buffers.push({part: i, name: p.name, lod: k, level: object.buffer(i, k).level}));
  });
  const drawn = [];
  const lodCounts = {};
  root.traverseVisible((m) => {
    if (m.isMesh && m.userData.lop) {
      drawn.push(m.userData.lop);
      lodCounts[m.userData.lop.lod] = (lodCounts[m.userData.lop.lod] || 0) + 1;
    }
  });
  return {bytes: object.bytes, fileSize: object.fileSize, level: object.level, complete: c.complete, buffers, drawn,
    lodCounts, triangles: renderer.info.render.triangles};
}
