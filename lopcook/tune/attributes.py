"""Every attribute's bits chosen by image error: Purnomo's greedy +-1-bit search.

This work is based on: Purnomo, Bilodeau, Cohen and Kumar, "Hardware-Compatible Vertex Compression
Using Quantization and Simplification", Graphics Hardware 2005, sections 4.1 (the image-space
metric: renders of the quantized model against the original from the 20 faces of an icosahedron,
error over object pixels) and 4.2 (Fig. 3: the greedy bit-reduce / bit-increase operators, ended
when the error stops decreasing). Meyer et al. 2011 section 5.1 give the positions' knob (the k_f
of ``k_f * E_v * dx(b) <= eps``).

The allocation (``Allocation``). Per part: the bits per field of each attribute codec in record
order (``RANGES``, from ``lopcook.lop.codecs``: normals 4..16, UVs 6..16, colours 4..8, ...), each
None where the part has no such attribute; and one
scale of the positions' k_f for the whole scene, ``x`` = log2 sigma on the grid of
``POSITION_STEP`` (every attribute's k_f times sigma, as ``lopcook.tune.calibrate``: a probe cooks
with ``eps / sigma``; the per-vertex LOP levels stay the analysis's). It is cooked through
``Settings.attributes.parts`` (``lopcook.settings.AttributeSettings``) and the ordinary pipeline
(``lopcook.pipeline.run``), so a probe's container is exactly what ``cook`` writes for it.

The knobs (``knobs``). Each knob moves one quantity by one step: ``positions`` (x by
``POSITION_STEP``), and per part and attribute ``normals[i]``, ``uvs[i]``, ... (one bit per field).
With more than ``MAX_PART_KNOBS`` parts carrying an attribute, one knob moves that attribute on
every part at once (each clipped to its range): the search's cost grows with the knobs, and a
scene of many small parts gains little from per-part bits.

The cost (``vertex_bits``): bits per vertex at level ``COST_LEVEL`` (11) over every LOD-0 vertex of
the scene: the CAP position buffer's bits at that level (``lopcook.lop.summary.memory_rows``,
word padding included) plus each part's record bits ``S = 2 b_n + 2 b_u + 4 b_c`` times its
vertices (``lopcook inspect``'s ``vertex_bits`` total at 11, vertex-weighted).

The error (``Search.quality``). Each probe is rendered **quantized**: CAP positions decoded on the
GPU and the container's own decoded normals, UVs and colours (``lopcook.verify.evaluate`` with
``attributes="container"``), against the float source, on the reduced harness (the calibration's:
``TuneSettings.calibration``, default 8 views at 640 x 360, levels 6..12). The objective is the
worst level's PSNR statistic: ``"mean"`` (the PSNR of the view-averaged MSE over object pixels:
Purnomo average the views' errors) for a bit budget; the tune's ``psnr_stat`` (default ``"min"``
over views, the gate's) for a quality target. An identical render counts as ``INF_DB``.

The searches. ``budget`` (``cook --vertex-bits N``): from the start allocation (the default cook's
bound-based bits and k_f), Purnomo's bit-reduce operator (every knob one step down, rendered; the
least error wins; ties: the lower cost, then the knob order) until the cost is <= N; then rounds of
(a) bit-increase while it fits (the least error among the steps up that keep cost <= N, taken when
it lowers the error), else (b) Purnomo's swap: the bit-reduce winner (among the steps down that
save bits) followed by the best bit-increase of another knob that fits, taken when it lowers the
error; at most ``MAX_ROUNDS``
rounds. The result fits N by construction (its cost is computed from its own container).
``target`` (``cook --target-psnr DB``): from the start (the k_f calibration's choice with the
default attribute bits, the **anchor**): while it misses, the bit-increase winner (least error)
until it reaches the target; then while it passes, the bit-reduce winner (least error among the
steps down that lower the cost) while it still passes, and when it does not, the swap of that
winner with the bit-increase of another knob that passes and still costs less than the current
choice (the cheapest such). Then one **confirmation** on verify's harness (``TuneSettings.confirm``,
20 views at 1280 x 720): when the choice misses there (the reduced harness crops the object at
high levels, so it flatters coarse positions and UVs on magnified textures), ``refine_on_gate``:
``last_passing`` bisects the search's path (the passing choices in the order taken, cost falling)
for the last one that passes the gate (at most 1 + ceil(log2(len(path))) gate renders), freezes
the knobs of the step after it (``moved_knobs``: what the reduced harness misjudged) and searches
on from there with the others, confirmed the same way (at most ``MAX_FREEZES`` freezes; the
record's ``frozen``); when even the path's first misses, ``fallbacks`` walk
back toward the anchor (the choice's bits at the anchor's k_f, then halfway to the anchor's bits,
then the anchor), the first that passes the gate is taken; ``reached`` is False (exit 1 in ``cook``) only when the anchor
misses too, so the search never ends below the default cook's quality.

Direct search (``allocate(..., watch=...)``, ``cook --target-psnr``'s default, after the direct k_f
calibration of ``lopcook.tune.calibrate``, "Watched levels"): the reduced harness *is* the gate's
(20 views at 1280 x 720, levels 6..11), a probe renders the watched levels only (the calibration's,
least margin first) and stops at the first that misses the target, and the confirmation renders
the choice's other levels (the watched ones are memoised). A level the choice misses there is
watched from then on, and ``refine_on_gate`` / ``fallbacks`` go on as above, each gated
allocation rendered at every level. Nothing the search sees can differ from the gate.

Predicted steps (``_best_predicted``, the target search's rounds). Each round of bit-reduce
predicts every step at the current objective plus its knob's last measured effect of one step
(dB; a knob never measured is rendered first), renders the steps in that order, and ends the
round once a rendered step passes and no step left is predicted within ``PREDICT_TOL`` dB of it:
the least-error step of Purnomo's operator as far as the measured effects tell, without rendering
the steps that cannot win (a knob whose step missed by several dB is not rendered again until
every likelier step has missed).

Jumps (``_jump``): after a passing step of a knob whose effect per step is small against the
margin left (positions on textured assets move by tenths of a dB per half step of log2 k_f), the
knob is tried ``n`` steps further at once, n = min(``MAX_JUMP``, (objective - target -
``JUMP_MARGIN_DB``) / max(-effect, ``JUMP_MIN_DB``)); a passing jump is taken (the steps it
passed over join the path, unrendered, so ``refine_on_gate`` can still stop between them) and the
next jump is tried at the effect it measured; a failing one (it stops at its first view below the
target: a few draws) is tried again half as far, and then the greedy steps go on. Measured
effects are not guarantees: every choice is confirmed by the gate as above.

Determinism: probes are made in a fixed order, ties are broken by cost and knob order, and the
renderer is deterministic (llvmpipe), so the same command makes the same probes, chooses the same
allocation and writes the same bytes. Every probe is recorded (``probes``: allocation, bits per
vertex, PSNR per level, step), the error-against-bits curve of Purnomo's Fig. 11.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

from ..errors import EXIT_VERIFY_FAILED, LopcookError
from ..lop.codecs import CODECS
from ..lop.memo import with_code_memo

#: the searched attributes, in record order, with their bit ranges (``lopcook.lop.codecs``)
RANGES = {c.name: c.bits for c in CODECS}
ATTRIBUTES = tuple(c.name for c in CODECS)
#: record bits per unit of each attribute's bits: its number of fields (normals 2, UVs 2, colours 4)
COMPONENTS = {c.name: len(c.field_widths(c.bits[0])) for c in CODECS}
#: containers a search keeps cooked (``Search.cook``)
KEEP_COOKED = 2
#: the positions' knob: log2 of the k_f scale, its grid step and range (as ``lopcook.tune.calibrate``)
POSITION_STEP = 0.5
POSITION_RANGE = (-8.0, 8.0)
#: the edges' knob (target searches with the edge constraint on): whole steps of x_e, its range
EDGE_STEPS = (-8.0, 8.0)
#: the level whose bits per vertex the budget counts
COST_LEVEL = 11
#: at most this many parts get their own knob per attribute (more: one knob for all of them)
MAX_PART_KNOBS = 4
#: at most this many improvement rounds after the budget is met (each 2 x knobs probes at most)
MAX_ROUNDS = 16
#: at most this many probes in one search (a safety bound; the curve says when it was hit)
MAX_PROBES = 96
#: an identical render (PSNR None) in the objective's arithmetic, dB
INF_DB = 200.0
#: a passing step ends a round once no step left is predicted within this many dB of it (``_best_predicted``)
PREDICT_TOL = 0.25
#: jumps (``_jump``): at most this many steps at once, aiming this far above the target, with at
#: least this loss per step assumed (dB)
MAX_JUMP = 16
JUMP_MARGIN_DB = 0.5
JUMP_MIN_DB = 0.25
MODES = ("budget", "target")


@dataclass(frozen=True)
class Allocation:
    """One point of the search: ``x`` = log2 of the positions' k_f scale, ``parts`` = per part
    the bits of each codec in record order (normal, UV, colour, ...), None where the part has no
    such attribute."""

    x: float
    parts: tuple
    #: the edge constraint's strictness x_e (``edge_eps / 2^e`` of the search's settings, at most 1;
    #: whole steps, as ``lopcook.tune.calibrate``), None: not a knob (edges off, or a bit budget)
    e: float | None = None

    def key(self) -> tuple:
        return (float(self.x), tuple(tuple(p) for p in self.parts), self.e)

    def record(self) -> dict:
        """JSON form: {"log2_kf_scale", "parts": [{"normals", "uvs", "colors", ...}]} (a codec newer
        than the first format only where set) and, when edges are a knob, "edge_scale"."""
        out = {"log2_kf_scale": float(self.x),
               "parts": [{c.name: None if b is None else int(b) for c, b in zip(CODECS, p)
                          if c.format_major == 2 or b is not None} for p in self.parts]}
        if self.e is not None:
            out["edge_scale"] = float(self.e)
        return out


@dataclass(frozen=True)
class Knob:
    """One searched quantity: ``attribute`` "positions" or one of ``ATTRIBUTES``; ``parts`` the part
    indices it moves (empty for positions)."""

    attribute: str
    parts: tuple = ()

    @property
    def name(self) -> str:
        if self.attribute in ("positions", "edges"):
            return self.attribute
        return f"{self.attribute}[{','.join(map(str, self.parts)) if len(self.parts) <= MAX_PART_KNOBS else 'all'}]"


def knobs(alloc: Allocation) -> list[Knob]:
    """The knobs of an allocation (module doc): positions first, edges (when ``alloc.e`` is not
    None), then per attribute its parts' knobs (or one for all of them past ``MAX_PART_KNOBS``), in
    part order."""
    out = [Knob("positions")]
    if alloc.e is not None:
        out.append(Knob("edges"))
    for a, attr in enumerate(ATTRIBUTES):
        have = tuple(i for i, p in enumerate(alloc.parts) if p[a] is not None)
        if not have:
            continue
        if len(have) <= MAX_PART_KNOBS:
            out += [Knob(attr, (i,)) for i in have]
        else:
            out.append(Knob(attr, have))
    return out


def step(alloc: Allocation, knob: Knob, delta: int) -> Allocation | None:
    """``alloc`` with ``knob`` moved ``delta`` (+1 / -1) steps, or None when nothing moves (every
    part the knob moves is at the end of its range)."""
    if knob.attribute == "positions":
        x = alloc.x + delta * POSITION_STEP
        lo, hi = POSITION_RANGE
        return None if not lo <= x <= hi else replace(alloc, x=x)
    if knob.attribute == "edges":
        e = float(alloc.e) + delta
        lo, hi = EDGE_STEPS
        return None if not lo <= e <= hi else replace(alloc, e=e)
    a = ATTRIBUTES.index(knob.attribute)
    lo, hi = RANGES[knob.attribute]
    parts = [list(p) for p in alloc.parts]
    moved = False
    for i in knob.parts:
        b = parts[i][a]
        nb = min(hi, max(lo, b + delta))
        if nb != b:
            parts[i][a] = nb
            moved = True
    return replace(alloc, parts=tuple(tuple(p) for p in parts)) if moved else None


def clamp_bits(attribute: str, bits: int) -> int:
    lo, hi = RANGES[attribute]
    return min(hi, max(lo, int(bits)))


def vertex_bits(c, level: int = COST_LEVEL) -> dict:
    """Bits per vertex of container ``c`` at ``level`` over every LOD-0 vertex: {"positions" (CAP
    buffer bits at ``level`` / vertices), "attributes" (sum of n_i * record bits / vertices),
    "total", "vertices", "per_part" [{"vertices", "record_bits"}]}. The record bits are the
    manifest's ``record_bits`` (the packed record, ``lopcook.lop.record``)."""
    from ..lop.summary import memory_rows

    verts = attr = 0
    per_part = []
    for part in c.manifest["parts"]:
        lod = part["lods"][0]
        n = int(lod["vertices"])
        s = int(lod.get("record_bits") or 0)
        verts += n
        attr += n * s
        per_part.append({"vertices": n, "record_bits": s})
    cap = next(r["cap_bytes"] for r in memory_rows(c, levels=[int(level)]) if int(r["level"]) == int(level))
    v = max(verts, 1)
    return {"positions": 8.0 * cap / v, "attributes": attr / v, "total": (8.0 * cap + attr) / v, "vertices": verts,
            "per_part": per_part}


def container_allocation(c, x: float = 0.0) -> Allocation:
    """The allocation a container was cooked with: per part its LOD-0 ``attribute_bits``."""
    parts = []
    for part in c.manifest["parts"]:
        bits = part.get("attribute_bits") or part["lods"][0].get("attribute_bits") or {}
        parts.append(tuple(None if bits.get(a) is None else int(bits[a]) for a in ATTRIBUTES))
    return Allocation(x=float(x), parts=tuple(parts))


def cook_settings(settings, alloc: Allocation):
    """``settings`` with ``alloc`` applied: eps divided by 2^x, edge_eps by 2^e (at most 1) when
    edges are a knob, and ``attributes.parts`` set."""
    from ..settings import AttributeSettings

    base = getattr(settings, "attributes", None) or AttributeSettings()
    analyse = {"eps": settings.analyse.eps / 2.0**float(alloc.x)}
    if alloc.e is not None:
        analyse["edge_eps"] = min(1.0, float(settings.analyse.edge_eps) / 2.0**float(alloc.e))
    return settings.with_(analyse=analyse, attributes=replace(base, parts=tuple(tuple(p) for p in alloc.parts)))


class Search:
    """Probes of one scene: cooks (``lopcook.pipeline.run``) and quantized renders, each made once
    per allocation. ``harness`` = (views, (w, h), levels) of the reduced harness; ``statistic``
    "min" or "mean"; ``progress(dict)`` is called with each probe."""

    def __init__(self, scene, settings, *, harness, statistic: str, progress=None, watch=None, goal=None):
        from ..verify.renderer import shared_harness

        #: the watched levels of a direct search (render order; None: every level of the harness) and
        #: the target a probe's renders stop at (``allocate``, module doc "Direct search")
        self.watch = None if watch is None else [int(b) for b in watch]
        self.goal = None if goal is None else float(goal)
        self.scene = scene
        self.settings = settings
        self.views, self.resolution, self.levels = harness[0], tuple(harness[1]), [int(b) for b in harness[2]]
        self.statistic = statistic
        self.progress = progress
        # the k_f calibration's reduced harness when it ran on this scene (its float renders and
        # decoded draws are reused: ``shared_harness``)
        self.h = shared_harness(scene, self.resolution).harness
        self.costs: dict = {}
        self._margin: dict = {}  # level -> PSNR of the last passing probe (a direct search's render order)
        self._position_bits: dict = {}  # (x, e) -> positions' bits per vertex at COST_LEVEL
        self._vertices = None  # LOD-0 vertices per part
        self._prepared = None
        self.quality_memo: dict = {}
        self.probes: list = []
        self.path: list = []
        self._recent: list = []  # (key, container) of the last ``KEEP_COOKED`` cooks, the latest last

    def close(self) -> None:
        """Drops the containers kept; the harness is shared (``lopcook.verify.renderer.release_shared``)."""
        self.h = None
        self._recent = []

    def cook(self, alloc: Allocation):
        """The container of ``alloc`` (the last ``KEEP_COOKED`` are kept: a round costs its candidates
        before it renders them). On the plain path the analysis comes from one ``PreparedAnalysis``
        of the search (only what eps changes is recomputed: the same minimum levels, so the same
        bytes, as a fresh cook)."""
        from ..pipeline import plain, run

        k = alloc.key()
        for i, (key, kept) in enumerate(self._recent):
            if key == k:
                self._recent.append(self._recent.pop(i))
                return kept
        s = cook_settings(self.settings, alloc)
        analysis = None
        if plain(s):
            if self._prepared is None:  # the k_f calibration's, when it ran on this scene
                from ..analyse.prepared import shared

                self._prepared = shared(self.scene, self.settings.analyse)
            analysis = self._prepared.analyse(s.analyse.eps, s.analyse.edge_eps)
        c = run(self.scene, s, options=s.to_manifest()["options"], analysis=analysis).container
        self._recent = (self._recent + [(k, c)])[-KEEP_COOKED:]
        return c

    def cost(self, alloc: Allocation) -> float:
        """Bits per vertex at ``COST_LEVEL`` (``vertex_bits``), from the cook alone (no render). The
        position bits depend on ``x`` and ``e`` alone and the record bits on the attribute bits alone
        (``S = 2 b_n + 2 b_u + 4 b_c`` per vertex): once an allocation of the same ``x``, ``e`` was cooked,
        another is costed without cooking it (the sum is checked against the cook's own each time
        one is cooked; where it does not hold, every allocation is cooked)."""
        k = alloc.key()
        if k not in self.costs:
            x = (float(alloc.x), alloc.e)
            if x in self._position_bits and self._vertices is not None:
                self.costs[k] = self._position_bits[x] + _record_bits(alloc, self._vertices)
            else:
                vb = vertex_bits(self.cook(alloc))
                self._vertices = [p["vertices"] for p in vb["per_part"]]
                if abs(vb["positions"] + _record_bits(alloc, self._vertices) - vb["total"]) <= 1e-9:
                    self._position_bits[x] = vb["positions"]
                else:  # the formula does not hold here (never seen): every allocation is cooked
                    self._position_bits, self._vertices = {}, None
                self.costs[k] = vb["total"]
        return self.costs[k]

    def quality(self, alloc: Allocation, step_name: str = "") -> float:
        """The objective (module doc): min over levels of the PSNR statistic, dB (``INF_DB`` for
        identical renders). Records the probe."""
        k = alloc.key()
        if k in self.quality_memo and self._settled(self.quality_memo[k]):
            return self.quality_memo[k]["objective"]
        t0 = time.perf_counter()
        c = self.cook(alloc)
        cost = self.cost(alloc)
        levels, stop, stop_view = self.levels, None, None
        if self.watch is not None and self.goal is not None:
            from .calibrate import stop_rule, view_rule

            # the watched levels, least margin first as the last passing probe measured them (a step
            # that misses usually misses where the margin was least: the miss is then found first)
            watch = sorted(self.watch, key=lambda b: (self._margin.get(b, -INF_DB), self.watch.index(b)))
            levels = watch + [b for b in self.levels if b not in self.watch]
            stop = stop_rule(self.goal, self.statistic, len(self.watch))
            stop_view = view_rule(self.goal, self.statistic)
        res = self.h.evaluate(c, levels=levels, views=self.views, variants=("cap",), attributes="container",
                              stop=stop, stop_view=stop_view, cooked_from=self.scene)
        per = [r["cap"][f"psnr_{self.statistic}"] for r in res["levels"]]
        obj = min(INF_DB if v is None else float(v) for v in per)
        p = {"allocation": alloc.record(), "bits_per_vertex": round(cost, 4), "objective_db": round(obj, 4),
             "levels": [int(r["level"]) for r in res["levels"]],
             "psnr_per_level": [None if v is None else round(float(v), 4) for v in per],
             "psnr_min": _min_db(r["cap"]["psnr_min"] for r in res["levels"]),
             "psnr_mean": _min_db(r["cap"]["psnr_mean"] for r in res["levels"]),
             "step": step_name, "seconds": round(time.perf_counter() - t0, 3)}
        self.quality_memo[k] = dict(p, objective=obj)
        if self.goal is not None and obj >= self.goal:
            self._margin = {int(r["level"]): (INF_DB if v is None else float(v)) for r, v in zip(res["levels"], per)}
        self.probes.append(p)
        if self.progress is not None:
            self.progress(p)
        return obj

    def _settled(self, memo: dict) -> bool:
        """Whether a memoised probe's verdict holds for the watched levels (it missed the goal on a
        level it rendered, or it rendered every watched level)."""
        if self.watch is None or self.goal is None:
            return True
        return memo["objective"] < self.goal or set(self.watch) <= set(memo["levels"])

    def full(self) -> bool:
        return len(self.probes) >= MAX_PROBES


def _record_bits(alloc: Allocation, vertices: list) -> float:
    """The attribute records' bits per vertex of ``alloc`` (vertex-weighted over the parts, as
    ``vertex_bits``): 2 b_n + 2 b_u + 4 b_c per part, 0 for an attribute it does not store."""
    total = sum(int(n) * sum(COMPONENTS[a] * int(b or 0) for a, b in zip(ATTRIBUTES, bits))
                for n, bits in zip(vertices, alloc.parts))
    return total / max(sum(int(n) for n in vertices), 1)


def _min_db(values):
    vals = [v for v in values if v is not None]
    return None if not vals else round(min(float(v) for v in vals), 4)


def _best(search: Search, cands: list[tuple[Knob, Allocation]], name: str,
          measured: list | None = None) -> tuple | None:
    """(objective, alloc, knob) of the least-error candidate (ties: lower cost, then order),
    rendering each; None without candidates. ``measured`` (a list) receives (knob, objective) of
    each candidate rendered."""
    best = None
    for idx, (k, a) in enumerate(cands):
        if search.full():
            break
        q = search.quality(a, f"{name} {k.name}")
        if measured is not None:
            measured.append((k, q))
        key = (-q, search.cost(a), idx)
        if best is None or key < best[0]:
            best = (key, q, a, k)
    return None if best is None else (best[1], best[2], best[3])


def _best_predicted(search, cands: list[tuple[Knob, Allocation]], name: str, q_cur: float, effect: dict,
                    target: float, measured: list) -> tuple | None:
    """``_best`` of the steps down ``cands`` from an allocation of objective ``q_cur``, rendering
    fewer (module doc, "Predicted steps"): each step is predicted at ``q_cur`` plus its knob's last
    measured effect (``effect``; a knob never measured is rendered first), and rendered in order of
    prediction; once a rendered step passes ``target`` and no step left is predicted within
    ``PREDICT_TOL`` dB of it, the rest are not rendered. ``measured`` receives (knob, objective) of
    each step rendered."""
    order = sorted(range(len(cands)), key=lambda i: (-(q_cur + effect[cands[i][0].name])
                                                    if cands[i][0].name in effect else -INF_DB, i))
    best = None
    for n, i in enumerate(order):
        k, a = cands[i]
        if best is not None and best[1] >= target:
            left = [q_cur + effect.get(cands[j][0].name, INF_DB) for j in order[n:]]
            if max(left) < best[1] - PREDICT_TOL:
                break
        if search.full():
            break
        q = search.quality(a, f"{name} {k.name}")
        measured.append((k, q))
        key = (-q, search.cost(a), i)
        if best is None or key < best[0]:
            best = (key, q, a, k)
    return None if best is None else (best[1], best[2], best[3])


def _jump(search, cur: Allocation, knob: Knob, q: float, effect: dict, target: float, frozen) -> Allocation:
    """After a passing step down of ``knob`` to ``cur`` (objective ``q``): when its effect per
    step is small against the margin left, try that knob ``n`` steps further at once (module doc,
    "Jumps"), n = min(``MAX_JUMP``, (q - target - ``JUMP_MARGIN_DB``) / max(-effect,
    ``JUMP_MIN_DB``)); a passing jump is taken (added to the path), a failing one is tried again
    half as far (while that is 2 steps or more), and then the greedy steps go on from where they
    are; after a passing jump the next is tried at once, with the effect per step that jump
    measured."""
    if knob.name in frozen:
        return cur
    per = max(-float(effect.get(knob.name, 0.0)), JUMP_MIN_DB)
    n = int(min(MAX_JUMP, math.floor((q - target - JUMP_MARGIN_DB) / per)))
    while n >= 2 and not search.full():
        a, between = cur, []
        for _ in range(n):
            nxt = step(a, knob, -1)
            if nxt is None:
                break
            a = nxt
            between.append(a)
        if a == cur or search.cost(a) >= search.cost(cur):
            return cur
        qa = search.quality(a, f"jump {knob.name}")
        if qa >= target:
            effect[knob.name] = (qa - q) / len(between)
            # the steps jumped over join the path unrendered (they pass if the end does, as the
            # verdict falls along a knob): ``refine_on_gate`` can still stop at any of them
            search.path.extend(between)
            return _jump(search, a, knob, qa, effect, target, frozen)  # on, at the effect now measured
        n = min(n, len(between)) // 2  # a miss (usually a few views of one level): half as far
    return cur


def _moves(alloc: Allocation, delta: int, exclude: Knob | None = None,
           frozen: frozenset = frozenset()) -> list[tuple[Knob, Allocation]]:
    out = []
    for k in knobs(alloc):
        if (exclude is not None and k == exclude) or k.name in frozen:
            continue
        a = step(alloc, k, delta)
        if a is not None:
            out.append((k, a))
    return out


def search_budget(search: Search, start: Allocation, budget: float) -> Allocation:
    """``cook --vertex-bits N`` (module doc): the allocation of least error with cost <= ``budget``
    bits per vertex found by the greedy operators. Raises LopcookError (usage) when even every knob
    at its minimum costs more than the budget."""
    cur = start
    search.quality(cur, "start")
    while search.cost(cur) > budget:
        cands = [(k, a) for k, a in _moves(cur, -1) if search.cost(a) < search.cost(cur)]
        if not cands:
            raise LopcookError("usage", search.scene.source,
                               f"--vertex-bits {budget:g}: the least this scene can take is "
                               f"{search.cost(cur):.2f} bits per vertex at level {COST_LEVEL} (every attribute "
                               f"at its fewest bits, the positions' k_f at 2^{cur.x:g})",
                               hint="give a larger --vertex-bits")
        got = _best(search, cands, "reduce")
        if got is None:  # probe bound: take the cheapest step down
            cur = min(cands, key=lambda t: search.cost(t[1]))[1]
            continue
        cur = got[1]
    for _ in range(MAX_ROUNDS):
        if search.full():
            break
        q_cur = search.quality(cur)
        up = [(k, a) for k, a in _moves(cur, +1) if search.cost(a) <= budget]
        got = _best(search, up, "increase") if up else None
        if got is not None and got[0] > q_cur:
            cur = got[1]
            continue
        red = _best(search, [(k, a) for k, a in _moves(cur, -1) if search.cost(a) < search.cost(cur)], "reduce")
        if red is None:
            break
        swaps = [(k, a) for k, a in _moves(red[1], +1, exclude=red[2]) if search.cost(a) <= budget]
        got = _best(search, swaps, f"swap after {red[2].name}") if swaps else None
        if got is not None and got[0] > q_cur:
            cur = got[1]
            continue
        break
    return cur


def search_target(search: Search, start: Allocation, target: float,
                  frozen: frozenset = frozenset()) -> tuple[Allocation, bool]:
    """``cook --target-psnr DB`` on the reduced harness (module doc): (choice, whether it passed).
    Knobs named in ``frozen`` (``Knob.name``) are not moved."""
    cur = start
    q = search.quality(cur, "start")
    while q < target and not search.full():
        got = _best(search, _moves(cur, +1, frozen=frozen), "increase")
        if got is None:
            return cur, False
        q, cur = got[0], got[1]
    if q < target:
        return cur, False
    search.path = [cur]  # the passing choices in the order taken
    effect: dict = {}  # knob name -> objective change of its last step down measured (dB per step)
    while not search.full():
        down = [(k, a) for k, a in _moves(cur, -1, frozen=frozen) if search.cost(a) < search.cost(cur)]
        q_cur = search.quality(cur)
        measured: list = []
        got = _best_predicted(search, down, "reduce", q_cur, effect, target, measured) if down else None
        for k, q in measured:  # the knobs' measured effect of one step down, for the next rounds
            effect[k.name] = q - q_cur
        if got is None:
            break
        if got[0] >= target:
            cur = got[1]
            search.path.append(cur)
            cur = _jump(search, cur, got[2], got[0], effect, target, frozen)
            continue
        swaps = [(k, a) for k, a in _moves(got[1], +1, exclude=got[2], frozen=frozen)
                 if search.cost(a) < search.cost(cur)]
        passing = []
        for k, a in swaps:
            if search.full():
                break
            if search.quality(a, f"swap after {got[2].name} {k.name}") >= target:
                passing.append((search.cost(a), len(passing), a))
        if not passing:
            break
        cur = min(passing)[2]
        search.path.append(cur)
    return cur, True


def last_passing(path: list, passes) -> int | None:
    """Index of the last allocation of ``path`` that ``passes(alloc, index)`` (the gate), by
    bisection, assuming the gate's verdict falls monotonically along the path (a target search's
    path: passing choices of falling cost, ``Search.path``); None when ``path`` is empty or its
    first entry fails. Calls ``passes`` at most ``1 + ceil(log2(len(path)))`` times, on the first
    entry, then on midpoints."""
    if not path or not passes(path[0], 0):
        return None
    lo, hi = 0, len(path)  # path[lo] passes; path[hi:] fail or are untested past the end
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if passes(path[mid], mid):
            lo = mid
        else:
            hi = mid
    return lo


#: at most this many knobs frozen by ``refine_on_gate`` (each freeze: one more reduced-harness search)
MAX_FREEZES = 3


def moved_knobs(a: Allocation, b: Allocation) -> list[str]:
    """Names (``Knob.name``) of the knobs of ``a`` whose quantities differ in ``b``, in knob order."""
    out = []
    for k in knobs(a):
        if k.attribute in ("positions", "edges"):
            if (a.x if k.attribute == "positions" else a.e) != (b.x if k.attribute == "positions" else b.e):
                out.append(k.name)
            continue
        i = ATTRIBUTES.index(k.attribute)
        if any(a.parts[p][i] != b.parts[p][i] for p in k.parts):
            out.append(k.name)
    return out


def refine_on_gate(search: Search, choice: Allocation, target: float, passes) -> tuple | None:
    """After a target search's ``choice`` missed the gate: (allocation that passes the gate, the
    frozen knob names), or None when even the first choice of the search's path misses.

    ``last_passing`` finds the last choice of ``search.path`` that ``passes(alloc, role)`` (the
    gate); the step after it (the knobs it moved, ``moved_knobs``) is what the reduced harness
    misjudged, so those knobs are frozen and the search continues from that choice
    (``search_target`` with ``frozen``); its new choice is confirmed the same way, at most
    ``MAX_FREEZES`` times. The result is the last allocation that passed the gate (cost falls
    along every path, so it is the cheapest gated one)."""
    frozen: list = []
    best = None
    path = [a for a in search.path if a != choice]
    for _ in range(MAX_FREEZES + 1):
        k = last_passing(path, lambda a, i: passes(a, f"path {i}"))
        if k is None:
            break
        best = path[k]
        nxt = search.path[search.path.index(best) + 1] if best in search.path[:-1] else choice
        new = [n for n in moved_knobs(best, nxt) if n not in frozen]
        if not new or len(frozen) >= MAX_FREEZES or search.full():
            break
        frozen += new
        cur, ok = search_target(search, best, target, frozenset(frozen))
        if not ok or cur == best:
            break
        if passes(cur, f"choice, frozen {','.join(frozen)}"):
            best = cur
            break
        choice = cur
        path = [a for a in search.path if a != cur]
    return None if best is None else (best, frozen)


def _gate_record(search, a, gate, goal, conf, role, gated) -> bool:
    """Whether ``a`` passes the gate (``gate(container)``'s objective >= ``goal``, dB): renders it
    once (memo ``gated``) and records it in ``conf`` with ``role``."""
    k = a.key()
    if k not in gated:
        ga = gate(search.cook(a))
        conf.append(dict(ga, allocation=a.record(), role=role))
        gated[k] = ga["objective_db"]
    return gated[k] >= goal


def fallbacks(choice: Allocation, start: Allocation) -> list[tuple[str, Allocation]]:
    """The allocations a target search confirms on the gate, in order, after its choice missed
    there: (1) "anchor positions": the choice's attribute bits with the anchor's k_f scale and edges (the
    k_f calibration already chose it on the gate; the reduced harness flatters position error
    most), (2) "halfway": that with every attribute's bits halfway back to the anchor's (rounded
    up), (3) "anchor". Duplicates and the choice itself are left out."""
    pos = replace(choice, x=start.x, e=start.e)
    half = replace(pos, parts=tuple(tuple(None if c is None else (c + s + 1) // 2 for c, s in zip(pc, ps))
                                     for pc, ps in zip(choice.parts, start.parts)))
    out, seen = [], {choice.key()}
    for role, a in (("anchor positions", pos), ("halfway", half), ("anchor", start)):
        if a.key() not in seen:
            seen.add(a.key())
            out.append((role, a))
    return out


def gate_quality(scene, c, confirm, levels, statistic: str, stop_below: float | None = None,
                 cooked_here: bool = False) -> dict:
    """Render ``c`` quantized on the gate's harness ``confirm`` = (views, (w, h)): {"psnr_min",
    "psnr_mean", "objective_db" (the ``statistic``, min over levels), "psnr_per_level", "levels"
    (those rendered)}. ``stop_below`` (dB): the renders end after the first level that misses it
    (the levels in the order given). ``cooked_here``: ``c`` was cooked from ``scene`` by the caller
    (the harness then skips checking that it was: ``Harness.evaluate``'s ``cooked_from``)."""
    from ..verify.renderer import shared_harness

    stop = stop_view = None
    if stop_below is not None:
        from .calibrate import stop_rule, view_rule

        stop, stop_view = stop_rule(float(stop_below), statistic), view_rule(float(stop_below), statistic)
    # the k_f calibration's gate harness: its float renders, and its draws of the same buffers, are reused
    with shared_harness(scene, tuple(confirm[1])) as h:
        res = h.evaluate(c, levels=levels, views=confirm[0], variants=("cap",), attributes="container", stop=stop,
                         stop_view=stop_view, cooked_from=scene if cooked_here else None)
    per = [r["cap"][f"psnr_{statistic}"] for r in res["levels"]]
    return {"views": confirm[0], "resolution": list(confirm[1]), "levels": [int(r["level"]) for r in res["levels"]],
            "psnr_min": _min_db(r["cap"]["psnr_min"] for r in res["levels"]),
            "psnr_mean": _min_db(r["cap"]["psnr_mean"] for r in res["levels"]),
            "psnr_per_level": [None if v is None else round(float(v), 4) for v in per],
            "objective_db": round(min(INF_DB if v is None else float(v) for v in per), 4)}


def attribute_errors(c, scene) -> list[dict]:
    """Attribute-space errors of a container's LOD 0 against the source, per part: normals' angle
    (degrees, max and mean over vertices, decoded normal normalised) and UVs' error in texels
    (max over vertices of the per-component error times the texture's size; in UV units when the
    part has no texture). Vertices matched by order (``lopcook.verify.buffers.source_order``)."""
    import numpy as np

    from ..lop.reader import lod_attributes
    from ..verify.buffers import source_order

    orders = source_order(c, scene)
    out = []
    for i, p in enumerate(scene.parts):
        a = lod_attributes(c, i, 0)
        row: dict = {"part": i, "name": p.name}
        o = orders[i]
        if p.normals is not None and a.get("normals") is not None:
            d = np.asarray(a["normals"], np.float64)
            d = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
            s = np.asarray(p.normals, np.float64)[o]
            s = s / np.maximum(np.linalg.norm(s, axis=1, keepdims=True), 1e-300)
            ang = np.degrees(np.arccos(np.clip(np.sum(d * s, axis=1), -1.0, 1.0)))
            row.update(normal_deg_max=float(ang.max()) if ang.size else 0.0,
                       normal_deg_mean=float(ang.mean()) if ang.size else 0.0)
        if p.uvs is not None and a.get("uvs") is not None:
            err = np.abs(np.asarray(a["uvs"], np.float64) - np.asarray(p.uvs, np.float64)[o])
            size = None
            if p.texture is not None:
                try:
                    w, h = p.texture.image().size
                    size = (w, h)
                except Exception:  # noqa: BLE001 -- an undecodable texture: UV units
                    size = None
            scale = np.array(size if size else (1.0, 1.0), np.float64)
            texels = err * scale
            row.update(uv_error_max=float(texels.max()) if texels.size else 0.0,
                       uv_error_mean=float(texels.mean()) if texels.size else 0.0,
                       uv_error_unit="texels" if size else "uv", texture_size=list(size) if size else None)
        out.append(row)
    return out


@with_code_memo
def allocate(scene, settings, *, mode: str, goal: float, harness, confirm=None, statistic: str = "mean",
             progress=None, watch=None) -> dict:
    """Run one search (module doc). ``mode`` "budget" (``goal`` bits per vertex) or "target"
    (``goal`` dB); ``settings`` the cook's (for "target" the k_f calibration's choice already
    applied); ``harness`` (views, (w, h), levels) the reduced harness; ``confirm`` (views, (w, h))
    the gate's or None. ``watch`` (target mode): the watched levels of a direct search (module doc,
    "Direct search"; ``harness`` is then the gate's, and so is ``confirm``), None: every probe renders
    every level.

    Returns the search record: {"mode", "goal", "statistic", "harness", "start" and "choice"
    (allocation records), "bits_per_vertex" (choice's, at ``COST_LEVEL``), "vertex_bits" (its
    positions / attributes split), "start_bits_per_vertex", "objective_db", "reached",
    "confirmation" (gate renders of the choice, and of the anchor when the choice missed), "probes",
    "seconds", "attribute_errors"} and "_settings" (the Settings to cook, popped by the caller)."""
    if mode not in MODES:
        raise ValueError(f"mode {mode!r}")
    t0 = time.perf_counter()
    from ..pipeline import plain, run

    analysis = None
    if plain(settings):  # the prepared analysis the search's probes use (the same buffers)
        from ..analyse.prepared import shared

        analysis = shared(scene, settings.analyse).analyse(settings.analyse.eps, settings.analyse.edge_eps)
    base = run(scene, settings, options=settings.to_manifest()["options"], analysis=analysis).container
    del analysis
    start = container_allocation(base, 0.0)
    if mode == "target" and settings.analyse.edges:  # the edge constraint's strictness is a knob too
        start = replace(start, e=0.0)
    direct = watch is not None and mode == "target"
    search = Search(scene, settings, harness=harness, statistic=statistic, progress=progress,
                    watch=watch if direct else None, goal=goal if direct else None)
    conf = []
    frozen: list = []
    all_levels = [int(b) for b in harness[2]]

    def gate(c) -> dict:
        """The gate's verdict on container ``c``: every level; a direct search renders the watched
        levels first, stops at the first miss and watches the level it missed from then on."""
        if not direct:
            return gate_quality(scene, c, confirm, all_levels, statistic, cooked_here=True)
        order = search.watch + [b for b in all_levels if b not in search.watch]
        g = gate_quality(scene, c, confirm, order, statistic, stop_below=float(goal), cooked_here=True)
        if g["objective_db"] < float(goal) and g["levels"] and g["levels"][-1] not in search.watch:
            search.watch.append(g["levels"][-1])
        return g

    try:
        if mode == "budget":
            choice = search_budget(search, start, float(goal))
            reached = search.cost(choice) <= float(goal)
        else:
            choice, reached = search_target(search, start, float(goal))
            if not reached:
                choice = start
        objective = search.quality(choice)
        c = search.cook(choice)
        if confirm is not None:
            g = gate(c)
            conf.append(dict(g, allocation=choice.record(), role="choice"))
            gated = {choice.key(): g["objective_db"]}
            if mode == "target":
                reached = g["objective_db"] >= float(goal)
                if not reached:
                    got = refine_on_gate(search, choice, float(goal),
                                         lambda a, role: _gate_record(search, a, gate, float(goal), conf, role,
                                                                      gated))
                    if got is not None:
                        choice, frozen = got
                        c, objective, reached = search.cook(choice), search.quality(choice, "confirm path"), True
                # walk back toward the anchor (``fallbacks``)
                for role, a in fallbacks(choice, start):
                    if reached:
                        break
                    ca = search.cook(a)
                    ga = gate(ca)
                    conf.append(dict(ga, allocation=a.record(), role=role))
                    if ga["objective_db"] >= float(goal) or role == "anchor":
                        choice, c, objective = a, ca, search.quality(a, f"confirm {role}")
                        reached = ga["objective_db"] >= float(goal)
    finally:
        search.close()
    vb = vertex_bits(c)
    return {"mode": mode, "goal": float(goal), "statistic": statistic,
            "harness": {"views": harness[0], "resolution": list(harness[1]), "levels": list(harness[2])},
            "start": start.record(), "start_bits_per_vertex": round(vertex_bits(base)["total"], 4),
            "choice": choice.record(), "bits_per_vertex": round(vb["total"], 4),
            "vertex_bits": {k: round(vb[k], 4) for k in ("positions", "attributes", "total")},
            "objective_db": round(objective, 4), "reached": bool(reached), "confirmation": conf, "frozen": frozen,
            "watch": None if search.watch is None else list(search.watch),
            "probes": search.probes, "seconds": round(time.perf_counter() - t0, 3),
            "attribute_errors": attribute_errors(c, scene), "_settings": cook_settings(settings, choice)}


def search_record(result: dict) -> dict:
    """The manifest's ``options.attribute_search``: the search record without probes' timings and
    without anything machine-dependent (so the same command writes the same bytes)."""
    keep = ("mode", "goal", "statistic", "harness", "start", "start_bits_per_vertex", "choice", "bits_per_vertex",
            "vertex_bits", "objective_db", "reached", "confirmation", "attribute_errors")
    rec = {k: result[k] for k in keep}
    if result.get("frozen"):
        rec["frozen"] = list(result["frozen"])
    rec["probes"] = [{k: v for k, v in p.items() if k != "seconds"} for p in result["probes"]]
    return rec


def require_reached(result: dict, path: str | None = None) -> None:
    """LopcookError (exit 1) when a target search missed even at the anchor."""
    if result["mode"] == "target" and not result["reached"]:
        conf = result["confirmation"]
        got = conf[-1]["objective_db"] if conf else result["objective_db"]
        raise LopcookError("verify", path, f"--target-psnr {result['goal']:g}: even the default attribute bits "
                           f"reach only {got:.2f} dB with quantized attributes", exit_code=EXIT_VERIFY_FAILED,
                           hint="lower --target-psnr, or cook without it")


def _alloc_text(rec: dict) -> str:
    """``k_f 2^x, n/uv/c 8/12/- 7/-/-``: the bits per part, runs of equal parts as ``8/6/- x49``."""
    parts = ["/".join("-" if p.get(a) is None else str(p[a]) for a in ATTRIBUTES) for p in rec["parts"]]
    runs: list = []
    for t in parts:
        if runs and runs[-1][0] == t:
            runs[-1][1] += 1
        else:
            runs.append([t, 1])
    edges = "" if rec.get("edge_scale") is None else f", edges {rec['edge_scale']:+g}"
    return f"k_f 2^{rec['log2_kf_scale']:g}{edges}, n/uv/c " + " ".join(t if n == 1 else f"{t} x{n}" for t, n in runs)


def format_probe(p: dict) -> str:
    """One progress line per probe."""
    return (f"attribute search {p['step'] or 'probe'}: {_alloc_text(p['allocation'])}: {p['bits_per_vertex']:.2f} "
            f"bits/vertex, {p['objective_db']:.2f} dB ({p['seconds']:.1f} s)")


def format_search(result: dict) -> str:
    """Human-readable lines: the allocation per part, bits per vertex, PSNR, probes."""
    lines = [f"attribute search ({result['mode']} {result['goal']:g}"
             f"{' bits/vertex' if result['mode'] == 'budget' else ' dB'}): {len(result['probes'])} probes, "
             f"{result['seconds']:.1f} s"]
    ch = result["choice"]
    lines.append(f"  positions k_f scale 2^{ch['log2_kf_scale']:g}; bits per vertex at level {COST_LEVEL}: "
                 f"{result['bits_per_vertex']:.2f} (positions {result['vertex_bits']['positions']:.2f}, attributes "
                 f"{result['vertex_bits']['attributes']:.2f}; the default cook: {result['start_bits_per_vertex']:.2f})")
    for i, p in enumerate(ch["parts"]):
        bits = ", ".join(f"{a} {p[a]}" for a in ATTRIBUTES if p.get(a) is not None) or "no attributes"
        lines.append(f"  part {i}: {bits} bits per component")
    lines.append(f"  reduced harness PSNR ({result['statistic']}, worst level): {result['objective_db']:.2f} dB")
    for c in result["confirmation"]:
        lines.append(f"  gate ({c['views']} views at {c['resolution'][0]}x{c['resolution'][1]}, {c['role']}): "
                     f"min {c['psnr_min']} dB, mean {c['psnr_mean']} dB")
    return "\n".join(lines)


__all__ = ["RANGES", "ATTRIBUTES", "POSITION_STEP", "COST_LEVEL", "MAX_PART_KNOBS", "MAX_ROUNDS",
           "Allocation", "Knob", "knobs", "step", "vertex_bits", "container_allocation", "cook_settings", "Search",
           "search_budget", "search_target", "last_passing", "moved_knobs", "refine_on_gate", "MAX_FREEZES",
           "fallbacks", "gate_quality", "attribute_errors", "allocate", "search_record",
           "require_reached", "format_search", "format_probe"]
