"""Item 5 of issue 13: can one default k_f / edge_eps model replace the calibration?

Not a test. Usage::

    .venv/bin/python benchmarks/bench_default_model.py CAL.lop:SOURCE [CAL.lop:SOURCE ...]
        [--levels 6-11] [--grid -3:1:0.25] [--verify]

Each ``CAL.lop`` is a container cooked with ``cook --target-psnr 40`` from ``SOURCE``; its
``options.analyse`` record gives the knobs it was cooked with, after the k_f calibration and the
attribute search (log2 sigma = log2(default eps / eps), edge strictness x_e = log2(default
edge_eps / edge_eps)), and ``options.clusters`` its cluster size, which every candidate is built
with too. For every candidate default (log2 sigma on
``--grid``, x_e = the largest calibrated x_e, so no asset's edges are looser than it needed) the
script cooks every source with that model (analysis and build only, no render) and prints, per
asset, the mean CAP memory over ``--levels`` as a multiple of the calibrated container's. A
candidate is a default for every asset when its log2 sigma is >= every calibrated one (so, PSNR
being non-decreasing in sigma, every asset keeps its 40 dB) and every multiple is <= 1.15.
``--verify`` renders the best such candidate on the gate (20 views, 1280 x 720) per asset.
``--edge X`` sets the candidates' x_e instead (then quality is not implied: ``--verify`` it).
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import replace
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from lopcook.analyse import analyse  # noqa: E402
from lopcook.emit import build  # noqa: E402
from lopcook.lop.container import from_bytes, read  # noqa: E402
from lopcook.ingest import load  # noqa: E402
from lopcook.settings import DEFAULT_ANALYSE  # noqa: E402
from lopcook.verify.buffers import position_bytes  # noqa: E402
from lopcook.verify.decoders import parse_levels  # noqa: E402


def mean_cap(c, levels) -> float:
    lods = [0] * len(c.manifest["parts"])
    return sum(position_bytes(c, lods, b)["cap"] for b in levels) / len(levels)


def cook(scene, x: float, e: float, clusters: int | None = None):
    s = replace(DEFAULT_ANALYSE, eps=DEFAULT_ANALYSE.eps / 2.0**x,
                edge_eps=min(1.0, DEFAULT_ANALYSE.edge_eps / 2.0**e))
    data = build(scene, analyse(scene, s), options={"analyse": s.to_record()}, cluster_size=clusters)
    return from_bytes(data, None), s


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("pairs", nargs="+")
    ap.add_argument("--levels", default="6-11")
    ap.add_argument("--grid", default="-3:1:0.25")
    ap.add_argument("--verify", action="store_true")
    ap.add_argument("--edge", type=float, default=None,
                    help="x_e of the candidates (default: the largest calibrated x_e, the sufficient choice)")
    a = ap.parse_args(argv)
    levels = parse_levels(a.levels)
    g0, g1, gs = (float(v) for v in a.grid.split(":"))
    grid = [g0 + k * gs for k in range(int(round((g1 - g0) / gs)) + 1)]
    assets = []
    for pair in a.pairs:
        lop, src = pair.split(":", 1)
        c = read(lop)
        opts = c.manifest["options"]
        if "calibration" not in opts:
            raise SystemExit(f"{lop}: not cooked with --target-psnr (no calibration record)")
        x = math.log2(DEFAULT_ANALYSE.eps / float(opts["analyse"]["eps"]))
        e = math.log2(DEFAULT_ANALYSE.edge_eps / float(opts["analyse"]["edge_eps"]))
        n = int(opts.get("clusters") or 0) or None
        t = {"name": Path(src).name, "scene": load(src), "x": x, "e": e, "cal_bytes": mean_cap(c, levels), "src": src,
             "clusters": n}
        again = mean_cap(cook(t["scene"], x, e, n)[0], levels)
        assert again == t["cal_bytes"], f"{src}: the calibrated knobs give {again} B here, {t['cal_bytes']} B in {lop}"
        assets.append(t)
    e_d = max(t["e"] for t in assets) if a.edge is None else float(a.edge)
    x_need = max(t["x"] for t in assets)
    print(f"calibrated knobs: " + ", ".join(f"{t['name']} (log2 sigma {t['x']:+.2f}, x_e {t['e']:+.0f})" for t in assets))
    print(f"candidate defaults at x_e = {e_d:+.0f} (edge_eps {min(1.0, DEFAULT_ANALYSE.edge_eps / 2**e_d):g}); "
          f"quality needs log2 sigma >= {x_need:+.2f}")
    header = "| log2 sigma | " + " | ".join(t["name"] for t in assets) + " | max |"
    print(header)
    print("|" + "---|" * (len(assets) + 2))
    best = None
    for x in sorted(set(grid) | {0.0}):
        ratios = [mean_cap(cook(t["scene"], x, e_d, t["clusters"])[0], levels) / t["cal_bytes"] for t in assets]
        tag = "" if x >= x_need and e_d >= max(t["e"] for t in assets) else " (looser than a calibrated knob)"
        print(f"| {x:+.2f}{tag} | " + " | ".join(f"{r:.3f}" for r in ratios) + f" | {max(ratios):.3f} |")
        if not tag and max(ratios) <= 1.15 and best is None:
            best = x
    # today's default for reference
    ratios = [mean_cap(cook(t["scene"], 0.0, 0.0, t["clusters"])[0], levels) / t["cal_bytes"] for t in assets]
    print("| today's default (0, x_e 0) | " + " | ".join(f"{r:.3f}" for r in ratios) + f" | {max(ratios):.3f} |")
    print("one default for every asset:", "none" if best is None else f"log2 sigma {best:+.2f}, x_e {e_d:+.0f}")
    if a.verify and best is not None:
        from lopcook.verify.evaluate import evaluate
        for t in assets:
            c, _ = cook(t["scene"], best, e_d, t["clusters"])
            r = evaluate(c, t["scene"], levels=levels, views=20, resolution=(1280, 720), variants=("cap",))
            print(t["name"], [None if row["cap"]["psnr_min"] is None else round(row["cap"]["psnr_min"], 2)
                              for row in r["levels"]])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
