"""Position memory of clustered buffers (``cook --clusters N``) against the unclustered layout.

Not a test. Usage::

    .venv/bin/python benchmarks/bench_clusters.py [--corpus DIR] [--out bench-out/clusters]
        [--sizes 32,64,128,256] [--levels 6-12] [--assets a.obj,b.glb] [--check 64] [-- extra cook flags]

For every asset: one ``lopcook cook`` (unclustered, with the extra flags) in a fresh process, then
for every N the clustered layout of exactly the same buffers (the container's LOD 0 grid
integers at 24 bits and its minimum levels: what ``cook --clusters N`` encodes, since clustering
changes no level) through ``lopcook.lop.clusters``. GPU-resident position bytes as % of
float32 per level: words of P + 16 B per cluster record + 128 B ClusterId per buffer. ``--check N``
also cooks ``--clusters N`` and asserts that its manifest accounting equals the re-encoding.
Prints a Markdown table; CPU times (user + sys of the children and this process) and the load
average are printed with it.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

ASSETS = ["stanford-bunny.obj", "fandisk.obj", "DamagedHelmet/DamagedHelmet.gltf", "CesiumMilkTruck.glb",
          "chess_set_flat.usdc"]


def cpu_seconds() -> float:
    a, b = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return a.ru_utime + a.ru_stime + b.ru_utime + b.ru_stime


def clustered_memory(c, sizes, levels) -> dict:
    """{N: {level: bytes}} of LOD 0 of every part, re-encoded clustered; plus the k histogram."""
    import numpy as np

    from lopcook.lop.binning import LEVELS
    from lopcook.lop.clusters import cluster_order, clustered_bytes, k_histogram, make_clusters
    from lopcook.lop.bitplane import to_grid
    from lopcook.lop.reader import top_values

    out = {n: {b: 0 for b in levels} for n in sizes}
    hist = {n: np.zeros(LEVELS + 1, np.int64) for n in sizes}
    clusters = {n: 0 for n in sizes}
    for i, part in enumerate(c.manifest["parts"]):
        e = part["lods"][0]
        q = to_grid(*top_values(c, i, 0, c.available_level))
        vid = np.asarray(e["vertex_id"], np.int64)
        lv = np.repeat(np.arange(LEVELS + 1), np.diff(vid, prepend=0))
        for n in sizes:
            bins = cluster_order(q, lv)
            cl = make_clusters(q[bins.order], bins.vertex_id, n)
            clusters[n] += cl.n_clusters
            hist[n] += k_histogram(cl)
            for b in levels:
                out[n][b] += clustered_bytes(cl, b)
    return {"bytes": out, "k_histogram": {n: hist[n].tolist() for n in sizes}, "clusters": clusters}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--corpus", default=os.environ.get("LOPCOOK_CORPUS", str(REPO.parent / "shared" / "corpus")))
    ap.add_argument("--out", default=str(REPO / "bench-out" / "clusters"))
    ap.add_argument("--sizes", default="32,64,128,256")
    ap.add_argument("--levels", default="6-12")
    ap.add_argument("--assets", default=",".join(ASSETS))
    ap.add_argument("--check", type=int, default=None, help="also cook --clusters N and compare its accounting")
    ap.add_argument("extra", nargs="*", help="extra cook flags, e.g. --target-psnr 40")
    args = ap.parse_args()
    from lopcook.lop.container import read
    from lopcook.lop.summary import memory_rows
    from lopcook.verify.decoders import parse_levels

    sizes = [int(v) for v in args.sizes.split(",")]
    levels = parse_levels(args.levels)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    results = []
    for name in args.assets.split(","):
        src = Path(args.corpus) / name
        tag = "".join(ch if ch.isalnum() else "_" for ch in " ".join(args.extra))
        dst = out / f"{Path(name).stem}{'_' + tag if tag else ''}.lop"
        t0, c0 = time.perf_counter(), cpu_seconds()
        subprocess.run([sys.executable, "-m", "lopcook", "cook", str(src), "-o", str(dst), "-q", *args.extra],
                       check=True, env=dict(os.environ, PYTHONPATH=str(REPO)))
        cook_wall, cook_cpu = time.perf_counter() - t0, cpu_seconds() - c0
        c = read(str(dst))
        rows = {r["level"]: r for r in memory_rows(c, levels=levels)}
        f32 = rows[levels[0]]["float32_bytes"]
        t0, c0 = time.perf_counter(), cpu_seconds()
        mem = clustered_memory(c, sizes, levels)
        enc_wall, enc_cpu = time.perf_counter() - t0, cpu_seconds() - c0
        rec = {"asset": name, "float32_bytes": f32, "cook_wall_s": cook_wall, "cook_cpu_s": cook_cpu,
               "encode_wall_s": enc_wall, "encode_cpu_s": enc_cpu,
               "unclustered": {b: rows[b]["cap_bytes"] for b in levels},
               "clustered": mem["bytes"], "clusters": mem["clusters"], "k_histogram": mem["k_histogram"],
               "vertices": c.entries.float32_bytes(0) // 12}
        if args.check is not None:
            cdst = out / f"{Path(name).stem}_c{args.check}{'_' + tag if tag else ''}.lop"
            subprocess.run([sys.executable, "-m", "lopcook", "cook", str(src), "-o", str(cdst), "-q",
                            "--clusters", str(args.check), *args.extra], check=True,
                           env=dict(os.environ, PYTHONPATH=str(REPO)))
            cc = read(str(cdst))
            got = {r["level"]: r for r in memory_rows(cc, levels=levels)}
            rec["check"] = {b: [got[b]["cap_bytes"], mem["bytes"][args.check][b], got[b]["unclustered_cap_bytes"],
                                rows[b]["cap_bytes"]] for b in levels}
            assert all(v[0] == v[1] and v[2] == v[3] for v in rec["check"].values()), rec["check"]
        results.append(rec)
        print(f"# {name}: cook {cook_wall:.1f} s wall / {cook_cpu:.1f} s CPU, re-encode {enc_wall:.1f} s wall / "
              f"{enc_cpu:.1f} s CPU, load {os.getloadavg()[0]:.1f}", file=sys.stderr)
    (out / "results.json").write_text(json.dumps(results, indent=1, default=str))
    print(f"| asset | layout | " + " | ".join(f"L{b}" for b in levels) + " | mean | vs unclustered |")
    print("|---|---|" + "---:|" * (len(levels) + 2))
    for r in results:
        f32 = r["float32_bytes"]
        un = [100.0 * r["unclustered"][b] / f32 for b in levels]
        print(f"| {r['asset']} | unclustered | " + " | ".join(f"{v:.1f}" for v in un) + f" | {sum(un) / len(un):.1f} | |")
        for n in sizes:
            cl = [100.0 * r["clustered"][n][b] / f32 for b in levels]
            gain = 100.0 * (1 - sum(r["clustered"][n].values()) / sum(r["unclustered"].values()))
            print(f"| | N = {n} | " + " | ".join(f"{v:.1f}" for v in cl) + f" | {sum(cl) / len(cl):.1f} | "
                  f"{-gain:+.1f} % |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
