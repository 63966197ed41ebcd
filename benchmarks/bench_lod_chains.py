"""LOD chains of every corpus mesh through ``lod_chain`` (default ratios 1/2, 1/4, ... from the
previous LOD, no error cap), per backend and seam mode, with each LOD's recorded error and its
full symmetric Hausdorff distance to LOD 0 (``error.hausdorff``: every vertex and centroid of both
meshes), so chains recorded with the sampled measurement are compared on the same footing. Not a
test (pytest does not collect benchmarks/). Usage::

    PYTHONPATH=. .venv/bin/python benchmarks/bench_lod_chains.py --backend auto --seams lock \\
        [--meshes bunny,fandisk] [--out bench-out/lod_chains]

Parts: every distinct mesh of each corpus asset (copies of one mesh, as ``instances.copies``
finds them, once). Writes ``<out>/<backend>_<seams>.json``: per part its LODs (target ratio,
triangles, error_m, hausdorff_m recorded, full_m measured in full, backend, seconds) and the stop
reason. ``--compare A B`` prints, per part and ratio both reached within 5 % of the target, the
ratio of B's full Hausdorff distance to A's.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
ASSETS = {"bunny": "stanford-bunny.obj", "fandisk": "fandisk.obj", "spot": "spot.obj", "Duck": "Duck.glb",
          "DamagedHelmet": "DamagedHelmet/DamagedHelmet.gltf", "CesiumMilkTruck": "CesiumMilkTruck.glb",
          "UtahTeapot": "UtahTeapot.usd", "chess": "chess_set_flat.usdc"}


def run(corpus: Path, backend: str, seams: str, meshes: list[str]) -> list[dict]:
    from lopcook.ingest import load
    from lopcook.simplify import error as E
    from lopcook.simplify.chain import lod_chain
    from lopcook.simplify.instances import copies

    rows = []
    for name in meshes:
        scene = load(corpus / ASSETS[name])
        for lead, _ in copies(scene.parts):
            part = scene.parts[lead]
            t0 = time.perf_counter()
            lods, report = lod_chain(part, backend=backend, seams=seams)
            wall = time.perf_counter() - t0
            out = []
            for lod in lods[1:]:
                full = E.hausdorff(lod.part, part)[0]
                out.append({"ratio": lod.target_ratio, "target": lod.target_triangles, "triangles": lod.triangles,
                            "error_m": lod.error_m, "hausdorff_m": lod.hausdorff_m, "full_m": full,
                            "bound_m": lod.error_bound_m, "backend": lod.backend, "seconds": lod.seconds})
            rows.append({"asset": name, "part": part.name, "triangles": part.n_triangles, "seconds": wall,
                         "lods": out, "stop": report.stop_reason})
            print(f"{name:<16} {part.name[-28:]:<28} {part.n_triangles:>7} {wall:6.2f} s  "
                  + " ".join(f"{r['triangles']}:{r['full_m']:.3g}" for r in out) + f"  ({report.stop_reason})",
                  flush=True)
    return rows


def compare(a: list[dict], b: list[dict]) -> None:
    worst = []
    for ra, rb in zip(a, b):
        assert ra["part"] == rb["part"]
        la = {x["ratio"]: x for x in ra["lods"]}
        cells = []
        for x in rb["lods"]:
            y = la.get(x["ratio"])
            if y is None:
                cells.append(f"1/{round(1 / x['ratio'])}: B only")
                continue
            ok = all(abs(z["triangles"] - z["target"]) <= 0.05 * z["target"] for z in (x, y))
            if not ok:
                cells.append(f"1/{round(1 / x['ratio'])}: {y['triangles']} vs {x['triangles']} tris")
                continue
            r = x["full_m"] / y["full_m"] if y["full_m"] > 0 else float("inf")
            worst.append((r, ra["asset"], ra["part"], x["ratio"]))
            cells.append(f"1/{round(1 / x['ratio'])}: {r:.2f}")
        print(f"{ra['asset']:<16} {ra['part'][-28:]:<28} " + ", ".join(cells))
    worst.sort(reverse=True)
    print("worst B/A:", [(round(r, 3), n, p[-20:], f"1/{round(1 / q)}") for r, n, p, q in worst[:8]])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--corpus", default=os.environ.get("LOPCOOK_CORPUS", str(REPO.parent / "shared" / "corpus")))
    ap.add_argument("--out", default=str(REPO / "bench-out" / "lod_chains"))
    ap.add_argument("--backend", default="auto")
    ap.add_argument("--seams", default="lock")
    ap.add_argument("--meshes", default=",".join(ASSETS))
    ap.add_argument("--compare", nargs=2, metavar=("A.json", "B.json"))
    args = ap.parse_args()
    if args.compare:
        compare(*(json.loads(Path(p).read_text()) for p in args.compare))
        return 0
    rows = run(Path(args.corpus), args.backend, args.seams, [m for m in args.meshes.split(",") if m])
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{args.backend}_{args.seams}.json").write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
