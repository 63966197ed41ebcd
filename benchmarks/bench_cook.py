"""Cook every corpus asset: container bytes, GPU-resident position bytes at B = 6..12, stage times.

Not a test. Usage::

    .venv/bin/python benchmarks/bench_cook.py [--corpus DIR] [--out bench-out/cook]

Runs ``lopcook cook ... --json`` in a fresh process per asset (so timings include imports the
way a build system sees them) and prints one row per asset plus the memory table.
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
ASSETS = ["stanford-bunny.obj", "fandisk.obj", "spot.obj", "DamagedHelmet/DamagedHelmet.gltf",
          "CesiumMilkTruck.glb", "Duck.glb", "UtahTeapot.usd", "chess_set_flat.usdc"]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--corpus", default=os.environ.get("LOPCOOK_CORPUS", str(REPO.parent / "shared" / "corpus")))
    ap.add_argument("--out", default=str(REPO / "bench-out" / "cook"))
    ap.add_argument("extra", nargs="*", help="extra cook flags, e.g. --kf 4")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for name in ASSETS:
        src = Path(args.corpus) / name
        dst = out / (Path(name).stem + ".lop")
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, "-m", "lopcook", "cook", str(src), "-o", str(dst), "--json", *args.extra],
                              capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if proc.returncode:
            print(f"{name}: failed: {proc.stderr.strip()}")
            continue
        d = json.loads(proc.stdout)
        mem = {r["level"]: r for r in d["memory"]}
        rows.append({"asset": name, "vertices": d["totals"]["vertices"], "triangles": d["totals"]["triangles"],
                     "file_bytes": d["file_bytes"], "float32_bytes": d["totals"]["float32_position_bytes"],
                     "cap": {b: mem[b]["cap_bytes"] for b in range(6, 13)},
                     "cap_percent": {b: round(mem[b]["cap_percent"], 1) for b in range(6, 13)},
                     "timings_s": d["timings_s"], "wall_s": wall})
    print("GPU-resident CAP position bytes (% of float32) at per-buffer level B")
    print(f"{'asset':<34} {'verts':>8} {'file B':>11} {'f32 B':>10} " + " ".join(f"{'B=' + str(b):>15}" for b in range(6, 13)))
    for r in rows:
        print(f"{r['asset']:<34} {r['vertices']:>8,} {r['file_bytes']:>11,} {r['float32_bytes']:>10,} "
              + " ".join(f"{r['cap'][b]:>10,} {r['cap_percent'][b]:>3.0f}%" for b in range(6, 13)))
    print()
    print(f"{'asset':<34} {'wall':>6} {'ingest':>7} {'E_v':>6} {'depth':>6} {'coloc':>6} {'emit':>6} {'write':>6}")
    for r in rows:
        t = r["timings_s"]
        print(f"{r['asset']:<34} {r['wall_s']:>6.2f} {t['ingest']:>7.2f} {t['analyse.attribute_error']:>6.2f} "
              f"{t['analyse.depth']:>6.2f} {t['analyse.co_located']:>6.2f} {t['emit']:>6.2f} {t['write']:>6.3f}")
    (out / "cook.json").write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
