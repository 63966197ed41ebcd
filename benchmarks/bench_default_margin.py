"""Issue 13 item 5 / issue 16: does one default position margin keep >= 40 dB on every asset, and
what does it save against the earlier default?

Not a test. Usage::

    .venv/bin/python benchmarks/bench_default_margin.py [--corpus DIR] [--assets A,B]
        [--candidates 16:0.0625,8:0.0625] [--levels 6-11] [--memory-levels 6-12] [--out DIR]

Per asset it cooks the earlier default (``--position-margin 1 --edge-eps 0.125 --clusters 0``:
the paper's worst-case bound, unclustered) and, per candidate ``M:EDGE_EPS``, ``cook
--position-margin M --edge-eps EDGE_EPS`` (every other option the default: clusters 64, default
attribute bits), then ``lopcook verify --min-psnr 40 --levels 6-11`` on the candidate (20 views at
1280 x 720, every attribute drawn as the container decodes it). It prints one JSON row per run:
CAP min PSNR per level, depth-order errors, and the mean GPU-resident position bytes over
``--memory-levels`` (``lopcook.lop.summary.memory_rows``: clusters' records and tables counted)
as a multiple of the earlier default's.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from lopcook.lop.container import read  # noqa: E402
from lopcook.lop.summary import memory_rows  # noqa: E402
from lopcook.verify.decoders import parse_levels  # noqa: E402

ASSETS = ("stanford-bunny.obj,fandisk.obj,spot.obj,DamagedHelmet/DamagedHelmet.gltf,CesiumMilkTruck.glb,"
          "Duck.glb,UtahTeapot.usd,chess_set_flat.usdc")


def lopcook(*argv) -> tuple[int, str, float]:
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-m", "lopcook", *map(str, argv)], capture_output=True, text=True,
                       env=dict(os.environ, PYTHONPATH=str(REPO)))
    return p.returncode, p.stdout if p.returncode in (0, 1) else p.stderr, time.perf_counter() - t0


def mean_bytes(lop: Path, levels) -> float:
    rows = memory_rows(read(lop), levels)
    return sum(r["cap_bytes"] for r in rows) / len(rows)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--corpus", default=os.environ.get("LOPCOOK_CORPUS", str(REPO.parent / "shared" / "corpus")))
    ap.add_argument("--assets", default=ASSETS)
    ap.add_argument("--candidates", default="16:0.0625")
    ap.add_argument("--levels", default="6-11")
    ap.add_argument("--memory-levels", default="6-12")
    ap.add_argument("--out", default="/tmp/bench_default_margin")
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    mem_levels = parse_levels(a.memory_levels)
    for name in a.assets.split(","):
        src = Path(a.corpus) / name
        stem = Path(name).stem
        base = out / f"{stem}_before.lop"
        if not base.exists():
            rc, err, _ = lopcook("cook", src, "-o", base, "-q", "--position-margin", 1, "--edge-eps", 0.125,
                                 "--clusters", 0)
            if rc:
                print(json.dumps({"asset": stem, "run": "before", "rc": rc, "error": err.strip()[-300:]}), flush=True)
                continue
        b0 = mean_bytes(base, mem_levels)
        for cand in a.candidates.split(","):
            m, e = cand.split(":")
            lop = out / f"{stem}_m{m}_e{e}.lop"
            rc, err, t_cook = lopcook("cook", src, "-o", lop, "-q", "--position-margin", m, "--edge-eps", e)
            row = {"asset": stem, "margin": float(m), "edge_eps": float(e), "cook_s": round(t_cook, 1)}
            if rc:
                row.update(rc=rc, error=err.strip()[-300:])
                print(json.dumps(row), flush=True)
                continue
            b = mean_bytes(lop, mem_levels)
            rc, text, t_ver = lopcook("verify", lop, "--source", src, "--min-psnr", 40, "--levels", a.levels, "--json")
            row.update(memory_vs_before=round(b / b0, 4), before_bytes=round(b0), bytes=round(b),
                       verify_rc=rc, verify_s=round(t_ver, 1))
            if rc in (0, 1):
                d = json.loads(text)["render"]
                row["cap_min_psnr"] = {str(L["level"]): round(L["cap"]["psnr_min"], 2) for L in d["levels"]}
                row["cap_percent_of_float32"] = {str(L["level"]): round(L["cap"]["percent_of_float32"], 2)
                                                 for L in d["levels"]}
                row["depth_order_errors"] = sum(L["cap"]["depth_order_errors"] for L in d["levels"])
                row["worst_psnr"] = min(row["cap_min_psnr"].values())
            else:
                row["error"] = text.strip()[-300:]
            print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
