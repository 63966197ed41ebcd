"""Time ``lopcook.ingest.load`` on the corpus and on a ~1M-triangle mesh in OBJ, GLB and USDC.

Not a test (pytest does not collect benchmarks/). Usage::

    .venv/bin/python benchmarks/bench_ingest.py [--corpus ../shared/corpus] [--out bench-out/ingest]

The large mesh is the Stanford bunny subdivided twice (69,451 -> 1,111,216 triangles, midpoint
subdivision with trimesh), written once per format into the output folder. Each file is loaded
``--repeat`` times in this process (after one warm-up load); the best time is reported, with
vertices/s = vertices after ingest / best seconds. Peak RSS is of a fresh process loading the
file once (VmHWM of a child process).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]


def make_big(out: Path) -> list[Path]:
    import trimesh
    from pxr import Usd, UsdGeom, Vt

    src = REPO.parent / "shared" / "corpus" / "stanford-bunny.obj"
    mesh = trimesh.load(src, process=False).subdivide().subdivide()
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    obj = out / "bunny_1M.obj"
    if not obj.exists():
        v = np.asarray(mesh.vertices)
        f = np.asarray(mesh.faces) + 1
        with open(obj, "w") as fh:
            fh.write("o bunny\n")
            np.savetxt(fh, v, fmt="v %.7g %.7g %.7g")
            np.savetxt(fh, f, fmt="f %d %d %d")
    paths.append(obj)
    glb = out / "bunny_1M.glb"
    if not glb.exists():
        mesh.export(glb)
    paths.append(glb)
    usdc = out / "bunny_1M.usdc"
    if not usdc.exists():
        stage = Usd.Stage.CreateNew(str(usdc))
        UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
        UsdGeom.SetStageMetersPerUnit(stage, 1.0)
        root = UsdGeom.Xform.Define(stage, "/bunny")
        stage.SetDefaultPrim(root.GetPrim())
        m = UsdGeom.Mesh.Define(stage, "/bunny/mesh")
        m.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(np.asarray(mesh.vertices, dtype=np.float32)))
        m.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(mesh.faces), 3, dtype=np.int32)))
        m.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.asarray(mesh.faces, dtype=np.int32).ravel()))
        stage.GetRootLayer().Save()
    paths.append(usdc)
    return paths


def peak_rss_mb(path: Path) -> float:
    # VmHWM, not ru_maxrss: Linux keeps ru_maxrss across fork+exec, so a child would report the
    # parent's high-water mark; VmHWM belongs to the new address space.
    code = ("import sys; from lopcook.ingest import load; load(sys.argv[1]); "
            "print([l.split()[1] for l in open('/proc/self/status') if l.startswith('VmHWM')][0])")
    out = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True, check=True)
    return int(out.stdout.strip()) / 1024.0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--corpus", default=os.environ.get("LOPCOOK_CORPUS", str(REPO.parent / "shared" / "corpus")))
    ap.add_argument("--out", default=str(REPO / "bench-out" / "ingest"))
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    from lopcook.ingest import load

    corpus = Path(args.corpus)
    meta = json.loads((corpus / "corpus.json").read_text())
    files = [corpus / a["file"] for a in meta["assets"]] + make_big(Path(args.out))
    rows = []
    print(f"{'file':<36} {'fmt':<5} {'parts':>5} {'vertices':>10} {'triangles':>10} {'best s':>8} "
          f"{'Mvert/s':>8} {'RSS MB':>7}")
    for path in files:
        load(path)  # warm-up (imports, file cache)
        best = np.inf
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            scene = load(path)
            best = min(best, time.perf_counter() - t0)
        rss = peak_rss_mb(path)
        row = {"file": path.name, "format": scene.format, "parts": len(scene.parts),
               "vertices": scene.n_vertices, "triangles": scene.n_triangles, "seconds": best,
               "vertices_per_s": scene.n_vertices / best, "peak_rss_mb": rss}
        rows.append(row)
        print(f"{path.name:<36} {scene.format:<5} {row['parts']:>5} {row['vertices']:>10,} "
              f"{row['triangles']:>10,} {best:>8.3f} {row['vertices_per_s'] / 1e6:>8.2f} {rss:>7.0f}")
    Path(args.out).mkdir(parents=True, exist_ok=True)
    (Path(args.out) / "ingest.json").write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
