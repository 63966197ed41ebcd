// Node driver of runtime/js/lop.js for tests/runtime/test_js_reader.py.
//
//   node tests/runtime/js_reader.mjs JOBS.json
//
// JOBS.json: {"cases": [{"id", "file", "allow_prefix": bool, "levels": [B, ...], "decode": bool,
// "chunks": [end, ...] (stream the file, pushing up to each byte end in turn)}]}. Prints one JSON
// line per case: {"id", "ok", "error", "available_level", "version", "buffers": [...], "stream":
// {...}, "ranges": {...}} ("range_levels": [B, ...] reads the file with LopRangeReader). "buffers"
// holds a SHA-256 (hex) of every decoded array, as little-endian bytes, so the test compares them
// with the Python reference without moving the arrays.
import {createHash} from 'node:crypto';
import {readFileSync} from 'node:fs';
import * as lop from '../../runtime/js/lop.js';

const digest = (a) => (a === null ? null : createHash('sha256').update(new Uint8Array(a.buffer, a.byteOffset, a.byteLength)).digest('hex'));

function decodeAll(c, levels) {
  const out = [];
  c.manifest.parts.forEach((part, i) => part.lods.forEach((_, k) => {
    if (c.levelOf(i, k) < 1) return; // a streaming prefix: the buffer's stage has not arrived
    const attrs = c.attributes(i, k);
    const rec = {part: i, lod: k, indices: digest(Uint32Array.from(c.indices(i, k))), levels: {}};
    for (const name of ['normals', 'uvs', 'colors', 'tangents']) rec[name] = digest(attrs[name]);
    for (const level of levels.filter((b) => b <= c.levelOf(i, k))) {
      const d = c.decodePositions(i, k, level);
      const r = {positions: digest(d.positions), grid: digest(d.grid)};
      if (c.owner(i) === i) {
        r.words = digest(c.gpuBuffer(i, k, level).words);
        if (c.clusters(i, k) !== null) {
          const g = c.clusteredGpuBuffer(i, k, level);
          r.cwords = digest(g.words);
          r.records = digest(g.records);
        }
      }
      rec.levels[level] = r;
    }
    out.push(rec);
  }));
  return out;
}

function streamed(data, chunks) {
  const events = [];
  const s = new lop.LopStream({onUpdate: (st) => events.push([st.event, st.level, st.bytes, st.stage])});
  const levels = [], stages = [];
  let at = 0;
  try {
    for (const end of chunks) {
      s.push(data.subarray(at, end));
      at = end;
      levels.push(s.level);
      stages.push(s.container ? s.container.stageLevels : [0]);
    }
    s.end();
    return {levels, stages, events, error: null};
  } catch (exc) {
    if (!(exc instanceof lop.LopError)) throw exc;
    return {levels, stages, events, error: exc.message, at};
  }
}

/** LopRangeReader over a fake server holding `data` (HTTP 206 for each Range request). */
async function ranged(data, levels, firstBytes) {
  const fetchFn = async (url, init) => {
    const m = /^bytes=(\d+)-(\d+)$/.exec(init.headers.Range);
    const start = +m[1], end = Math.min(+m[2] + 1, data.length);
    return new Response(data.slice(start, end), {status: 206});
  };
  const r = new lop.LopRangeReader('mem://x.lop', {fetch: fetchFn, firstBytes});
  const steps = [];
  try {
    for (const level of levels) {
      await r.fetchLevel(level);
      steps.push([level, r.bytes, r.level]);
    }
    return {requests: r.requests.map(([a, b]) => [a, Math.min(b, data.length)]), steps, error: null,
      positions24: digest(r.container.decodePositions(0, 0, 24).positions)};
  } catch (exc) {
    return {requests: r.requests, steps, error: String(exc && exc.stack)};
  }
}

const jobs = JSON.parse(readFileSync(process.argv[2], 'utf8'));
for (const job of jobs.cases) {
  const data = new Uint8Array(readFileSync(job.file));
  const out = {id: job.id, ok: false, error: null};
  try {
    const c = lop.parse(data, {path: job.file, allowPrefix: !!job.allow_prefix});
    out.available_level = c.availableLevel;
    out.stage_levels = c.stageLevels;
    out.version = [c.header.major, c.header.minor];
    if (job.decode) out.buffers = decodeAll(c, job.levels || []);
    out.ok = true;
  } catch (exc) {
    if (!(exc instanceof lop.LopError)) {
      out.error = `NOT A LopError: ${exc && exc.stack}`;
    } else out.error = exc.message;
  }
  if (job.chunks) out.stream = streamed(data, job.chunks);
  if (job.range_levels) out.ranges = await ranged(data, job.range_levels, job.first_bytes || 65536);
  process.stdout.write(JSON.stringify(out) + '\n');
}
