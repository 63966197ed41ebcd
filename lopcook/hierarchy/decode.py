"""Decoding of the coded connectivity: whole hierarchy, one subtree, or one cut.

This work is based on the view-dependent connectivity coding paper, sections 3, 5 and 9: a
node's record is decodable from its ancestors' records alone ("decompression is only dependent
on ancestor nodes"). The decoder walks nodes top-down in preorder; the only state a node needs
is the list of ancestor-subtri corners that reached it (its control bits say which child each
follows) and the path of ancestors (for the external corners' ``(h, diff)``).

Every read is bounded by the node's record; a record that is too short or too long, an invalid
Huffman prefix, or a value outside its range raises ``LopcookError`` (stage ``"decode"``).
Decoding is a bounded loop over the nodes asked for: it always terminates.
"""

from __future__ import annotations

import numpy as np

from ..errors import LopcookError
from .coding import H_CONTEXTS, NONE, NONMANIFOLD, context_table
from .decode_vec import decode_records_vec, supported

_HINT = "the hierarchy data is corrupt or truncated; re-encode it"


def _fail(msg: str):
    raise LopcookError("decode", None, f"connectivity: {msg}", hint=_HINT)


def decode_records(h, nodes):
    """Decode the records of ``nodes`` (internal nodes in preorder, each one's ancestors included).

    Control-bit variants (the paper's section 5, ``PROPOSED``, ``PROPOSED_PLUS``) are decoded
    level by level with numpy (``decode_vec.decode_records_vec``); the others (relative ID, VDS
    numbering) node by node (:func:`decode_records_scalar`). Both give the same result and raise
    on the same bad data.

    Parameters
    ----------
    h : lopcook.hierarchy.format.Hierarchy
    nodes : iterable of int, internal node indices (preorder numbering), sorted ascending and
        closed under ancestors.

    Returns
    -------
    owner : (t,) int64 node owning each decoded subtri
    corners : (t, 3) int64 corners in input orientation; a value ``>= 0`` is a leaf ID, a value
        ``< 0`` is ``-(node + 1)``: the corner lies below that node, whose record was not decoded.
        Rows are ordered by owner node, then by the subtri's place in its record.
    """
    if supported(h.variant):
        return decode_records_vec(h, nodes)
    return decode_records_scalar(h, nodes)


def decode_records_scalar(h, nodes):
    """:func:`decode_records` node by node, for every decodable variant (the reference decoder)."""
    nodes = np.asarray(nodes, np.int64).reshape(-1).tolist()
    dec = _NodeDecoder(h)
    for u in nodes:
        dec.node(u)
    own = np.asarray(dec.owner, np.int64)
    tri = np.asarray(dec.corn, np.int64).reshape(-1, 3)
    return own, tri


class _NodeDecoder:
    """State of the per-node decoder over one hierarchy ``h`` (python lists, for speed).

    ``owner`` (t,) node of each decoded subtri and ``corn`` (3t,) its corners, flat, in the
    encoding of :func:`decode_records`; ``pend_of[v]``: the indices into ``corn`` of the ancestor
    corners that reached node v and wait for v's control bits (None when none); ``path``: the
    ancestors of the node being decoded, by depth. ``R`` holds the bytes around the current node's
    record as one big-endian integer ending at bit ``Rend`` of the data: data bit ``pos`` (MSB
    first) is bit ``Rend - pos - 1`` of ``R``."""

    def __init__(self, h):
        var = h.variant
        self.var = var
        self.compact = var.numbering == "compact"
        self.explicit = var.internal == "explicit"
        if var.control != "raw" or var.corner != "id":
            _fail(f"variant {var} cannot be decoded")
        self.cands_on = var.candidates
        self.bucket = var.external == "bucket"
        self.left, self.right, self.depth, self.size, self.lo = h.left_l, h.right_l, h.depth_l, h.size_l, h.lo_l
        self.parent = h.parent_l
        self.rank = h.rank_l
        self.starts = h.record_starts_l
        self.buf = bytes(h.data) + b"\0" * 16
        self.R = 0
        self.Rend = 0
        luts = {k: t.lut() for k, t in h.tables.items()}
        self.H = luts["H"]
        if self.bucket:
            self.ctx_luts = [luts.get(context_table(k)) for k in range(H_CONTEXTS)]
        else:
            self.E = luts["D" if var.tables == "single" else "E"]
        if self.explicit:
            self.I = luts["D" if var.tables == "single" else "I"]
        self.N = luts["N"]
        self.pend_of = [None] * len(self.left)
        self.path = []
        self.owner = []
        self.corn = []
        self.n_nodes = len(self.left)

    def peek(self, pos):
        """The next 32 bits from bit ``pos`` of the current record's window."""
        return (self.R >> (self.Rend - pos - 32)) & 0xFFFFFFFF

    def sym(self, lut, pos, escbits, end):
        """One symbol of the table ``lut`` = (symbols, lengths, L) at bit ``pos``; an escape is
        followed by ``escbits`` raw bits (0: the value 0). Returns (symbol, new pos)."""
        lut_s, lut_l, L = lut
        x = self.peek(pos) >> (32 - L) if L else 0
        ln = lut_l[x]
        if ln == 0:
            _fail(f"invalid code at bit {pos}")
        s = lut_s[x]
        pos += ln
        if s is None:
            if escbits:
                s = self.peek(pos) >> (32 - escbits)
                pos += escbits
            else:
                s = 0
        if pos > end:
            _fail(f"record overrun at bit {pos} (ends at {end})")
        return s, pos

    def node(self, u):
        """Decode node u's record: (1) its subtris, (2) the control bits of the ancestor corners
        that reached it, which route them (and its own subtris' internal corners) to its children."""
        d, pos, end = self._open(u)
        pend = self.pend_of[u]
        self.pend_of[u] = None
        entries, pos = self._subtris(u, d, pos, end, pend)
        if not self.explicit:
            pos = self._control_bits(u, pos, end, pend)
            for ref, ch in entries:
                self._follow(ref, ch)
        if pos != end:
            _fail(f"record of node {u} has {end - pos} bits left over")

    def _open(self, u):
        """Check u is an internal node decoded after its ancestors, load its record's window and
        push it on the path. Returns (depth, first bit, end bit) of the record."""
        if u < 0 or u >= self.n_nodes or self.left[u] < 0:
            _fail(f"node {u} is not an internal node")
        r = self.rank[u]
        pos, end = self.starts[r], self.starts[r + 1]
        k0 = pos >> 3
        k1 = (end >> 3) + 9
        self.R = int.from_bytes(self.buf[k0:k1], "big")
        self.Rend = k1 << 3
        d = self.depth[u]
        path = self.path
        if d > len(path) or (d and path[d - 1] != self.parent[u]):
            _fail(f"node {u} decoded before its ancestors")
        del path[d:]
        path.append(u)
        return d, pos, end

    def _first_slot(self, pos, end, dbits):
        """The record's first slot symbol (height, candidate, NONE or NONMANIFOLD; escape:
        ``dbits`` raw bits), read straight from the window. Returns (symbol, new pos)."""
        Hs, Hl, HL = self.H
        x = (self.R >> (self.Rend - pos - HL)) & ((1 << HL) - 1)
        ln = Hl[x]
        if not ln:
            _fail(f"invalid code at bit {pos}")
        s = Hs[x]
        pos += ln
        if s is None:
            s = (self.R >> (self.Rend - pos - dbits)) & ((1 << dbits) - 1)
            pos += dbits
        if pos > end:
            _fail(f"record overrun at bit {pos} (ends at {end})")
        return s, pos

    def _subtris(self, u, d, pos, end, pend):
        """Decode the subtris of node u (depth d): the slot symbols, each subtri's third corner
        and, for explicit variants, its internal corners. Appends to ``owner`` and ``corn``.
        Returns (entries, pos): entries are (index into corn, child) of the internal corners the
        control bits route (control variants only)."""
        Lu, Ru = self.left[u], self.right[u]
        dbits = d.bit_length()
        cands = None
        entries = []
        s, pos = self._first_slot(pos, end, dbits)
        if s == NONMANIFOLD:
            n0, pos = self.sym(self.N, pos, 16, end)
            n1, pos = self.sym(self.N, pos, 16, end)
            todo = [0] * n0 + [1] * n1
            first = None
        else:
            todo = [0, 1]
            first = s
        for k, orient in enumerate(todo):
            if first is not None:
                if k == 1:
                    s, pos = self.sym(self.H, pos, dbits, end)
                else:
                    s = first
                if s == NONE:
                    continue
            else:
                s, pos = self.sym(self.H, pos, dbits, end)
            c, pos, cands = self._third_corner(s, u, d, pos, end, pend, cands)
            t = len(self.owner)
            self.owner.append(u)
            if self.explicit:
                pos = self._explicit_corners(u, orient, c, pos, end)
            elif orient == 0:
                self.corn.extend((-(Lu + 1), -(Ru + 1), c))
                entries.append((3 * t, Lu))
                entries.append((3 * t + 1, Ru))
            else:
                self.corn.extend((-(Ru + 1), -(Lu + 1), c))
                entries.append((3 * t + 1, Lu))
                entries.append((3 * t, Ru))
        return entries, pos

    def _third_corner(self, hh, u, d, pos, end, pend, cands):
        """The external corner of a subtri of node u from its slot symbol ``hh``: a candidate (an
        external corner of an arrived ancestor corner, ``cands`` built on first use) or a
        height h in [1, d] and its coded difference. Returns (corner, pos, cands)."""
        if hh is not None and hh <= -2 and self.cands_on:
            if cands is None:
                corn = self.corn
                cands = list(dict.fromkeys([corn[ref - ref % 3 + 2] for ref in (pend or ())]))
            if -2 - hh >= len(cands):
                _fail(f"candidate {-2 - hh} of {len(cands)} at node {u}")
            return cands[-2 - hh], pos, cands
        if hh is None or hh < 1 or hh > d:
            _fail(f"height {hh} at node {u} (depth {d})")
        c, pos = self._external(hh, u, d, pos, end)
        return c, pos, cands

    def _external_range(self, vp, vleft):
        """(base, range) of the external difference at ancestor ``vp`` (the corner lies in the
        subtree of vp's child other than the path's when the variant refines, ``vleft``: the
        path goes through vp's left child)."""
        left, right, size, lo = self.left, self.right, self.size, self.lo
        if self.compact:
            if self.var.refine:
                if vleft:
                    return lo[right[vp]], size[right[vp]]
                return lo[vp], size[left[vp]]
            return lo[vp], size[vp]
        if self.var.refine:
            if vleft:
                return right[vp], 2 * size[right[vp]] - 1
            return vp, 2 * size[left[vp]] + 1
        return vp, 2 * size[vp] - 1

    def _external(self, hh, u, d, pos, end):
        """Leaf ID of an external corner coded as (h, diff) at node u (depth d)."""
        vp = self.path[d - hh]
        child = self.path[d - hh + 1]
        base, rng = self._external_range(vp, child == self.left[vp])
        if self.bucket:
            lut = self.ctx_luts[min(hh, H_CONTEXTS) - 1]
            if lut is None:
                _fail(f"no bucket table for height {hh} at node {u}")
            bk, pos = self.sym(lut, pos, ((rng - 1).bit_length()).bit_length(), end)
            if bk is None or bk < 0 or bk > 32:
                _fail(f"difference bucket {bk} at node {u}")
            if bk >= 2:
                e = (1 << (bk - 1)) | (self.peek(pos) >> (33 - bk))
                pos += bk - 1
                if pos > end:
                    _fail(f"record overrun at bit {pos} (ends at {end})")
            else:
                e = bk
        else:
            e, pos = self.sym(self.E, pos, (rng - 1).bit_length(), end)
        if e is None or e < 0 or e >= rng:
            _fail(f"external difference {e} outside [0, {rng}) at node {u}")
        if self.compact:
            return base + e, pos
        cn = base + e
        if cn >= self.n_nodes or self.left[cn] >= 0:
            _fail(f"external corner {cn} is not a leaf at node {u}")
        return self.lo[cn], pos

    def _explicit_corners(self, u, orient, c, pos, end):
        """Read a subtri's two internal corners (explicit variants: differences in the left and
        the right subtree) and append its three corners, in input orientation. Returns pos."""
        left, size, lo = self.left, self.size, self.lo
        compact = self.compact
        Lu, Ru = left[u], self.right[u]
        ra = size[Lu] if compact else 2 * size[Lu] + 1
        ia, pos = self.sym(self.I, pos, (ra - 1).bit_length(), end)
        if self.var.refine:
            rb = size[Ru] if compact else 2 * size[Ru] - 1
        else:
            rb = size[u] if compact else 2 * size[u]
        ib, pos = self.sym(self.I, pos, (rb - 1).bit_length(), end)
        if ia is None or ib is None or not (0 <= ia < ra) or not (0 <= ib < rb):
            _fail(f"internal difference outside its range at node {u}")
        if compact:
            a = lo[u] + ia
            b = (lo[Ru] if self.var.refine else lo[u]) + ib
            if not (lo[Lu] <= a < lo[Ru]) or not (lo[Ru] <= b < lo[u] + size[u]):
                _fail(f"internal corner outside its subtree at node {u}")
        else:
            an = u + ia
            bn = (Ru if self.var.refine else u) + ib
            if an >= self.n_nodes or bn >= self.n_nodes or left[an] >= 0 or left[bn] >= 0 \
                    or not (Lu <= an < Ru) or not (Ru <= bn < u + 2 * size[u] - 1):
                _fail(f"internal corner is not a leaf of its subtree at node {u}")
            a, b = lo[an], lo[bn]
        self.corn.extend((a, b, c) if orient == 0 else (b, a, c))
        return pos

    def _control_bits(self, u, pos, end, pend):
        """One control bit per ancestor corner that reached u, in arrival order (1: it follows
        the right child), each corner routed on. Returns pos."""
        k = len(pend) if pend else 0
        if not k:
            return pos
        if pos + k > end:
            _fail(f"record of node {u} too short for {k} control bits")
        w = (self.R >> (self.Rend - pos - k)) & ((1 << k) - 1)
        pos += k
        Lu, Ru = self.left[u], self.right[u]
        for ref in pend:
            k -= 1
            self._follow(ref, Ru if (w >> k) & 1 else Lu)
        return pos

    def _follow(self, ref, ch):
        """Corner ``corn[ref]`` lies below child ``ch``: the leaf's ID when ch is a leaf, else
        ``-(ch + 1)``, and it waits for ch's control bits."""
        if self.left[ch] < 0:
            self.corn[ref] = self.lo[ch]
            return
        self.corn[ref] = -(ch + 1)
        q = self.pend_of[ch]
        if q is None:
            self.pend_of[ch] = [ref]
        else:
            q.append(ref)
