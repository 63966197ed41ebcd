"""Bits per triangle of every hierarchy connectivity variant on the corpus, with references.

Not a test. Usage (``benchmarks/bench_connectivity.py`` and ``lopcook bench --connectivity -o
DIR`` run this)::

    PYTHONPATH=. .venv/bin/python benchmarks/bench_connectivity.py [--corpus DIR] [--assets A ...]
        [--json OUT.json] [--out DIR]

``--out`` (default ``bench-out``) receives ``connectivity.json`` and the chart
``connectivity_unit_size.png``: bits per triangle (proposed_plus records plus the random-access
index) against the size of the random-access unit, per asset, with the codecs that have no
random access (meshoptimizer, Draco: one unit = the whole mesh) and the Nanite-style cluster DAG
figure quoted by docs/hierarchy.md (128-triangle clusters, about 14.3 bits per original triangle,
bunny).

For each asset, every part with at least 4 triangles is built into a vertex tree (the part's own
vertices and index buffer, degenerate triangles dropped) and coded with every variant of
``lopcook.hierarchy.coding.VARIANTS``. Numbers are summed over parts: ``bits`` are connectivity
records only (the paper's way), ``+tab`` adds the Huffman tables, ``struct`` is the tree structure
(one preorder bit per node). References on the same index buffers:

* meshoptimizer's index codec: ``encode_index_buffer`` after ``optimize_vertex_cache`` and
  ``optimize_vertex_fetch_remap`` (raw bytes, no general-purpose compressor after it);
* Draco (DracoPy, Edgebreaker, compression level 7, 14-bit positions): whole-mesh bits per
  triangle, positions included (DracoPy does not report the connectivity share, and subtracting
  a point cloud of the same positions gives negative numbers: the mesh codec predicts positions
  from the connectivity).

Random access: the blob indexes every record (one varint of its bit length per internal node).
``index`` lists, for proposed_plus, the index bits per triangle if instead only nodes whose
subtree has at least U leaves stored the bit length of their left subtree (a reader skips to any
node through those and parses at most about 2U records sequentially below them).

Throughput: ``encode_hierarchy`` (tree given) and ``decode_hierarchy`` + ``triangles()`` for the
proposed and proposed_plus variants, in triangles per second (every decode is checked to give
back exactly the part's triangles); for the bunny also one
view-dependent cut (select + decode) for a near, middle and far camera. Times are the best of
a few runs, as wall clock and as this process's CPU time (what the code costs when it has a core
to itself, whatever else the machine runs).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

from ..api import load
from ..hierarchy import (PROPOSED, PROPOSED_PLUS, VARIANTS, build_tree, decode_hierarchy, drop_degenerate,
                         encode_hierarchy, measure, select_cut)
from ..hierarchy import coding as C
from ..mesh import canonical_triangles
from .charts import pyplot

REPO = Path(__file__).resolve().parents[2]

ASSETS = ["stanford-bunny.obj", "fandisk.obj", "spot.obj", "DamagedHelmet/DamagedHelmet.gltf",
          "CesiumMilkTruck.glb", "Duck.glb", "UtahTeapot.usd", "chess_set_flat.usdc"]
SHOW = ["came", "relative_id_refine", "relative_id", "proposed", "proposed_plus"]


CPU = {}  # label -> best process CPU seconds of the last best_of with that label


def best_of(fn, repeat=3, label=None):
    """Best wall-clock seconds of ``repeat`` runs (and, under ``label``, best CPU seconds)."""
    best, cpu, out = np.inf, np.inf, None
    for _ in range(repeat):
        t, c = time.perf_counter(), time.process_time()
        out = fn()
        best = min(best, time.perf_counter() - t)
        cpu = min(cpu, time.process_time() - c)
    if label:
        CPU[label] = cpu
    return best, out


def meshopt_bits(tri, n):
    import meshoptimizer as mo  # the peers' codecs (DracoPy: lopcook[bench]) load when measured

    idx = np.ascontiguousarray(tri.reshape(-1).astype(np.uint32))
    opt = np.zeros_like(idx)
    mo.optimize_vertex_cache(opt, idx, idx.size, n)
    remap = np.zeros(n, np.uint32)
    mo.optimize_vertex_fetch_remap(remap, opt, opt.size, n)
    opt = remap[opt].astype(np.uint32)
    return 8 * len(mo.encode_index_buffer(opt, opt.size, n))


def draco_bits(pos, tri):
    import DracoPy  # optional (lopcook[bench]): imported where Draco runs

    mesh = DracoPy.encode(pos.astype(np.float32), tri.astype(np.uint32), quantization_bits=14,
                          compression_level=7)
    return 8 * len(mesh)


UNITS = (1, 8, 64, 512, 4096)


def index_bits(T, variant):
    """{"per_record": bits, U: bits} of the random-access index (see the module docstring)."""
    lay = C.layout(T, variant.restructure)
    coded = C.encode_connectivity(T, variant, lay)

    def varint_bits(x):
        x = np.maximum(np.asarray(x, np.int64), 1)
        return 8 * ((np.floor(np.log2(x)).astype(np.int64) // 7) + 1)

    out = {"per_record": int(varint_bits(coded.record_bits).sum())}
    bits_pre = np.zeros(lay.order.shape[0], np.int64)
    inner = lay.left[lay.order] >= 0
    bits_pre[inner] = coded.record_bits
    cs = np.r_[0, np.cumsum(bits_pre)]
    internal = np.flatnonzero(lay.left >= 0)
    k = lay.pre[internal]
    L = lay.left[internal]
    left_bits = cs[k + 1 + 2 * lay.size[L] - 1] - cs[k + 1]
    for U in UNITS:
        sel = lay.size[internal] >= U
        out[U] = int(varint_bits(left_bits[sel]).sum())
    return out


def run_asset(path, variants):
    scene = load(path)
    acc = {k: {"bits": 0, "tables": 0, "struct": 0} for k in variants}
    ref = {"tri": 0, "meshopt": 0, "draco": 0, "parts": 0, "build_s": 0.0, "depth": 0,
           "index": {}}
    trees = []
    for part in scene.parts:
        tri = drop_degenerate(np.asarray(part.indices, np.int64))
        if tri.shape[0] < 4:
            continue
        t = time.perf_counter()
        T = build_tree(part.positions, tri)
        ref["build_s"] += time.perf_counter() - t
        ref["depth"] = max(ref["depth"], int(T.depth().max()))
        trees.append((T, part))
        ref["tri"] += tri.shape[0]
        ref["parts"] += 1
        for k, v in variants.items():
            r = measure(T, v)
            acc[k]["bits"] += r["records"]
            acc[k]["tables"] += r["tables"]
            acc[k]["struct"] += r["structure"]
        ref["meshopt"] += meshopt_bits(tri, part.positions.shape[0])
        ref["draco"] += draco_bits(part.positions, tri)
        for key, b in index_bits(T, variants["proposed_plus"]).items():
            ref["index"][key] = ref["index"].get(key, 0) + b
    return acc, ref, trees


def throughput(trees):
    out = {}
    m = sum(T.triangles.shape[0] for T, _ in trees)
    for name, v in (("proposed", PROPOSED), ("proposed_plus", PROPOSED_PLUS)):
        te, blobs = best_of(lambda: [encode_hierarchy(T, variant=v) for T, _ in trees], 2, "enc")
        td, dec = best_of(lambda: [decode_hierarchy(b).triangles() for b in blobs], 2, "dec")
        for (T, _), tri in zip(trees, dec):  # exact round trip (oriented multiset of triangles)
            if not np.array_equal(canonical_triangles(tri), canonical_triangles(T.triangles)):
                raise SystemExit(f"round trip failed ({name})")
        out[name] = {"encode_tri_per_s": m / te, "decode_tri_per_s": m / td, "decode_s": td,
                     "decode_cpu_s": CPU["dec"], "encode_cpu_s": CPU["enc"],
                     "blob_bytes": sum(len(b) for b in blobs)}
    return out


def cut_timings(T):
    h = decode_hierarchy(encode_hierarchy(T, variant=PROPOSED_PLUS))
    p = h.origin + (h.positions.astype(np.float64) + 0.5) * h.step
    c = p.mean(axis=0)
    ext = float(np.ptp(p, axis=0).max())
    rows = []
    for name, k in (("near", 0.8), ("middle", 3.0), ("far", 30.0)):
        cam = c + np.array([0.3, 0.2, 1.0]) * ext * k
        dt, cut = best_of(lambda: select_cut(h, cam, c, fov=60, viewport=(1024, 768),
                                             pixel_error=1.0), 5, "cut")
        rows.append({"camera": name, "seconds": dt, "cpu_seconds": CPU["cut"],
                     "triangles": int(cut.triangles.shape[0]),
                     "split_nodes": int(cut.split.shape[0])})
    return rows


#: the quoted figure (docs/hierarchy.md) for a Nanite-style cluster DAG (meshoptimizer clusterlod, 128-triangle
#: clusters) on the bunny: bits per original triangle, triangles only (not measured here)
CLUSTER_DAG_QUOTED = {"triangles_per_unit": 128, "bits_per_triangle": 14.3}


def unit_size_chart(results: dict, path) -> Path | None:
    """PNG of bits per triangle against random-access unit size; None without matplotlib.

    x: triangles per random-access unit (about 2U for a unit of U leaves; the unit of 1 leaf is
    every record indexed), log scale; the rightmost column is the whole mesh (no random access).
    y: proposed_plus connectivity records plus that unit's index bits, per triangle."""
    try:
        plt = pyplot()
    except ImportError:
        return None
    fig, ax = plt.subplots(figsize=(8.0, 4.8), dpi=110)
    whole = 2 ** 21
    for i, (a, res) in enumerate(results.items()):
        colour = f"C{i % 10}"
        base = res["bits_per_triangle"]["proposed_plus"]["bits"]
        xs = [2 * u for u in UNITS] + [whole]
        ys = [base + res["index_bits_per_triangle"][str(u)] for u in UNITS] + [base]
        ax.plot(xs, ys, "-o", color=colour, ms=3.5, label=Path(a).name)
        ax.plot([whole * 1.6], [res["meshopt_bits_per_triangle"]], "s", color=colour, ms=5, mfc="none")
        ax.plot([whole * 2.6], [res["draco_bits_per_triangle"]], "^", color=colour, ms=5, mfc="none")
    ax.plot([CLUSTER_DAG_QUOTED["triangles_per_unit"]], [CLUSTER_DAG_QUOTED["bits_per_triangle"]], "*", color="k",
            ms=10, label="cluster DAG, bunny (quoted)")
    ax.plot([], [], "ks", mfc="none", label="meshoptimizer index codec (no random access)")
    ax.plot([], [], "k^", mfc="none", label="Draco, whole mesh incl. 14-bit positions")
    ax.set_xscale("log", base=2)
    ax.set_xticks([2 * u for u in UNITS] + [whole])
    ax.set_xticklabels([str(2 * u) for u in UNITS] + ["whole\nmesh"])
    ax.set_xlabel("triangles per random-access unit (about 2 x its leaves)")
    ax.set_ylabel("bits per triangle (connectivity + index)")
    ax.set_title("Dependency-free connectivity (proposed_plus): cost of random access")
    ax.grid(True, which="major", alpha=0.3)
    top = max([res["draco_bits_per_triangle"] for res in results.values()] + [CLUSTER_DAG_QUOTED["bits_per_triangle"]])
    ax.set_ylim(top=top + 5.0)
    ax.legend(fontsize=7, ncol=2, loc="upper center")
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--corpus", default=os.environ.get("LOPCOOK_CORPUS", str(REPO.parent / "shared" / "corpus")))
    ap.add_argument("--assets", nargs="*", default=ASSETS)
    ap.add_argument("--json", default=None)
    ap.add_argument("--out", default="bench-out", help="folder for connectivity.json and the chart")
    args = ap.parse_args(argv)
    results = {}
    print(f"{'asset':34s} {'tris':>8s} {'depth':>5s} " + " ".join(f"{k[:14]:>14s}" for k in SHOW)
          + f" {'+tab':>6s} {'struct':>6s} {'meshopt':>7s} {'draco':>6s}")
    for a in args.assets:
        path = Path(args.corpus) / a
        acc, ref, trees = run_asset(path, VARIANTS)
        m = max(ref["tri"], 1)
        row = {k: {x: y / m for x, y in v.items()} for k, v in acc.items()}
        res = {"triangles": ref["tri"], "parts": ref["parts"], "max_depth": ref["depth"],
               "build_s": ref["build_s"], "bits_per_triangle": row,
               "meshopt_bits_per_triangle": ref["meshopt"] / m,
               "draco_bits_per_triangle": ref["draco"] / m,
               "index_bits_per_triangle": {str(k): v / m for k, v in ref["index"].items()},
               "throughput": throughput(trees)}
        if a == "stanford-bunny.obj":
            res["cuts"] = cut_timings(trees[0][0])
        results[a] = res
        print(f"{a:34s} {ref['tri']:8d} {ref['depth']:5d} "
              + " ".join(f"{row[k]['bits']:14.2f}" for k in SHOW)
              + f" {row['proposed_plus']['tables']:6.2f} {row['proposed']['struct']:6.2f}"
              + f" {res['meshopt_bits_per_triangle']:7.2f} {res['draco_bits_per_triangle']:6.2f}",
              flush=True)
    print("\nall variants (records only, bits/triangle):")
    for a, res in results.items():
        print(a, {k: round(v["bits"], 2) for k, v in res["bits_per_triangle"].items()})
    print("\nrandom-access index, bits/triangle (per record as stored; per unit of U leaves):")
    for a, res in results.items():
        print(a, {k: round(v, 2) for k, v in res["index_bits_per_triangle"].items()})
    print("\nthroughput (triangles/s) and blob bytes:")
    for a, res in results.items():
        print(a, {k: {x: (round(y, 3) if x in ("decode_s", "decode_cpu_s", "encode_cpu_s") else round(y))
                      for x, y in v.items()}
                  for k, v in res["throughput"].items()}, f"build {res['build_s']:.2f}s")
    for a, res in results.items():
        for c in res.get("cuts", []):
            print(f"{a} cut {c['camera']}: {c['seconds']:.3f} s wall, {c['cpu_seconds']:.3f} s CPU, "
                  f"{c['triangles']} triangles, {c['split_nodes']} split nodes")
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "connectivity.json").write_text(json.dumps(results, indent=1))
    png = unit_size_chart(results, out / "connectivity_unit_size.png")
    print(f"\nwrote {out / 'connectivity.json'}" + (f" and {png}" if png else " (no matplotlib: no chart)"))
    return results


if __name__ == "__main__":
    main()
