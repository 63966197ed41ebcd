"""Serialisation of a coded vertex hierarchy: ``encode_hierarchy(...) -> bytes`` and back.

Self-delimiting and versioned; the byte layout is documented field by field in
``docs/hierarchy.md`` (all integers little-endian). The blob holds the tree structure (one
preorder bit per node), the node positions (leaf grid coordinates plus one representative bit
per internal node), the per-node selection data (error, normal cone), the Huffman tables, the
per-record bit lengths (the random-access index) and the coded connectivity, closed by a CRC-32
of everything before it. ``decode_hierarchy`` checks the CRC, every count and the tree shape
before anything is decoded, and raises ``LopcookError`` (stage ``"decode"``) on any mismatch.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass

import numpy as np

from ..errors import LopcookError
from . import coding as C
from .decode import decode_records
from .huffman import Table, get_varint, get_varints, put_varint
from .tree import VertexTree, build_tree

MAGIC = b"LOPH"
VERSION = 1
_HINT = "the hierarchy data is corrupt or truncated; re-encode it"
_TABLE_NAMES = ["H", "E", "I", "D", "N", "C"] + [C.context_table(k) for k in range(C.H_CONTEXTS)]
_LIST_FIELDS = frozenset(f + "_l" for f in ("left", "right", "parent", "depth", "size", "lo", "rank",
                                            "record_starts"))


def _fail(msg: str):
    raise LopcookError("decode", None, f"hierarchy: {msg}", hint=_HINT)


def _variant_flags(v: C.Variant) -> int:
    return ((v.numbering == "vds") << 0 | (not v.refine) << 1 | (not v.restructure) << 2
            | (v.tables == "single") << 3 | (v.internal == "explicit") << 4
            | (v.control == "predicted") << 5 | v.candidates << 6 | (v.external == "bucket") << 7)


def _variant_from(flags: int, table_size: int) -> C.Variant:
    if flags & 32:
        _fail(f"unsupported variant flags {flags:#x} (predicted control bits)")
    return C.Variant(numbering="vds" if flags & 1 else "compact", refine=not flags & 2,
                     restructure=not flags & 4, tables="single" if flags & 8 else "separate",
                     internal="explicit" if flags & 16 else "control",
                     control="predicted" if flags & 32 else "raw", table_size=table_size,
                     candidates=bool(flags & 64), external="bucket" if flags & 128 else "value")


@dataclass
class Hierarchy:
    """A decoded hierarchy blob; connectivity stays coded until asked for.

    Nodes are numbered in preorder (``0..N-1``; a node's subtree is ``[k, k + 2*size[k] - 1)``).
    Leaf IDs ``0..n-1`` number the leaves left to right; ``leaf_node[i]`` is leaf ``i``'s node.

    Attributes
    ----------
    n_leaves, n_nodes, n_triangles : int
    variant : Variant
    left, right, parent, depth, size, lo : (N,) int64 (``-1`` children / parent where none)
    positions : (n, 3) uint32 grid coordinates of the leaves (by leaf ID)
    node_leaf : (N,) int64 representative leaf of each node (its position)
    error, cone_angle : (N,) float32; cone_axis : (N, 3) float32 (see ``tree.VertexTree``;
        quantised conservatively: the error rounded up, the cone widened to cover its
        quantised axis, axis zero and angle pi where no cone is usable)
    vertex_of_leaf : (n,) int64 input vertex index of each leaf, or None when not stored
    origin (3,), step : grid coordinate ``q`` lies at ``origin + (q + 0.5) * step`` (world units)
    reach : (N,) float32 or None: radius (grid cells) of the triangles each node's refinement
        affects (``tree.VertexTree.reach``), when the blob stores it
    open_leaf : (n,) bool or None: leaves on the oriented boundary chain
        (``tree.VertexTree.open_vertex``), when the blob stores them; ``node_open`` lifts them
        to every node
    tables : dict name -> Table; data : bytes; record_starts : (I + 1,) int64 bit offsets
    """

    n_leaves: int
    n_nodes: int
    n_triangles: int
    variant: C.Variant
    left: np.ndarray
    right: np.ndarray
    parent: np.ndarray
    depth: np.ndarray
    size: np.ndarray
    lo: np.ndarray
    positions: np.ndarray
    node_leaf: np.ndarray
    error: np.ndarray
    cone_axis: np.ndarray
    cone_angle: np.ndarray
    vertex_of_leaf: np.ndarray | None
    tables: dict
    data: bytes
    record_starts: np.ndarray
    rank: np.ndarray
    bits: dict
    origin: np.ndarray
    step: float
    reach: np.ndarray | None = None
    open_leaf: np.ndarray | None = None

    def __getattr__(self, name):
        # ``left_l`` ... ``record_starts_l``: Python lists of those arrays for the per-node
        # decoder, made on first use
        if name in _LIST_FIELDS:
            v = getattr(self, name[:-2]).tolist()
            object.__setattr__(self, name, v)
            return v
        raise AttributeError(name)

    @property
    def internal_nodes(self) -> np.ndarray:
        return np.flatnonzero(self.left >= 0)

    @property
    def node_positions(self) -> np.ndarray:
        """(N, 3) uint32 grid position of every node (computed once)."""
        if getattr(self, "_node_positions", None) is None:
            self._node_positions = self.positions[self.node_leaf]
        return self._node_positions

    @property
    def node_open(self) -> np.ndarray | None:
        """(N,) bool: the node's subtree holds a leaf of ``open_leaf`` (None when not stored;
        computed once)."""
        if self.open_leaf is None:
            return None
        c = getattr(self, "_node_open", None)
        if c is None or c[0] is not self.open_leaf:
            cs = np.r_[0, np.cumsum(self.open_leaf, dtype=np.int64)]
            c = (self.open_leaf, cs[self.lo + self.size] - cs[self.lo] > 0)
            self._node_open = c
        return c[1]

    @property
    def roots(self) -> np.ndarray:
        return np.flatnonzero(self.parent < 0)

    def leaf_nodes(self) -> np.ndarray:
        out = np.empty(self.n_leaves, np.int64)
        leaves = np.flatnonzero(self.left < 0)
        out[self.lo[leaves]] = leaves
        return out

    def triangles(self, input_vertices: bool = True) -> np.ndarray:
        """(m, 3) int64 all triangles, in record order; input vertex indices when stored."""
        _, tri = decode_records(self, self.internal_nodes.tolist())
        if (tri < 0).any():
            _fail("a corner was left unresolved after decoding every record")
        if input_vertices and self.vertex_of_leaf is not None:
            return self.vertex_of_leaf[tri]
        return tri

    def ancestors(self, node: int) -> list[int]:
        out = []
        p = int(self.parent[node])
        while p >= 0:
            out.append(p)
            p = int(self.parent[p])
        return out[::-1]

    def decode_subtree(self, node: int):
        """Subtris of ``node``'s subtree, decoded from the records of its ancestors and subtree only.

        Returns (owner (t,), corners (t, 3) leaf IDs) for the subtris owned by nodes in the
        subtree (all corners resolved: the subtree's own records suffice for its internal
        corners, external corners are explicit).
        """
        node = int(node)
        if not 0 <= node < self.n_nodes:
            raise LopcookError("usage", None, f"node {node} outside [0, {self.n_nodes})",
                               hint="pass a preorder node index of this hierarchy")
        sub = np.arange(node, node + 2 * self.size[node] - 1)
        sub = sub[self.left[sub] >= 0]
        nodes = self.ancestors(node) + sub.tolist()
        own, tri = decode_records(self, nodes)
        keep = (own >= node) & (own < node + 2 * self.size[node] - 1)
        return own[keep], tri[keep]



def _oct_encode(axis: np.ndarray) -> np.ndarray:
    """(N, 3) unit (or zero) vectors -> (N, 2) int16 octahedral coordinates."""
    a = np.asarray(axis, np.float64)
    l1 = np.abs(a).sum(axis=1)
    l1[l1 == 0] = 1.0
    p = a / l1[:, None]
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    ox = np.where(z >= 0, x, (1 - np.abs(y)) * np.sign(x + (x == 0)))
    oy = np.where(z >= 0, y, (1 - np.abs(x)) * np.sign(y + (y == 0)))
    return np.clip(np.round(np.stack([ox, oy], axis=1) * 32767), -32767, 32767).astype(np.int16)


def _oct_decode(q: np.ndarray) -> np.ndarray:
    """(N, 2) int16 octahedral coordinates -> (N, 3) unit vectors."""
    o = np.asarray(q, np.float64) / 32767
    x, y = o[:, 0], o[:, 1]
    z = 1 - np.abs(x) - np.abs(y)
    t = np.maximum(-z, 0)
    x = x - t * np.sign(x + (x == 0))
    y = y - t * np.sign(y + (y == 0))
    v = np.stack([x, y, z], axis=1)
    return v / np.linalg.norm(v, axis=1)[:, None]


def _pack_selection(error, axis, angle):
    """Per-node selection data, conservatively quantised: f32 error rounded up, octahedral int16
    axis, u16 half-angle rounded up and widened by the axis' quantisation error (65535 = pi, no
    usable cone)."""
    err = np.asarray(error, np.float64)
    e32 = err.astype(np.float32)
    low = e32.astype(np.float64) < err
    e32[low] = np.nextafter(e32[low], np.float32(np.inf))
    q = _oct_encode(axis)
    dec = _oct_decode(q)
    has = np.linalg.norm(axis, axis=1) > 0.5
    delta = np.zeros(err.shape[0])
    delta[has] = np.arccos(np.clip(np.einsum("ij,ij->i", dec[has], axis[has]), -1, 1))
    ang = np.where(has, np.asarray(angle, np.float64) + delta + 1e-6, np.pi)
    qa = np.minimum(np.ceil(ang / np.pi * 65535), 65535).astype(np.uint16)
    q[~has] = 0
    return e32.astype("<f4").tobytes() + q.astype("<i2").tobytes() + qa.astype("<u2").tobytes()


def _round_up_f32(x) -> np.ndarray:
    x = np.asarray(x, np.float64)
    f = x.astype(np.float32)
    low = f.astype(np.float64) < x
    f[low] = np.nextafter(f[low], np.float32(np.inf))
    return f


def _unpack_selection(body, p, N):
    error = np.frombuffer(body, "<f4", N, p).astype(np.float32)
    p += 4 * N
    q = np.frombuffer(body, "<i2", 2 * N, p).reshape(N, 2)
    p += 4 * N
    qa = np.frombuffer(body, "<u2", N, p).astype(np.float64)
    p += 2 * N
    angle = (qa / 65535 * np.pi).astype(np.float32)
    axis = _oct_decode(q).astype(np.float32)
    axis[qa == 65535] = 0.0
    angle[qa == 65535] = np.float32(np.pi)
    if not np.isfinite(error).all() or (error < 0).any():
        _fail("node errors are not finite and non-negative")
    return error, axis, angle, p


def _shape_arrays(isint: np.ndarray, n_roots: int):
    """Preorder internal/leaf bits -> left, right, parent, depth, size, lo (validated).

    Vectorised with the preorder excess ``S(k) = sum_{j<k} (2 isint_j - 1)``: a full binary
    subtree starting at ``k`` nets -1, so it ends right before the first ``j > k`` with
    ``S(j) = S(k) - 1``, an internal node's left child is ``u + 1`` and its right child the
    first ``j > u`` with ``S(j) = S(u)``; a tree of the forest starts wherever ``S`` reaches a
    new minimum. Same result as :func:`_shape_arrays_scalar`."""
    b = np.asarray(isint).astype(bool)
    N = b.shape[0]
    if N == 0:
        _fail("tree structure bits do not describe a full binary forest")
    S = np.r_[0, np.cumsum(np.where(b, 1, -1))].astype(np.int64)  # (N + 1,)
    pre_min = np.minimum.accumulate(S[:N])
    is_root = np.r_[True, S[1:N] < pre_min[:-1]]
    if not S[N] < pre_min[-1] or int(is_root.sum()) != n_roots:
        _fail("tree structure bits do not describe a full binary forest")
    # sorted (S value, position) keys: the next position after k holding a given S value
    off = -int(S.min())
    key = (S + off) * (N + 1) + np.arange(N + 1)
    order = np.argsort(key, kind="stable")
    skey = key[order]

    def next_at(value, after):
        i = np.searchsorted(skey, (value + off) * (N + 1) + after)
        return order[np.minimum(i, N)]

    k = np.arange(N)
    end = next_at(S[:N] - 1, k + 1)  # one past each subtree
    inner = np.flatnonzero(b)
    left = np.full(N, -1, np.int64)
    right = np.full(N, -1, np.int64)
    left[inner] = inner + 1
    right[inner] = next_at(S[inner], inner + 1)
    parent = np.full(N, -1, np.int64)
    parent[left[inner]] = inner
    parent[right[inner]] = inner
    size = (end - k + 1) // 2
    # depth by pointer jumping: O(N log depth)
    depth = (parent >= 0).astype(np.int64)
    anc = parent.copy()
    while True:
        go = anc >= 0
        if not go.any():
            break
        a = anc[go]
        depth[go] += depth[a]
        anc[go] = anc[a]
    leaves = np.flatnonzero(~b)
    lo = np.searchsorted(leaves, k).astype(np.int64)
    return left, right, parent, depth, size, lo


def _shape_arrays_scalar(isint: np.ndarray, n_roots: int):
    """:func:`_shape_arrays` with a stack, node by node (the reference for the tests)."""
    N = isint.shape[0]
    flags = isint.tolist()
    left = [-1] * N
    right = [-1] * N
    parent = [-1] * N
    depth = [0] * N
    stack = []  # (node, state) state 0: expecting left, 1: expecting right
    roots = 0
    for k in range(N):
        if stack:
            p, st = stack[-1]
            parent[k] = p
            depth[k] = depth[p] + 1
            if st == 0:
                left[p] = k
                stack[-1] = (p, 1)
            else:
                right[p] = k
                stack.pop()
        else:
            roots += 1
        if flags[k]:
            stack.append((k, 0))
    if stack or roots != n_roots:
        _fail("tree structure bits do not describe a full binary forest")
    left = np.asarray(left, np.int64)
    right = np.asarray(right, np.int64)
    parent = np.asarray(parent, np.int64)
    depth = np.asarray(depth, np.int64)
    size = np.ones(N, np.int64)
    size[left >= 0] = 0
    for k in np.flatnonzero(left >= 0)[::-1].tolist():
        size[k] = size[left[k]] + size[right[k]]
    # a node's compact ID is its leftmost leaf: the first leaf at or after it in preorder
    leaves = np.flatnonzero(~isint.astype(bool))
    nxt = np.searchsorted(leaves, np.arange(N))
    lo = nxt.astype(np.int64)
    return left, right, parent, depth, size, lo


def _pack_uint(values: np.ndarray, width: int) -> bytes:
    """(n,) non-negative ints < 2**width -> ``ceil(n * width / 8)`` bytes, LSB first."""
    v = np.asarray(values, np.uint64)
    bits = ((v[:, None] >> np.arange(width, dtype=np.uint64)) & np.uint64(1)).astype(np.uint8)
    return np.packbits(bits.ravel(), bitorder="little").tobytes()


def _unpack_uint(body, p: int, n: int, width: int) -> np.ndarray:
    nbytes = (n * width + 7) // 8
    bits = np.unpackbits(np.frombuffer(body, np.uint8, nbytes, p), bitorder="little")[:n * width]
    return (bits.reshape(n, width).astype(np.int64) << np.arange(width, dtype=np.int64)).sum(axis=1)


def index_width(n: int) -> int:
    """Bits of one packed vertex index for ``n`` vertices (at least 1)."""
    return max(1, int(n - 1).bit_length())


def encode_hierarchy(tree_or_positions, triangles=None, variant: C.Variant = C.PROPOSED,
                     keep_vertex_order: bool = True, store_positions: bool = True,
                     store_reach: bool = False, store_open: bool = False) -> bytes:
    """Serialise a part's vertex hierarchy with coded connectivity.

    Parameters
    ----------
    tree_or_positions : VertexTree, or (n, 3) positions (float64 or uint32 grid) with ``triangles``
    triangles : (m, 3) int, when positions are given
    variant : a decodable Variant (``corner == "id"``)
    keep_vertex_order : store the leaf -> input vertex permutation (``n`` uint32), so
        ``triangles()`` returns input vertex indices.
    store_positions : False leaves the leaf positions out (flag bit 1): the reader passes the
        input vertices' grid positions to ``decode_hierarchy(..., positions=)``, as the
        container does from its LOP bit planes. The vertex order is then always stored, packed
        at ``index_width(n)`` bits per leaf.
    store_reach : also store each node's ``reach`` (flag bit 2; f32 grid cells rounded up), the
        radius of the triangles its refinement affects, for the frustum and back-face tests.
    store_open : also store one bit per leaf (flag bit 3): the leaf lies on the oriented
        boundary chain (``VertexTree.open_vertex``), so the back-face test leaves the nodes
        above it to the screen-space error.

    Returns
    -------
    bytes, deterministic for the same input and options.
    """
    tree = tree_or_positions if isinstance(tree_or_positions, VertexTree) else \
        build_tree(tree_or_positions, triangles)
    if not variant.decodable:
        raise LopcookError("usage", None, f"variant {variant} is measurable but not decodable",
                           hint="use corner='id'")
    lay = C.layout(tree, variant.restructure)
    coded = C.encode_connectivity(tree, variant, lay)
    order = lay.order  # preorder -> tree node
    N = tree.n_nodes
    n = tree.n_leaves
    isint = (lay.left[order] >= 0).astype(np.uint8)
    internal = order[isint.astype(bool)]
    repside = (tree.rep[internal] != tree.rep[lay.left[internal]]).astype(np.uint8)
    out = bytearray()
    out += MAGIC
    out += struct.pack("<BBH", VERSION, _variant_flags(variant), variant.table_size)
    body = bytearray()
    for x in (n, N, int(tree.roots.shape[0]), int(tree.triangles.shape[0])):
        put_varint(body, x)
    external = not store_positions
    keep_vertex_order = keep_vertex_order or external
    if store_reach and tree.reach is None:
        raise LopcookError("usage", None, "store_reach: this tree has no reach radii", hint="build it with build_tree")
    if store_open and tree.open_vertex is None:
        raise LopcookError("usage", None, "store_open: this tree has no boundary vertices", hint="build it with build_tree")
    body.append((1 if keep_vertex_order else 0) | (2 if external else 0) | (4 if store_reach else 0)
                | (8 if store_open else 0))
    body += struct.pack("<4d", *[float(x) for x in tree.origin], float(tree.step))
    body += np.packbits(isint).tobytes()
    body += np.packbits(repside).tobytes()
    if not external:
        body += tree.positions[lay.leaf_vertex].astype("<u4").tobytes()
    body += _pack_selection(tree.error[order], tree.cone_axis[order], tree.cone_angle[order])
    if store_reach:
        body += _round_up_f32(tree.reach[order]).astype("<f4").tobytes()
    if store_open:
        body += np.packbits(tree.open_vertex[lay.leaf_vertex].astype(np.uint8)).tobytes()
    if external:
        body += _pack_uint(lay.leaf_vertex, index_width(n))
    elif keep_vertex_order:
        body += lay.leaf_vertex.astype("<u4").tobytes()
    names = [k for k in _TABLE_NAMES if k in coded.tables]
    body.append(len(names))
    for k in names:
        body.append(ord(k))
        body += coded.tables[k].to_bytes()
    for b in coded.record_bits.tolist():
        put_varint(body, int(b))
    put_varint(body, len(coded.data))
    body += coded.data
    out += struct.pack("<Q", len(body))
    out += body
    out += struct.pack("<I", zlib.crc32(bytes(out)))
    return bytes(out)


def blob_length(buf: bytes, offset: int = 0) -> int:
    """Length in bytes of the hierarchy blob starting at ``offset`` (header read only)."""
    if len(buf) - offset < 16 or buf[offset:offset + 4] != MAGIC:
        _fail("missing LOPH magic")
    (blen,) = struct.unpack_from("<Q", buf, offset + 8)
    return 16 + blen + 4


def decode_hierarchy(buf: bytes, positions: np.ndarray | None = None) -> Hierarchy:
    """Parse and validate a blob written by :func:`encode_hierarchy` (trailing bytes ignored).

    ``positions``: (n, 3) uint32 grid positions of the input vertices, required exactly when the
    blob was written with ``store_positions=False`` (and ignored otherwise)."""
    buf = bytes(buf)
    total, variant = _read_header(buf)
    body = buf[16:total - 4]
    n, N, n_roots, m, p = _read_counts(body)
    (keep_order, external, has_reach, has_open), (ox, oy, oz, step), p = _read_node_flags(body, p, n, N, n_roots)
    if external and positions is None:
        raise LopcookError("usage", None, "hierarchy: this blob keeps its positions outside; pass positions=",
                           hint="read it through lopcook.hierarchy.container, which decodes them from the planes")
    isint, repside, p = _read_shape_bits(body, p, n, N, n_roots)
    I = n - n_roots
    if not external:
        positions = np.frombuffer(body, "<u4", 3 * n, p).reshape(n, 3).astype(np.uint32)
        p += 12 * n
    error, axis, angle, p = _unpack_selection(body, p, N)
    reach, open_leaf, p = _read_optional(body, p, n, N, has_reach, has_open)
    vol, positions, p = _read_vertex_order(body, p, n, external, keep_order, positions)
    left, right, parent, depth, size, lo = _shape_arrays(isint, n_roots)
    tables, p = _read_tables(body, p, variant)
    starts, data = _read_records(body, p, I)
    rank = np.full(N, -1, np.int64)
    rank[left >= 0] = np.arange(I)
    node_leaf = _representative_leaves(left, right, lo, repside)
    return Hierarchy(n_leaves=n, n_nodes=N, n_triangles=m, variant=variant, left=left, right=right,
                     parent=parent, depth=depth, size=size, lo=lo, positions=positions,
                     node_leaf=node_leaf, error=error, cone_axis=axis, cone_angle=angle,
                     vertex_of_leaf=vol, tables=tables, data=data, record_starts=starts,
                     rank=rank, bits={"connectivity": int(starts[-1])},
                     origin=np.array([ox, oy, oz]), step=step, reach=reach, open_leaf=open_leaf)


def _read_header(buf: bytes):
    """The 16-byte header and the CRC: returns (total blob length in bytes, Variant)."""
    total = blob_length(buf)
    if total > len(buf):
        _fail(f"truncated: {len(buf)} bytes, the header announces {total}")
    version, flags, tsize = struct.unpack_from("<BBH", buf, 4)
    if version != VERSION:
        raise LopcookError("decode", None, f"hierarchy: version {version}, this build reads {VERSION}",
                           hint="re-encode the hierarchy with this lopcook version")
    (crc,) = struct.unpack_from("<I", buf, total - 4)
    if zlib.crc32(buf[:total - 4]) != crc:
        _fail("CRC-32 mismatch")
    variant = _variant_from(flags, tsize)
    try:
        C._check_variant(variant)
    except LopcookError:
        _fail(f"invalid variant flags {flags:#x}")
    return total, variant


def _read_counts(body: bytes):
    """Leaves n, nodes N, roots, triangles m (varints), checked against each other; and the
    next byte offset."""
    p = 0
    n, p = get_varint(body, p, "hierarchy")
    N, p = get_varint(body, p, "hierarchy")
    n_roots, p = get_varint(body, p, "hierarchy")
    m, p = get_varint(body, p, "hierarchy")
    if not (n >= 1 and N == 2 * n - n_roots and 1 <= n_roots <= n) or m > 4 * N + 16:
        _fail(f"inconsistent counts (leaves {n}, nodes {N}, roots {n_roots}, triangles {m})")
    return n, N, n_roots, m, p


def _read_node_flags(body: bytes, p: int, n: int, N: int, n_roots: int):
    """The node-data flag byte and the grid placement (origin, step: 4 float64), after checking
    that the fixed-size node data fits. Returns ((keep_order, external, has_reach, has_open),
    (ox, oy, oz, step), p)."""
    if p >= len(body):
        _fail("truncated before the node data")
    flag = body[p]
    keep_order, external, has_reach, has_open = flag & 1, flag >> 1 & 1, flag >> 2 & 1, flag >> 3 & 1
    need = 33 + (N + 7) // 8 + (n - n_roots + 7) // 8 + (0 if external else 12 * n) + 10 * N
    if p + need > len(body):
        _fail("truncated before the node data")
    p += 1
    ox, oy, oz, step = struct.unpack_from("<4d", body, p)
    p += 32
    if flag > 15 or (external and not keep_order) or not (np.isfinite([ox, oy, oz, step]).all() and step > 0):
        _fail("invalid header (vertex order flag or grid placement)")
    return (keep_order, external, has_reach, has_open), (ox, oy, oz, step), p


def _read_shape_bits(body: bytes, p: int, n: int, N: int, n_roots: int):
    """The preorder "is internal" bit of each node (N,) and the representative side bit of each
    internal node (n - n_roots,), both uint8; and the next offset."""
    isint = np.unpackbits(np.frombuffer(body, np.uint8, (N + 7) // 8, p))[:N]
    p += (N + 7) // 8
    I = n - n_roots
    if int(isint.sum()) != I:
        _fail("tree structure bits do not match the node counts")
    repside = np.unpackbits(np.frombuffer(body, np.uint8, (I + 7) // 8, p))[:I]
    p += (I + 7) // 8
    return isint, repside, p


def _read_optional(body: bytes, p: int, n: int, N: int, has_reach: int, has_open: int):
    """The optional per-node reach radii ((N,) float32, finite and >= 0) and per-leaf boundary
    bits ((n,) bool), None where absent; and the next offset."""
    reach = None
    if has_reach:
        if p + 4 * N > len(body):
            _fail("truncated reach radii")
        reach = np.frombuffer(body, "<f4", N, p).astype(np.float32)
        p += 4 * N
        if not np.isfinite(reach).all() or (reach < 0).any():
            _fail("node reach radii are not finite and non-negative")
    open_leaf = None
    if has_open:
        if p + (n + 7) // 8 > len(body):
            _fail("truncated boundary bits")
        open_leaf = np.unpackbits(np.frombuffer(body, np.uint8, (n + 7) // 8, p))[:n].astype(bool)
        p += (n + 7) // 8
    return reach, open_leaf, p


def _read_vertex_order(body: bytes, p: int, n: int, external: int, keep_order: int, positions):
    """The leaf -> input vertex permutation (n,) int64 (None when not stored): packed at
    ``index_width(n)`` bits when the positions are external (then the given (n, 3) positions are
    put in leaf order), else n uint32. Returns (vertex order, leaf positions, next offset)."""
    vol = None
    if external:
        w = index_width(n)
        if p + (n * w + 7) // 8 > len(body):
            _fail("truncated vertex order")
        vol = _unpack_uint(body, p, n, w)
        p += (n * w + 7) // 8
        if not np.array_equal(np.sort(vol), np.arange(n)):
            _fail("vertex order is not a permutation")
        given = np.asarray(positions)
        if given.shape != (n, 3):
            raise LopcookError("usage", None, f"hierarchy: positions must be ({n}, 3), got {given.shape}",
                               hint="pass the grid positions of the buffer the hierarchy was built on")
        positions = given.astype(np.uint32)[vol]
    elif keep_order:
        if p + 4 * n > len(body):
            _fail("truncated vertex order")
        vol = np.frombuffer(body, "<u4", n, p).astype(np.int64)
        p += 4 * n
        if not np.array_equal(np.sort(vol), np.arange(n)):
            _fail("vertex order is not a permutation")
    return vol, positions, p


def _read_tables(body: bytes, p: int, variant: C.Variant):
    """The Huffman tables (a count, then name byte + table each; every table the variant reads
    must be there). Returns (dict name -> Table, next offset)."""
    if p >= len(body):
        _fail("truncated before the tables")
    nt = body[p]
    p += 1
    tables = {}
    for _ in range(nt):
        if p >= len(body):
            _fail("truncated table list")
        name = chr(body[p])
        p += 1
        if name not in _TABLE_NAMES or name in tables:
            _fail(f"unknown or repeated table {name!r}")
        tables[name], p = Table.from_bytes(body, p, f"hierarchy table {name}")
    needed = {"H", "N"} | ({"D" if variant.tables == "single" else "E"}
                           if variant.external == "value" else set())
    if variant.internal == "explicit":
        needed.add("D" if variant.tables == "single" else "I")
    if variant.control == "predicted":
        needed.add("C")
    if not needed <= set(tables):
        _fail(f"missing tables {sorted(needed - set(tables))}")
    return tables, p


def _read_records(body: bytes, p: int, I: int):
    """The record index (I varint bit lengths) and the connectivity bytes, which must end the
    body. Returns (record start bits (I + 1,), connectivity bytes)."""
    rb, p = get_varints(body, p, I, "hierarchy record index")
    nbytes, p = get_varint(body, p, "hierarchy")
    if p + nbytes != len(body):
        _fail(f"connectivity is {len(body) - p} bytes, the index announces {nbytes}")
    starts = np.r_[0, np.cumsum(rb)]
    if starts[-1] > 8 * nbytes:
        _fail("record index runs past the connectivity bytes")
    return starts, body[p:]


def _representative_leaves(left, right, lo, repside) -> np.ndarray:
    """(N,) leaf ID of each node's representative: follow the representative side (bit 1: the
    right child) down to a leaf."""
    N = left.shape[0]
    side = np.zeros(N, np.uint8)
    side[left >= 0] = repside
    x = np.arange(N)
    while True:
        inner = left[x] >= 0
        if not inner.any():
            break
        x = np.where(inner, np.where(side[x] == 1, right[np.maximum(x, 0)], left[x]), x)
    return lo[x]
