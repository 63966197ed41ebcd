"""Where the render harness looks from: 20 icosahedron view directions, camera placement at the
distance where the half-pixel criterion selects a per-buffer level, and the GL matrices.

This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
section 4 (per-buffer level by the half-pixel criterion, ``lopcook.viewing.required_level``); and
Purnomo et al., "Hardware-Compatible Vertex Compression Using Quantization and Simplification",
Graphics Hardware 2005, section 4.1 (20 views on an icosahedron).

Units: metres, degrees, pixels. Contract:

* Views: the 20 face-centre directions of a regular icosahedron (``icosahedron_directions``, turned
  by ``lopcook.viewing.VIEW_ROTATION`` so that none is within 8.9 degrees of a coordinate plane)
  around the centre of the scene's axis-aligned bounding box. ``views=N`` takes N of them spread
  over the list (``select_views``).
* Distance for level B: ``d_B = distance_for_level(B, extent, viewing) * (1 + 2^-20)``
  (``camera_distance``), where ``extent`` is the grid extent and ``viewing`` the container's field
  of view and pixel error with the **render** resolution as viewport (``render_viewing``). The eye
  is placed on the view ray so that its distance to the **nearest point of the bounding box** is
  exactly d_B (``place_camera``): ``required_level`` selects B for the whole scene and for every
  part (each part's box is at least that far). Since d_B grows with the viewport height, an object
  covers the same number of pixels at level B whatever the resolution (about 2^B / sqrt(3) pixels
  across at the nearest point): a smaller resolution crops, it does not shrink.
* Projection (``make_camera``): perspective, vertical field of view from the viewing (60 degrees
  by default), aspect w/h; near = 0.9 * d_B * cos(half diagonal field of view) (no visible point is
  closer), far = |eye - centre| + 1.01 * r with r the half diagonal of the box.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import LopcookError
from ..mesh import icosahedron
from ..settings import DEFAULTS
from ..viewing import VIEW_ROTATION, Viewing, distance_for_level, nearest_box_distance

#: number of icosahedron view directions
VIEW_COUNT = DEFAULTS.render.views
#: cameras sit this much (relative) beyond d_B, so that ``required_level`` gives B
DISTANCE_MARGIN = 2.0**-20


def icosahedron_directions() -> np.ndarray:
    """(20, 3) float64 unit vectors: the face centres of the regular icosahedron of
    ``lopcook.mesh.icosahedron`` (vertices (±1, ±φ, 0) and cyclic permutations), in its face order,
    rotated by ``VIEW_ROTATION``. Directions point from the scene centre to the eye. Unrotated, 12
    of the 20 lie in a coordinate plane, and a flat axis-aligned part (a plate, a CAD face, a chess
    board) seen exactly edge-on is a line of coverage pixels and nothing else; rotated, every
    direction is at least 8.9 degrees away from each coordinate plane."""
    v, f = icosahedron()
    c = v[f].sum(axis=1)
    c = c / np.linalg.norm(c, axis=1, keepdims=True)
    return c @ VIEW_ROTATION.T


def select_views(views) -> list[int]:
    """Indices into ``icosahedron_directions``: an int N in [1, 20] takes N spread over the 20
    (``floor(i * 20 / N)``), a sequence is taken as given."""
    if isinstance(views, (int, np.integer)):
        n = int(views)
        if not 1 <= n <= VIEW_COUNT:
            raise LopcookError("usage", None, f"views must be in [1, {VIEW_COUNT}], got {n}")
        return [(i * VIEW_COUNT) // n for i in range(n)]
    out = [int(v) for v in views]
    if not out or min(out) < 0 or max(out) >= VIEW_COUNT:
        raise LopcookError("usage", None, f"view indices must be in [0, {VIEW_COUNT - 1}], got {out}")
    return out


def render_viewing(manifest: dict, resolution) -> Viewing:
    """The container's viewing conditions (field of view, pixel error) with the render resolution
    as viewport: the criterion the render is judged by."""
    v = manifest.get("viewing") or {}
    return Viewing(viewport=(int(resolution[0]), int(resolution[1])), fov_y_deg=float(v.get("fov_y_deg", 60.0)),
                   pixel_error=float(v.get("pixel_error", 0.5)))


def camera_distance(level: int, extent: float, viewing: Viewing) -> float:
    """Distance (metres) from the camera to the nearest bounding-box point at which
    ``required_level`` selects ``level``: ``distance_for_level`` plus a 2^-20 relative margin."""
    return distance_for_level(int(level), float(extent), viewing) * (1.0 + DISTANCE_MARGIN)


def place_camera(direction, lo, hi, distance: float) -> np.ndarray:
    """Eye position (3,) float64 on the ray ``centre + t * direction`` (centre of the box [lo, hi])
    whose distance to the nearest box point is ``distance`` metres (bisection on t, to 1e-15 relative)."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    u = np.asarray(direction, np.float64)
    u = u / np.linalg.norm(u)
    centre = 0.5 * (lo + hi)
    a, b = 0.0, float(distance) + float(np.linalg.norm(hi - lo)) + 1e-300
    for _ in range(200):
        m = 0.5 * (a + b)
        if nearest_box_distance(centre + m * u, lo, hi) < distance:
            a = m
        else:
            b = m
        if b - a <= 1e-15 * b:
            break
    return centre + b * u


def look_at(eye, target, up=None) -> np.ndarray:
    """(4, 4) float64 view matrix (right-handed, camera looks down -z). ``up`` defaults to +Y, or +Z
    when the view direction is within about 8 degrees of the Y axis."""
    eye, target = np.asarray(eye, np.float64), np.asarray(target, np.float64)
    f = target - eye
    f /= np.linalg.norm(f)
    if up is None:
        up = np.array([0.0, 1.0, 0.0]) if abs(f[1]) < 0.99 else np.array([0.0, 0.0, 1.0])
    s = np.cross(f, up)
    s /= np.linalg.norm(s)
    u = np.cross(s, f)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = s, u, -f
    m[:3, 3] = -m[:3, :3] @ eye
    return m


def perspective(fov_y_deg: float, aspect: float, near: float, far: float) -> np.ndarray:
    """(4, 4) float64 OpenGL projection matrix (clip z in [-w, w])."""
    f = 1.0 / math.tan(math.radians(fov_y_deg) / 2.0)
    m = np.zeros((4, 4))
    m[0, 0], m[1, 1] = f / aspect, f
    m[2, 2] = (far + near) / (near - far)
    m[2, 3] = 2.0 * far * near / (near - far)
    m[3, 2] = -1.0
    return m


@dataclass
class Camera:
    """One view: eye (3,) metres, direction index, mvp (4, 4) float64, near/far metres, and the
    distance from the eye to the nearest box point (metres)."""

    view: int
    eye: np.ndarray
    centre: np.ndarray
    mvp: np.ndarray
    near: float
    far: float
    box_distance: float


def make_camera(view: int, lo, hi, distance: float, viewing: Viewing) -> Camera:
    """The camera of icosahedron view ``view`` at ``distance`` metres from the box [lo, hi]."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    centre = 0.5 * (lo + hi)
    radius = 0.5 * float(np.linalg.norm(hi - lo))
    eye = place_camera(icosahedron_directions()[view], lo, hi, distance)
    w, h = viewing.viewport
    aspect = float(w) / float(h)
    t = math.tan(math.radians(viewing.fov_y_deg) / 2.0)
    cos_diag = 1.0 / math.sqrt(1.0 + t * t * (1.0 + aspect * aspect))
    span = float(np.linalg.norm(eye - centre)) + 1.01 * radius
    near = 0.9 * distance * cos_diag if distance > 0 else 1e-4 * max(radius, 1e-9)
    near = max(near, span * 1e-7)
    far = span
    mvp = perspective(viewing.fov_y_deg, aspect, near, far) @ look_at(eye, centre)
    return Camera(view=int(view), eye=eye, centre=centre, mvp=mvp, near=near, far=far,
                  box_distance=nearest_box_distance(eye, lo, hi))


__all__ = ["VIEW_COUNT", "DISTANCE_MARGIN", "VIEW_ROTATION", "icosahedron_directions", "select_views",
           "render_viewing", "camera_distance", "place_camera", "look_at", "perspective", "Camera", "make_camera"]
