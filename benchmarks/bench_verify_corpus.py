"""Corpus render check with calibrated k_f: the Table-1 rows (Meyer et al. 2011) per asset.

Not a test (pytest does not collect benchmarks/). Usage::

    .venv/bin/python benchmarks/bench_verify_corpus.py [--assets NAME ...] [--target-psnr 40]
        [--statistic min mean] [--levels 6-11] [--cal-views 8] [--cal-resolution 640x360]
        [--views 20] [--resolution 1280x720] [--out bench-out/verify_corpus]

Per asset (default: bunny, fandisk, DamagedHelmet, CesiumMilkTruck, chess set):

1. ingest (default settings);
2. ``lopcook.verify.calibrate.calibrate``, once per ``--statistic`` (default both ``min``: every view
   must reach the target, and ``mean``: the PSNR of the view-averaged MSE must): the least k_f scale
   whose CAP renders reach the target PSNR at every level, with the reduced harness
   (``--cal-views``, ``--cal-resolution``);
3. for each distinct choice, cook with the chosen k_f (eps / sigma) and render float vs AP vs CAP with
   the full harness
   (``--views``, ``--resolution``; default 20 views at 1280 x 720) at ``--levels`` (default 6-11,
   the paper's Table 1);
4. rows: level, AP memory % of float32, AP PSNR (min / mean over views), CAP memory %, CAP PSNR,
   depth-order error pixels (AP / CAP), and the interior PSNR (pixels fully covered in both images:
   shading error without silhouette coverage); the calibrated k_f; seconds per stage.

Writes ``OUT/results.json`` (everything, images excluded) and ``OUT/table.md`` and prints the table.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from lopcook.analyse import analyse  # noqa: E402
from lopcook.analyse.summary import _settings_dict  # noqa: E402
from lopcook.emit import build  # noqa: E402
from lopcook.emit.container import from_bytes  # noqa: E402
from lopcook.ingest import load  # noqa: E402
from lopcook.settings import DEFAULT_ANALYSE, DEFAULT_INGEST  # noqa: E402
from lopcook.verify.calibrate import calibrate, format_calibration  # noqa: E402
from lopcook.verify.decoders import parse_levels  # noqa: E402
from lopcook.verify.render import evaluate, format_table  # noqa: E402
from lopcook.viewing import Viewing  # noqa: E402

ASSETS = ["stanford-bunny.obj", "fandisk.obj", "DamagedHelmet/DamagedHelmet.gltf", "CesiumMilkTruck.glb",
          "chess_set_flat.usdc"]


def _wh(text: str) -> tuple[int, int]:
    w, h = (int(v) for v in text.lower().split("x"))
    return w, h


def _psnr(v) -> str:
    return "inf" if v is None else f"{v:.1f}"


def run_asset(path: Path, args) -> list[dict]:
    levels = parse_levels(args.levels)
    t0 = time.perf_counter()
    scene = load(str(path), DEFAULT_INGEST)
    t_ingest = time.perf_counter() - t0
    viewing = Viewing()

    def progress(p):
        print(f"    probe log2 sigma {p['log2_sigma']:+.3f}: CAP min {_psnr(p['psnr_min'])} / mean "
              f"{_psnr(p['psnr_mean'])} dB, mem {min(p['cap_percent']):.1f}-{max(p['cap_percent']):.1f}% "
              f"({p['seconds']:.1f} s)", flush=True)

    out, rendered = [], {}
    for statistic in args.statistic:
        t0 = time.perf_counter()
        cal = calibrate(scene, DEFAULT_ANALYSE, target_psnr=args.target_psnr, levels=levels, views=args.cal_views,
                        resolution=_wh(args.cal_resolution), viewing=viewing,
                        ingest_options={"crease_angle_deg": DEFAULT_INGEST.crease_angle_deg}, progress=progress,
                        statistic=statistic)
        t_cal = time.perf_counter() - t0
        print(format_calibration(cal), flush=True)
        t_cook = t_eval = 0.0
        if cal["sigma"] not in rendered:
            t0 = time.perf_counter()
            settings = replace(DEFAULT_ANALYSE, eps=cal["eps"])
            data = build(scene, analyse(scene, settings), options={"analyse": _settings_dict(settings)},
                         viewing=viewing)
            c = from_bytes(data, path.name)
            t_cook = time.perf_counter() - t0
            t0 = time.perf_counter()
            rendered[cal["sigma"]] = evaluate(c, scene, levels=levels, views=args.views,
                                              resolution=_wh(args.resolution))
            t_eval = time.perf_counter() - t0
            print(format_table(rendered[cal["sigma"]]), flush=True)
        out.append({"asset": path.name, "statistic": statistic, "vertices": scene.n_vertices,
                    "triangles": scene.n_triangles, "parts": len(scene.parts),
                    "textured_parts": sum(p.texture is not None for p in scene.parts), "calibration": cal,
                    "render": rendered[cal["sigma"]],
                    "seconds": {"ingest": t_ingest, "calibrate": t_cal, "cook": t_cook, "evaluate": t_eval}})
    return out


def table(results: list[dict]) -> str:
    lines = []
    for r in results:
        cal = r["calibration"]
        kfn = "-" if cal["kf_normal"] is None else f"{cal['kf_normal']:.3g}"
        res = r["render"]
        lines += [f"### {r['asset']}  ({r['vertices']:,} vertices, {r['parts']} parts), calibrated on the "
                  f"{r['statistic']} over views",
                  "",
                  f"calibrated: k_f scale sigma = {cal['sigma']:.3g} (2^{cal['log2_sigma']:.2f}), k_f normal = {kfn}, "
                  f"eps = {cal['eps']:.3g}; target {cal['target_psnr']:g} dB "
                  f"{'reached' if cal['reached'] else 'NOT reached'} "
                  f"in calibration ({cal['views']} views, {cal['resolution'][0]}x{cal['resolution'][1]}, "
                  f"{len(cal['curve'])} probes, {r['seconds']['calibrate']:.0f} s); final check "
                  f"{len(res['views'])} views, {res['resolution'][0]}x{res['resolution'][1]} "
                  f"({r['seconds']['evaluate']:.0f} s)",
                  "",
                  "| level | AP mem % | AP PSNR min / mean | CAP mem % | CAP PSNR min / mean | depth-order px AP / CAP "
                  "| interior PSNR min AP / CAP |",
                  "|---|---|---|---|---|---|---|"]
        for row in res["levels"]:
            ap, cp = row["ap"], row["cap"]
            lines.append(f"| {row['level']} | {ap['percent_of_float32']:.1f} | {_psnr(ap['psnr_min'])} / "
                         f"{_psnr(ap['psnr_mean'])} | {cp['percent_of_float32']:.1f} | {_psnr(cp['psnr_min'])} / "
                         f"{_psnr(cp['psnr_mean'])} | {ap['depth_order_errors']} / {cp['depth_order_errors']} "
                         f"| {_psnr(ap['psnr_interior_min'])} / {_psnr(cp['psnr_interior_min'])} |")
        lines.append("")
    return "\n".join(lines)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--corpus", default=os.environ.get("LOPCOOK_CORPUS", str(REPO.parent / "shared" / "corpus")))
    ap.add_argument("--assets", nargs="*", default=ASSETS)
    ap.add_argument("--target-psnr", type=float, default=40.0)
    ap.add_argument("--statistic", nargs="+", choices=("min", "mean"), default=["min", "mean"])
    ap.add_argument("--levels", default="6-11")
    ap.add_argument("--cal-views", type=int, default=8)
    ap.add_argument("--cal-resolution", default="640x360")
    ap.add_argument("--views", type=int, default=20)
    ap.add_argument("--resolution", default="1280x720")
    ap.add_argument("--out", default=str(REPO / "bench-out" / "verify_corpus"))
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    results = []
    for name in args.assets:
        print(f"== {name}", flush=True)
        t0 = time.perf_counter()
        results += run_asset(Path(args.corpus) / name, args)
        results[-1]["seconds"]["asset_total"] = time.perf_counter() - t0
        (out / "results.json").write_text(json.dumps(results, indent=1, sort_keys=True))
    text = table(results)
    (out / "table.md").write_text(text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
