"""Connectivity coding of a vertex tree, every variant of the paper selectable.

This work is based on the view-dependent connectivity coding paper
(``shared/papers/view-dependent-connectivity-coding.txt``, "relative encoding of triangle
topology"):

* section 4.1: internal corners as ``n.id - v.id``, the external corner as ``(h, c.id - v'.id)``
  (``v'`` the common ancestor of the owner ``v`` and ``c``, ``h`` their depth difference); the
  compact node numbering of Figure 5(b) (a node's ID is its leftmost leaf's, leaves numbered
  0..n-1 depth first) against VDS preorder numbering (Figure 5(a)); the leftmost-leaf-of-the-
  right-subtree refinement (``b`` coded as ``b.id - b'.id``, applied to ``c`` too);
* section 4.2: bounded Huffman tables (511 most frequent values + escape), separate dictionaries
  for heights and ID differences (and, for relative ID, internal and external differences with
  halved tables);
* section 4.3: tree restructuring (the deeper subtree to the right);
* sections 5 and 6: only the external corners are coded, plus one control bit per ancestor subtri
  corner that reaches a node (which child it follows); the height dictionary carries two special
  symbols, ``NONE`` (no subtri in that slot) and ``NONMANIFOLD`` (followed by the two orientation
  counts and that many external corners);
* the CAME baseline (M. Grabner, "Compressed adaptive multiresolution encoding", 2002), as the
  paper describes it: corners as relative paths (Huffman-coded path length + raw path bits, the
  implied first step omitted). It is measured here, not decoded.

Improvements not in the paper (``PROPOSED_PLUS``): ``candidates`` codes an external corner as
its index among the external corners of the ancestor subtris that reach the node (known to a
top-down decoder, so still dependency-free); ``external="bucket"`` codes a difference as its bit
length, Huffman-coded per height context, plus raw low bits. Tried and measured only:
``control="predicted"`` predicts each control bit from positions of children of ancestors and
Huffman-codes groups of up to 8 mispredictions as ``(1 << g) | xor_bits`` (it costs more than the
raw bits on the corpus; see docs/hierarchy.md).

Record layout (one record per internal node, preorder): see ``docs/hierarchy.md``. A record holds
the node's subtris in two orientation slots (slot 0: ``(a, b, c)`` with ``a`` in the left child,
``b`` in the right; slot 1: ``(b, a, c)``), each as ``H(h | NONE)`` then ``E(diff)`` then (explicit
variants) ``I(a) I(b)``; or ``H(NONMANIFOLD) N(n0) N(n1)`` followed by ``n0 + n1`` subtris; then
the node's control bits. Bits per triangle are measured the paper's way: connectivity only, tree
structure counted apart.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import LopcookError
from .huffman import Table, bitlen, pack_bits
from .tree import Lifting, VertexTree, node_height

NONE = 0
NONMANIFOLD = -1
N_ESC_BITS = 16
CONTROL_MAX = 8  # predicted control patterns longer than this go out raw after an escape


@dataclass(frozen=True)
class Variant:
    """Which coding to use. Defaults are the paper's proposed method (sections 5 and 6).

    numbering : "compact" (Figure 5b) or "vds" (preorder, Figure 5a).
    refine : code ``b`` (and ``c``) against the leftmost leaf of the right subtree.
    restructure : swap children so the deeper subtree is on the right (section 4.3).
    tables : "separate" (heights, external and internal differences apart, halved when both
             difference tables exist) or "single" (one table for all ID differences).
    internal : "explicit" (relative ID, section 4) or "control" (control bits, section 5).
    corner : "id" or "path" (CAME baseline: measurement only).
    control : "raw" (one bit each, the paper) or "predicted" (geometric prediction, ours).
    table_size : entries per table including the escape (512 in the paper).
    candidates : (ours) an external corner equal to the external corner of an ancestor subtri
                 that reaches the node is coded as its index in that arrival-ordered list, by a
                 special height symbol ``-(2 + index)`` (index < 16); needs ``internal="control"``.
    external : "value" (the paper: Huffman over the difference values) or "bucket" (ours: the
               difference's bit length Huffman-coded in one small table per height context
               ``min(h, 16)``, then its bits below the leading one raw).
    """

    numbering: str = "compact"
    refine: bool = True
    restructure: bool = True
    tables: str = "separate"
    internal: str = "control"
    corner: str = "id"
    control: str = "raw"
    table_size: int = 512
    candidates: bool = False
    external: str = "value"

    @property
    def decodable(self) -> bool:
        """Whether :func:`~lopcook.hierarchy.format.encode_hierarchy` can write (and the decoder
        read) this variant; CAME paths and predicted control bits are measured only."""
        return self.corner == "id" and self.control == "raw"


PROPOSED = Variant()
PROPOSED_PLUS = Variant(candidates=True, external="bucket")
RELATIVE_ID = Variant(internal="explicit")
CAME = Variant(corner="path", internal="explicit", numbering="vds", refine=False, restructure=False)

#: Table 1 columns and the ablations the benchmark reports, by name.
VARIANTS = {
    "came": CAME,
    "relative_id_vds_plain": Variant(internal="explicit", numbering="vds", refine=False,
                                     restructure=False, tables="single"),
    "relative_id_compact": Variant(internal="explicit", refine=False, restructure=False,
                                   tables="single"),
    "relative_id_refine": Variant(internal="explicit", restructure=False, tables="single"),
    "relative_id_restructure": Variant(internal="explicit", tables="single"),
    "relative_id": RELATIVE_ID,
    "proposed": PROPOSED,
    "proposed_predicted": Variant(control="predicted"),
    "proposed_candidates": Variant(candidates=True),
    "proposed_bucket": Variant(external="bucket"),
    "proposed_plus": PROPOSED_PLUS,
}
CAND_MAX = 16
H_CONTEXTS = 16


def _check_variant(v: Variant) -> None:
    ok = (v.numbering in ("compact", "vds") and v.tables in ("separate", "single")
          and v.internal in ("explicit", "control") and v.corner in ("id", "path")
          and v.control in ("raw", "predicted") and 4 <= v.table_size <= 1 << 15
          and v.external in ("value", "bucket")
          and (v.internal == "control" or (not v.candidates and v.control == "raw"))
          and (v.external == "value" or (v.corner == "id" and v.numbering == "compact")))
    if not ok:
        raise LopcookError("usage", None, f"invalid hierarchy coding variant {v}",
                           hint="see lopcook.hierarchy.coding.Variant for the allowed values")


@dataclass(frozen=True)
class Layout:
    """Child order and node numbering of a tree for coding.

    left, right : (N,) int64 children after restructuring (-1 for leaves).
    parent, depth, size : (N,) int64; size = number of leaves below.
    lo : (N,) int64 compact ID (leftmost leaf's ID; leaves are numbered 0..n-1 depth first).
    pre : (N,) int64 preorder (VDS) ID over the forest.
    order : (N,) int64 the nodes in preorder (``order[pre[x]] == x``).
    internal_rank : (N,) int64 rank of an internal node among internal nodes in preorder (-1 leaf).
    leaf_vertex : (n,) int64 input vertex of each leaf ID.
    """

    left: np.ndarray
    right: np.ndarray
    parent: np.ndarray
    depth: np.ndarray
    size: np.ndarray
    lo: np.ndarray
    pre: np.ndarray
    order: np.ndarray
    internal_rank: np.ndarray
    leaf_vertex: np.ndarray


def _groups_by_height(left, right):
    h = node_height(left, right)
    internal = np.flatnonzero(left >= 0)
    order = internal[np.argsort(h[internal], kind="stable")]
    return h, np.split(order, np.flatnonzero(np.diff(h[order])) + 1) if order.size else []


def layout(tree: VertexTree, restructure: bool = True) -> Layout:
    """Number the tree's nodes depth first (roots in ``tree.roots`` order), vectorised per level."""
    left = tree.left.astype(np.int64).copy()
    right = tree.right.astype(np.int64).copy()
    N = left.shape[0]
    h, groups = _groups_by_height(left, right)
    if restructure:
        swap = (left >= 0) & (h[np.maximum(left, 0)] > h[np.maximum(right, 0)])
        left[swap], right[swap] = right[swap], left[swap].copy()
    size = np.ones(N, np.int64)
    size[left >= 0] = 0
    for grp in groups:
        size[grp] = size[left[grp]] + size[right[grp]]
    parent = tree.parent.astype(np.int64)
    depth = np.zeros(N, np.int64)
    lo = np.zeros(N, np.int64)
    pre = np.zeros(N, np.int64)
    roots = tree.roots.astype(np.int64)
    lo[roots] = np.cumsum(size[roots]) - size[roots]
    pre[roots] = np.cumsum(2 * size[roots] - 1) - (2 * size[roots] - 1)
    level = roots
    d = 0
    while level.size:
        depth[level] = d
        inner = level[left[level] >= 0]
        L, R = left[inner], right[inner]
        lo[L] = lo[inner]
        lo[R] = lo[inner] + size[L]
        pre[L] = pre[inner] + 1
        pre[R] = pre[inner] + 2 * size[L]
        level = np.concatenate([L, R])
        d += 1
    order = np.empty(N, np.int64)
    order[pre] = np.arange(N)
    is_int = left[order] >= 0
    internal_rank = np.full(N, -1, np.int64)
    internal_rank[order[is_int]] = np.arange(int(is_int.sum()))
    n = tree.n_leaves
    leaf_vertex = np.empty(n, np.int64)
    leaf_vertex[lo[:n]] = np.arange(n)
    return Layout(left, right, parent, depth, size, lo, pre, order, internal_rank, leaf_vertex)


@dataclass(frozen=True)
class Subtris:
    """Per-triangle coding fields (arrays of length m, in coding order: by owner record, rank).

    tri : index into the input triangles. v : owner node. a, b, c : leaf nodes (a under
    left[v], b under right[v], c external). orient : 0 when the input cycle is (a, b, c), 1 when
    (b, a, c). vp : common ancestor of v and c. h : depth[v] - depth[vp]. vleft : v lies under
    left[vp]. rank : position among the owner's subtris. nm : owner is a non-manifold split.
    """

    tri: np.ndarray
    v: np.ndarray
    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    orient: np.ndarray
    vp: np.ndarray
    h: np.ndarray
    vleft: np.ndarray
    rank: np.ndarray
    nm: np.ndarray


def subtris(tree: VertexTree, lay: Layout) -> Subtris:
    """Split every triangle into its owner's internal corners and its external corner."""
    T = tree.triangles.astype(np.int64)
    m = T.shape[0]
    v = tree.owner.astype(np.int64)
    lo_v, sz_v = lay.lo[v], lay.size[v]
    ids = lay.lo[T]  # leaf nodes are vertex indices; their compact id
    inside = (ids >= lo_v[:, None]) & (ids < (lo_v + sz_v)[:, None])
    if not np.all(inside.sum(axis=1) == 2):
        raise LopcookError("encode", None, "a triangle does not have exactly two internal corners",
                           hint="report this mesh")
    ext = np.argmin(inside, axis=1)
    r = np.arange(m)
    c = T[r, ext]
    i1, i2 = (ext + 1) % 3, (ext + 2) % 3
    x1, x2 = T[r, i1], T[r, i2]
    split = lay.lo[lay.right[v]]
    x1_left = lay.lo[x1] < split
    a = np.where(x1_left, x1, x2)
    b = np.where(x1_left, x2, x1)
    # cycle (x1, x2, c) is the input orientation; (a, b, c) matches it when x1 == a
    orient = np.where(x1_left, 0, 1).astype(np.int64)
    lift = Lifting(lay.parent, lay.left, lay.right)
    vp = lift.lca(v, c)
    h = lay.depth[v] - lay.depth[vp]
    child = lift.ancestor(v, h - 1)
    vleft = lay.left[vp] == child
    # record order: by owner's preorder, then orientation, then corner IDs
    key = np.lexsort((lay.lo[b], lay.lo[a], lay.lo[c], orient, lay.pre[v]))
    n0 = np.bincount(v[orient == 0], minlength=lay.left.shape[0])
    n1 = np.bincount(v[orient == 1], minlength=lay.left.shape[0])
    nm_node = (n0 > 1) | (n1 > 1)
    sv = v[key]
    first = np.r_[0, np.flatnonzero(np.diff(sv)) + 1] if m else np.zeros(0, np.int64)
    rank = np.arange(m) - np.repeat(first, np.diff(np.r_[first, m])) if m else np.zeros(0, np.int64)
    return Subtris(tri=key, v=sv, a=a[key], b=b[key], c=c[key], orient=orient[key], vp=vp[key],
                   h=h[key], vleft=vleft[key], rank=rank, nm=nm_node[sv])


class _Tokens:
    """Tokens keyed (record rank, position in record); a token is a table symbol or raw bits."""

    def __init__(self):
        self.sym = {}   # table -> list of (key, value, escbits)
        self.raw = []   # (key, code, nbits)

    def add(self, table, key, value, escbits):
        self.sym.setdefault(table, []).append((np.asarray(key, np.int64), np.asarray(value, np.int64),
                                               np.broadcast_to(np.asarray(escbits, np.int64),
                                                               np.shape(key))))

    def add_raw(self, key, code, nbits):
        self.raw.append((np.asarray(key, np.int64), np.asarray(code, np.uint64),
                         np.broadcast_to(np.asarray(nbits, np.int64), np.shape(key))))


def _key(rank, pos):
    return (np.asarray(rank, np.int64) << 32) | np.asarray(pos, np.int64)


@dataclass(frozen=True)
class Coded:
    """Result of :func:`encode_connectivity`.

    tables : dict name -> Table. data : bytes of all records, concatenated in preorder.
    record_bits : (I,) int64 bits of each internal node's record (preorder).
    bits : dict of measured bit counts: ``records``, ``tables``, ``structure``, and per category.
    """

    variant: Variant
    tables: dict
    data: bytes
    record_bits: np.ndarray
    bits: dict


def table_sizes(variant: Variant) -> dict:
    s = variant.table_size
    explicit = variant.internal == "explicit"
    if variant.tables == "single":
        out = {"H": s, "D": s}
    else:
        out = {"H": s, "E": s // 2 if explicit else s}
        if explicit:
            out["I"] = s // 2
    out["N"] = 64
    if variant.corner == "path":
        out["P"] = 64
    if variant.control == "predicted":
        out["C"] = s
    if variant.external == "bucket":
        for k in range(H_CONTEXTS):
            out[context_table(k)] = 64
    return out


def context_table(k: int) -> str:
    """Table name of the bucket dictionary for height context ``k = min(h, 16) - 1``."""
    return chr(ord("a") + k)


def _table_for(variant, kind):
    if variant.tables == "single" and kind in ("E", "I"):
        return "D"
    return kind


def encode_connectivity(tree: VertexTree, variant: Variant = PROPOSED, lay: Layout | None = None,
                        st: Subtris | None = None) -> Coded:
    """Code the tree's triangles with ``variant``; returns the records and the measured bits.

    Steps: (1) the slot symbols of empty and non-manifold records, (2) the control bits and,
    with ``candidates``, each subtri's candidate index, (3) each subtri's height symbol, (4) its
    corners (ID differences, or CAME paths), (5) the control bits as tokens, (6) the Huffman
    tables and the records packed in (record, position) order."""
    _check_variant(variant)
    if lay is None:
        lay = layout(tree, variant.restructure)
    if st is None:
        st = subtris(tree, lay)
    toks = _Tokens()
    m = st.v.shape[0]
    owner_rank = lay.internal_rank[st.v]
    # position in record
    slotpos = 2 * np.where(st.nm, 3 + st.rank * 4, st.orient * 4)  # even: symbols, odd: raw tails
    depth_bits = bitlen(lay.depth)
    internal, nmn = _slot_tokens(toks, lay, st, depth_bits)
    # control bits (and their sources) first: the candidate lists come from them
    if variant.internal == "control":
        w, bit, ckey, cti, cj = control_bits(lay, st, with_source=True)
    cand = np.full(m, -1, np.int64)
    if variant.candidates and w.size:
        cand = _candidate_index(lay, st, w, cti)
    usec = cand >= 0
    hval = np.where(usec, -2 - cand, st.h)
    toks.add("H", _key(owner_rank, slotpos), hval, depth_bits[st.v])
    if variant.corner == "id":
        _external_tokens(toks, variant, lay, st, owner_rank, slotpos, ~usec)
        if variant.internal == "explicit":
            _explicit_tokens(toks, variant, lay, st, owner_rank, slotpos)
    else:
        _path_tokens(toks, lay, st, owner_rank, slotpos)
    n_control = 0
    if variant.internal == "control":
        n_control = int(w.shape[0])
        if variant.control == "raw":
            toks.add_raw(_key(lay.internal_rank[w], ckey), bit.astype(np.uint64), 1)
        else:
            pred = predict_control(tree, lay, st, w, cti, cj)
            _add_predicted(toks, lay.internal_rank, w, bit ^ pred)
    tables, K, Ln, cat, data, total = _pack_tokens(toks, variant)
    n_int = int(internal.shape[0])
    record_bits = np.bincount(K >> 32, weights=Ln, minlength=n_int).astype(np.int64)
    bits = {"records": int(total),
            "tables": 8 * sum(len(t.to_bytes()) for t in tables.values()),
            "structure": int(lay.left.shape[0]),  # one preorder bit per node (the blob's shape bits)
            "control": int(Ln[cat == "C"].sum()) if variant.control == "predicted" else
            n_control,
            "control_count": n_control,
            "nonmanifold_nodes": int(nmn.sum()),
            "triangles": int(m)}
    for name in tables:
        bits[f"table_{name}"] = int(Ln[cat == name].sum())
    return Coded(variant, tables, data, record_bits, bits)


def _slot_tokens(toks: _Tokens, lay: Layout, st: Subtris, depth_bits: np.ndarray):
    """Tokens of the records' slot structure: ``NONE`` for an empty slot of a manifold record,
    ``NONMANIFOLD`` then the two orientation counts ``N(n0) N(n1)`` for a record with more than
    one subtri of an orientation. Returns (internal nodes (I,), non-manifold flag per node)."""
    L = lay.left
    rank_of = lay.internal_rank
    internal = np.flatnonzero(L >= 0)
    n0 = np.bincount(st.v[st.orient == 0], minlength=L.shape[0])
    n1 = np.bincount(st.v[st.orient == 1], minlength=L.shape[0])
    nmn = (n0 > 1) | (n1 > 1)
    for slot, cnt in ((0, n0), (1, n1)):
        empty = internal[(~nmn[internal]) & (cnt[internal] == 0)]
        toks.add("H", _key(rank_of[empty], slot * 8), np.full(empty.shape, NONE), depth_bits[empty])
    nmi = internal[nmn[internal]]
    toks.add("H", _key(rank_of[nmi], 0), np.full(nmi.shape, NONMANIFOLD), depth_bits[nmi])
    if np.any(n0[nmi] >= 1 << N_ESC_BITS) or np.any(n1[nmi] >= 1 << N_ESC_BITS):
        raise LopcookError("encode", None, "a node owns more than 65535 triangles of one orientation",
                           hint="split the part")
    toks.add("N", _key(rank_of[nmi], 2), n0[nmi], N_ESC_BITS)
    toks.add("N", _key(rank_of[nmi], 4), n1[nmi], N_ESC_BITS)
    return internal, nmn


def _candidate_index(lay: Layout, st: Subtris, w: np.ndarray, cti: np.ndarray) -> np.ndarray:
    """(m,) int64 per subtri: the index of its external corner among the distinct external
    corners of the ancestor subtris whose control bits reach its owner (in arrival order), or
    -1 when it is not among them or the index is ``CAND_MAX`` or more. ``w``, ``cti``: the
    control bits' nodes and source subtris (:func:`control_bits` with ``with_source``)."""
    n_ids = int(lay.lo.max()) + 1
    ck = w * n_ids + lay.lo[st.c[cti]]
    _, first = np.unique(ck, return_index=True)
    first = np.sort(first)  # arrival order (entries are sorted by record, then key)
    dw, dk = w[first], ck[first]
    gs = np.r_[0, np.flatnonzero(np.diff(dw)) + 1]
    idx = np.arange(dw.shape[0]) - np.repeat(gs, np.diff(np.r_[gs, dw.shape[0]]))
    o = np.argsort(dk)
    sk = st.v * n_ids + lay.lo[st.c]
    j = np.minimum(np.searchsorted(dk[o], sk), max(dk.shape[0] - 1, 0))
    hit = dk[o][j] == sk
    cand = np.where(hit, idx[o][j], -1)
    cand[cand >= CAND_MAX] = -1
    return cand


def _external_tokens(toks: _Tokens, variant: Variant, lay: Layout, st: Subtris, owner_rank, slotpos, keep):
    """The external difference ``c.id - base`` of the subtris ``keep`` (those not coded as a
    candidate), against the range below their common ancestor ``vp`` (its other child's subtree
    when refining): one ``E`` symbol, or (bucket) a bit-length symbol per height context and
    the bits below the leading one raw."""
    compact = variant.numbering == "compact"
    ident = lay.lo if compact else lay.pre
    L, R, size = lay.left, lay.right, lay.size
    vp = st.vp
    if compact:
        if variant.refine:
            base = np.where(st.vleft, lay.lo[R[vp]], lay.lo[vp])
            rng = np.where(st.vleft, size[R[vp]], size[L[vp]])
        else:
            base, rng = lay.lo[vp], size[vp]
    else:
        if variant.refine:
            base = np.where(st.vleft, lay.pre[R[vp]], lay.pre[vp])
            rng = np.where(st.vleft, 2 * size[R[vp]] - 1, 2 * size[L[vp]] + 1)
        else:
            base, rng = lay.pre[vp], 2 * size[vp] - 1
    ediff = ident[st.c] - base
    if variant.external == "value":
        toks.add(_table_for(variant, "E"), _key(owner_rank[keep], slotpos[keep] + 2), ediff[keep],
                 bitlen(rng - 1)[keep])
        return
    bk = bitlen(ediff)
    ctx = np.minimum(st.h, H_CONTEXTS) - 1
    for k in np.unique(ctx[keep]).tolist():
        sel = keep & (ctx == k)
        toks.add(context_table(k), _key(owner_rank[sel], slotpos[sel] + 2), bk[sel],
                 bitlen(bitlen(rng - 1))[sel])
    mant = keep & (bk >= 2)
    toks.add_raw(_key(owner_rank[mant], slotpos[mant] + 3),
                 (ediff[mant] - (np.int64(1) << (bk[mant] - 1))).astype(np.uint64),
                 bk[mant] - 1)


def _explicit_tokens(toks: _Tokens, variant: Variant, lay: Layout, st: Subtris, owner_rank, slotpos):
    """Relative ID (explicit variants): the internal corners as ``I`` differences against the
    owner (``a``) and against the right child when refining (``b``)."""
    compact = variant.numbering == "compact"
    ident = lay.lo if compact else lay.pre
    L, R, size = lay.left, lay.right, lay.size
    v = st.v
    ia = ident[st.a] - ident[v]
    ra = size[L[v]] if compact else 2 * size[L[v]] + 1
    if variant.refine:
        ib = ident[st.b] - ident[R[v]]
        rb = size[R[v]] if compact else 2 * size[R[v]] - 1
    else:
        ib = ident[st.b] - ident[v]
        rb = size[v] if compact else 2 * size[v]
    tb = _table_for(variant, "I")
    toks.add(tb, _key(owner_rank, slotpos + 4), ia, bitlen(ra - 1))
    toks.add(tb, _key(owner_rank, slotpos + 6), ib, bitlen(rb - 1))


def _path_tokens(toks: _Tokens, lay: Layout, st: Subtris, owner_rank, slotpos):
    """CAME-like relative paths: per corner a path-length symbol ``P`` and the path's raw bits
    (the implied first step omitted; measured only, so the bits are zeros of the right count)."""
    L, R, depth = lay.left, lay.right, lay.depth
    m = st.v.shape[0]
    side = np.where(st.vleft, R[st.vp], L[st.vp])
    lc = depth[st.c] - depth[side]
    pb = bitlen(int(depth.max()))
    toks.add("P", _key(owner_rank, slotpos + 2), lc, pb)
    toks.add_raw(_key(owner_rank, slotpos + 3), np.zeros(m, np.uint64), lc)
    for j, (x, ch) in enumerate(((st.a, L[st.v]), (st.b, R[st.v]))):
        lx = depth[x] - depth[ch]
        toks.add("P", _key(owner_rank, slotpos + 4 + 2 * j), lx, pb)
        toks.add_raw(_key(owner_rank, slotpos + 5 + 2 * j), np.zeros(m, np.uint64), lx)


def _pack_tokens(toks: _Tokens, variant: Variant):
    """Build one bounded Huffman table per symbol stream (empty ``H E I D N`` tables the
    variant names too), code every token and pack all of them in (record, position) order.

    Returns (tables, K keys, Ln bit lengths, cat table name or "raw" per token, data, total
    bits), the token arrays in packing order."""
    sizes = table_sizes(variant)
    tables = {}
    keys, codes, lens, cats = [], [], [], []
    for name, lst in sorted(toks.sym.items()):
        k = np.concatenate([x[0] for x in lst])
        val = np.concatenate([x[1] for x in lst])
        eb = np.concatenate([np.asarray(x[2]).reshape(-1) for x in lst])
        force = tuple(sorted({NONE, NONMANIFOLD} | set(np.unique(val[val < 0]).tolist()))) \
            if name == "H" else ()
        t = Table.build(val, sizes[name], force=force)
        tables[name] = t
        cd, ln = t.encode(val, eb)
        keys.append(k), codes.append(cd), lens.append(ln), cats.append(np.full(k.shape, name, object))
    for name in ("H", "E", "I", "D", "N"):
        if name in sizes and name not in tables:
            tables[name] = Table.build(np.zeros(0, np.int64), sizes[name],
                                       force=(NONE, NONMANIFOLD) if name == "H" else ())
    for k, cd, nb in toks.raw:
        keys.append(k), codes.append(cd), lens.append(nb), cats.append(np.full(k.shape, "raw", object))
    K = np.concatenate(keys)
    C = np.concatenate(codes)
    Ln = np.concatenate(lens)
    cat = np.concatenate(cats)
    order = np.argsort(K, kind="stable")
    K, C, Ln, cat = K[order], C[order], Ln[order], cat[order]
    data, total = pack_bits(C, Ln)
    return tables, K, Ln, cat, data, total


def control_bits(lay: Layout, st: Subtris, with_source: bool = False):
    """All control bits: (w node, bit, key in record) sorted by record and key.

    For the internal corner ``x`` of a subtri owned by ``A``, every internal node ``w`` strictly
    between ``A`` and the leaf ``x`` carries one bit: 1 when ``x`` follows ``right[w]``. Within
    ``w`` the bits are ordered by (depth of ``A``, rank of the subtri in ``A``'s record), which is
    the order in which a top-down decoder sees the corners arrive. With ``with_source`` also the
    subtri index (into ``st``) and which corner (0: ``a``, 1: ``b``) each bit belongs to.
    """
    P = lay.parent
    ws, bs, ks, ts, cs = [], [], [], [], []
    base = (1 << 31) | (lay.depth[st.v] << 20) | st.rank
    m_all = np.arange(st.v.shape[0])
    for j, x in enumerate((st.a, st.b)):
        prev = x.copy()
        cur = P[x]
        kb = base.copy()
        A = st.v
        ti = m_all
        m = cur != A
        prev, cur, kb, A, ti = prev[m], cur[m], kb[m], A[m], ti[m]
        while cur.size:
            ws.append(cur)
            bs.append((lay.right[cur] == prev).astype(np.int64))
            ks.append(kb)
            ts.append(ti)
            cs.append(np.full(cur.shape, j, np.int64))
            prev = cur
            cur = P[cur]
            m = cur != A
            prev, cur, kb, A, ti = prev[m], cur[m], kb[m], A[m], ti[m]
    if not ws:
        z = np.zeros(0, np.int64)
        return (z, z, z, z, z) if with_source else (z, z, z)
    w = np.concatenate(ws)
    b = np.concatenate(bs)
    k = np.concatenate(ks)
    o = np.lexsort((k, lay.pre[w]))
    if with_source:
        return w[o], b[o], k[o], np.concatenate(ts)[o], np.concatenate(cs)[o]
    return w[o], b[o], k[o]


def predict_control(tree, lay, st, w, cti, cj):
    """Predicted control bit of each control entry, from positions the client holds.

    For the corner of subtri ``t`` (owner ``A``) arriving at ``w``: ``q = P[o] + P[s]`` where
    ``o`` is ``A``'s child holding the subtri's other internal corner and ``s`` the child of the
    common ancestor ``v'`` that holds its external corner (both children of ancestors of ``w``:
    no sibling data is used). The prediction is 1 when ``|2 P[right[w]] - q|^2 <
    |2 P[left[w]] - q|^2`` (exact integers; a tie predicts 0).
    """
    P = tree.node_positions.astype(np.int64)
    A = st.v[cti]
    other = np.where(cj == 0, lay.right[A], lay.left[A])
    vp = st.vp[cti]
    cside = np.where(st.vleft[cti], lay.right[vp], lay.left[vp])
    q = P[other] + P[cside]
    dr = ((2 * P[lay.right[w]] - q) ** 2).sum(axis=1)
    dl = ((2 * P[lay.left[w]] - q) ** 2).sum(axis=1)
    return (dr < dl).astype(np.int64)


def _add_predicted(toks, rank_of, w, xbits):
    """Misprediction bits per node in groups of up to 8, each one symbol ``(1 << g) | bits``."""
    if not w.size:
        return
    gs = np.r_[0, np.flatnonzero(np.diff(w)) + 1]
    cnt = np.diff(np.r_[gs, w.shape[0]])
    j = np.arange(w.shape[0]) - np.repeat(gs, cnt)
    k = np.repeat(cnt, cnt)
    chunk = j // CONTROL_MAX
    g = np.minimum(CONTROL_MAX, k - chunk * CONTROL_MAX)
    inpos = j % CONTROL_MAX
    first = inpos == 0
    gid = np.cumsum(first) - 1
    val = np.zeros(int(first.sum()), np.int64)
    np.add.at(val, gid, xbits.astype(np.int64) << (g - 1 - inpos))
    gg = g[first]
    val |= np.int64(1) << gg
    toks.add("C", _key(rank_of[w[first]], (1 << 31) | chunk[first]), val, gg + 1)


def measure(tree: VertexTree, variant: Variant = PROPOSED) -> dict:
    """Bits per triangle of ``variant`` on ``tree``: records (+ tables) and structure, apart."""
    coded = encode_connectivity(tree, variant)
    b = coded.bits
    m = max(b["triangles"], 1)
    return {"bits_per_triangle": b["records"] / m,
            "bits_per_triangle_with_tables": (b["records"] + b["tables"]) / m,
            "structure_bits_per_triangle": b["structure"] / m,
            "control_bits_per_triangle": b["control"] / m, **b}
