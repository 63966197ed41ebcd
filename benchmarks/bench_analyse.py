"""Time the analysis (E_v, depth) on the corpus and on a two-part ~1M-triangle scene, and the
paper's O(n^2) depth scan against the spatial index on growing sizes (the crossover).

Not a test. Usage::

    .venv/bin/python benchmarks/bench_analyse.py [--corpus DIR] [--skip-reference]

Two-part scene: the bunny subdivided twice (1.1M triangles) and a copy of it shifted by 1.2 x its
extent along x (so depth distances are real but not tiny). The reference crossover uses two
icospheres 1 cm apart with 2 * 20 * 4^s triangles for s = 1..5; the reference is skipped once it
would take more than about a minute (its cost grows as n * m).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
ASSETS = ["stanford-bunny.obj", "fandisk.obj", "spot.obj", "DamagedHelmet/DamagedHelmet.gltf",
          "CesiumMilkTruck.glb", "Duck.glb", "UtahTeapot.usd", "chess_set_flat.usdc"]


def best_of(fn, repeat=3):
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main() -> int:
    import trimesh

    from lopcook.analyse import analyse
    from lopcook.analyse.depth import depth_levels, depth_levels_reference
    from lopcook.ingest import load
    from lopcook.ingest.build import make_part
    from lopcook.settings import IngestSettings
    from lopcook.types import Scene

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--corpus", default=os.environ.get("LOPCOOK_CORPUS", str(REPO.parent / "shared" / "corpus")))
    ap.add_argument("--skip-reference", action="store_true")
    args = ap.parse_args()

    print(f"{'scene':<36} {'verts':>9} {'tris':>9} {'E_v s':>7} {'depth s':>8} {'coloc s':>8} {'total s':>8}")

    def row(name, scene):
        t, an = best_of(lambda: analyse(scene))
        tm = an.timings
        print(f"{name:<36} {scene.n_vertices:>9,} {scene.n_triangles:>9,} {tm['attribute_error']:>7.3f} "
              f"{tm['depth']:>8.3f} {tm['co_located']:>8.3f} {t:>8.3f}")

    for name in ASSETS:
        row(name, load(Path(args.corpus) / name))
    m = trimesh.load(Path(args.corpus) / "stanford-bunny.obj", process=False).subdivide().subdivide()
    v = np.asarray(m.vertices)
    f = np.asarray(m.faces)
    shift = np.array([1.2 * (v[:, 0].max() - v[:, 0].min()), 0.0, 0.0])
    st = IngestSettings()
    scene = Scene(parts=(make_part("a", v, f, settings=st), make_part("b", v + shift, f, settings=st)),
                  source="two bunnies", format="obj").validate()
    row("two subdivided bunnies", scene)

    if args.skip_reference:
        return 0
    print()
    print(f"{'triangles':>10} {'spatial s':>10} {'reference s':>12} {'ratio':>8}  identical levels")
    for s in range(1, 6):
        a = trimesh.creation.icosphere(s, radius=0.5)
        b = trimesh.creation.icosphere(s, radius=0.5)
        pos = [np.asarray(a.vertices), np.asarray(b.vertices) + [1.01, 0, 0]]
        idx = [np.asarray(a.faces), np.asarray(b.faces)]
        extent = 2.01
        tri = sum(len(i) for i in idx)
        ts, fast = best_of(lambda: depth_levels(pos, idx, extent, ceiling=24))
        est = None
        if s <= 4:
            tr, (ref, _) = best_of(lambda: depth_levels_reference(pos, idx, extent, ceiling=24), repeat=1)
            same = all(np.array_equal(x, y) for x, y in zip(fast.level, ref))
            print(f"{tri:>10,} {ts:>10.4f} {tr:>12.3f} {tr / ts:>8.1f}  {same}")
            est = tr
        else:
            print(f"{tri:>10,} {ts:>10.4f} {'(skipped)':>12}")
        del est
    return 0


if __name__ == "__main__":
    sys.exit(main())
