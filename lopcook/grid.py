"""ONE 24-bit fixed-point grid for the whole scene (all parts, all LODs).

This work is based on: Q. Meyer, G. Sussner, G. Greiner, M. Stamminger, "Adaptive
Level-of-Precision for GPU-Rendering", VMV 2011, section 3 (24-bit fixed point per component).

Every position of every part and LOD is quantized on the same grid, so vertices that coincide in
the source (shared part boundaries, UV seams) get identical integers and can never crack apart.

Definitions (lengths in metres, ``B = 24`` bits):

* ``origin`` (3,) float64: the minimum corner of the scene bounds.
* ``extent`` float64 > 0: the largest side of the scene bounds (a cube, so all axes share one
  step); ``h = extent / 2**24`` is the cell size.
* quantize: ``q = clip(floor((p - origin) / h), 0, 2**24 - 1)`` (uint32 per component). The point
  lies in cell ``q`` (or on the far face of the last cell).
* decode at level ``b`` in [1, 24]: keep the top ``b`` bits, ``s = 24 - b`` dropped bits, and
  reconstruct at the centre of the dropped range::

      p_b = origin + (((q >> s) << s) + 2**s / 2) * h          (per component)

  i.e. the centre of the block of ``2**s`` cells the point lies in. The per-component error is at
  most half a block, ``2**s * h / 2 = extent * 2**-(b+1)``, so the displacement is at most

      dx(b) = sqrt(3) * extent * 2**-(b+1)        [metres]

  (at ``b = 24`` this is the centre of the point's own cell).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

BITS = 24
CELLS = 1 << BITS
#: smallest grid extent, metres (see ``Grid.fit``): keeps every decoded float32 value normal
MIN_EXTENT = 2.0 ** -75


def dx(level, extent: float) -> np.ndarray:
    """Maximum displacement (metres) of a vertex decoded at ``level`` bits: sqrt(3)*extent*2^-(level+1).

    ``level`` may be an int or an integer array in [1, 24]; returns float64 of the same shape.
    """
    level = np.asarray(level, dtype=np.float64)
    return np.sqrt(3.0) * float(extent) * np.exp2(-(level + 1.0))


@dataclass(frozen=True)
class Grid:
    """Scene quantization grid: ``origin`` (3,) float64 metres, ``extent`` float64 metres (cube side)."""

    origin: tuple[float, float, float]
    extent: float
    bits: int = BITS

    @classmethod
    def fit(cls, position_arrays) -> "Grid":
        """Smallest axis-aligned cube (min corner, largest side) holding every (n_i, 3) array given.

        A scene whose points all coincide gets extent 1 m (any step works for it). The extent is
        at least ``MIN_EXTENT`` (2^-75 m), so that no float32 value a decoder computes from the grid
        (origin + (q + 1/2) * cell, and its partial sums) is subnormal: half a cell is then at least
        2^-100, a sum near zero is exact (Sterbenz) and so either 0 or at least 2^-124, and GPUs
        that flush subnormals to zero agree with the CPU reference bit for bit."""
        lo = np.min([np.asarray(p, dtype=np.float64).min(axis=0) for p in position_arrays], axis=0)
        hi = np.max([np.asarray(p, dtype=np.float64).max(axis=0) for p in position_arrays], axis=0)
        extent = float(np.max(hi - lo))
        if not extent > 0.0:
            extent = 1.0
        extent = max(extent, MIN_EXTENT)
        return cls(origin=tuple(float(v) for v in lo), extent=extent)

    @property
    def cell(self) -> float:
        """Cell size h = extent / 2^24, metres."""
        return self.extent / CELLS

    def dx(self, level) -> np.ndarray:
        """Maximum displacement at ``level`` bits, metres (see module doc)."""
        return dx(level, self.extent)

    def quantize(self, positions: np.ndarray) -> np.ndarray:
        """(n, 3) float64 metres -> (n, 3) uint32 in [0, 2^24). Points outside the cube are clamped."""
        t = (np.asarray(positions, dtype=np.float64) - np.asarray(self.origin)) / self.cell
        return np.clip(np.floor(t), 0, CELLS - 1).astype(np.uint32)

    def reconstruct(self, q: np.ndarray, level) -> np.ndarray:
        """(n, 3) uint32 grid integers decoded at ``level`` (int, or (n,) int array) -> (n, 3) float64 metres.

        Keeps the top ``level`` bits and reconstructs at the centre of the dropped range."""
        q = np.asarray(q, dtype=np.int64)
        s = (BITS - np.asarray(level, dtype=np.int64))
        if s.ndim == 1:
            s = s[:, None]
        top = (q >> s) << s
        centre = top.astype(np.float64) + np.exp2(s.astype(np.float64)) * 0.5
        return np.asarray(self.origin) + centre * self.cell

    def level_for_displacement(self, distance) -> np.ndarray:
        """Smallest level b in [1, 24] with dx(b) <= distance (int array); 25 where even 24 is too coarse."""
        d = np.asarray(distance, dtype=np.float64)
        return smallest_level(lambda b: self.dx(b) <= d[..., None], d.shape)


def smallest_level(ok, shape) -> np.ndarray:
    """Smallest b in [1, 24] for which the vectorised predicate ``ok(b)`` holds, else 25.

    ``ok`` receives a (1, ..., 24)-shaped level array broadcast against ``shape + (24,)`` and must be
    monotone (false below some level, true from it on). Exact: evaluates the predicate itself
    rather than a logarithm, so rounding can never put a vertex one level too low.
    """
    levels = np.arange(1, BITS + 1, dtype=np.float64).reshape((1,) * len(shape) + (BITS,))
    good = np.broadcast_to(ok(levels), tuple(shape) + (BITS,))
    first = np.argmax(good, axis=-1) + 1
    return np.where(good.any(axis=-1), first, BITS + 1).astype(np.int64)
