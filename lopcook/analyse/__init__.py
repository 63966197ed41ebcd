"""Analyse: a Scene -> per-vertex minimum bit levels (constrained adaptive precision, CAP).

This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
sections 3-5. Steps: (1) one 24-bit grid for the scene, (2) E_v per shading attribute and the
attribute level, (2b) raised on the discontinuities E_v cannot see (``discontinuity``: hard edges,
folds, open boundaries, colour seams), (3) depth-critical levels, (4) m_v = max of both, (5)
co-located vertices (same quantized position, any part) share the maximum of their levels
(``colocated_max``).
"""

from __future__ import annotations

import time

import numpy as np

from ..settings import DEFAULT_ANALYSE, AnalyseSettings, DepthMode
from ..types import Scene
from .attribute_error import triangle_frames, triangle_gradient_norms, vertex_max
from .bitlevel import attribute_kf, attribute_level, texture_slope
from .depth import depth_levels
from .discontinuity import discontinuity_levels
from ..grid import BITS, Grid
from .result import REASON_CODE, Analysis, PartAnalysis


def colocated_max(q: np.ndarray, values: np.ndarray) -> np.ndarray:
    """(N,) int64: the maximum of ``values`` (N,) over each group of equal rows of ``q`` (N, 3) uint32
    grid integers (co-located vertices), for every row (``ColocatedGroups(q).max(values)``)."""
    return ColocatedGroups(q).max(values)


class ColocatedGroups:
    """The groups of equal rows of ``q`` (N, 3) grid integers (co-located vertices), found once:
    ``max(values)`` is ``colocated_max(q, values)`` for any (N,) ``values``, at the cost of two
    gathers and one reduction (a prepared analysis asks it once per probe of a search).

    Sorts one int64 key holding x, y (24 bits each) and the top 16 bits of z, then, inside each run
    of equal keys, the low 8 bits of z: two integer sorts instead of a sort of 12-byte rows (rows
    that are not 24-bit grid integers: one sort of the rows)."""

    def __init__(self, q: np.ndarray):
        q = np.asarray(q)
        n = self.n = int(q.shape[0])
        if n == 0:
            self.order = self.starts = self.group = np.zeros(0, dtype=np.int64)
            return
        if int(q.min()) < 0 or int(q.max()) >= 1 << BITS:  # not 24-bit grid integers: sort the rows
            rows = np.ascontiguousarray(q).view(np.dtype((np.void, q.dtype.itemsize * 3))).ravel()
            _, inverse = np.unique(rows, return_inverse=True)
            self.group = inverse.ravel().astype(np.int64)
            self.order = np.argsort(self.group, kind="stable")
            ranked = self.group[self.order]
            start = np.ones(n, dtype=bool)
            start[1:] = ranked[1:] != ranked[:-1]
            self.starts = np.flatnonzero(start)
            return
        # one column at a time and each temporary freed once used: on large scenes this is the
        # cook's memory peak (docs/performance.md, "Memory at 1.1M and 4.4M")
        key = q[:, 0].astype(np.int64) << 40
        key |= q[:, 1].astype(np.int64) << 16
        key |= q[:, 2].astype(np.int64) >> 8
        order = np.argsort(key)
        key = key[order]
        run = np.zeros(n, dtype=np.int64)
        np.cumsum(key[1:] != key[:-1], out=run[1:])
        del key
        run <<= 8
        run |= (q[:, 2] & 0xFF)[order]  # (run, low 8 bits of z): equal exactly for co-located rows
        within = np.argsort(run, kind="stable")  # nearly sorted already
        order = order[within]
        run = run[within]
        del within
        start = np.ones(n, dtype=bool)
        start[1:] = run[1:] != run[:-1]
        del run
        self.order, self.starts = order, np.flatnonzero(start)
        group = np.cumsum(start) - 1
        del start
        self.group = np.empty(n, dtype=np.int64)
        self.group[order] = group

    def max(self, values: np.ndarray) -> np.ndarray:
        """(N,) int64: the maximum of ``values`` (N,) over each row's group, for every row."""
        values = np.asarray(values, dtype=np.int64)
        if values.shape != (self.n,):
            raise ValueError(f"values {values.shape}: expected ({self.n},)")
        if self.n == 0:
            return np.zeros(0, dtype=np.int64)
        return np.maximum.reduceat(values[self.order], self.starts)[self.group]



def attribute_levels(e_v: dict, kf: dict, eps: float, extent: float, n: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Per-vertex attribute levels of one part (Meyer et al. 2011, section 3.2): for each attribute
    ``name`` of ``e_v`` ((n,) E_v, attribute units per metre) with ``kf[name] > 0``, the level whose
    position error keeps ``kf * E_v * error <= eps``; the maximum over attributes, clamped to
    [1, 24]. Returns (level (n,) int64, reason (n,) uint8 REASON_CODE of the attribute that set
    it, "none" at level 1; count of vertices whose bound needs more than 24 bits)."""
    level = np.ones(n, dtype=np.int64)
    reason = np.full(n, REASON_CODE["none"], dtype=np.uint8)
    for name in e_v:
        if kf[name] <= 0:
            continue
        lv = attribute_level(e_v[name], kf[name], eps, extent)
        reason[lv > level] = REASON_CODE[name]
        level = np.maximum(level, lv)
    over = int(np.count_nonzero(level > BITS))
    level = np.minimum(level, BITS)
    reason[level == 1] = REASON_CODE["none"]
    return level, reason, over


def _attribute_levels(scene: Scene, settings: AnalyseSettings, extent: float):
    """Step (2): per part, E_v of every shading attribute k_f covers and the attribute level.

    Returns lists over the parts: level (n,) int64, reason (n,) uint8, e_v dict, k_f dict,
    degenerate triangle count, count of vertices whose bound needs more than 24 bits."""
    attr_level, attr_reason, e_vs, kfs, degenerate, unsatisfied = [], [], [], [], [], []
    for part in scene.parts:
        n = part.n_vertices
        kf = attribute_kf(part, settings)
        e_v = {}
        named = [(name, attr) for name, attr in (("normal", part.normals), ("uv", part.uvs),
                                                  ("color", part.colors)) if name in kf]
        frames = triangle_frames(part.positions, part.indices)  # shared by all attributes
        e_ts, degen = triangle_gradient_norms(part.positions, part.indices, [a for _, a in named], frames)
        deg = int(np.count_nonzero(degen))
        for (name, _), e_t in zip(named, e_ts):
            e_v[name] = vertex_max(frames.tri, e_t, n)
        level, reason, over = attribute_levels(e_v, kf, settings.position_eps, extent, n)
        unsatisfied.append(over)
        attr_level.append(level)
        attr_reason.append(reason)
        e_vs.append(e_v)
        kfs.append(kf)
        degenerate.append(deg)
    return attr_level, attr_reason, e_vs, kfs, degenerate, unsatisfied


def _depth_levels(scene: Scene, settings: AnalyseSettings, extent: float, attr_level: list):
    """Step (3): per part the depth level (n,) int64, the distance (n,) float64 metres and the
    capped flags (n,) bool, in the mode ``settings.depth``; and the touching and intersecting
    pairs of part names."""
    positions = [p.positions for p in scene.parts]
    indices = [p.indices for p in scene.parts]
    names = [p.name for p in scene.parts]
    depth = settings.depth
    touching: list = []
    intersecting: list = []
    if depth == "off":
        depth_level = [np.ones(p.n_vertices, np.int64) for p in scene.parts]
        depth_dist = [np.full(p.n_vertices, np.inf) for p in scene.parts]
        capped = [np.zeros(p.n_vertices, bool) for p in scene.parts]
    elif depth is DepthMode.FIXED:
        res = depth_levels(positions, indices, extent, threshold=settings.depth_threshold)
        depth_level = [np.where(c > 0, int(settings.depth_level), 1).astype(np.int64) for c in res.level]
        depth_dist, capped = res.distance, res.capped
        intersecting = [(names[i], names[j]) for i, j in res.intersecting]
    else:
        res = depth_levels(positions, indices, extent, floors=attr_level, ceiling=settings.depth_ceiling)
        depth_level, depth_dist, capped = res.level, res.distance, res.capped
        touching = [(names[i], names[j]) for i, j in res.touching]
        intersecting = [(names[i], names[j]) for i, j in res.intersecting]
    return depth_level, depth_dist, capped, touching, intersecting


def _combine(attr_level: list, attr_reason: list, depth_level: list, capped: list):
    """Step (4): per part m_v = max(attribute, depth level) (n,) int64 and its reason (n,) uint8
    (``depth`` or ``depth-capped`` where the depth level is the larger)."""
    combined, reasons = [], []
    for k in range(len(attr_level)):
        lv = np.maximum(attr_level[k], depth_level[k])
        reason = attr_reason[k].copy()
        by_depth = depth_level[k] > attr_level[k]
        reason[by_depth] = np.where(capped[k][by_depth], REASON_CODE["depth-capped"], REASON_CODE["depth"])
        combined.append(lv)
        reasons.append(reason)
    return combined, reasons


def analyse(scene: Scene, settings: AnalyseSettings = DEFAULT_ANALYSE, grid: Grid | None = None) -> Analysis:
    """Minimum bit level m_v for every vertex of every part (see module doc and PartAnalysis)."""
    timings: dict = {}
    t0 = time.perf_counter()
    grid = grid or Grid.fit([p.positions for p in scene.parts])
    quantized = [grid.quantize(p.positions) for p in scene.parts]
    timings["grid"] = time.perf_counter() - t0

    # (2) attribute error and level
    t0 = time.perf_counter()
    attr_level, attr_reason, e_vs, kfs, degenerate, unsatisfied = _attribute_levels(scene, settings, grid.extent)
    timings["attribute_error"] = time.perf_counter() - t0

    # (2b) discontinuities E_v cannot see: hard edges, folds, boundaries, seams (reason "edge")
    if settings.edges:
        t0 = time.perf_counter()
        disc = discontinuity_levels(scene.parts, quantized, edge_eps=settings.edge_eps,
                                    edge_level=settings.edge_level, edge_angle_deg=settings.edge_angle_deg)
        for k, edge in enumerate(disc.level):
            attr_reason[k][edge > attr_level[k]] = REASON_CODE["edge"]
            attr_level[k] = np.maximum(attr_level[k], edge)
        timings["discontinuity"] = time.perf_counter() - t0

    # (3) depth
    t0 = time.perf_counter()
    depth_level, depth_dist, capped, touching, intersecting = _depth_levels(scene, settings, grid.extent, attr_level)
    timings["depth"] = time.perf_counter() - t0

    # (4) combine, (5) co-located vertices share the maximum
    t0 = time.perf_counter()
    combined, reasons = _combine(attr_level, attr_reason, depth_level, capped)
    allq = np.concatenate(quantized)
    alll = np.concatenate(combined)
    shared = colocated_max(allq, alll)
    raised_total = int(np.count_nonzero(shared > alll))
    timings["co_located"] = time.perf_counter() - t0

    parts = []
    start = 0
    for k, part in enumerate(scene.parts):
        n = part.n_vertices
        final = shared[start:start + n]
        reason = reasons[k]
        reason[final > combined[k]] = REASON_CODE["co-located"]
        parts.append(PartAnalysis(
            min_level=final.astype(np.uint8),
            reason=reason,
            attribute_level=attr_level[k].astype(np.uint8),
            depth_level=np.asarray(depth_level[k]).astype(np.uint8),
            e_v=e_vs[k],
            kf=kfs[k],
            depth_distance=np.asarray(depth_dist[k], dtype=np.float64),
            quantized=quantized[k],
            degenerate_triangles=degenerate[k],
            attribute_unsatisfied=unsatisfied[k],
            depth_capped=int(np.count_nonzero(capped[k])),
        ))
        start += n
    names = [p.name for p in scene.parts]
    return Analysis(grid=grid, parts=parts, part_names=names, settings=settings, touching=touching,
                    intersecting=intersecting, timings=timings, colocated_raised=raised_total)


__all__ = ["analyse", "Analysis", "PartAnalysis", "Grid"]
