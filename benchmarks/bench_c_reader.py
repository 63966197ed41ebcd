"""Speed of runtime/c/lop.h on one core: building the packed buffer P (the file's own layout:
clustered P and cluster records where the file clusters) at levels 11 and 16, and decoding float32
positions on the CPU, on the 1.1M-triangle mesh (the Stanford bunny subdivided twice, as
``lopcook bench --scaling`` makes it) and the chess set, in GB/s of output next to memcpy of the
same bytes measured in the same process (benchmarks/bench_c_reader.c: the median of N runs of each).

    .venv/bin/python benchmarks/bench_c_reader.py [--out bench-out/c_reader] [--runs 21]

Writes OUT/results.json and prints one table; docs/runtime-c.md ("Speed") quotes a run. Not a
test: the numbers depend on the machine and its load.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
LEVELS = "11,16"


def corpus() -> Path:
    path = Path(os.environ.get("LOPCOOK_CORPUS", REPO.parent / "shared" / "corpus"))
    if not (path / "corpus.json").is_file():
        sys.exit(f"bench_c_reader: corpus not found at {path} (set LOPCOOK_CORPUS)")
    return path


def inputs(out: Path) -> list[tuple[str, Path]]:
    """(name, source): the 1.1M-triangle bunny (GLB written by lopcook.bench) and the chess set."""
    from lopcook.bench import scaling_inputs

    rows = scaling_inputs(out, corpus(), 1_200_000, None)
    bunny = next(path for name, path, tris, _ in rows if name == "bunny s2")
    return [("bunny s2 (1,111,216 triangles)", bunny), ("chess set", corpus() / "chess_set_flat.usdc")]


def cooked(source: Path, out: Path) -> Path:
    lop = out / (source.stem + ".lop")
    if not lop.exists():
        subprocess.run([sys.executable, "-m", "lopcook", "cook", str(source), "-o", str(lop), "-q"], check=True)
    return lop


def build(out: Path) -> Path:
    exe = out / "bench_c_reader"
    subprocess.run(["gcc", "-std=c99", "-O2", "-Wall", "-Wextra", "-Wpedantic", "-Werror",
                    str(REPO / "benchmarks" / "bench_c_reader.c"), "-o", str(exe)], check=True)
    return exe


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(REPO / "bench-out" / "c_reader"))
    ap.add_argument("--runs", type=int, default=21)
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    exe = build(out)
    results = []
    for name, source in inputs(out):
        lop = cooked(source, out)
        run = subprocess.run([str(exe), str(lop), "--levels", LEVELS, "--runs", str(args.runs)], capture_output=True,
                             text=True, check=True)
        for line in run.stdout.splitlines():
            results.append(dict(json.loads(line), input=name, file_bytes=lop.stat().st_size))
    (out / "results.json").write_text(json.dumps(results, indent=1) + "\n")
    print(f"{'input':32s} {'what':17s} {'level':>5s} {'MB out':>8s} {'GB/s':>6s} {'memcpy GB/s':>11s}")
    for r in results:
        if r["what"] == "open":
            continue
        print(f"{r['input']:32s} {r['what']:17s} {r['level']:5d} {r['bytes'] / 1e6:8.2f} {r['GBps']:6.2f} "
              f"{r['memcpy_GBps']:11.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
