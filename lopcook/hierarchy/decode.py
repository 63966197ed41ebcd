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
    var = h.variant
    compact = var.numbering == "compact"
    explicit = var.internal == "explicit"
    if var.control != "raw" or var.corner != "id":
        _fail(f"variant {var} cannot be decoded")
    cands_on = var.candidates
    bucket = var.external == "bucket"
    left, right, depth, size, lo = h.left_l, h.right_l, h.depth_l, h.size_l, h.lo_l
    parent = h.parent_l
    rank = h.rank_l
    starts = h.record_starts_l
    buf = bytes(h.data) + b"\0" * 16
    R = 0
    Rend = 0

    def peek(pos):
        # the next 32 bits of the current record's window (R holds bytes [k0, k0 + nb))
        return (R >> (Rend - pos - 32)) & 0xFFFFFFFF
    luts = {k: t.lut() for k, t in h.tables.items()}
    Hs, Hl, HL = luts["H"]
    HM = (1 << HL) - 1
    if bucket:
        ctx_luts = [luts.get(context_table(k)) for k in range(H_CONTEXTS)]
    else:
        Es, El, EL = luts["D" if var.tables == "single" else "E"]
    if explicit:
        Is, Il, IL = luts["D" if var.tables == "single" else "I"]
    Ns, Nl, NL = luts["N"]
    pend_of = [None] * len(left)  # ancestor corners (refs into corn) that reached each node
    path = []
    owner = []
    corn = []
    n_nodes = len(left)

    def sym(lut_s, lut_l, L, pos, escbits, end):
        x = peek(pos) >> (32 - L) if L else 0
        ln = lut_l[x]
        if ln == 0:
            _fail(f"invalid code at bit {pos}")
        s = lut_s[x]
        pos += ln
        if s is None:
            if escbits:
                s = peek(pos) >> (32 - escbits)
                pos += escbits
            else:
                s = 0
        if pos > end:
            _fail(f"record overrun at bit {pos} (ends at {end})")
        return s, pos

    def external(hh, u, d, pos, end):
        """Leaf ID of an external corner coded as (h, diff) at node u (depth d)."""
        vp = path[d - hh]
        child = path[d - hh + 1]
        vleft = child == left[vp]
        if compact:
            if var.refine:
                if vleft:
                    base, rng = lo[right[vp]], size[right[vp]]
                else:
                    base, rng = lo[vp], size[left[vp]]
            else:
                base, rng = lo[vp], size[vp]
        else:
            if var.refine:
                if vleft:
                    base, rng = right[vp], 2 * size[right[vp]] - 1
                else:
                    base, rng = vp, 2 * size[left[vp]] + 1
            else:
                base, rng = vp, 2 * size[vp] - 1
        if bucket:
            lut = ctx_luts[min(hh, H_CONTEXTS) - 1]
            if lut is None:
                _fail(f"no bucket table for height {hh} at node {u}")
            bk, pos = sym(lut[0], lut[1], lut[2], pos, ((rng - 1).bit_length()).bit_length(), end)
            if bk is None or bk < 0 or bk > 32:
                _fail(f"difference bucket {bk} at node {u}")
            if bk >= 2:
                e = (1 << (bk - 1)) | (peek(pos) >> (33 - bk))
                pos += bk - 1
                if pos > end:
                    _fail(f"record overrun at bit {pos} (ends at {end})")
            else:
                e = bk
        else:
            e, pos = sym(Es, El, EL, pos, (rng - 1).bit_length(), end)
        if e is None or e < 0 or e >= rng:
            _fail(f"external difference {e} outside [0, {rng}) at node {u}")
        if compact:
            return base + e, pos
        cn = base + e
        if cn >= n_nodes or left[cn] >= 0:
            _fail(f"external corner {cn} is not a leaf at node {u}")
        return lo[cn], pos

    for u in nodes:
        if u < 0 or u >= n_nodes or left[u] < 0:
            _fail(f"node {u} is not an internal node")
        r = rank[u]
        pos, end = starts[r], starts[r + 1]
        k0 = pos >> 3
        k1 = (end >> 3) + 9
        R = int.from_bytes(buf[k0:k1], "big")
        Rend = k1 << 3
        d = depth[u]
        if d > len(path) or (d and path[d - 1] != parent[u]):
            _fail(f"node {u} decoded before its ancestors")
        del path[d:]
        path.append(u)
        Lu, Ru = left[u], right[u]
        dbits = d.bit_length()
        cands = None
        pend = pend_of[u]
        pend_of[u] = None
        # (1) the subtris: slot symbols
        entries = []  # (orient, h)
        x = (R >> (Rend - pos - HL)) & HM
        ln = Hl[x]
        if not ln:
            _fail(f"invalid code at bit {pos}")
        s = Hs[x]
        pos += ln
        if s is None:
            s = (R >> (Rend - pos - dbits)) & ((1 << dbits) - 1)
            pos += dbits
        if pos > end:
            _fail(f"record overrun at bit {pos} (ends at {end})")
        if s == NONMANIFOLD:
            n0, pos = sym(Ns, Nl, NL, pos, 16, end)
            n1, pos = sym(Ns, Nl, NL, pos, 16, end)
            todo = [0] * n0 + [1] * n1
            first = None
        else:
            todo = [0, 1]
            first = s
        for k, orient in enumerate(todo):
            if first is not None:
                if k == 1:
                    s, pos = sym(Hs, Hl, HL, pos, dbits, end)
                else:
                    s = first
                if s == NONE:
                    continue
            else:
                s, pos = sym(Hs, Hl, HL, pos, dbits, end)
            hh = s
            if hh is not None and hh <= -2 and cands_on:
                if cands is None:
                    cands = list(dict.fromkeys([corn[ref - ref % 3 + 2]
                                                for ref in (pend or ())]))
                if -2 - hh >= len(cands):
                    _fail(f"candidate {-2 - hh} of {len(cands)} at node {u}")
                c = cands[-2 - hh]
                hh = 0
            elif hh is None or hh < 1 or hh > d:
                _fail(f"height {hh} at node {u} (depth {d})")
            if hh:
                c, pos = external(hh, u, d, pos, end)
            t = len(owner)
            owner.append(u)
            if explicit:
                ra = size[Lu] if compact else 2 * size[Lu] + 1
                ia, pos = sym(Is, Il, IL, pos, (ra - 1).bit_length(), end)
                if var.refine:
                    rb = size[Ru] if compact else 2 * size[Ru] - 1
                else:
                    rb = size[u] if compact else 2 * size[u]
                ib, pos = sym(Is, Il, IL, pos, (rb - 1).bit_length(), end)
                if ia is None or ib is None or not (0 <= ia < ra) or not (0 <= ib < rb):
                    _fail(f"internal difference outside its range at node {u}")
                if compact:
                    a = lo[u] + ia
                    b = (lo[Ru] if var.refine else lo[u]) + ib
                    if not (lo[Lu] <= a < lo[Ru]) or not (lo[Ru] <= b < lo[u] + size[u]):
                        _fail(f"internal corner outside its subtree at node {u}")
                else:
                    an = u + ia
                    bn = (Ru if var.refine else u) + ib
                    if an >= n_nodes or bn >= n_nodes or left[an] >= 0 or left[bn] >= 0 \
                            or not (Lu <= an < Ru) or not (Ru <= bn < u + 2 * size[u] - 1):
                        _fail(f"internal corner is not a leaf of its subtree at node {u}")
                    a, b = lo[an], lo[bn]
                corn.extend((a, b, c) if orient == 0 else (b, a, c))
            else:
                if orient == 0:
                    corn.extend((-(Lu + 1), -(Ru + 1), c))
                    entries.append((3 * t, Lu))
                    entries.append((3 * t + 1, Ru))
                else:
                    corn.extend((-(Ru + 1), -(Lu + 1), c))
                    entries.append((3 * t + 1, Lu))
                    entries.append((3 * t, Ru))
        # (2) control bits for the ancestor corners that reached u, in arrival order
        if not explicit:
            k = len(pend) if pend else 0
            if k:
                if pos + k > end:
                    _fail(f"record of node {u} too short for {k} control bits")
                w = (R >> (Rend - pos - k)) & ((1 << k) - 1)
                pos += k
                Lleaf, Rleaf = left[Lu] < 0, left[Ru] < 0
                for ref in pend:
                    k -= 1
                    if (w >> k) & 1:
                        if Rleaf:
                            corn[ref] = lo[Ru]
                        else:
                            corn[ref] = -(Ru + 1)
                            q = pend_of[Ru]
                            if q is None:
                                pend_of[Ru] = [ref]
                            else:
                                q.append(ref)
                    elif Lleaf:
                        corn[ref] = lo[Lu]
                    else:
                        corn[ref] = -(Lu + 1)
                        q = pend_of[Lu]
                        if q is None:
                            pend_of[Lu] = [ref]
                        else:
                            q.append(ref)
            for ref, ch in entries:
                if left[ch] < 0:
                    corn[ref] = lo[ch]
                else:
                    q = pend_of[ch]
                    if q is None:
                        pend_of[ch] = [ref]
                    else:
                        q.append(ref)
        if pos != end:
            _fail(f"record of node {u} has {end - pos} bits left over")
    own = np.asarray(owner, np.int64)
    tri = np.asarray(corn, np.int64).reshape(-1, 3)
    return own, tri
