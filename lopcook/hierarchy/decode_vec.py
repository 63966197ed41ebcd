"""Level-by-level vectorised decoding of the coded connectivity (control-bit variants).

The same records, the same checks and the same result as the per-node decoder in
``decode.py`` (``decode_records_scalar``), for the variants whose internal corners are implied
by control bits (``internal="control"``, compact numbering: the paper's section 5 and our
``PROPOSED_PLUS``). This work is based on the view-dependent connectivity coding paper,
sections 5 and 9: a node's record depends only on its ancestors' records, so every node of one
tree level can be decoded at once, once the level above is done. Per level, numpy reads one
Huffman symbol for every node in lockstep (each node has its own bit position inside its own
record, from the random-access index), then the external differences, then the control bits
of the ancestor corners that arrived at each node, and routes those corners to the next level.

State carried from level to level: for each node of the level, the path of its ancestors
(an ``(n, depth + 1)`` array, for ``v'`` of the external corners) and the ancestor corners that
reached it, in arrival order (by the depth of the owning ancestor, then by the subtri's rank in
that ancestor's record). Every read is checked against its record's end before the next one;
a violation raises ``LopcookError`` (stage ``"decode"``). The loop runs once per tree level and,
inside a level, once per subtri slot, and a slot consumes at least one bit of its record, so it
always ends.

Per-hierarchy tables (64-bit windows of the record bytes, numpy Huffman lookup tables) are built
once per ``Hierarchy`` and cached on it.
"""

from __future__ import annotations

import numpy as np

from ..errors import LopcookError
from .coding import H_CONTEXTS, N_ESC_BITS, NONE, NONMANIFOLD, context_table

_HINT = "the hierarchy data is corrupt or truncated; re-encode it"
_U1 = np.uint64(1)
_U63 = np.uint64(63)


def _fail(msg: str):
    raise LopcookError("decode", None, f"connectivity: {msg}", hint=_HINT)


def supported(variant) -> bool:
    """Whether :func:`decode_records_vec` decodes ``variant`` (else use the per-node decoder)."""
    return (variant.numbering == "compact" and variant.internal == "control"
            and variant.control == "raw" and variant.corner == "id")


class _Lut:
    """One Huffman table as numpy lookups indexed by the next ``L`` bits."""

    __slots__ = ("L", "esc", "ln", "sym")

    def __init__(self, table):
        # the same lookup as ``Table.lut()``, filled with numpy: code c of length l covers the
        # entries [c << (L - l), (c + 1) << (L - l)); entries no code covers keep length 0
        L = int(table.maxlen)
        vals = table.values.astype(np.int64)
        codes = table.codes.astype(np.int64)
        lens = table.lengths.astype(np.int64)
        esc = np.zeros(vals.shape[0], bool)
        if table.esc_len:
            vals = np.r_[vals, 0]
            codes = np.r_[codes, table.esc_code]
            lens = np.r_[lens, table.esc_len]
            esc = np.r_[esc, True]
        span = np.int64(1) << (L - lens)
        at = np.repeat(codes << (L - lens), span) + (np.arange(int(span.sum())) - np.repeat(np.cumsum(span) - span, span))
        self.sym = np.zeros(1 << L, np.int64)
        self.ln = np.zeros(1 << L, np.int64)
        self.esc = np.zeros(1 << L, bool)
        self.sym[at] = np.repeat(vals, span)
        self.ln[at] = np.repeat(lens, span)
        self.esc[at] = np.repeat(esc, span)
        self.L = np.uint64(L)


class _Tables:
    """Everything the vectorised decoder needs from one hierarchy, built once."""

    def __init__(self, h):
        data = np.frombuffer(bytes(h.data) + b"\0" * 16, np.uint8)
        # W[i]: the 8 bytes from byte i, big-endian (MSB first, as the records are written)
        m = data.shape[0] - 7
        w = np.zeros(m, np.uint64)
        for k in range(8):
            w |= data[k:k + m].astype(np.uint64) << np.uint64(56 - 8 * k)
        self.W = w
        self.nbits = 8 * len(h.data)
        var = h.variant
        self.H = _Lut(h.tables["H"])
        self.N = _Lut(h.tables["N"])
        self.bucket = var.external == "bucket"
        if self.bucket:
            syms, escs, lns, off, Ls, have = [], [], [], [], [], []
            o = 0
            for k in range(H_CONTEXTS):
                t = h.tables.get(context_table(k))
                have.append(t is not None)
                off.append(o)
                if t is None:
                    Ls.append(0)
                    continue
                lt = _Lut(t)
                syms.append(lt.sym)
                escs.append(lt.esc)
                lns.append(lt.ln)
                Ls.append(int(lt.L))
                o += lt.sym.shape[0]
            cat = (lambda xs, dt: np.concatenate(xs) if xs else np.zeros(1, dt))
            self.b_sym = cat(syms, np.int64)
            self.b_esc = cat(escs, bool)
            self.b_ln = cat(lns, np.int64)
            self.b_off = np.asarray(off, np.int64)
            self.b_L = np.asarray(Ls, np.uint64)
            self.b_have = np.asarray(have, bool)
        else:
            self.E = _Lut(h.tables["D" if var.tables == "single" else "E"])


def _tables(h) -> _Tables:
    c = getattr(h, "_vec_tables", None)
    if c is None or c[0] is not h.data:
        c = (h.data, _Tables(h))
        h._vec_tables = c
    return c[1]


def _window(W, pos):
    """64-bit windows at bit positions ``pos``: the next 57 bits or more, MSB first."""
    return W[pos >> 3] << (pos & 7).astype(np.uint64)


def _take(win, w):
    """The top ``w`` bits (0..57, scalar or array) of 64-bit windows, as int64."""
    return ((win >> _U1) >> (_U63 - np.asarray(w, np.uint64))).astype(np.int64)


def _bitlen(x):
    """Bit length of non-negative integers below 2**53 (0 for 0)."""
    return np.frexp(np.asarray(x, np.float64))[1].astype(np.int64)


class _Reader:
    """Lockstep reads for a set of records: ``pos`` and ``end`` per record (bit offsets)."""

    def __init__(self, T, pos, end, node):
        self.T, self.pos, self.end, self.node = T, pos, end, node

    def _check(self, idx):
        over = self.pos[idx] > self.end[idx]
        if over.any():
            j = idx[over][0]
            _fail(f"record overrun at bit {self.pos[j]} (ends at {self.end[j]}) at node {self.node[j]}")

    def sym(self, lut, idx, escw):
        """Symbols of ``lut`` for records ``idx`` (escape: ``escw`` raw bits, scalar or per record)."""
        p = self.pos[idx]
        x = _take(_window(self.T.W, p), lut.L)
        ln = lut.ln[x]
        if (ln == 0).any():
            j = int(np.flatnonzero(ln == 0)[0])
            _fail(f"invalid code at bit {p[j]} at node {self.node[idx[j]]}")
        s = lut.sym[x]
        p = p + ln
        e = lut.esc[x]
        if e.any():
            w = np.broadcast_to(np.asarray(escw, np.int64), idx.shape)[e]
            s[e] = _take(_window(self.T.W, p[e]), w)
            p[e] += w
        self.pos[idx] = p
        self._check(idx)
        return s

    def raw(self, idx, w):
        """``w`` raw bits (scalar or per record) for records ``idx``."""
        p = self.pos[idx]
        v = _take(_window(self.T.W, p), w)
        self.pos[idx] = p + w
        self._check(idx)
        return v

    def bucket(self, idx, ctx, escw):
        """Bucket symbols from the height-context tables ``ctx`` (0-based) for records ``idx``."""
        T = self.T
        if not T.b_have[ctx].all():
            j = int(np.flatnonzero(~T.b_have[ctx])[0])
            _fail(f"no bucket table for height {ctx[j] + 1} at node {self.node[idx[j]]}")
        p = self.pos[idx]
        x = T.b_off[ctx] + _take(_window(T.W, p), T.b_L[ctx])
        ln = T.b_ln[x]
        if (ln == 0).any():
            j = int(np.flatnonzero(ln == 0)[0])
            _fail(f"invalid code at bit {p[j]} at node {self.node[idx[j]]}")
        s = T.b_sym[x]
        p = p + ln
        e = T.b_esc[x]
        if e.any():
            w = escw[e]
            s[e] = _take(_window(T.W, p[e]), w)
            p[e] += w
        self.pos[idx] = p
        self._check(idx)
        return s


class _Corners:
    """Growable (t, 3) corner store with the owner and record slot of each subtri."""

    def __init__(self, cap):
        self.c = np.zeros(3 * max(cap, 4), np.int64)
        self.owner = np.zeros(max(cap, 4), np.int64)
        self.slot = np.zeros(max(cap, 4), np.int64)
        self.t = 0

    def add(self, owner, slot, ext):
        k = owner.shape[0]
        while self.t + k > self.owner.shape[0]:
            self.c = np.concatenate([self.c, np.zeros_like(self.c)])
            self.owner = np.concatenate([self.owner, np.zeros_like(self.owner)])
            self.slot = np.concatenate([self.slot, np.zeros_like(self.slot)])
        t = np.arange(self.t, self.t + k)
        self.owner[t] = owner
        self.slot[t] = slot
        self.c[3 * t + 2] = ext
        self.t += k
        return t


def _check_nodes(h, nodes) -> np.ndarray:
    """Check that ``nodes`` (k,) int64 (k > 0) are internal nodes, strictly ascending and closed
    under ancestors (else the per-node decoder's error). Returns (N,) bool: the node set."""
    left, parent = h.left, h.parent
    N = left.shape[0]
    bad = (nodes < 0) | (nodes >= N)
    if not bad.any():
        bad = left[nodes] < 0
    if bad.any():
        _fail(f"node {int(nodes[bad][0])} is not an internal node")
    if (np.diff(nodes) <= 0).any():
        j = int(np.flatnonzero(np.diff(nodes) <= 0)[0]) + 1
        _fail(f"node {int(nodes[j])} decoded before its ancestors")
    in_set = np.zeros(N, bool)
    in_set[nodes] = True
    par = parent[nodes]
    orphan = (par >= 0) & ~in_set[np.maximum(par, 0)]
    if orphan.any():
        _fail(f"node {int(nodes[orphan][0])} decoded before its ancestors")
    return in_set


def decode_records_vec(h, nodes):
    """Vectorised :func:`lopcook.hierarchy.decode.decode_records` (same arguments, same result,
    same errors), for variants where :func:`supported` is true."""
    var = h.variant
    if not supported(var):
        _fail(f"variant {var} is not decoded level by level")
    T = _tables(h)
    nodes = np.asarray(nodes, np.int64).reshape(-1)
    if nodes.size == 0:
        return np.zeros(0, np.int64), np.zeros((0, 3), np.int64)
    in_set = _check_nodes(h, nodes)
    dep = h.depth[nodes]
    by_level = np.argsort(dep, kind="stable")
    level_bounds = np.searchsorted(dep[by_level], np.arange(int(dep.max()) + 2))
    store = _Corners(2 * nodes.shape[0] + 16)
    arr_node = np.zeros(0, np.int64)  # ancestor corners arriving at this level's nodes, by node
    arr_ref = np.zeros(0, np.int64)   # (index into store.c), in arrival order per node
    prevU = None
    A = None
    for d in range(int(dep.max()) + 1):
        U = nodes[by_level[level_bounds[d]:level_bounds[d + 1]]]
        if not U.shape[0]:
            break
        if d == 0:
            A = U[:, None]
        else:
            A = np.concatenate([A[np.searchsorted(prevU, h.parent[U])], U[:, None]], axis=1)
        arr_node, arr_ref = _decode_level(h, T, store, d, U, A, arr_node, arr_ref, in_set)
        prevU = U
    t = store.t
    o = np.lexsort((store.slot[:t], store.owner[:t]))
    return store.owner[:t][o], store.c[:3 * t].reshape(-1, 3)[o]


def _decode_level(h, T, store, d, U, A, arr_node, arr_ref, in_set):
    """Decode the records of the nodes ``U`` (ascending) of tree level ``d``, whose ancestor
    paths are the rows of ``A`` (nU, d + 1): their subtris into ``store``, then the control bits
    of the ancestor corners ``arr_ref`` (indices into ``store.c``) that arrived at nodes
    ``arr_node``. Returns the (arr_node, arr_ref) of the corners arriving at the next level."""
    nU = U.shape[0]
    r = h.rank[U]
    pos = h.record_starts[r].astype(np.int64)
    end = h.record_starts[r + 1].astype(np.int64)
    rd = _Reader(T, pos, end, U)
    a_idx = np.searchsorted(U, arr_node)
    kpend = np.bincount(a_idx, minlength=nU)
    a_first = np.r_[0, np.cumsum(kpend)[:-1]]
    cands = _candidates(h.variant.candidates, store, arr_ref, a_idx, nU)
    subs = _level_subtris(h, T, rd, d, U, A, cands)
    dest_p = _control_bits(h, T, rd, U, kpend, a_idx, a_first, arr_ref)
    left_over = rd.pos != rd.end
    if left_over.any():
        j = int(np.flatnonzero(left_over)[0])
        _fail(f"record of node {U[j]} has {rd.end[j] - rd.pos[j]} bits left over")
    return _route(h, store, U, subs, arr_ref, dest_p, in_set)


def _candidates(cands_on, store, arr_ref, a_idx, nU):
    """Candidates (ours): per node of the level, the distinct external corners of the ancestor
    corners that arrived at it, in arrival order. Returns (values, count (nU,), first (nU,))."""
    if cands_on and arr_ref.size:
        ext = store.c[arr_ref - arr_ref % 3 + 2]
        o = np.lexsort((np.arange(ext.shape[0]), ext, a_idx))
        first = np.ones(o.shape[0], bool)
        first[1:] = (a_idx[o][1:] != a_idx[o][:-1]) | (ext[o][1:] != ext[o][:-1])
        keep = np.zeros(ext.shape[0], bool)
        keep[o[first]] = True
        cand_val = ext[keep]
        cand_n = np.bincount(a_idx[keep], minlength=nU)
        cand_first = np.r_[0, np.cumsum(cand_n)[:-1]]
    else:
        cand_val = np.zeros(0, np.int64)
        cand_n = np.zeros(nU, np.int64)
        cand_first = cand_n
    return cand_val, cand_n, cand_first


def _slot_counts(rd, T, nm, U):
    """Subtri slots per record: 2, or n0 + n1 for the non-manifold records ``nm`` (their two
    counts read here). Returns (nslots (nU,), n0 (nU,)) int64."""
    nU = U.shape[0]
    nslots = np.full(nU, 2, np.int64)
    n0 = np.zeros(nU, np.int64)
    if nm.any():
        im = np.flatnonzero(nm)
        n0[im] = rd.sym(T.N, im, N_ESC_BITS)
        n1 = rd.sym(T.N, im, N_ESC_BITS)
        nslots[im] = n0[im] + n1
        over = nslots[im] > rd.end[im] - rd.pos[im]
        if over.any():
            j = im[over][0]
            _fail(f"record overrun: {nslots[j]} subtris in {rd.end[j] - rd.pos[j]} bits at node {U[j]}")
    return nslots, n0


def _level_subtris(h, T, rd, d, U, A, cands):
    """The subtris of the level's records, slot by slot in lockstep. Returns four lists of
    arrays, one entry per slot: record index into U, slot k, orientation, external corner."""
    nU = U.shape[0]
    dbits = int(d).bit_length()
    s0 = rd.sym(T.H, np.arange(nU), dbits)
    nm = s0 == NONMANIFOLD
    nslots, n0 = _slot_counts(rd, T, nm, U)
    sub_i, sub_k, sub_o, sub_c = [], [], [], []
    for k in range(int(nslots.max()) if nU else 0):
        act = np.flatnonzero(nslots > k)
        if k == 0:
            s = s0[act]
            mm = nm[act]
            if mm.any():
                s = s.copy()
                s[mm] = rd.sym(T.H, act[mm], dbits)
        else:
            s = rd.sym(T.H, act, dbits)
        normal = ~nm[act]
        real = ~(normal & (s == NONE))
        act, s, normal = act[real], s[real], normal[real]
        if not act.size:
            continue
        sub_i.append(act)
        sub_k.append(np.full(act.shape[0], k, np.int64))
        sub_o.append(np.where(normal, k, (k >= n0[act]).astype(np.int64)))
        sub_c.append(_third_corners(h, T, rd, d, U, A, act, s, cands))
    return sub_i, sub_k, sub_o, sub_c


def _third_corners(h, T, rd, d, U, A, act, s, cands):
    """External corners of the subtris of records ``act`` from their slot symbols ``s``: a
    candidate index (symbol <= -2) or a height in [1, d] followed by a coded difference."""
    cand_val, cand_n, cand_first = cands
    is_c = (s <= -2) & h.variant.candidates
    hbad = ~is_c & ((s < 1) | (s > d))
    if hbad.any():
        j = int(np.flatnonzero(hbad)[0])
        _fail(f"height {s[j]} at node {U[act[j]]} (depth {d})")
    c = np.zeros(act.shape[0], np.int64)
    if is_c.any():
        ic = np.flatnonzero(is_c)
        ci = -2 - s[ic]
        cb = ci >= cand_n[act[ic]]
        if cb.any():
            j = int(np.flatnonzero(cb)[0])
            _fail(f"candidate {ci[j]} of {cand_n[act[ic[j]]]} at node {U[act[ic[j]]]}")
        c[ic] = cand_val[cand_first[act[ic]] + ci]
    ie = np.flatnonzero(~is_c)
    if ie.size:
        c[ie] = _external_corners(h, T, rd, d, U, A, act[ie], s[ie])
    return c


def _external_corners(h, T, rd, d, U, A, ii, hh):
    """Leaf IDs of external corners coded as (height ``hh``, difference) in records ``ii``: the
    difference (a value, or a bucket and its raw bits) is read against the range below the
    ancestor ``hh`` levels up (its other child's subtree when the variant refines)."""
    left, right, size, lo = h.left, h.right, h.size, h.lo
    vp = A[ii, d - hh]
    if h.variant.refine:
        ch = A[ii, d - hh + 1]
        vleft = ch == left[vp]
        base = np.where(vleft, lo[right[vp]], lo[vp])
        rng = np.where(vleft, size[right[vp]], size[left[vp]])
    else:
        base, rng = lo[vp], size[vp]
    if T.bucket:
        ctx = np.minimum(hh, H_CONTEXTS) - 1
        bk = rd.bucket(ii, ctx, _bitlen(_bitlen(rng - 1)))
        if ((bk < 0) | (bk > 32)).any():
            j = int(np.flatnonzero((bk < 0) | (bk > 32))[0])
            _fail(f"difference bucket {bk[j]} at node {U[ii[j]]}")
        e = bk.copy()
        big = np.flatnonzero(bk >= 2)
        if big.size:
            e[big] = (np.int64(1) << (bk[big] - 1)) | rd.raw(ii[big], bk[big] - 1)
    else:
        e = rd.sym(T.E, ii, _bitlen(rng - 1))
    ebad = (e < 0) | (e >= rng)
    if ebad.any():
        j = int(np.flatnonzero(ebad)[0])
        _fail(f"external difference {e[j]} outside [0, {rng[j]}) at node {U[ii[j]]}")
    return base + e


def _control_bits(h, T, rd, U, kpend, a_idx, a_first, arr_ref):
    """One control bit per arrived corner, in arrival order (1 = right child). Returns the
    child (arr_ref.size,) each arrived corner goes to."""
    short = rd.pos + kpend > rd.end
    if short.any():
        j = int(np.flatnonzero(short)[0])
        _fail(f"record of node {U[j]} too short for {kpend[j]} control bits")
    if not arr_ref.size:
        return np.zeros(0, np.int64)
    bitpos = rd.pos[a_idx] + (np.arange(arr_ref.shape[0]) - a_first[a_idx])
    bit = _take(_window(T.W, bitpos), 1)
    rd.pos += kpend
    return np.where(bit == 1, h.right[U[a_idx]], h.left[U[a_idx]])


def _route(h, store, U, subs, arr_ref, dest_p, in_set):
    """Store the level's subtris and send every corner below this level to its child: a leaf's
    ID where the child is a leaf, else ``-(child + 1)`` and, when the child is to be decoded, an
    arrival there (ordered by child; arrived corners first, then the level's subtris in order).
    Returns the next level's (arr_node, arr_ref)."""
    left, lo = h.left, h.lo
    sub_i, sub_k, sub_o, sub_c = subs
    if sub_i:
        si = np.concatenate(sub_i)
        so = np.concatenate(sub_o)
        t = store.add(U[si], np.concatenate(sub_k), np.concatenate(sub_c))
    else:
        si = so = t = np.zeros(0, np.int64)
    Lu, Ru = left[U[si]], h.right[U[si]]
    ref = np.concatenate([arr_ref, 3 * t + so, 3 * t + 1 - so])
    dest = np.concatenate([dest_p, Lu, Ru])
    grp = np.concatenate([np.zeros(arr_ref.shape[0], np.int64), np.ones(2 * t.shape[0], np.int64)])
    seq = np.concatenate([np.arange(arr_ref.shape[0]), t, t])
    leaf = left[dest] < 0
    store.c[ref] = np.where(leaf, lo[dest], -(dest + 1))
    go = ~leaf & in_set[dest]
    ref, dest, grp, seq = ref[go], dest[go], grp[go], seq[go]
    o = np.lexsort((seq, grp, dest))
    return dest[o], ref[o]
