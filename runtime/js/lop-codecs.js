// lop-codecs.js: the decoders of .lop encoded sections (docs/format.md section 15), no dependency.
//
//   inflateRaw(bytes, limit, exact)  raw DEFLATE (RFC 1951) with zlib's verdict on every stream,
//                                    never more than `limit` bytes out
//   decodeTriangles(stream, m, n)    an EXT_meshopt_compression triangle stream (mode 1, version 1)
//                                    of m triangles, every index checked below n
//
// Both are synchronous and bounded (a reader decodes a section once, when its last byte has
// arrived), and both throw Error with a one-line reason for any stream the format refuses. They
// mirror lopcook/lop/encoding.py (zlib's inflate, meshoptimizer's meshopt_decodeIndexBuffer with
// the header, table and range rules of format.md 15.2): the same stream gets the same verdict.

/** DEFLATE expands at most 1032 times: a section claiming more is refused before any allocation. */
export const DEFLATE_MAX_RATIO = 1032;

const LENGTH_BASE = [3, 4, 5, 6, 7, 8, 9, 10, 11, 13, 15, 17, 19, 23, 27, 31, 35, 43, 51, 59, 67, 83, 99, 115, 131, 163, 195, 227, 258];
const LENGTH_EXTRA = [0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2, 3, 3, 3, 3, 4, 4, 4, 4, 5, 5, 5, 5, 0];
const DIST_BASE = [1, 2, 3, 4, 5, 7, 9, 13, 17, 25, 33, 49, 65, 97, 129, 193, 257, 385, 513, 769, 1025, 1537, 2049, 3073,
  4097, 6145, 8193, 12289, 16385, 24577];
const DIST_EXTRA = [0, 0, 0, 0, 1, 1, 2, 2, 3, 3, 4, 4, 5, 5, 6, 6, 7, 7, 8, 8, 9, 9, 10, 10, 11, 11, 12, 12, 13, 13];
const CODE_ORDER = [16, 17, 18, 0, 8, 7, 9, 6, 10, 5, 11, 4, 12, 3, 13, 2, 14, 1, 15];

/**
 * A canonical Huffman code from code lengths (0: no code): `{count, symbol}` for bit-by-bit
 * decoding. As zlib's inflate_table: an over-subscribed set is refused; an incomplete one too,
 * unless it is one code of length 1 (or no code at all) and `incompleteOk` (literal/length and
 * distance codes; never the code-length code).
 */
function huffman(lengths, incompleteOk, what) {
  const count = new Uint16Array(16);
  for (const len of lengths) count[len]++;
  count[0] = 0;
  let left = 1, max = 0;
  for (let len = 1; len < 16; len++) {
    left = 2 * left - count[len];
    if (left < 0) throw new Error(`over-subscribed ${what}`);
    if (count[len]) max = len;
  }
  if (left > 0 && max > 0 && (!incompleteOk || max !== 1)) throw new Error(`incomplete ${what}`);
  if (max === 0 && !incompleteOk) throw new Error(`empty ${what}`);
  const offs = new Uint16Array(16);
  for (let len = 1; len < 15; len++) offs[len + 1] = offs[len] + count[len];
  const symbol = new Uint16Array(lengths.length);
  lengths.forEach((len, sym) => { if (len) symbol[offs[len]++] = sym; });
  return {count, symbol};
}

let FIXED = null;
function fixedCodes() {
  if (FIXED === null) {
    const lit = new Uint8Array(288);
    lit.fill(8, 0, 144); lit.fill(9, 144, 256); lit.fill(7, 256, 280); lit.fill(8, 280, 288);
    FIXED = [huffman(lit, false, 'literal/length code'), huffman(new Uint8Array(32).fill(5), false, 'distance code')];
  }
  return FIXED;
}

class BitReader {
  constructor(bytes) { this.b = bytes; this.pos = 0; this.bit = 0; this.n = 0; }
  need(k) { // k <= 16 bits, least significant first
    while (this.n < k) {
      if (this.pos >= this.b.length) throw new Error('the deflate stream ends before its final block');
      this.bit |= this.b[this.pos++] << this.n;
      this.n += 8;
    }
    const v = this.bit & ((1 << k) - 1);
    this.bit >>>= k;
    this.n -= k;
    return v;
  }
  decode(h, what) {
    let code = 0, first = 0, index = 0;
    for (let len = 1; len < 16; len++) {
      code |= this.need(1);
      const c = h.count[len];
      if (code - first < c) return h.symbol[index + code - first];
      index += c;
      first = (first + c) << 1;
      code <<= 1;
    }
    throw new Error(`invalid ${what}`);
  }
  align() { this.bit = 0; this.n = 0; } // drop the bits left of the current byte (held bits are < 8)
  /** Bytes consumed: the byte holding the last bit read is the last one. */
  get end() { return this.pos - (this.n >> 3); }
}

function dynamicCodes(br) {
  const nlen = br.need(5) + 257, ndist = br.need(5) + 1, ncode = br.need(4) + 4;
  if (nlen > 286 || ndist > 30) throw new Error('too many length or distance symbols');
  const cl = new Uint8Array(19);
  for (let i = 0; i < ncode; i++) cl[CODE_ORDER[i]] = br.need(3);
  const lencode = huffman(cl, false, 'code lengths set');
  const lens = new Uint8Array(nlen + ndist);
  for (let have = 0; have < nlen + ndist;) {
    const sym = br.decode(lencode, 'code lengths code');
    if (sym < 16) { lens[have++] = sym; continue; }
    let len = 0, rep;
    if (sym === 16) {
      if (have === 0) throw new Error('invalid bit length repeat');
      len = lens[have - 1];
      rep = 3 + br.need(2);
    } else rep = sym === 17 ? 3 + br.need(3) : 11 + br.need(7);
    if (have + rep > nlen + ndist) throw new Error('invalid bit length repeat');
    lens.fill(len, have, have + rep);
    have += rep;
  }
  if (lens[256] === 0) throw new Error('invalid code -- missing end-of-block');
  return [huffman(lens.subarray(0, nlen), true, 'literal/lengths set'), huffman(lens.subarray(nlen), true, 'distances set')];
}

/**
 * Inflate the raw DEFLATE stream at the start of `bytes` (Uint8Array). Gives at most `limit` bytes
 * (throws as soon as the stream would give more), exactly `limit` when `exact`. Returns
 * `{out: Uint8Array, end}`, `end` = the bytes the stream occupies (the byte of its last bit
 * included). Throws Error for a stream zlib's inflate refuses (format.md 15.1).
 */
export function inflateRaw(bytes, limit, exact = false) {
  const br = new BitReader(bytes);
  let out = new Uint8Array(Math.min(limit, exact ? limit : Math.max(1024, 4 * bytes.length)));
  let n = 0;
  const room = (k) => {
    if (n + k > limit) throw new Error(`the deflate stream expands beyond its ${limit} bytes`);
    if (n + k > out.length) {
      const grown = new Uint8Array(Math.min(limit, Math.max(2 * out.length, n + k)));
      grown.set(out.subarray(0, n));
      out = grown;
    }
  };
  for (let last = 0; !last;) {
    last = br.need(1);
    const type = br.need(2);
    if (type === 0) {
      br.align();
      if (br.pos + 4 > bytes.length) throw new Error('the deflate stream ends before its final block');
      const len = bytes[br.pos] | (bytes[br.pos + 1] << 8), nlen = bytes[br.pos + 2] | (bytes[br.pos + 3] << 8);
      if (len !== (~nlen & 0xFFFF)) throw new Error('invalid stored block lengths');
      br.pos += 4;
      if (br.pos + len > bytes.length) throw new Error('the deflate stream ends before its final block');
      room(len);
      out.set(bytes.subarray(br.pos, br.pos + len), n);
      n += len;
      br.pos += len;
      continue;
    }
    if (type === 3) throw new Error('invalid block type');
    const [lit, dist] = type === 1 ? fixedCodes() : dynamicCodes(br);
    for (;;) {
      const sym = br.decode(lit, 'literal/length code');
      if (sym < 256) { room(1); out[n++] = sym; continue; }
      if (sym === 256) break;
      if (sym > 285) throw new Error('invalid literal/length code');
      const len = LENGTH_BASE[sym - 257] + br.need(LENGTH_EXTRA[sym - 257]);
      const ds = br.decode(dist, 'distance code');
      if (ds > 29) throw new Error('invalid distance code');
      const d = DIST_BASE[ds] + br.need(DIST_EXTRA[ds]);
      if (d > n) throw new Error('invalid distance too far back');
      room(len);
      for (let i = 0; i < len; i++, n++) out[n] = out[n - d];
    }
  }
  if (exact && n !== limit) throw new Error(`the deflate stream gives ${n} bytes, not the ${limit} its size says`);
  return {out: n === out.length ? out : out.slice(0, n), end: br.end};
}

/**
 * The 3m indices (Uint32Array) of an EXT_meshopt_compression triangle stream (bitstream version 1,
 * header byte 0xE1) of `m` triangles, as format.md 15.2 specifies (meshoptimizer's
 * meshopt_decodeIndexBuffer); every index must be below `n`. Throws Error otherwise.
 */
export function decodeTriangles(E, m, n) {
  if (E.length < 1 + m + 16) throw new Error(`the triangle stream is ${E.length} bytes, too short for ${m} triangles`);
  if (E[0] !== 0xE1) throw new Error(`the triangle stream starts with 0x${E[0].toString(16).padStart(2, '0')}, not 0xe1`);
  const end = E.length - 16;
  const table = E.subarray(end);
  if (table[14] || table[15] || table.subarray(0, 14).some((b) => b >> 4 === 15 || (b & 15) === 15)) {
    throw new Error("the triangle stream's table has a nibble 0xF or its last two bytes are not 0");
  }
  const edgeA = new Uint32Array(16).fill(0xFFFFFFFF), edgeB = new Uint32Array(16).fill(0xFFFFFFFF);
  const vert = new Uint32Array(16).fill(0xFFFFFFFF);
  let ep = 0, vp = 0, next = 0, last = 0, code = 1, data = 1 + m;
  const pushEdge = (a, b) => { edgeA[ep] = a; edgeB[ep] = b; ep = (ep + 1) & 15; };
  const pushVert = (v) => { vert[vp] = v; vp = (vp + 1) & 15; };
  const vertAt = (i) => vert[(vp - 1 - i) & 15];
  const byte = () => {
    if (data >= end) throw new Error('the triangle stream reads past its data');
    return E[data++];
  };
  const index = () => {
    let v = 0;
    for (let j = 0; j < 5; j++) {
      const b = byte();
      v = (v | ((b & 127) << (7 * j))) >>> 0;
      if (b < 128) break;
    }
    last = (last + ((v >>> 1) ^ -(v & 1))) >>> 0;
    return last;
  };
  const out = new Uint32Array(3 * m);
  for (let t = 0; t < m; t++) {
    const x = E[code++];
    let a, b, c;
    if (x < 0xF0) {
      const e = (ep - 1 - (x >> 4)) & 15;
      a = edgeA[e]; b = edgeB[e];
      const f = x & 15;
      if (f === 0) { c = next; next = (next + 1) >>> 0; pushVert(c); } else if (f <= 12) c = vertAt(f);
      else if (f === 13) { c = last = (last - 1) >>> 0; pushVert(c); } else if (f === 14) { c = last = (last + 1) >>> 0; pushVert(c); } else { c = index(); pushVert(c); }
      pushEdge(c, b); pushEdge(a, c);
    } else {
      let aux, fa;
      if (x < 0xFE) { aux = table[x & 15]; fa = 0; } else {
        aux = byte(); fa = x === 0xFE ? 0 : 15;
        if (aux === 0) next = 0;
      }
      const fb = aux >> 4, fc = aux & 15;
      if (fa === 0) { a = next; next = (next + 1) >>> 0; }
      if (fb === 0) { b = next; next = (next + 1) >>> 0; } else if (fb < 15) b = vertAt(fb - 1);
      if (fc === 0) { c = next; next = (next + 1) >>> 0; } else if (fc < 15) c = vertAt(fc - 1);
      if (fa === 15) a = index();
      if (fb === 15) b = index();
      if (fc === 15) c = index();
      pushVert(a);
      if (fb === 0 || fb === 15) pushVert(b);
      if (fc === 0 || fc === 15) pushVert(c);
      pushEdge(b, a); pushEdge(c, b); pushEdge(a, c);
    }
    out[3 * t] = a; out[3 * t + 1] = b; out[3 * t + 2] = c;
  }
  if (data !== end) throw new Error('the triangle stream holds data its triangles do not read');
  let max = 0;
  for (let i = 0; i < out.length; i++) if (out[i] > max) max = out[i];
  if (out.length && max >= n) throw new Error(`index ${max} is out of range for ${n} vertices`);
  return out;
}
