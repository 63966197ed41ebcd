"""The hierarchy in the container, per corpus asset: what ``cook --hierarchy`` adds and what
``refine`` gives at a far, a middle and a near camera. Not a test. Usage::

    PYTHONPATH=. .venv/bin/python benchmarks/bench_refine.py [--corpus DIR] [--assets A ...]
        [--pixel-error PX] [--resolution WxH] [--levels 6,8,10] [--no-backface] [--json OUT.json]

Per asset: the cook's wall time with and without ``--hierarchy`` (in-process, default settings),
the container bytes it adds, ``inspect``'s per-part figures summed over parts
(``lopcook.lop.summary.hierarchy_stats``), then for the harness cameras of ``--levels``
(icosahedron view 0, ``lopcook.verify.cameras.make_camera``) the cut of ``refine`` (wall time,
triangles against LOD 0, position level) rendered against the float source with the harness
(``evaluate_scene``: same shading and metrics as the render check; textures and UVs kept).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

ASSETS = ["stanford-bunny.obj", "fandisk.obj", "spot.obj", "DamagedHelmet/DamagedHelmet.gltf",
          "CesiumMilkTruck.glb", "Duck.glb", "UtahTeapot.usd"]
LEVELS = (6, 8, 10)


def run_asset(path, pixel_error, resolution, levels=LEVELS, backface=True):
    import lopcook
    from lopcook.lop.summary import hierarchy_stats
    from lopcook.hierarchy.container import refine
    from lopcook.settings import DEFAULTS, Settings, SimplifySettings
    from lopcook.types import MeshPart, Scene
    from lopcook.verify.cameras import camera_distance, make_camera
    from lopcook.verify.evaluate import evaluate_scene
    from lopcook.viewing import Viewing

    scene = lopcook.load(path)
    t = time.perf_counter()
    plain = lopcook.cook(scene, DEFAULTS)
    t_plain = time.perf_counter() - t
    t = time.perf_counter()
    c = lopcook.cook(scene, Settings(simplify=SimplifySettings(hierarchy=True)))
    t_hier = time.perf_counter() - t
    stats = [hierarchy_stats(c, i) for i in range(len(c.manifest["parts"]))]
    m = sum(s["triangles"] for s in stats)
    n = sum(p["hierarchy"]["leaves"] for p in c.manifest["parts"])
    out = {"triangles": m, "parts": len(stats), "cook_s": t_plain, "cook_hierarchy_s": t_hier,
           "bytes": len(plain.data), "bytes_hierarchy": len(c.data),
           "bits_per_triangle": sum(s["bits_per_triangle"] * s["triangles"] for s in stats) / m,
           "structure_bits_per_triangle": sum(s["structure_bits_per_triangle"] * s["triangles"] for s in stats) / m,
           "position_bits_per_vertex": sum(s["position_bits_per_vertex"] * p["hierarchy"]["leaves"]
                                           for s, p in zip(stats, c.manifest["parts"])) / n,
           "cameras": []}
    lo = np.min([p.positions.min(axis=0) for p in scene.parts], axis=0)
    hi = np.max([p.positions.max(axis=0) for p in scene.parts], axis=0)
    v = Viewing(viewport=resolution)
    extent = float(c.manifest["grid"]["extent"])
    textures = {p.name: p.texture for p in scene.parts}
    for level in levels:
        cam = make_camera(0, lo, hi, camera_distance(level, extent, v), v)
        t = time.perf_counter()
        meshes = refine(c, cam.eye, cam.centre, viewport=resolution, pixel_error=pixel_error, backface=backface)
        t_ref = time.perf_counter() - t
        test = Scene(tuple(MeshPart(x["name"], x["positions"].astype(np.float64), x["indices"].astype(np.uint32),
                                    normals=x["normals"], uvs=x["uvs"], colors=x["colors"],
                                    texture=textures.get(x["name"])) for x in meshes), "cut", "glb")
        r = evaluate_scene(test, scene, levels=[level], views=[0], resolution=resolution, extent=extent)
        row = r["levels"][0]["scene"]
        out["cameras"].append({"camera_level": level, "refine_s": t_ref,
                               "triangles": sum(x["stats"]["triangles"] for x in meshes),
                               "levels": sorted({x["stats"]["level"] for x in meshes}),
                               "psnr_db": row["psnr_min"], "object_pixels": row["object_pixels"]})
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--corpus", default=os.environ.get("LOPCOOK_CORPUS", str(REPO.parent / "shared" / "corpus")))
    ap.add_argument("--assets", nargs="*", default=ASSETS)
    ap.add_argument("--pixel-error", type=float, default=0.1)
    ap.add_argument("--resolution", default="320x180")
    ap.add_argument("--levels", default="6,8,10", help="camera levels (far to near)")
    ap.add_argument("--no-backface", dest="backface", action="store_false",
                    help="refine without Hoppe's back-face test")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    res = tuple(int(x) for x in args.resolution.split("x"))
    results = {}
    for a in args.assets:
        r = run_asset(Path(args.corpus) / a, args.pixel_error, res, [int(x) for x in args.levels.split(",")],
                      args.backface)
        results[a] = r
        cams = "; ".join(f"L{x['camera_level']}: {x['triangles']} t, {x['psnr_db'] if x['psnr_db'] is None else round(x['psnr_db'], 1)} dB, "
                         f"{x['refine_s']:.2f} s" for x in r["cameras"])
        print(f"{a}: {r['triangles']} t, +{r['bytes_hierarchy'] - r['bytes']} B, cook {r['cook_s']:.2f} -> "
              f"{r['cook_hierarchy_s']:.2f} s, {r['bits_per_triangle']:.2f} + {r['structure_bits_per_triangle']:.2f} "
              f"bits/t, {r['position_bits_per_vertex']:.1f} pos bits/v | {cams}", flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
