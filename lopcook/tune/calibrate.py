"""k_f calibration: the least position memory whose CAP renders reach a target PSNR.

This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
sections 5.1 (the minimum level of a vertex: the smallest b with k_f * E_v * dx(b) <= eps) and 7
(k_f chosen empirically for CAP). Here k_f is measured: every probe cooks the scene and renders its
CAP buffers against the float source with the harness of ``lopcook.verify.evaluate`` (Purnomo et
al. 2005, section 4.1: views on an icosahedron, error over object pixels). The method in full,
with its reasons: docs/tune.md, "The calibration in full".

The knobs: ``sigma`` scales every attribute's k_f at once (a probe cooks with ``eps / sigma``; the
ratios between attributes are kept), searched on the grid ``lo + k * tolerance`` of log2 sigma
(``LOG2_RANGE``, ``TOLERANCE``); with ``search="kf+edge"`` also the edge strictness x_e
(``edge_eps = settings.edge_eps / 2^x_e``, at most 1, whole steps, at most ``EDGE_RANGE``).

A probe (``probe``) passes when at every level its CAP PSNR statistic reaches the target: ``"min"``
over views (an identical render counts as infinite) or ``"mean"`` (the PSNR of the view-averaged
MSE). Its memory (``cap_percent``, % of float32 positions) needs no render (``cap_memory``).

The search (``calibrate``): (1) k_f by ``model_search`` (PSNR per level linear in log2 sigma:
``SLOPE_DB`` per doubling from one probe, the secant of two, a bisection when predictions stall);
with ``"kf+edge"`` (2a) the edges loosened at that k_f, (2b) made stricter when no k_f passes, (2c)
loosened and paid for with more k_f; of the passing pairs the least mean CAP memory is chosen.
``watch_db`` (the direct search): the probes render on the gate's own harness, the anchor (the
default cook, sigma 1) names the watched levels and every other probe renders those first,
stopping at its first miss; ``complete`` renders the choice at every level. ``confirm`` (a reduced
harness): the choice is confirmed on the gate's harness (``CONFIRM``, levels ``CONFIRM_LEVELS``),
moving toward the default cook while it misses (at most ``CONFIRM_STEPS`` gate probes).

Guarantees: the choice passed when probed (on the gate's harness when confirmed or direct); a
search never ends below the default cook's quality: ``reached`` is False (exit 1 in ``cook``) when
no knob in the range passes or when even the default cook's knobs miss the gate. A joint optimum of
the two knobs is not guaranteed (the curve lists every probe). The harnesses are shared
(``shared_harness``): the attribute search that follows reuses their renders. Deterministic: the
same command makes the same probes and the same choice.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

from ..analyse import analyse, attribute_kf
from ..analyse.prepared import shared as shared_prepared
from ..emit import build
from ..errors import EXIT_VERIFY_FAILED, LopcookError
from ..lop.container import from_bytes
from ..lop.memo import with_code_memo
from ..settings import DEFAULT_ANALYSE, DEFAULTS, AnalyseSettings
from ..verify import metrics as M
from ..verify.buffers import DEFAULT_LEVELS, position_bytes
from ..verify.cameras import VIEW_COUNT, select_views
from ..verify.evaluate import harness_evaluate
from ..verify.renderer import RESOLUTION, Harness, shared_harness
from ..viewing import Viewing

CAL_VIEWS = DEFAULTS.tune.calibration.views
CAL_RESOLUTION = DEFAULTS.tune.calibration.resolution
#: the gate's harness (``lopcook verify --source`` defaults): the calibration's choice is confirmed there
CONFIRM = (VIEW_COUNT, RESOLUTION)
#: at most this many probes on the gate's harness (the choice, then moves toward the default cook)
CONFIRM_STEPS = 4
#: the levels confirmed on the gate's harness: those of ``lopcook verify --levels 6-11`` (the paper's
#: Table 1 levels); the reduced harness searches every calibration level
CONFIRM_LEVELS = tuple(range(6, 12))
LOG2_RANGE = (-8.0, 8.0)
TOLERANCE = 0.25
#: a direct search watches the levels where the anchor's PSNR is within this many dB of its least
WATCH_DB = 4.0
STATISTICS = ("min", "mean")
SEARCHES = ("kf", "kf+edge")
EDGE_RANGE = 8  # whole steps of edge strictness x_e above the given edge_eps (edge_eps / 2^8 at most)
#: the model's slope of PSNR per doubling of sigma with one probe (MSE / 4: 10 log10 4 dB) and its clip
SLOPE_DB = 10.0 * math.log10(4.0)
SLOPE_MIN, SLOPE_MAX = 0.2, 12.0
#: predictions of the model per k_f search before it bisects what is left of the bracket
MODEL_STEPS = 4
#: at most this many probes for k_f at the loosest edges (step 2c), an optional saving
EDGE_KF_PROBES = 4
#: the model aims this far above the target (dB): the predicted grid point should pass
MODEL_MARGIN_DB = 0.1
#: the confirmation's move toward the default aims this far above the target on the gate (dB)
CONFIRM_MARGIN_DB = 0.25
#: an identical render (PSNR None, infinite) in the model's arithmetic, dB
INF_DB = 200.0


def _kf_dict(scene, settings: AnalyseSettings, sigma: float) -> dict:
    """sigma times the k_f the analysis uses per attribute present in the scene (max over parts)."""
    out: dict = {}
    for part in scene.parts:
        for name, kf in attribute_kf(part, settings).items():
            out[name] = max(out.get(name, 0.0), float(kf) * sigma)
    return out


def _log2(sigma: float) -> float:
    """log2 sigma, exact for the searched grid (multiples of 2^-10, where 2^x round-trips)."""
    lg = math.log2(float(sigma))
    r = round(lg * 1024.0) / 1024.0
    return r if 2.0**r == float(sigma) else lg


def _edge_eps(settings: AnalyseSettings, edge_scale: float) -> float:
    """edge_eps at strictness ``edge_scale`` (x_e): settings.edge_eps / 2^x_e, at most 1."""
    return min(1.0, float(settings.edge_eps) / 2.0**float(edge_scale))


def _statistic(per_view, statistic: str):
    """A level's PSNR statistic over its views' metrics (None: identical renders)."""
    if statistic == "mean":
        return M.mean_mse_psnr([m["mse"] for m in per_view])
    return min((m["psnr"] for m in per_view if m["psnr"] is not None), default=None)


def scout_rule(statistic: str, watch_db: float):
    """The ``stop(per_view)`` of the anchor's renders (levels ascending): true once the last two
    levels rendered are each at least ``watch_db`` dB above the least so far (the PSNR climbs with the
    level there, as the object grows on screen; a higher level that binds anyway is found when the
    choice is completed)."""
    seen: list = []

    def stop(per_view) -> bool:
        v = _statistic(per_view, statistic)
        seen.append(INF_DB if v is None else float(v))
        least = min(seen)
        return len(seen) >= 3 and all(x >= least + float(watch_db) for x in seen[-2:])

    return stop


def stop_rule(target: float, statistic: str, watch: int | None = None):
    """The ``stop(per_view)`` of ``harness_evaluate`` for a probe that must reach ``target`` dB
    (``statistic`` "min" or "mean" over views) at every level it renders: true after the first level
    that misses it, or once ``watch`` levels (when given) have been rendered."""
    done = [0]

    def stop(per_view) -> bool:
        v = _statistic(per_view, statistic)
        done[0] += 1
        return (v is not None and v < target) or (watch is not None and done[0] >= int(watch))

    return stop


def view_rule(target: float, statistic: str):
    """The ``stop_view(metrics)`` of ``harness_evaluate`` for a probe that must reach ``target`` dB on
    the minimum over views: true at the first view below it (the level, and the probe, miss
    whatever the other views give; the level's recorded minimum is then that view's, an upper
    bound of the minimum over every view). None for the "mean" statistic, which needs every view."""
    if statistic != "min":
        return None
    return lambda m: m["psnr"] is not None and m["psnr"] < float(target)


def probe(scene, settings: AnalyseSettings, sigma: float, harness: Harness, *, levels, views,
          viewing: Viewing, options: dict | None = None, ingest_options: dict | None = None,
          edge_scale: float = 0.0, stop_below: tuple[float, str] | None = None, prepared=None,
          watch: int | None = None, stop=None, clusters: tuple | None = None) -> dict:
    """Cook ``scene`` with every k_f scaled by ``sigma`` (and edge_eps divided by 2^``edge_scale``)
    and render its CAP buffers.

    Returns ``{"sigma", "log2_sigma", "eps", "edge_scale", "edge_eps", "edges", "kf", "kf_normal",
    "psnr_min" (min over levels of the min over views, dB; None = identical), "psnr_mean" (min over
    levels of the PSNR of the view-averaged MSE), "psnr_min_per_level", "psnr_mean_per_level" [per level
    rendered], "cap_percent", "cap_bytes" [per level of ``levels``, rendered or not: memory needs no
    render], "depth_order_errors" (summed), "seconds", "complete", "levels" (the levels rendered, in
    the order of ``levels``: the PSNR lists follow it)}``.

    ``stop_below`` = (target dB, statistic): the renders end after the first level whose statistic
    misses the target (the probe fails whatever the other levels give; with "min", at the first view
    below it, ``view_rule``); the per-level lists then hold the levels rendered and ``complete`` is
    False. ``watch`` = k (with ``stop_below``): the renders also end once the first k levels of
    ``levels`` have passed (the watched levels of a direct search, ``calibrate``; the probe passes
    provisionally). ``stop``: another rule of that
    kind (``scout_rule``). ``clusters`` = (cluster size or None, cluster_all): the position layout
    of the cook (``lopcook.settings.EmitSettings``; default unclustered), so that memory is counted
    as the cook will store it and a probe draws what the cook of the same knobs draws. A probe that
    draws exactly what an earlier one drew on the same harness (e.g. edge_eps 1 and 0.5 when no
    vertex's bound tells them apart: the same buffers and attribute bits) takes the earlier renders'
    numbers (``Harness.view_memo``, keyed by the content of every draw). ``prepared``: a
    ``lopcook.analyse.prepared.PreparedAnalysis`` of ``scene`` and ``settings`` (the same minimum
    levels as ``analyse``, without recomputing what does not depend on eps and edge_eps); None
    analyses from scratch.
    """
    t0 = time.perf_counter()
    s = replace(settings, eps=settings.eps / float(sigma), edge_eps=_edge_eps(settings, edge_scale))
    analysis = analyse(scene, s) if prepared is None else prepared.analyse(s.eps, s.edge_eps)
    opts = dict(options or {})
    opts["analyse"] = s.to_record()
    if ingest_options is not None:
        opts["ingest"] = ingest_options
    size, every = clusters if clusters is not None else (None, False)
    c = from_bytes(build(scene, analysis, options=opts, viewing=viewing, cluster_size=size, cluster_all=every), None)
    if stop is None and stop_below is not None:
        stop = stop_rule(float(stop_below[0]), stop_below[1], watch)
    # a probe that draws what an earlier one drew (the same buffers and attributes) takes its
    # numbers from the harness's content memo (``Harness.view_memo``) and renders nothing
    stop_view = None if stop_below is None else view_rule(float(stop_below[0]), stop_below[1])
    res = harness_evaluate(harness, c, levels=levels, views=views, variants=("cap",), stop=stop, stop_view=stop_view,
                           cooked_from=scene)
    return _probe_record(scene, settings, sigma, s, edge_scale, c, res, levels, t0)


def _probe_record(scene, settings: AnalyseSettings, sigma: float, s: AnalyseSettings, edge_scale: float, c, res,
                  levels, t0: float) -> dict:
    """``probe``'s result (its doc) from the probe's settings ``s`` (eps / sigma, edge_eps), its
    container ``c`` and ``harness_evaluate``'s ``res``; ``seconds`` counted from ``t0``."""
    lods = [0] * len(c.manifest["parts"])
    f32 = 12 * sum(int(p["lods"][0]["vertices"]) for p in c.manifest["parts"])
    cap_bytes = [int(position_bytes(c, lods, int(b))["cap"]) for b in levels]  # memory needs no render
    per_level = [r["cap"]["psnr_min"] for r in res["levels"]]
    per_level_mean = [r["cap"]["psnr_mean"] for r in res["levels"]]
    finite = [p for p in per_level if p is not None]
    finite_mean = [p for p in per_level_mean if p is not None]
    kf = _kf_dict(scene, settings, sigma)
    return {
        "sigma": float(sigma),
        "log2_sigma": _log2(sigma),
        "eps": float(s.eps),
        "edge_scale": float(edge_scale),
        "edge_eps": float(s.edge_eps),
        "edges": bool(s.edges),
        "kf": kf,
        "kf_normal": kf.get("normal"),
        "psnr_min": min(finite) if finite else None,
        "psnr_mean": min(finite_mean) if finite_mean else None,
        "psnr_min_per_level": per_level,
        "psnr_mean_per_level": per_level_mean,
        "cap_percent": [100.0 * b / max(f32, 1) for b in cap_bytes],
        "cap_bytes": cap_bytes,
        "depth_order_errors": int(sum(r["cap"]["depth_order_errors"] for r in res["levels"])),
        "seconds": round(time.perf_counter() - t0, 3),
        "complete": len(res["levels"]) == len(list(levels)),
        "levels": [int(r["level"]) for r in res["levels"]],
    }


def cap_memory(scene, settings: AnalyseSettings, x: float, e: float, levels, cache: dict | None = None,
               prepared=None, clusters: tuple | None = None) -> float:
    """Mean over ``levels`` of the CAP memory (% of float32 positions) of the cook at log2 sigma ``x``
    and edge strictness ``e``: what ``probe`` reports as ``cap_percent``, from the analysis and the
    build alone (no render). ``cache`` (a dict) keeps results by (x, e); ``prepared`` as in ``probe``."""
    if cache is not None and (x, e) in cache:
        return cache[(x, e)]
    s = replace(settings, eps=settings.eps / 2.0**x, edge_eps=_edge_eps(settings, e))
    analysis = analyse(scene, s) if prepared is None else prepared.analyse(s.eps, s.edge_eps)
    size, every = clusters if clusters is not None else (None, False)
    c = from_bytes(build(scene, analysis, options={"analyse": s.to_record()}, cluster_size=size, cluster_all=every),
                   None)
    f32 = 12 * sum(int(p["lods"][0]["vertices"]) for p in c.manifest["parts"])
    lods = [0] * len(c.manifest["parts"])
    out = sum(100.0 * position_bytes(c, lods, int(b))["cap"] / max(f32, 1) for b in levels) / len(levels)
    if cache is not None:
        cache[(x, e)] = out
    return out


def _passes(p: dict, target: float, statistic: str = "min") -> bool:
    v = p[f"psnr_{statistic}"]
    return v is None or v >= target


def _same_harness(confirm, views, resolution) -> bool:
    """Whether the gate's harness ``confirm`` = (views, (w, h)) renders the same views (as
    ``render.select_views`` picks them from a count or a list) at the same size as the search's."""
    cv, cr = confirm
    return select_views(cv) == select_views(views) and tuple(cr) == tuple(resolution)


def _level_psnrs(p: dict, statistic: str, levels=None) -> list:
    """Per level rendered, the probe's PSNR statistic in dB (an identical render, None, counts as
    ``INF_DB``); with ``levels``, one entry per level given: None where the probe did not render it."""
    got = [INF_DB if v is None else float(v) for v in p[f"psnr_{statistic}_per_level"]]
    if levels is None:
        return got
    by = dict(zip(p.get("levels") or [], got))
    return [by.get(int(b)) for b in levels]


def _predict(points: list[tuple[float, list[float]]], targets: list[float]) -> float:
    """The least log2 sigma at which every level is predicted to reach its target (dB), from probes
    ``points`` = [(log2 sigma, PSNR per level)] of one edge strictness ("The model" in docs/tune.md).

    Per level: PSNR is taken as linear in log2 sigma through the two probes nearest the level's
    crossing (the highest failing and the lowest passing one when both exist), its slope clipped
    to [``SLOPE_MIN``, ``SLOPE_MAX``] dB per doubling (a flat curve sends the next probe far: to the range's end); with one probe the slope is ``SLOPE_DB``
    (MSE falls 4x per doubling of sigma: 10 log10 4 = 6.02 dB). A level that two probes at different
    sigma give exactly the same PSNR (the same renders: k_f does not move it) sets no bound when it
    passes (``targets`` are the search's, ``MODEL_MARGIN_DB`` above the pass line), and makes the
    prediction +inf (no sigma reaches it) when it fails; -inf when no level sets a bound."""
    need = -math.inf
    for li, target in enumerate(targets):
        # the probes that rendered this level (a probe of a direct search may have stopped before it)
        pts = sorted(((x, ps) for x, ps in points if li < len(ps) and ps[li] is not None), key=lambda t: t[0])
        if not pts:
            continue
        below = [(x, ps[li]) for x, ps in pts if ps[li] < target]
        above = [(x, ps[li]) for x, ps in pts if ps[li] >= target]
        if below and above and max(b[0] for b in below) < min(a[0] for a in above):
            (xa, pa), (xb, pb) = max(below), min(above)
        elif len(pts) >= 2:
            near = sorted(pts, key=lambda t: abs(t[1][li] - target))[:2]
            (xa, pa), (xb, pb) = sorted((x, ps[li]) for x, ps in near)
        else:
            (xa, pa) = (xb, pb) = (pts[0][0], pts[0][1][li])
        if xb > xa and pb == pa:
            # two probes render this level alike (k_f does not reach it: its error is edges' or none):
            # passing (the target less the model's margin), it sets no bound; failing, no k_f in the
            # range reaches it
            if pa >= target - MODEL_MARGIN_DB:
                continue
            return math.inf
        slope = (pb - pa) / (xb - xa) if xb > xa else SLOPE_DB
        slope = min(SLOPE_MAX, max(SLOPE_MIN, slope))
        ref_x, ref_p = (xa, pa) if abs(pa - target) <= abs(pb - target) else (xb, pb)
        need = max(need, ref_x + (target - ref_p) / slope)
    return need


def model_search(run, ok, lo: float, hi: float, tol: float, start: float, psnrs, targets, give_up=None,
                 max_probes: int | None = None, reach_check: bool = True, before=None):
    """Least x on the grid ``lo + k * tol`` (``hi`` the last point) with ``ok(run(x))``, assuming
    ``ok`` is non-decreasing in x: probe ``start``, then the grid point the model predicts
    (``_predict`` over every probe made so far, ``psnrs(probe)`` per level, ``targets`` per level),
    clamped strictly inside the bracket of the highest failing and the lowest passing grid points;
    when ``start`` fails, ``hi`` is probed next (with ``reach_check``; the target is unreachable
    when it fails). Ends when the bracket is one grid step wide (the passing end is returned), when
    the lowest grid point passes, when ``hi`` fails (None), when ``give_up(probe)`` is true for a
    failing probe (None: the caller needs no pass above it) or after ``max_probes`` probes (the
    least passing point so far, or None). ``before(x)`` true for the next point (nothing probed
    there: e.g. its memory, known without rendering, is already too much) removes it and every
    point above it from the search, which goes on below it. When two predictions in a row have not
    halved the bracket a bisection follows (as in Dekker's method); after ``MODEL_STEPS``
    predictions only bisections."""
    n_steps = max(1, int(math.ceil((hi - lo) / tol - 1e-9)))

    def xk(k: int) -> float:
        return hi if k >= n_steps else lo + k * tol

    seen: dict = {}

    def at(k: int) -> bool | None:
        if k not in seen:
            if before is not None and before(xk(k)):
                return None
            p = run(xk(k))
            seen[k] = (ok(p), p)
        return seen[k][0]

    k = min(n_steps, max(0, int(round((min(hi, max(lo, start)) - lo) / tol))))
    predictions = 0
    widths: list = []  # unprobed grid points inside the bracket at each prediction since a bisection
    ceiling = n_steps  # grid points above it are of no use (``before``)
    while True:
        passed = at(k)
        kp = min((j for j, (v, _) in seen.items() if v), default=None)
        kf = max((j for j, (v, _) in seen.items() if not v and (kp is None or j < kp)), default=None)
        if passed is None:  # nothing at or above k is of use: search below it
            ceiling = min(ceiling, k - 1)
            low = 0 if kf is None else kf + 1
            if ceiling < low:
                return None if kp is None or kp > k else xk(kp)
            k = (low + ceiling + 1) // 2
            continue
        if not passed and give_up is not None and give_up(seen[k][1]):
            return None
        if kp == 0:
            return xk(0)
        if kp is None and kf is not None and kf >= n_steps:
            return None
        if kp is not None and kf is not None and kp - kf <= 1:
            return xk(kp)
        if max_probes is not None and len(seen) >= max_probes:
            return None if kp is None else xk(kp)
        if reach_check and kp is None and n_steps not in seen:  # the start failed: is the target reachable?
            k = n_steps
            continue
        low, high = (0 if kf is None else kf + 1), min(ceiling, n_steps if kp is None else kp - 1)
        if high < low:
            return None if kp is None else xk(kp)
        width = high - low + 1
        # two predictions in a row that did not halve the bracket: bisect once
        bisect = predictions >= MODEL_STEPS or (len(widths) >= 2 and 2 * width > widths[-2])
        if not bisect:
            predictions += 1
            widths.append(width)
            x_star = _predict([(xk(j), psnrs(p)) for j, (_, p) in seen.items()], targets)
            k_star = int(math.ceil((x_star - lo) / tol - 1e-9)) if math.isfinite(x_star) else (
                high if x_star > 0 else low)
        else:
            widths = []
            k_star = (low + high) // 2
        k = min(high, max(low, k_star))


def _confirm(scene, settings, x: float, e: float, curve: dict, hi: float, tolerance: float, target_psnr: float,
             statistic: str, confirm, *, edges: bool, levels, viewing, options, ingest_options, progress,
             run_reduced, dry, prepared=None, confirm_levels=None, clusters: tuple | None = None) -> dict:
    """Check the choice (log2 sigma ``x``, edge strictness ``e``) on the gate's harness
    ("Confirmation" in docs/tune.md); ``curve`` holds the reduced harness's probes by (x, e),
    ``run_reduced(x, e)`` probes there, ``dry(x, e)`` is the memory of a cook without rendering it.
    While the gate misses the target: the moves that cost less memory than the anchor (the default
    cook's knobs, or the choice's where it is stricter) and not the same as the choice -- toward
    the anchor as far as the model needs (``_toward_anchor``), and one step stricter on the edges
    -- cheaper first, then the anchor, then (only when the anchor is stricter than the default)
    steps stricter on both knobs (``_gate_moves``); after a pass on the k_f line, the point the
    gate's own secant (failed choice, pass) predicts (``_gate_secant``); at most ``CONFIRM_STEPS``
    probes on the gate in all. The passing probe with the least memory is kept.
    ``confirm_levels``: the levels of ``levels`` rendered on the gate (None: all; ``calibrate``
    passes those of ``CONFIRM_LEVELS``); ``prepared`` as in ``probe``."""
    views, resolution = confirm
    clevels = [b for b in levels if confirm_levels is None or b in set(int(v) for v in confirm_levels)] or list(levels)
    at = [levels.index(b) for b in clevels]  # the gate's levels among the reduced harness's
    out = {"views": views if isinstance(views, int) else list(views),
           "resolution": [int(resolution[0]), int(resolution[1])], "passed": False, "probes": []}
    # the float renders are cached (cropped to the object's box, capped): a second probe renders CAP only
    with shared_harness(scene, resolution) as h:
        gate = _GateProbes(scene, settings, h, out["probes"], progress, target_psnr, statistic,
                           dict(levels=clevels, views=views, viewing=viewing, options=options,
                                ingest_options=ingest_options, stop_below=(target_psnr, statistic),
                                prepared=prepared, clusters=clusters))
        c0 = (x, e)
        if not gate.ok(c0):
            anchor = (_snap_up(max(x, 0.0), x, hi, tolerance), max(e, 0.0) if edges else e)
            moves = []
            if anchor != c0:
                moves.append(_toward_anchor(c0, anchor, curve[c0], run_reduced(*anchor), gate.run(c0), at,
                                            target_psnr, statistic, hi, tolerance))
            if edges and e + 1.0 <= EDGE_RANGE:  # coverage along edges does not depend on k_f
                moves.append((x, e + 1.0))
            moves = _gate_moves(moves, c0, anchor, dry, edges, hi, tolerance)
            for m in moves[:CONFIRM_STEPS - 1]:
                if gate.ok(m):
                    _gate_secant(gate, c0, m, hi, tolerance, target_psnr, statistic)
                    break
        probed = gate.probed
        passing = [c for c in probed if _passes(probed[c], target_psnr, statistic)]
        chosen = min(passing, key=lambda c: (sum(probed[c]["cap_percent"]), c)) if passing else None
        out["passed"] = chosen is not None
        out["chosen"] = probed[chosen] if chosen is not None else max(
            probed.values(), key=lambda p: min(_level_psnrs(p, statistic)))
        out["chosen_knobs"] = chosen
    return out


class _GateProbes:
    """``probe``s on the gate's harness ``h`` for ``_confirm``, each made once per knobs
    (log2 sigma, x_e), marked ``"confirm"``, appended to ``record`` and passed to
    ``progress``; ``kw``: ``probe``'s keyword arguments (levels, views, ``stop_below``, ...)."""

    def __init__(self, scene, settings, h, record: list, progress, target_psnr: float, statistic: str, kw: dict):
        self.scene, self.settings, self.h, self.record, self.progress = scene, settings, h, record, progress
        self.target_psnr, self.statistic, self.kw = target_psnr, statistic, kw
        self.probed: dict = {}

    def run(self, c) -> dict:
        if c not in self.probed:
            p = probe(self.scene, self.settings, 2.0**c[0], self.h, edge_scale=c[1], **self.kw)
            p["confirm"] = True
            self.probed[c] = p
            self.record.append(p)
            if self.progress is not None:
                self.progress(p)
        return self.probed[c]

    def ok(self, c) -> bool:
        return _passes(self.run(c), self.target_psnr, self.statistic)


def _snap_up(v: float, x: float, hi: float, tolerance: float) -> float:
    """``v`` rounded up to whole ``tolerance`` steps above ``x``, at most ``hi`` (``x`` itself when
    ``v`` is not above it)."""
    return min(hi, x + tolerance * math.ceil((v - x) / tolerance - 1e-9)) if v > x else x


def _toward_anchor(c0, anchor, reduced0: dict, reduced1: dict, gate0: dict, at: list, target_psnr: float,
                   statistic: str, hi: float, tolerance: float) -> tuple:
    """The knobs a fraction t of the way from the choice ``c0`` to ``anchor`` (log2 sigma rounded up
    to the grid, x_e up to whole steps), t in [0, 1] the least that, per gate level that misses
    (``gate0``, the choice's gate probe), the reduced harness's gain between the choice
    (``reduced0``) and the anchor (``reduced1``) covers: aiming ``CONFIRM_MARGIN_DB`` above the
    target. ``at``: the gate's levels' indices among the reduced harness's."""
    x, e = c0
    red0 = [_level_psnrs(reduced0, statistic)[i] for i in at]
    red1 = [_level_psnrs(reduced1, statistic)[i] for i in at]
    g = _level_psnrs(gate0, statistic)
    t = 0.0
    for r0, r1, g0 in zip(red0, red1, g):
        if g0 >= target_psnr + CONFIRM_MARGIN_DB:
            continue
        gain = r1 - r0
        t = max(t, 1.0 if gain <= 0 else (target_psnr + CONFIRM_MARGIN_DB - g0) / gain)
    t = min(1.0, t)
    return (_snap_up(x + t * (anchor[0] - x), x, hi, tolerance), e + math.ceil(t * (anchor[1] - e) - 1e-9))


def _gate_moves(moves: list, c0, anchor, dry, edges: bool, hi: float, tolerance: float) -> list:
    """The knobs the gate probes in order after the choice ``c0`` missed: of ``moves`` those that
    cost less memory than ``anchor`` (``dry``, no render) and not the same as the choice, cheaper
    first (a move whose memory equals the choice's changes no bit that matters: skipped), then the
    anchor, then -- only when the anchor is stricter than the default cook -- steps stricter on
    both knobs, up to ``CONFIRM_STEPS - 1`` moves in all."""
    limit = dry(*anchor) if anchor != c0 else math.inf
    moves = sorted((m for m in dict.fromkeys(moves)
                    if m != c0 and m != anchor and dry(*c0) != dry(*m) < limit),
                   key=lambda m: (dry(*m), m))
    if anchor != c0:
        moves.append(anchor)
    # past the anchor only when it is stricter than the default cook (the choice was)
    stricter = anchor[0] > 0.0 or (edges and anchor[1] > 0.0)
    cur = anchor
    while stricter and len(moves) < CONFIRM_STEPS - 1:
        nxt = (min(hi, cur[0] + tolerance), min(float(EDGE_RANGE), cur[1] + 1.0) if edges else cur[1])
        if nxt == cur:
            break
        moves.append(nxt)
        cur = nxt
    return moves


def _gate_secant(gate: _GateProbes, c0, m, hi: float, tolerance: float, target_psnr: float,
                 statistic: str) -> None:
    """After the gate passed at ``m`` on the k_f line of the failed choice ``c0``: the point the
    gate's own secant between them predicts, probed when it lies strictly between them (it may
    pass with less memory) and the budget of ``CONFIRM_STEPS`` gate probes has room."""
    x, e = c0
    if m[1] == e and m[0] > x and len(gate.probed) < CONFIRM_STEPS:
        g0, g1 = _level_psnrs(gate.probed[c0], statistic), _level_psnrs(gate.probed[m], statistic)
        n = min(len(g0), len(g1))
        guess = _predict([(x, g0[:n]), (m[0], g1[:n])], [target_psnr + CONFIRM_MARGIN_DB] * n)
        between = (_snap_up(guess, x, hi, tolerance), e)
        if x < between[0] < m[0]:
            gate.ok(between)


@with_code_memo
def calibrate(scene, settings: AnalyseSettings = DEFAULT_ANALYSE, *, target_psnr: float,
              levels=DEFAULT_LEVELS, views=CAL_VIEWS, resolution=CAL_RESOLUTION, viewing: Viewing | None = None,
              log2_range=LOG2_RANGE, tolerance: float = TOLERANCE, options: dict | None = None,
              ingest_options: dict | None = None, progress=None, statistic: str = "min",
              search: str | None = None, confirm=CONFIRM, confirm_levels=CONFIRM_LEVELS,
              watch_db: float | None = None, complete: bool = True, clusters: tuple | None = None,
              loosen_edges: bool = True) -> dict:
    """Search the smallest k_f scale sigma whose CAP renders reach ``target_psnr`` dB (module doc).

    Parameters: ``scene`` (the ingested source), ``settings`` (the analysis settings to scale),
    ``target_psnr`` dB, ``levels`` (per-buffer levels, default 6..12), ``views`` (int or indices),
    ``resolution`` (w, h), ``viewing`` (recorded in each probe container: its field of view and pixel
    error set the camera distances), ``log2_range`` (lo, hi) of log2 sigma, ``tolerance`` (grid step
    of log2 sigma: the choice passes and the grid point below it fails), ``options``/``ingest_options``
    (recorded in the probe containers), ``progress(probe_dict)`` called after each probe,
    ``statistic`` ("min" or "mean" over views), ``search`` ("kf" or "kf+edge", module doc; default
    "kf+edge" when ``settings.edges``, else "kf"), ``confirm`` ((views, (w, h)) of the gate's
    harness, default 20 views at 1280 x 720; None: no confirmation; skipped when it equals the
    search harness), ``confirm_levels`` (the levels of ``levels`` confirmed there, default
    ``CONFIRM_LEVELS`` = 6..11, the gate's ``verify --levels 6-11``; None: every level),
    ``watch_db`` (None: every probe renders every level; a number: the direct search ("Watched
    levels" in docs/tune.md), with the anchor's margin ``watch_db`` dB; give the gate's harness as
    ``views``/``resolution``/``levels`` and ``confirm=None``), ``complete`` (direct search: render
    the choice at every level before returning it, and search again watching the level it missed;
    False leaves that to the caller: ``lopcook.tune.attributes`` completes its own choice),
    ``clusters`` (the cook's position layout, as ``probe``), ``loosen_edges`` (False: steps 2a and 2c
    are left out -- the edges are loosened only by the attribute search that follows, which has
    them as a knob -- while 2b, stricter edges where the given ones cannot pass, stays).

    Returns a JSON-ready dict: ``target_psnr``, ``statistic``, ``reached`` (bool), ``sigma`` / ``log2_sigma`` /
    ``eps`` / ``edge_eps`` / ``edge_scale`` / ``edges`` / ``kf`` / ``kf_normal`` of the choice (the
    passing probe with the least memory; the best probe when unreachable), ``search``, ``chosen``
    (that probe), ``curve`` (every probe on the search's harness, sorted by sigma, then edge
    strictness: sigma, eps, edge_eps, kf, psnr_min, psnr_min_per_level, cap_percent per level, ...),
    ``levels``, ``views``, ``resolution``, ``base_eps``, ``seconds``, ``confirmation`` (None, or
    ``views``, ``resolution``, ``passed``, ``probes`` [the probes on the gate's harness, in order]), and
    ``watch`` (the watched levels, in render order; None without ``watch_db``) and ``complete``
    (whether the choice was rendered at every level).
    """
    search, lo, hi = _checked(search, settings, statistic, target_psnr, log2_range)
    viewing = viewing or Viewing()
    levels = [int(b) for b in levels]
    t0 = time.perf_counter()
    # what no probe changes, computed once (and kept for the attribute search)
    prepared = shared_prepared(scene, settings)
    direct = watch_db is not None
    with shared_harness(scene, resolution) as h:
        ks = _KfSearch(scene, settings, h, dict(views=views, viewing=viewing, options=options,
                                                 ingest_options=ingest_options, prepared=prepared, clusters=clusters),
                       target_psnr=target_psnr, statistic=statistic, levels=levels, lo=lo, hi=hi, tolerance=tolerance,
                       progress=progress, direct=direct)
        if direct:
            ks.scout(float(watch_db))
        reached, x, e, chosen, whole = ks.settle(search, loosen_edges, complete)
        confirmation = None
        same = confirm is not None and _same_harness(confirm, views, resolution)
        if reached and confirm is not None and not same and not direct:
            confirmation = _confirm(scene, settings, x, e, ks.probes, hi, tolerance, target_psnr, statistic, confirm,
                                    edges=search == "kf+edge" and bool(settings.edges), levels=levels,
                                    viewing=viewing, options=options, ingest_options=ingest_options,
                                    progress=progress, run_reduced=ks.run, dry=ks.dry, prepared=prepared,
                                    confirm_levels=confirm_levels, clusters=clusters)
            reached = confirmation["passed"]
            chosen = confirmation.pop("chosen")
            confirmation.pop("chosen_knobs")
        if direct and complete:
            reached = reached and whole
    return _calibration_result(target_psnr, statistic, reached, chosen, search, ks, views, resolution, settings,
                               lo, hi, tolerance, confirmation, t0)


def _checked(search: str | None, settings: AnalyseSettings, statistic: str, target_psnr: float, log2_range):
    """``calibrate``'s arguments checked: ``(search, lo, hi)``, the search defaulted ("kf+edge" when
    ``settings.edges``, else "kf"); LopcookError (usage) for any value out of its range."""
    search = search or ("kf+edge" if settings.edges else "kf")
    if search not in SEARCHES:
        raise LopcookError("usage", None, f"calibration search must be one of {SEARCHES}, got {search!r}")
    if statistic not in STATISTICS:
        raise LopcookError("usage", None, f"PSNR statistic must be one of {STATISTICS}, got {statistic!r}")
    if not math.isfinite(float(target_psnr)) or target_psnr <= 0:
        raise LopcookError("usage", None, f"target PSNR must be a positive number of dB, got {target_psnr}")
    lo, hi = (float(v) for v in log2_range)
    if not lo < hi:
        raise LopcookError("usage", None, f"log2 k_f range must have lo < hi, got {log2_range}")
    return search, lo, hi


def _calibration_result(target_psnr: float, statistic: str, reached: bool, chosen: dict, search: str, ks,
                        views, resolution, settings: AnalyseSettings, lo: float, hi: float, tolerance: float,
                        confirmation, t0: float) -> dict:
    """``calibrate``'s result (its doc): the choice ``chosen`` (a probe), the curve of every probe of
    the search ``ks`` (a ``_KfSearch``), sorted by sigma, then edge strictness."""
    curve = [ks.probes[k] for k in sorted(ks.probes)]  # by sigma, then edge strictness
    watch = ks.watch
    return {
        "target_psnr": float(target_psnr),
        "statistic": statistic,
        "reached": bool(reached),
        "sigma": chosen["sigma"],
        "log2_sigma": chosen["log2_sigma"],
        "eps": chosen["eps"],
        "edge_eps": chosen["edge_eps"],
        "edge_scale": chosen["edge_scale"],
        "edges": chosen["edges"],
        "search": search,
        "kf": chosen["kf"],
        "kf_normal": chosen["kf_normal"],
        "chosen": chosen,
        "curve": curve,
        "levels": ks.levels,
        "views": views if isinstance(views, int) else list(views),
        "resolution": [int(resolution[0]), int(resolution[1])],
        "base_eps": float(settings.eps),
        "log2_range": [lo, hi],
        "tolerance": float(tolerance),
        "confirmation": confirmation,
        "watch": None if watch is None else [int(b) for b in watch],
        "complete": bool(chosen.get("complete", True)),
        "seconds": round(time.perf_counter() - t0, 3),
    }


class _KfSearch:
    """The probes of one ``calibrate`` search on the harness ``h``, each made once per knobs
    (log2 sigma ``x``, edge strictness ``e``) and kept in ``probes`` (the curve); ``kw``:
    ``probe``'s keyword arguments common to every probe (views, viewing, options, prepared, ...).
    ``direct``: the watched levels (``watch``, set by ``scout``) are rendered first and a probe
    stops at its first miss; a probe whose verdict does not cover a level watched since is made
    again."""

    def __init__(self, scene, settings: AnalyseSettings, h, kw: dict, *, target_psnr: float, statistic: str,
                 levels: list, lo: float, hi: float, tolerance: float, progress, direct: bool):
        self.scene, self.settings, self.h, self.kw = scene, settings, h, kw
        self.target_psnr, self.statistic, self.levels = target_psnr, statistic, levels
        self.lo, self.hi, self.tolerance = lo, hi, tolerance
        self.progress, self.direct = progress, direct
        self.probes: dict = {}
        self.dry_cache: dict = {}
        self.targets = [float(target_psnr) + MODEL_MARGIN_DB] * len(levels)
        self.start = min(hi, max(lo, 0.0))  # the default cook's k_f
        self.watch: list | None = None  # the watched levels, in render order (direct search)

    def order(self) -> list:
        """The levels in render order: the watched ones first."""
        return list(self.watch) + [b for b in self.levels if b not in self.watch]

    def settled(self, p: dict) -> bool:
        """Whether a direct probe's verdict holds for the watched levels: it failed on a level it
        rendered, or it rendered every watched level."""
        return not self.passes(p) or set(self.watch) <= set(p["levels"])

    def _made(self, p: dict, x: float, e: float) -> dict:
        self.probes[(x, e)] = p
        if self.progress is not None:
            self.progress(p)
        return p

    def run(self, x: float, e: float = 0.0) -> dict:
        """The probe at (x, e), made when not made yet (or not settled, direct)."""
        if (x, e) not in self.probes or (self.direct and not self.settled(self.probes[(x, e)])):
            extra = {}
            if self.direct:  # the watched levels first (least margin first), up to the first that fails
                extra = dict(levels=self.order(), stop_below=(float(self.target_psnr), self.statistic),
                             watch=len(self.watch))
            p = probe(self.scene, self.settings, 2.0**x, self.h, **{"levels": self.levels, **extra}, edge_scale=e,
                      **self.kw)
            self._made(p, x, e)
        return self.probes[(x, e)]

    def ok(self, x: float, e: float = 0.0) -> bool:
        return self.passes(self.run(x, e))

    def passes(self, p: dict) -> bool:
        return _passes(p, self.target_psnr, self.statistic)

    def psnrs(self, p: dict) -> list:
        return _level_psnrs(p, self.statistic, self.levels if self.direct else None)

    def kf_search(self, e: float, a: float, x_start: float, give_up=None):
        """``model_search`` over log2 sigma in [a, hi] at edge strictness ``e``, from ``x_start``."""
        return model_search(lambda t: self.run(t, e), self.passes, a, self.hi, self.tolerance, x_start, self.psnrs,
                            self.targets, give_up)

    def memory(self, c) -> float:
        """Mean CAP memory over the levels (% of float32 positions) of the probe at knobs ``c``."""
        return sum(self.run(*c)["cap_percent"]) / len(self.levels)

    def dry(self, x: float, e: float) -> float:
        """The memory of a probe, without rendering it."""
        if (x, e) in self.probes:
            return self.memory((x, e))
        return cap_memory(self.scene, self.settings, x, e, self.levels, self.dry_cache,
                          prepared=self.kw["prepared"], clusters=self.kw["clusters"])

    def scout(self, watch_db: float) -> None:
        """The direct search's anchor (the default cook), levels ascending until the PSNR has climbed
        clear of its least (``scout_rule``): the levels within ``watch_db`` dB of the least are
        watched, least margin first."""
        anchor = probe(self.scene, self.settings, 2.0**self.start, self.h, levels=sorted(self.levels),
                       stop=scout_rule(self.statistic, watch_db), **self.kw)
        self._made(anchor, self.start, 0.0)
        per = dict(zip(anchor["levels"], _level_psnrs(anchor, self.statistic)))
        least = min(per.values())
        self.watch = sorted((b for b in per if per[b] < least + watch_db), key=lambda b: (per[b], b))

    def settle(self, search: str, loosen_edges: bool, complete: bool):
        """``(reached, x, e, chosen probe, whole)``: the choice of ``choose``; a direct search with
        ``complete`` renders it at every level (the watched ones first) and, when it misses a level
        nobody watched, watches that level too and chooses again. ``whole``: the choice passed at
        every level."""
        whole = False
        for _ in range(len(self.levels) + 1):
            reached, x, e = self.choose(search, loosen_edges)
            chosen = self.run(x, e)
            if not (self.direct and complete and reached):
                break
            if set(chosen["levels"]) < set(self.levels):  # the choice at every level, the watched ones first
                chosen = probe(self.scene, self.settings, 2.0**x, self.h, levels=self.order(), edge_scale=e,
                               stop_below=(float(self.target_psnr), self.statistic), **self.kw)
                self._made(chosen, x, e)
            if self.passes(chosen):
                whole = True
                break
            # it missed a level nobody watched: watch it too, and search again
            missed = chosen["levels"][-1]
            if missed in self.watch:
                break
            self.watch.append(missed)
        return reached, x, e, chosen, whole

    def choose(self, search: str, loosen_edges: bool):
        """(reached, x, e) of one search over the knobs (module doc, steps 1-2c)."""
        # (1) k_f at the given edge_eps
        e = 0.0
        x = self.kf_search(e, self.lo, self.start)
        candidates = [] if x is None else [(x, e)]
        if search == "kf+edge" and self.settings.edges:
            loosest = float(-math.floor(math.log2(1.0 / float(self.settings.edge_eps))))
            if x is not None and loosest < 0 and loosen_edges:
                candidates += self._looser_edges(x, loosest)
            elif x is None:  # (2b) stricter edges at the largest k_f, then k_f again
                e_found = _least_passing(lambda t: self.ok(self.hi, t), 1.0, float(EDGE_RANGE))
                if e_found is not None:
                    e = e_found
                    x = self.kf_search(e, self.lo, self.hi)
                    candidates = [(x, e)]
        # only candidates whose verdict holds for the watched levels (a direct search's watch may
        # have grown since one was found)
        candidates = [c for c in candidates if self.ok(*c)]
        if candidates:  # the least position memory, averaged over the levels (ties: less k_f)
            x, e = min(candidates, key=lambda c: (self.memory(c), c[0]))
            return True, x, e
        return False, self.hi, e

    def _looser_edges(self, x: float, loosest: float) -> list:
        """Steps (2a) and (2c) after k_f ``x`` passed at the given edges: the candidates (x, e1),
        e1 the loosest edges in [``loosest``, 0] that still pass at ``x``, and, when the edges
        could not be loosened all the way and the loosest edges at ``x`` cost less memory than the
        best so far, (x1, loosest) with the k_f above ``x`` that passes there (at most
        ``EDGE_KF_PROBES`` probes, over points whose memory is below the best)."""
        # (2a) loosen the edges while the target holds at the chosen k_f
        e1 = _least_passing(lambda t: self.ok(x, t), loosest, 0.0)
        out = [(x, e1)]
        if e1 > loosest:  # (2c) the loosest edges, paid for with more k_f, while that can cost less
            best = min(self.memory(c) for c in [(x, 0.0)] + out)
            if self.memory((x, loosest)) < best:
                guess = _predict([(x, self.psnrs(self.run(x, loosest)))], self.targets)
                guess = x + self.tolerance * max(1, math.ceil((guess - x) / self.tolerance - 1e-9))
                n = len(self.levels)
                x1 = model_search(lambda t: self.run(t, loosest), self.passes, x, self.hi, self.tolerance, guess,
                                  self.psnrs, self.targets, reach_check=False, max_probes=EDGE_KF_PROBES,
                                  give_up=lambda p: sum(p["cap_percent"]) / n >= best,
                                  before=lambda t: self.dry(t, loosest) >= best)
                if x1 is not None:
                    out.append((x1, loosest))
        return out


def _least_passing(f, a: float, b: float):
    """Smallest whole t in [a, b] with f(t) (f non-decreasing in t); None when f(b) fails."""
    if f(a):
        return a
    if not f(b):
        return None
    while b - a > 1.0:  # f(a) fails, f(b) passes
        m = float(math.floor(0.5 * (a + b)))
        if m <= a:
            break
        if f(m):
            b = m
        else:
            a = m
    return b


def calibrated_settings(settings: AnalyseSettings, result: dict) -> AnalyseSettings:
    """The analysis settings of the calibration's choice (eps divided by the chosen sigma, and the
    chosen edge_eps)."""
    return replace(settings, eps=float(result["eps"]), edge_eps=float(result.get("edge_eps", settings.edge_eps)))


def require_reached(result: dict, path: str | None = None) -> None:
    """Raise LopcookError (exit 1) when the calibration did not reach its target."""
    if not result["reached"]:
        key = f"psnr_{result.get('statistic', 'min')}"
        best = max((p for p in result["curve"] if p[key] is not None), key=lambda p: p[key], default=None)
        got = "" if best is None else (f": the best CAP PSNR ({result.get('statistic', 'min')} over views, worst "
                                       f"level) was {best[key]:.1f} dB, at k_f scale 2^{best['log2_sigma']:g}")
        conf = result.get("confirmation")
        if conf and not conf.get("passed") and conf.get("probes"):
            best = max(conf["probes"], key=lambda p: float("inf") if p[key] is None else p[key])
            raise LopcookError("verify", path, f"the k_f chosen on {result['views']} views at "
                               f"{result['resolution'][0]}x{result['resolution'][1]} reached {result['target_psnr']:g} "
                               f"dB there, but on the gate's {conf['views']} views at {conf['resolution'][0]}x"
                               f"{conf['resolution'][1]} the best of {len(conf['probes'])} stricter probes was "
                               f"{best[key]:.1f} dB", hint="calibrate on the gate's views (--calibration-views 20 "
                               "--calibration-resolution 1280x720) or lower --target-psnr", exit_code=EXIT_VERIFY_FAILED)
        both = result.get("search") == "kf+edge" and result.get("edges")
        what = "k_f and edge_eps" if both else "k_f"
        if both:  # every knob that moves the PSNR was searched over its whole range
            hint = "lower --target-psnr: both knobs were searched over their whole range"
        elif result.get("edges"):
            hint = ("lower --target-psnr; coverage error along edges does not depend on k_f (let the calibration "
                    "search edge_eps too with --search kf+edge)")
        else:
            hint = ("lower --target-psnr; coverage error along edges does not depend on k_f (turn on --edges and let "
                    "the calibration search edge_eps with --search kf+edge)")
        raise LopcookError("verify", path, f"no {what} reaches {result['target_psnr']:g} dB{got}", hint=hint,
                           exit_code=EXIT_VERIFY_FAILED)


def format_calibration(result: dict) -> str:
    """Text table of the curve: sigma, k_f (normal), eps, CAP memory % per level, min PSNR."""
    lines = [f"k_f calibration: target {result['target_psnr']:g} dB ({result['statistic']} over {result['views']} "
             f"views, every level {result['levels'][0]}-{result['levels'][-1]}, "
             f"{result['resolution'][0]}x{result['resolution'][1]})",
             "  log2 sigma   k_f normal   eps          edge eps   CAP mem % per level            "
             "PSNR min / mean (worst level)"]
    for p in result["curve"]:
        kfn = "-" if p["kf_normal"] is None else f"{p['kf_normal']:.4g}"
        mem = " ".join(f"{v:4.1f}" for v in p["cap_percent"])
        ps = "inf" if p["psnr_min"] is None else f"{p['psnr_min']:.1f}"
        pm = "inf" if p["psnr_mean"] is None else f"{p['psnr_mean']:.1f}"
        mark = " <-" if p["sigma"] == result["sigma"] and p.get("edge_eps") == result.get("edge_eps") else ""
        ee = f"{p['edge_eps']:.4g}" if p.get("edges", False) else "off"
        lines.append(f"  {p['log2_sigma']:>10.3f}   {kfn:>10}   {p['eps']:.4e}   {ee:>8}   {mem:<30} {ps:>6} / "
                     f"{pm:<6}{mark}")
    conf = result.get("confirmation")
    if conf:
        lines.append(f"  confirmed on {conf['views']} views at {conf['resolution'][0]}x{conf['resolution'][1]} "
                     "(the gate's harness):")
        for p in conf["probes"]:
            ps = "inf" if p["psnr_min"] is None else f"{p['psnr_min']:.1f}"
            mem = " ".join(f"{v:4.1f}" for v in p["cap_percent"])
            lines.append(f"  {p['log2_sigma']:>10.3f}   {'':>10}   {p['eps']:.4e}   {'':>8}   {mem:<30} {ps:>6}")
        if not conf["passed"]:
            lines.append(f"  the confirmation did not reach the target after {len(conf['probes'])} probes")
    verdict = "reached" if result["reached"] else "NOT reached"
    kfn = "-" if result["kf_normal"] is None else f"{result['kf_normal']:.4g}"
    edge = f", edge eps {result['edge_eps']:.4g}" if result.get("edges", False) else ""
    lines.append(f"  {verdict}: sigma {result['sigma']:.4g} (k_f normal {kfn}), eps "
                 f"{result['eps']:.4e}{edge}; {len(result['curve'])} probes, {result['seconds']:.1f} s")
    return "\n".join(lines)


__all__ = ["CAL_VIEWS", "CAL_RESOLUTION", "CONFIRM", "CONFIRM_STEPS", "CONFIRM_LEVELS", "WATCH_DB", "stop_rule", "view_rule", "cap_memory", "LOG2_RANGE", "TOLERANCE", "SEARCHES", "EDGE_RANGE",
           "SLOPE_DB", "MODEL_STEPS", "probe", "model_search", "calibrate",
           "calibrated_settings", "require_reached", "format_calibration"]


def calibration_record(cal: dict) -> dict:
    """What the container records of a calibration (``options.calibration``): target, the chosen
    k_f (scale sigma, eps, per-attribute k_f), the curve (memory vs PSNR over k_f; each probe's
    ``levels`` are those it rendered: a direct search's probes stop at the first level that misses
    and otherwise render the watched levels) and the watched levels (``watch``, None for a search on
    a reduced harness)."""
    keep = ("sigma", "log2_sigma", "eps", "edge_eps", "kf", "kf_normal", "psnr_min", "psnr_mean", "psnr_min_per_level",
            "psnr_mean_per_level", "cap_percent", "levels")
    return {"target_psnr": cal["target_psnr"], "statistic": cal["statistic"], "reached": cal["reached"],
            "kf": cal["kf_normal"], "kf_per_attribute": cal["kf"], "kf_scale": cal["sigma"], "eps": cal["eps"],
            "edge_eps": cal["edge_eps"],
            "base_eps": cal["base_eps"], "levels": cal["levels"], "views": cal["views"],
            "resolution": cal["resolution"], "curve": [{k: p[k] for k in keep if k in p} for p in cal["curve"]],
            "watch": cal.get("watch"),
            "confirmation": None if not cal.get("confirmation") else {
                "views": cal["confirmation"]["views"], "resolution": cal["confirmation"]["resolution"],
                "passed": cal["confirmation"]["passed"],
                "probes": [{k: p[k] for k in keep if k in p} for p in cal["confirmation"]["probes"]]}}
