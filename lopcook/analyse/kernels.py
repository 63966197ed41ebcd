"""Compiled kernels of the attribute error (E_t, E_v), beside ``attribute_error.py`` whose numpy
code they replace for large meshes (``lopcook.jit.use``) and which stays their test oracle.

This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
section 5.1 (attribute error); the formulas are those of ``attribute_error``'s module doc.

Bit for bit: every operation is numpy's, in numpy's order. numpy's ``einsum("ij,ij->i")`` over
k <= 7 components sums the products in two 128-bit lanes, ``(p0 + p2 + p4 + p6) + (p1 + p3 + p5)``
(``_dot``); ``np.cross`` is ``a1*b2 - a2*b1`` and so on; no fused multiply-add (no ``fastmath``).
tests/test_kernels_analyse.py compares the kernels with the numpy functions on random and corpus
inputs. Rows (triangles) are independent and run in ``lopcook.jit.threads()`` threads;
``vertex_max`` is one serial scatter (a maximum: the order of the triangles does not matter).
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import njit, parallel_ranges

#: widest attribute (components) whose dot products ``_dot`` sums in numpy's einsum order
MAX_COMPONENTS = 7


@njit(inline="always")
def _dot3(ax, ay, az, bx, by, bz):
    """numpy's ``einsum("ij,ij->i")`` of two 3-vectors: (x*x' + z*z') + y*y'."""
    return (ax * bx + az * bz) + ay * by


@njit(inline="always")
def _dot(u, v, k):
    """numpy's ``einsum("ij,ij->i")`` of two k-vectors (k <= ``MAX_COMPONENTS``): even and odd
    products summed in two lanes, then the lanes added."""
    even = u[0] * v[0]
    odd = u[1] * v[1] if k > 1 else 0.0
    for j in range(2, k, 2):
        even += u[j] * v[j]
        if j + 1 < k:
            odd += u[j + 1] * v[j + 1]
    return even + odd


@njit
def _frames(pos, tri, tol, m11, m12, m22, degenerate, a, b):
    """Rows a..b of ``attribute_error.triangle_frames``: M and the degenerate flag per triangle."""
    for f in range(a, b):
        i0, i1, i2 = tri[f, 0], tri[f, 1], tri[f, 2]
        x0, y0, z0 = pos[i0, 0], pos[i0, 1], pos[i0, 2]
        e1x, e1y, e1z = pos[i1, 0] - x0, pos[i1, 1] - y0, pos[i1, 2] - z0
        e2x, e2y, e2z = pos[i2, 0] - x0, pos[i2, 1] - y0, pos[i2, 2] - z0
        l1sq = _dot3(e1x, e1y, e1z, e1x, e1y, e1z)
        l2sq = _dot3(e2x, e2y, e2z, e2x, e2y, e2z)
        cx = e1y * e2z - e1z * e2y
        cy = e1z * e2x - e1x * e2z
        cz = e1x * e2y - e1y * e2x
        csq = _dot3(cx, cy, cz, cx, cy, cz)
        deg = not (csq > tol * l1sq * l2sq) or not math.isfinite(csq)
        degenerate[f] = deg
        r11 = math.sqrt(1.0 if deg else l1sq)
        m11[f] = r11
        m12[f] = (0.0 if deg else _dot3(e1x, e1y, e1z, e2x, e2y, e2z)) / r11
        m22[f] = math.sqrt(1.0 if deg else csq) / r11


@njit
def _gradient_norms(attr, start, k, tri, m11, m12, m22, degenerate, out, a, b):
    """Rows a..b of E_t for the attribute in columns ``start .. start + k`` of ``attr`` (n, K)
    float64: ``attribute_error.triangle_gradient_norms``' J = A M^-1 and its spectral norm."""
    u = np.empty(k)
    v = np.empty(k)
    for f in range(a, b):
        i0, i1, i2 = tri[f, 0], tri[f, 1], tri[f, 2]
        r11, r12, r22 = m11[f], m12[f], m22[f]
        for j in range(k):
            c0 = attr[i0, start + j]
            j0 = (attr[i1, start + j] - c0) / r11
            u[j] = j0
            v[j] = ((attr[i2, start + j] - c0) - j0 * r12) / r22
        p = _dot(u, u, k)
        q = _dot(u, v, k)
        r = _dot(v, v, k)
        half = 0.5 * (p - r)
        lam = 0.5 * (p + r) + math.sqrt(half * half + q * q)
        out[f] = 0.0 if degenerate[f] else math.sqrt(lam)


@njit
def _vertex_max(tri, per_triangle, out):
    """``attribute_error.vertex_max``: out[v] = max(out[v], per_triangle[f]) for every corner
    (a NaN stays, as in ``np.maximum``)."""
    for k in range(3):
        for f in range(tri.shape[0]):
            x = per_triangle[f]
            v = tri[f, k]
            o = out[v]
            if x > o or (x != x and o == o):
                out[v] = x


def triangle_frames(positions: np.ndarray, tri: np.ndarray, tol: float):
    """(m11, m12, m22, degenerate) of ``attribute_error.triangle_frames``: positions (n, 3)
    float64, tri (m, 3) int64, ``tol`` its ``DEGENERATE_TOL``."""
    m = tri.shape[0]
    m11, m12, m22 = np.empty(m), np.empty(m), np.empty(m)
    degenerate = np.empty(m, dtype=bool)
    parallel_ranges(_frames, m, np.ascontiguousarray(positions), np.ascontiguousarray(tri), float(tol),
                    m11, m12, m22, degenerate)
    return m11, m12, m22, degenerate


def gradient_norms(attr: np.ndarray, widths: list[int], frames) -> list[np.ndarray]:
    """E_t (m,) per attribute of ``attribute_error.triangle_gradient_norms``: ``attr`` (n, K)
    float64 the attributes side by side, ``widths`` their component counts (each at most
    ``MAX_COMPONENTS``), ``frames`` an ``attribute_error.TriangleFrames``."""
    a = np.ascontiguousarray(attr, dtype=np.float64)
    tri = np.ascontiguousarray(frames.tri)
    out, start = [], 0
    for k in widths:
        e = np.empty(tri.shape[0])
        parallel_ranges(_gradient_norms, tri.shape[0], a, start, k, tri, frames.m11, frames.m12, frames.m22,
                        frames.degenerate, e)
        out.append(e)
        start += k
    return out


def vertex_max(tri: np.ndarray, per_triangle: np.ndarray, n_vertices: int) -> np.ndarray:
    """``attribute_error.vertex_max``: (n,) float64 max of ``per_triangle`` (m,) over each vertex's
    triangles ``tri`` (m, 3) int64, 0 where none."""
    out = np.zeros(n_vertices)
    _vertex_max(np.ascontiguousarray(tri), np.ascontiguousarray(per_triangle, dtype=np.float64), out)
    return out


__all__ = ["MAX_COMPONENTS", "triangle_frames", "gradient_norms", "vertex_max"]
