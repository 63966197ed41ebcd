"""Measure the attribute search (issue 15): ``cook --target-psnr DB`` and ``cook --vertex-bits N`` on
corpus assets, each container's bits per vertex at level 11 and its quality on verify's harness with
every attribute rendered quantized, against gltfpack's default bytes per vertex.

Not a test. Usage::

    .venv/bin/python benchmarks/bench_attribute_search.py [--corpus DIR] [--assets A,B] [--target 40]
        [--vertex-bits 64] [--budget-assets stanford-bunny.obj,...] [--views 20] [--resolution 1280x720]
        [--levels 6-11] [--out DIR] [--gltfpack-bpv NAME=B,...]

Each cook runs as a child process (``python -m lopcook cook ... --json``; wall time and the child's
CPU time from ``os.wait4``). The quality row renders the container with its own decoded attributes
(``lopcook.verify.evaluate(..., attributes="container")``) against the float source at levels 6-11,
20 views at 1280 x 720 by default (verify's harness). gltfpack's default bytes per vertex
(positions 14 bits in 8 B, normals 8 bits in 4 B, UVs 12 bits in 4 B) come from ``lopcook bench
--attributes`` (``--gltfpack-bpv``) or are computed from the attributes the source has.
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


def gltfpack_default_bpv(scene) -> float:
    """gltfpack's default GPU bytes per vertex for the attributes ``scene`` has: positions 8 B
    (14 bits as 16-bit VEC3 padded), normals 4 B (8-bit VEC3 padded), UVs 4 B (12 bits as 16-bit),
    colours 4 B (8-bit RGBA); vertex-weighted over the parts."""
    n = sum(p.n_vertices for p in scene.parts)
    b = sum(p.n_vertices * (8 + 4 * (p.normals is not None) + 4 * (p.uvs is not None) + 4 * (p.colors is not None))
            for p in scene.parts)
    return b / max(n, 1)


def cook(src: Path, out: Path, extra: list) -> dict:
    argv = [sys.executable, "-m", "lopcook", "cook", str(src), "-o", str(out), "--json", *extra]
    t0 = time.perf_counter()
    import tempfile

    with tempfile.TemporaryFile() as out_f, tempfile.TemporaryFile() as err_f:  # files: no pipe to fill
        proc = subprocess.Popen(argv, stdout=out_f, stderr=err_f, env=dict(os.environ, PYTHONPATH=str(REPO)))
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        out_f.seek(0)
        err_f.seek(0)
        stdout, stderr = out_f.read().decode(), err_f.read().decode()
    rc = os.waitstatus_to_exitcode(status)
    desc = json.loads(stdout) if rc == 0 else None
    return {"argv": " ".join(["lopcook", "cook", src.name, *extra]), "rc": rc, "wall_s": round(wall, 1),
            "cpu_s": round(usage.ru_utime + usage.ru_stime, 1), "desc": desc,
            "error": None if rc == 0 else (stderr.strip().splitlines() or ["?"])[-1]}


def quality(lop: Path, scene, views, resolution, levels) -> dict:
    from lopcook.lop.container import read
    from lopcook.verify.evaluate import evaluate

    c = read(lop)
    t0 = time.process_time()
    ev = evaluate(c, scene, levels=levels, views=views, resolution=resolution, variants=("cap",),
                  attributes="container")
    mins = [r["cap"]["psnr_min"] for r in ev["levels"]]
    means = [r["cap"]["psnr_mean"] for r in ev["levels"]]
    return {"psnr_min_db": min(float("inf") if v is None else v for v in mins),
            "psnr_mean_db": min(float("inf") if v is None else v for v in means),
            "per_level_min": mins, "render_cpu_s": round(time.process_time() - t0, 1)}


def main(argv=None) -> int:
    from lopcook.ingest import load
    from lopcook.tune.attributes import vertex_bits
    from lopcook.lop.container import read
    from lopcook.verify.decoders import parse_levels

    ap = argparse.ArgumentParser()
    ap.add_argument("--corpus", default=os.environ.get("LOPCOOK_CORPUS", str(REPO.parent / "shared" / "corpus")))
    ap.add_argument("--assets", default="stanford-bunny.obj,DamagedHelmet/DamagedHelmet.gltf,Duck.glb")
    ap.add_argument("--budget-assets", default="stanford-bunny.obj,DamagedHelmet/DamagedHelmet.gltf")
    ap.add_argument("--target", type=float, default=40.0)
    ap.add_argument("--vertex-bits", type=float, default=64.0)
    ap.add_argument("--views", type=int, default=20)
    ap.add_argument("--resolution", default="1280x720")
    ap.add_argument("--levels", default="6-11")
    ap.add_argument("--out", default="/tmp/bench_attribute_search")
    ap.add_argument("--cook-args", default="", help="extra cook arguments, e.g. '--calibration-views 4'")
    ap.add_argument("--skip-default", action="store_true", help="no default cooks")
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    res = tuple(int(v) for v in a.resolution.split("x"))
    levels = parse_levels(a.levels)
    extra = a.cook_args.split()
    rows = []
    runs = [] if a.skip_default else [(name, "default", []) for name in a.assets.split(",")]
    runs += [(name, f"target {a.target:g}", ["--target-psnr", f"{a.target:g}"]) for name in a.assets.split(",")]
    runs = [(name, f"vertex-bits {a.vertex_bits:g}", ["--vertex-bits", f"{a.vertex_bits:g}"])
            for name in a.budget_assets.split(",") if name] + runs
    scenes = {}
    for name, kind, args in runs:
        src = Path(a.corpus) / name
        if name not in scenes:
            scenes[name] = load(src)
        lop = out / f"{Path(name).stem}_{kind.replace(' ', '_')}.lop"
        r = cook(src, lop, args + extra)
        row = {"asset": Path(name).stem, "run": kind, "command": r["argv"] + (" " + " ".join(extra) if extra else ""),
               "rc": r["rc"], "wall_s": r["wall_s"], "cpu_s": r["cpu_s"], "error": r["error"],
               "gltfpack_default_bytes_per_vertex": gltfpack_default_bpv(scenes[name]),
               "load": os.getloadavg()[0]}
        if r["rc"] == 0:
            c = read(lop)
            vb = vertex_bits(c)
            row.update(bits_per_vertex_11=round(vb["total"], 2), position_bits=round(vb["positions"], 2),
                       attribute_bits=round(vb["attributes"], 2),
                       ratio_to_gltfpack=round(vb["total"] / (8 * row["gltfpack_default_bytes_per_vertex"]), 3),
                       allocation=[p.get("attribute_bits") for p in c.manifest["parts"]])
            row.update(quality(lop, scenes[name], a.views, res, levels))
            s = (r["desc"] or {}).get("attribute_search")
            if s:
                row.update(search_probes=len(s["probes"]), search_seconds=s["seconds"], chosen=s["choice"])
        rows.append(row)
        print(json.dumps(row, default=str), flush=True)
    (out / "results.json").write_text(json.dumps(rows, indent=1, default=str) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
