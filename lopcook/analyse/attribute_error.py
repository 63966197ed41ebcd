"""Attribute error per triangle and per vertex: E_t = ||A M^-1||_2, E_v = max over incident triangles.

This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
section 5.1 (attribute error).

For a triangle (v0, v1, v2) with attribute vectors a_i (k components: a normal, a UV, a colour),
``A = [a1 - a0, a2 - a0]`` (k x 2) and ``M`` maps barycentric (beta, gamma) to coordinates (u, v)
in an orthonormal basis of the triangle's plane. ``A M^-1`` is the gradient of the linearly
interpolated attribute with respect to position in the plane, so its spectral norm

    E_t = ||A M^-1||_2         [attribute units per metre]

is how fast the attribute changes across the triangle (independent of which corner is v0).
Computed without forming M: with edges e1 = v1 - v0, e2 = v2 - v0 and the Gram matrix
``G = [e1 e2]^T [e1 e2] = M^T M``, ``E_t^2`` is the largest eigenvalue of ``G^-1 (A^T A)``, a
2 x 2 problem solved in closed form for all triangles at once.

Degenerate triangles (zero area: repeated or collinear corners) have no plane; they are excluded
(E_t = 0, they add nothing to E_v) and counted.
"""

from __future__ import annotations

import numpy as np

#: A triangle is degenerate when det(G) = (2 * area)^2 <= DEGENERATE_TOL * |e1|^2 |e2|^2, i.e. the
#: sine of its angle at v0 is below 1e-6 (or an edge has zero length). Dimensionless.
DEGENERATE_TOL = 1e-12


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
    tri = np.asarray(indices, dtype=np.int64)
    p = positions[tri]                                   # (m, 3, 3)
    a = np.asarray(attribute, dtype=np.float64)[tri]     # (m, 3, k)
    e1 = p[:, 1] - p[:, 0]
    e2 = p[:, 2] - p[:, 0]
    a1 = a[:, 1] - a[:, 0]
    a2 = a[:, 2] - a[:, 0]
    g11 = np.einsum("ij,ij->i", e1, e1)
    g12 = np.einsum("ij,ij->i", e1, e2)
    g22 = np.einsum("ij,ij->i", e2, e2)
    det = g11 * g22 - g12 * g12
    degenerate = ~(det > DEGENERATE_TOL * g11 * g22) | ~np.isfinite(det)
    b11 = np.einsum("ij,ij->i", a1, a1)
    b12 = np.einsum("ij,ij->i", a1, a2)
    b22 = np.einsum("ij,ij->i", a2, a2)
    safe = np.where(degenerate, 1.0, det)
    # C = G^-1 B = adj(G) B / det(G)
    c11 = (g22 * b11 - g12 * b12) / safe
    c12 = (g22 * b12 - g12 * b22) / safe
    c21 = (g11 * b12 - g12 * b11) / safe
    c22 = (g11 * b22 - g12 * b12) / safe
    # largest eigenvalue of the 2x2 matrix C: tr/2 + sqrt(tr^2/4 - det), with the discriminant
    # written as ((c11 - c22)/2)^2 + c12*c21 so it does not cancel when both eigenvalues are equal
    half_diff = 0.5 * (c11 - c22)
    disc = np.maximum(half_diff * half_diff + c12 * c21, 0.0)
    lam = np.maximum(0.5 * (c11 + c22) + np.sqrt(disc), 0.0)
    e_t = np.where(degenerate, 0.0, np.sqrt(lam))
    return e_t, degenerate


def vertex_max(indices: np.ndarray, per_triangle: np.ndarray, n_vertices: int) -> np.ndarray:
    """(n,) float64: max of ``per_triangle`` (m,) over the triangles incident to each vertex (0 if none)."""
    out = np.zeros(n_vertices, dtype=np.float64)
    tri = np.asarray(indices, dtype=np.int64)
    for k in range(3):  # three vectorised passes, one per corner
        np.maximum.at(out, tri[:, k], per_triangle)
    return out


def vertex_attribute_error(positions: np.ndarray, indices: np.ndarray, attribute: np.ndarray
                           ) -> tuple[np.ndarray, int]:
    """E_v = max over incident triangles of E_t.

    Returns (e_v (n,) float64 in attribute units per metre, number of degenerate triangles)."""
    e_t, degenerate = triangle_gradient_norm(positions, indices, attribute)
    return vertex_max(indices, e_t, positions.shape[0]), int(np.count_nonzero(degenerate))
