"""Run-time choice of LOD and per-buffer level for a camera distance.

This work is based on: Meyer et al. 2011, section 4 (per-buffer level by the half-pixel criterion,
``lopcook.viewing.required_level``), combined with classic discrete LOD selection by screen-space
geometric error.

LOD rule: at distance d a pixel spans ``s(d)`` metres (``Viewing.pixel_size``); LOD k may be shown
when its ``geometric_error_m`` projects to at most ``pixel_error`` pixels, i.e.
``error_k <= pixel_error * s(d)``, equivalently ``d >= t_k = error_k / (pixel_error * s(1 m))``
(``lod_threshold_m``). Of the LODs allowed at d the one with the fewest triangles is chosen (ties:
the lower index). The set of allowed LODs only grows with d, so a farther camera never gets a
finer LOD, and the per-buffer level (from the distance alone) never rises. A LOD is ever chosen
iff it is the best LOD allowed at its own threshold; then its selection range starts at
``t_k``, recorded in the manifest as ``min_distance_m`` (``selection_ranges``).
"""

from __future__ import annotations

import numpy as np

from .grid import BITS
from .viewing import Viewing, required_level


def lod_threshold_m(error_m: float, viewing: Viewing) -> float:
    """Smallest camera distance (metres) at which a LOD of geometric error ``error_m`` metres
    projects to at most ``viewing.pixel_error`` pixels (0 for an exact LOD)."""
    per_metre = float(viewing.pixel_error * viewing.pixel_size(1.0))
    return float(error_m) / per_metre


def selection_ranges(errors_m, triangles, viewing: Viewing) -> list[float | None]:
    """Per LOD of one part: the smallest distance at which ``select`` picks it (its
    ``min_distance_m``), or None when its selection range is empty (another LOD allowed at the
    same distance has no more triangles)."""
    t = [lod_threshold_m(e, viewing) for e in errors_m]
    out: list[float | None] = []
    for k in range(len(t)):
        allowed = [j for j in range(len(t)) if t[j] <= t[k]]
        best = min(allowed, key=lambda j: (int(triangles[j]), j))
        out.append(t[k] if best == k else None)
    return out


def viewing_of(manifest: dict) -> Viewing:
    """The Viewing recorded in a container manifest."""
    v = manifest["viewing"]
    return Viewing(viewport=(int(v["viewport"][0]), int(v["viewport"][1])), fov_y_deg=float(v["fov_y_deg"]),
                   nearest_m=v.get("nearest_m"), pixel_error=float(v["pixel_error"]))


def select(manifest_or_container, distance_m: float, viewing: Viewing | None = None) -> list[tuple[int, int]]:
    """Per part (manifest order): ``(lod, level)`` for a camera ``distance_m`` metres from it.

    ``manifest_or_container``: a manifest dict or a ``Container`` (its ``.manifest``).
    ``viewing``: default the one recorded in the manifest. ``lod``: the LOD with the fewest
    triangles whose ``geometric_error_m`` projects to at most ``pixel_error`` pixels at that
    distance; ``level``: ``required_level(distance_m, grid extent, viewing)`` clamped to the
    container's ``positions.max_level``. Both are non-increasing in ``distance_m``."""
    m = getattr(manifest_or_container, "manifest", manifest_or_container)
    viewing = viewing or viewing_of(m)
    d = float(distance_m)
    if not d >= 0.0:
        raise ValueError(f"distance must be >= 0 m, got {distance_m}")
    extent = float(m["grid"]["extent"])
    max_level = int(m["positions"].get("max_level", BITS))
    level = int(min(int(np.asarray(required_level(d, extent, viewing))), max_level))
    out = []
    for part in m["parts"]:
        best = 0
        best_key = None
        for k, e in enumerate(part["lods"]):
            if lod_threshold_m(e["geometric_error_m"], viewing) <= d:
                key = (int(e["triangles"]), k)
                if best_key is None or key < best_key:
                    best, best_key = k, key
        out.append((best, level))
    return out


__all__ = ["select", "selection_ranges", "lod_threshold_m", "viewing_of"]
