"""The analysis split for searches over eps and edge_eps: what does not depend on them is computed
once, each probe pays only the per-threshold part.

This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
sections 5.1 (the minimum level: the smallest b with k_f * E_v * dx(b) <= eps) and 5.2 (depth). The
k_f calibration (``lopcook.tune.calibrate``) cooks the same scene at many eps (= eps / sigma) and
edge_eps; of ``lopcook.analyse.analyse``'s steps

* the grid and the quantized positions, E_v per attribute (triangle frames and gradient norms),
  the discontinuities' co-located groups, open boundary, fold levels B_v and seam jumps J_v do not
  depend on either threshold: ``PreparedAnalysis`` computes them once;
* the attribute level (E_v against eps), the discontinuity level (B_v, J_v against edge_eps) and
  the co-located maximum are cheap per probe;
* the depth constraint (``auto`` mode) depends on the vertices' floors (their attribute level)
  only through which exact distances it looks up: within a vertex's binding radius 2 dx(floor)
  the distance is exact, beyond it the level it gives is <= the floor. The prepared analysis keeps,
  per vertex, the exact distance found at the lowest floor seen so far; a probe whose floor of a
  vertex is not below it reuses it (any distance up to the smaller radius is the same exact
  minimum, a larger one gives a level <= the floor either way). A distance at most the radius it
  was found within is the exact nearest distance to any other part, at every floor. When some
  vertex's floor is lower than any before (and its distance is not known exactly), every vertex
  not known exactly is looked up again at ``LOOKAHEAD`` levels below its floor
  (``lopcook.analyse.depth.depth_levels`` with the other vertices' radius at its smallest,
  2 dx(24)): building the parts' trees is most of a look-up's cost, and a search that lowers k_f
  step by step then looks up once every few steps. ``FIXED`` and ``off`` depth do not depend on
  the floors at all.

Guarantee (``tests/analyse/test_analyse_prepared.py``): ``PreparedAnalysis(scene, s).analyse(eps, edge_eps)``
gives the same ``min_level``, ``reason``, ``attribute_level``, ``e_v``, ``kf`` and ``quantized``
per part as ``analyse(scene, replace(s, eps=eps, edge_eps=edge_eps))``, hence the same built
container buffers, whatever the order of the probes. ``depth_level`` and ``depth_distance`` may hold
more (finite distances beyond a vertex's binding radius, where the level they give is <= the floor
and changes nothing), and ``touching`` / ``intersecting`` are not computed (empty): a probe's
container is only rendered and measured, never written.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from ..grid import BITS, Grid, dx
from ..settings import AnalyseSettings, DepthMode
from ..types import Scene
from . import ColocatedGroups, attribute_kf, attribute_levels
from .attribute_error import triangle_frames, triangle_gradient_norms, vertex_max
from .depth import depth_levels, level_from_distance
from .discontinuity import (base_colours, boundary_vertices, colocated_groups, fold_levels, required_level,
                            seam_jumps)
from .result import REASON_CODE, Analysis, PartAnalysis


#: when a probe's floors fall below every floor seen, the depth distances are looked up for this many
#: levels lower still: a k_f search lowers the floors one level per step of log2 k_f, and one look-up
#: then serves the next LOOKAHEAD steps (the choice, measured: docs/performance.md, "Depth look-ups
#: ahead of the floors" and "The chess set's calibration under 90 s")
LOOKAHEAD = 6


class PreparedAnalysis:
    """The eps- and edge_eps-independent part of ``analyse(scene, settings)`` (module doc); every
    other field of ``settings`` is fixed. ``analyse(eps, edge_eps)`` returns the Analysis of
    ``replace(settings, eps=eps, edge_eps=edge_eps)``. ``timings`` holds the one-time costs (s);
    ``depth_queries`` counts the exact distance look-ups made so far (a cost measure)."""

    def __init__(self, scene: Scene, settings: AnalyseSettings):
        t_start = time.perf_counter()
        self.scene, self.settings = scene, settings
        parts = scene.parts
        self.grid = Grid.fit([p.positions for p in parts])
        self.quantized = [self.grid.quantize(p.positions) for p in parts]
        self.kfs, self.e_vs, self.degenerate = [], [], []
        for part in parts:
            kf = attribute_kf(part, settings)
            named = [(name, attr) for name, attr in (("normal", part.normals), ("uv", part.uvs),
                                                      ("color", part.colors)) if name in kf]
            frames = triangle_frames(part.positions, part.indices)
            e_ts, degen = triangle_gradient_norms(part.positions, part.indices, [a for _, a in named], frames)
            self.e_vs.append({name: vertex_max(frames.tri, e_t, part.n_vertices) for (name, _), e_t in zip(named, e_ts)})
            self.kfs.append(kf)
            self.degenerate.append(int(np.count_nonzero(degen)))
        sizes = [p.n_vertices for p in parts]
        self.offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        self.fold = self.jump = self.seam = None
        if settings.edges and self.offsets[-1] > 0:  # discontinuity_levels, up to its edge_eps step
            q = np.concatenate([np.asarray(x, dtype=np.int64).reshape(-1, 3) for x in self.quantized])
            groups = colocated_groups(q)
            tris = np.concatenate([np.asarray(p.indices, dtype=np.int64).reshape(-1, 3) + self.offsets[k]
                                   for k, p in enumerate(parts)])
            boundary = boundary_vertices(groups, tris)
            normals = np.concatenate([np.zeros((p.n_vertices, 3)) if p.normals is None
                                      else np.asarray(p.normals, dtype=np.float64) for p in parts])
            has_normal = np.concatenate([np.full(p.n_vertices, p.normals is not None) for p in parts])
            self.fold = fold_levels(q, normals, has_normal, boundary, settings.edge_level, settings.edge_angle_deg)
            self.jump = seam_jumps(groups, base_colours(parts, None))
            self.seam = self.jump > 0
        allq = np.concatenate(self.quantized) if parts else np.zeros((0, 3), np.uint32)
        self.colocated = ColocatedGroups(allq)  # the co-located groups every analyse() takes the maximum over
        del allq
        # depth: per vertex the exact distance at the lowest floor seen (BITS + 1: none yet)
        self._floor_seen = [np.full(n, BITS + 1, np.int64) for n in sizes]
        self._best = [np.full(n, np.inf) for n in sizes]
        self.depth_queries = 0
        self._fixed = None
        if settings.depth is DepthMode.FIXED:
            res = depth_levels([p.positions for p in parts], [p.indices for p in parts], self.grid.extent,
                               threshold=settings.depth_threshold, detect_intersections=False)
            self._fixed = ([np.where(c > 0, int(settings.depth_level), 1).astype(np.int64) for c in res.level],
                           res.distance)
            self.depth_queries += res.queries
        self.timings = {"prepare": time.perf_counter() - t_start}

    def _depth(self, floors: list[np.ndarray]):
        """(levels, distances, capped) per part for the auto depth mode at ``floors`` (module doc)."""
        parts = self.scene.parts
        ceiling = int(self.settings.depth_ceiling)
        # a distance found within the binding radius of the floor it was looked up at is the exact
        # nearest distance to any other part (a part farther than that radius from the vertex's box
        # test is farther than the distance): a lower floor cannot change it (the 1e-9 is slack for
        # the rounding of the box distances against libigl's)
        exact = [b <= 2.0 * dx(np.minimum(s, BITS), self.grid.extent) * (1.0 - 1e-9)
                 for b, s in zip(self._best, self._floor_seen)]
        if len(parts) >= 2 and any(((f < s) & ~e).any() for f, s, e in zip(floors, self._floor_seen, exact)):
            # some vertex's floor is below any seen: look up every vertex not known exactly at
            # LOOKAHEAD levels below its floor (the trees, not the look-ups, are most of the cost,
            # and the searches lower k_f step by step)
            ahead = [np.maximum(np.asarray(f, dtype=np.int64) - LOOKAHEAD, 1) for f in floors]
            ask = [(a < s) & ~e for a, s, e in zip(ahead, self._floor_seen, exact)]
            res = depth_levels([p.positions for p in parts], [p.indices for p in parts], self.grid.extent,
                               floors=[np.where(n, a, BITS) for n, a in zip(ask, ahead)], ceiling=ceiling,
                               detect_intersections=False)
            self.depth_queries += res.queries
            for k, n in enumerate(ask):
                self._best[k] = np.where(n, res.distance[k], self._best[k])
                self._floor_seen[k] = np.where(n, ahead[k], self._floor_seen[k])
        for k in range(len(parts)):  # the exact ones hold at every lower floor too
            self._floor_seen[k] = np.minimum(self._floor_seen[k], floors[k])
        levels, capped = [], []
        for b in self._best:
            raw = level_from_distance(b, self.grid.extent)
            capped.append(raw > ceiling)
            levels.append(np.minimum(raw, ceiling).astype(np.int64))
        return levels, [b.copy() for b in self._best], capped

    def analyse(self, eps: float, edge_eps: float | None = None) -> Analysis:
        """The Analysis of ``replace(settings, eps=eps, edge_eps=edge_eps)`` (edge_eps None: the
        settings'); the guarantee of the module doc."""
        timings: dict = {}
        t0 = time.perf_counter()
        s = replace(self.settings, eps=float(eps),
                    edge_eps=self.settings.edge_eps if edge_eps is None else float(edge_eps))
        parts = self.scene.parts
        attr_level, attr_reason, unsatisfied = [], [], []
        for part, e_v, kf in zip(parts, self.e_vs, self.kfs):
            level, reason, over = attribute_levels(e_v, kf, s.position_eps, self.grid.extent, part.n_vertices)
            unsatisfied.append(over)
            attr_level.append(level)
            attr_reason.append(reason)
        timings["attribute_error"] = time.perf_counter() - t0
        if s.edges and self.fold is not None:
            t0 = time.perf_counter()
            fold_level = required_level(self.fold, np.ones(self.fold.shape[0]), s.edge_eps)
            seam_level = required_level(np.where(self.seam, int(s.edge_level), 0), self.jump, s.edge_eps)
            edge_all = np.maximum(fold_level, seam_level)
            for k in range(len(parts)):
                edge = edge_all[self.offsets[k]:self.offsets[k + 1]]
                attr_reason[k][edge > attr_level[k]] = REASON_CODE["edge"]
                attr_level[k] = np.maximum(attr_level[k], edge)
            timings["discontinuity"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        if s.depth == "off":
            depth_level = [np.ones(p.n_vertices, np.int64) for p in parts]
            depth_dist = [np.full(p.n_vertices, np.inf) for p in parts]
            capped = [np.zeros(p.n_vertices, bool) for p in parts]
        elif s.depth is DepthMode.FIXED:
            depth_level, depth_dist = self._fixed
            capped = [np.zeros(p.n_vertices, bool) for p in parts]
        else:
            depth_level, depth_dist, capped = self._depth(attr_level)
        timings["depth"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        combined, reasons = [], []
        for k in range(len(parts)):
            combined.append(np.maximum(attr_level[k], depth_level[k]))
            reason = attr_reason[k].copy()
            by_depth = depth_level[k] > attr_level[k]
            reason[by_depth] = np.where(capped[k][by_depth], REASON_CODE["depth-capped"], REASON_CODE["depth"])
            reasons.append(reason)
        alll = np.concatenate(combined) if combined else np.zeros(0, np.int64)
        shared = self.colocated.max(alll)
        timings["co_located"] = time.perf_counter() - t0
        out = []
        for k, part in enumerate(parts):
            final = shared[self.offsets[k]:self.offsets[k + 1]]
            reason = reasons[k]
            reason[final > combined[k]] = REASON_CODE["co-located"]
            out.append(PartAnalysis(
                min_level=final.astype(np.uint8), reason=reason, attribute_level=attr_level[k].astype(np.uint8),
                depth_level=np.asarray(depth_level[k]).astype(np.uint8), e_v=self.e_vs[k], kf=self.kfs[k],
                depth_distance=np.asarray(depth_dist[k], dtype=np.float64), quantized=self.quantized[k],
                degenerate_triangles=self.degenerate[k], attribute_unsatisfied=unsatisfied[k],
                depth_capped=int(np.count_nonzero(capped[k]))))
        return Analysis(grid=self.grid, parts=out, part_names=[p.name for p in parts], settings=s, touching=[],
                        intersecting=[], timings=timings,
                        colocated_raised=int(np.count_nonzero(shared > alll)))


#: the last ``shared`` analysis: (scene, its settings with eps and edge_eps set to 1, PreparedAnalysis)
_SHARED: list = []


def shared(scene: Scene, settings: AnalyseSettings) -> PreparedAnalysis:
    """A ``PreparedAnalysis`` of ``scene`` (the same object) and ``settings`` (up to eps and edge_eps,
    which it does not depend on), kept for the next caller: the k_f calibration and the attribute
    search of one cook prepare the scene once. Asking for another scene or other settings replaces
    it (one is held at a time)."""
    prep = held(scene, settings)
    if prep is not None:
        return prep
    _SHARED.clear()
    prep = PreparedAnalysis(scene, settings)
    _SHARED.append((scene, _key(settings), prep))
    return prep


def held(scene: Scene, settings: AnalyseSettings) -> PreparedAnalysis | None:
    """The analysis ``shared`` holds for ``scene`` and ``settings`` (up to eps and edge_eps), or None;
    prepares nothing."""
    if _SHARED and _SHARED[0][0] is scene and _SHARED[0][1] == _key(settings):
        return _SHARED[0][2]
    return None


def _key(settings: AnalyseSettings) -> AnalyseSettings:
    """What a preparation depends on: the settings without eps and edge_eps."""
    return replace(settings, eps=1.0, edge_eps=1.0)


def release_shared() -> None:
    """Drop the analysis ``shared`` holds."""
    _SHARED.clear()


__all__ = ["PreparedAnalysis", "shared", "held", "release_shared"]
