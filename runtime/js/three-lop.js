// three-lop.js: a three.js loader for lopcook's .lop containers (ES module; three is a peer import
// resolved by the page's import map, as for three's own addons).
//
// This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
// section 6.2 (positions decoded in the vertex shader from a packed buffer) and section 8 of
// docs/format.md (a prefix of the file decodes).
//
// Meshes decode positions, normals, UVs, colours and tangents in the vertex shader
// (runtime/js/glsl/, bit-exact with lopcook's CPU reference) from integer textures by gl_VertexID,
// and refine in place as bytes arrive: the loader calls onLoad at the first renderable state and
// raises the level of every buffer each time a plane arrives (event 'refine' on the returned object).
//
//   import {LOPLoader, LOPGLTFPlugin} from './three-lop.js';
//   // a container alone: untextured meshes (MeshStandardMaterial)
//   new LOPLoader().load('bunny.lop', (object) => scene.add(object));
//   // with the source's materials: the glTF `lopcook web x.lop -o x.gltf` writes, through GLTFLoader
//   const gltfLoader = new GLTFLoader();
//   gltfLoader.register((parser) => new LOPGLTFPlugin(parser, new LOPLoader()));
//   gltfLoader.load('x.gltf', (gltf) => scene.add(gltf.scene));
//
// docs/runtime-js.md is the guide and reference.

import * as THREE from 'three';
import * as lop from './lop.js';
import {DECODE_BITPLANES, DECODE_ATTRIBUTES} from './lop-glsl.js';

/** The glTF extension naming a .lop container's part as a primitive's geometry (lopcook.emit.web). */
export const LOP_GLTF_EXTENSION = 'LOPCOOK_lop_geometry';

function dataTexture(words, channels) {
  const {width, height, data} = lop.textureLayout(words, channels);
  const t = new THREE.DataTexture(data, width, height, channels === 4 ? THREE.RGBAIntegerFormat : THREE.RedIntegerFormat,
    THREE.UnsignedIntType);
  t.internalFormat = channels === 4 ? 'RGBA32UI' : 'R32UI';
  t.minFilter = t.magFilter = THREE.NearestFilter;
  t.generateMipmaps = false;
  t.flipY = false;
  t.unpackAlignment = 4;
  t.needsUpdate = true;
  return t;
}

/**
 * The GPU state of one stored buffer (a part's LOD; placements share their owner's): its packed
 * buffer P (and cluster records) as integer textures with the uniforms of decode_bitplanes at the
 * current level, and its attribute record with the uniforms of decode_attributes. Every mesh
 * drawing the buffer holds these uniform objects, so `setLevel` refines all of them at once.
 */
class LOPBuffer {
  constructor(container, owner, lod) {
    this.container = container;
    this.owner = owner;
    this.lod = lod;
    this.level = 0;
    this.clustered = container.clusters(owner, lod) !== null;
    const e = container.lodEntry(owner, lod);
    this.entry = e;
    const idx = container.indices(owner, lod);
    this.index = new THREE.BufferAttribute(idx, 1);
    this.uniforms = {
      lop_positions: {value: null}, lop_clusters: {value: null},
      lop_vertex_id: {value: new Uint32Array(32)}, lop_bit_id: {value: new Uint32Array(32)},
      lop_cluster_id: {value: new Uint32Array(32)}, lop_origin_half: {value: new Float32Array(4)},
      lop_params: {value: new Uint32Array(4)},
    };
    const a = lop.attributeInputs(container, owner, lod);
    this.attributes = a === null ? null : {normals: a.bits[0] > 0, uvs: a.bits[1] > 0, colors: a.bits[2] > 0, tangents: a.params[1] > 0};
    if (a !== null) {
      Object.assign(this.uniforms, {
        lop_attributes: {value: dataTexture(a.words, 1)}, lop_attr_bits: {value: a.bits},
        lop_attr_scale: {value: a.scale}, lop_attr_uv: {value: a.uv}, lop_attr_params: {value: a.params},
      });
    }
  }

  /** Decode at per-buffer level `level` from now on (the container must hold it). */
  setLevel(level) {
    if (level === this.level) return;
    const inp = lop.decodeInputs(this.container, this.owner, this.lod, level);
    const u = this.uniforms;
    const old = [u.lop_positions.value, u.lop_clusters.value];
    u.lop_positions.value = dataTexture(inp.words, 1);
    u.lop_clusters.value = inp.clustered ? dataTexture(inp.records, 4) : null;
    u.lop_vertex_id.value.set(inp.vertexId);
    u.lop_bit_id.value.set(inp.bitId);
    u.lop_cluster_id.value.set(inp.clusterId);
    u.lop_origin_half.value.set(inp.originHalf);
    u.lop_params.value.set(inp.params);
    for (const t of old) if (t) t.dispose();
    this.level = level;
  }

  dispose() {
    for (const key of ['lop_positions', 'lop_clusters', 'lop_attributes']) {
      if (this.uniforms[key] && this.uniforms[key].value) this.uniforms[key].value.dispose();
    }
  }
}

/** The vertex-shader code three-lop adds before a material's own (after three's prefix). */
function decoderSource(buffer) {
  const a = buffer.attributes || {};
  const defs = ['#define LOP_NO_VIEW'];
  if (buffer.clustered) defs.push('#define LOP_CLUSTERED');
  for (const [key, name] of [['normals', 'NORMALS'], ['uvs', 'UVS'], ['colors', 'COLORS'], ['tangents', 'TANGENTS']]) {
    if (a[key]) defs.push(`#define LOP_HAS_${name}`);
  }
  return `${defs.join('\n')}
${DECODE_BITPLANES}
${buffer.attributes ? DECODE_ATTRIBUTES : ''}
uniform uint lop_placed;
uniform vec4 lop_place0;
uniform vec4 lop_place1;
uniform vec4 lop_place2;
uniform mat3 lop_normal_matrix;   // A^-T of a placement
uniform mat3 lop_tangent_matrix;  // A of a placement
uniform float lop_handedness;     // sign(det A) of a placement
vec3 lop_v_position;
vec3 lop_v_normal;
vec2 lop_v_uv;
vec4 lop_v_color;
vec4 lop_v_tangent;
// Decode vertex gl_VertexID: world position (a placement's transform applied, format.md 6.8),
// normal (unnormalised; A^-T for a placement), UV, linear RGBA colour, tangent (A, w * sign(det A)).
void lop_vertex() {
  uint j = uint(gl_VertexID);
  uvec3 grid;
  uint level;
  lop_decode(j, grid, lop_v_position, level);
  if (lop_placed != 0u) lop_v_position = lop_place(lop_v_position, lop_place0, lop_place1, lop_place2);
  lop_v_normal = vec3(0.0, 0.0, 1.0);
  lop_v_uv = vec2(0.0);
  lop_v_color = vec4(1.0);
  lop_v_tangent = vec4(1.0, 0.0, 0.0, 1.0);
#ifdef LOP_HAS_NORMALS
  lop_v_normal = lop_decode_normal(j);
  if (lop_placed != 0u) lop_v_normal = lop_normal_matrix * lop_v_normal;
#endif
#ifdef LOP_HAS_UVS
  lop_v_uv = lop_decode_uv(j);
#endif
#ifdef LOP_HAS_COLORS
  lop_v_color = lop_decode_color(j);
#endif
#ifdef LOP_HAS_TANGENTS
  lop_v_tangent = lop_decode_tangent(j);
  if (lop_placed != 0u) lop_v_tangent = vec4(lop_tangent_matrix * lop_v_tangent.xyz, lop_v_tangent.w * lop_handedness);
#endif
}
`;
}

/** Each three.js chunk that reads a vertex attribute, and the attributes it reads: the decoded
 * values stand in for them inside that chunk only (#define ... #undef). */
const CHUNK_ATTRIBUTES = {
  begin_vertex: [['position', 'lop_v_position']],
  beginnormal_vertex: [['normal', 'lop_v_normal'], ['tangent', 'lop_v_tangent']],
  normal_vertex: [['tangent', 'lop_v_tangent']],
  uv_vertex: [['uv', 'lop_v_uv']],
  color_vertex: [['color', 'LOP_COLOR']],
};

/**
 * Make `material` (any three.js material whose vertex shader uses three's chunks: the built-in
 * ones, or a ShaderMaterial that #includes begin_vertex, beginnormal_vertex, uv_vertex, ...)
 * draw `buffer` decoded in its vertex shader, placed by `placement` (the part's uniforms). The
 * material is changed in place (onBeforeCompile, customProgramCacheKey) and returned.
 */
export function patchMaterial(material, buffer, placement) {
  const key = `lop:${buffer.clustered ? 'c' : 'u'}:${JSON.stringify(buffer.attributes)}`;
  const previous = material.onBeforeCompile;
  material.onBeforeCompile = (shader, renderer) => {
    if (previous) previous.call(material, shader, renderer);
    Object.assign(shader.uniforms, buffer.uniforms, placement);
    let vs = shader.vertexShader;
    for (const [chunk, names] of Object.entries(CHUNK_ATTRIBUTES)) {
      const def = names.map(([a, b]) => `#define ${a} ${b}`).join('\n');
      const undef = names.map(([a]) => `#undef ${a}`).join('\n');
      vs = vs.replace(`#include <${chunk}>`, `${def}\n#include <${chunk}>\n${undef}`);
    }
    if (!/void\s+main\s*\(\s*\)\s*\{/.test(vs)) throw new Error('three-lop: the vertex shader has no main()');
    vs = vs.replace(/void\s+main\s*\(\s*\)\s*\{/, 'void main() {\n\tlop_vertex();');
    const color = '#ifdef USE_COLOR_ALPHA\n#define LOP_COLOR lop_v_color\n#else\n#define LOP_COLOR lop_v_color.rgb\n#endif\n';
    shader.vertexShader = decoderSource(buffer) + color + vs;
  };
  const previousKey = material.customProgramCacheKey.bind(material);
  material.customProgramCacheKey = () => `${previousKey()}|${key}`;
  if (buffer.attributes && buffer.attributes.colors) material.vertexColors = true;
  if (buffer.attributes && buffer.attributes.tangents && material.normalMap) {
    material.defines = Object.assign({}, material.defines, {USE_TANGENT: ''});
  }
  if (!(buffer.attributes && buffer.attributes.normals) && 'flatShading' in material) material.flatShading = true;
  material.needsUpdate = true;
  return material;
}

/** geometry -> {buffer, placement} of the meshes LOPObject creates (not in userData, which
 * Object3D.clone copies through JSON). */
const DRAWS = new WeakMap();

/** The placement uniforms of part `part` (identity on the scene grid). */
function placementUniforms(c, part) {
  const rows = lop.placementRows(c, part);
  const tf = c.placementTransform(part);
  const nm = new THREE.Matrix3(), tm = new THREE.Matrix3();
  let hand = 1;
  if (tf !== null) {
    const [a] = lop.splitTransform(tf);
    tm.set(a[0][0], a[0][1], a[0][2], a[1][0], a[1][1], a[1][2], a[2][0], a[2][1], a[2][2]);
    nm.copy(tm).invert().transpose();
    hand = tm.determinant() < 0 ? -1 : 1;
  }
  return {lop_placed: {value: tf === null ? 0 : 1}, lop_place0: {value: rows[0]}, lop_place1: {value: rows[1]},
    lop_place2: {value: rows[2]}, lop_normal_matrix: {value: nm}, lop_tangent_matrix: {value: tm},
    lop_handedness: {value: hand}};
}

/**
 * What a LOPLoader returns: a THREE.Group with one child per part (a Mesh, or a THREE.LOD of one
 * Mesh per LOD when the part has several, switched at the LODs' `min_distance_m`), every mesh
 * decoding in its vertex shader. It refines in place: `level` is the per-buffer level drawn now,
 * `bytes` / `fileSize` what has arrived, and each rise of the level dispatches
 * `{type: 'refine', level, bytes}`; `complete` resolves when the whole file has arrived (and
 * rejects when it turns out corrupt). `container` is the lop.js container (manifest, CPU decoders).
 *
 * A file in the streaming layout (format.md 14) arrives stage by stage, coarsest LODs first: a
 * part's THREE.LOD holds the LODs that have arrived (the coarsest drawn at every distance until a
 * finer one comes), `update()` adds each finer LOD as its stage arrives and draws every buffer at
 * its own stage's level (`{type: 'refine', level, stage, bytes}` per stage that improved).
 */
export class LOPObject extends THREE.Group {
  constructor(container, {maxLevel = lop.LEVELS, material = null} = {}) {
    super();
    this.name = container.path || 'lop';
    this.container = container;
    this.maxLevel = maxLevel;
    this.level = 0;
    this.bytes = container.bytesReceived;
    this.fileSize = container.fileSize;
    this._buffers = new Map();
    this._material = material;
    this._parts = new Map(); // part -> {node, centre, material, lods: Set} of a streamed THREE.LOD
    this._stages = [];
    if (container.stream) this.level = Math.min(container.stageLevels[0], maxLevel);
    else this.refine(container.availableLevel);
    container.manifest.parts.forEach((_, i) => this.add(this.createPart(i)));
    if (container.stream) this.update();
  }

  /** The level buffer (part, lod) is drawn at: the level that has arrived (its stage's in the
   * streaming layout), capped by maxLevel. */
  levelOf(part, lod) {
    const c = this.container;
    return Math.min(c.stream ? c.levelOf(part, lod) : this.level, this.maxLevel);
  }

  /** Streaming layout: add the LODs whose stage has arrived and draw every buffer at its stage's
   * level (called as stages and planes arrive). */
  update() {
    const c = this.container;
    if (!c.stream) return this.refine(c.availableLevel);
    for (const [part, st] of this._parts) {
      c.manifest.parts[part].lods.forEach((e, k) => {
        if (st.lods.has(k) || c.levelOf(part, k) < 1) return;
        const mesh = this.createMesh(part, k, st.material ? st.material.clone() : null); // patched per mesh
        mesh.position.copy(st.centre).negate();
        st.node.addLevel(mesh, e.min_distance_m || 0);
        st.lods.add(k);
      });
    }
    for (const b of this._buffers.values()) {
      const want = this.levelOf(b.owner, b.lod);
      if (want > b.level) b.setLevel(want);
    }
    c.stageLevels.forEach((level, s) => {
      const want = Math.min(level, this.maxLevel);
      if (want > (this._stages[s] || 0)) {
        this._stages[s] = want;
        this.level = Math.max(this.level, want);
        this.dispatchEvent({type: 'refine', level: want, stage: s, bytes: this.bytes});
      }
    });
    return undefined;
  }

  /** The shared GPU state of stored buffer (owner part, lod). */
  buffer(part, lod) {
    const owner = this.container.owner(part);
    const key = `${owner}/${lod}`;
    if (!this._buffers.has(key)) {
      const b = new LOPBuffer(this.container, owner, lod);
      const level = this.levelOf(owner, lod);
      if (level) b.setLevel(level);
      this._buffers.set(key, b);
    }
    return this._buffers.get(key);
  }

  /** A Mesh drawing LOD `lod` of part `part` with `material` (default: this object's material
   * factory, else a MeshStandardMaterial); the material is patched (patchMaterial). */
  createMesh(part, lod, material = null) {
    const c = this.container;
    const b = this.buffer(part, lod);
    const g = new THREE.BufferGeometry();
    g.setIndex(b.index);
    g.boundingBox = this._bounds(part, lod);
    g.boundingSphere = g.boundingBox.getBoundingSphere(new THREE.Sphere());
    const mat = material || (this._material ? this._material(c, part, lod) : new THREE.MeshStandardMaterial({color: 0xcccccc, roughness: 0.6}));
    const placement = placementUniforms(c, part);
    patchMaterial(mat, b, placement);
    const mesh = new THREE.Mesh(g, mat);
    mesh.userData.lop = {part, lod};
    DRAWS.set(g, {buffer: b, placement}); // on the geometry: a clone of the mesh shares it
    mesh.name = `${c.manifest.parts[part].name} LOD ${lod}`;
    for (const [prop, Kind] of [['customDepthMaterial', THREE.MeshDepthMaterial], ['customDistanceMaterial', THREE.MeshDistanceMaterial]]) {
      const m = new Kind(Kind === THREE.MeshDepthMaterial ? {depthPacking: THREE.RGBADepthPacking} : {});
      mesh[prop] = patchMaterial(m, b, placement);
    }
    return mesh;
  }

  /** Give `mesh` (one of this object's, or a clone of one) the material `material`, patched to
   * decode its buffer. */
  setMaterial(mesh, material) {
    const draw = DRAWS.get(mesh.geometry);
    if (!draw) throw new Error('three-lop: setMaterial needs a mesh a LOPObject created');
    mesh.material = patchMaterial(material, draw.buffer, draw.placement);
    return mesh;
  }

  /** Part `part` as an Object3D: its LOD 0 Mesh, or a THREE.LOD of all its LODs (in the streaming
   * layout, of those that have arrived; `update` adds the others). */
  createPart(part, material = null) {
    const lods = this.container.manifest.parts[part].lods;
    if (lods.length === 1) return this.createMesh(part, 0, material);
    const node = new THREE.LOD();
    node.name = this.container.manifest.parts[part].name;
    if (this.container.stream) {
      const coarsest = lods.length - 1; // stage 0: there whenever the object exists
      const centre = this._bounds(part, coarsest).getCenter(new THREE.Vector3());
      node.position.copy(centre);
      this._parts.set(part, {node, centre, material: material ? material.clone() : null, lods: new Set()}); // unpatched
      this.update();
      return node;
    }
    const centre = this._bounds(part, 0).getCenter(new THREE.Vector3());
    node.position.copy(centre); // distances are measured from the part's centre
    const materials = lods.map((_, k) => (material && k ? material.clone() : material)); // before patching
    lods.forEach((e, k) => {
      const mesh = this.createMesh(part, k, materials[k]);
      mesh.position.copy(centre).negate();
      node.addLevel(mesh, e.min_distance_m || 0);
    });
    return node;
  }

  /** The box holding every decode of the part at any level >= the current one: the current
   * decode grown by the block radius dx(level) (times the placement's largest scale). */
  _bounds(part, lod) {
    const c = this.container;
    const level = Math.max(1, this.levelOf(part, lod));
    const {positions} = c.decodePositions(part, lod, level);
    const box = new THREE.Box3();
    const v = new THREE.Vector3();
    for (let j = 0; j < positions.length; j += 3) box.expandByPoint(v.set(positions[j], positions[j + 1], positions[j + 2]));
    const {extent} = c.partGrid(part);
    const tf = c.placementTransform(part);
    const grow = Math.sqrt(3) * extent * 2 ** -(level + 1) * (tf === null ? 1 : lop.sigma(tf)) * (1 + 1e-6) + 1e-30;
    return box.expandByScalar(grow);
  }

  /** Draw every buffer at min(level, maxLevel) (called as planes arrive). */
  refine(level) {
    const want = Math.min(level, this.maxLevel);
    if (want <= this.level) return;
    this.level = want;
    for (const b of this._buffers.values()) b.setLevel(want);
    this.dispatchEvent({type: 'refine', level: want, bytes: this.bytes});
  }

  /** Release the textures of every buffer (the meshes' geometries and materials are the caller's). */
  dispose() {
    for (const b of this._buffers.values()) b.dispose();
    this._buffers.clear();
  }
}

/**
 * A three.js loader of .lop containers, used as GLTFLoader and DRACOLoader are:
 * `load(url, onLoad, onProgress, onError)` streams the file and calls onLoad with a LOPObject at
 * the first renderable state (it then refines in place); `loadAsync(url)` resolves then;
 * `parse(buffer, onLoad, onError)` reads a whole file. `setMaxLevel(B)` caps the per-buffer level
 * drawn (fewer bytes decoded, not fewer fetched), `setMaterial(fn)` gives each mesh its material
 * (`fn(container, part, lod)`), `setRangeLevel(B)` fetches only the bytes level B needs with HTTP
 * range requests (lop.LopRangeReader; `object.fetchLevel(B2)` fetches more later).
 */
export class LOPLoader extends THREE.Loader {
  constructor(manager) {
    super(manager);
    this.maxLevel = lop.LEVELS;
    this.rangeLevel = null;
    this.materialFactory = null;
  }

  setMaxLevel(level) { this.maxLevel = level; return this; }
  setMaterial(fn) { this.materialFactory = fn; return this; }
  setRangeLevel(level) { this.rangeLevel = level; return this; }

  load(url, onLoad, onProgress, onError) {
    const full = this.manager.resolveURL(this.path + url);
    this.manager.itemStart(full);
    const fail = (e) => {
      if (onError) onError(e); else console.error(e);
      this.manager.itemError(full);
      this.manager.itemEnd(full);
    };
    const init = {headers: this.requestHeader, credentials: this.withCredentials ? 'include' : 'same-origin'};
    const source = this.rangeLevel === null ? fetch(full, init) : null;
    this.loadFrom(source || full, {path: full, onProgress}).then((object) => {
      object.complete.then(() => this.manager.itemEnd(full), (e) => { console.error(e); this.manager.itemError(full); this.manager.itemEnd(full); });
      onLoad(object);
    }, fail);
  }

  /**
   * Read a container from `source`: a Response (or a promise of one), a ReadableStream, a URL
   * read with range requests (with setRangeLevel), or bytes. Resolves with a LOPObject at the first
   * renderable state; `object.complete` resolves when every byte has arrived.
   */
  async loadFrom(source, {path = null, onProgress = null} = {}) {
    let object = null;
    let resolveFirst, rejectFirst;
    const first = new Promise((res, rej) => { resolveFirst = res; rejectFirst = rej; });
    const onUpdate = (state) => {
      if (onProgress) onProgress({type: 'progress', lengthComputable: true, loaded: state.bytes, total: state.fileSize});
      if (state.event === 'renderable') {
        object = new LOPObject(state.container, {maxLevel: this.maxLevel, material: this.materialFactory});
        resolveFirst(object);
      } else if (object !== null && ['plane', 'lod', 'complete'].includes(state.event)) {
        object.bytes = state.bytes;
        if (state.container.stream) object.update();
        else object.refine(state.level);
      }
    };
    let done;
    if (typeof source === 'string' && this.rangeLevel !== null) {
      const reader = new lop.LopRangeReader(source, {onUpdate});
      done = reader.fetchLevel(this.rangeLevel).then(() => reader.container);
      first.then((o) => { o.fetchLevel = (b) => reader.fetchLevel(b); });
    } else {
      done = Promise.resolve(source).then((s) => {
        if (s && typeof s.ok === 'boolean' && !s.ok) throw new lop.LopError('container', path, `HTTP ${s.status} ${s.statusText}`, 'check the URL');
        return lop.load(s, {onUpdate, path});
      });
    }
    done.then(() => { if (object === null) rejectFirst(new lop.LopError('container', path, 'the stream ended before a renderable state')); }, rejectFirst);
    const o = await first;
    o.complete = done.then(() => o);
    o.complete.catch(() => {});
    return o;
  }

  parse(buffer, onLoad, onError) {
    try {
      const c = lop.parse(buffer instanceof Uint8Array ? buffer : new Uint8Array(buffer));
      const o = new LOPObject(c, {maxLevel: this.maxLevel, material: this.materialFactory});
      o.complete = Promise.resolve(o);
      if (onLoad) onLoad(o);
      return o;
    } catch (e) {
      if (onError) onError(e); else throw e;
      return null;
    }
  }
}

/**
 * The GLTFLoader plugin of LOPCOOK_lop_geometry (the glTF `lopcook web` writes): a primitive whose
 * extension names part i of the container the document's extension points at is drawn by
 * three-lop, with the material GLTFLoader built for it (textures, factors, alpha mode, sides).
 *
 *   gltfLoader.register((parser) => new LOPGLTFPlugin(parser, lopLoader));
 *
 * The container is fetched once per document, streamed, and shared by every mesh; `load` of the
 * glTF completes at its first renderable state; `gltf.userData.lop` is the LOPObject (its
 * `complete` promise, 'refine' events, level and bytes).
 */
export class LOPGLTFPlugin {
  constructor(parser, loader = null) {
    this.name = LOP_GLTF_EXTENSION;
    this.parser = parser;
    this.loader = loader || new LOPLoader(parser.options.manager);
    this._object = null;
  }

  /** The LOPObject of the document's container (fetched and streamed once). */
  lopObject() {
    if (this._object === null) {
      const ext = (this.parser.json.extensions || {})[LOP_GLTF_EXTENSION];
      if (!ext || typeof ext.uri !== 'string') {
        this._object = Promise.reject(new Error(`three-lop: the glTF has no ${LOP_GLTF_EXTENSION} extension with a uri`));
      } else {
        const url = THREE.LoaderUtils.resolveURL(decodeURIComponent(ext.uri), this.parser.options.path);
        this._object = this.loader.loadFrom(this.loader.rangeLevel === null ? fetch(url) : url, {path: url});
      }
    }
    return this._object;
  }

  loadMesh(meshIndex) {
    const def = this.parser.json.meshes[meshIndex];
    const prims = def.primitives;
    if (!prims.every((p) => p.extensions && p.extensions[LOP_GLTF_EXTENSION])) return null;
    const mats = prims.map((p) => (p.material === undefined ? Promise.resolve(null) : this.parser.getDependency('material', p.material)));
    return Promise.all([this.lopObject(), ...mats]).then(([object, ...materials]) => {
      const nodes = prims.map((p, k) => {
        const part = p.extensions[LOP_GLTF_EXTENSION].part;
        const parts = object.container.manifest.parts;
        if (!(Number.isInteger(part) && part >= 0 && part < parts.length)) throw new Error(`three-lop: mesh ${meshIndex} names part ${part}, the container has ${parts.length}`);
        return object.createPart(part, materials[k] ? this._material(materials[k], object, part) : null);
      });
      const out = nodes.length === 1 ? nodes[0] : new THREE.Group().add(...nodes);
      if (def.name) out.name = def.name;
      return out;
    });
  }

  /** GLTFLoader's material, made ready for decoded geometry as its assignFinalMaterial does for a
   * primitive: a copy (the material may be shared), with the normal map's y flipped when the
   * tangent frame comes from screen-space derivatives (no tangents in the container). */
  _material(material, object, part) {
    const m = material.clone();
    const ab = object.container.manifest.parts[part].attribute_bits;
    if (m.normalScale && ab.tangents == null) m.normalScale.y = -m.normalScale.y;
    return m;
  }

  afterRoot(gltf) {
    if (this._object === null) return null;
    return this._object.then((o) => { gltf.userData.lop = o; });
  }
}
