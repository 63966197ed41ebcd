"""Speed against accuracy of the two LOD backends (issue 7, item 2): time vs Hausdorff and vs image PSNR.

Not a test (pytest does not collect benchmarks/). Usage::

    .venv/bin/python benchmarks/bench_lod.py [--assets NAME ...] [--chess] [--no-big] [--no-render]
        [--backends pymeshlab fast] [--ratios 1/2,1/4,1/8,1/16] [--views 20] [--resolution 640x360]
        [--repeat 1] [--out bench-out/lod]

For each asset (default: bunny, fandisk, spot, DamagedHelmet, CesiumMilkTruck, Duck, UtahTeapot; the
chess set with ``--chess``, it takes minutes) and the ~1M-triangle mesh (the bunny subdivided twice,
``bench_ingest.make_big``; ``--no-big`` skips it), and for each backend, every part gets a chain
``lopcook.simplify.chain.lod_chain(part, ratios, backend, max_error_m=None)`` with the default seam mode
(``"lock"``) and chaining (``"previous"``). The scene's LOD k is every part's LOD k (a part whose chain
stopped early contributes its last LOD; counted in ``parts_short``). Per scene LOD:

* ``seconds``: wall time of that LOD summed over parts (``Lod.seconds``: simplification, attribute
  transfer and error measurement; best of ``--repeat`` runs); ``cpu_seconds_chain``: CPU time
  (``resource.getrusage``, user + system) of the whole chain of all parts, per backend;
* ``triangles`` vs ``target_triangles`` (sums over parts of ``round(ratio * n0)``),
  ``parts_within_5pct`` / ``parts_simplifiable`` (parts of at least 4 triangles whose LOD is within
  +-5 % of its target);
* ``hausdorff_m``: the largest part's measured symmetric Hausdorff distance to LOD 0 (``Lod.hausdorff_m``),
  ``hausdorff_rel``: that over the scene's bounding-box diagonal; ``error_m``: the monotone envelope;
  ``hausdorff_monotone``: whether every part's *measured* distance is non-decreasing along its chain;
* UV seams: ``seam_edges`` / ``seam_vertices`` / ``uv_islands`` summed over parts with UVs, and
  ``seams_equal``: every part's ``SeamStats`` equals its LOD 0's;
* ``fallbacks``: notes saying a backend failed and the other one was tried; ``notes``: all LOD notes;
* image PSNR of the LOD against the float source (``lopcook.verify.metrics.image_metrics``, PSNR over
  object pixels, background in both excluded): both scenes are rendered with float positions by two
  ``lopcook.verify.renderer.Harness`` objects (Phong, ``Shading()`` defaults: ks 0.5, n 32; source
  normals/UVs/textures for the source, the LOD's carried attributes for the LOD) from the same
  ``--views`` icosahedron cameras (``make_camera`` on the **source** bounding box), at two distances
  (camera to the nearest bounding-box point, metres):

  - ``near``: half the box diagonal r. With the 60 degree field of view the eye is then about 2r from
    the centre, where the bounding sphere just fills the frame height: the closest useful view.
  - ``select``: the distance from which ``lopcook.selection`` starts to pick this LOD,
    ``lod_threshold_m(error_m, viewing)`` with the default viewing (60 degrees, half a pixel) and the
    render resolution as viewport, using the scene LOD's largest ``error_m``: the LOD's error
    projects to half a pixel of the rendered image there. LOD 0 (error 0) is not rendered.

  ``psnr_min`` is the minimum over views, ``psnr_mean`` the PSNR of the view-averaged MSE, ``None``
  when identical (infinite).

Writes ``OUT/lod.json`` (everything), ``OUT/lod.csv`` (one row per asset, backend and LOD),
``OUT/table.md``, and the charts ``OUT/time_vs_hausdorff.png`` and ``OUT/time_vs_psnr.png`` (one panel
per asset, one marker per backend per LOD, labelled with the LOD index). Numbers depend on the machine
(2 shared cores, llvmpipe): take the best of several runs (``--repeat``) when comparing times.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import resource
import sys
import time
from dataclasses import replace
from fractions import Fraction
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

from lopcook.simplify.chain import MIN_SIMPLIFY_TRIANGLES, TARGET_TOLERANCE, lod_chain  # noqa: E402
from lopcook.ingest import load  # noqa: E402
from lopcook.selection import lod_threshold_m  # noqa: E402
from lopcook.settings import DEFAULT_INGEST  # noqa: E402
from lopcook.viewing import Viewing  # noqa: E402

ASSETS = ["stanford-bunny.obj", "fandisk.obj", "spot.obj", "DamagedHelmet/DamagedHelmet.gltf", "CesiumMilkTruck.glb",
          "Duck.glb", "UtahTeapot.usd"]
CHESS = "chess_set_flat.usdc"
BACKENDS = ("pymeshlab", "fast")
COLOURS = {"pymeshlab": "#1f77b4", "fast": "#d62728"}


def _cpu() -> float:
    """User + system CPU seconds of this process and of its reaped children (large simplifications
    run in forked children, ``lopcook.isolate``)."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    c = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime + c.ru_utime + c.ru_stime


def _wh(text: str) -> tuple[int, int]:
    w, h = (int(v) for v in text.lower().split("x"))
    return w, h


def _fmt(v, spec=".1f") -> str:
    return "inf" if v is None else format(v, spec)


# ---- chains -------------------------------------------------------------------------------------------

def build_chains(scene, backend: str, ratios: list[float], repeat: int):
    """Per part: (lods, report) of ``lod_chain``; per-LOD seconds are the best of ``repeat`` runs.
    Returns (chains, cpu seconds of one run of all chains (best), wall seconds (best))."""
    best = None
    cpu_best = wall_best = math.inf
    for _ in range(max(1, repeat)):
        c0, w0 = _cpu(), time.perf_counter()
        chains = [lod_chain(p, ratios=ratios, backend=backend, max_error_m=None) for p in scene.parts]
        cpu_best = min(cpu_best, _cpu() - c0)
        wall_best = min(wall_best, time.perf_counter() - w0)
        if best is None:
            best = chains
        else:  # results are deterministic; keep the fastest time per LOD
            for (lods_a, _), (lods_b, _) in zip(best, chains):
                for a, b in zip(lods_a, lods_b):
                    a.seconds = min(a.seconds, b.seconds)
    return best, cpu_best, wall_best


def _seams(lods, k):
    s = [lods[min(k, len(lods) - 1)].seam_stats for lods in lods]
    s = [x for x in s if x is not None]
    if not s:
        return None
    return {"seam_edges": sum(x.seam_edges for x in s), "seam_vertices": sum(x.seam_vertices for x in s),
            "uv_islands": sum(x.uv_islands for x in s)}


def lod_rows(scene, chains, ratios) -> list[dict]:
    """One dict per scene LOD (0 = source) from per-part chains (see module doc)."""
    lo, hi = scene.bounds()
    diag = float(np.linalg.norm(hi - lo))
    all_lods = [lods for lods, _ in chains]
    depth = 1 + len(ratios)
    rows = []
    for k in range(depth):
        ratio = 1.0 if k == 0 else ratios[k - 1]
        picked = [lods[min(k, len(lods) - 1)] for lods in all_lods]
        short = sum(1 for lods in all_lods if len(lods) <= k)
        target = sum(int(round(ratio * p.n_triangles)) for p in scene.parts)
        simplifiable = [i for i, p in enumerate(scene.parts)
                        if int(round(ratio * p.n_triangles)) >= MIN_SIMPLIFY_TRIANGLES]
        within = sum(1 for i in simplifiable if len(all_lods[i]) > k and abs(
            all_lods[i][k].triangles - all_lods[i][k].target_triangles) <= TARGET_TOLERANCE * all_lods[i][k].target_triangles)
        h = max(lod.hausdorff_m for lod in picked)
        e = max(lod.error_m for lod in picked)
        notes = [f"{scene.parts[i].name}: {n}" for i, lods in enumerate(all_lods) if len(lods) > k
                 for n in lods[k].notes]
        seams0, seams = _seams(all_lods, 0), _seams(all_lods, k)
        seams_equal = all(lods[min(k, len(lods) - 1)].seam_stats == lods[0].seam_stats for lods in all_lods)
        rows.append({
            "lod": k, "ratio": ratio, "target_triangles": target,
            "triangles": sum(lod.triangles for lod in picked),
            "vertices": sum(lod.part.n_vertices for lod in picked),
            "triangles_vs_target": (sum(lod.triangles for lod in picked) - target) / target if target else 0.0,
            "parts_within_5pct": within if k else len(scene.parts),
            "parts_simplifiable": len(simplifiable) if k else len(scene.parts),
            "parts_short": short,
            "seconds": sum(lod.seconds for lods in all_lods if len(lods) > k for lod in [lods[k]]),
            "hausdorff_m": h, "hausdorff_rel": h / diag if diag > 0 else 0.0, "error_m": e,
            "backends_used": sorted({lod.backend for lod in picked}),
            "fallbacks": sum(1 for n in notes if "falling back" in n),
            "failed_parts": sum(1 for lod in picked if lod.failed),
            "seams": seams, "seams_lod0": seams0, "seams_equal": bool(seams_equal),
            "notes": notes,
        })
    mono = all(all(b.hausdorff_m >= a.hausdorff_m for a, b in zip(lods, lods[1:])) for lods in all_lods)
    mono_env = all(all(b.error_m >= a.error_m for a, b in zip(lods, lods[1:])) for lods in all_lods)
    for r in rows:
        r["hausdorff_monotone"] = bool(mono)
        r["error_monotone"] = bool(mono_env)
    return rows


# ---- images -------------------------------------------------------------------------------------------

class Images:
    """Float renders of the source scene (near-distance views cached) against LOD scenes."""

    def __init__(self, scene, views: int, resolution):
        from lopcook.verify.cameras import select_views
        from lopcook.verify.renderer import Harness, Shading

        self.scene = scene
        self.resolution = resolution
        self.views = select_views(views)
        self.viewing = Viewing(viewport=resolution)
        self.shading = Shading()
        self.src = Harness(scene, resolution, cache_float=True)
        lo, hi = scene.bounds()
        self.lo, self.hi = lo, hi
        self.near_m = 0.5 * float(np.linalg.norm(hi - lo))

    def release(self):
        self.src.release()

    def compare(self, lod_scene, distances: dict) -> dict:
        """{name: {"distance_m", "psnr_min", "psnr_mean", "object_pixels_mean"}} per distance."""
        from lopcook.verify import metrics as M
        from lopcook.verify.cameras import make_camera
        from lopcook.verify.renderer import Harness

        out = {}
        with Harness(lod_scene, self.resolution) as h:
            for name, d in distances.items():
                if d is None or not d > 0:
                    out[name] = None
                    continue
                per = []
                for v in self.views:
                    cam = make_camera(v, self.lo, self.hi, d, self.viewing)
                    key = ("near", v) if name == "near" else None
                    ref, _ = self.src.render_float(cam, self.shading, key=key)
                    tst, _ = h.render_float(cam, self.shading)
                    per.append(M.image_metrics(ref, tst))
                finite = [m["psnr"] for m in per if m["psnr"] is not None]
                out[name] = {"distance_m": float(d), "psnr_min": min(finite) if finite else None,
                             "psnr_mean": M.mean_mse_psnr([m["mse"] for m in per]),
                             "psnr_views": [m["psnr"] for m in per],
                             "object_pixels_mean": float(np.mean([m["object_pixels"] for m in per]))}
        return out


# ---- one asset ----------------------------------------------------------------------------------------

def run_asset(name: str, path: Path, args, ratios) -> list[dict]:
    t0 = time.perf_counter()
    scene = load(str(path), DEFAULT_INGEST)
    print(f"== {name}: {len(scene.parts)} parts, {scene.n_triangles:,} triangles, {scene.n_vertices:,} vertices "
          f"(ingest {time.perf_counter() - t0:.1f} s)", flush=True)
    images = None if args.no_render else Images(scene, args.views, _wh(args.resolution))
    rows = []
    try:
        for backend in args.backends:
            chains, cpu, wall = build_chains(scene, backend, ratios, args.repeat)
            for r in lod_rows(scene, chains, ratios):
                r.update(asset=name, backend=backend, cpu_seconds_chain=cpu, wall_seconds_chain=wall,
                         source_triangles=scene.n_triangles, parts=len(scene.parts))
                r["psnr"] = None
                if images is not None and r["lod"] > 0 and r["parts_short"] < len(scene.parts):
                    k = r["lod"]
                    lod_scene = replace(scene, parts=tuple(lods[min(k, len(lods) - 1)].part for lods, _ in chains))
                    sel = lod_threshold_m(r["error_m"], images.viewing)
                    r["psnr"] = images.compare(lod_scene, {"near": images.near_m, "select": sel})
                rows.append(r)
                p = r["psnr"] or {}
                near, sel = p.get("near") or {}, p.get("select") or {}
                print(f"  {backend:<9} LOD {r['lod']} {r['triangles']:>9,}/{r['target_triangles']:<9,} t "
                      f"{r['triangles_vs_target']:+6.1%} {r['seconds']:7.2f} s  H {r['hausdorff_m']:.3g} m "
                      f"({r['hausdorff_rel']:.2e} diag)  PSNR near {_fmt(near.get('psnr_mean'))} "
                      f"select {_fmt(sel.get('psnr_mean'))} dB @ {sel.get('distance_m', 0):.3g} m  "
                      f"seams {'=' if r['seams_equal'] else '!='} fb {r['fallbacks']}", flush=True)
            print(f"  {backend}: chain CPU {cpu:.2f} s, wall {wall:.2f} s", flush=True)
    finally:
        if images is not None:
            images.release()
    return rows


# ---- outputs ------------------------------------------------------------------------------------------

CSV_KEYS = ["asset", "backend", "lod", "ratio", "target_triangles", "triangles", "triangles_vs_target",
            "parts_within_5pct", "parts_simplifiable", "seconds", "cpu_seconds_chain", "hausdorff_m", "hausdorff_rel",
            "error_m", "hausdorff_monotone", "seams_equal", "fallbacks", "failed_parts",
            "near_distance_m", "near_psnr_min", "near_psnr_mean", "select_distance_m", "select_psnr_min",
            "select_psnr_mean"]


def _flat(r: dict) -> dict:
    out = {k: r.get(k) for k in CSV_KEYS}
    for name in ("near", "select"):
        p = (r.get("psnr") or {}).get(name) or {}
        out[f"{name}_distance_m"] = p.get("distance_m")
        out[f"{name}_psnr_min"] = p.get("psnr_min")
        out[f"{name}_psnr_mean"] = p.get("psnr_mean")
    return out


def checks(rows: list[dict]) -> str:
    """Issue 7 "done when" checks per asset and backend: LODs within +-5 % of target (every
    simplifiable part), measured Hausdorff monotone along every part's chain, UV seams kept."""
    lines = ["| asset | backend | LODs built | LODs within +-5 % | Hausdorff monotone | UV seams kept (LOD 0 -> last) "
             "| chain CPU s |", "|---|---|---|---|---|---|---|"]
    for key in dict.fromkeys((r["asset"], r["backend"]) for r in rows):
        rs = [r for r in rows if (r["asset"], r["backend"]) == key and r["lod"] > 0]
        built = [r for r in rs if r["parts_short"] == 0]
        ok = [r for r in built if r["parts_within_5pct"] == r["parts_simplifiable"]]
        s0, s1 = (rs[0]["seams_lod0"], rs[-1]["seams"]) if rs else (None, None)
        seam = "no UVs" if s0 is None else (("yes" if all(r["seams_equal"] for r in rs) else "no")
                                            + f" ({s0['seam_edges']} -> {s1['seam_edges']} seam edges)")
        lines.append(f"| {key[0]} | {key[1]} | {len(built)} of {len(rs)} | {len(ok)} of {len(built)} | "
                     f"{'yes' if rs and rs[0]['hausdorff_monotone'] else 'no'} | {seam} | "
                     f"{rs[0]['cpu_seconds_chain'] if rs else 0:.2f} |")
    return "\n".join(lines)


def write_table(rows: list[dict]) -> str:
    lines = ["| asset | backend | LOD | triangles / target | time s | Hausdorff m (rel. diag) | PSNR near min/mean "
             "| PSNR select min/mean @ m | seams kept | fallbacks |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if r["lod"] == 0 or r["parts_short"] == r.get("parts", 0):
            continue
        p = r.get("psnr") or {}
        n, s = p.get("near") or {}, p.get("select") or {}
        lines.append(f"| {r['asset']} | {r['backend']} | {r['lod']} | {r['triangles']:,} / {r['target_triangles']:,} "
                     f"({r['triangles_vs_target']:+.1%}) | {r['seconds']:.2f} | {r['hausdorff_m']:.3g} "
                     f"({r['hausdorff_rel']:.2e}) | {_fmt(n.get('psnr_min'))} / {_fmt(n.get('psnr_mean'))} | "
                     f"{_fmt(s.get('psnr_min'))} / {_fmt(s.get('psnr_mean'))} @ {s.get('distance_m', 0):.3g} | "
                     f"{'yes' if r['seams_equal'] else 'no'} | {r['fallbacks']} |")
    return "\n".join(lines)


def charts(rows: list[dict], out: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    assets = list(dict.fromkeys(r["asset"] for r in rows))
    ncol = 3
    nrow = max(1, math.ceil(len(assets) / ncol))
    written = []
    for kind in ("hausdorff", "psnr"):
        fig, axes = plt.subplots(nrow, ncol, figsize=(5 * ncol, 3.8 * nrow), squeeze=False)
        for ax, asset in zip(axes.ravel(), assets):
            for backend in COLOURS:
                pts = [r for r in rows if r["asset"] == asset and r["backend"] == backend and r["lod"] > 0
                       and r["parts_short"] < (r.get("parts") or 1 << 30)]  # LODs no part has are left out
                if not pts:
                    continue
                c = COLOURS[backend]
                x = [max(r["seconds"], 1e-4) for r in pts]
                if kind == "hausdorff":
                    y = [max(r["hausdorff_rel"], 1e-9) for r in pts]
                    ax.plot(x, y, "o-", color=c, label=backend, ms=5, lw=1)
                    for xi, yi, r in zip(x, y, pts):
                        ax.annotate(str(r["lod"]), (xi, yi), textcoords="offset points", xytext=(4, 3), fontsize=8,
                                    color=c)
                else:
                    for dist, marker, fill in (("near", "o", c), ("select", "s", "none")):
                        xs, ys, labs = [], [], []
                        for xi, r in zip(x, pts):
                            p = ((r.get("psnr") or {}).get(dist) or {}).get("psnr_mean")
                            if p is not None:
                                xs.append(xi)
                                ys.append(p)
                                labs.append(str(r["lod"]))
                        ax.plot(xs, ys, marker=marker, ls="-" if dist == "near" else ":", color=c, mfc=fill, ms=5,
                                lw=1, label=f"{backend} ({dist})")
                        for xi, yi, lab in zip(xs, ys, labs):
                            ax.annotate(lab, (xi, yi), textcoords="offset points", xytext=(4, 3), fontsize=8,
                                        color=c)
            ax.set_xscale("log")
            if kind == "hausdorff":
                ax.set_yscale("log")
                ax.set_ylabel("Hausdorff / bbox diagonal")
            else:
                ax.set_ylabel("PSNR vs float source, dB (mean over views)")
            ax.set_xlabel("seconds per LOD (simplify + transfer + measure)")
            ax.set_title(asset, fontsize=10)
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=7)
        for ax in axes.ravel()[len(assets):]:
            ax.axis("off")
        fig.suptitle("LOD backends: time vs " + ("symmetric Hausdorff error" if kind == "hausdorff" else
                                                 "image PSNR (filled: near view, hollow: selection distance)")
                     + "; labels = LOD index (ratio 2^-k)")
        fig.tight_layout()
        path = out / f"time_vs_{kind}.png"
        fig.savefig(path, dpi=90)
        plt.close(fig)
        written.append(path)
    return written


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--corpus", default=os.environ.get("LOPCOOK_CORPUS", str(REPO.parent / "shared" / "corpus")))
    ap.add_argument("--assets", nargs="*", default=ASSETS)
    ap.add_argument("--chess", action="store_true", help=f"also {CHESS} (slow)")
    ap.add_argument("--no-big", action="store_true", help="skip the ~1M-triangle subdivided bunny")
    ap.add_argument("--no-render", action="store_true", help="skip the image PSNR")
    ap.add_argument("--backends", nargs="+", choices=BACKENDS, default=list(BACKENDS))
    ap.add_argument("--ratios", default="1/2,1/4,1/8,1/16")
    ap.add_argument("--views", type=int, default=20)
    ap.add_argument("--resolution", default="640x360")
    ap.add_argument("--repeat", type=int, default=1, help="chain runs per backend; best time per LOD")
    ap.add_argument("--out", default=str(REPO / "bench-out" / "lod"))
    ap.add_argument("--from-json", metavar="LOD.json", help="only rewrite the CSV, table and charts of a previous run")
    args = ap.parse_args()
    ratios = [float(Fraction(t)) for t in args.ratios.split(",")]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.from_json:
        return write_outputs(json.loads(Path(args.from_json).read_text())["rows"], out)
    todo = [(a, Path(args.corpus) / a) for a in args.assets] + ([(CHESS, Path(args.corpus) / CHESS)] if args.chess else [])
    if not args.no_big:
        from bench_ingest import make_big

        todo.append(("bunny_1M.obj (bunny subdivided twice)", make_big(out)[0]))
    rows: list[dict] = []
    t_all = time.perf_counter()
    for name, path in todo:
        rows += run_asset(name, path, args, ratios)
        (out / "lod.json").write_text(json.dumps({"args": vars(args), "rows": rows}, indent=1, sort_keys=True))
    write_outputs(rows, out)
    print(f"({time.perf_counter() - t_all:.0f} s)")
    return 0


def write_outputs(rows: list[dict], out: Path) -> int:
    n_parts = {r["asset"]: r["parts_simplifiable"] for r in rows if r["lod"] == 0}  # LOD 0 counts every part
    for r in rows:
        r.setdefault("parts", n_parts.get(r["asset"]))
    with open(out / "lod.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=CSV_KEYS)
        w.writeheader()
        for r in rows:
            w.writerow(_flat(r))
    text = write_table(rows) + "\n\n" + checks(rows)
    (out / "table.md").write_text(text + "\n")
    paths = charts(rows, out)
    print(text)
    print(f"wrote {out / 'lod.csv'}, {out / 'table.md'}, " + ", ".join(map(str, paths)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
