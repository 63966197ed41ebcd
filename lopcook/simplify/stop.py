"""Where a LOD chain stops, and the record that says so: the ``--lods auto`` stop rule.

Rule (``StopRule``; the reasons for its numbers: docs/lod.md, "Where --lods auto stops"). A LOD of
a part, of recorded error ``e`` metres (``Lod.error_m``), is kept only if

1. at its selection distance ``t = lopcook.selection.lod_threshold_m(e, viewing)`` the part still
   spans at least ``min_pixels`` pixels: ``L / s(t) >= N``, where ``L`` is the part's largest
   extent (the longest side of LOD 0's axis-aligned bounding box, metres) and ``s(t)`` the size
   of a pixel at distance ``t`` (``Viewing.pixel_size``); and
2. ``e <= max_relative_error * L``.

At the selection distance ``e = pixel_error * s(t)``, so (1) reads ``e <= pixel_error * L / N``:
the viewport and the field of view cancel (they move the distance, not the pixels the part spans
there), and ``max_error_m(L) = L * min(pixel_error / N, max_relative_error)``. The chain makes the
next LOD, measures it and drops it (and every coarser one) when its error is above that.

``STOP_CODES`` names why a chain ended. ``LodReport.stop`` holds the code, ``LodReport.dropped``
the LOD that was made and dropped (None when none was), ``LodReport.extent_m`` the part's ``L``;
``manifest_record`` turns the reports into the ``options.lods`` entries a container keeps
(docs/format.md: ``options.lods.stop_rule`` and ``options.lods.reports``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..selection import lod_threshold_m
from ..viewing import Viewing

#: rule (1): the fewest pixels a part may span at a kept LOD's selection distance (docs/lod.md)
MIN_PIXELS = 8.0
#: rule (2): the largest recorded error a kept LOD may have, as a fraction of the part's largest extent
MAX_RELATIVE_ERROR = 0.10

#: why a chain ended: code -> meaning
STOP_CODES = {
    "pixels": "the next LOD would be selected only where the part spans fewer than min_pixels pixels",
    "relative_error": "the next LOD's error is above max_relative_error of the part's largest extent",
    "view": "the next LOD's error is above what the farthest useful view shows (viewing.nearest_m given)",
    "min_triangles": "the next target has fewer triangles than the chain's minimum",
    "ratios": "every ratio asked for was made",
    "failed": "no backend could make the next LOD",
    "no_fewer": "the next LOD has no fewer triangles than the last",
    "small": "the part has too few triangles to simplify",
}


def part_extent(positions: np.ndarray) -> float:
    """The largest side of the axis-aligned bounding box of ``positions`` ((n, 3) metres), metres;
    0 for no positions."""
    p = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    if p.shape[0] == 0:
        return 0.0
    return float(np.max(p.max(axis=0) - p.min(axis=0)))


@dataclass(frozen=True)
class StopRule:
    """The ``--lods auto`` stop rule (module doc). ``viewing``: the cook's viewing conditions
    (its pixel error decides rule 1; viewport and field of view only word the record);
    ``min_pixels`` N > 0; ``max_relative_error`` in (0, 1]."""

    viewing: Viewing = field(default_factory=Viewing)
    min_pixels: float = MIN_PIXELS
    max_relative_error: float = MAX_RELATIVE_ERROR

    def __post_init__(self) -> None:
        if not (math.isfinite(self.min_pixels) and self.min_pixels > 0):
            raise ValueError(f"min_pixels must be a finite number > 0, got {self.min_pixels}")
        if not 0.0 < self.max_relative_error <= 1.0:
            raise ValueError(f"max_relative_error must be in (0, 1], got {self.max_relative_error}")

    @property
    def binding(self) -> str:
        """The stop code of the tighter rule: ``"pixels"`` (1) or ``"relative_error"`` (2)."""
        return "pixels" if self.viewing.pixel_error / self.min_pixels <= self.max_relative_error else "relative_error"

    def max_error_m(self, extent_m: float) -> float:
        """The largest error (metres) a kept LOD of a part of largest extent ``extent_m`` may have."""
        return float(extent_m) * min(self.viewing.pixel_error / self.min_pixels, self.max_relative_error)

    def distance_m(self, error_m: float) -> float:
        """The selection distance (metres) of a LOD of error ``error_m`` under ``viewing``."""
        return lod_threshold_m(error_m, self.viewing)

    def span_px(self, error_m: float, extent_m: float) -> float:
        """Pixels a part of largest extent ``extent_m`` spans at the selection distance of a LOD of
        error ``error_m`` (inf for an exact LOD)."""
        d = self.distance_m(error_m)
        if d <= 0.0:
            return math.inf
        return float(extent_m) / float(self.viewing.pixel_size(d))

    def record(self) -> dict:
        """``options.lods.stop_rule``."""
        return {"min_pixels": float(self.min_pixels), "max_relative_error": float(self.max_relative_error)}


def limit(extent_m: float, max_error_m: float | None, rule: StopRule | None) -> tuple[float | None, str]:
    """The error limit of a chain and the stop code its breach gets: the tighter of the view cap
    ``max_error_m`` (code ``"view"``; None: no cap) and the rule's (``StopRule.binding``)."""
    if rule is None:
        return max_error_m, "view"
    own = rule.max_error_m(extent_m)
    if max_error_m is not None and max_error_m < own:
        return max_error_m, "view"
    return own, rule.binding


def breach_text(code: str, name: str, triangles: int, error_m: float, limit_m: float, extent_m: float,
                rule: StopRule | None) -> str:
    """The stop reason for a LOD ``name`` (e.g. ``"LOD 0.00390625"``) dropped for an error above the
    limit, in words a technical artist acts on."""
    what = f"{name} ({triangles:,} triangles, error {error_m:.3g} m)"
    if code == "pixels" and rule is not None:
        return (f"{what} would be selected from {rule.distance_m(error_m):.3g} m, where the part spans "
                f"{rule.span_px(error_m, extent_m):.3g} px (fewer than {rule.min_pixels:g}); dropped")
    if code == "relative_error" and rule is not None:
        return (f"{what} is {100.0 * error_m / max(extent_m, 1e-300):.3g}% of the part's {extent_m:.3g} m extent "
                f"(more than {100.0 * rule.max_relative_error:g}%); dropped")
    return f"{what} exceeds max_error_m {limit_m:.3g} m; dropped"


def manifest_record(reports: list[dict], rule: StopRule) -> dict:
    """The ``options.lods`` entries of a chain cooked with ``rule``: ``{"stop_rule": rule.record(),
    "reports": [per part: {"stop", "stop_reason", "extent_m", "max_error_m", "dropped"}]}`` from
    ``LodReport.as_dict()`` records (``dropped``: ``{"triangles", "error_m"}`` of the LOD made and
    dropped, or None; its ``error_m`` None for a copy placed by a map that is not a similarity)."""
    out = []
    for r in reports:
        d = r.get("dropped")
        out.append({"stop": r.get("stop", ""), "stop_reason": r.get("stop_reason", ""),
                    "extent_m": r.get("extent_m"), "max_error_m": r.get("max_error_m"),
                    "dropped": None if d is None else {
                        "triangles": int(d["triangles"]),
                        "error_m": None if d.get("error_m") is None else float(d["error_m"])}})
    return {"stop_rule": rule.record(), "reports": out}


__all__ = ["MIN_PIXELS", "MAX_RELATIVE_ERROR", "STOP_CODES", "StopRule", "part_extent", "limit", "breach_text",
           "manifest_record"]
