// lop.js: a reader of lopcook's .lop containers for the browser and Node (ES module, no dependency).
//
// This work is based on: Meyer, Sussner, Greiner, Stamminger, "Adaptive Level-of-Precision for
// GPU-Rendering", VMV 2011, sections 4-6 (binned adaptive precision buffers, VertexId / BitId,
// bit planes); Purnomo, Bilodeau, Cohen, Kumar, "Hardware-Compatible Vertex Compression Using
// Quantization and Simplification", Graphics Hardware 2005 (the packed attribute record); Cigolle
// et al., "A Survey of Efficient Representations for Independent Unit Vectors", JCGT 3(2), 2014
// (octahedral normals and tangents).
//
// The specification is docs/format.md; this module mirrors the Python reference reader
// (lopcook/emit/container.py, manifest.py, reader.py, bitplane.py, clusters.py, placement.py,
// attributes.py): the same checks (format.md section 12), the same verdict on every file, and
// bit-identical decodes (every float32 operation is one Math.fround of a double result, which is
// the correctly rounded float32 result for +, - and *).
//
//   import * as lop from './lop.js';
//   const c = lop.parse(new Uint8Array(await (await fetch('x.lop')).arrayBuffer()));
//   const {positions} = c.decodePositions(0, 0, c.availableLevel);   // Float32Array, metres
//   const idx = c.indices(0, 0);                                     // Uint16Array | Uint32Array
//   const {normals, uvs} = c.attributes(0, 0);                       // Float32Array or null
//
//   // streaming: every callback is a better renderable state (first renderable, each new plane)
//   const c2 = await lop.load('x.lop', {onUpdate: (state) => draw(state.container)});
//
// Every failure throws LopError, whose message is one line naming the file, what is wrong and
// what to do. Safe on untrusted input: every read is bounds-checked against the bytes received;
// a hostile file is refused with LopError, never read outside its bytes.
//
// Both layouts of format.md are read: the default one and the streaming layout of version 4.0
// (section 14: stages, coarsest LODs first, each buffer decoding at its stage's level), and
// encoded sections (section 15), decoded by ./lop-codecs.js as soon as they are complete.

import {DEFLATE_MAX_RATIO, decodeTriangles, inflateRaw} from './lop-codecs.js';

/** The manifest's format string. */
export const FORMAT = 'lopcook.lop';
/** Container majors this reader knows (2.x, 3.x: clusters and placements, 4.x: tangents, the
 * streaming layout, encoded sections). */
export const READABLE_MAJORS = Object.freeze([2, 3, 4]);
/** The first major that may hold the streaming layout and encoded sections (format.md 14, 15). */
export const STREAM_MAJOR = 4;
/** The encodings a section may have (format.md 15). */
export const ENCODINGS = Object.freeze(['deflate', 'meshopt-deflate']);
/** Bits of the position grid and the highest level. */
export const LEVELS = 24;
/** Bytes of the header. */
export const HEADER_SIZE = 32;
/** Bits per component allowed for each attribute (docs/format.md 7.2; tangents: 7.x). */
export const ATTRIBUTE_BITS = Object.freeze({normals: [4, 16], uvs: [6, 16], colors: [4, 8], tangents: [4, 16]});
/** The smallest grid extent lopcook cooks with (metres): 2^-75. */
export const MIN_EXTENT = 2 ** -75;
/** |origin| + extent of any grid: 2^102 metres. */
export const MAX_GRID_REACH = 2 ** 102;
/** The largest finite float32. */
export const F32_MAX = 3.4028234663852886e38;
/** Cluster sizes N allowed (docs/format.md 6.9). */
export const CLUSTER_SIZE_RANGE = Object.freeze([16, 1024]);
/** Nesting depth beyond which a manifest is refused (a JSON parser's recursion limit). */
export const MAX_JSON_DEPTH = 900;
/** Fields of a placement's LOD entry that are its own (every other field equals its owner's). */
const SHARED_OWN_FIELDS = ['geometric_error_m', 'min_distance_m'];
/** The first major that may hold tangents. */
const TANGENT_MAJOR = 4;
/** A stream's buffer is sized from the manifest up to this many bytes, grown as bytes arrive beyond. */
const MAX_PREALLOCATION = 2 ** 28;
const CORRUPT = 'the file is corrupt or not a lopcook container; cook it again';
const INCOMPLETE = 'the copy is incomplete; cook it again';
const f32 = Math.fround;

// ============================================================================================
// errors

/**
 * The one error this module throws: `stage` ("container" for a bad file, "usage" for a bad
 * request), `path` (the file, or null), `detail` (what is wrong), `hint` (what to do). `message`
 * is the one-line text lopcook prints: "container: x.lop: file is truncated: ... (hint)".
 */
export class LopError extends Error {
  constructor(stage, path, detail, hint = null) {
    const where = path ? `${path}: ` : '';
    super(`${stage}: ${where}${detail}${hint ? ` (${hint})` : ''}`.replace(/\s*[\x00-\x08\x0a-\x1f\x7f]+\s*/g, ' '));
    this.name = 'LopError';
    this.stage = stage;
    this.path = path;
    this.detail = detail;
    this.hint = hint;
  }
}

// ============================================================================================
// CRC-32 (ISO-HDLC: reflected 0xEDB88320, init and final XOR 0xFFFFFFFF; zlib.crc32)

const CRC_TABLE = (() => {
  const t = new Uint32Array(256);
  for (let n = 0; n < 256; n++) {
    let c = n;
    for (let k = 0; k < 8; k++) c = c & 1 ? 0xEDB88320 ^ (c >>> 1) : c >>> 1;
    t[n] = c >>> 0;
  }
  return t;
})();

/** CRC-32 of `bytes` (Uint8Array), continuing from `crc` (0 to start); an unsigned 32-bit number. */
export function crc32(bytes, crc = 0) {
  let c = (crc ^ 0xFFFFFFFF) >>> 0;
  for (let i = 0; i < bytes.length; i++) c = CRC_TABLE[(c ^ bytes[i]) & 0xFF] ^ (c >>> 8);
  return (c ^ 0xFFFFFFFF) >>> 0;
}

// ============================================================================================
// strict JSON: what Python's json.loads accepts, with duplicate keys and NaN/Infinity refused

/** container (object or array) -> Set of keys holding a number written as a float literal
 * ("8.0", "1e3") with an integral value: JSON.parse cannot tell 8.0 from 8, the format can (an
 * integer field holds an integer literal, format.md section 12). */
const FLOAT_LITERALS = new WeakMap();

function isFloatLiteral(obj, key) {
  const s = FLOAT_LITERALS.get(obj);
  return s !== undefined && s.has(key);
}

function setKey(obj, key, value) {
  // defineProperty: a key "__proto__" is an ordinary key, as in Python
  Object.defineProperty(obj, key, {value, writable: true, enumerable: true, configurable: true});
}

/** Parse `text` (ASCII JSON). Throws Error with a parser message. Numbers keep whether they were
 * written as integers (isInt below); NaN, Infinity and duplicate keys are refused; integer literals
 * of more than 4300 digits are refused (Python's int limit). */
export function parseJson(text) {
  let i = 0;
  const n = text.length;
  const ws = () => { while (i < n && (text[i] === ' ' || text[i] === '\t' || text[i] === '\n' || text[i] === '\r')) i++; };
  const err = (what) => { throw new Error(`${what} at char ${i}`); };
  const numberRe = /-?(?:0|[1-9][0-9]*)(\.[0-9]+)?([eE][-+]?[0-9]+)?/y;

  function value(depth, parent, key) {
    if (depth > MAX_JSON_DEPTH) throw new Error('JSON is nested too deeply');
    ws();
    if (i >= n) err('Expecting value');
    const ch = text[i];
    if (ch === '{') return object(depth + 1);
    if (ch === '[') return array(depth + 1);
    if (ch === '"') return string();
    if (text.startsWith('true', i)) { i += 4; return true; }
    if (text.startsWith('false', i)) { i += 5; return false; }
    if (text.startsWith('null', i)) { i += 4; return null; }
    for (const bad of ['NaN', 'Infinity', '-Infinity']) {
      if (text.startsWith(bad, i)) throw new Error(`${bad} is not a JSON number`);
    }
    numberRe.lastIndex = i;
    const m = numberRe.exec(text);
    if (m === null) err('Expecting value');
    i = numberRe.lastIndex;
    const isFloat = m[1] !== undefined || m[2] !== undefined;
    if (!isFloat && m[0].replace('-', '').length > 4300) throw new Error('Exceeds the limit (4300 digits) for integer string conversion');
    const v = Number(m[0]);
    if (isFloat && Number.isInteger(v)) {
      let s = FLOAT_LITERALS.get(parent);
      if (s === undefined) FLOAT_LITERALS.set(parent, (s = new Set()));
      s.add(key);
    }
    return v;
  }

  function string() {
    i++; // opening quote
    let out = '';
    let start = i;
    for (;;) {
      if (i >= n) err('Unterminated string');
      const c = text.charCodeAt(i);
      if (c === 0x22) { out += text.slice(start, i); i++; return out; }
      if (c < 0x20) err('Invalid control character');
      if (c === 0x5C) {
        out += text.slice(start, i);
        const e = text[i + 1];
        const simple = {'"': '"', '\\': '\\', '/': '/', b: '\b', f: '\f', n: '\n', r: '\r', t: '\t'}[e];
        if (simple !== undefined) { out += simple; i += 2; } else if (e === 'u') {
          const hex = text.slice(i + 2, i + 6);
          if (!/^[0-9a-fA-F]{4}$/.test(hex)) err('Invalid \\uXXXX escape');
          out += String.fromCharCode(parseInt(hex, 16));
          i += 6;
        } else err('Invalid \\escape');
        start = i;
      } else i++;
    }
  }

  function object(depth) {
    i++;
    const obj = {};
    const seen = new Set();
    ws();
    if (text[i] === '}') { i++; return obj; }
    for (;;) {
      ws();
      if (text[i] !== '"') err('Expecting property name enclosed in double quotes');
      const key = string();
      if (seen.has(key)) throw new Error(`duplicate key '${key}'`);
      seen.add(key);
      ws();
      if (text[i] !== ':') err("Expecting ':' delimiter");
      i++;
      setKey(obj, key, value(depth, obj, key));
      ws();
      if (text[i] === ',') { i++; continue; }
      if (text[i] === '}') { i++; return obj; }
      err("Expecting ',' delimiter");
    }
  }

  function array(depth) {
    i++;
    const arr = [];
    ws();
    if (text[i] === ']') { i++; return arr; }
    for (;;) {
      arr.push(value(depth, arr, arr.length));
      ws();
      if (text[i] === ',') { i++; continue; }
      if (text[i] === ']') { i++; return arr; }
      err("Expecting ',' delimiter");
    }
  }

  const root = {};
  const out = value(0, root, 'root');
  ws();
  if (i !== n) err('Extra data');
  return out;
}

// ---- JSON value predicates with Python's meaning ------------------------------------------

const isDict = (v) => v !== null && typeof v === 'object' && !Array.isArray(v);
const has = (obj, key) => Object.prototype.hasOwnProperty.call(obj, key);
/** obj[key] is a JSON integer (not a bool, not a float literal). */
const isIntAt = (obj, key) => Number.isInteger(obj[key]) && !isFloatLiteral(obj, key);
/** obj[key] is a finite number within +-limit (not a bool). */
const isNumAt = (obj, key, limit = F32_MAX) => typeof obj[key] === 'number' && Number.isFinite(obj[key]) && Math.abs(obj[key]) <= limit;

/** Python's == on JSON values: numbers and booleans compare as numbers (True == 1), lists by
 * elements, objects by keys and values. */
function pyEqual(a, b) {
  const num = (v) => (typeof v === 'boolean' ? +v : v);
  if ((typeof a === 'number' || typeof a === 'boolean') && (typeof b === 'number' || typeof b === 'boolean')) return num(a) === num(b);
  if (a === null || b === null || typeof a !== 'object' || typeof b !== 'object') return a === b;
  if (Array.isArray(a) !== Array.isArray(b)) return false;
  if (Array.isArray(a)) return a.length === b.length && a.every((v, k) => pyEqual(v, b[k]));
  const ka = Object.keys(a);
  return ka.length === Object.keys(b).length && ka.every((k) => has(b, k) && pyEqual(a[k], b[k]));
}

const repr = (v) => (typeof v === 'string' ? `'${v}'` : JSON.stringify(v));

// ============================================================================================
// the manifest checks (lopcook/emit/manifest.py validate_manifest; format.md section 12, item 6)

/** The attribute bits of a buffer: `{normals, uvs, colors, tangents}` (null when absent) and the
 * record size S = 2 b_n + 2 b_u + 4 b_c (+ 2 b_t + 1 with tangents). */
export function recordBits(ab) {
  const t = ab.tangents == null ? 0 : 2 * ab.tangents + 1;
  return 2 * (ab.normals || 0) + 2 * (ab.uvs || 0) + 4 * (ab.colors || 0) + t;
}

function bitsDict(ab) {
  const out = {normals: ab.normals, uvs: ab.uvs, colors: ab.colors};
  if (ab.tangents != null) out.tangents = ab.tangents;
  return out;
}

/**
 * Throw LopError unless the manifest `m` is sound (format.md section 12, item 6, in the order of
 * lopcook.lop.manifest.validate_manifest): the fields a reader uses and the informative fields
 * inspect shows, with their JSON types (integers are integer literals, never booleans or floats),
 * the grid finite and within float32, sections back to back with the position sections last and
 * in level order, every LOD's tables, counts and section sizes consistent, placements and
 * clustered buffers as section 6.8 and 6.9 say, and tangents (`attribute_bits.tangents`, b_t in
 * [4, 16]) counted in record_bits. Which container version may hold what is the caller's check.
 */
export function validateManifest(m, path = null) {
  const fail = (msg) => { throw new LopError('container', path, `manifest: ${msg}`, 'the file is corrupt; cook it again'); };
  function need(obj, key, kind, where) {
    if (!isDict(obj) || !has(obj, key)) fail(`${where}: missing ${repr(key)}`);
    const v = obj[key];
    if (kind === 'int' && !isIntAt(obj, key)) fail(`${where}.${key} must be an integer`);
    if (kind === 'float' && !isNumAt(obj, key)) fail(`${where}.${key} must be a finite number within the float32 range`);
    if (kind === 'dict' && !isDict(v)) fail(`${where}.${key} has the wrong type`);
    if (kind === 'list' && !Array.isArray(v)) fail(`${where}.${key} has the wrong type`);
    if (kind === 'str' && typeof v !== 'string') fail(`${where}.${key} has the wrong type`);
    return v;
  }
  function count(obj, key, where, minimum = 0) {
    const v = need(obj, key, 'int', where);
    if (v < minimum) fail(`${where}.${key} is ${v}, expected at least ${minimum}`);
    return v;
  }
  const ctx = {fail, need, count};

  if (!isDict(m) || m.format !== FORMAT) fail(`format is not '${FORMAT}'`);
  checkInformative(m, ctx);
  const {names, length, order} = checkSections(m, ctx);
  const {extent} = checkGrid(need(m, 'grid', 'dict', 'manifest'), ctx);
  const pos = checkPositions(m, names, order, ctx);
  const parts = need(m, 'parts', 'list', 'manifest');
  if (!parts.length) fail('no parts');
  const stages = new Map(); // stage -> running totals of its buffers (one stage in the default layout)
  const stageAcc = (s) => {
    if (!stages.has(s)) {
      const acc = {wordsNext: 0, headersNext: 0, nClustered: 0, planeBits: new Map()};
      for (let p = 2; p <= pos.max_level; p++) acc.planeBits.set(p, 0);
      stages.set(s, acc);
    }
    return stages.get(s);
  };
  for (let i = 0; i < parts.length; i++) checkPart(m, parts, i, extent, names, length, pos, stageAcc, ctx);
  if (pos.stream) checkStreamLayout(m, length, stageAcc, ctx);
  else {
    const acc = stageAcc(0);
    if (pos.clustered && !acc.nClustered) fail('positions.clusters is present but no buffer is clustered');
    if (pos.clustered && length.get(pos.clusters) < 4 * acc.headersNext) fail('positions.clusters is shorter than the cluster headers it holds');
    if (length.get(pos.mandatory) < 4 * acc.wordsNext) fail('positions.mandatory is shorter than the buffers it holds');
    for (const [p, bits] of acc.planeBits) {
      if (length.get(pos.planes[String(p)]) < Math.ceil(bits / 8)) fail(`refinement plane ${p} is shorter than its ${bits} bits`);
    }
  }
  checkEncodedIndices(m, ctx);
}

/** The streaming layout (format.md 14): every stage holds a stored buffer, the section table is
 * exactly the list of 14.3, each stage's sections as long as its buffers need (checkStage has
 * checked each LOD's stage). */
function checkStreamLayout(m, length, stageAcc, {fail}) {
  const lay = layoutOf(m);
  const empty = lay.stages.find((st) => !st.buffers.length);
  if (empty) fail(`positions.stages[${empty.index}] holds no buffer`);
  const want = expectedSections(lay), have = [...length.keys()];
  const at = want.findIndex((v, k) => have[k] !== v);
  if (at >= 0 || have.length !== want.length) {
    const j = at >= 0 ? at : Math.min(have.length, want.length);
    fail(`the sections are not those of the streaming layout in its order: section ${j} is ${repr(j < have.length ? have[j] : 'missing')}, expected ${repr(j < want.length ? want[j] : 'none')}`);
  }
  for (const st of lay.stages) {
    const acc = stageAcc(st.index);
    if (st.clusters && length.get(st.clusters) < 4 * acc.headersNext) fail(`${st.clusters} is shorter than the cluster headers it holds`);
    if (length.get(st.mandatory) < 4 * acc.wordsNext) fail(`${st.mandatory} is shorter than the buffers it holds`);
    for (const [p, name] of st.planes) {
      if (length.get(name) !== planeBytes(st.bits.get(p))) fail(`${name} is not the ${st.bits.get(p)} bits its buffers hold`);
    }
    if (st.deferred) {
      let bytes = 0;
      for (let p = st.level + 1; p <= lay.maxLevel; p++) bytes += planeBytes(st.bits.get(p));
      if (length.get(st.deferred) !== bytes) fail(`${st.deferred} is not the ${bytes} bytes of planes ${st.level + 1}..${lay.maxLevel}`);
    }
  }
}

/** A meshopt-deflate section is a LOD's indices and nothing else, its size the 3 m indices' bytes,
 * its stored length enough for a triangle stream of m triangles (format.md 15.2). */
function checkEncodedIndices(m, {fail}) {
  const named = new Map();
  for (const part of m.parts) {
    for (const e of part.lods) {
      if (!named.has(e.indices)) named.set(e.indices, e);
      if (e.attributes != null) named.set(e.attributes, null);
    }
    if (isDict(part.hierarchy)) named.set(part.hierarchy.section, null);
  }
  for (const s of m.sections) {
    if (s.encoding !== 'meshopt-deflate') continue;
    const e = named.get(s.name);
    if (!e) fail(`section ${repr(s.name)} is encoded meshopt-deflate but is no LOD's index section`);
    const want = 4 * Math.ceil((3 * e.triangles * e.index_width) / 4);
    if (s.size !== want) fail(`section ${repr(s.name)} size ${s.size} is not the ${want} bytes of its ${e.triangles} triangles`);
    if (e.triangles + 17 > DEFLATE_MAX_RATIO * s.length) fail(`section ${repr(s.name)}: ${s.length} stored bytes cannot hold ${e.triangles} triangles`);
  }
}

function checkInformative(m, {fail, need, count}) {
  need(m, 'generator', 'str', 'manifest');
  const src = need(m, 'source', 'dict', 'manifest');
  need(src, 'file', 'str', 'source');
  need(src, 'format', 'str', 'source');
  const viewing = need(m, 'viewing', 'dict', 'manifest');
  const vp = need(viewing, 'viewport', 'list', 'viewing');
  if (vp.length !== 2 || !vp.every((v, k) => isIntAt(vp, k) && v > 0)) fail('viewing.viewport must be two positive integers');
  const fov = need(viewing, 'fov_y_deg', 'float', 'viewing');
  if (!(fov > 0 && fov < 180)) fail('viewing.fov_y_deg must be in (0, 180)');
  if (!(need(viewing, 'pixel_error', 'float', 'viewing') > 0)) fail('viewing.pixel_error must be > 0');
  const nearest = viewing.nearest_m;
  if (nearest !== undefined && nearest !== null && !(isNumAt(viewing, 'nearest_m') && nearest > 0)) fail('viewing.nearest_m must be a positive number or null');
  const options = need(m, 'options', 'dict', 'manifest');
  for (const key of ['analyse', 'ingest']) {
    if (has(options, key) && !isDict(options[key])) fail(`options.${key} must be an object`);
  }
  const stats = need(m, 'stats', 'dict', 'manifest');
  for (const key of ['vertices', 'triangles', 'float32_position_bytes']) count(stats, key, 'stats');
  const hist = need(stats, 'histogram', 'list', 'stats');
  if (hist.length !== LEVELS + 1 || !hist.every((v, k) => isIntAt(hist, k) && v >= 0)) fail('stats.histogram must be 25 counts');
  const savings = m.savings;
  if (savings !== undefined && savings !== null) {
    if (!isDict(savings)) fail('savings must be an object or null');
    count(savings, 'bytes_saved', 'savings');
    need(savings, 'planes_dropped', 'list', 'savings');
    count(savings, 'lods_dropped', 'savings');
  }
}

function checkSections(m, ctx) {
  const {fail, need, count} = ctx;
  const sections = need(m, 'sections', 'list', 'manifest');
  const names = new Set();
  const length = new Map();
  let offset = 0;
  sections.forEach((s, i) => {
    const name = need(s, 'name', 'str', `sections[${i}]`);
    for (const key of ['offset', 'length', 'crc32']) count(s, key, `sections[${i}]`);
    if (s.length % 4) fail(`section ${repr(name)} length is not a multiple of 4`);
    if (s.offset !== offset) fail(`section ${repr(name)} starts at ${s.offset}, not where the previous one ends (${offset})`);
    if (s.crc32 > 0xFFFFFFFF) fail(`section ${repr(name)} crc32 is not a 32-bit value`);
    offset += s.length;
    if (names.has(name)) fail(`section ${repr(name)} appears twice`);
    names.add(name);
    length.set(name, checkEncoded(s, name, ctx));
  });
  return {names, length, order: sections.map((s) => s.name)};
}

/** An encoded section's `encoding` and `size` (format.md 15): both or neither, a known encoding,
 * size a multiple of 4 and, for deflate, at most 1032 times the stored length. Returns the
 * section's decoded length. */
function checkEncoded(s, name, {fail, need, count}) {
  if (!has(s, 'encoding') && !has(s, 'size')) return s.length;
  const enc = need(s, 'encoding', 'str', `section ${repr(name)}`);
  const size = count(s, 'size', `section ${repr(name)}`);
  if (!ENCODINGS.includes(enc)) fail(`section ${repr(name)} has the unknown encoding ${repr(enc)} (known: ${ENCODINGS.join(', ')})`);
  if (size % 4) fail(`section ${repr(name)} size is not a multiple of 4`);
  if (enc !== 'meshopt-deflate' && size > DEFLATE_MAX_RATIO * s.length) fail(`section ${repr(name)} claims ${size} decoded bytes, more than ${DEFLATE_MAX_RATIO} times its ${s.length} stored bytes`);
  return size;
}

function checkGrid(grid, {fail, need}) {
  const origin = need(grid, 'origin', 'list', 'grid');
  if (origin.length !== 3 || !origin.every((v, k) => isNumAt(origin, k))) fail('grid.origin must be 3 finite numbers within the float32 range');
  const extent = need(grid, 'extent', 'float', 'grid');
  if (!(extent > 0) || need(grid, 'bits', 'int', 'grid') !== LEVELS) fail('grid.extent must be > 0 and grid.bits 24');
  if (extent < MIN_EXTENT) fail(`grid.extent ${extent} is below the ${MIN_EXTENT} m floor lopcook cooks with (its cells would decode to subnormal float32 values)`);
  if (Math.max(...origin.map(Math.abs)) + extent > MAX_GRID_REACH) fail(`grid origin ${JSON.stringify(origin)} + extent ${extent} reaches beyond ${MAX_GRID_REACH} m (lopcook cooks positions within 2^100 m of the origin, so that float32 decoding stays finite)`);
  return {extent};
}

function checkPositions(m, names, order, {fail, need}) {
  const pos = need(m, 'positions', 'dict', 'manifest');
  const maxLevel = need(pos, 'max_level', 'int', 'positions');
  if (!(maxLevel >= 1 && maxLevel <= LEVELS)) fail('positions.max_level must be in [1, 24]');
  if (has(pos, 'stages')) { // the streaming layout (format.md 14.2); its section list: checkStreamLayout
    for (const key of ['mandatory', 'planes', 'clusters']) if (has(pos, key)) fail(`positions.${key} must not be given with positions.stages (the streaming layout)`);
    const stages = need(pos, 'stages', 'list', 'positions');
    if (!stages.length) fail('positions.stages is empty');
    stages.forEach((st, s) => {
      if (!isDict(st) || Object.keys(st).join(',') !== 'level') fail(`positions.stages[${s}] must hold exactly level`);
      const level = need(st, 'level', 'int', `positions.stages[${s}]`);
      if (!(level >= 1 && level <= maxLevel)) fail(`positions.stages[${s}].level must be in [1, ${maxLevel}]`);
    });
    return {max_level: maxLevel, stream: true, clustered: true};
  }
  if (!names.has(need(pos, 'mandatory', 'str', 'positions'))) fail('positions.mandatory names no section');
  const planes = need(pos, 'planes', 'dict', 'positions');
  for (let p = 2; p <= maxLevel; p++) {
    const name = has(planes, String(p)) ? planes[String(p)] : undefined;
    if (typeof name !== 'string' || !names.has(name)) fail(`positions.planes[${p}] names no section`);
  }
  const clustered = has(pos, 'clusters');
  if (clustered && !names.has(need(pos, 'clusters', 'str', 'positions'))) fail('positions.clusters names no section');
  const tail = [...(clustered ? [pos.clusters] : []), pos.mandatory];
  for (let p = 2; p <= maxLevel; p++) tail.push(planes[String(p)]);
  const end = order.slice(Math.max(0, order.length - tail.length));
  if (end.length !== tail.length || end.some((v, k) => v !== tail[k])) fail('position sections are not last and in level order');
  return {max_level: maxLevel, mandatory: pos.mandatory, planes, clustered, clusters: clustered ? pos.clusters : null, stream: false};
}

function checkBits(lod, where, {fail, need}) {
  const ab = need(lod, 'attribute_bits', 'dict', where);
  const keys = Object.keys(ab).sort().join(',');
  const tangents = has(ab, 'tangents');
  if (keys !== 'colors,normals,uvs' && keys !== 'colors,normals,tangents,uvs') fail(`${where}.attribute_bits must hold exactly normals, uvs, colors (and tangents)`);
  for (const key of ['normals', 'uvs', 'colors']) {
    const [lo, hi] = ATTRIBUTE_BITS[key];
    const v = ab[key];
    if (v !== null && !(isIntAt(ab, key) && v >= lo && v <= hi)) fail(`${where}.attribute_bits.${key} must be null or an integer in [${lo}, ${hi}]`);
  }
  if (tangents) {
    const [lo, hi] = ATTRIBUTE_BITS.tangents;
    if (!(isIntAt(ab, 'tangents') && ab.tangents >= lo && ab.tangents <= hi)) fail(`${where}.attribute_bits.tangents must be an integer in [${lo}, ${hi}]`);
  }
  return {normals: ab.normals, uvs: ab.uvs, colors: ab.colors, tangents: tangents ? ab.tangents : null};
}

function checkPart(m, parts, i, extent, names, length, pos, stageAcc, ctx) {
  const {fail, need} = ctx;
  const part = parts[i];
  need(part, 'name', 'str', `parts[${i}]`);
  if (part.hierarchy !== undefined && part.hierarchy !== null) { // optional (cook --hierarchy)
    const hier = need(part, 'hierarchy', 'dict', `parts[${i}]`);
    const sec = need(hier, 'section', 'str', `parts[${i}].hierarchy`);
    if (!names.has(sec) || sec.startsWith('positions/')) fail(`parts[${i}].hierarchy.section names no hierarchy section`);
    for (const key of ['leaves', 'nodes', 'triangles', 'connectivity_bits', 'structure_bits', 'vertex_map_bits', 'representative_bits']) {
      if (need(hier, key, 'int', `parts[${i}].hierarchy`) < 0) fail(`parts[${i}].hierarchy.${key} is negative`);
    }
  }
  need(part, 'source', 'str', `parts[${i}]`);
  const lods = need(part, 'lods', 'list', `parts[${i}]`);
  if (!lods.length) fail(`parts[${i}] has no LODs`);
  let iBits = null;
  const sharedOf = checkPlacement(m, parts, i, part, extent, ctx);
  lods.forEach((lod, k) => {
    const where = `parts[${i}].lods[${k}]`;
    if (!isDict(lod)) fail(`${where} is not an object`);
    const stage = pos.stream ? checkStage(m, lod, where, k, lods, ctx) : 0;
    if (!pos.stream && has(lod, 'stage')) fail(`${where}.stage is only allowed in the streaming layout (positions.stages)`);
    if (sharedOf !== null) {
      const ref = parts[sharedOf].lods;
      if (lods.length !== ref.length) fail(`parts[${i}] has ${lods.length} LODs, the buffers it places (parts[${sharedOf}]) ${ref.length}`);
      const strip = (e) => Object.fromEntries(Object.entries(e).filter(([key]) => !SHARED_OWN_FIELDS.includes(key)));
      if (!pyEqual(strip(lod), strip(ref[k]))) fail(`${where} does not name the buffer of parts[${sharedOf}].lods[${k}] it places`);
      if (need(lod, 'geometric_error_m', 'float', where) < 0) fail(`${where}.geometric_error_m is negative`);
      iBits = iBits === null ? checkBits(lod, where, ctx) : iBits;
      return;
    }
    const abits = checkLod(lod, where, names, length, pos, stageAcc(stage), ctx);
    if (iBits === null) iBits = abits;
  });
  const pb = need(part, 'attribute_bits', 'dict', `parts[${i}]`);
  if (!pyEqual(pb, bitsDict(iBits))) fail(`parts[${i}].attribute_bits is not the attribute_bits its LODs share`);
}

/** A LOD entry's stage in the streaming layout (format.md 14.1): an integer naming a stage, 0 for
 * the part's coarsest LOD, never below the stage of a coarser LOD of the part. */
function checkStage(m, lod, where, k, lods, {fail, need}) {
  const s = need(lod, 'stage', 'int', where);
  const count = m.positions.stages.length;
  if (!(s >= 0 && s < count)) fail(`${where}.stage ${s} names no stage (the file has ${count})`);
  if (k === lods.length - 1 && s !== 0) fail(`${where}.stage must be 0: a part's coarsest LOD is in the first stage`);
  const next = lods[k + 1];
  if (k < lods.length - 1 && isDict(next) && isIntAt(next, 'stage') && s < next.stage) fail(`${where}.stage ${s} comes before the stage of the coarser LOD ${k + 1}`);
  return s;
}

function checkLod(lod, where, names, length, pos, acc, ctx) {
  const {fail, need} = ctx;
  const n = need(lod, 'vertices', 'int', where);
  const tri = need(lod, 'triangles', 'int', where);
  if (n < 1 || tri < 1) fail(`${where} is empty`);
  if (n > 0xFFFFFFFF || tri > 0xFFFFFFFF) fail(`${where} has more than 2^32 vertices or triangles`);
  if (need(lod, 'geometric_error_m', 'float', where) < 0) fail(`${where}.geometric_error_m is negative`);
  const vid = need(lod, 'vertex_id', 'list', where);
  if (vid.length !== LEVELS + 1 || !vid.every((v, k) => isIntAt(vid, k)) || vid[0] !== 0 || vid[LEVELS] !== n
      || vid.some((v, k) => k > 0 && vid[k - 1] > v)) fail(`${where}.vertex_id is not 25 non-decreasing counts from 0 to ${n}`);
  const width = need(lod, 'index_width', 'int', where);
  if (width !== 2 && width !== 4) fail(`${where}.index_width must be 2 or 4`);
  if (!names.has(need(lod, 'indices', 'str', where))) fail(`${where}.indices names no section`);
  const abits = checkBits(lod, where, ctx);
  const S = recordBits(abits);
  const rec = lod.attributes;
  if (rec !== undefined && rec !== null && (typeof rec !== 'string' || !names.has(rec))) fail(`${where}.attributes names no section`);
  if ((rec === undefined || rec === null) !== (S === 0)) fail(`${where}.attributes must name a section exactly when record_bits > 0`);
  if (need(lod, 'record_bits', 'int', where) !== S) fail(`${where}.record_bits is not 2 b_n + 2 b_u + 4 b_c (+ 2 b_t + 1) of its attribute_bits`);
  const mw = need(lod, 'mandatory_words', 'list', where);
  if (mw.length !== 2 || !mw.every((v, k) => isIntAt(mw, k) && v >= 0)) fail(`${where}.mandatory_words must be [offset, count]`);
  let bits = 0; // the buffer at level 1 holds sum_k 3 k |bin k| bits, buffers back to back
  for (let k = 1; k <= LEVELS; k++) bits += 3 * k * (vid[k] - vid[k - 1]);
  if (has(lod, 'cluster_size') || has(lod, 'cluster_words')) checkClusteredLod(lod, where, vid, mw, bits, pos, acc, ctx);
  else {
    if (mw[0] !== acc.wordsNext || mw[1] !== Math.ceil(bits / 32)) fail(`${where}.mandatory_words do not match its bins`);
    for (const p of acc.planeBits.keys()) acc.planeBits.set(p, acc.planeBits.get(p) + 3 * vid[p - 1]);
  }
  acc.wordsNext += mw[1];
  if ((n <= 65535) !== (width === 2)) fail(`${where}.index_width ${width} does not match ${n} vertices`);
  if (length.get(lod.indices) < 3 * tri * width) fail(`${where}: index section is shorter than ${tri} triangles`);
  if (rec != null && length.get(rec) < 4 * Math.ceil((n * S) / 32)) fail(`${where}: attributes section is shorter than ${n} records of ${S} bits`);
  if (abits.uvs !== null) checkUvRange(lod, where, abits.uvs, ctx);
  return abits;
}

function checkClusteredLod(lod, where, vid, mw, bits, pos, acc, {fail, need}) {
  if (!pos.clustered) fail(`${where} is clustered but positions.clusters is missing`);
  const size = need(lod, 'cluster_size', 'int', where);
  if (!(size >= CLUSTER_SIZE_RANGE[0] && size <= CLUSTER_SIZE_RANGE[1])) fail(`${where}.cluster_size must be in [16, 1024]`);
  const cw = need(lod, 'cluster_words', 'list', where);
  let nc = 0;
  for (let k = 1; k <= LEVELS; k++) nc += Math.ceil((vid[k] - vid[k - 1]) / size);
  if (cw.length !== 2 || !cw.every((v, k) => isIntAt(cw, k)) || cw[0] !== acc.headersNext || cw[1] !== 3 * nc) {
    fail(`${where}.cluster_words must be [offset, 3 * clusters] = [${acc.headersNext}, ${3 * nc}]`);
  }
  acc.headersNext += cw[1];
  acc.nClustered += 1;
  const pw = need(lod, 'cluster_p_words', 'list', where);
  if (pw.length !== LEVELS || !pw.every((v, k) => isIntAt(pw, k) && v >= 1) || pw[0] !== mw[1]) {
    fail(`${where}.cluster_p_words must be 24 positive word counts, the first its mandatory count`);
  }
  const cpb = need(lod, 'cluster_plane_bits', 'list', where);
  if (cpb.length !== LEVELS - 1 || !cpb.every((v, k) => isIntAt(cpb, k) && v >= 0 && v <= 3 * vid[k + 1])) {
    fail(`${where}.cluster_plane_bits must be 23 bit counts, at most 3 VertexId[p-1] each`);
  }
  for (const p of acc.planeBits.keys()) acc.planeBits.set(p, acc.planeBits.get(p) + cpb[p - 2]);
  if (mw[0] !== acc.wordsNext || !(mw[1] >= 1 && mw[1] <= Math.max(1, Math.ceil(bits / 32)))) fail(`${where}.mandatory_words do not match its bins`);
}

function checkUvRange(lod, where, bu, {fail, need}) {
  const rng = need(lod, 'uv_range', 'list', where);
  if (rng.length !== 2 || !rng.every((r) => Array.isArray(r) && r.length === 2 && r.every((v, k) => isNumAt(r, k)))) {
    fail(`${where}.uv_range must be [[lo_u, lo_v], [hi_u, hi_v]] of finite float32 numbers`);
  }
  if (!(rng[0][0] <= rng[1][0] && rng[0][1] <= rng[1][1])) fail(`${where}.uv_range has lo above hi`);
  const step = need(lod, 'uv_step', 'list', where);
  if (step.length !== 2 || !step.every((v, k) => isNumAt(step, k))) fail(`${where}.uv_step must be [step_u, step_v] of finite float32 numbers`);
  for (let c = 0; c < 2; c++) {
    if (step[c] !== uvStep(rng[0][c], rng[1][c], bu)) fail(`${where}.uv_step is not float32((hi - lo) / (2^b_u - 1)) of its uv_range`);
  }
}

/** float32((float32(hi) - float32(lo)) / (2^b - 1)), the difference and quotient in float64. */
export function uvStep(lo, hi, bits) {
  return f32((f32(hi) - f32(lo)) / (2 ** bits - 1));
}

// ---- placements (format.md 6.8; lopcook/emit/placement.py) ---------------------------------

/** [A (3x3 rows, float32 values), t (3, float32)] of a manifest transform (12 numbers, row-major 3x4). */
export function splitTransform(tf) {
  const v = tf.map((x) => f32(x));
  return [[v.slice(0, 3), v.slice(4, 7), v.slice(8, 11)], [v[3], v[7], v[11]]];
}

function det3(a) {
  return a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
    + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
}

/** Largest singular value of the float32 A of a transform (float64: the square root of the largest
 * eigenvalue of A^T A by cyclic Jacobi rotations), widened by a relative 1e-9 as
 * lopcook.lop.placement.sigma does. */
export function sigma(tf) {
  const [a] = splitTransform(tf);
  const s = [[0, 0, 0], [0, 0, 0], [0, 0, 0]];
  for (let r = 0; r < 3; r++) for (let c = 0; c < 3; c++) for (let k = 0; k < 3; k++) s[r][c] += a[k][r] * a[k][c];
  for (let sweep = 0; sweep < 60; sweep++) {
    const off = s[0][1] ** 2 + s[0][2] ** 2 + s[1][2] ** 2;
    if (!(off > 1e-300)) break;
    for (const [p, q] of [[0, 1], [0, 2], [1, 2]]) {
      if (s[p][q] === 0) continue;
      const theta = (s[q][q] - s[p][p]) / (2 * s[p][q]);
      const t = Math.sign(theta || 1) / (Math.abs(theta) + Math.sqrt(theta * theta + 1));
      const c = 1 / Math.sqrt(t * t + 1);
      const sn = t * c;
      for (let k = 0; k < 3; k++) { // rotate columns p, q then rows p, q
        const kp = s[k][p], kq = s[k][q];
        s[k][p] = c * kp - sn * kq; s[k][q] = sn * kp + c * kq;
      }
      for (let k = 0; k < 3; k++) {
        const pk = s[p][k], qk = s[q][k];
        s[p][k] = c * pk - sn * qk; s[q][k] = sn * pk + c * qk;
      }
    }
  }
  return Math.sqrt(Math.max(s[0][0], s[1][1], s[2][2], 0)) * (1.0 + 1e-9);
}

function ldexp(x, e) {
  while (e > 1000) { x *= 2 ** 1000; e -= 1000; }
  while (e < -1000) { x *= 2 ** -1000; e += 1000; }
  return x * 2 ** e;
}

/** The smallest integer s with 2^s >= sig * meshExtent / worldExtent (lopcook.lop.placement.level_shift). */
export function levelShift(sig, meshExtent, worldExtent) {
  const r = sig * meshExtent;
  const w = worldExtent;
  if (!(r > 0 && w > 0 && Number.isFinite(r) && Number.isFinite(w))) return null;
  let s = Math.ceil(Math.log2(r) - Math.log2(w));
  while (ldexp(w, s - 1) >= r) s -= 1;
  while (ldexp(w, s) < r) s += 1;
  return s;
}

function checkPlacement(m, parts, i, part, worldExtent, {fail}) {
  const rec = part.placement;
  if (rec === undefined || rec === null) {
    if (part.grid !== undefined && part.grid !== null) fail(`parts[${i}].grid is only allowed with a placement`);
    return null;
  }
  const where = `parts[${i}].placement`;
  if (!isDict(rec) || Object.keys(rec).sort().join(',') !== 'level_shift,of,transform') fail(`${where} must hold exactly of, transform, level_shift`);
  const of = rec.of;
  if (!isIntAt(rec, 'of') || !(of >= 0 && of <= i)) fail(`${where}.of must be the index of this or an earlier part, got ${JSON.stringify(of)}`);
  const tf = rec.transform;
  if (!Array.isArray(tf) || tf.length !== 12 || !tf.every((v, k) => isNumAt(tf, k))) fail(`${where}.transform must be 12 finite float32 numbers (3 x 4, row-major)`);
  if (!(Math.abs(det3(splitTransform(tf)[0])) > 0)) fail(`${where}.transform is singular`);
  const g = part.grid;
  if (!isDict(g) || Object.keys(g).sort().join(',') !== 'extent,origin') fail(`parts[${i}].grid must hold exactly origin and extent`);
  if (!(Array.isArray(g.origin) && g.origin.length === 3 && g.origin.every((v, k) => isNumAt(g.origin, k)))) {
    fail(`parts[${i}].grid.origin must be 3 finite numbers within the float32 range`);
  }
  if (!(isNumAt(g, 'extent') && g.extent >= MIN_EXTENT && Math.max(...g.origin.map(Math.abs)) + g.extent <= MAX_GRID_REACH)) {
    fail(`parts[${i}].grid.extent must be at least ${MIN_EXTENT} m and within ${MAX_GRID_REACH} m`);
  }
  const shift = levelShift(sigma(tf), g.extent, worldExtent);
  if (shift === null) throw new LopError('emit', null, `placement scale or extents ${g.extent}, ${worldExtent} are not positive and finite`, 'cook without --instances');
  if (!isIntAt(rec, 'level_shift') || rec.level_shift !== shift) fail(`${where}.level_shift is not ceil(log2(sigma E_m / E_w)) of its transform and grids`);
  const owner = parts[of];
  const orec = isDict(owner) ? owner.placement : undefined;
  if (!isDict(orec) || !pyEqual(orec.of === undefined ? null : orec.of, of)) fail(`${where}.of names parts[${of}], which does not own its buffers`);
  if (!pyEqual(owner.grid === undefined ? null : owner.grid, g)) fail(`parts[${i}].grid differs from the grid of the buffers it places (parts[${of}].grid)`);
  return of === i ? null : of;
}

// ============================================================================================
// layouts: where each buffer's position bits lie (lopcook/lop/layout.py; format.md 6.4-6.5, 14)

/** Bytes of a plane holding `bits` bits: whole uint32 words. */
export const planeBytes = (bits) => 4 * Math.ceil(bits / 32);

/** Bits of one buffer's slice of plane p: 3 VertexId[p-1], or a clustered one's cluster_plane_bits[p-2]. */
const sliceBits = (e, p) => (has(e, 'cluster_size') ? e.cluster_plane_bits[p - 2] : 3 * e.vertex_id[p - 1]);

/** Whether a manifest is in the streaming layout (format.md 14). */
export const isStream = (m) => isDict(m) && isDict(m.positions) && has(m.positions, 'stages');

/**
 * The stages of a manifest whose LOD entries are sound (lopcook.lop.layout.layout_of): `{stream,
 * maxLevel, stages, stageOf: Map "part/lod" -> stage}`; a stage is `{index, buffers: [[part, lod,
 * entry], ...] (stored buffers, manifest order), level (L_s; max_level in the default layout),
 * mandatory, clusters (null when none), planes: Map p -> section name (the planes stored as
 * sections), deferred (null when none), bits: Map p -> bits of plane p, required: the sections that
 * must be complete before any level of the stage decodes}`. The default layout is one stage.
 */
export function layoutOf(m) {
  const pos = m.positions, maxLevel = pos.max_level, stream = isStream(m);
  const count = stream ? pos.stages.length : 1;
  const buffers = Array.from({length: count}, () => []);
  const stageOf = new Map();
  m.parts.forEach((part, i) => {
    const own = !isDict(part.placement) || part.placement.of === i;
    part.lods.forEach((e, k) => {
      const st = stream ? e.stage : 0;
      stageOf.set(`${i}/${k}`, st);
      if (own && st >= 0 && st < count) buffers[st].push([i, k, e]);
    });
  });
  const stages = buffers.map((bufs, si) => {
    const bits = new Map();
    for (let p = 2; p <= maxLevel; p++) bits.set(p, bufs.reduce((a, [, , e]) => a + sliceBits(e, p), 0));
    if (!stream) {
      const planes = new Map();
      for (let p = 2; p <= maxLevel; p++) planes.set(p, pos.planes[String(p)]);
      const required = m.sections.map((t) => t.name).filter((n) => !n.startsWith('positions/'));
      return {index: 0, buffers: bufs, level: maxLevel, mandatory: pos.mandatory, clusters: has(pos, 'clusters') ? pos.clusters : null, planes, deferred: null, bits, required};
    }
    const level = pos.stages[si].level, name = (kind) => `positions/stage${si}/${kind}`;
    const planes = new Map();
    for (let p = 2; p <= level; p++) if (bits.get(p)) planes.set(p, name(`plane${String(p).padStart(2, '0')}`));
    let deferred = null;
    for (let p = level + 1; p <= maxLevel; p++) if (bits.get(p)) deferred = name('deferred');
    const required = [];
    for (const [i, k, e] of bufs) {
      required.push(e.indices);
      if (e.attributes != null) required.push(e.attributes);
      if (k === 0 && isDict(m.parts[i].hierarchy)) required.push(m.parts[i].hierarchy.section);
    }
    const clustered = bufs.some(([, , e]) => has(e, 'cluster_size'));
    return {index: si, buffers: bufs, level, mandatory: name('mandatory'), clusters: clustered ? name('clusters') : null, planes, deferred, bits, required};
  });
  return {stream, maxLevel, stages, stageOf};
}

/** A stage's position sections in file order (the deferred one excluded). */
const stageSections = (st) => [...(st.clusters ? [st.clusters] : []), st.mandatory, ...[...st.planes.keys()].sort((a, b) => a - b).map((p) => st.planes.get(p))];

/** The section list of a streaming file, in order (format.md 14.3). */
export function expectedSections(lay) {
  const out = [];
  for (const st of lay.stages) out.push(...st.required, ...stageSections(st));
  for (const st of lay.stages) if (st.deferred) out.push(st.deferred);
  return out;
}

/** [section name, byte offset] of plane p of a stage, null when the plane holds no bits. */
export function planeLocation(st, p, maxLevel) {
  if (!st.bits.get(p)) return null;
  if (st.planes.has(p)) return [st.planes.get(p), 0];
  let offset = 0;
  for (let q = st.level + 1; q < p; q++) offset += planeBytes(st.bits.get(q));
  return p <= maxLevel ? [st.deferred, offset] : null;
}

/** A stage's level given the complete sections `present` (a Set or Map of names; format.md 8, 14.4). */
export function stageLevel(st, present, maxLevel) {
  for (const name of [...st.required, ...(st.clusters ? [st.clusters] : []), st.mandatory]) if (!present.has(name)) return 0;
  let level = 1;
  for (let p = 2; p <= st.level; p++) {
    if (st.planes.has(p) && !present.has(st.planes.get(p))) return level;
    level = p;
  }
  if (st.level < maxLevel && (st.deferred === null || present.has(st.deferred))) return maxLevel;
  return level;
}

// ============================================================================================
// bins, clusters and plane slices (lopcook/emit/binning.py, clusters.py)

/** BitId at per-buffer level B: Float64Array(25), BitId[k] = bit offset after bin k (format.md 6.2). */
export function bitId(vid, level) {
  const out = new Float64Array(LEVELS + 1);
  for (let k = 1; k <= LEVELS; k++) out[k] = out[k - 1] + 3 * Math.max(k, level) * (vid[k] - vid[k - 1]);
  return out;
}

/**
 * The clusters of a clustered buffer from its stored header words (format.md 6.9;
 * lopcook.lop.clusters.from_header): `{size, vertexId, clusterId (25), m, start, count (per
 * cluster), k, anchor (3 per cluster)}`. Throws Error when the words do not fit the table.
 */
export function clustersFromHeader(header, vid, size) {
  const cid = new Float64Array(LEVELS + 1);
  for (let k = 1; k <= LEVELS; k++) cid[k] = cid[k - 1] + Math.ceil((vid[k] - vid[k - 1]) / size);
  const nc = cid[LEVELS];
  if (header.length !== 3 * nc) throw new Error(`${header.length} cluster header words, expected ${3 * nc}`);
  const m = new Uint8Array(nc), start = new Float64Array(nc), count = new Float64Array(nc);
  for (let k = 1; k <= LEVELS; k++) {
    for (let c = cid[k - 1]; c < cid[k]; c++) {
      m[c] = k;
      start[c] = vid[k - 1] + (c - cid[k - 1]) * size;
      count[c] = Math.min(size, vid[k] - start[c]);
    }
  }
  const kk = new Uint8Array(3 * nc), anchor = new Uint32Array(3 * nc);
  for (let t = 0; t < 3 * nc; t++) {
    const k = header[t] >>> 24, a = header[t] & 0xFFFFFF;
    if (k > LEVELS || (k < LEVELS && a >= 2 ** k)) throw new Error('a cluster header has k > 24 or an anchor wider than k bits');
    kk[t] = k;
    anchor[t] = a;
  }
  return {size, vertexId: vid, clusterId: cid, m, start, count, k: kk, anchor, nClusters: nc};
}

/** ClusterBit at level B: Float64Array(n_c + 1), the last entry the bits of P. */
export function clusterBit(cl, level) {
  const out = new Float64Array(cl.nClusters + 1);
  for (let c = 0; c < cl.nClusters; c++) {
    const b = Math.max(cl.m[c], level);
    let s = 0;
    for (let t = 0; t < 3; t++) s += Math.max(0, b - cl.k[3 * c + t]);
    out[c + 1] = out[c] + cl.count[c] * s;
  }
  return out;
}

/** Words of the clustered P at level B: max(1, ceil(bits / 32)). */
export const clusterWordsAt = (cl, level) => Math.max(1, Math.ceil(clusterBit(cl, level)[cl.nClusters] / 32));

/** Bits of a clustered buffer's slice of refinement plane p (PlaneBit_p[n_c]). */
export function clusterPlaneBits(cl, p) {
  let bits = 0;
  for (let c = 0; c < cl.nClusters; c++) {
    if (cl.m[c] >= p) continue;
    let active = 0;
    for (let t = 0; t < 3; t++) active += cl.k[3 * c + t] < p ? 1 : 0;
    bits += cl.count[c] * active;
  }
  return bits;
}

// ============================================================================================
// the container

const textDecoder = typeof TextDecoder !== 'undefined' ? new TextDecoder('latin1') : null;

function asciiText(bytes) {
  for (let i = 0; i < bytes.length; i++) {
    if (bytes[i] > 0x7F) {
      throw new Error(`'ascii' codec can't decode byte 0x${bytes[i].toString(16)} in position ${i}: ordinal not in range(128)`);
    }
  }
  if (textDecoder) return textDecoder.decode(bytes);
  let s = '';
  for (let i = 0; i < bytes.length; i += 8192) s += String.fromCharCode.apply(null, bytes.subarray(i, i + 8192));
  return s;
}

function u32le(bytes, at) {
  return (bytes[at] | (bytes[at + 1] << 8) | (bytes[at + 2] << 16) | (bytes[at + 3] << 24)) >>> 0;
}

/** A little-endian uint32 view of `bytes` (a Uint8Array whose length is a multiple of 4): the bytes
 * themselves when aligned on a little-endian host, else an aligned copy. */
function wordsOf(bytes) {
  const n = bytes.length >>> 2;
  if (LITTLE_ENDIAN && bytes.byteOffset % 4 === 0) return new Uint32Array(bytes.buffer, bytes.byteOffset, n);
  const out = new Uint32Array(n);
  for (let i = 0; i < n; i++) out[i] = u32le(bytes, 4 * i);
  return out;
}
const LITTLE_ENDIAN = new Uint8Array(new Uint32Array([1]).buffer)[0] === 1;

/** A deflate stream ending at byte `end` of a section's stored bytes: the rest is its zero padding
 * (fewer than 4 bytes, format.md 15.1). */
function checkPadding(stored, end) {
  if (stored.length !== 4 * Math.ceil(end / 4) || stored.subarray(end).some((b) => b !== 0)) {
    throw new Error(`the deflate stream ends at byte ${end}, not in the last word of its ${stored.length} stored bytes with zero padding after it`);
  }
}

/** Whether a manifest holds clustered buffers / placements / tangents. */
const isClustered = (m) => isDict(m) && isDict(m.positions) && has(m.positions, 'clusters');
const hasPlacements = (m) => isDict(m) && Array.isArray(m.parts) && m.parts.some((p) => isDict(p) && has(p, 'placement'));
const hasTangents = (m) => isDict(m) && Array.isArray(m.parts) && m.parts.some((p) => isDict(p)
  && ((isDict(p.attribute_bits) && has(p.attribute_bits, 'tangents'))
      || (Array.isArray(p.lods) && p.lods.some((e) => isDict(e) && isDict(e.attribute_bits) && has(e.attribute_bits, 'tangents')))));

/**
 * The incremental reader both `parse` and `LopStream` use: bytes arrive in order (`push`), the
 * header and manifest are checked as soon as they are complete, each section as soon as it is
 * complete (its CRC, its indices, the cluster headers and plane sizes), so a prefix of the file is
 * a usable container as format.md section 8 describes. `finish(allowPrefix)` applies the checks
 * of a file that will not grow (format.md section 12, items 4 and 7).
 */
class Reader {
  constructor(path) {
    this.path = path;
    this.bytes = new Uint8Array(0); // the received bytes are bytes[0, received)
    this.received = 0;
    this.header = null;
    this.manifest = null;
    this.table = null; // [{name, start, end, crc32}] absolute file offsets
    this.next = 0; // index into table of the first section not yet complete
    this.present = new Map(); // name -> [start, end)
    this.decoded = new Map(); // name -> Uint8Array, the decoded bytes of an encoded section
    this.words = new Map(); // name -> Uint32Array cache
    this.clusterChecks = null; // with clustered buffers: expected exact bytes of each plane section
    this.growable = true; // false once a whole input is adopted (its bytes are used as they are)
  }

  fail(msg, hint = CORRUPT) { throw new LopError('container', this.path, msg, hint); }

  /** Append bytes (Uint8Array) and check what became complete. */
  push(chunk) {
    if (!chunk.length) return;
    const need = this.received + chunk.length;
    if (this.header && need > this.header.fileSize) {
      this.fail(`${need - this.header.fileSize} bytes of trailing data after the declared end (${this.header.fileSize} bytes)`);
    }
    if (need > this.bytes.length) {
      let cap = Math.max(need, 2 * this.bytes.length, 1 << 16);
      if (this.sectionsEnd !== undefined) cap = Math.max(need, Math.min(cap, this.sectionsEnd));
      this.grow(cap);
    }
    this.bytes.set(chunk, this.received);
    this.received = need;
    this.advance();
  }

  grow(cap) {
    let grown;
    try {
      grown = new Uint8Array(cap);
    } catch (exc) {
      if (exc instanceof RangeError) this.fail(`${cap} bytes do not fit in memory`, 'read a prefix, or a smaller file');
      throw exc;
    }
    grown.set(this.bytes.subarray(0, this.received));
    this.bytes = grown;
    this.words.clear();
  }

  /** Adopt `bytes` as the whole input (no copy); `advance` then checks it. */
  adopt(bytes) {
    this.bytes = bytes;
    this.received = bytes.length;
    this.growable = false;
  }

  advance() {
    if (!this.header) {
      if (this.received < HEADER_SIZE) return;
      this.readHeader();
      if (this.received > this.header.fileSize) {
        this.fail(`${this.received - this.header.fileSize} bytes of trailing data after the declared end (${this.header.fileSize} bytes)`);
      }
    }
    if (!this.manifest) {
      if (this.received < HEADER_SIZE + this.header.manifestSize) return;
      this.readManifest();
    }
    while (this.next < this.table.length && this.table[this.next].end <= this.received) this.completeSection(this.table[this.next++]);
    if (this.next === this.table.length && this.received > this.sectionsEnd) {
      this.fail(`sections end at byte ${this.sectionsEnd}, file size says ${this.header.fileSize}`);
    }
  }

  readHeader() {
    const b = this.bytes;
    if (b[0] !== 0x4C || b[1] !== 0x4F || b[2] !== 0x50 || b[3] !== 0x43) {
      const magic = String.fromCharCode(b[0], b[1], b[2], b[3]);
      this.fail(`bad magic ${JSON.stringify(magic)} (expected "LOPC")`, 'this is not a .lop container');
    }
    if (crc32(b.subarray(0, 28)) !== u32le(b, 28)) this.fail('header checksum mismatch');
    const major = b[4] | (b[5] << 8), minor = b[6] | (b[7] << 8);
    if (!READABLE_MAJORS.includes(major)) {
      this.fail(`container version ${major}.${minor} is not supported (this reader reads ${READABLE_MAJORS.map((v) => `${v}.x`).join(', ')})`,
        'use a lopcook release that reads this version, or cook the source again');
    }
    const headerSize = u32le(b, 8);
    if (headerSize !== HEADER_SIZE) this.fail(`header size ${headerSize} (expected ${HEADER_SIZE})`);
    const fileSize = u32le(b, 20) + 2 ** 32 * u32le(b, 24);
    this.header = {major, minor, headerSize, manifestSize: u32le(b, 12), manifestCrc: u32le(b, 16), fileSize};
  }

  readManifest() {
    const h = this.header;
    const mbytes = this.bytes.subarray(HEADER_SIZE, HEADER_SIZE + h.manifestSize);
    if (crc32(mbytes) !== h.manifestCrc) this.fail('manifest checksum mismatch');
    let manifest;
    const text = this.manifestText(mbytes);
    try {
      manifest = parseJson(asciiText(text));
    } catch (exc) {
      if (exc instanceof RangeError || /nested too deeply/.test(exc.message)) this.fail('manifest JSON is nested too deeply');
      this.fail(`manifest is not valid JSON (${String(exc.message).split(/\s+/).join(' ').slice(0, 160)})`);
    }
    validateManifest(manifest, this.path);
    const v = `${h.major}.${h.minor}`;
    if (h.major === 2 && isClustered(manifest)) this.fail(`container version ${v} must not hold clustered position buffers (they need 3.x)`);
    if (h.major === 2 && hasPlacements(manifest) && h.minor < 1) this.fail(`container version ${v} must not hold placements (they need 3.x)`);
    if (h.major < TANGENT_MAJOR && hasTangents(manifest)) this.fail(`container version ${v} must not hold tangents (they need 4.x)`);
    if (h.major < STREAM_MAJOR && (isStream(manifest) || manifest.sections.some((t) => has(t, 'encoding') || has(t, 'size')))) {
      this.fail(`container version ${v} must not hold the streaming layout or encoded sections (they need ${STREAM_MAJOR}.x)`);
    }
    const base = HEADER_SIZE + h.manifestSize;
    this.table = manifest.sections.map((s) => ({name: s.name, start: base + s.offset, end: base + s.offset + s.length, crc32: s.crc32,
      encoding: has(s, 'encoding') ? s.encoding : null, size: s.size}));
    this.layout = layoutOf(manifest);
    this.sectionsEnd = this.table.length ? this.table[this.table.length - 1].end : base;
    this.manifest = manifest;
    MANIFEST_SIZE.set(manifest, h.manifestSize);
    const whole = Math.min(this.sectionsEnd, h.fileSize);
    if (this.growable && this.bytes.length < whole && whole <= MAX_PREALLOCATION) {
      this.grow(whole); // size a stream's buffer once (a larger one grows as bytes arrive)
    }
  }

  /** The JSON text of the manifest's stored bytes: as they are, or decoded when the first byte is
   * 0x00 (a 4.x file's encoded manifest: its uint32 size, then raw DEFLATE; format.md 4). */
  manifestText(mbytes) {
    if (mbytes.length === 0 || mbytes[0] !== 0) return mbytes;
    const h = this.header;
    if (h.major < STREAM_MAJOR) this.fail(`container version ${h.major}.${h.minor} must not hold an encoded manifest (it needs ${STREAM_MAJOR}.x)`);
    try {
      if (mbytes.length < 5) throw new Error('an encoded manifest starts with 0x00 and its 4-byte size');
      const size = u32le(mbytes, 1), body = mbytes.subarray(5);
      if (size > DEFLATE_MAX_RATIO * body.length) throw new Error(`the encoded manifest claims ${size} bytes, more than ${DEFLATE_MAX_RATIO} times its ${body.length} stored bytes`);
      const {out, end} = inflateRaw(body, size, true);
      if (end !== body.length) throw new Error(`the deflate stream ends at byte ${end} of its ${body.length} bytes`);
      return out;
    } catch (exc) {
      if (exc instanceof LopError) throw exc;
      this.fail(`manifest (encoded): ${exc.message}`);
    }
  }

  completeSection(s) {
    const payload = this.bytes.subarray(s.start, s.end);
    if (crc32(payload) !== s.crc32) this.fail(`section '${s.name}' checksum mismatch`);
    if (s.encoding !== null) this.decoded.set(s.name, this.decode(s, payload));
    this.present.set(s.name, [s.start, s.end]);
    this.checkIndices(s.name);
    const st = this.layout.stages.find((x) => x.clusters === s.name);
    if (st) this.checkClusterHeaders(st);
    if (this.clusterChecks && this.clusterChecks.has(s.name) && s.end - s.start !== this.clusterChecks.get(s.name).bytes) {
      const {p, bits} = this.clusterChecks.get(s.name);
      this.fail(`refinement plane ${p} is not the ${bits} bits its buffers hold`);
    }
  }

  /** The decoded bytes of an encoded section (format.md 15), or LopError naming it. */
  decode(s, stored) {
    try {
      if (s.encoding === 'deflate') {
        const {out, end} = inflateRaw(stored, s.size, true);
        checkPadding(stored, end);
        return out;
      }
      const lod = this.indexLods().get(s.name);
      const {out: stream, end} = inflateRaw(stored, DEFLATE_MAX_RATIO * stored.length, false);
      checkPadding(stored, end);
      const idx = decodeTriangles(stream, lod.triangles, lod.vertices);
      const out = new Uint8Array(s.size);
      if (lod.index_width === 2) for (let j = 0; j < idx.length; j++) { out[2 * j] = idx[j] & 0xFF; out[2 * j + 1] = idx[j] >>> 8; }
      else for (let j = 0; j < idx.length; j++) for (let b = 0; b < 4; b++) out[4 * j + b] = (idx[j] >>> (8 * b)) & 0xFF;
      return out;
    } catch (exc) {
      if (exc instanceof LopError) throw exc;
      if (exc instanceof RangeError) this.fail(`section '${s.name}' (${s.encoding}): its decoded bytes do not fit in memory`, 'read a prefix, or a smaller file');
      this.fail(`section '${s.name}' (${s.encoding}): ${exc.message}`);
    }
  }

  /** index section name -> its LOD entry (what a meshopt-deflate section decodes with). */
  indexLods() {
    if (!this._indexLods) {
      this._indexLods = new Map();
      for (const part of this.manifest.parts) for (const e of part.lods) if (!this._indexLods.has(e.indices)) this._indexLods.set(e.indices, e);
    }
    return this._indexLods;
  }

  /** Bytes of a complete section (a view of the received bytes, or its decoded bytes), or null. */
  section(name) {
    const r = this.present.get(name);
    if (r === undefined) return null;
    return this.decoded.get(name) || this.bytes.subarray(r[0], r[1]);
  }

  sectionWords(name) {
    let w = this.words.get(name);
    if (w === undefined) {
      const b = this.section(name);
      if (b === null) return null;
      w = wordsOf(b);
      this.words.set(name, w);
    }
    return w;
  }

  /** Every index of every LOD naming this section is below its vertex count (format.md 12, item 9). */
  checkIndices(name) {
    if (!this.indexUsers) { // section name -> [[part, lod, entry], ...], built once
      this.indexUsers = new Map();
      this.manifest.parts.forEach((part, i) => part.lods.forEach((lod, k) => {
        if (!this.indexUsers.has(lod.indices)) this.indexUsers.set(lod.indices, []);
        this.indexUsers.get(lod.indices).push([i, k, lod]);
      }));
    }
    for (const [i, k, lod] of this.indexUsers.get(name) || []) {
      const data = this.section(name);
      const count = 3 * lod.triangles;
      let max = -1;
      if (lod.index_width === 2) for (let j = 0; j < count; j++) max = Math.max(max, data[2 * j] | (data[2 * j + 1] << 8));
      else for (let j = 0; j < count; j++) max = Math.max(max, u32le(data, 4 * j));
      if (max >= lod.vertices) this.fail(`part ${i} LOD ${k}: index ${max} is out of range for ${lod.vertices} vertices`);
    }
  }

  /** A stage's cluster headers sound, cluster_p_words / cluster_plane_bits as the headers give, and
   * in the default layout the exact size every plane must have (lopcook.lop.container._check_cluster_sizes;
   * the streaming layout's plane sizes follow from the manifest, which validateManifest checked). */
  checkClusterHeaders(st) {
    const pos = this.manifest.positions;
    const head = this.sectionWords(st.clusters);
    const planeBits = new Map();
    for (let p = 2; p <= pos.max_level; p++) planeBits.set(p, 0);
    if (!this.clusters) this.clusters = new Map();
    for (const [i, k, lod] of st.buffers) {
      {
        const vid = lod.vertex_id;
        if (!has(lod, 'cluster_size')) {
          for (const p of planeBits.keys()) planeBits.set(p, planeBits.get(p) + 3 * vid[p - 1]);
          continue;
        }
        const [off, count] = lod.cluster_words;
        let cl;
        try {
          cl = clustersFromHeader(head.subarray(Math.min(off, head.length), Math.min(off + count, head.length)), vid, lod.cluster_size);
        } catch (exc) {
          this.fail(`part ${i} LOD ${k}: cluster headers: ${exc.message}`);
        }
        for (let b = 1; b <= LEVELS; b++) {
          if (lod.cluster_p_words[b - 1] !== clusterWordsAt(cl, b)) {
            this.fail(`part ${i} LOD ${k}: cluster_p_words (mandatory_words count ${lod.mandatory_words[1]}) do not match its clusters (${clusterWordsAt(cl, 1)} words at level 1)`);
          }
        }
        for (let p = 2; p <= LEVELS; p++) {
          if (lod.cluster_plane_bits[p - 2] !== clusterPlaneBits(cl, p)) this.fail(`part ${i} LOD ${k}: cluster_plane_bits do not match its clusters`);
        }
        for (const p of planeBits.keys()) planeBits.set(p, planeBits.get(p) + clusterPlaneBits(cl, p));
        this.clusters.set(`${i}/${k}`, cl);
      }
    }
    if (this.layout.stream) return;
    this.clusterChecks = new Map();
    for (const [p, bits] of planeBits) this.clusterChecks.set(pos.planes[String(p)], {p, bits, bytes: 4 * Math.ceil(bits / 32)});
    for (const [name, want] of this.clusterChecks) { // planes already complete
      const r = this.present.get(name);
      if (r !== undefined && r[1] - r[0] !== want.bytes) this.fail(`refinement plane ${want.p} is not the ${want.bits} bits its buffers hold`);
    }
  }

  /** Every stage's level (format.md 8, 14.4; one stage in the default layout), [0] before the manifest. */
  stageLevels() {
    if (!this.manifest) return [0];
    return this.layout.stages.map((st) => stageLevel(st, this.present, this.layout.maxLevel));
  }

  /** The highest level every buffer can be decoded at, 0 when some buffer cannot (format.md 8); in
   * the streaming layout the lowest stage level. */
  availableLevel() {
    return Math.min(...this.stageLevels());
  }

  /** The checks of a file that will not grow: not truncated (unless `allowPrefix`), and usable. */
  finish(allowPrefix) {
    if (this.received < HEADER_SIZE) this.fail(`file is ${this.received} bytes, shorter than the ${HEADER_SIZE}-byte header`);
    const truncated = this.received < this.header.fileSize;
    if (truncated && !allowPrefix) this.fail(`file is truncated: ${this.received} of ${this.header.fileSize} bytes`, INCOMPLETE);
    if (!this.manifest) this.fail('manifest is truncated');
    if (!truncated && this.next < this.table.length) this.fail(`section '${this.table[this.next].name}' runs past the end of the file`);
    if (this.sectionsEnd !== this.header.fileSize) this.fail(`sections end at byte ${this.sectionsEnd}, file size says ${this.header.fileSize}`);
    if (this.stageLevels()[0] < 1) {
      this.fail(this.layout.stream ? "the file ends before the first stage's mandatory position bits" : 'the file ends before the mandatory position bits', INCOMPLETE);
    }
  }
}

/**
 * Parse and check a container (lopcook.lop.container.from_bytes): `bytes` a Uint8Array,
 * ArrayBuffer or Node Buffer. With `allowPrefix` a file cut inside the position planes is
 * accepted and `availableLevel` says which levels it holds (format.md section 8). Throws LopError.
 */
export function parse(bytes, {path = null, allowPrefix = false} = {}) {
  const data = bytes instanceof Uint8Array ? bytes : new Uint8Array(bytes);
  const r = new Reader(path);
  r.adopt(data);
  if (data.length < HEADER_SIZE) r.fail(`file is ${data.length} bytes, shorter than the ${HEADER_SIZE}-byte header`);
  r.readHeader();
  if (data.length > r.header.fileSize) r.fail(`${data.length - r.header.fileSize} bytes of trailing data after the declared end (${r.header.fileSize} bytes)`);
  if (data.length < r.header.fileSize && !allowPrefix) r.fail(`file is truncated: ${data.length} of ${r.header.fileSize} bytes`, INCOMPLETE);
  if (HEADER_SIZE + r.header.manifestSize > data.length) r.fail('manifest is truncated');
  r.advance();
  r.finish(allowPrefix);
  return new LopContainer(r);
}

// ============================================================================================
// decoding

/** Read the `b`-bit field (b <= 32) at bit offset `o` of `words`, least significant bit first; a
 * field may span two words (format.md 6.3). */
function readField(words, o, b) {
  if (b === 0) return 0;
  const w = Math.floor(o / 32), s = o % 32;
  let v = words[w] >>> s;
  if (s + b > 32) v |= words[w + 1] << (32 - s);
  return b === 32 ? v >>> 0 : (v & ((1 << b) - 1)) >>> 0;
}

function writeField(words, o, v, b) {
  if (b === 0) return;
  const w = Math.floor(o / 32), s = o % 32;
  words[w] |= v << s;
  if (s + b > 32) words[w + 1] |= v >>> (32 - s);
}

/** The float32 block centre of a field v of b bits on a grid (format.md 6.7): float32(origin) +
 * float32(float32(c) * half32), c = (2 v + 1) << (24 - b), half32 = float32(extent / 2^25). */
export function reconstruct(v, b, origin32, half32) {
  const c = (2 * v + 1) * 2 ** (LEVELS - b);
  return f32(origin32 + f32(f32(c) * half32));
}

/** Octahedral decode of codes (cu, cv) of b bits (format.md 7.3): the unnormalised float32 vector,
 * written to out[at..at+2]. */
export function octDecode(cu, cv, b, out, at) {
  const h = 2 ** (b - 1);
  const r = f32(1 / (h - 1));
  const px = Math.max(f32((cu - h) * r), -1), py = Math.max(f32((cv - h) * r), -1);
  const ax = Math.abs(px), ay = Math.abs(py);
  const z = f32(f32(1 - ax) - ay);
  if (z < 0) {
    out[at] = f32(f32(1 - ay) * (px >= 0 ? 1 : -1));
    out[at + 1] = f32(f32(1 - ax) * (py >= 0 ? 1 : -1));
  } else {
    out[at] = px;
    out[at + 1] = py;
  }
  out[at + 2] = z;
}

/**
 * A parsed container: its `manifest` (checked), `header` ({major, minor, manifestSize,
 * fileSize}), `availableLevel` (the highest level every buffer can be decoded at), the section
 * bytes by name (`section`), and the decoders of every buffer. Buffers are (part, lod) pairs; a
 * placement's buffers are its owner's (`owner`), decoded on the placement's grid and mapped by its
 * transform where positions are asked for.
 */
export class LopContainer {
  constructor(reader) {
    this._r = reader;
    this._planeBits = new Map();
    this._planeOffsets = new Map();
    this._clusters = new Map();
    this._values = new Map();
  }

  get path() { return this._r.path; }
  get header() { return this._r.header; }
  get manifest() { return this._r.manifest; }
  /** The highest per-buffer level every buffer can be decoded at, 0 before the first renderable
   * state (in the streaming layout: while a stage has not arrived; `levelOf` gives each buffer's). */
  get availableLevel() { return this._r.availableLevel(); }
  /** Every stage's level in the bytes received (format.md 14.4; one stage in the default layout). */
  get stageLevels() { return this._r.stageLevels(); }
  /** The stages (layoutOf): which buffers each holds and where their position bits lie. */
  get layout() { return this._r.layout; }
  /** Whether the container is in the streaming layout (format.md 14). */
  get stream() { return this._r.layout.stream; }

  /** The stage of buffer (part, lod) (a part's coarsest when its chain is shorter). */
  stageOf(part, lod) {
    const lods = this.manifest.parts[part].lods;
    return this._r.layout.stageOf.get(`${part}/${Math.min(lod, lods.length - 1)}`);
  }

  /** The highest level buffer (part, lod) decodes at in the bytes received: its stage's level; 0
   * when its sections have not arrived. */
  levelOf(part, lod) { return this.stageLevels[this.stageOf(part, lod)]; }
  /** Bytes of the file received (the whole file for `parse`). */
  get bytesReceived() { return this._r.received; }
  /** The file's size as its header gives it. */
  get fileSize() { return this._r.header.fileSize; }
  /** Whether every section has arrived. */
  get complete() { return !!this._r.table && this._r.next === this._r.table.length; }

  /**
   * The bytes of the section called `name` (a Uint8Array view, padding included); LopError when it
   * has not arrived. Every other method reads sections through this one, so a later layout (per-LOD
   * position sections, compressed sections) changes only what it returns.
   */
  section(name) {
    const b = this._r.section(name);
    if (b === null) throw new LopError('container', this.path, `section '${name}' is missing from the container (the file holds levels up to ${this.availableLevel})`);
    return b;
  }

  /** Whether the section called `name` has arrived. */
  hasSection(name) { return this._r.present.has(name); }

  /** The section's bytes as little-endian uint32 words (cached). */
  sectionWords(name) {
    this.section(name);
    return this._r.sectionWords(name);
  }

  /** The LOD entry of buffer (part, lod); LopError ("usage") when it does not exist. */
  lodEntry(part, lod) {
    const parts = this.manifest.parts;
    if (!(Number.isInteger(part) && part >= 0 && part < parts.length)) throw new LopError('usage', this.path, `part ${part} does not exist (0..${parts.length - 1})`);
    const lods = parts[part].lods;
    if (!(Number.isInteger(lod) && lod >= 0 && lod < lods.length)) throw new LopError('usage', this.path, `part ${part} has no LOD ${lod} (0..${lods.length - 1})`);
    return lods[lod];
  }

  /** The part whose bytes hold part `part`'s buffers: itself, or a placement's `placement.of`. */
  owner(part) {
    const pl = this.manifest.parts[part].placement;
    return isDict(pl) ? pl.of : part;
  }

  /** `{origin: [x, y, z], extent}` of the grid part `part`'s buffers are quantised on (metres). */
  partGrid(part) {
    const g = this.manifest.parts[part].grid || this.manifest.grid;
    return {origin: g.origin, extent: g.extent};
  }

  /** Part `part`'s 3x4 row-major local-to-world transform (12 numbers), null on the scene grid. */
  placementTransform(part) {
    const pl = this.manifest.parts[part].placement;
    return isDict(pl) ? pl.transform : null;
  }

  /** The per-buffer level part `part` decodes its buffer at when the scene asks for `level`:
   * clamp(level + level_shift, 1, 24) for a placement (format.md 6.8), `level` otherwise. */
  partLevel(part, level) {
    const pl = this.manifest.parts[part].placement;
    return isDict(pl) ? Math.min(Math.max(level + pl.level_shift, 1), LEVELS) : level;
  }

  /** The clusters of a clustered buffer (from its stored headers), null when unclustered. */
  clusters(part, lod) {
    const o = this.owner(part);
    const e = this.lodEntry(o, lod);
    if (!has(e, 'cluster_size')) return null;
    const key = `${o}/${lod}`;
    let cl = this._clusters.get(key) || (this._r.clusters && this._r.clusters.get(key));
    if (!cl) {
      const head = this.sectionWords(this.layout.stages[this.stageOf(o, lod)].clusters);
      const [off, count] = e.cluster_words;
      if (off + count > head.length) throw new LopError('container', this.path, 'cluster header words out of range');
      cl = clustersFromHeader(head.subarray(off, off + count), e.vertex_id, e.cluster_size);
    }
    this._clusters.set(key, cl);
    return cl;
  }

  /** Where buffer (owner part, lod)'s slice of plane p starts in its stage's plane p (bits; the
   * stage's earlier buffers in manifest order). */
  planeSlice(part, lod, p) {
    const si = this.stageOf(this.owner(part), lod);
    const key = `${si}/${p}`;
    if (!this._planeOffsets.has(key)) {
      const offsets = new Map();
      let start = 0;
      for (const [i, k, e] of this.layout.stages[si].buffers) {
        offsets.set(`${i}/${k}`, start);
        start += sliceBits(e, p);
      }
      this._planeOffsets.set(key, offsets);
    }
    return this._planeOffsets.get(key).get(`${this.owner(part)}/${lod}`);
  }

  /** The bytes of plane p of buffer (part, lod)'s stage (its section, or its part of the stage's
   * deferred section); an empty array when the plane holds no bits. */
  planeBytes(part, lod, p) {
    const st = this.layout.stages[this.stageOf(this.owner(part), lod)];
    const loc = planeLocation(st, p, this.layout.maxLevel);
    if (loc === null) return new Uint8Array(0);
    return this.section(loc[0]).subarray(loc[1], loc[1] + planeBytes(st.bits.get(p)));
  }

  _checkLevel(level, part, lod) {
    if (!(Number.isInteger(level) && level >= 1 && level <= LEVELS)) throw new LopError('usage', this.path, `level ${level} is outside [1, 24]`);
    const have = this.levelOf(part, lod);
    if (level > have && !this.stream) {
      throw new LopError('usage', this.path, `level ${level} is not in this file (it holds levels up to ${have})`, 'use a lower --level or the complete file');
    }
    if (level > have) {
      throw new LopError('usage', this.path, `level ${level} of part ${part} LOD ${lod} is not in this file (${have ? `its stage holds levels up to ${have}` : 'its stage has not arrived'})`,
        'use a lower --level, a coarser --lod or the complete file');
    }
  }

  /**
   * Top bits of every vertex of buffer (part, lod) at per-buffer level B (binned order;
   * lopcook.lop.reader.top_values): `{values: Uint32Array(3 n) x, y, z per vertex, widths:
   * Uint8Array(n) max(bin, B)}`: the mandatory bits, then one bit per plane 2..B for the vertices
   * below that plane. Results are cached per buffer and extended plane by plane, so asking for
   * B + 1 after B reads one plane.
   */
  topValues(part, lod, level) {
    this.lodEntry(part, lod);
    this._checkLevel(level, part, lod);
    const o = this.owner(part);
    const e = this.lodEntry(o, lod);
    const key = `${o}/${lod}`;
    let st = this._values.get(key);
    if (!st || st.level > level) {
      st = {level: 1, values: this._mandatoryValues(o, lod, e)};
      this._values.set(key, st);
    }
    const cl = this.clusters(o, lod);
    for (let p = st.level + 1; p <= level; p++) this._addPlane(o, lod, e, cl, st.values, p);
    st.level = level;
    const n = e.vertices, vid = e.vertex_id;
    const widths = new Uint8Array(n);
    for (let k = 1; k <= LEVELS; k++) widths.fill(Math.max(k, level), vid[k - 1], vid[k]);
    return {values: st.values.slice(), widths};
  }

  _mandatoryValues(o, lod, e) {
    const all = this.sectionWords(this.layout.stages[this.stageOf(o, lod)].mandatory);
    const [off, count] = e.mandatory_words;
    if (off + count > all.length) throw new LopError('container', this.path, 'mandatory position words out of range');
    const words = all.subarray(off, off + count);
    const vid = e.vertex_id;
    const values = new Uint32Array(3 * e.vertices);
    const cl = this.clusters(o, lod);
    let bit = 0;
    if (cl === null) {
      for (let k = 1; k <= LEVELS; k++) {
        for (let j = vid[k - 1]; j < vid[k]; j++, bit += 3 * k) {
          values[3 * j] = readField(words, bit, k);
          values[3 * j + 1] = readField(words, bit + k, k);
          values[3 * j + 2] = readField(words, bit + 2 * k, k);
        }
      }
      return values;
    }
    const end = 32 * words.length;
    for (let c = 0; c < cl.nClusters; c++) {
      const b = cl.m[c];
      for (let j = cl.start[c]; j < cl.start[c] + cl.count[c]; j++) {
        for (let t = 0; t < 3; t++) {
          const kt = cl.k[3 * c + t], at = cl.anchor[3 * c + t];
          const w = Math.max(0, b - kt);
          if (bit + w > end) throw new LopError('container', this.path, 'mandatory position words out of range');
          values[3 * j + t] = b <= kt ? Math.floor(at / 2 ** (kt - b)) : at * 2 ** (b - kt) + readField(words, bit, w);
          bit += w;
        }
      }
    }
    return values;
  }

  _addPlane(o, lod, e, cl, values, p) {
    const g = e.vertex_id[p - 1];
    if (g === 0) return;
    const plane = this.planeBytes(o, lod, p);
    let bit = this.planeSlice(o, lod, p);
    const stored = cl === null ? 3 * g : e.cluster_plane_bits[p - 2];
    if (bit + stored > 8 * plane.length) throw new LopError('container', this.path, `plane ${p} is shorter than its buffers`);
    if (cl === null) {
      for (let i = 0; i < 3 * g; i++, bit++) values[i] = ((values[i] << 1) | ((plane[bit >>> 3] >>> (bit & 7)) & 1)) >>> 0;
      return;
    }
    for (let c = 0; c < cl.nClusters && cl.start[c] < g; c++) {
      for (let j = cl.start[c]; j < cl.start[c] + cl.count[c]; j++) {
        for (let t = 0; t < 3; t++) {
          const kt = cl.k[3 * c + t];
          let b;
          if (kt < p) { b = (plane[bit >>> 3] >>> (bit & 7)) & 1; bit++; } else b = Math.floor(cl.anchor[3 * c + t] / 2 ** (kt - p)) & 1;
          values[3 * j + t] = ((values[3 * j + t] << 1) | b) >>> 0;
        }
      }
    }
  }

  /**
   * The packed buffer P of buffer (part, lod) at per-buffer level B, as a renderer uploads it
   * (format.md 6.3; lopcook.lop.reader.gpu_buffer): `{words: Uint32Array, vertexId, bitId:
   * Float64Array(25), level}`. For a clustered buffer this is the unclustered P of the same vertices.
   */
  gpuBuffer(part, lod, level) {
    const {values} = this.topValues(part, lod, level);
    const vid = this.lodEntry(this.owner(part), lod).vertex_id;
    const bid = bitId(vid, level);
    const words = new Uint32Array(Math.ceil(bid[LEVELS] / 32));
    let bit = 0;
    for (let k = 1; k <= LEVELS; k++) {
      const b = Math.max(k, level);
      for (let j = vid[k - 1]; j < vid[k]; j++) {
        for (let t = 0; t < 3; t++, bit += b) writeField(words, bit, values[3 * j + t], b);
      }
    }
    return {words, vertexId: vid, bitId: bid, level};
  }

  /**
   * The clustered P of a clustered buffer at level B with its GPU cluster records (format.md 6.9;
   * lopcook.lop.reader.clustered_gpu_buffer): `{words: Uint32Array, records: Uint32Array(4 n_c)
   * (a_t | k_t << 24 for x, y, z, then ClusterBit[c]), clusters, level}`. LopError ("usage") when
   * the buffer is not clustered.
   */
  clusteredGpuBuffer(part, lod, level) {
    const cl = this.clusters(part, lod);
    if (cl === null) throw new LopError('usage', this.path, `part ${part} LOD ${lod} is not clustered`, 'cook with --clusters N');
    const {values} = this.topValues(part, lod, level);
    const cb = clusterBit(cl, level);
    const words = new Uint32Array(Math.max(1, Math.ceil(cb[cl.nClusters] / 32)));
    const records = new Uint32Array(4 * cl.nClusters);
    for (let c = 0; c < cl.nClusters; c++) {
      if (cb[c] > 0xFFFFFFFF) throw new LopError('container', this.path, 'cluster bit offsets exceed 32 bits (a buffer over 4 Gbit)');
      const b = Math.max(cl.m[c], level);
      const w = [0, 1, 2].map((t) => Math.max(0, b - cl.k[3 * c + t]));
      for (let t = 0; t < 3; t++) records[4 * c + t] = (cl.anchor[3 * c + t] | (cl.k[3 * c + t] << 24)) >>> 0;
      records[4 * c + 3] = cb[c];
      let bit = cb[c];
      for (let j = cl.start[c]; j < cl.start[c] + cl.count[c]; j++) {
        for (let t = 0; t < 3; t++) {
          writeField(words, bit, w[t] ? values[3 * j + t] % 2 ** w[t] : 0, w[t]);
          bit += w[t];
        }
      }
    }
    return {words, records, clusters: cl, level};
  }

  /**
   * Decode buffer (part, lod) at level B (lopcook.lop.reader.decode_positions): `{grid:
   * Uint32Array(3 n) 24-bit integers with the dropped bits zero, widths: Uint8Array(n), positions:
   * Float32Array(3 n) metres}`, the float32 decode of format.md 6.7 on the part's grid, mapped by
   * the placement's transform in the float32 order of format.md 6.8.
   */
  decodePositions(part, lod, level) {
    const {values, widths} = this.topValues(part, lod, level);
    const n = widths.length;
    const {origin, extent} = this.partGrid(part);
    const o32 = origin.map((v) => f32(v));
    const half = f32(extent / 2 ** 25);
    const grid = new Uint32Array(3 * n);
    const positions = new Float32Array(3 * n);
    for (let j = 0; j < n; j++) {
      const b = widths[j];
      for (let t = 0; t < 3; t++) {
        const v = values[3 * j + t];
        grid[3 * j + t] = v * 2 ** (LEVELS - b);
        positions[3 * j + t] = reconstruct(v, b, o32[t], half);
      }
    }
    const tf = this.placementTransform(part);
    if (tf !== null) toWorld(positions, tf);
    return {grid, widths, positions};
  }

  /** The triangles of buffer (part, lod): Uint16Array or Uint32Array of 3 m indices (binned order). */
  indices(part, lod) {
    const e = this.lodEntry(part, lod);
    const data = this.section(e.indices);
    const count = 3 * e.triangles;
    if (count * e.index_width > data.length) throw new LopError('container', this.path, `part ${part} LOD ${lod}: index section is too short`);
    const out = e.index_width === 2 ? new Uint16Array(count) : new Uint32Array(count);
    for (let j = 0; j < count; j++) out[j] = e.index_width === 2 ? data[2 * j] | (data[2 * j + 1] << 8) : u32le(data, 4 * j);
    return out;
  }

  /**
   * The decoded attribute record of buffer (part, lod) (format.md 7.2-7.4; attributes.decode_record):
   * `{normals: Float32Array(3 n) unnormalised octahedral, uvs: Float32Array(2 n), colors:
   * Float32Array(4 n) linear RGBA, tangents: Float32Array(4 n) (x, y, z unnormalised, w = +-1)}`,
   * each null when absent, bit-exact with the Python reference and the shaders.
   */
  attributes(part, lod) {
    const e = this.lodEntry(part, lod);
    const n = e.vertices;
    const ab = e.attribute_bits;
    const out = {normals: null, uvs: null, colors: null, tangents: null};
    if (e.attributes == null) return out;
    const words = this.sectionWords(e.attributes);
    const S = e.record_bits;
    if (words.length < Math.ceil((n * S) / 32)) throw new LopError('container', this.path, `part ${part} LOD ${lod}: attributes section is too short`);
    const last = words.length - 1;
    const field = (o, b) => { // the shaders' read: second word index clamped to the last
      const w = Math.floor(o / 32), s = o % 32;
      const hi = s === 0 ? 0 : words[Math.min(w + 1, last)] << (32 - s);
      return ((words[w] >>> s) | hi) & ((1 << b) - 1);
    };
    const bn = ab.normals || 0, bu = ab.uvs || 0, bc = ab.colors || 0, bt = ab.tangents || 0;
    if (bn) out.normals = new Float32Array(3 * n);
    if (bu) out.uvs = new Float32Array(2 * n);
    if (bc) out.colors = new Float32Array(4 * n);
    if (bt) out.tangents = new Float32Array(4 * n);
    const lo = bu ? e.uv_range[0].map((v) => f32(v)) : null;
    const step = bu ? e.uv_step.map((v) => f32(v)) : null;
    const rc = bc ? f32(1 / (2 ** bc - 1)) : 0;
    for (let j = 0; j < n; j++) {
      let o = j * S;
      if (bn) { octDecode(field(o, bn), field(o + bn, bn), bn, out.normals, 3 * j); o += 2 * bn; }
      if (bu) {
        for (let c = 0; c < 2; c++) out.uvs[2 * j + c] = f32(lo[c] + f32(field(o + c * bu, bu) * step[c]));
        o += 2 * bu;
      }
      if (bc) {
        for (let c = 0; c < 4; c++) out.colors[4 * j + c] = f32(field(o + c * bc, bc) * rc);
        o += 4 * bc;
      }
      if (bt) {
        octDecode(field(o, bt), field(o + bt, bt), bt, out.tangents, 4 * j);
        out.tangents[4 * j + 3] = field(o + 2 * bt, 1) ? -1 : 1;
      }
    }
    return out;
  }

  /** Part `part`'s normals (Float32Array(3 n), mesh space) in world space: unchanged on the scene
   * grid; for a placement mapped by A^-T (float64 of its float32 A) and normalised (format.md 6.8). */
  worldNormals(part, normals) {
    const tf = this.placementTransform(part);
    if (tf === null || normals === null) return normals;
    const [a] = splitTransform(tf);
    const inv = inverse3(a);
    const out = new Float32Array(normals.length);
    for (let j = 0; j < normals.length; j += 3) {
      const x = normals[j], y = normals[j + 1], z = normals[j + 2];
      const v = [0, 1, 2].map((c) => x * inv[0][c] + y * inv[1][c] + z * inv[2][c]); // (A^-T n) = n^T A^-1
      const len = Math.hypot(v[0], v[1], v[2]) || 1;
      for (let c = 0; c < 3; c++) out[j + c] = v[c] / len;
    }
    return out;
  }

  /** Part `part`'s tangents (Float32Array(4 n)) in world space: xyz mapped by A (not its inverse
   * transpose) and normalised, w times sign(det A); unchanged on the scene grid. (format.md 7.6) */
  worldTangents(part, tangents) {
    const tf = this.placementTransform(part);
    if (tf === null || tangents === null) return tangents;
    const [a] = splitTransform(tf);
    const sign = det3(a) < 0 ? -1 : 1;
    const out = new Float32Array(tangents.length);
    for (let j = 0; j < tangents.length; j += 4) {
      const v = a.map((row) => row[0] * tangents[j] + row[1] * tangents[j + 1] + row[2] * tangents[j + 2]);
      const len = Math.hypot(v[0], v[1], v[2]) || 1;
      for (let c = 0; c < 3; c++) out[j + c] = v[c] / len;
      out[j + 3] = tangents[j + 3] * sign;
    }
    return out;
  }
}

function inverse3(a) {
  const d = det3(a);
  const m = (r0, c0, r1, c1) => a[r0][c0] * a[r1][c1] - a[r0][c1] * a[r1][c0];
  return [
    [m(1, 1, 2, 2) / d, -m(0, 1, 2, 2) / d, m(0, 1, 1, 2) / d],
    [-m(1, 0, 2, 2) / d, m(0, 0, 2, 2) / d, -m(0, 0, 1, 2) / d],
    [m(1, 0, 2, 1) / d, -m(0, 0, 2, 1) / d, m(0, 0, 1, 1) / d],
  ];
}

/** Map local float32 positions (Float32Array(3 n), in place) to world: w_i = ((a_i0 p_0 + a_i1 p_1)
 * + a_i2 p_2) + t_i, every product and sum rounded to float32 (lopcook.lop.placement.to_world). */
export function toWorld(positions, tf) {
  const [a, t] = splitTransform(tf);
  for (let j = 0; j < positions.length; j += 3) {
    const p0 = positions[j], p1 = positions[j + 1], p2 = positions[j + 2];
    for (let i = 0; i < 3; i++) {
      const s = f32(f32(f32(a[i][0] * p0) + f32(a[i][1] * p1)) + f32(a[i][2] * p2));
      positions[j + i] = f32(s + t[i]);
    }
  }
  return positions;
}

// ============================================================================================
// streaming: bytes as they arrive, a callback at each better renderable state

/**
 * The names of the sections a renderer needs for `level` (format.md section 8): every non-position
 * section (indices, attribute records, hierarchies), the cluster anchors, the mandatory bits and
 * planes 2..level. In the streaming layout (section 14) `level` is a number (every stage at that
 * level) or an array of one level per stage (0: the stage is not wanted): each wanted stage's
 * sections, its planes up to min(level, L_s) and, above L_s, its deferred planes.
 */
export function sectionsForLevel(manifest, level) {
  if (isStream(manifest)) {
    const lay = layoutOf(manifest);
    const want = new Set();
    lay.stages.forEach((st, s) => {
      const b = Array.isArray(level) ? (level[s] || 0) : level;
      if (b < 1) return;
      for (const name of [...st.required, ...(st.clusters ? [st.clusters] : []), st.mandatory]) want.add(name);
      for (const [p, name] of st.planes) if (p <= b) want.add(name);
      if (b > st.level && st.deferred) want.add(st.deferred);
    });
    return want;
  }
  const pos = manifest.positions;
  const want = new Set(manifest.sections.filter((s) => !s.name.startsWith('positions/')).map((s) => s.name));
  if (has(pos, 'clusters')) want.add(pos.clusters);
  want.add(pos.mandatory);
  for (let p = 2; p <= Math.min(level, pos.max_level); p++) want.add(pos.planes[String(p)]);
  return want;
}

/**
 * Byte ranges `[[start, end), ...]` (absolute file offsets, merged, ascending) that hold the
 * sections needed for `level` and lie at or after byte `have` (what a reader already holds): what
 * to request with HTTP range requests so that nothing is fetched twice.
 */
export function planRanges(manifest, level, have = 0) {
  const base = HEADER_SIZE + manifestLength(manifest);
  const want = sectionsForLevel(manifest, level);
  const out = [];
  for (const s of manifest.sections) {
    if (!want.has(s.name) || s.length === 0) continue;
    const start = Math.max(base + s.offset, have), end = base + s.offset + s.length;
    if (start >= end) continue;
    if (out.length && out[out.length - 1][1] >= start) out[out.length - 1][1] = Math.max(out[out.length - 1][1], end);
    else out.push([start, end]);
  }
  return out;
}

const MANIFEST_SIZE = new WeakMap();
function manifestLength(manifest) {
  const n = MANIFEST_SIZE.get(manifest);
  if (n === undefined) throw new LopError('usage', null, 'planRanges needs the manifest of a container read by this module');
  return n;
}

/**
 * A container read as its bytes arrive. `push(chunk)` appends a Uint8Array; `onUpdate(state)` is
 * called each time the renderable state improves:
 *
 *   state = {event, container, level, stage, stageLevels, bytes, fileSize}
 *   event: 'manifest'   the header and manifest arrived (nothing renderable yet; sizes and the
 *                       section table are known: plan ranges, allocate)
 *          'renderable' the first renderable state: in the default layout every index and
 *                       attribute section, the cluster anchors and the mandatory bits (level >= 1);
 *                       in the streaming layout stage 0: every part's coarsest LOD
 *          'lod'        (streaming layout) stage `stage` became renderable: the next finer LOD of
 *                       every part with one (container.levelOf gives each buffer's level)
 *          'plane'      a higher level: the planes up to `level` arrived (in the streaming layout,
 *                       of stage `stage`)
 *          'complete'   the whole file arrived and passed every check (`end()`)
 *
 * `level` is the highest per-buffer level every buffer can be decoded at (container.availableLevel)
 * in the default layout, the level of stage `stage` in the streaming layout; `stageLevels` every
 * stage's level (one entry in the default layout). In the default layout a finer LOD never arrives
 * separately (every LOD's sections come before the positions): `stage` is 0. A streaming file gives
 * one event per stage that improved, coarse to fine. A corrupt byte throws LopError from `push` as
 * soon as the section holding it is complete; what was renderable before stays valid. Bytes are
 * kept once (one buffer sized by the manifest), so nothing needs to be fetched twice.
 */
export class LopStream {
  constructor({path = null, onUpdate = null} = {}) {
    this._r = new Reader(path);
    this._c = new LopContainer(this._r);
    this._onUpdate = onUpdate;
    this._level = 0;
    this._stages = null; // the stage levels last reported (streaming layout)
    this._manifest = false;
    this._done = false;
  }

  /** The container (its manifest and sections so far); null before the manifest arrived. */
  get container() { return this._r.manifest ? this._c : null; }
  /** Bytes received so far. */
  get bytes() { return this._r.received; }
  /** The highest level every buffer can be decoded at now (0 before the first renderable state). */
  get level() { return this._r.availableLevel(); }

  push(chunk) {
    if (this._done) throw new LopError('usage', this._r.path, 'bytes pushed after end()');
    this._r.push(chunk instanceof Uint8Array ? chunk : new Uint8Array(chunk));
    this._report();
  }

  /** The stream ended: the file must be complete (or, with `allowPrefix`, a usable prefix). */
  end({allowPrefix = false} = {}) {
    this._r.finish(allowPrefix);
    this._report();
    this._done = true;
    if (this._r.received === this._r.header.fileSize) this._emit('complete');
    return this._c;
  }

  _report() {
    const r = this._r;
    if (r.manifest && !this._manifest) {
      this._manifest = true;
      this._emit('manifest');
    }
    if (!r.manifest) return;
    if (r.layout.stream) {
      const now = r.stageLevels();
      if (this._stages === null) this._stages = now.map(() => 0);
      if (now[0] < 1) return; // nothing drawable before stage 0
      now.forEach((level, s) => {
        if (level <= this._stages[s]) return;
        const first = this._stages[s] === 0;
        this._stages[s] = level;
        this._emit(s === 0 && first ? 'renderable' : first ? 'lod' : 'plane', s, level);
      });
      return;
    }
    const level = r.availableLevel();
    if (level > this._level) {
      const first = this._level === 0;
      this._level = level;
      this._emit(first ? 'renderable' : 'plane');
    }
  }

  _emit(event, stage = 0, stageLevel = null) {
    if (this._onUpdate) {
      const r = this._r;
      const level = stageLevel === null ? r.availableLevel() : stageLevel;
      this._onUpdate({event, container: this._c, level, stage, stageLevels: r.manifest ? r.stageLevels() : [0],
        bytes: r.received, fileSize: r.header.fileSize});
    }
  }
}

async function pump(readable, stream, signal) {
  const reader = readable.getReader();
  try {
    for (;;) {
      if (signal && signal.aborted) throw new LopError('usage', stream._r.path, 'loading was aborted');
      const {done, value} = await reader.read();
      if (done) break;
      stream.push(value);
    }
  } finally {
    reader.releaseLock();
  }
}

/**
 * Load a container from `source` — a URL (string or URL, fetched with `fetch`), a Response, a
 * ReadableStream of Uint8Array chunks, or the bytes — calling `onUpdate(state)` at each better
 * renderable state (LopStream). Resolves with the complete container; rejects with LopError.
 */
export async function load(source, {onUpdate = null, path = null, signal = undefined, fetch: fetchFn = globalThis.fetch} = {}) {
  const name = path || (typeof source === 'string' || source instanceof URL ? String(source) : null);
  const stream = new LopStream({path: name, onUpdate});
  let body = source;
  if (typeof source === 'string' || source instanceof URL) {
    const res = await fetchFn(source, {signal});
    if (!res.ok) throw new LopError('container', name, `HTTP ${res.status} ${res.statusText}`, 'check the URL');
    body = res;
  }
  if (typeof Response !== 'undefined' && body instanceof Response) body = body.body;
  if (body && typeof body.getReader === 'function') await pump(body, stream, signal);
  else stream.push(body instanceof Uint8Array ? body : new Uint8Array(body));
  return stream.end();
}

/**
 * A container read with HTTP range requests planned from its manifest (format.md section 8):
 * `await r.open()` fetches the header and manifest (one request of `firstBytes`, a second if the
 * manifest is longer); `await r.fetchLevel(B)` fetches what level B needs beyond what is held
 * (`planRanges`), so nothing is fetched twice. A server that ignores Range and sends the whole
 * file (status 200) is read as a stream. `container`, `level`, `bytes` as LopStream's.
 */
export class LopRangeReader {
  constructor(url, {onUpdate = null, fetch: fetchFn = globalThis.fetch, firstBytes = 65536} = {}) {
    this.url = url;
    this._fetch = fetchFn;
    this._first = firstBytes;
    this._s = new LopStream({path: String(url), onUpdate});
    this.requests = []; // [start, end) of every request made, for the caller's accounting
  }

  get container() { return this._s.container; }
  get level() { return this._s.level; }
  get bytes() { return this._s.bytes; }
  get complete() { return this._s._r.header !== null && this._s.bytes === this._s._r.header.fileSize; }

  async _get(start, end) {
    this.requests.push([start, end]);
    const res = await this._fetch(this.url, {headers: {Range: `bytes=${start}-${end - 1}`}});
    if (res.status === 200) { // the whole file: read it as a stream from where we are
      const all = new Uint8Array(await res.arrayBuffer());
      this._s.push(all.subarray(this._s.bytes));
      return;
    }
    if (res.status !== 206) throw new LopError('container', String(this.url), `HTTP ${res.status} ${res.statusText} for bytes ${start}-${end - 1}`, 'check the URL');
    const got = new Uint8Array(await res.arrayBuffer());
    // a range past the end of the file is cut at the end (only the first request, made before the
    // file size is known, may reach past it)
    const cut = this._s._r.header === null && got.length < end - start;
    if (got.length !== end - start && !cut) throw new LopError('container', String(this.url), `the server sent ${got.length} bytes for a range of ${end - start}`);
    this._s.push(got);
    if (cut && this._s.bytes === this._s._r.header?.fileSize) this._s.end();
  }

  /** Fetch the header and the manifest. */
  async open() {
    if (this.container || this.complete) return this.container;
    await this._get(0, this._first);
    const r = this._s._r;
    if (!r.manifest && r.header && !this.complete) await this._get(this._s.bytes, HEADER_SIZE + r.header.manifestSize);
    if (!r.manifest) r.finish(false);
    return this.container;
  }

  /** Fetch what level `level` needs (every section up to its plane; in the streaming layout a
   * number for every stage or one level per stage, as sectionsForLevel takes): the bytes from what
   * is held to the end of the last section needed, in one request (this reader keeps a prefix, so
   * a streaming file's deferred planes bring the stages before them along); resolves with the
   * container. */
  async fetchLevel(level) {
    const c = await this.open();
    const ranges = planRanges(c.manifest, level, this._s.bytes);
    if (ranges.length) await this._get(this._s.bytes, ranges[ranges.length - 1][1]);
    if (this.complete && !this._s._done) this._s.end();
    return c;
  }
}

// ============================================================================================
// GPU upload: what the WebGL2 decoders (runtime/js/glsl/) read

/** Texels per row of the integer textures the WebGL2 decoders read (log2 11: 2048, the width every
 * WebGL2 implementation supports); a word i is texel (i & 2047, i >> 11). */
export const TEXTURE_WIDTH_LOG2 = 11;
export const TEXTURE_WIDTH = 1 << TEXTURE_WIDTH_LOG2;

/** A table of 25 entries padded to 32 with 0xFFFFFFFF (the shaders' uvec4[8]; gpu._table32). */
export function table32(table) {
  const out = new Uint32Array(32).fill(0xFFFFFFFF);
  for (let k = 0; k <= LEVELS; k++) {
    if (!(table[k] >= 0 && table[k] < 2 ** 32)) throw new LopError('usage', null, 'table entries must fit in uint32 (at most 59 652 323 vertices per buffer)');
    out[k] = table[k];
  }
  return out;
}

/** `{width, height, data}`: `words` (Uint32Array) laid out in rows of TEXTURE_WIDTH texels of
 * `channels` words each, the last row zero-padded (an R32UI / RGBA32UI texture). */
export function textureLayout(words, channels = 1) {
  const texels = Math.max(1, Math.ceil(words.length / channels));
  const width = Math.min(TEXTURE_WIDTH, texels);
  const height = Math.ceil(texels / TEXTURE_WIDTH);
  const data = new Uint32Array(channels * (height === 1 ? width : TEXTURE_WIDTH * height));
  data.set(words);
  return {width: height === 1 ? width : TEXTURE_WIDTH, height, data};
}

/**
 * Everything `decode_bitplanes` reads for buffer (part, lod) at level B (the uniform block of
 * shaders/decode_bitplanes.glsl; lopcook.verify.gpu.decode_block / cluster_decode_block):
 * `{clustered, words (P), records (clustered: 4 words per cluster, else null), vertexId, bitId,
 * clusterId (Uint32Array(32) each), originHalf (Float32Array(4): float32 origin, float32(extent /
 * 2^25)), params (Uint32Array(4): B, words of P, N, 0), level}`. A placement's grid is its own
 * (mesh grid); its transform is applied after the decode (`placementRows`).
 */
export function decodeInputs(c, part, lod, level) {
  const cl = c.clusters(part, lod);
  const {origin, extent} = c.partGrid(part);
  const originHalf = new Float32Array([origin[0], origin[1], origin[2], f32(extent / 2 ** 25)]);
  const vid = c.lodEntry(c.owner(part), lod).vertex_id;
  if (cl === null) {
    const g = c.gpuBuffer(part, lod, level);
    return {clustered: false, words: g.words, records: null, vertexId: table32(vid), bitId: table32(g.bitId),
      clusterId: table32(new Float64Array(LEVELS + 1)), originHalf, params: new Uint32Array([level, Math.max(g.words.length, 1), 0, 0]), level};
  }
  const g = c.clusteredGpuBuffer(part, lod, level);
  return {clustered: true, words: g.words, records: g.records, vertexId: table32(vid), bitId: table32(new Float64Array(LEVELS + 1)),
    clusterId: table32(cl.clusterId), originHalf, params: new Uint32Array([level, Math.max(g.words.length, 1), cl.size, 0]), level};
}

/**
 * Everything `decode_attributes` reads for buffer (part, lod) (lopcook.verify.gpu.attribute_block,
 * plus the tangent fields): `{words, bits: Uint32Array(4) (b_n, b_u, b_c, S; 0 for an absent
 * attribute), scale: Float32Array(4) (float32(1 / (2^(b_n-1) - 1)), float32(1 / (2^b_c - 1)),
 * float32(1 / (2^(b_t-1) - 1)), 0), uv: Float32Array(4) (lo_u, lo_v, step_u, step_v), params:
 * Uint32Array(4) (words >= 1, b_t, 0, 0)}`; null when the buffer has no attribute record.
 */
export function attributeInputs(c, part, lod) {
  const e = c.lodEntry(part, lod);
  if (e.attributes == null) return null;
  const ab = e.attribute_bits;
  const bn = ab.normals || 0, bu = ab.uvs || 0, bc = ab.colors || 0, bt = ab.tangents || 0;
  const words = c.sectionWords(e.attributes);
  const used = words.subarray(0, Math.max(1, Math.ceil((e.vertices * e.record_bits) / 32)));
  return {
    words: used,
    bits: new Uint32Array([bn, bu, bc, e.record_bits]),
    scale: new Float32Array([bn ? 1 / (2 ** (bn - 1) - 1) : 0, bc ? 1 / (2 ** bc - 1) : 0, bt ? 1 / (2 ** (bt - 1) - 1) : 0, 0]),
    uv: new Float32Array(bu ? [e.uv_range[0][0], e.uv_range[0][1], e.uv_step[0], e.uv_step[1]] : [0, 0, 0, 0]),
    params: new Uint32Array([Math.max(used.length, 1), bt, 0, 0]),
    recordBits: e.record_bits,
  };
}

/** The placement rows (A | t) of part `part` as three Float32Array(4), the identity on the scene grid. */
export function placementRows(c, part) {
  const tf = c.placementTransform(part);
  if (tf === null) return [new Float32Array([1, 0, 0, 0]), new Float32Array([0, 1, 0, 0]), new Float32Array([0, 0, 1, 0])];
  return [0, 1, 2].map((r) => new Float32Array(tf.slice(4 * r, 4 * r + 4)));
}
