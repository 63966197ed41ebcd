"""The hierarchy in the .lop container: one ``partI/lod0/hierarchy`` section per part, and the
view-dependent cut read back from it (``lopcook cook --hierarchy``, ``lopcook refine``).

Design (docs/format.md, *Hierarchy sections*; docs/hierarchy.md):

* The tree is built on the part's **LOD 0 buffer as stored**: its grid integers in binned order
  and its remapped indices (``lopcook.emit.EncodedBuffer``), on the scene grid. Leaves are that
  buffer's vertices, and every internal node sits on the position of one leaf of its subtree (its
  representative, ``lopcook.hierarchy.tree``). So **node positions are LOD 0's positions**: the
  section stores none (``encode_hierarchy(..., store_positions=False)``), only the leaf -> buffer
  vertex map (``index_width(n)`` bits per leaf) and one representative bit per internal node.
  The positions stay on the LOP bit planes, after every other section: the prefix property holds.
* **A node's minimum level is its representative vertex's m_v.** The node *is* that vertex, so
  at every per-buffer level B it decodes bit for bit as LOD 0 does; co-located vertices share
  their level (``lopcook.pipeline``, step 3), so co-located nodes decode to the same point at
  every level and no cut can crack apart from LOD 0, from another part or from another cut.
* The section is the blob of ``encode_hierarchy`` (``PROPOSED_PLUS``), whose own CRC-32 is
  checked again on read, on top of the container's section CRC.

``refine(container, camera, target, ...)`` selects the cut of every part that has a section
(``select_cut``), decodes only the split nodes' records and the position planes up to the level
the camera needs, and returns meshes ready for ``lopcook.emit.gltf_writer.write_gltf``.
"""

from __future__ import annotations

import numpy as np

from ..lop.indices import decode_indices
from ..lop.summary import hierarchy_stats
from ..lop.reader import decode_positions, lod_attributes, top_values
from ..errors import LopcookError
from ..grid import BITS
from ..viewing import Viewing, required_level
from .coding import PROPOSED_PLUS, VARIANTS
from .format import decode_hierarchy, encode_hierarchy, index_width
from .select import select_cut
from .tree import build_tree, drop_degenerate

VARIANT_NAME = "proposed_plus"
VARIANT = VARIANTS[VARIANT_NAME]
assert VARIANT == PROPOSED_PLUS


def section_name(part: int) -> str:
    return f"part{part}/lod0/hierarchy"


def encode_part(encoded, grid) -> tuple[bytes, dict]:
    """(section payload, manifest record) of one part's LOD 0 ``EncodedBuffer`` on ``grid``.

    The record: ``section``, ``lod`` (0), ``variant``, ``leaves``, ``nodes``, ``roots``,
    ``triangles`` (coded; triangles that repeat a vertex index are left out and counted in
    ``degenerate_triangles``), ``connectivity_bits`` (the records, the paper's measure),
    ``structure_bits`` (one per node: the preorder shape), ``record_index_bits``, ``table_bits``
    (Huffman tables), ``vertex_map_bits`` and ``representative_bits`` (what places the nodes on
    LOD 0's vertices), ``selection_bits`` (error, normal cone and reach radius, 112 per node,
    and one boundary bit per leaf, padded to bytes)."""
    e = encoded.entry
    raw = dict(encoded.attributes)["indices"]
    width = int(e["index_width"])
    m = int(e["triangles"])
    tri = decode_indices(np.frombuffer(raw, "<u2" if width == 2 else "<u4")[:3 * m], width, m).astype(np.int64)
    kept = drop_degenerate(tri)
    step = float(grid.extent) / float(1 << BITS)
    tree = build_tree(encoded.q, kept, grid=(np.asarray(grid.origin, np.float64), step))
    blob = encode_hierarchy(tree, variant=VARIANT, store_positions=False, store_reach=True, store_open=True)
    h = decode_hierarchy(blob, positions=encoded.q)
    n, N = h.n_leaves, h.n_nodes
    internal = n - int(h.roots.shape[0])
    rec_index = sum(8 * _varint_len(int(b)) for b in np.diff(h.record_starts).tolist())
    tables = sum(8 * len(t.to_bytes()) + 8 for t in h.tables.values())
    record = {"section": None, "lod": 0, "variant": VARIANT_NAME, "leaves": int(n), "nodes": int(N),
              "roots": int(h.roots.shape[0]), "triangles": int(kept.shape[0]),
              "degenerate_triangles": int(m - kept.shape[0]), "connectivity_bits": int(h.bits["connectivity"]),
              "structure_bits": int(N), "record_index_bits": int(rec_index), "table_bits": int(tables),
              "vertex_map_bits": int(n * index_width(n)), "representative_bits": int(internal),
              "selection_bits": int(112 * N + 8 * ((n + 7) // 8))}
    return blob, record


def _varint_len(x: int) -> int:
    return max(1, (int(x).bit_length() + 6) // 7)


def add_hierarchy(manifest: dict, sections: list, lod0: list, grid, cache: dict | None = None):
    """``(manifest, sections)`` with one hierarchy section per part inserted right before
    ``positions/mandatory`` (so the position sections stay last) and ``parts[i].hierarchy``
    recorded. ``lod0``: per part its LOD 0 ``EncodedBuffer``. ``cache``: id(EncodedBuffer) ->
    (blob, record), shared between the containers of one cook. Inputs are not changed."""
    cache = {} if cache is None else cache
    parts = []
    extra = []
    for i, (part, enc) in enumerate(zip(manifest["parts"], lod0)):
        if id(enc) not in cache:
            cache[id(enc)] = encode_part(enc, grid)
        blob, record = cache[id(enc)]
        name = section_name(i)
        parts.append(dict(part, hierarchy=dict(record, section=name)))
        extra.append((name, blob))
    at = next(k for k, (name, _) in enumerate(sections) if name.startswith("positions/"))
    return dict(manifest, parts=parts), sections[:at] + extra + sections[at:]


def part_stats(c, part: int) -> dict | None:
    """``lopcook.lop.summary.hierarchy_stats``: inspect's figures of one part's hierarchy."""
    return hierarchy_stats(c, part)


def read_part(c, part: int, level: int | None = None):
    """``(Hierarchy, grid (n, 3) uint32, level)`` of part ``part``: its section decoded with
    LOD 0's positions at per-buffer level ``level`` (default: the file's available level)."""
    parts = c.manifest["parts"]
    if not 0 <= part < len(parts) or parts[part].get("hierarchy") is None:
        raise LopcookError("usage", c.path, f"part {part} has no hierarchy section",
                           hint="cook the source with lopcook cook --hierarchy")
    level = c.available_level if level is None else int(level)
    q, _, _ = decode_positions(c, part, 0, level)
    return _decode(c, part, q), q, level


def _decode(c, part: int, q):
    blob = c.section(c.manifest["parts"][part]["hierarchy"]["section"])
    try:
        return decode_hierarchy(blob, positions=q)
    except LopcookError as exc:
        raise LopcookError("emit", c.path, f"part {part}: {exc.message}", hint=exc.hint) from None


def part_level(c, part: int, eye, viewing: Viewing) -> int:
    """The per-buffer level the camera at ``eye`` needs for part ``part`` (the half-pixel
    criterion of ``lopcook.viewing.required_level`` at the distance to the part's bounds),
    computed from the mandatory bits alone: every vertex lies in its level-1 block, so the
    blocks' bounding box is a conservative bound. Capped at the file's available level."""
    values, widths = top_values(c, part, 0, 1)
    shift = (BITS - widths.astype(np.int64))[:, None]
    lo = values.astype(np.int64) << shift
    hi = (values.astype(np.int64) + 1) << shift
    g = c.manifest["grid"]
    cell = float(g["extent"]) / float(1 << BITS)
    blo = np.asarray(g["origin"]) + lo.min(axis=0) * cell
    bhi = np.asarray(g["origin"]) + hi.max(axis=0) * cell
    d = float(np.linalg.norm(np.maximum(np.maximum(blo - eye, eye - bhi), 0.0)))
    return int(min(int(np.asarray(required_level(d, float(g["extent"]), viewing))), c.available_level))


def refine(c, camera, target, *, fov: float = 60.0, viewport=(1920, 1080), pixel_error: float = 0.5,
           up=(0.0, 1.0, 0.0), backface: bool = True) -> list[dict]:
    """The view-dependent meshes of every part with a hierarchy, for one camera.

    Per part: the positions are decoded at ``part_level`` (the planes the camera needs), the cut
    is selected by ``select_cut`` (frustum, back-face and ``pixel_error`` pixels of projected
    error at ``fov`` degrees and ``viewport`` (w, h) pixels) and only the split nodes' records
    are decoded. ``backface``: Hoppe's back-face test (on by default; False also refines
    back-facing regions, whose coarse triangles can show at silhouettes of thin or multi-part
    assets; docs/hierarchy.md, section 7). Each mesh: ``name``, ``positions`` (k, 3) float32 metres (the cut vertices as
    the shaders decode them at that level), ``indices`` (t, 3) counter-clockwise, ``normals`` /
    ``uvs`` / ``colors`` of each node's representative vertex (or None), and ``stats`` (level,
    split nodes, cut vertices, triangles, LOD 0 triangles)."""
    parts = c.manifest["parts"]
    have = [i for i, p in enumerate(parts) if p.get("hierarchy") is not None]
    if not have:
        raise LopcookError("usage", c.path, "the container has no hierarchy sections",
                           hint="cook the source with lopcook cook --hierarchy")
    eye = np.asarray(camera, np.float64)
    try:
        viewing = Viewing(viewport=(int(viewport[0]), int(viewport[1])), fov_y_deg=float(fov),
                          pixel_error=float(pixel_error))
    except ValueError as exc:
        raise LopcookError("usage", c.path, str(exc), hint="use e.g. --fov 60 --viewport 1920x1080 --pixel-error 0.5")
    meshes = []
    for i in have:
        level = part_level(c, i, eye, viewing)
        q, _, pos = decode_positions(c, i, 0, level)
        h = _decode(c, i, q)
        cut = select_cut(h, camera, target, fov=fov, viewport=viewport, pixel_error=pixel_error, up=up,
                         backface=backface)
        vert = h.vertex_of_leaf[h.node_leaf[cut.nodes]]
        a = lod_attributes(c, i, 0, unit_directions=True)
        meshes.append({"name": parts[i]["name"], "positions": pos[vert], "indices": cut.triangles,
                       "normals": None if a["normals"] is None else a["normals"][vert],
                       "uvs": None if a["uvs"] is None else a["uvs"][vert],
                       "colors": None if a["colors"] is None else a["colors"][vert],
                       "stats": {"level": level, "split_nodes": int(cut.split.shape[0]),
                                 "vertices": int(cut.nodes.shape[0]), "triangles": int(cut.triangles.shape[0]),
                                 "lod0_triangles": int(parts[i]["lods"][0]["triangles"])}})
    return meshes
