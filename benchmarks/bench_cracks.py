"""Co-located vertices decode identically from random cameras (issue 16, "Cracks").

Not a test. Usage::

    .venv/bin/python benchmarks/bench_cracks.py OUT.lop [--cameras 24] [--seed 1]

For every camera (seeded, deterministic): each buffer (every part and LOD, placements excluded)
gets its per-buffer level from the camera (``verify.decoders.buffer_level`` on the buffer's
level-24 box), every vertex its crack-free per-vertex level (``decode_crack_free``, the CPU mirror
that ``verify --decoders`` checks bit for bit against the GLSL and HLSL decoders), and its float32
position. Vertices are grouped by their 24-bit grid integers (co-located on the scene grid); a
group whose members decode to different float32 bits is a crack. Clustered and unclustered
buffers go through the same reader (``emit.reader.top_values``).

Cameras: uniformly random directions, at distances from 0.05 to 4 scene extents from the scene
centre (log-uniform), so near cameras give high per-buffer levels and far ones low levels.
Prints one line per camera and a total; exits 1 on any crack. ``--naive`` is the control: without
the per-vertex rule, buffers at different levels disagree, so the measure can fail.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from lopcook import api  # noqa: E402
from lopcook.lop.binning import LEVELS  # noqa: E402
from lopcook.lop.bitplane import to_grid  # noqa: E402
from lopcook.lop.reader import buffer_clusters, part_grid, top_values  # noqa: E402
from lopcook.verify.decoders import _manifest_viewing, buffer_level, decode_crack_free, view_tables  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("container")
    ap.add_argument("--cameras", type=int, default=24)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--naive", action="store_true",
                    help="control: decode every buffer at its own per-buffer level without the crack-free "
                         "per-vertex rule (co-located vertices of buffers at different levels then differ)")
    a = ap.parse_args(argv)
    t0 = time.process_time()
    c = api.read(a.container)
    parts = c.manifest["parts"]
    origin, extent = c.manifest["grid"]["origin"], float(c.manifest["grid"]["extent"])
    cell = extent / float(1 << LEVELS)
    level_dist, radius = view_tables(extent, _manifest_viewing(c), origin)
    buffers = []
    for i, p in enumerate(parts):
        if p.get("placement") is not None:
            continue  # a placement's buffer lives on its own mesh grid (docs/instances.md)
        for j in range(len(p["lods"])):
            v24, w24 = top_values(c, i, j, LEVELS)
            q24 = to_grid(v24, w24)
            pos = q24.astype(np.float64) * cell + np.asarray(origin)
            vid = np.asarray(p["lods"][j]["vertex_id"], np.int64)
            bins = np.repeat(np.arange(LEVELS + 1), np.diff(vid, prepend=0))
            buffers.append((i, j, q24, pos.min(axis=0), pos.max(axis=0) + cell, bins,
                            buffer_clusters(c, i, j) is not None))
    keys = np.concatenate([b[2] for b in buffers]).astype(np.int64)  # (n, 3) 24-bit grid integers
    owner = np.concatenate([np.full(b[2].shape[0], k) for k, b in enumerate(buffers)])
    order = np.lexsort((keys[:, 2], keys[:, 1], keys[:, 0]))
    ks = keys[order]
    same = np.flatnonzero(np.all(ks[1:] == ks[:-1], axis=1))  # sorted neighbours sharing a cell
    cross = same[owner[order][same] != owner[order][same + 1]]
    centre = np.asarray(origin) + extent / 2
    rng = np.random.default_rng(a.seed)
    total_bad = 0
    print(f"{a.container}: {len(buffers)} buffers ({sum(b[6] for b in buffers)} clustered), "
          f"{keys.shape[0]} vertices, {cross.size} co-located pairs across buffers")
    for cam_i in range(a.cameras):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        cam = centre + d * extent * float(np.exp(rng.uniform(np.log(0.05), np.log(4.0))))
        pos32 = []
        levels = []
        for (i, j, _q, lo, hi, bins, _cl) in buffers:
            B = buffer_level(cam, lo, hi, level_dist)
            v, w = top_values(c, i, j, B)
            if a.naive:
                from lopcook.lop.bitplane import reconstruct_float32
                p32 = reconstruct_float32(v, w, origin, cell)
            else:
                _g, p32, _lv = decode_crack_free(v, w, bins, B, origin, cell, cam, level_dist, radius)
            pos32.append(p32.view(np.uint32))
            levels.append(B)
        bits = np.concatenate(pos32)[order]
        bad = int(np.count_nonzero(np.any(bits[cross] != bits[cross + 1], axis=1)))
        total_bad += bad
        print(f"  camera {cam_i:2d} at {np.linalg.norm(cam - centre) / extent:5.2f} extents: buffer levels "
              f"{min(levels)}..{max(levels)}, co-located pairs differing: {bad}")
    print(f"total: {total_bad} differing pairs over {a.cameras} cameras; {time.process_time() - t0:.1f} s CPU")
    return 1 if total_bad else 0


if __name__ == "__main__":
    sys.exit(main())
