"""k_f calibration: the least position memory whose CAP renders reach a target PSNR.

This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
sections 5.1 (the minimum level of a vertex: the smallest b with k_f * E_v * dx(b) <= eps) and 7
("For CAP we empirically choose k_f to avoid shading artifacts"). Here k_f is measured instead:
every probe cooks the scene and renders its CAP buffers against the float source with the
harness of ``lopcook.verify.render`` (Purnomo et al. 2005, section 4.1: views on an icosahedron,
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
nearly always does too. The search: probe sigma = 2^lo and 2^hi (defaults 2^-8 and 2^8); if 2^lo
already passes it is chosen, if 2^hi fails the target is unreachable (``reached`` False: the coverage
error of vertices whose attributes do not vary, e.g. flat faces, does not depend on k_f); otherwise
bisect on log2 sigma until the bracket is ``tolerance`` wide (default 0.25: sigma within 19%) and
choose the passing end. A probe passes when, at every level, the CAP PSNR statistic is >= the
target: ``statistic="min"`` (default) the minimum over views (every view must reach it; a view
identical to the float render counts as infinite), ``"mean"`` the PSNR of the view-averaged MSE
(Purnomo et al. average the per-view errors; one view with few object pixels weighs less). The
chosen sigma passed when probed; if the PSNR is not monotonic in sigma somewhere inside the bracket,
a smaller passing sigma may exist (the curve shows it).

Cost and the reduced harness. Each probe = analyse + build + CAP renders at every level and view
(AP is not rendered; float renders are computed once and reused, they do not depend on sigma).
Defaults for speed: ``CAL_VIEWS`` = 8 of the 20 views and ``CAL_RESOLUTION`` = 640 x 360. An object
covers the same pixels at level B whatever the resolution (``lopcook.verify.render``), so a smaller
viewport crops close-ups instead of shrinking the object; fewer views sample the sphere of
directions more coarsely. Check the chosen k_f with ``lopcook verify OUT.lop --source SOURCE`` at
the full 20 views and 1280 x 720.

Measured (``benchmarks/bench_verify_corpus.py``, target 40 dB, levels 6-11, llvmpipe on 2 cores):
8 probes take 8-25 s for the bunny, DamagedHelmet and CesiumMilkTruck and about 3 minutes for the
chess set (774k vertices). Where the target is unreachable (fandisk, and the chess set on the min
over views), the residual CAP error at low levels is silhouette coverage of vertices whose
attributes are constant (E_v = 0), which the half-pixel criterion allows and k_f cannot change.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

from ..errors import EXIT_VERIFY_FAILED, LopcookError
from ..settings import DEFAULT_ANALYSE, AnalyseSettings
from ..viewing import Viewing
from .render import DEFAULT_LEVELS, Harness

CAL_VIEWS = 8
CAL_RESOLUTION = (640, 360)
LOG2_RANGE = (-8.0, 8.0)
TOLERANCE = 0.25
STATISTICS = ("min", "mean")


def _kf_dict(scene, settings: AnalyseSettings, sigma: float) -> dict:
    """sigma times the k_f the analysis uses per attribute present in the scene (max over parts)."""
    from ..analyse import _kf_for

    out: dict = {}
    for part in scene.parts:
        for name, kf in _kf_for(part, settings).items():
            out[name] = max(out.get(name, 0.0), float(kf) * sigma)
    return out


def probe(scene, settings: AnalyseSettings, sigma: float, harness: Harness, *, levels, views,
          viewing: Viewing, options: dict | None = None, ingest_options: dict | None = None) -> dict:
    """Cook ``scene`` with every k_f scaled by ``sigma`` and render its CAP buffers.

    Returns ``{"sigma", "log2_sigma", "eps", "kf", "kf_normal", "psnr_min" (min over levels of the
    min over views, dB; None = identical), "psnr_mean" (min over levels of the PSNR of the
    view-averaged MSE), "psnr_min_per_level", "psnr_mean_per_level" [per level], "cap_percent",
    "cap_bytes" [per level], "depth_order_errors" (summed), "seconds"}``."""
    from ..analyse import analyse
    from ..analyse.summary import _settings_dict
    from ..emit import build
    from ..emit.container import from_bytes

    t0 = time.perf_counter()
    s = replace(settings, eps=settings.eps / float(sigma))
    analysis = analyse(scene, s)
    opts = dict(options or {})
    opts["analyse"] = _settings_dict(s)
    if ingest_options is not None:
        opts["ingest"] = ingest_options
    c = from_bytes(build(scene, analysis, options=opts, viewing=viewing), None)
    res = harness.evaluate(c, levels=levels, views=views, variants=("cap",))
    per_level = [r["cap"]["psnr_min"] for r in res["levels"]]
    per_level_mean = [r["cap"]["psnr_mean"] for r in res["levels"]]
    finite = [p for p in per_level if p is not None]
    finite_mean = [p for p in per_level_mean if p is not None]
    kf = _kf_dict(scene, settings, sigma)
    return {
        "sigma": float(sigma),
        "log2_sigma": math.log2(sigma),
        "eps": float(s.eps),
        "kf": kf,
        "kf_normal": kf.get("normal"),
        "psnr_min": min(finite) if finite else None,
        "psnr_mean": min(finite_mean) if finite_mean else None,
        "psnr_min_per_level": per_level,
        "psnr_mean_per_level": per_level_mean,
        "cap_percent": [r["cap"]["percent_of_float32"] for r in res["levels"]],
        "cap_bytes": [r["cap"]["bytes"] for r in res["levels"]],
        "depth_order_errors": int(sum(r["cap"]["depth_order_errors"] for r in res["levels"])),
        "seconds": round(time.perf_counter() - t0, 3),
    }


def _passes(p: dict, target: float, statistic: str = "min") -> bool:
    v = p[f"psnr_{statistic}"]
    return v is None or v >= target


def calibrate(scene, settings: AnalyseSettings = DEFAULT_ANALYSE, *, target_psnr: float,
              levels=DEFAULT_LEVELS, views=CAL_VIEWS, resolution=CAL_RESOLUTION, viewing: Viewing | None = None,
              log2_range=LOG2_RANGE, tolerance: float = TOLERANCE, options: dict | None = None,
              ingest_options: dict | None = None, progress=None, statistic: str = "min") -> dict:
    """Search the smallest k_f scale sigma whose CAP renders reach ``target_psnr`` dB (module doc).

    Parameters: ``scene`` (the ingested source), ``settings`` (the analysis settings to scale),
    ``target_psnr`` dB, ``levels`` (per-buffer levels, default 6..12), ``views`` (int or indices),
    ``resolution`` (w, h), ``viewing`` (recorded in each probe container: its field of view and pixel
    error set the camera distances), ``log2_range`` (lo, hi) of log2 sigma, ``tolerance`` (bracket
    width in log2 sigma), ``options``/``ingest_options`` (recorded in the probe containers),
    ``progress(probe_dict)`` called after each probe, ``statistic`` ("min" or "mean" over views).

    Returns a JSON-ready dict: ``target_psnr``, ``statistic``, ``reached`` (bool), ``sigma`` / ``log2_sigma`` /
    ``eps`` / ``kf`` / ``kf_normal`` of the choice (the passing probe with the least sigma; the
    largest probed sigma when unreachable), ``chosen`` (that probe), ``curve`` (every probe, sorted by
    sigma: sigma, eps, kf, psnr_min, psnr_min_per_level, cap_percent per level, ...), ``levels``,
    ``views``, ``resolution``, ``base_eps``, ``seconds``.
    """
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
    with Harness(scene, resolution, cache_float=True) as h:
        def run(x: float) -> dict:
            if x not in probes:
                p = probe(scene, settings, 2.0**x, h, levels=levels, views=views, viewing=viewing, options=options,
                          ingest_options=ingest_options)
                probes[x] = p
                if progress is not None:
                    progress(p)
            return probes[x]

        if _passes(run(lo), target_psnr, statistic):
            chosen, reached = run(lo), True
        elif not _passes(run(hi), target_psnr, statistic):
            chosen, reached = run(hi), False
        else:
            a, b = lo, hi  # a fails, b passes
            while b - a > tolerance:
                m = 0.5 * (a + b)
                if _passes(run(m), target_psnr, statistic):
                    b = m
                else:
                    a = m
            chosen, reached = run(b), True
    curve = [probes[x] for x in sorted(probes)]
    return {
        "target_psnr": float(target_psnr),
        "statistic": statistic,
        "reached": bool(reached),
        "sigma": chosen["sigma"],
        "log2_sigma": chosen["log2_sigma"],
        "eps": chosen["eps"],
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
        "seconds": round(time.perf_counter() - t0, 3),
    }


def calibrated_settings(settings: AnalyseSettings, result: dict) -> AnalyseSettings:
    """The analysis settings of the calibration's choice (eps divided by the chosen sigma)."""
    return replace(settings, eps=float(result["eps"]))


def require_reached(result: dict, path: str | None = None) -> None:
    """Raise LopcookError (exit 1) when the calibration did not reach its target."""
    if not result["reached"]:
        key = f"psnr_{result.get('statistic', 'min')}"
        best = max((p for p in result["curve"] if p[key] is not None), key=lambda p: p[key], default=None)
        got = "" if best is None else (f": the best CAP PSNR ({result.get('statistic', 'min')} over views, worst "
                                       f"level) was {best[key]:.1f} dB, at k_f scale 2^{best['log2_sigma']:g}")
        raise LopcookError("verify", path, f"no k_f reaches {result['target_psnr']:g} dB{got}",
                           hint="lower --target-psnr; the coverage error of flat regions does not depend on k_f",
                           exit_code=EXIT_VERIFY_FAILED)


def format_calibration(result: dict) -> str:
    """Text table of the curve: sigma, k_f (normal), eps, CAP memory % per level, min PSNR."""
    lines = [f"k_f calibration: target {result['target_psnr']:g} dB ({result['statistic']} over {result['views']} "
             f"views, every level {result['levels'][0]}-{result['levels'][-1]}, "
             f"{result['resolution'][0]}x{result['resolution'][1]})",
             "  log2 sigma   k_f normal   eps          CAP mem % per level            PSNR min / mean (worst level)"]
    for p in result["curve"]:
        kfn = "-" if p["kf_normal"] is None else f"{p['kf_normal']:.4g}"
        mem = " ".join(f"{v:4.1f}" for v in p["cap_percent"])
        ps = "inf" if p["psnr_min"] is None else f"{p['psnr_min']:.1f}"
        pm = "inf" if p["psnr_mean"] is None else f"{p['psnr_mean']:.1f}"
        mark = " <-" if p["sigma"] == result["sigma"] else ""
        lines.append(f"  {p['log2_sigma']:>10.3f}   {kfn:>10}   {p['eps']:.4e}   {mem:<30} {ps:>6} / {pm:<6}{mark}")
    verdict = "reached" if result["reached"] else "NOT reached"
    kfn = "-" if result["kf_normal"] is None else f"{result['kf_normal']:.4g}"
    lines.append(f"  {verdict}: sigma {result['sigma']:.4g} (k_f normal {kfn}), eps "
                 f"{result['eps']:.4e}; {len(result['curve'])} probes, {result['seconds']:.1f} s")
    return "\n".join(lines)


__all__ = ["CAL_VIEWS", "CAL_RESOLUTION", "LOG2_RANGE", "TOLERANCE", "probe", "calibrate", "calibrated_settings",
           "require_reached", "format_calibration"]
