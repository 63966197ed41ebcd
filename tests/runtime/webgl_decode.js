// Transform-feedback check of the WebGL2 decoders (runtime/js/glsl/, runtime/js/lop-glsl.js) for
// tests/runtime/test_webgl_decoders.py: for every job {url, levels}, every part and LOD of the
// container is decoded by the GLSL ES vertex shaders (gl_VertexID = j, rasterizer off), and the
// SHA-256 of each output (as little-endian uint32 words: float32 bits for floats) is posted back:
//   positions per level: grid (3 n), level (n), position (3 n, world metres after lop_place)
//   attributes once: normals (3 n), uvs (2 n), colors (4 n), tangents (4 n) where present
//   crack-free decodes (lop_decode_crack_free) from each of the job's cameras, LOD 0 of each part
//   on the scene grid: grid, level, position
import * as lop from '/runtime/js/lop.js';
import {DECODE_BITPLANES, DECODE_ATTRIBUTES} from '/runtime/js/lop-glsl.js';

const POS_MAIN = `
uniform uint u_placed;
uniform vec4 u_place0, u_place1, u_place2;
flat out uvec3 o_grid;
flat out uint o_level;
flat out uvec3 o_pos;
void main() {
  uvec3 grid; vec3 p; uint level;
  lop_decode(uint(gl_VertexID), grid, p, level);
  if (u_placed != 0u) p = lop_place(p, u_place0, u_place1, u_place2);
  o_grid = grid; o_level = level; o_pos = floatBitsToUint(p);
  gl_Position = vec4(0.0); gl_PointSize = 1.0;
}`;
const VIEW_MAIN = `
flat out uvec3 o_grid;
flat out uint o_level;
flat out uvec3 o_pos;
void main() {
  uvec3 grid; vec3 p; uint level;
  lop_decode_crack_free(uint(gl_VertexID), grid, p, level);
  o_grid = grid; o_level = level; o_pos = floatBitsToUint(p);
  gl_Position = vec4(0.0); gl_PointSize = 1.0;
}`;
const ATTR_MAIN = `
flat out uvec3 o_normal;
flat out uvec2 o_uv;
flat out uvec4 o_color;
flat out uvec4 o_tangent;
void main() {
  uint j = uint(gl_VertexID);
  o_normal = lop_attr_bits.x != 0u ? floatBitsToUint(lop_decode_normal(j)) : uvec3(0u);
  o_uv = lop_attr_bits.y != 0u ? floatBitsToUint(lop_decode_uv(j)) : uvec2(0u);
  o_color = lop_attr_bits.z != 0u ? floatBitsToUint(lop_decode_color(j)) : uvec4(0u);
  o_tangent = lop_attr_params.y != 0u ? floatBitsToUint(lop_decode_tangent(j)) : uvec4(0u);
  gl_Position = vec4(0.0); gl_PointSize = 1.0;
}`;
const FS = '#version 300 es\nprecision highp float;\nout vec4 c;\nvoid main() { c = vec4(0.0); }\n';

function program(gl, vs, varyings) {
  const p = gl.createProgram();
  for (const [type, src] of [[gl.VERTEX_SHADER, vs], [gl.FRAGMENT_SHADER, FS]]) {
    const s = gl.createShader(type);
    gl.shaderSource(s, src);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    gl.attachShader(p, s);
  }
  gl.transformFeedbackVaryings(p, varyings, gl.INTERLEAVED_ATTRIBS);
  gl.linkProgram(p);
  if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(p));
  return p;
}

function texture(gl, unit, words, channels) {
  const {width, height, data} = lop.textureLayout(words, channels);
  const t = gl.createTexture();
  gl.activeTexture(gl.TEXTURE0 + unit);
  gl.bindTexture(gl.TEXTURE_2D, t);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
  gl.texImage2D(gl.TEXTURE_2D, 0, channels === 4 ? gl.RGBA32UI : gl.R32UI, width, height, 0,
    channels === 4 ? gl.RGBA_INTEGER : gl.RED_INTEGER, gl.UNSIGNED_INT, data);
  return t;
}

function run(gl, p, n, stride, setup) {
  gl.useProgram(p);
  const textures = setup((name) => gl.getUniformLocation(p, name));
  const buf = gl.createBuffer();
  gl.bindBuffer(gl.TRANSFORM_FEEDBACK_BUFFER, buf);
  gl.bufferData(gl.TRANSFORM_FEEDBACK_BUFFER, 4 * stride * n, gl.STREAM_READ);
  gl.bindBufferBase(gl.TRANSFORM_FEEDBACK_BUFFER, 0, buf);
  gl.enable(gl.RASTERIZER_DISCARD);
  gl.beginTransformFeedback(gl.POINTS);
  gl.drawArrays(gl.POINTS, 0, n);
  gl.endTransformFeedback();
  gl.disable(gl.RASTERIZER_DISCARD);
  gl.bindBufferBase(gl.TRANSFORM_FEEDBACK_BUFFER, 0, null);
  const out = new Uint32Array(stride * n);
  gl.bindBuffer(gl.COPY_READ_BUFFER, buf);
  gl.getBufferSubData(gl.COPY_READ_BUFFER, 0, out);
  gl.deleteBuffer(buf);
  for (const t of textures) gl.deleteTexture(t);
  const err = gl.getError();
  if (err) throw new Error(`GL error ${err}`);
  return out;
}

/** Columns [from, from + width) of an interleaved (n, stride) uint32 array. */
function column(a, n, stride, from, width) {
  const out = new Uint32Array(n * width);
  for (let j = 0; j < n; j++) for (let c = 0; c < width; c++) out[j * width + c] = a[j * stride + from + c];
  return out;
}

async function sha(a) {
  const d = new Uint8Array(await crypto.subtle.digest('SHA-256', new Uint8Array(a.buffer, a.byteOffset, a.byteLength)));
  return Array.from(d, (b) => b.toString(16).padStart(2, '0')).join('');
}

function positions(gl, progs, c, part, lod, level) {
  const inp = lop.decodeInputs(c, part, lod, level);
  const n = c.lodEntry(c.owner(part), lod).vertices;
  const rows = lop.placementRows(c, part);
  return run(gl, progs[inp.clustered ? 'clustered' : 'plain'], n, 7, (loc) => {
    const tex = [texture(gl, 0, inp.words, 1)];
    gl.uniform1i(loc('lop_positions'), 0);
    if (inp.clustered) {
      tex.push(texture(gl, 1, inp.records, 4));
      gl.uniform1i(loc('lop_clusters'), 1);
      gl.uniform4uiv(loc('lop_cluster_id'), inp.clusterId);
    } else gl.uniform4uiv(loc('lop_bit_id'), inp.bitId);
    gl.uniform4uiv(loc('lop_vertex_id'), inp.vertexId);
    gl.uniform4fv(loc('lop_origin_half'), inp.originHalf);
    gl.uniform4uiv(loc('lop_params'), inp.params);
    gl.uniform1ui(loc('u_placed'), c.placementTransform(part) === null ? 0 : 1);
    rows.forEach((r, i) => gl.uniform4fv(loc(`u_place${i}`), r));
    return tex;
  });
}

/** The crack-free decode (lop_decode_crack_free) of buffer (part, lod) at level B from one camera. */
function crackFree(gl, progs, c, part, lod, view) {
  const inp = lop.decodeInputs(c, part, lod, view.level);
  const n = c.lodEntry(c.owner(part), lod).vertices;
  return run(gl, progs[inp.clustered ? 'viewClustered' : 'view'], n, 7, (loc) => {
    const tex = [texture(gl, 0, inp.words, 1)];
    gl.uniform1i(loc('lop_positions'), 0);
    if (inp.clustered) {
      tex.push(texture(gl, 1, inp.records, 4));
      gl.uniform1i(loc('lop_clusters'), 1);
      gl.uniform4uiv(loc('lop_cluster_id'), inp.clusterId);
    } else gl.uniform4uiv(loc('lop_bit_id'), inp.bitId);
    gl.uniform4uiv(loc('lop_vertex_id'), inp.vertexId);
    gl.uniform4fv(loc('lop_origin_half'), inp.originHalf);
    gl.uniform4uiv(loc('lop_params'), inp.params);
    gl.uniform4fv(loc('lop_camera'), new Float32Array([...view.camera, 0]));
    gl.uniform4fv(loc('lop_level_dist'), new Float32Array(view.level_dist));
    gl.uniform4fv(loc('lop_block_radius'), new Float32Array(view.block_radius));
    return tex;
  });
}

function attributes(gl, progs, c, part, lod) {
  const inp = lop.attributeInputs(c, part, lod);
  const n = c.lodEntry(part, lod).vertices;
  return run(gl, progs.attributes, n, 13, (loc) => {
    const tex = [texture(gl, 0, inp.words, 1)];
    gl.uniform1i(loc('lop_attributes'), 0);
    gl.uniform4uiv(loc('lop_attr_bits'), inp.bits);
    gl.uniform4fv(loc('lop_attr_scale'), inp.scale);
    gl.uniform4fv(loc('lop_attr_uv'), inp.uv);
    gl.uniform4uiv(loc('lop_attr_params'), inp.params);
    return tex;
  });
}

async function main() {
  const jobs = await (await fetch('/jobs.json')).json();
  const gl = document.createElement('canvas').getContext('webgl2');
  if (!gl) throw new Error('no WebGL2 context');
  const info = gl.getExtension('WEBGL_debug_renderer_info');
  const renderer = info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER);
  const head = '#version 300 es\n#define LOP_NO_VIEW\n';
  const progs = {
    plain: program(gl, head + DECODE_BITPLANES + POS_MAIN, ['o_grid', 'o_level', 'o_pos']),
    clustered: program(gl, head + '#define LOP_CLUSTERED\n' + DECODE_BITPLANES + POS_MAIN, ['o_grid', 'o_level', 'o_pos']),
    attributes: program(gl, '#version 300 es\n' + DECODE_ATTRIBUTES + ATTR_MAIN, ['o_normal', 'o_uv', 'o_color', 'o_tangent']),
    view: program(gl, '#version 300 es\n' + DECODE_BITPLANES + VIEW_MAIN, ['o_grid', 'o_level', 'o_pos']),
    viewClustered: program(gl, '#version 300 es\n#define LOP_CLUSTERED\n' + DECODE_BITPLANES + VIEW_MAIN, ['o_grid', 'o_level', 'o_pos']),
  };
  gl.bindVertexArray(gl.createVertexArray());
  const out = {renderer, containers: {}};
  const t0 = performance.now();
  let vertices = 0;
  for (const job of jobs) {
    const c = lop.parse(new Uint8Array(await (await fetch(job.url)).arrayBuffer()), {path: job.url});
    const buffers = [];
    for (let i = 0; i < c.manifest.parts.length; i++) {
      for (let k = 0; k < c.manifest.parts[i].lods.length; k++) {
        const e = c.lodEntry(i, k), n = e.vertices, ab = e.attribute_bits;
        const rec = {part: i, lod: k, levels: {}};
        for (const level of job.levels) {
          const a = positions(gl, progs, c, i, k, level);
          vertices += n;
          rec.levels[level] = {grid: await sha(column(a, n, 7, 0, 3)), widths: await sha(column(a, n, 7, 3, 1)),
            positions: await sha(column(a, n, 7, 4, 3))};
        }
        for (const [v, view] of (k === 0 && job.views && c.owner(i) === i && c.placementTransform(i) === null ? job.views : []).entries()) {
          const a = crackFree(gl, progs, c, i, k, view);
          vertices += n;
          rec.views = rec.views || {};
          rec.views[v] = {grid: await sha(column(a, n, 7, 0, 3)), widths: await sha(column(a, n, 7, 3, 1)),
            positions: await sha(column(a, n, 7, 4, 3))};
        }
        if (e.attributes != null) {
          const a = attributes(gl, progs, c, i, k);
          const cols = {normals: [0, 3, ab.normals], uvs: [3, 2, ab.uvs], colors: [5, 4, ab.colors], tangents: [9, 4, ab.tangents]};
          for (const [name, [from, width, bits]] of Object.entries(cols)) rec[name] = bits ? await sha(column(a, n, 13, from, width)) : null;
        }
        buffers.push(rec);
      }
    }
    out.containers[job.name] = buffers;
  }
  out.seconds = (performance.now() - t0) / 1000;
  out.vertices = vertices;
  return out;
}

main().then((r) => fetch('/result', {method: 'POST', body: JSON.stringify(r)}),
  (e) => fetch('/result', {method: 'POST', body: JSON.stringify({error: String(e && e.stack || e)})}));
