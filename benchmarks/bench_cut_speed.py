"""Speed of one view-dependent cut (select + decode) and of the full decode, on the bunny.

Not a test. Builds the bunny's tree once, encodes it with ``PROPOSED_PLUS`` (as ``cook
--hierarchy`` does) and times, best of ``--repeat`` runs, ``decode_hierarchy`` + ``triangles()``
and ``select_cut`` for a near, middle and far camera (1024x768, 60 degrees, 1 px): wall clock
(best / median / worst of the runs) and this process's CPU time (best), with the load average. ``--profile`` prints a cProfile of the
middle cut. Usage::

    PYTHONPATH=. .venv/bin/python benchmarks/bench_cut_speed.py [--corpus DIR] [--repeat 11] [--profile]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def best_of(fn, repeat):
    """(wall "best / median / worst" text, best CPU seconds, result) of ``repeat`` runs."""
    walls, cpu, out = [], np.inf, None
    for _ in range(repeat):
        t, c = time.perf_counter(), time.process_time()
        out = fn()
        walls.append(time.perf_counter() - t)
        cpu = min(cpu, time.process_time() - c)
    w = np.sort(walls)
    return f"{w[0]:.3f} / {np.median(w):.3f} / {w[-1]:.3f}", cpu, out


def main(argv=None):
    import lopcook
    from lopcook.hierarchy import PROPOSED_PLUS, build_tree, decode_hierarchy, drop_degenerate, \
        encode_hierarchy, select_cut

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--corpus", default=os.environ.get("LOPCOOK_CORPUS", str(Path(__file__).resolve().parents[2] / "shared" / "corpus")))
    ap.add_argument("--repeat", type=int, default=11)
    ap.add_argument("--profile", action="store_true")
    a = ap.parse_args(argv)
    part = lopcook.load(Path(a.corpus) / "stanford-bunny.obj").parts[0]
    T = build_tree(part.positions, drop_degenerate(np.asarray(part.indices, np.int64)))
    blob = encode_hierarchy(T, variant=PROPOSED_PLUS)
    print(f"load average {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} (2 cores)")
    w, c, tri = best_of(lambda: decode_hierarchy(blob).triangles(), a.repeat)
    print(f"full decode (decode_hierarchy + triangles, {tri.shape[0]} triangles): "
          f"wall {w} s, CPU {c:.3f} s")
    w, c, h = best_of(lambda: decode_hierarchy(blob), a.repeat)
    print(f"decode_hierarchy alone (parse, no records): wall {w} s, CPU {c:.3f} s")
    p = h.origin + (h.positions.astype(np.float64) + 0.5) * h.step
    ctr = p.mean(axis=0)
    ext = float(np.ptp(p, axis=0).max())
    cams = {name: ctr + np.array([0.3, 0.2, 1.0]) * ext * k
            for name, k in (("near", 0.8), ("middle", 3.0), ("far", 30.0))}
    w, c, _ = best_of(lambda: select_cut(decode_hierarchy(blob), cams["middle"], ctr, fov=60,
                                         viewport=(1024, 768), pixel_error=1.0), a.repeat)
    print(f"decode_hierarchy + first middle cut (per-hierarchy tables built): wall {w} s, CPU {c:.3f} s")
    for name, cam in cams.items():
        def run(cam=cam):
            return select_cut(h, cam, ctr, fov=60, viewport=(1024, 768), pixel_error=1.0)
        w, c, cut = best_of(run, a.repeat)
        print(f"cut {name:6s}: {cut.triangles.shape[0]:6d} triangles, {cut.split.shape[0]:6d} split "
              f"nodes: wall {w} s, CPU {c:.4f} s")
        if a.profile and name == "middle":
            import cProfile
            import pstats

            pr = cProfile.Profile()
            pr.enable()
            run()
            pr.disable()
            pstats.Stats(pr).sort_stats("cumulative").print_stats(15)
    print(f"load average {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} (2 cores)")


if __name__ == "__main__":
    main()
