"""Viewing conditions and the level of precision a view needs.

This work is based on: Meyer et al. 2011, section 4 (per-buffer level by a screen-space
criterion: the bounding-box vertex closest to the camera must project its quantization error
below half a pixel; per-vertex levels from each vertex's own distance make neighbouring buffers
crack-free) and Hao & Varshney 2001, section 3.5 (bits as a function of view distance).

Units: distances in metres, angles in degrees, viewport in pixels.

Half-pixel criterion: at distance d a pixel spans ``s(d) = 2 d tan(fov_y / 2) / height`` metres
(perspective, the worst case of the vertical and horizontal fields for square pixels). A vertex
decoded at level b moves by at most ``dx(b)``, which projects to at most ``dx(b) / s(d)``
pixels, so the level is the smallest b with ``dx(b) <= pixel_error * s(d)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .grid import BITS, dx, smallest_level


@dataclass(frozen=True)
class Viewing:
    """viewport (width, height) pixels; fov_y_deg vertical field of view in degrees (0, 180);
    nearest_m: the closest any camera gets to the scene's surface, metres (None: unknown);
    pixel_error: allowed screen-space displacement in pixels (0.5 = half a pixel)."""

    viewport: tuple[int, int] = (1920, 1080)
    fov_y_deg: float = 60.0
    nearest_m: float | None = None
    pixel_error: float = 0.5

    def __post_init__(self) -> None:
        w, h = self.viewport
        if not (int(w) > 0 and int(h) > 0):
            raise ValueError(f"viewport must be positive pixels, got {self.viewport}")
        if not 0.0 < self.fov_y_deg < 180.0:
            raise ValueError(f"fov must be in (0, 180) degrees, got {self.fov_y_deg}")
        if self.nearest_m is not None and not (math.isfinite(self.nearest_m) and self.nearest_m > 0):
            raise ValueError(f"nearest distance must be a finite number > 0 m, got {self.nearest_m}")
        if not (math.isfinite(self.pixel_error) and self.pixel_error > 0):
            raise ValueError(f"pixel error must be a finite number > 0 pixels, got {self.pixel_error}")

    def pixel_size(self, distance) -> np.ndarray:
        """Metres covered by one pixel at ``distance`` metres."""
        return 2.0 * np.asarray(distance, dtype=np.float64) * math.tan(math.radians(self.fov_y_deg) / 2.0) \
            / float(self.viewport[1])

    def as_dict(self) -> dict:
        return {"viewport": [int(self.viewport[0]), int(self.viewport[1])], "fov_y_deg": float(self.fov_y_deg),
                "nearest_m": None if self.nearest_m is None else float(self.nearest_m),
                "pixel_error": float(self.pixel_error)}


def axis_rotation(axis: int, degrees: float) -> np.ndarray:
    """(3, 3) float64 right-handed rotation by ``degrees`` about axis 0 (x), 1 (y) or 2 (z)."""
    c, s = np.cos(np.radians(degrees)), np.sin(np.radians(degrees))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    m = np.eye(3)
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


#: Ry(45 deg) Rx(34 deg), the turn of the render harness's 20 icosahedron views: no view
#: direction lies within 8.9 degrees of a coordinate plane (the best of a 1-degree search), so
#: axis-aligned flat parts are never seen exactly edge-on. The glossy_crease fixture uses it too.
VIEW_ROTATION = axis_rotation(1, 45.0) @ axis_rotation(0, 34.0)


def required_level(distance, extent: float, viewing: Viewing = Viewing()) -> np.ndarray:
    """Per-buffer level for a camera ``distance`` metres from the buffer's nearest bounding-box
    vertex (half-pixel criterion, see module doc): int array in [1, 24]; 24 when even 24 bits are
    not enough (distance ~ 0)."""
    d = np.asarray(distance, dtype=np.float64)
    allowed = viewing.pixel_error * viewing.pixel_size(d)
    level = smallest_level(lambda b: dx(b, extent) <= allowed[..., None], d.shape)
    return np.minimum(level, BITS)


def distance_for_level(level: int, extent: float, viewing: Viewing = Viewing()) -> float:
    """The smallest camera distance (metres) at which ``required_level`` selects ``level`` or less:
    dx(level) = pixel_error * s(d). Beyond it, ``level`` bits are enough."""
    per_metre = viewing.pixel_error * 2.0 * math.tan(math.radians(viewing.fov_y_deg) / 2.0) / viewing.viewport[1]
    return float(dx(level, extent)) / per_metre


def nearest_box_distance(camera: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> float:
    """Distance (metres) from the camera to the closest point of the box [lo, hi] (0 inside)."""
    gap = np.maximum(np.maximum(np.asarray(lo) - camera, camera - np.asarray(hi)), 0.0)
    return float(np.linalg.norm(gap))


def hao_varshney_level(distance, far: float, viewing: Viewing = Viewing()) -> np.ndarray:
    """Hao & Varshney 2001, eq. of section 3.5: m = n + 3 + ceil(log2(1 + far / d)), with
    n = ceil(log2(max(width, height))) screen bits plus the sub-pixel bits of ``pixel_error``
    (ceil(log2(1 / pixel_error))). A conservative alternative to the half-pixel criterion (it
    assumes the object fills the view volume); clamped to [1, 24]."""
    d = np.maximum(np.asarray(distance, dtype=np.float64), 1e-300)
    n = math.ceil(math.log2(max(viewing.viewport))) + max(0, math.ceil(math.log2(1.0 / viewing.pixel_error)))
    m = n + 3 + np.ceil(np.log2(1.0 + float(far) / d))
    return np.clip(m, 1, BITS).astype(np.int64)


def per_vertex_level(positions: np.ndarray, camera: np.ndarray, extent: float, buffer_level: int,
                     min_level: np.ndarray, viewing: Viewing = Viewing()) -> np.ndarray:
    """Crack-free per-vertex level (paper section 4): the level each vertex's own distance needs,
    never above the per-buffer level (the bits in memory) and never below its bin's minimum level.
    Co-located vertices of two buffers get the same value whatever the buffers' levels, as long as
    both buffers hold at least that many bits (the per-buffer level is chosen for the buffer's
    nearest point, so it does)."""
    d = np.linalg.norm(np.asarray(positions, dtype=np.float64) - np.asarray(camera, dtype=np.float64), axis=1)
    own = required_level(d, extent, viewing)
    return np.maximum(np.minimum(own, int(buffer_level)), np.asarray(min_level, dtype=np.int64))
