"""Copies stored once (``cook --instances``): one buffer set per distinct mesh, one transform per
placement.

A **group** is a set of parts that are copies of one mesh (``lopcook.simplify.instances.copies``:
same triangles and attributes, positions related by ``x -> A x + t``). The group's buffers (every
LOD) are the representative's ("lead"), encoded once on a **mesh grid** of their own, and every
placement is a part entry ``placement: {"of": j, "transform": [12 floats], "level_shift": s}``
whose LOD entries name the buffers of part ``j`` (the buffer owner, itself a placement of the
group) instead of owning bytes. docs/format.md has the manifest fields.

Mesh grid
    Local coordinates are the lead's positions minus the lower corner ``lo`` of the box of every
    LOD of the lead; the grid has origin (0, 0, 0) and extent ``E_m`` (the box's largest side), 24
    bits, quantised and decoded exactly as ``lopcook.grid`` (the per-buffer origin and half cell of
    the decoders' uniform block). A placement's stored transform maps local to world:
    ``(A, t + A lo)``, both rounded to float32 (the manifest holds what a shader uses).

World position (the CPU reference, ``to_world``; the harness vertex shader does the same with
``precise``)
    ``p`` = the float32 decode on the mesh grid (``bitplane.reconstruct_float32``), then per
    component ``w_i = ((a_i0 p_0 + a_i1 p_1) + a_i2 p_2) + t_i``, every product and sum rounded
    to float32, no fused multiply-add.

Minimum levels (``level_shift``, ``local_level``, ``resident_level``)
    A placement's world levels ``m_w`` (scene grid, extent ``E_w``) become mesh-grid levels
    ``clamp(m_w + s_p, 1, 24)`` with ``s_p = ceil(log2(sigma_p E_m / E_w))``, ``sigma_p`` the
    largest singular value of ``A_p``: then ``sigma_p dx_m(l) <= dx_w(m_w)``, so every placement
    keeps its bound; a vertex needing more than 24 bits keeps the placement off the group. The
    shared buffer takes the per-vertex maximum, and at view time the maximum over the placements
    drawn. A copy sharing a scene-grid cell with another part is never grouped
    (``touching_parts``), so shared vertices cannot crack. The proof and the crack argument:
    docs/instances.md, "Why every placement keeps its levels".
"""

from __future__ import annotations

import hashlib
import math

import numpy as np

from ..errors import LopcookError
from ..grid import BITS, Grid

#: float32 unit round-off
U32 = 2.0 ** -24


def transform_f32(a: np.ndarray, t: np.ndarray) -> list[float]:
    """The manifest's 3 x 4 row-major transform ``[a00, a01, a02, t0, a10, ...]`` of ``(a, t)``,
    every value rounded to float32 (and written as the float64 of that float32)."""
    m = np.concatenate([np.asarray(a, np.float64), np.asarray(t, np.float64).reshape(3, 1)], axis=1)
    if not np.all(np.isfinite(m)) or np.abs(m).max() > 3.0e38:
        raise LopcookError("emit", None, "a placement transform is not finite in float32",
                           hint="cook without --instances")
    return [float(v) for v in m.astype(np.float32).ravel()]


def split(transform) -> tuple[np.ndarray, np.ndarray]:
    """``(A (3, 3) float32, t (3,) float32)`` of a manifest transform (12 numbers)."""
    m = np.asarray(transform, dtype=np.float64).reshape(3, 4).astype(np.float32)
    return m[:, :3], m[:, 3]


def to_world(p: np.ndarray, transform) -> np.ndarray:
    """(n, 3) float32 local positions -> (n, 3) float32 world positions, in the documented order
    (module doc): ``((a_i0 p_0 + a_i1 p_1) + a_i2 p_2) + t_i``, each operation rounded to float32."""
    a, t = split(transform)
    p = np.asarray(p, dtype=np.float32)
    out = np.empty(p.shape, dtype=np.float32)
    for i in range(3):  # three components, each vectorised over the vertices
        s = (a[i, 0] * p[:, 0]).astype(np.float32) + (a[i, 1] * p[:, 1]).astype(np.float32)
        s = s.astype(np.float32) + (a[i, 2] * p[:, 2]).astype(np.float32)
        out[:, i] = (s.astype(np.float32) + t[i]).astype(np.float32)
    return out


def float32_slack(transform, extent_m: float) -> np.ndarray:
    """(3,) metres: a bound on the float32 rounding ``to_world`` adds per component for local
    positions within ``[0, extent_m]^3`` (decoded in float32, relative error at most 2u each):
    ``(|a_i| . (3u E_m)) + 4u (|a_i| . E_m + |t_i|)``, u = 2^-24; the Euclidean bound is its norm."""
    a, t = split(transform)
    a64, t64 = np.abs(a.astype(np.float64)), np.abs(t.astype(np.float64))
    e = float(extent_m)
    return a64.sum(axis=1) * 3.0 * U32 * e + 4.0 * U32 * (a64.sum(axis=1) * e + t64)


def sigma(transform) -> float:
    """Largest singular value of the float32 ``A`` of ``transform`` (float64 SVD), widened by a
    relative 1e-9 so that rounding of the SVD never makes it smaller than the true value."""
    a, _ = split(transform)
    return float(np.linalg.svd(a.astype(np.float64), compute_uv=False)[0]) * (1.0 + 1e-9)


def level_shift(sig: float, mesh_extent: float, world_extent: float) -> int:
    """The smallest integer ``s`` with ``2^s >= sig * mesh_extent / world_extent`` (module doc),
    exact: the candidate from a logarithm is checked and corrected with ``ldexp``."""
    r = float(sig) * float(mesh_extent)
    w = float(world_extent)
    if not (r > 0 and w > 0 and math.isfinite(r) and math.isfinite(w)):
        raise LopcookError("emit", None, f"placement scale {sig!r} or extents {mesh_extent!r}, {world_extent!r} "
                           "are not positive and finite", hint="cook without --instances")
    s = int(math.ceil(math.log2(r) - math.log2(w)))
    while math.ldexp(w, s - 1) >= r:
        s -= 1
    while math.ldexp(w, s) < r:
        s += 1
    return s


def local_level(world_level, shift: int):
    """Scene-grid level(s) -> mesh-grid level(s): ``clamp(level + shift, 1, 24)`` (int or array)."""
    return np.clip(np.asarray(world_level, dtype=np.int64) + int(shift), 1, BITS)


def resident_level(world_level: int, shifts) -> int:
    """The level a shared buffer is resident at when each placement asks for ``world_level``: the
    maximum over its placements' ``local_level``."""
    return int(max(int(local_level(world_level, s)) for s in shifts))


#: the last ``touching_parts`` answer: (digest of its inputs, the answer). A search's probes ask
#: again for the same cells (a scene's grid integers do not depend on the knobs they move)
_LAST_TOUCHING: list = []


def touching_parts(quantized: list[np.ndarray], part_of: list[int]) -> np.ndarray:
    """Which parts share a scene-grid cell with another part: ``quantized`` a list of (n_k, 3)
    uint32 grid integers (every LOD of every part), ``part_of[k]`` the part array k belongs to.
    Returns a bool array over ``max(part_of) + 1`` parts (a fresh copy). Vectorised: one sort over
    all cells, then the smallest and largest part per cell. The same inputs as the last call (a
    SHA-1 of every array and of ``part_of``) give the last answer without sorting again."""
    n_parts = max(part_of) + 1 if part_of else 0
    if not quantized:
        return np.zeros(n_parts, dtype=bool)
    arrays = [np.ascontiguousarray(a, dtype=np.uint32).reshape(-1, 3) for a in quantized]
    h = hashlib.sha1(np.asarray(part_of, np.int64).tobytes())
    for a in arrays:
        h.update(np.int64(a.shape[0]).tobytes())
        h.update(a.data)
    key = h.digest()
    if _LAST_TOUCHING and _LAST_TOUCHING[0] == key:
        return _LAST_TOUCHING[1].copy()
    out = _touching(arrays, part_of, n_parts)
    _LAST_TOUCHING[:] = [key, out.copy()]
    return out


def _touching(quantized: list[np.ndarray], part_of: list[int], n_parts: int) -> np.ndarray:
    """``touching_parts`` without the memory of the last answer."""
    q = np.concatenate(quantized).astype(np.uint64)
    owner = np.concatenate([np.full(np.asarray(a).reshape(-1, 3).shape[0], p, np.int64)
                            for a, p in zip(quantized, part_of)])
    order = np.lexsort((q[:, 2], q[:, 1], q[:, 0]))
    qs, os = q[order], owner[order]
    new = np.ones(qs.shape[0], dtype=bool)
    new[1:] = np.any(qs[1:] != qs[:-1], axis=1)
    cell = np.cumsum(new) - 1
    n_cells = int(cell[-1]) + 1 if cell.size else 0
    lo = np.full(n_cells, np.iinfo(np.int64).max, np.int64)
    hi = np.full(n_cells, -1, np.int64)
    np.minimum.at(lo, cell, os)
    np.maximum.at(hi, cell, os)
    shared = (lo != hi)[cell]
    out = np.zeros(n_parts, dtype=bool)
    out[np.unique(os[shared])] = True
    return out


def mesh_grid(chain_positions: list[np.ndarray]) -> tuple[Grid, np.ndarray]:
    """``(grid, lo)``: the mesh grid of a lead's LOD chain (every LOD's (n, 3) float64 positions)
    -- origin (0, 0, 0), extent the largest side of their box (at least ``grid.MIN_EXTENT``) --
    and the box's lower corner ``lo`` (3,) float64 that local coordinates are measured from."""
    lo = np.min([np.asarray(p, np.float64).min(axis=0) for p in chain_positions], axis=0)
    g = Grid.fit([np.asarray(p, np.float64) - lo for p in chain_positions])
    return Grid(origin=(0.0, 0.0, 0.0), extent=g.extent), lo


__all__ = ["U32", "transform_f32", "split", "to_world", "float32_slack", "sigma", "level_shift", "local_level",
           "resident_level", "touching_parts", "mesh_grid"]
