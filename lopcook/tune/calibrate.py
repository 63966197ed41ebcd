"""k_f calibration: the least position memory whose CAP renders reach a target PSNR.

This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
sections 5.1 (the minimum level of a vertex: the smallest b with k_f * E_v * dx(b) <= eps) and 7
("For CAP we empirically choose k_f to avoid shading artifacts"). Here k_f is measured instead:
every probe cooks the scene and renders its CAP buffers against the float source with the
harness of ``lopcook.verify.evaluate`` (Purnomo et al. 2005, section 4.1: views on an icosahedron,
error over object pixels).

The knob. k_f enters the analysis only through the test ``k_f * E_v * dx(b) <= eps``. The
calibration searches a dimensionless scale ``sigma`` applied to **every** attribute's k_f at once
(normals: ks * n, UVs: the texture's slope, colours), so the ratios between attributes the analysis
derived are kept. Scaling every k_f by sigma is the same test as dividing eps by sigma (up to float
rounding), which is how a probe is cooked: ``AnalyseSettings(eps = eps / sigma)``, all other
settings unchanged (depth constraints included; they do not depend on sigma). Reported per probe:
``sigma``, ``eps`` (colour units), ``kf`` (sigma times the analysis's k_f per attribute, colour per
attribute unit; ``kf_normal`` = sigma * ks * n, the paper's Phong k_f, when the scene has normals).

Memory grows with sigma (every minimum level is a non-decreasing function of it), and the PSNR
nearly always does too. A probe passes when, at every level, the CAP PSNR statistic is >= the
target: ``statistic="min"`` (default) the minimum over views (every view must reach it; a view
identical to the float render counts as infinite), ``"mean"`` the PSNR of the view-averaged MSE
(Purnomo et al. average the per-view errors; one view with few object pixels weighs less).

The model (``model_search``). The search runs on the grid ``lo + k * tolerance`` of log2 sigma
(defaults [-8, 8] and 0.25: sigma within 19%) and returns its least passing point whose grid
neighbour below fails (or ``lo`` when it passes; None when ``hi`` fails: the target is unreachable,
e.g. the coverage error of vertices whose attributes do not vary, flat faces, does not depend on
k_f). Shading error is a quantization error: MSE falls about 4x per doubling of the k_f scale (per
level of the bits it buys), so per level PSNR is modelled as linear in log2 sigma, 6.02 dB per
doubling from one probe, the secant through the two probes nearest the crossing from two (its slope
clipped to [0.2, 12] dB: a flat curve, e.g. edge-limited, sends the next probe to the range's end). The first probe is the default cook's k_f (sigma 1, the anchor of the
confirmation); each next probe is the grid point where the model predicts every level reaches the
target (+0.1 dB), strictly inside the bracket of the highest failing and lowest passing probes;
when two predictions in a row have not halved the bracket a bisection follows, and after ``MODEL_STEPS``
predictions only bisections are made. When the first probe fails, ``hi`` is probed next. Typical
cost: 3-6 probes per search instead of the bisection's 8. The chosen sigma passed when probed; if
the PSNR is not monotonic in sigma somewhere inside the bracket, a smaller passing sigma may exist
(the curve shows it).

The second knob: ``edge_eps`` of the discontinuity constraint (``lopcook.analyse.discontinuity``;
hard edges, sub-pixel folds, open boundaries and seams need m >= B_v + ceil(log2(0.5 J / edge_eps)),
which k_f cannot set: on flat-shaded assets the coverage error along edges does not depend on k_f).
It is searched as a strictness ``x_e`` (``edge_eps = settings.edge_eps / 2^x_e``, at most 1, in whole
steps: with J = 1 one step is one bit on every edge vertex). ``search="kf+edge"`` (the default when
the settings have ``edges`` on) is a coordinate search: (1) the k_f search above at x_e = 0; (2a)
if it reached the target, the loosest x_e in [-log2(1 / edge_eps), 0] that still passes at the chosen
sigma (less memory on edge vertices; bisection on whole steps, the loosest probed first); (2b) if it
did not, the least x_e in (0, EDGE_RANGE] passing at the largest sigma, then the k_f search again at
that x_e; (2c) after (2a), if the edges could not be loosened all the way and the loosest edges at
the sigma of (1) cost less memory than the best choice so far, the k_f search above that sigma with
the loosest edges, at most ``EDGE_KF_PROBES`` probes, over the grid points whose memory (known
without rendering) is below the best choice's, and stopped by a failing probe that already costs as
much.
Of the passing pairs (1), (2a), (2c) the one with the least CAP memory (mean over the levels) is
chosen (which wins on which kind of asset: docs/tune.md). Every choice
passed when probed; a joint optimum of the two knobs is not guaranteed (the curve lists every
probe). ``search="kf"`` keeps edge_eps as given.

Cost and the reduced harness. Each probe = analyse + build + CAP renders at every level and view
(AP is not rendered; float renders are computed once and reused, they do not depend on sigma). The
analysis is split (``lopcook.analyse.prepared.PreparedAnalysis``, one per search): the grid, E_v,
the discontinuities' fold levels and seam jumps and the depth distances are computed once, a probe
pays only the per-threshold levels (the same minimum levels as a fresh ``analyse``).
Defaults for speed: ``CAL_VIEWS`` = 8 of the 20 views and ``CAL_RESOLUTION`` = 640 x 360. An object
covers the same pixels at level B whatever the resolution (``lopcook.verify.cameras``), so a smaller
viewport crops close-ups instead of shrinking the object; fewer views sample the sphere of
directions more coarsely. Measured costs: docs/performance.md ("Calibration").

Watched levels (the direct search, ``watch_db``; ``cook --target-psnr``'s default). The search
renders on the gate's harness itself (20 views at 1280 x 720, levels 6..11), so nothing it sees can
differ from the gate, and it renders there only what decides a probe. The **anchor** (the default
cook, sigma 1) is rendered level by level upward until two levels in a row are ``watch_db`` dB
above the least so far (``scout_rule``: the PSNR climbs with the level as the object grows on
screen); the levels rendered whose PSNR is within ``watch_db`` dB of the least are **watched**, in
order of margin. Every other probe renders the watched levels only, least
margin first, and stops at the first that misses the target: a failing probe usually costs one
level (at levels 6-8 the object covers a small part of the frame, so those are also the cheapest),
a passing one the watched levels. The choice is then rendered at every level (``complete``); if it
misses an unwatched level, that level is watched too and the search runs again (its probes are
memoised by content: only the new level is rendered). So the result passes every level or, as
before, ``reached`` is False. The float renders are made once per (level, view) and cached.

Harnesses. Both harnesses (the reduced one and the gate's) are ``shared_harness``es of the scene:
they stay open after the search, so that the attribute search of the same cook
(``lopcook.tune.attributes``) finds their float renders cached and every decoded draw already made
memoised by content (``Harness.view_memo``); their results equal fresh harnesses'.

Confirmation. The reduced harness is not the gate (fewer views can miss the worst one, and a small
object is sensitive to its sub-pixel placement; docs/tune.md has the measured misses), so the
choice is **confirmed** once with the gate's harness (``confirm``, default ``lopcook verify``'s 20
views at 1280 x 720, at the levels of ``confirm_levels``, default ``CONFIRM_LEVELS`` = 6..11, those of
the gate ``lopcook verify --levels 6-11``; float renders cached, cropped, so a further probe there
renders CAP only; a gate probe stops rendering at its first level that misses the target). A
search never ends below the default cook's quality: when the gate misses the target, the
confirmation moves toward the **anchor** -- the default cook's knobs (sigma 1, x_e 0), or the
choice's on a knob where it is stricter -- first as far as the model needs (per level, the gate's
shortfall at the choice against the PSNR the reduced harness gains between the choice and the
anchor, aiming 0.25 dB above the target; whole grid steps), then to the anchor itself; only when
the anchor is stricter than the default cook does it step further (log2 sigma + ``tolerance`` and
x_e + 1); after a pass on the k_f line it tries the point the gate's own secant (failed choice,
pass) predicts -- at most ``CONFIRM_STEPS`` probes on the gate in all. The passing gate probe with the
least memory is the choice; ``reached`` is False (exit 1 in ``cook``) only when every gate probe
missed, i.e. when even the anchor -- the default cook, for a choice looser than it -- fails the
gate. ``confirm=None`` (CLI ``--no-calibration-confirm``) skips it. With the paper's CAP alone
(``edges`` off) hard-surface assets cannot reach 40 dB at any k_f: their residual error is coverage
along hard edges and sub-pixel folds whose vertices have E_v = 0 (docs/analyse.md, section 2b).
"""

from __future__ import annotations

import math
import time
from dataclasses import replace


from ..lop.memo import with_code_memo
from ..errors import EXIT_VERIFY_FAILED, LopcookError
from ..settings import DEFAULT_ANALYSE, DEFAULTS, AnalyseSettings
from ..viewing import Viewing
from ..verify.buffers import DEFAULT_LEVELS
from ..verify.cameras import VIEW_COUNT, select_views
from ..verify.evaluate import harness_evaluate
from ..verify.renderer import RESOLUTION, Harness, shared_harness

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
    from ..analyse import attribute_kf

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
    from ..verify import metrics as M

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
    numbers (``Harness.view_memo``, keyed by the content of every draw). (Until this was keyed by
    content, probes with the same minimum levels shared renders even when eps gave them different
    attribute bits.) ``prepared``: a ``lopcook.analyse.prepared.PreparedAnalysis`` of ``scene`` and
    ``settings`` (the same minimum levels as ``analyse``, without recomputing what does not depend
    on eps and edge_eps); None analyses from scratch.
    """
    from ..analyse import analyse
    from ..emit import build
    from ..lop.container import from_bytes

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
    from ..verify.buffers import position_bytes

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
    from ..analyse import analyse
    from ..emit import build
    from ..lop.container import from_bytes
    from ..verify.buffers import position_bytes

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
    ``points`` = [(log2 sigma, PSNR per level)] of one edge strictness (module doc, "The model").

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
    """Check the choice (log2 sigma ``x``, edge strictness ``e``) on the gate's harness (module doc,
    "Confirmation"); ``curve`` holds the reduced harness's probes by (x, e), ``run_reduced(x, e)``
    probes there, ``dry(x, e)`` is the memory of a cook without rendering it. While the gate misses
    the target: the moves that cost less memory than the anchor (the default cook's knobs, or the
    choice's where it is stricter) and not the same as the choice -- toward the anchor as far as
    the model needs, and one step stricter on the edges -- cheaper first, then the anchor, then (only when the anchor is stricter
    than the default) steps stricter on both knobs; after a pass on the k_f line, the point the
    gate's own secant (failed choice, pass) predicts; at most ``CONFIRM_STEPS`` probes on the gate
    in all. The passing probe with the least memory is kept. ``confirm_levels``: the levels of
    ``levels`` rendered on the gate (None: all; ``calibrate`` passes those of ``CONFIRM_LEVELS``);
    ``prepared`` as in ``probe``."""
    views, resolution = confirm
    clevels = [b for b in levels if confirm_levels is None or b in set(int(v) for v in confirm_levels)] or list(levels)
    at = [levels.index(b) for b in clevels]  # the gate's levels among the reduced harness's
    out = {"views": views if isinstance(views, int) else list(views),
           "resolution": [int(resolution[0]), int(resolution[1])], "passed": False, "probes": []}
    probed: dict = {}
    # the float renders are cached (cropped to the object's box, capped): a second probe renders CAP only
    with shared_harness(scene, resolution) as h:
        def run(c):
            if c not in probed:
                p = probe(scene, settings, 2.0**c[0], h, levels=clevels, views=views, viewing=viewing,
                          options=options, ingest_options=ingest_options, edge_scale=c[1],
                          stop_below=(target_psnr, statistic), prepared=prepared, clusters=clusters)
                p["confirm"] = True
                probed[c] = p
                out["probes"].append(p)
                if progress is not None:
                    progress(p)
            return probed[c]

        def ok(c) -> bool:
            return _passes(run(c), target_psnr, statistic)

        def snap_x(v: float) -> float:  # whole tolerance steps above x, at most hi
            return min(hi, x + tolerance * math.ceil((v - x) / tolerance - 1e-9)) if v > x else x

        c0 = (x, e)
        if not ok(c0):
            anchor = (snap_x(max(x, 0.0)), max(e, 0.0) if edges else e)
            moves = []
            if anchor != c0:
                # per level: how much the gate misses what the reduced harness saw at the choice, and
                # how far toward the anchor the reduced harness's PSNR rises by that much
                red0 = [_level_psnrs(curve[c0], statistic)[i] for i in at]
                red1 = [_level_psnrs(run_reduced(*anchor), statistic)[i] for i in at]
                gate0 = _level_psnrs(run(c0), statistic)
                t = 0.0
                for r0, r1, g0 in zip(red0, red1, gate0):
                    if g0 >= target_psnr + CONFIRM_MARGIN_DB:
                        continue
                    gain = r1 - r0
                    t = max(t, 1.0 if gain <= 0 else (target_psnr + CONFIRM_MARGIN_DB - g0) / gain)
                t = min(1.0, t)
                mid = (snap_x(x + t * (anchor[0] - x)), e + math.ceil(t * (anchor[1] - e) - 1e-9))
                moves.append(mid)
            if edges and e + 1.0 <= EDGE_RANGE:  # coverage along edges does not depend on k_f
                moves.append((x, e + 1.0))
            # the cheaper move first (memory is known without rendering), only moves cheaper than the
            # anchor, then the anchor
            # (a move whose memory equals the choice's changes no bit that matters: skipped)
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
            for m in moves[:CONFIRM_STEPS - 1]:
                if ok(m):
                    # a pass on the k_f line: the gate's own secant between the failed choice and
                    # the pass may find less memory that passes (one more probe, if the budget has it)
                    if m[1] == e and m[0] > x and len(probed) < CONFIRM_STEPS:
                        g0, g1 = _level_psnrs(probed[c0], statistic), _level_psnrs(probed[m], statistic)
                        n = min(len(g0), len(g1))
                        guess = _predict([(x, g0[:n]), (m[0], g1[:n])], [target_psnr + CONFIRM_MARGIN_DB] * n)
                        between = (snap_x(guess), e)
                        if x < between[0] < m[0]:
                            ok(between)
                    break
        passing = [c for c in probed if _passes(probed[c], target_psnr, statistic)]
        chosen = min(passing, key=lambda c: (sum(probed[c]["cap_percent"]), c)) if passing else None
        out["passed"] = chosen is not None
        out["chosen"] = probed[chosen] if chosen is not None else max(
            probed.values(), key=lambda p: min(_level_psnrs(p, statistic)))
        out["chosen_knobs"] = chosen
    return out


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
    ``watch_db`` (None: every probe renders every level; a number: the direct search of the module
    doc, "Watched levels", with the anchor's margin ``watch_db`` dB; give the gate's harness as
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
    viewing = viewing or Viewing()
    levels = [int(b) for b in levels]
    t0 = time.perf_counter()
    probes: dict = {}
    dry_cache: dict = {}
    targets = [float(target_psnr) + MODEL_MARGIN_DB] * len(levels)
    start = min(hi, max(lo, 0.0))  # the default cook's k_f
    from ..analyse.prepared import shared

    prepared = shared(scene, settings)  # what no probe changes, computed once (and kept for the attribute search)
    direct = watch_db is not None
    watch: list | None = None  # the watched levels, in render order (direct search)
    with shared_harness(scene, resolution) as h:
        def order() -> list:
            return list(watch) + [b for b in levels if b not in watch]

        def settled(p: dict) -> bool:
            """Whether a direct probe's verdict holds for the watched levels: it failed on a level it
            rendered, or it rendered every watched level."""
            return not _passes(p, target_psnr, statistic) or set(watch) <= set(p["levels"])

        def run(x: float, e: float = 0.0) -> dict:
            if (x, e) not in probes or (direct and not settled(probes[(x, e)])):
                extra = {}
                if direct:  # the watched levels first (least margin first), up to the first that fails
                    extra = dict(levels=order(), stop_below=(float(target_psnr), statistic), watch=len(watch))
                p = probe(scene, settings, 2.0**x, h, **{"levels": levels, **extra}, views=views, viewing=viewing,
                          options=options, ingest_options=ingest_options, edge_scale=e, prepared=prepared,
                          clusters=clusters)
                probes[(x, e)] = p
                if progress is not None:
                    progress(p)
            return probes[(x, e)]

        def ok(x: float, e: float = 0.0) -> bool:
            return _passes(run(x, e), target_psnr, statistic)

        def passes(p: dict) -> bool:
            return _passes(p, target_psnr, statistic)

        def psnrs(p: dict) -> list:
            return _level_psnrs(p, statistic, levels if direct else None)

        def kf_search(e: float, a: float, x_start: float, give_up=None):
            return model_search(lambda t: run(t, e), passes, a, hi, tolerance, x_start, psnrs, targets, give_up)

        def memory(c) -> float:
            return sum(run(*c)["cap_percent"]) / len(levels)

        def dry(x: float, e: float) -> float:  # the memory of a probe, without rendering it
            if (x, e) in probes:
                return memory((x, e))
            return cap_memory(scene, settings, x, e, levels, dry_cache, prepared=prepared, clusters=clusters)

        def least_passing(f, a: float, b: float):
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

        def choose():
            """(reached, x, e) of one search over the knobs (module doc, steps 1-2c)."""
            # (1) k_f at the given edge_eps
            e = 0.0
            x = kf_search(e, lo, start)
            candidates = [] if x is None else [(x, e)]
            if search == "kf+edge" and settings.edges:
                loosest = float(-math.floor(math.log2(1.0 / float(settings.edge_eps))))
                if x is not None and loosest < 0 and loosen_edges:
                    # (2a) loosen the edges while the target holds at the chosen k_f
                    e1 = least_passing(lambda t: ok(x, t), loosest, 0.0)
                    candidates.append((x, e1))
                    if e1 > loosest:  # (2c) the loosest edges, paid for with more k_f, while that can cost less
                        best = min(memory(c) for c in candidates)
                        if memory((x, loosest)) < best:
                            guess = _predict([(x, psnrs(run(x, loosest)))], targets)
                            guess = x + tolerance * max(1, math.ceil((guess - x) / tolerance - 1e-9))
                            x1 = model_search(lambda t: run(t, loosest), passes, x, hi, tolerance, guess,
                                              psnrs, targets, reach_check=False, max_probes=EDGE_KF_PROBES,
                                              give_up=lambda p: sum(p["cap_percent"]) / len(levels) >= best,
                                              before=lambda t: dry(t, loosest) >= best)
                            if x1 is not None:
                                candidates.append((x1, loosest))
                elif x is None:  # (2b) stricter edges at the largest k_f, then k_f again
                    e_found = least_passing(lambda t: ok(hi, t), 1.0, float(EDGE_RANGE))
                    if e_found is not None:
                        e = e_found
                        x = kf_search(e, lo, hi)
                        candidates = [(x, e)]
            # only candidates whose verdict holds for the watched levels (a direct search's watch may
            # have grown since one was found)
            candidates = [c for c in candidates if ok(*c)]
            if candidates:  # the least position memory, averaged over the levels (ties: less k_f)
                x, e = min(candidates, key=lambda c: (memory(c), c[0]))
                return True, x, e
            return False, hi, e

        if direct:
            # the anchor (the default cook), levels ascending until the PSNR has climbed clear of its
            # least (``scout_rule``): its margins name the watched levels
            anchor = probe(scene, settings, 2.0**start, h, levels=sorted(levels), views=views, viewing=viewing,
                           options=options, ingest_options=ingest_options, prepared=prepared,
                           stop=scout_rule(statistic, float(watch_db)), clusters=clusters)
            probes[(start, 0.0)] = anchor
            if progress is not None:
                progress(anchor)
            per = dict(zip(anchor["levels"], _level_psnrs(anchor, statistic)))
            least = min(per.values())
            watch = sorted((b for b in per if per[b] < least + float(watch_db)), key=lambda b: (per[b], b))
        whole = False
        for _ in range(len(levels) + 1):
            reached, x, e = choose()
            chosen = run(x, e)
            if not (direct and complete and reached):
                break
            if set(chosen["levels"]) < set(levels):  # the choice at every level, the watched ones first
                chosen = probe(scene, settings, 2.0**x, h, levels=order(), views=views, viewing=viewing,
                               options=options, ingest_options=ingest_options, edge_scale=e, prepared=prepared,
                               stop_below=(float(target_psnr), statistic), clusters=clusters)
                probes[(x, e)] = chosen
                if progress is not None:
                    progress(chosen)
            if passes(chosen):
                whole = True
                break
            # it missed a level nobody watched: watch it too, and search again
            missed = chosen["levels"][-1]
            if missed in watch:
                break
            watch.append(missed)
        confirmation = None
        same = confirm is not None and _same_harness(confirm, views, resolution)
        if reached and confirm is not None and not same and not direct:
            confirmation = _confirm(scene, settings, x, e, probes, hi, tolerance, target_psnr, statistic, confirm,
                                    edges=search == "kf+edge" and bool(settings.edges), levels=levels,
                                    viewing=viewing, options=options, ingest_options=ingest_options,
                                    progress=progress, run_reduced=run, dry=dry, prepared=prepared,
                                    confirm_levels=confirm_levels, clusters=clusters)
            reached = confirmation["passed"]
            chosen = confirmation.pop("chosen")
            confirmation.pop("chosen_knobs")
        if direct and complete:
            reached = reached and whole
    curve = [probes[k] for k in sorted(probes)]  # by sigma, then edge strictness
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
        "levels": levels,
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
