"""Simplification backends behind one signature: ``(positions, faces, target, ...) -> BackendResult``.

``"pymeshlab"``: MeshLab's quadric edge collapse (texture-aware with UVs); ``"fast"``:
fast-simplification's quadric collapse with its collapse map. ``prepare`` welds the input the way
the seam mode needs, ``check_result`` rejects results that miss their target by more than
``TARGET_FAIL_FACTOR`` or are empty.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mesh import (compact, components, degenerate_mask, sorted_unique, stable_argsort, unique_rows,
                    weld_labels)
from ..types import MeshPart
from .meshopt import simplify_meshopt
from .types import BackendFailure, BackendResult


#: a backend result more than this factor off its target counts as a failure
TARGET_FAIL_FACTOR = 2.0

BACKENDS = ("pymeshlab", "fast")
#: every backend a chain can be asked for; a failed one falls back through ``BACKENDS`` in order.
#: ``"auto"`` is meshoptimizer, and pymeshlab as well on small inputs (``lopcook.simplify.chain``)
SELECTABLE = BACKENDS + ("meshopt", "auto")


def simplify_fast(positions, faces, target, *, lock_border=False) -> BackendResult:
    """fast-simplification to ``target`` triangles; the collapse map gives ``vertex_source``."""
    import fast_simplification  # the native simplifiers load when a chain first uses them

    p_out, f_out, collapses = fast_simplification.simplify(
        np.ascontiguousarray(positions, dtype=np.float64), np.ascontiguousarray(faces, dtype=np.int32),
        target_count=int(target), agg=7.0, return_collapses=True, preserve_border=bool(lock_border))
    n = positions.shape[0]
    rep = np.arange(n, dtype=np.int64)
    collapses = np.asarray(collapses, dtype=np.int64).reshape(-1, 2)
    if collapses.size:
        rep[collapses[:, 1]] = collapses[:, 0]
        for _ in range(64):  # pointer jumping: log2(chain length) rounds
            nxt = rep[rep]
            if np.array_equal(nxt, rep):
                break
            rep = nxt
    used = np.zeros(n, dtype=bool)
    used[np.asarray(faces, dtype=np.int64).ravel()] = True
    survivors = sorted_unique(rep[used])
    source = survivors if survivors.size == p_out.shape[0] else None
    return BackendResult(np.asarray(p_out, dtype=np.float64), np.asarray(f_out, dtype=np.int64).reshape(-1, 3),
                          vertex_source=source)


def simplify_pymeshlab(positions, faces, target, *, uvs=None, weld=False, lock_border=True,
                        topology=True) -> BackendResult:
    """MeshLab quadric edge collapse. With ``uvs`` (per vertex) the texture-aware variant runs on
    per-wedge UVs; ``weld`` first merges vertices with identical positions (seams become
    per-wedge UV discontinuities instead of boundaries)."""
    import pymeshlab  # optional native simplifier: loads when a chain first uses it

    ms = pymeshlab.MeshSet()
    p = np.ascontiguousarray(positions, dtype=np.float64)
    f = np.ascontiguousarray(faces, dtype=np.int32)
    common = dict(targetfacenum=int(target), preserveboundary=bool(lock_border), preservenormal=True,
                  planarquadric=True, optimalplacement=True)
    if uvs is not None:
        ms.add_mesh(pymeshlab.Mesh(vertex_matrix=p, face_matrix=f,
                                   v_tex_coords_matrix=np.ascontiguousarray(uvs, dtype=np.float64)))
        ms.compute_texcoord_transfer_vertex_to_wedge()
        if weld:
            ms.meshing_remove_duplicate_vertices()
        ms.meshing_decimation_quadric_edge_collapse_with_texture(**common)
    else:
        ms.add_mesh(pymeshlab.Mesh(vertex_matrix=p, face_matrix=f))
        ms.meshing_decimation_quadric_edge_collapse(preservetopology=bool(topology), autoclean=True, **common)
    m = ms.current_mesh()
    out_f = np.asarray(m.face_matrix(), dtype=np.int64).reshape(-1, 3)
    wedge = None
    if uvs is not None and m.has_wedge_tex_coord():
        wedge = np.asarray(m.wedge_tex_coord_matrix(), dtype=np.float64).reshape(-1, 3, 2)
    return BackendResult(np.asarray(m.vertex_matrix(), dtype=np.float64), out_f, wedge_uvs=wedge)


def parametrise_xatlas(positions: np.ndarray, indices: np.ndarray):
    """xatlas: (vertex mapping into the input vertices, new indices, uvs float32)."""
    import xatlas  # optional parametriser: loads only for seams='xatlas' or parametrise

    vmap, ind, uv = xatlas.parametrize(np.ascontiguousarray(positions, dtype=np.float32),
                                       np.ascontiguousarray(indices, dtype=np.uint32))
    return np.asarray(vmap, dtype=np.int64), np.asarray(ind, dtype=np.int64).reshape(-1, 3), np.asarray(uv, np.float32)


@dataclass
class Work:
    """The mesh handed to a backend."""

    positions: np.ndarray
    faces: np.ndarray
    uvs: np.ndarray | None      # per work vertex (lock: split mesh) or per input vertex (simplify)
    mode: str                   # seam mode
    region: np.ndarray | None = None  # lock: UV island of every work vertex


def weld_first(positions: np.ndarray) -> np.ndarray:
    """``weld_exact(positions)[0]``, the same array (groups of identical positions numbered by
    first appearance), through the hash weld ``weld_labels`` and two integer sorts instead of a
    sort of 24-byte rows."""
    n = positions.shape[0]
    lab, k = weld_labels(positions, np.int64)
    if n == 0:
        return lab
    order, _ = stable_argsort(lab)  # stable: each group's first index comes first
    starts = np.flatnonzero(np.r_[True, lab[order][1:] != lab[order][:-1]])
    first = np.empty(k, dtype=np.int64)
    first[lab[order[starts]]] = order[starts]
    rank = np.empty(k, dtype=np.int64)
    rank[stable_argsort(first)[0]] = np.arange(k)
    return rank[lab]


def prepare(part: MeshPart, mode: str, degenerate: np.ndarray | None = None) -> tuple[Work, int]:
    """Clean (drop zero-area faces) and weld/split the input for a backend; returns the work mesh
    and the number of faces dropped. ``degenerate``: ``degenerate_mask`` of the part if known."""
    faces = part.indices.astype(np.int64)
    bad = degenerate_mask(part.positions, faces) if degenerate is None else degenerate
    faces = faces[~bad]
    if mode == "simplify":  # pymeshlab welds by position itself and keeps per-wedge UVs
        p, f, keep = compact(part.positions, faces)
        return Work(p, f, part.uvs[keep].astype(np.float64), mode), int(bad.sum())
    w = weld_first(part.positions)
    if mode == "lock":
        uvbits = (np.ascontiguousarray(part.uvs, dtype=np.float32) + np.float32(0.0)).view(np.int32).astype(np.int64)
        first, inv = unique_rows(np.concatenate([w[:, None], uvbits], axis=1))
        f = inv[faces]
        p, f, keep = compact(part.positions[first], f)
        uv = part.uvs[first][keep].astype(np.float64)
        comp = components(f.shape[0], f, p.shape[0])
        region = np.zeros(p.shape[0], dtype=np.int64)
        region[f.ravel()] = np.repeat(comp, 3)
        return Work(p, f, uv, mode, region), int(bad.sum())
    # w is numbered by first appearance: a label's first index is where the running maximum rises
    # (np.unique(w, return_index=True)[1], without its sort)
    rise = np.maximum.accumulate(w)
    first = np.flatnonzero(np.r_[w.size > 0, rise[1:] > rise[:-1]])
    del rise
    p, f, _ = compact(part.positions[first], w[faces])
    return Work(p, f, None, mode), int(bad.sum())


#: backends that ignore ``run_backend``'s topology flag (only pymeshlab takes it)
TOPOLOGY_BLIND = ("meshopt", "fast")


def run_backend(backend: str, work: Work, target: int, lock_border: bool, topology: bool) -> BackendResult:
    if backend == "fast":
        lock = lock_border if work.mode not in ("lock",) else True
        return simplify_fast(work.positions, work.faces, target, lock_border=lock)
    # meshoptimizer takes pymeshlab's arguments (lopcook.simplify.meshopt)
    simplifier = simplify_meshopt if backend == "meshopt" else simplify_pymeshlab
    if work.mode == "lock":
        return simplifier(work.positions, work.faces, target, uvs=work.uvs, lock_border=True)
    if work.mode == "simplify":
        return simplifier(work.positions, work.faces, target, uvs=work.uvs, weld=True, lock_border=lock_border)
    return simplifier(work.positions, work.faces, target, lock_border=lock_border, topology=topology)


def check_result(res: BackendResult, target: int, n_in: int) -> tuple[BackendResult, int]:
    """Validate and clean a backend result (drop degenerate faces, unreferenced vertices); raise
    BackendFailure for unusable output. Returns (result, degenerate faces dropped)."""
    p, f = res.positions, res.faces
    if p.ndim != 2 or p.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
        raise BackendFailure(f"returned arrays of shape {p.shape} / {f.shape}")
    if f.shape[0] == 0:
        raise BackendFailure("returned no triangles")
    if f.min() < 0 or f.max() >= p.shape[0]:
        raise BackendFailure("returned out-of-range indices")
    if not np.isfinite(p).all():
        raise BackendFailure("returned NaN/Inf positions")
    bad = degenerate_mask(p, f)
    if bad.all():
        raise BackendFailure("returned only degenerate triangles")
    f = f[~bad]
    wedge = None if res.wedge_uvs is None else res.wedge_uvs[~bad]
    if wedge is not None and not np.isfinite(wedge).all():
        wedge = None
    p2, f2, keep = compact(p, f)
    source = None if res.vertex_source is None else res.vertex_source[keep]
    m = f2.shape[0]
    if m > TARGET_FAIL_FACTOR * max(target, 1) or m * TARGET_FAIL_FACTOR < target:
        raise BackendFailure(f"returned {m} triangles for a target of {target} (more than "
                       f"{TARGET_FAIL_FACTOR:g}x off)")
    if m >= n_in and target < n_in:
        raise BackendFailure(f"did not reduce the mesh ({m} of {n_in} triangles)")
    return BackendResult(p2, f2, wedge, source), int(bad.sum())
