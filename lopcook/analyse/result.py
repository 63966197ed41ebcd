"""Result types of the analyse stage (per part, per vertex minimum bit levels and why)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from typing import TYPE_CHECKING

from ..grid import BITS, Grid

if TYPE_CHECKING:
    from ..settings import AnalyseSettings

#: why a vertex has its minimum level (uint8 codes in PartAnalysis.reason)
REASONS = ("none", "normal", "uv", "color", "depth", "depth-capped", "co-located", "edge")
REASON_CODE = {name: i for i, name in enumerate(REASONS)}
#: the three coarse classes of a reason (attribute, depth, co-located), and none
REASON_CLASS = {"none": "none", "normal": "attribute", "uv": "attribute", "color": "attribute",
                "depth": "depth", "depth-capped": "depth", "co-located": "co-located",
                "edge": "attribute"}  # edge: lopcook.analyse.discontinuity (an attribute jump)


@dataclass
class PartAnalysis:
    """Per-vertex results for one part (arrays parallel to the part's vertices).

    min_level : (n,) uint8 in [1, 24]  m_v, the fewest bits per component the vertex may use
    reason : (n,) uint8  index into REASONS: the constraint that set m_v
    attribute_level : (n,) uint8  level from the attribute error and the discontinuity constraint (1..24)
    depth_level : (n,) uint8  level from the depth constraint alone (1..24; 1 = none)
    e_v : dict attribute name -> (n,) float64  E_v in attribute units per metre
    kf : dict attribute name -> float  k_f used (colour per attribute unit)
    depth_distance : (n,) float64 metres to the nearest other part (inf: farther than where it
        could matter, or no other part)
    quantized : (n, 3) uint32 grid integers (24 bits per component)
    degenerate_triangles : int  zero-area triangles excluded from E_v
    attribute_unsatisfied : int  vertices whose attribute bound even 24 bits cannot meet (set to 24)
    depth_capped : int  vertices whose depth constraint was capped at the ceiling
    """

    min_level: np.ndarray
    reason: np.ndarray
    attribute_level: np.ndarray
    depth_level: np.ndarray
    e_v: dict
    kf: dict
    depth_distance: np.ndarray
    quantized: np.ndarray
    degenerate_triangles: int = 0
    attribute_unsatisfied: int = 0
    depth_capped: int = 0

    def histogram(self) -> np.ndarray:
        """(25,) int64: number of vertices at each level (index = level; index 0 unused)."""
        return np.bincount(self.min_level, minlength=BITS + 1)[: BITS + 1].astype(np.int64)

    def reason_counts(self) -> dict:
        counts = np.bincount(self.reason, minlength=len(REASONS))
        return {REASONS[i]: int(c) for i, c in enumerate(counts)}


@dataclass
class Analysis:
    """Analysis of a whole scene: ``parts`` parallel to ``Scene.parts``; one grid for all.

    touching / intersecting: lists of (part name, part name) pairs; timings: stage -> seconds."""

    grid: Grid
    parts: list[PartAnalysis]
    part_names: list[str]
    settings: "AnalyseSettings"
    touching: list[tuple[str, str]] = field(default_factory=list)
    intersecting: list[tuple[str, str]] = field(default_factory=list)
    timings: dict = field(default_factory=dict)
    colocated_raised: int = 0

    def histogram(self) -> np.ndarray:
        """(25,) int64 vertex counts per level over all parts (paper Fig. 7b)."""
        return np.sum([p.histogram() for p in self.parts], axis=0)

    def reason_counts(self) -> dict:
        total: dict = {}
        for p in self.parts:
            for k, v in p.reason_counts().items():
                total[k] = total.get(k, 0) + v
        return total
