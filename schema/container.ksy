meta:
  id: lopcook_lop
  title: lopcook level-of-precision container (.lop), versions 2.0, 3.0 (clustered position buffers, placements) and 4.0 (tangents, the streaming layout, encoded sections)
  application: lopcook (offline asset cooker, Meyer et al. 2011 adaptive level-of-precision)
  file-extension: lop
  license: MIT
  ks-version: 0.9
  endian: le
  encoding: ASCII

doc: |
  A .lop file holds the vertex data of a scene as binned adaptive precision buffers
  (Meyer, Sussner, Greiner, Stamminger, "Adaptive Level-of-Precision for GPU-Rendering",
  VMV 2011, sections 4-6): positions quantized on one 24-bit grid, split into the mandatory
  bits of every vertex and 23 refinement bit planes, plus compact attributes (indices, and
  one packed record per vertex of octahedral normals, UVs and colours at per-part bit counts;
  Purnomo et al. 2005, sections 3-5).

  Layout: a 32-byte header, a JSON manifest, then sections back to back. Every integer is
  little-endian. The JSON manifest (schema/container.schema.json) says what each section
  is and where it lies, so the sections cannot be split by Kaitai Struct alone: a reader
  parses the header and the manifest, then cuts `sections` with the manifest's table
  (`section_list` below, or by hand) and interprets each piece with the types below.

  Prefix property: the position sections come last (mandatory bits, then planes 2, 3, ...),
  so a file cut after plane B still holds the header, the manifest, every attribute and
  the planes up to B, and decodes level B exactly (docs/format.md, "The prefix property").

  docs/format.md is the normative prose; docs/worked_example.py decodes a real file by hand.

doc-ref: docs/format.md

seq:
  - id: header
    type: header
    doc: The fixed 32-byte header (offset 0).
  - id: manifest
    type: str
    size: header.len_manifest
    encoding: ASCII
    doc: |
      The manifest: header.len_manifest bytes of JSON at file offset 32, validated by
      schema/container.schema.json. Canonical form: keys sorted, no whitespace, ASCII only
      (other characters escaped as \uXXXX, so UTF-8 and ASCII decoding agree), no NaN or
      Infinity. CRC-32 of exactly these bytes = header.crc32_manifest. Not NUL-terminated,
      not padded.
  - id: sections
    size-eos: true
    doc: |
      The section area: every byte after the manifest, from file offset
      header.ofs_sections = 32 + header.len_manifest to header.len_file (in a complete file
      its size is header.len_file - 32 - header.len_manifest; a truncated prefix file is
      shorter).

      It is a repeated raw area whose boundaries come from the manifest, not from the bytes:
      manifest.sections[i] = {name, offset, length, crc32} is bytes
      [offset, offset + length) of this area (offsets are relative to the start of the area,
      so the manifest does not depend on its own size). The sections are back to back, in
      the table's order, with no gaps: sections[0].offset = 0, sections[i+1].offset =
      sections[i].offset + sections[i].length, and the last ends at the end of the area.
      Every length is a multiple of 4 (0 to 3 zero bytes of padding end each payload and are
      included in its length and its CRC-32). An empty section (length 0, crc32 0) is
      allowed: a refinement plane no vertex of any buffer needs.

      Order and names: for each part i (manifest order), for each LOD k:
      "part{i}/lod{k}/indices", then "part{i}/lod{k}/attributes" when the buffer has normals,
      UVs or colours; then, in containers cooked with --hierarchy,
      "part{i}/lod0/hierarchy" for every part i (manifest parts[i].hierarchy.section); then,
      in version 3.0 files (clustered buffers), "positions/clusters"; then
      "positions/mandatory"; then
      "positions/plane02" .. "positions/planeNN" (two-digit plane number, NN =
      manifest.positions.max_level).

      Version 4.0 may use the streaming layout instead (manifest positions.stages; docs/format.md
      section 14): stage s (every LOD entry names its stage; stage 0 holds every part's coarsest
      LOD) holds, for each of
      its buffers, "part{i}/lod{k}/indices", "part{i}/lod{k}/attributes" (and for k = 0 the
      part's hierarchy), then "positions/stage{s}/clusters" (when a buffer of the stage is
      clustered), "positions/stage{s}/mandatory" and "positions/stage{s}/planePP" for the
      planes 2..stages[s].level that hold bits; after every stage,
      "positions/stage{s}/deferred" holds planes level+1..max_level of stage s concatenated
      (each 4 ceil(bits/32) bytes). And a 4.0 section may be stored encoded (its table entry
      has "encoding" and "size"; encoded_section): decode it first, then interpret the
      decoded bytes as below.

      Interpret a section with: indices_section, attributes_section (normals, UVs, colours
      of one buffer; attribute_record reads vertex j's), hierarchy_section (a part's vertex
      hierarchy), cluster_section (positions/clusters), mandatory_section (positions/mandatory),
      refinement_plane (positions/planePP); a buffer's packed positions at a level are
      described by packed_position_buffer, or clustered_position_buffer for a clustered
      buffer (lod.cluster_size present), whose plane slices skip the components its
      anchors imply (docs/format.md, "Clustered buffers"). To cut the area into its sections, parse it as
      section_list(lengths) with the lengths taken from the manifest.

types:
  header:
    doc: |
      32 bytes at offset 0. Check, in this order: magic; crc32_header over bytes 0..27;
      version_major (refuse a major you do not know); len_header == 32;
      file size <= len_file (longer: trailing data, an error; shorter: a truncated file,
      an error unless you accept prefixes); crc32_manifest.
    seq:
      - id: magic
        contents: LOPC
        doc: 'Offset 0, 4 bytes: the ASCII bytes "LOPC" (4c 4f 50 43).'
      - id: version_major
        type: u2
        valid:
          any-of: [2, 3, 4]
        doc: |
          Offset 4, uint16: format major version: 2, or 3 when the file holds clustered
          position buffers (manifest positions.clusters; cluster_section) or placement parts
          (cook --instances, parts[].placement); a file with neither is written as 2.0. 3.x
          means "may hold clusters and/or placements". 4 when some part has tangents
          (lod.attribute_bits.tangents), the file is in the streaming layout
          (positions.stages) or a section or the manifest is encoded (4.x may also hold
          clusters and placements). A writer writes the oldest major that
          reads the file correctly. A reader refuses a major version it does not know (an
          incompatible change of layout or meaning): a 2.x reader must not read clustered
          buffers, whose words and planes it would misread, nor placements, whose mesh-grid
          positions it would not transform.
      - id: version_minor
        type: u2
        doc: |
          Offset 6, uint16: format minor version, 0 for this description. Minor versions only
          add (new manifest properties, new optional sections); an N.x reader reads any N.y
          file, ignoring what it does not know. 2.1 was written by an earlier lopcook for
          placement parts without clusters (a placement's LOD entries name another part's
          buffers, stored once); lopcook still reads it, and now writes such files as 3.0.
      - id: len_header
        type: u4
        valid: 32
        doc: |
          Offset 8, uint32, bytes: size of this header, always 32 in version 1.
      - id: len_manifest
        type: u4
        doc: |
          Offset 12, uint32, bytes M of the manifest that follows the header, as stored: the
          JSON text, or in a 4.x file an encoded_manifest (its first byte is 0x00).
      - id: crc32_manifest
        type: u4
        doc: |
          Offset 16, uint32: CRC-32 of the M manifest bytes (ISO-HDLC / IEEE 802.3 CRC-32 as
          in zlib.crc32 and PNG: reflected polynomial 0xEDB88320, initial value and final XOR
          0xFFFFFFFF).
      - id: len_file
        type: u8
        doc: |
          Offset 20, uint64, bytes: total size of the file = 32 + M + the sum of all section
          lengths. A file longer than this has trailing data (an error); a shorter one is
          truncated (an error, or a prefix file if the reader accepts those).
      - id: crc32_header
        type: u4
        doc: Offset 28, uint32, CRC-32 (as above) of header bytes 0..27.
    instances:
      ofs_manifest:
        value: len_header
        doc: File offset of the manifest (32).
      ofs_sections:
        value: len_header + len_manifest
        doc: File offset of the section area; every manifest section offset is relative to it.

  encoded_manifest:
    doc: |
      Version 4.x: a manifest stored encoded (docs/format.md 4; lopcook writes it for files in
      the streaming layout). Its first byte is 0x00, which no JSON text starts with.
      header.crc32_manifest covers all M stored bytes; section offsets still count from 32 + M.
    seq:
      - id: mark
        contents: [0x00]
        doc: Tells an encoded manifest from JSON text.
      - id: len_text
        type: u4
        doc: Bytes D of the JSON text; at most 1032 (M - 5).
      - id: stream
        size-eos: true
        doc: |
          Raw DEFLATE (RFC 1951) of the D bytes of JSON text, ending at the manifest's last
          byte (no padding), under the rules of encoded_section.

  encoded_section:
    doc: |
      Version 4.0: a section whose table entry has "encoding" and "size" (docs/format.md 15).
      length and crc32 cover these stored bytes; decoding gives "size" bytes (a multiple of 4),
      which every other type here describes. encoding "deflate": the stream is a raw DEFLATE
      stream (RFC 1951; no zlib or gzip wrapper) of those bytes, valid as zlib's inflate reads
      it, giving exactly "size" bytes (size <= 1032 length). encoding "meshopt-deflate" (a LOD's
      indices only): the inflated bytes are a meshopt_triangle_stream of the LOD's m triangles,
      decoded to 3 m indices (each < n) written as index_width-byte integers plus zero padding.
    seq:
      - id: stream
        size: _io.size - len_padding
        doc: The encoded stream; it ends inside the last 4 bytes of the section.
      - id: padding
        size-eos: true
        doc: 0-3 zero bytes to a multiple of 4 (the last stream byte is the one holding its last bit).
    params:
      - id: len_padding
        type: u1
        doc: length - e, e the stream's bytes (known once it is inflated).

  meshopt_triangle_stream:
    doc: |
      EXT_meshopt_compression mode 1 ("TRIANGLES") bitstream version 1 of m triangles
      (meshoptimizer's meshopt_encodeIndexBuffer), the inflated bytes of a "meshopt-deflate"
      section; decoded as docs/format.md 15.2 writes out (edge and vertex FIFOs of 16 entries,
      initially 0xFFFFFFFF; a triangle may come out rotated, same winding).
    params:
      - id: num_triangles
        type: u4
        doc: lod.triangles.
    seq:
      - id: header
        contents: [0xe1]
        doc: Bitstream version 1.
      - id: codes
        size: num_triangles
        doc: One code byte per triangle.
      - id: data
        size: _io.size - _io.pos - 16
        doc: Extra bytes the codes read (zigzag LEB128 index deltas, explicit codeaux bytes); must be read exactly.
      - id: table
        size: 16
        doc: The codeaux table; bytes 14 and 15 are 0 and no nibble of bytes 0..13 is 0xF.

  section_list:
    doc: |
      The section area cut into its sections. Kaitai Struct cannot read the JSON manifest, so
      the caller passes manifest.sections[*].length in table order; section i is then
      sections[i] (the table's offsets are the running sums of these lengths). Check each
      piece's CRC-32 against manifest.sections[i].crc32.
    params:
      - id: lengths
        type: u8[]
        doc: manifest.sections[i].length for i = 0 .. N-1, bytes, each a multiple of 4.
    seq:
      - id: sections
        size: lengths[_index]
        repeat: expr
        repeat-expr: lengths.size
        doc: Raw payload of section i, padding included.

  hierarchy_section:
    doc: |
      Section "part{i}/lod0/hierarchy" (only with `lopcook cook --hierarchy`; manifest
      parts[i].hierarchy): the view-dependent vertex hierarchy of part i's LOD 0 buffer with
      its dependency-free connectivity coding (the blob of lopcook.hierarchy.encode_hierarchy,
      written with positions kept outside). Its leaves are that buffer's vertices; every node
      sits on the position of one of them, so node positions are the buffer's LOP bit-plane
      positions (a node's minimum level is its vertex's). The body's fields are varint-coded
      and described field by field in docs/hierarchy.md, section 4; flag byte of the body = 15
      (vertex order stored, positions outside, reach radii stored, boundary bits stored: one
      bit per leaf, most significant bit first; the vertex order is packed at
      bitlen(leaves - 1) bits per leaf, least significant bit first).
    seq:
      - id: magic
        contents: LOPH
        doc: Blob magic "LOPH".
      - id: version
        type: u1
        doc: Blob version, 1.
      - id: variant_flags
        type: u1
        doc: Coding variant (docs/hierarchy.md section 4); lopcook writes proposed_plus (0xC0).
      - id: table_size
        type: u2
        doc: Huffman table size including the escape (512).
      - id: len_body
        type: u8
        doc: Body length in bytes.
      - id: body
        size: len_body
        doc: Counts, grid placement, tree shape, representative bits, selection data, vertex
          order, Huffman tables, record index and coded connectivity (docs/hierarchy.md).
      - id: crc32
        type: u4
        doc: CRC-32 (zlib) of every byte of the blob before this field.
      - id: padding
        size-eos: true
        doc: 0 to 3 zero bytes up to a multiple of 4.

  indices_section:
    doc: |
      Section "part{i}/lod{k}/indices": the buffer's triangles, i0 i1 i2 per triangle
      (counter-clockwise front faces), indices into the buffer's vertices in binned order.
      index_width = manifest lod.index_width: 2 (uint16) when lod.vertices <= 65536, else 4
      (uint32). Exact. Section length = 3 * triangles * index_width rounded up to a multiple
      of 4 (2 zero bytes follow an odd number of uint16 indices).
    params:
      - id: index_width
        type: u1
        doc: manifest lod.index_width, bytes per index (2 or 4).
      - id: num_triangles
        type: u4
        doc: manifest lod.triangles.
    seq:
      - id: indices_u2
        type: u2
        repeat: expr
        repeat-expr: 3 * num_triangles
        if: index_width == 2
        doc: uint16 little-endian indices, each < lod.vertices.
      - id: indices_u4
        type: u4
        repeat: expr
        repeat-expr: 3 * num_triangles
        if: index_width == 4
        doc: uint32 little-endian indices, each < lod.vertices.
      - id: padding
        size-eos: true
        doc: 0 or 2 zero bytes up to a multiple of 4.

  attributes_section:
    doc: |
      Section "part{i}/lod{k}/attributes": one record of S = 2 b_n + 2 b_u + 4 b_c (+ 2 b_t + 1)
      bits per vertex (binned order), S = manifest lod.record_bits, the bits b_n, b_u, b_c, b_t
      from lod.attribute_bits (an absent attribute: null or, for tangents, no key; counted 0
      here). Vertex j's record starts at bit j * S of the section; its fields, each present
      attribute only, follow in the order normal.u, normal.v (b_n bits each), uv.u, uv.v (b_u),
      color.r, g, b, a (b_c), tangent.u, tangent.v (b_t) and the tangent's sign bit, least
      significant bit first (bit i of the section is bit i & 31 of word i >> 5). A field may
      span two words (unlike Purnomo's word-aligned bins); read it with bit_field. Length
      4 * ceil(vertices * S / 32) bytes, no padding word.
    params:
      - id: num_vertices
        type: u4
        doc: manifest lod.vertices.
      - id: bits_normal
        type: u1
        doc: lod.attribute_bits.normals (4..16), 0 when null.
      - id: bits_uv
        type: u1
        doc: lod.attribute_bits.uvs (6..16), 0 when null.
      - id: bits_color
        type: u1
        doc: lod.attribute_bits.colors (4..8), 0 when null.
      - id: bits_tangent
        type: u1
        doc: lod.attribute_bits.tangents (4..16, version 4.0), 0 when absent or null.
      - id: lo_u
        type: f8
        doc: lod.uv_range[0][0] (a float32 value); 0 without UVs.
      - id: lo_v
        type: f8
        doc: lod.uv_range[0][1].
      - id: step_u
        type: f8
        doc: lod.uv_step[0] = float32((hi_u - lo_u) / (2^b_u - 1)) (a float32 value).
      - id: step_v
        type: f8
        doc: lod.uv_step[1].
    instances:
      record_bits:
        value: '2 * bits_normal + 2 * bits_uv + 4 * bits_color + (bits_tangent > 0 ? 2 * bits_tangent + 1 : 0)'
        doc: S, bits per vertex.
      ofs_uv:
        value: 2 * bits_normal
        doc: Bit offset of uv.u inside a record.
      ofs_color:
        value: 2 * bits_normal + 2 * bits_uv
        doc: Bit offset of color.r inside a record.
      ofs_tangent:
        value: 2 * bits_normal + 2 * bits_uv + 4 * bits_color
        doc: Bit offset of tangent.u inside a record.
    seq:
      - id: words
        type: u4
        repeat: expr
        repeat-expr: (num_vertices * record_bits + 31) / 32
        doc: The packed records, little-endian uint32 words.

  attribute_record:
    doc: |
      Vertex j's record in an attributes_section (its _parent), decoded. Every decode instance
      is a float32 value: evaluate each operation in float32, rounding once per operation,
      with no fused multiply-add (a shader: `precise`); the decode is bit-exact with
      lopcook.lop.record.decode_record.
      Normal (Cigolle et al. 2014, precise octahedral, b_n bits): h = 2^(b_n - 1),
      R = float32(1 / (h - 1)); p = max(float32(code - h) * R, -1) per component;
      z = (1 - |p.x|) - |p.y|; if z < 0: (x, y) = ((1 - |p.y|) sgn(p.x), (1 - |p.x|) sgn(p.y)),
      sgn(t) = +1 for t >= 0 else -1; the normal is (x, y, z), unnormalised (normalise it).
      UV: u = lo_u + float32(q_u) * step_u (one rounded product, one rounded sum); likewise v.
      Colour: c = float32(q) * float32(1 / (2^b_c - 1)) per channel, linear.
      Tangent (version 4.0): xyz decoded exactly as the normal with b_t bits (unnormalised),
      w = -1.0 when the sign bit is 1, else +1.0.
    params:
      - id: j
        type: u4
        doc: Vertex index in binned order.
    instances:
      ofs_bit:
        value: j * _parent.record_bits
        doc: Bit offset of the record.
      normal_u:
        pos: 0
        type: bit_field(ofs_bit, _parent.bits_normal)
        if: _parent.bits_normal > 0
        doc: Octahedral code of u, 1 .. 2^b_n - 1 (0 reads as -1).
      normal_v:
        pos: 0
        type: bit_field(ofs_bit + _parent.bits_normal, _parent.bits_normal)
        if: _parent.bits_normal > 0
        doc: Octahedral code of v.
      uv_u:
        pos: 0
        type: bit_field(ofs_bit + _parent.ofs_uv, _parent.bits_uv)
        if: _parent.bits_uv > 0
        doc: Code q_u, 0 .. 2^b_u - 1.
      uv_v:
        pos: 0
        type: bit_field(ofs_bit + _parent.ofs_uv + _parent.bits_uv, _parent.bits_uv)
        if: _parent.bits_uv > 0
        doc: Code q_v.
      color_r:
        pos: 0
        type: bit_field(ofs_bit + _parent.ofs_color, _parent.bits_color)
        if: _parent.bits_color > 0
        doc: Red code, 0 .. 2^b_c - 1.
      color_g:
        pos: 0
        type: bit_field(ofs_bit + _parent.ofs_color + _parent.bits_color, _parent.bits_color)
        if: _parent.bits_color > 0
        doc: Green code.
      color_b:
        pos: 0
        type: bit_field(ofs_bit + _parent.ofs_color + 2 * _parent.bits_color, _parent.bits_color)
        if: _parent.bits_color > 0
        doc: Blue code.
      color_a:
        pos: 0
        type: bit_field(ofs_bit + _parent.ofs_color + 3 * _parent.bits_color, _parent.bits_color)
        if: _parent.bits_color > 0
        doc: Alpha code.
      tangent_u:
        pos: 0
        type: bit_field(ofs_bit + _parent.ofs_tangent, _parent.bits_tangent)
        if: _parent.bits_tangent > 0
        doc: Octahedral code of the tangent's u, 1 .. 2^b_t - 1 (0 reads as -1).
      tangent_v:
        pos: 0
        type: bit_field(ofs_bit + _parent.ofs_tangent + _parent.bits_tangent, _parent.bits_tangent)
        if: _parent.bits_tangent > 0
        doc: Octahedral code of the tangent's v.
      tangent_sign:
        pos: 0
        type: bit_field(ofs_bit + _parent.ofs_tangent + 2 * _parent.bits_tangent, 1)
        if: _parent.bits_tangent > 0
        doc: 1 when the handedness w is -1.
      half_n:
        value: 1 << (_parent.bits_normal - 1)
        doc: h = 2^(b_n - 1) (an integer).
      inv_n:
        value: 1.0 / (half_n - 1)
        doc: R = float32(1 / (h - 1)), rounded once.
      p_x:
        value: '(normal_u.value - half_n) * inv_n < -1.0 ? -1.0 : (normal_u.value - half_n) * inv_n'
        doc: p.x = max(float32(code_u - h) * R, -1).
      p_y:
        value: '(normal_v.value - half_n) * inv_n < -1.0 ? -1.0 : (normal_v.value - half_n) * inv_n'
        doc: p.y = max(float32(code_v - h) * R, -1).
      abs_p_x:
        value: 'p_x < 0 ? -p_x : p_x'
        doc: '|p.x|.'
      abs_p_y:
        value: 'p_y < 0 ? -p_y : p_y'
        doc: '|p.y|.'
      oct_z:
        value: (1.0 - abs_p_x) - abs_p_y
        doc: z (negative on the folded lower half).
      oct_x:
        value: 'oct_z < 0 ? (1.0 - abs_p_y) * (p_x >= 0 ? 1.0 : -1.0) : p_x'
        doc: x.
      oct_y:
        value: 'oct_z < 0 ? (1.0 - abs_p_x) * (p_y >= 0 ? 1.0 : -1.0) : p_y'
        doc: y. The normal is (oct_x, oct_y, oct_z), unnormalised.
      u:
        value: _parent.lo_u + uv_u.value * _parent.step_u
        doc: Decoded u (float32 product, then float32 sum).
      v:
        value: _parent.lo_v + uv_v.value * _parent.step_v
        doc: Decoded v.
      inv_c:
        value: 1.0 / ((1 << _parent.bits_color) - 1)
        doc: float32(1 / (2^b_c - 1)), rounded once.
      r_f:
        value: color_r.value * inv_c
        doc: Red in [0, 1].
      g_f:
        value: color_g.value * inv_c
        doc: Green in [0, 1].
      b_f:
        value: color_b.value * inv_c
        doc: Blue in [0, 1].
      a_f:
        value: color_a.value * inv_c
        doc: Alpha in [0, 1].
      half_t:
        value: 1 << (_parent.bits_tangent - 1)
        doc: h = 2^(b_t - 1) (an integer).
      inv_t:
        value: 1.0 / (half_t - 1)
        doc: float32(1 / (h - 1)), rounded once.
      tp_x:
        value: '(tangent_u.value - half_t) * inv_t < -1.0 ? -1.0 : (tangent_u.value - half_t) * inv_t'
        doc: The tangent's p.x.
      tp_y:
        value: '(tangent_v.value - half_t) * inv_t < -1.0 ? -1.0 : (tangent_v.value - half_t) * inv_t'
        doc: The tangent's p.y.
      abs_tp_x:
        value: 'tp_x < 0 ? -tp_x : tp_x'
        doc: '|p.x|.'
      abs_tp_y:
        value: 'tp_y < 0 ? -tp_y : tp_y'
        doc: '|p.y|.'
      tangent_z:
        value: (1.0 - abs_tp_x) - abs_tp_y
        doc: z of the tangent.
      tangent_x:
        value: 'tangent_z < 0 ? (1.0 - abs_tp_y) * (tp_x >= 0 ? 1.0 : -1.0) : tp_x'
        doc: x of the tangent.
      tangent_y:
        value: 'tangent_z < 0 ? (1.0 - abs_tp_x) * (tp_y >= 0 ? 1.0 : -1.0) : tp_y'
        doc: y of the tangent. The tangent is (tangent_x, tangent_y, tangent_z), unnormalised.
      tangent_w:
        value: 'tangent_sign.value == 1 ? -1.0 : 1.0'
        doc: The handedness w.

  mandatory_section:
    doc: |
      Section "positions/mandatory": uint32 little-endian words. For each buffer (manifest
      order: parts, then LODs) manifest lod.mandatory_words = [offset, count] locates, in
      words, the buffer's packed buffer P at level 1 (packed_position_buffer with level = 1):
      every vertex of bin k with its k mandatory bits per component. The buffers follow each
      other without gaps (offset of buffer t+1 = offset + count of buffer t); count =
      ceil(BitId_1[24] / 32); the unused high bits of a buffer's last word are zero.
    seq:
      - id: words
        type: u4
        repeat: eos
        doc: All buffers' words; buffer t is words[offset_t .. offset_t + count_t).

  refinement_plane:
    doc: |
      Section "positions/planePP" (PP = 02 .. 24): refinement plane p = PP. It adds one bit,
      bit 24 - p of the 24-bit grid integer, to each component of every vertex whose minimum
      level is below p, i.e. to vertices j < VertexId[p-1] of each buffer (the vertices whose
      mandatory bits and planes 2..p-1 hold only p-1 bits).

      Bit stream, least significant bit of each byte first (bit i of the stream is bit
      (i & 7) of byte (i >> 3)): the buffers in manifest order (parts, then LODs), and inside
      a buffer its vertices j = 0 .. VertexId[p-1]-1 in binned order, three bits each, x then
      y then z. So in buffer t, vertex j, component c (0 = x, 1 = y, 2 = z) is stream bit
      start_t + 3 * j + c, with start_t = sum over earlier buffers r of 3 * VertexId_r[p-1].
      No alignment between buffers; zero bits fill the last byte and zero bytes pad the
      section to a multiple of 4. A plane no vertex needs has length 0.

      Merging plane p into a buffer at level p-1 (top bits v, p-1 bits per component for
      j < VertexId[p-1]): v = (v << 1) | bit. The result is the buffer at level p.

      A clustered buffer's slice (version 3.0) holds, for every cluster with m_c < p in order,
      for every vertex, only the components with k_t < p (the others take bit
      (a_t >> (k_t - p)) & 1 from the anchor); its length is lod.cluster_plane_bits[p-2]
      bits, and start_t sums the earlier buffers' slice lengths.
    meta:
      bit-endian: le
    seq:
      - id: bits
        type: b1
        repeat: eos
        doc: The plane's bits in stream order (padding bits at the end are 0).

  plane_bit:
    doc: |
      One bit of a refinement plane section read by its stream index, without reading the
      stream bit by bit: bit (index & 7) of byte (index >> 3).
    params:
      - id: index
        type: u8
        doc: Stream bit index, start_t + 3 * j + c (see refinement_plane).
    instances:
      containing_byte:
        pos: index >> 3
        type: u1
        doc: The byte holding the bit.
      value:
        value: (containing_byte >> (index & 7)) & 1
        doc: The bit, 0 or 1.

  packed_position_buffer:
    doc: |
      A binned adaptive precision buffer P at per-buffer level B (1..24): what a renderer
      keeps in GPU memory and what positions/mandatory holds for B = 1. P is not stored for
      B > 1; it is rebuilt from the mandatory words and planes 2..B (docs/format.md,
      "Rebuilding P at level B").

      Vertices follow each other in binned order (sorted by minimum level). Bin k = the
      vertices j with VertexId[k-1] <= j < VertexId[k] (minimum level k). At level B each
      vertex of bin k stores b = max(k, B) bits per component, the top b bits
      v = q >> (24 - b) of its 24-bit grid integers q, x then y then z, each field least
      significant bit first:
        BitId[0] = 0, BitId[k] = BitId[k-1] + 3 * max(k, B) * (VertexId[k] - VertexId[k-1])
        o_j = 3 * b * (j - VertexId[k-1]) + BitId[k-1]     (bit offset of vertex j)
        x at o_j, y at o_j + b, z at o_j + 2b
      Bit offset o is bit (o & 31) (0 = least significant) of word o >> 5; a field never
      spans more than two words (b <= 24): value = (P[w] >> s | P[w+1] << (32 - s)) & (2^b - 1)
      with w = o >> 5, s = o & 31. P has ceil(BitId[24] / 32) words; unused high bits of the
      last word are zero. Since words are little-endian, the bit stream is also "bit (o & 7)
      of byte (o >> 3)".

      Position (shader order, every operation rounded to float32, no fused multiply-add):
        c = (2 v + 1) << (24 - b)          (integer, < 2^25: the block centre in half cells)
        p = float32(origin) + float32(c) * float32(extent / 2^25)
      Kaitai expressions compute in float64; position_x/y/z below are the float64 block
      centre, within dx(b) = sqrt(3) * extent * 2^-(b+1) metres of the source vertex.
    params:
      - id: level
        type: u1
        doc: Per-buffer level B, 1..24.
      - id: vertex_id
        type: u4[]
        doc: manifest lod.vertex_id (25 entries).
      - id: bit_id
        type: u8[]
        doc: BitId table for level B (25 entries), computed by the reader from vertex_id and B (formula above).
      - id: origin_x
        type: f8
        doc: manifest grid.origin[0], metres.
      - id: origin_y
        type: f8
        doc: manifest grid.origin[1], metres.
      - id: origin_z
        type: f8
        doc: manifest grid.origin[2], metres.
      - id: extent
        type: f8
        doc: manifest grid.extent, metres.
    seq:
      - id: words
        type: u4
        repeat: eos
        doc: The ceil(bit_id[24] / 32) uint32 words of P.
    instances:
      vertices:
        pos: 0
        type: packed_vertex(_index)
        repeat: expr
        repeat-expr: vertex_id[24]
        doc: Vertex j = vertices[j] (each reads its own bits; nothing is consumed).

  packed_vertex:
    doc: Vertex j of a packed_position_buffer (the paper's random access, section 5.3).
    params:
      - id: j
        type: u4
        doc: Vertex index in binned order.
    instances:
      bin:
        value: >-
          1 + (j >= _parent.vertex_id[1] ? 1 : 0) + (j >= _parent.vertex_id[2] ? 1 : 0)
          + (j >= _parent.vertex_id[3] ? 1 : 0) + (j >= _parent.vertex_id[4] ? 1 : 0)
          + (j >= _parent.vertex_id[5] ? 1 : 0) + (j >= _parent.vertex_id[6] ? 1 : 0)
          + (j >= _parent.vertex_id[7] ? 1 : 0) + (j >= _parent.vertex_id[8] ? 1 : 0)
          + (j >= _parent.vertex_id[9] ? 1 : 0) + (j >= _parent.vertex_id[10] ? 1 : 0)
          + (j >= _parent.vertex_id[11] ? 1 : 0) + (j >= _parent.vertex_id[12] ? 1 : 0)
          + (j >= _parent.vertex_id[13] ? 1 : 0) + (j >= _parent.vertex_id[14] ? 1 : 0)
          + (j >= _parent.vertex_id[15] ? 1 : 0) + (j >= _parent.vertex_id[16] ? 1 : 0)
          + (j >= _parent.vertex_id[17] ? 1 : 0) + (j >= _parent.vertex_id[18] ? 1 : 0)
          + (j >= _parent.vertex_id[19] ? 1 : 0) + (j >= _parent.vertex_id[20] ? 1 : 0)
          + (j >= _parent.vertex_id[21] ? 1 : 0) + (j >= _parent.vertex_id[22] ? 1 : 0)
          + (j >= _parent.vertex_id[23] ? 1 : 0)
        doc: |
          Bin k (= minimum level) of vertex j: the k with VertexId[k-1] <= j < VertexId[k],
          i.e. 1 + the number of k' in 1..23 with VertexId[k'] <= j (VertexId is
          non-decreasing). A shader does the same with a branch-free binary search.
      bits:
        value: 'bin > _parent.level ? bin : _parent.level'
        doc: b = max(bin, B), bits per component of this vertex at level B.
      ofs_bit:
        value: 3 * bits * (j - _parent.vertex_id[bin - 1]) + _parent.bit_id[bin - 1]
        doc: o_j, bit offset of the vertex's x field in P.
      x:
        pos: 0
        type: bit_field(ofs_bit, bits)
        doc: Top b bits of the x grid integer.
      y:
        pos: 0
        type: bit_field(ofs_bit + bits, bits)
        doc: Top b bits of the y grid integer.
      z:
        pos: 0
        type: bit_field(ofs_bit + 2 * bits, bits)
        doc: Top b bits of the z grid integer.
      grid_x:
        value: x.value << (24 - bits)
        doc: 24-bit grid integer of x with the 24 - b dropped bits zero.
      grid_y:
        value: y.value << (24 - bits)
        doc: 24-bit grid integer of y with the dropped bits zero.
      grid_z:
        value: z.value << (24 - bits)
        doc: 24-bit grid integer of z with the dropped bits zero.
      position_x:
        value: _parent.origin_x + ((2 * x.value + 1) << (24 - bits)) * (_parent.extent / 33554432.0)
        doc: x in metres, float64 block centre (33554432 = 2^25; see the float32 order above).
      position_y:
        value: _parent.origin_y + ((2 * y.value + 1) << (24 - bits)) * (_parent.extent / 33554432.0)
        doc: y in metres, float64 block centre.
      position_z:
        value: _parent.origin_z + ((2 * z.value + 1) << (24 - bits)) * (_parent.extent / 33554432.0)
        doc: z in metres, float64 block centre.

  bit_field:
    doc: |
      A field of `width` (1..24) bits at bit offset `ofs_bit` of a uint32 word array, least
      significant bit first: (P[w] >> s | P[w+1] << (32 - s)) & (2^width - 1), w = ofs_bit >> 5,
      s = ofs_bit & 31. The second word is read only when the field crosses into it.
    params:
      - id: ofs_bit
        type: u8
        doc: Bit offset of the field's least significant bit.
      - id: width
        type: u1
        doc: Field width in bits, 1..24.
    instances:
      word_lo:
        pos: 4 * (ofs_bit >> 5)
        type: u4
        doc: P[w], the word holding the field's first bit.
      word_hi:
        pos: 4 * ((ofs_bit >> 5) + 1)
        type: u4
        if: (ofs_bit & 31) + width > 32
        doc: P[w+1], read only when the field crosses the word boundary.
      value:
        value: >-
          ((word_lo >> (ofs_bit & 31))
          | ((ofs_bit & 31) + width > 32 ? word_hi << (32 - (ofs_bit & 31)) : 0))
          & ((1 << width) - 1)
        doc: The field's value, 0 .. 2^width - 1.

  cluster_section:
    doc: |
      Section "positions/clusters" (version 3.0 only, files with clustered buffers; it comes
      right before positions/mandatory): uint32 little-endian words, 3 per cluster of every
      clustered buffer in manifest order. Manifest lod.cluster_words = [offset, count] locates
      a buffer's headers in words (count = 3 * clusters, clusters = sum over bins k of
      ceil(|bin k| / N), N = lod.cluster_size). docs/format.md, "Clustered buffers".
    seq:
      - id: headers
        type: cluster_header
        repeat: eos
        doc: The clusters of all clustered buffers; buffer t's are headers[offset_t / 3 ..].

  cluster_header:
    doc: |
      Words 0-2 of a cluster record: per component t (x, y, z) the anchor a_t (the top k_t
      bits every vertex of the cluster shares, a_t < 2^k_t) in bits 0..23 and k_t (0..24) in
      bits 24..28. On the GPU a fourth word follows, ClusterBit[c] at the current level
      (computed by the reader, not stored).
    seq:
      - id: word_x
        type: u4
        doc: a_x | k_x << 24.
      - id: word_y
        type: u4
        doc: a_y | k_y << 24.
      - id: word_z
        type: u4
        doc: a_z | k_z << 24.
    instances:
      k_x:
        value: word_x >> 24
        doc: Common-prefix bits of x, 0..24.
      k_y:
        value: word_y >> 24
        doc: Common-prefix bits of y, 0..24.
      k_z:
        value: word_z >> 24
        doc: Common-prefix bits of z, 0..24.
      a_x:
        value: word_x & 0xffffff
        doc: Anchor of x (its top k_x bits).
      a_y:
        value: word_y & 0xffffff
        doc: Anchor of y.
      a_z:
        value: word_z & 0xffffff
        doc: Anchor of z.

  clustered_position_buffer:
    doc: |
      A clustered buffer P at per-buffer level B (version 3.0, manifest lod.cluster_size = N):
      what positions/mandatory holds for B = 1 and what a renderer keeps in GPU memory.
      Vertices are in cluster order (minimum level, then Morton code of the top 21 bits of
      x, y, z, then source index); bin k is cut into clusters of N (the last may be shorter).
      ClusterId[k] = clusters in bins <= k. Vertex j of bin k: cluster
      c = ClusterId[k-1] + (j - VertexId[k-1]) / N, local index l = (j - VertexId[k-1]) % N.
      b = max(k, B); stored widths w_t = max(0, b - k_t); stride s_c = w_x + w_y + w_z;
      ClusterBit[c] = sum over c' < c of count_c' * s_c'; vertex j's x field at
      o = ClusterBit[c] + l * s_c, y at o + w_x, z at o + w_x + w_y, each LSB first (a 0-bit
      field reads 0). Top b bits: a_t >> (k_t - b) if b <= k_t, else
      (a_t << (b - k_t)) | field_t: exactly q_t >> (24 - b), as in packed_position_buffer.
      P has max(1, ceil(ClusterBit[n_c] / 32)) words (lod.cluster_p_words[B-1]).
    params:
      - id: level
        type: u1
        doc: Per-buffer level B, 1..24.
      - id: vertex_id
        type: u4[]
        doc: manifest lod.vertex_id (25 entries).
      - id: cluster_size
        type: u2
        doc: manifest lod.cluster_size, N in 16..1024.
      - id: cluster_id
        type: u4[]
        doc: ClusterId (25 entries), computed by the reader from vertex_id and N.
      - id: cluster_bit
        type: u8[]
        doc: ClusterBit at level B (one entry per cluster), computed by the reader from the headers.
      - id: headers
        type: u4[]
        doc: The buffer's cluster header words (3 per cluster) from positions/clusters.
    seq:
      - id: words
        type: u4
        repeat: eos
        doc: The uint32 words of the clustered P.
    instances:
      vertices:
        pos: 0
        type: clustered_vertex(_index)
        repeat: expr
        repeat-expr: vertex_id[24]
        doc: Vertex j = vertices[j].

  clustered_vertex:
    doc: Vertex j of a clustered_position_buffer (random access through ClusterId, then one division).
    params:
      - id: j
        type: u4
        doc: Vertex index in cluster order.
    instances:
      bin:
        value: >-
          1 + (j >= _parent.vertex_id[1] ? 1 : 0) + (j >= _parent.vertex_id[2] ? 1 : 0)
          + (j >= _parent.vertex_id[3] ? 1 : 0) + (j >= _parent.vertex_id[4] ? 1 : 0)
          + (j >= _parent.vertex_id[5] ? 1 : 0) + (j >= _parent.vertex_id[6] ? 1 : 0)
          + (j >= _parent.vertex_id[7] ? 1 : 0) + (j >= _parent.vertex_id[8] ? 1 : 0)
          + (j >= _parent.vertex_id[9] ? 1 : 0) + (j >= _parent.vertex_id[10] ? 1 : 0)
          + (j >= _parent.vertex_id[11] ? 1 : 0) + (j >= _parent.vertex_id[12] ? 1 : 0)
          + (j >= _parent.vertex_id[13] ? 1 : 0) + (j >= _parent.vertex_id[14] ? 1 : 0)
          + (j >= _parent.vertex_id[15] ? 1 : 0) + (j >= _parent.vertex_id[16] ? 1 : 0)
          + (j >= _parent.vertex_id[17] ? 1 : 0) + (j >= _parent.vertex_id[18] ? 1 : 0)
          + (j >= _parent.vertex_id[19] ? 1 : 0) + (j >= _parent.vertex_id[20] ? 1 : 0)
          + (j >= _parent.vertex_id[21] ? 1 : 0) + (j >= _parent.vertex_id[22] ? 1 : 0)
          + (j >= _parent.vertex_id[23] ? 1 : 0)
        doc: Bin k of vertex j (as in packed_vertex).
      cluster:
        value: _parent.cluster_id[bin - 1] + (j - _parent.vertex_id[bin - 1]) / _parent.cluster_size
        doc: c, the vertex's cluster.
      local:
        value: (j - _parent.vertex_id[bin - 1]) % _parent.cluster_size
        doc: l, its index inside the cluster.
      bits:
        value: 'bin > _parent.level ? bin : _parent.level'
        doc: b = max(bin, B).
      k_x:
        value: _parent.headers[3 * cluster] >> 24
        doc: k_x of the cluster.
      k_y:
        value: _parent.headers[3 * cluster + 1] >> 24
        doc: k_y of the cluster.
      k_z:
        value: _parent.headers[3 * cluster + 2] >> 24
        doc: k_z of the cluster.
      w_x:
        value: 'bits > k_x ? bits - k_x : 0'
        doc: Stored bits of x.
      w_y:
        value: 'bits > k_y ? bits - k_y : 0'
        doc: Stored bits of y.
      w_z:
        value: 'bits > k_z ? bits - k_z : 0'
        doc: Stored bits of z.
      ofs_bit:
        value: _parent.cluster_bit[cluster] + local * (w_x + w_y + w_z)
        doc: o, bit offset of the vertex's x field.
      field_x:
        pos: 0
        type: bit_field(ofs_bit, w_x)
        if: w_x > 0
        doc: The stored low w_x bits of x.
      field_y:
        pos: 0
        type: bit_field(ofs_bit + w_x, w_y)
        if: w_y > 0
        doc: The stored low w_y bits of y.
      field_z:
        pos: 0
        type: bit_field(ofs_bit + w_x + w_y, w_z)
        if: w_z > 0
        doc: The stored low w_z bits of z.
      x:
        value: >-
          bits <= k_x ? (_parent.headers[3 * cluster] & 0xffffff) >> (k_x - bits)
          : ((_parent.headers[3 * cluster] & 0xffffff) << w_x) | field_x.value
        doc: Top b bits of the x grid integer.
      y:
        value: >-
          bits <= k_y ? (_parent.headers[3 * cluster + 1] & 0xffffff) >> (k_y - bits)
          : ((_parent.headers[3 * cluster + 1] & 0xffffff) << w_y) | field_y.value
        doc: Top b bits of the y grid integer.
      z:
        value: >-
          bits <= k_z ? (_parent.headers[3 * cluster + 2] & 0xffffff) >> (k_z - bits)
          : ((_parent.headers[3 * cluster + 2] & 0xffffff) << w_z) | field_z.value
        doc: Top b bits of the z grid integer.
