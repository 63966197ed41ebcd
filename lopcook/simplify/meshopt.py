"""meshoptimizer backend for LOD chains: attribute-aware edge collapse that keeps seams closed.

``simplify_meshopt`` has the signature and result type of ``lopcook.simplify.backends.simplify_pymeshlab`` (so
``lopcook.simplify.backends.run_backend`` calls it with the same arguments as pymeshlab) and adds the simplifier's own
error estimate (``MeshoptResult.error_m``).

Method: ``meshopt_simplifyWithAttributes`` (Kapoulkine, meshoptimizer; quadric error metric of
Garland & Heckbert 1997 with attribute quadrics after Hoppe 1999) on the indexed mesh as given.
meshoptimizer never moves a vertex: every collapse merges a vertex into a neighbour, so the result
is a subset of the input vertices (``vertex_source``) with their exact float64 positions and UVs.
Vertices that share a position exactly are a *seam* (UV seam, normal crease, colour edge): the
simplifier collapses seam edges only along the seam and both sides together, so co-located seam
vertices stay co-located (no cracks) and each side keeps its own UVs (no texture swimming).
Arguments as for pymeshlab:

* ``uvs`` (n, 2) per vertex: the attribute metric includes them (weight ``UV_WEIGHT``); the result
  carries per-corner ``wedge_uvs``, copied from the surviving input vertices.
* ``weld=False`` with ``uvs`` (``seams="lock"``): every seam vertex is locked, so the seams survive
  exactly, as with pymeshlab on the seam-split mesh. ``weld=True`` (``seams="simplify"``): seams
  collapse along themselves.
* ``lock_border``: open-boundary vertices (of the mesh welded by position) are locked, through the
  lock array as well as ``meshopt_SimplifyLockBorder``: the flag alone does not lock border
  vertices that are also seam vertices (they are not "border" to it; docs/lod.md).
* ``topology`` is accepted for signature compatibility: meshoptimizer's collapses never change the
  topology of manifold regions anyway.
* ``normals`` (n, 3), optional: added to the attribute metric (weight ``NORMAL_WEIGHT``).

Error: ``error_m`` is meshoptimizer's ``result_error`` with ``meshopt_SimplifyErrorAbsolute``: the
square root of the largest collapse's quadric error, in metres for the position part (the
attribute terms, unitless, are added into it). It is an estimate of the distance from the
simplified mesh to its *input*, not a bound (its ratio to the measured symmetric Hausdorff
distance: docs/lod.md). Along a chain built from the previous LOD, the
distance to LOD 0 is at most the sum of the steps' distances (triangle inequality); ``accumulate``
sums the steps' errors that way.

The PyPI wrapper (``meshoptimizer`` 0.2.30a0) declares no C prototype for
``meshopt_simplifyWithAttributes``, so its ``simplify_with_attributes`` raises ``ctypes.ArgumentError``
for any call; this module calls the bundled C function through its own ctypes prototype (the C
signature of meshoptimizer >= 0.21).
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass

import numpy as np

from ..mesh import used_ids, weld_labels
from .types import BackendResult

#: attribute weight of UVs (texture coordinates in [0, 1]) and of unit normals; positions are
#: normalised by meshoptimizer to the mesh extent, so these weigh a UV or normal change of 1
#: like a position change of the whole mesh size (gltfpack weighs normals 0.5 as well)
UV_WEIGHT = 1.0
NORMAL_WEIGHT = 0.5

_LOCK_BORDER = 1 << 0      # meshopt_SimplifyLockBorder
_ERROR_ABSOLUTE = 1 << 2   # meshopt_SimplifyErrorAbsolute


@dataclass
class MeshoptResult(BackendResult):
    """``BackendResult`` plus the simplifier's own error estimate in metres (see module doc)."""

    error_m: float = 0.0


_FN = None


def _simplify_fn():
    """The bundled ``meshopt_simplifyWithAttributes`` with its C prototype (a separate function
    object: the wrapper's own attribute is left as it is)."""
    global _FN
    if _FN is None:
        fn = _library()["meshopt_simplifyWithAttributes"]
        P = ctypes.POINTER
        fn.argtypes = [P(ctypes.c_uint), P(ctypes.c_uint), ctypes.c_size_t, P(ctypes.c_float), ctypes.c_size_t,
                       ctypes.c_size_t, P(ctypes.c_float), ctypes.c_size_t, P(ctypes.c_float), ctypes.c_size_t,
                       P(ctypes.c_ubyte), ctypes.c_size_t, ctypes.c_float, ctypes.c_uint, P(ctypes.c_float)]
        fn.restype = ctypes.c_size_t
        _FN = fn
    return _FN


def library_path() -> str:
    """Path of the native meshoptimizer library this backend calls (the pinned binding's bundled
    one). It must run on any x86-64 CPU: a binding built for AVX2 alone dies of SIGILL on import
    on CPUs without it (measured: docs/lod.md, "The simplifier binding")."""
    return str(_library()._name)


def _library():
    """The pinned binding's bundled C library (``ctypes.CDLL``), loaded on the first call."""
    from meshoptimizer._loader import lib  # the bundled C library loads on the first call

    return lib


def seam_vertices(positions: np.ndarray) -> np.ndarray:
    """(n,) bool: vertices whose exact position is shared with another vertex."""
    w, k = weld_labels(positions, np.int64)
    return np.bincount(w, minlength=k)[w] > 1


def border_vertices(positions: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(n,) bool: vertices on an open boundary of the mesh welded by exact position (an edge with
    one face there; seams are not borders)."""
    n = positions.shape[0]
    w, k = weld_labels(positions, np.int64)
    f = w[np.asarray(faces, dtype=np.int64).reshape(-1, 3)]
    a = f.ravel()
    b = f[:, [1, 2, 0]].ravel()
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    ok = lo != hi
    key = np.sort(lo[ok] * np.int64(max(k, 1)) + hi[ok])
    if key.size == 0:
        return np.zeros(n, dtype=bool)
    start = np.r_[True, key[1:] != key[:-1]]
    size = np.diff(np.r_[np.flatnonzero(start), key.size])
    single = key[start][size == 1]
    on = np.zeros(k, dtype=bool)
    on[single // max(k, 1)] = True
    on[single % max(k, 1)] = True
    return on[w]


def simplify_meshopt(positions, faces, target, *, uvs=None, weld=False, lock_border=True, topology=True,
                     normals=None) -> MeshoptResult:
    """Simplify to about ``target`` triangles with meshoptimizer (see the module doc).

    Parameters
    ----------
    positions : (n, 3) float64 metres; faces : (m, 3) int; target : int triangles
    uvs : (n, 2) or None; weld : bool (False with uvs: seams locked); lock_border : bool
    topology : ignored (signature of ``_simplify_pymeshlab``); normals : (n, 3) or None

    Returns
    -------
    MeshoptResult: positions (k, 3) float64 (input rows, bit for bit), faces (t, 3) int64,
    vertex_source (k,) int64 input vertex of each output vertex, wedge_uvs (t, 3, 2) float64 when
    ``uvs`` is given, error_m float. Deterministic: the same input gives the same output.
    """
    p = np.ascontiguousarray(positions, dtype=np.float64)
    f = np.ascontiguousarray(faces, dtype=np.uint32).reshape(-1)
    n = p.shape[0]
    cols = []
    weights = []
    if uvs is not None:
        cols.append(np.asarray(uvs, dtype=np.float32).reshape(n, 2))
        weights += [UV_WEIGHT] * 2
    if normals is not None:
        cols.append(np.asarray(normals, dtype=np.float32).reshape(n, 3))
        weights += [NORMAL_WEIGHT] * 3
    if cols:
        attr = np.ascontiguousarray(np.concatenate(cols, axis=1), dtype=np.float32)
    else:
        attr = np.zeros((n, 1), dtype=np.float32)
        weights = [0.0]
    w = np.asarray(weights, dtype=np.float32)
    lock = np.zeros(n, dtype=bool)
    if uvs is not None and not weld:
        lock |= seam_vertices(p)
    if lock_border:  # meshopt_SimplifyLockBorder alone leaves border vertices on a seam free to move
        lock |= border_vertices(p, f.reshape(-1, 3))
    lock = np.ascontiguousarray(lock, dtype=np.uint8)
    p32 = np.ascontiguousarray(p, dtype=np.float32)
    dest = np.empty(f.size, dtype=np.uint32)
    err = ctypes.c_float(0.0)
    options = _ERROR_ABSOLUTE | (_LOCK_BORDER if lock_border else 0)
    P = ctypes.POINTER
    count = _simplify_fn()(
        dest.ctypes.data_as(P(ctypes.c_uint)), f.ctypes.data_as(P(ctypes.c_uint)), f.size,
        p32.ctypes.data_as(P(ctypes.c_float)), n, 12,
        attr.ctypes.data_as(P(ctypes.c_float)), attr.shape[1] * 4, w.ctypes.data_as(P(ctypes.c_float)), w.size,
        lock.ctypes.data_as(P(ctypes.c_ubyte)),
        3 * int(max(target, 1)), ctypes.c_float(np.finfo(np.float32).max), options, ctypes.byref(err))
    out = dest[:count].astype(np.int64).reshape(-1, 3)
    keep = used_ids(out, n)
    remap = np.full(n, -1, dtype=np.int64)
    remap[keep] = np.arange(keep.size)
    out_f = remap[out]
    wedge = None if uvs is None else np.asarray(uvs, dtype=np.float64)[keep][out_f]
    return MeshoptResult(positions=p[keep], faces=out_f, wedge_uvs=wedge, vertex_source=keep,
                         error_m=float(err.value))


def accumulate(step_errors) -> list[float]:
    """Errors along a chain built from the previous LOD: the sum of the steps' errors up to LOD k,
    non-decreasing. By the triangle inequality the Hausdorff distance from LOD k to LOD 0 is at
    most the sum of the steps' distances, so if each step's error bounded its step, the sum would
    bound LOD k; meshoptimizer's error is an estimate, so the sum is one too."""
    return [float(v) for v in np.cumsum(np.asarray(step_errors, dtype=np.float64))]
