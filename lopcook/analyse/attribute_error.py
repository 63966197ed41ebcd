"""Attribute error per triangle and per vertex: E_t = ||A M^-1||_2, E_v = max over incident triangles.

This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
section 5.1 (attribute error).

For a triangle (v0, v1, v2) with attribute vectors a_i (k components: a normal, a UV, a colour),
``A = [a1 - a0, a2 - a0]`` (k x 2) and ``M`` maps barycentric (beta, gamma) to coordinates (u, v)
in an orthonormal basis of the triangle's plane. ``A M^-1`` is the gradient of the linearly
interpolated attribute with respect to position in the plane, so its spectral norm

    E_t = ||A M^-1||_2         [attribute units per metre]

is how fast the attribute changes across the triangle (independent of which corner is v0).
Computed as the paper writes it, vectorised over all triangles: M is upper triangular
(``m11 = |e1|``, ``m12 = e1.e2 / |e1|``, ``m22 = |e1 x e2| / |e1|`` with e1 = v1 - v0,
e2 = v2 - v0), so ``J = A M^-1`` is two column operations, and ``E_t^2`` is the largest eigenvalue
of the symmetric 2 x 2 matrix ``J^T J``, in closed form. Taking m22 from the cross product keeps
slivers accurate (no cancellation in a Gram determinant). M depends on the geometry alone, so a
part's attributes share it (``triangle_frames``) and are gathered together
(``triangle_gradient_norms``).

Degenerate triangles (zero area: repeated or collinear corners) have no plane; they are excluded
(E_t = 0, they add nothing to E_v) and counted.

Large meshes (``lopcook.jit.use`` with ``KERNEL_PAYS_FROM``: float64 positions, attributes of at most
``kernels.MAX_COMPONENTS`` components) go through the compiled kernels of ``analyse/kernels.py``,
which give the same values bit for bit; the numpy code here is their test oracle.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .. import jit

#: triangles from which the kernels pay for numba's start-up in a process that has not loaded it
#: (``lopcook.jit.use``; docs/performance.md, "Compiled kernels")
KERNEL_PAYS_FROM = 1 << 21

#: A triangle is degenerate when det(G) = (2 * area)^2 <= DEGENERATE_TOL * |e1|^2 |e2|^2, i.e. the
#: sine of its angle at v0 is below 1e-6 (or an edge has zero length). Dimensionless.
DEGENERATE_TOL = 1e-12


class TriangleFrames(NamedTuple):
    """What E_t needs from the geometry alone, shared by every attribute of a part.

    tri : (m, 3) int64 corner indices; m11, m12, m22 : (m,) the upper-triangular M (metres; m11 = 1,
    m12 = 0, m22 = 1 for degenerate triangles); degenerate : (m,) bool."""

    tri: np.ndarray
    m11: np.ndarray
    m12: np.ndarray
    m22: np.ndarray
    degenerate: np.ndarray


def triangle_frames(positions: np.ndarray, indices: np.ndarray) -> TriangleFrames:
    """M for every triangle (see module doc); positions (n, 3) metres, indices (m, 3) integer."""
    tri = np.asarray(indices, dtype=np.int64)
    pos = np.asarray(positions)
    if pos.dtype == np.float64 and jit.use(tri.shape[0], KERNEL_PAYS_FROM):
        from . import kernels  # compiled kernels (numba): loaded only for large meshes
        return TriangleFrames(tri, *kernels.triangle_frames(pos, tri.reshape(-1, 3), DEGENERATE_TOL))
    p0 = pos[tri[:, 0]]
    e1 = pos[tri[:, 1]] - p0
    e2 = pos[tri[:, 2]] - p0
    # M = [[m11, m12], [0, m22]] (paper, section 5.1): m11 = |e1|, m12 = |e2| cos(phi) = e1.e2/|e1|,
    # m22 = |e2| sin(phi) = |e1 x e2| / |e1| (from the cross product: accurate for slivers)
    l1sq = np.einsum("ij,ij->i", e1, e1)
    l2sq = np.einsum("ij,ij->i", e2, e2)
    cross = np.cross(e1, e2)
    cross_sq = np.einsum("ij,ij->i", cross, cross)
    degenerate = ~(cross_sq > DEGENERATE_TOL * l1sq * l2sq) | ~np.isfinite(cross_sq)
    m11 = np.sqrt(np.where(degenerate, 1.0, l1sq))
    m12 = np.where(degenerate, 0.0, np.einsum("ij,ij->i", e1, e2)) / m11
    m22 = np.sqrt(np.where(degenerate, 1.0, cross_sq)) / m11
    return TriangleFrames(tri, m11, m12, m22, degenerate)


def triangle_gradient_norms(positions: np.ndarray, indices: np.ndarray, attributes: list[np.ndarray],
                            frames: TriangleFrames | None = None) -> tuple[list[np.ndarray], np.ndarray]:
    """E_t of several attributes on the same triangles: the frames (M) are computed once and the
    attributes gathered together. Same values as ``triangle_gradient_norm`` for each attribute.

    Parameters: positions (n, 3) metres, indices (m, 3), attributes: list of (n, k_a) arrays, frames:
    ``triangle_frames(positions, indices)`` if already known.
    Returns ([e_t (m,) float64 per attribute], degenerate (m,) bool)."""
    f = frames if frames is not None else triangle_frames(positions, indices)
    if not attributes:
        return [], f.degenerate
    cols = [np.asarray(a, dtype=np.float64) for a in attributes]
    cols = [c.reshape(c.shape[0], -1) for c in cols]
    a = cols[0] if len(cols) == 1 else np.concatenate(cols, axis=1)   # (n, sum k_a)
    widths = [c.shape[1] for c in cols]
    if jit.use(f.tri.shape[0], KERNEL_PAYS_FROM):
        from . import kernels  # compiled kernels (numba): loaded only for large meshes
        if max(widths) <= kernels.MAX_COMPONENTS:
            return kernels.gradient_norms(a, widths, f), f.degenerate
    a0 = a[f.tri[:, 0]]
    a1 = a[f.tri[:, 1]] - a0
    a2 = a[f.tri[:, 2]] - a0
    # J = A M^-1: columns are the attribute's derivatives along the orthonormal (u, v) frame
    j0 = a1 / f.m11[:, None]
    j1 = (a2 - j0 * f.m12[:, None]) / f.m22[:, None]
    out, start = [], 0
    for c in cols:
        k = c.shape[1]
        u = np.ascontiguousarray(j0[:, start:start + k])
        v = np.ascontiguousarray(j1[:, start:start + k])
        start += k
        # ||J||_2^2 = largest eigenvalue of the symmetric 2x2 matrix J^T J = [[p, q], [q, r]]
        p_ = np.einsum("ij,ij->i", u, u)
        q_ = np.einsum("ij,ij->i", u, v)
        r_ = np.einsum("ij,ij->i", v, v)
        half_diff = 0.5 * (p_ - r_)
        lam = 0.5 * (p_ + r_) + np.sqrt(half_diff * half_diff + q_ * q_)
        out.append(np.where(f.degenerate, 0.0, np.sqrt(lam)))
    return out, f.degenerate


def triangle_gradient_norm(positions: np.ndarray, indices: np.ndarray, attribute: np.ndarray
                           ) -> tuple[np.ndarray, np.ndarray]:
    """E_t for every triangle.

    Parameters
    ----------
    positions : (n, 3) float64, metres
    indices : (m, 3) integer
    attribute : (n, k) float, any units

    Returns
    -------
    e_t : (m,) float64, attribute units per metre; 0 for degenerate triangles
    degenerate : (m,) bool
    """
    (e_t,), degenerate = triangle_gradient_norms(positions, indices, [attribute])
    return e_t, degenerate


def vertex_max(indices: np.ndarray, per_triangle: np.ndarray, n_vertices: int) -> np.ndarray:
    """(n,) float64: max of ``per_triangle`` (m,) over the triangles incident to each vertex (0 if none)."""
    tri = np.asarray(indices, dtype=np.int64)
    if jit.use(tri.shape[0], KERNEL_PAYS_FROM):
        from . import kernels  # compiled kernels (numba): loaded only for large meshes
        return kernels.vertex_max(tri.reshape(-1, 3), per_triangle, n_vertices)
    out = np.zeros(n_vertices, dtype=np.float64)
    for k in range(3):  # three vectorised passes, one per corner
        np.maximum.at(out, tri[:, k], per_triangle)
    return out


def vertex_attribute_error(positions: np.ndarray, indices: np.ndarray, attribute: np.ndarray
                           ) -> tuple[np.ndarray, int]:
    """E_v = max over incident triangles of E_t.

    Returns (e_v (n,) float64 in attribute units per metre, number of degenerate triangles)."""
    e_t, degenerate = triangle_gradient_norm(positions, indices, attribute)
    return vertex_max(indices, e_t, positions.shape[0]), int(np.count_nonzero(degenerate))
