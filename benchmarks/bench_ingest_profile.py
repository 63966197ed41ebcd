"""Profile ``lopcook.ingest.load`` on one file: best wall and CPU seconds, the computed-normals
share (cProfile), and the peak RSS (VmHWM) of a fresh process that loads the file once, with the
peak of the load's traced allocations (tracemalloc: numpy reports its buffers; deterministic, where
VmHWM moves by tens of MB with transparent huge pages).

Not a test (pytest does not collect benchmarks/). Usage::

    PYTHONPATH=. .venv/bin/python benchmarks/bench_ingest_profile.py FILE [--repeat 5] [--top 12]

Run it with another checkout first on ``PYTHONPATH`` to measure that version the same way (the
before/after tables of docs/history/performance-log.md were made so). The 1.1M-triangle GLB is the bunny
subdivided twice (``benchmarks/bench_simplifiers.py`` and ``bench_ingest.py`` write it).
"""

from __future__ import annotations

import argparse
import cProfile
import io
import pstats
import subprocess
import sys
import time

TRACED = ("import sys, tracemalloc; from lopcook.ingest import load; tracemalloc.start(); load(sys.argv[1]); "
          "print(tracemalloc.get_traced_memory()[1])")
RSS = ("import sys, time; t = time.perf_counter(); from lopcook.ingest import load; "
       "i = time.perf_counter(); load(sys.argv[1]); e = time.perf_counter(); "
       "print([l.split()[1] for l in open('/proc/self/status') if l.startswith('VmHWM')][0], i - t, e - i)")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("file")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--top", type=int, default=12)
    args = ap.parse_args()
    from lopcook.ingest import load

    scene = load(args.file)  # warm-up: imports, file cache
    walls, cpus = [], []
    for _ in range(args.repeat):
        w0, c0 = time.perf_counter(), time.process_time()
        load(args.file)
        walls.append(time.perf_counter() - w0)
        cpus.append(time.process_time() - c0)
    prof = cProfile.Profile()
    prof.enable()
    load(args.file)
    prof.disable()
    st = pstats.Stats(prof)
    total = max(st.total_tt, 1e-9)
    normals = sum(v[3] for k, v in st.stats.items() if k[2] == "compute_normals")
    out = subprocess.run([sys.executable, "-P", "-c", RSS, args.file], capture_output=True, text=True, check=True)
    kb, t_import, t_load = out.stdout.split()  # -P: the checkout on PYTHONPATH, not the cwd
    traced = int(subprocess.run([sys.executable, "-P", "-c", TRACED, args.file], capture_output=True, text=True,
                                check=True).stdout)
    print(f"{args.file}: {scene.n_triangles:,} triangles, {scene.n_vertices:,} vertices after ingest")
    print(f"load: best wall {min(walls):.3f} s, median wall {sorted(walls)[len(walls) // 2]:.3f} s, "
          f"best CPU {min(cpus):.3f} s (of {args.repeat})")
    print(f"cProfile run: {total:.3f} s, compute_normals {normals:.3f} s ({normals / total:.0%})")
    print(f"fresh process: peak RSS {int(kb) / 1024:.0f} MB (VmHWM), import {float(t_import):.2f} s, "
          f"load {float(t_load):.3f} s; tracemalloc peak of the load {traced / 2**20:.0f} MB")
    buf = io.StringIO()
    pstats.Stats(prof, stream=buf).sort_stats("tottime").print_stats(args.top)
    print("\n".join(line for line in buf.getvalue().splitlines() if line.strip()
                    and not line.startswith(("   Ordered", "   List reduced"))))
    return 0


if __name__ == "__main__":
    sys.exit(main())
