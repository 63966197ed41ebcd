"""The three.js loader (runtime/js/three-lop.js) against the render harness's CAP render: PSNR over
object pixels, and over pixels fully covered in both (shading without silhouettes), for
DamagedHelmet and the chess set at several levels and views; and where the first renderable state
and each level lie in the bytes of today's layout. Not a test (tests/runtime/test_three_loader.py
checks its cameras at >= 40 dB). Usage::

    .venv/bin/python benchmarks/bench_three_loader.py [--corpus DIR] [--levels 8,9,10,11,12] [--views 3,12]

Needs chromium, three.js in .ci/node and EGL, as the test does. Prints one line per render and
writes nothing.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests" / "runtime"))

import runtime_support as rs  # noqa: E402  (tests/runtime helpers)
import test_three_loader as T  # noqa: E402

ASSETS = {"DamagedHelmet": "DamagedHelmet/DamagedHelmet.gltf", "chess_set_flat": "chess_set_flat.usdc"}


def bytes_table(path: Path) -> str:
    """Bytes the first renderable state and levels 8, 12, 16, 24 need in a container, and the share of its file."""
    from lopcook.lop.container import read

    c = read(str(path))
    m = c.manifest
    base = len(c.data) - sum(s["length"] for s in m["sections"])  # 32 + manifest size
    end = {s["name"]: base + s["offset"] + s["length"] for s in m["sections"]}
    pos = m["positions"]
    cells = [("renderable", end[pos["mandatory"]])] + [(f"level {b}", end[pos["planes"][str(b)]]) for b in (8, 12, 16, 24)
                                                         if str(b) in pos["planes"]]
    return ", ".join(f"{k} {v:,} B ({100 * v / len(c.data):.1f} %)" for k, v in cells)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--corpus", type=Path, default=REPO.parent / "shared" / "corpus")
    p.add_argument("--levels", default="8,9,10,11,12")
    p.add_argument("--views", default="3,12")
    args = p.parse_args(argv)
    levels = [int(x) for x in args.levels.split(",")]
    views = [int(x) for x in args.views.split(",")]
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        cooked = {}
        for name, src in {**ASSETS, "stanford-bunny": "stanford-bunny.obj"}.items():
            cooked[name] = rs.cook(args.corpus / src, root / "cooked" / f"{name}.lop") if (root / "cooked").mkdir(
                exist_ok=True) is None else None
            print(f"{name}: {bytes_table(cooked[name])}")
        renders = [(n, s, b, v) for n, s in ASSETS.items() for b in levels for v in views]
        got, _, scores = T.render(cooked, args.corpus, root / "web", renders, streams=())
        for key, m in scores.items():
            print(f"{key}: PSNR {m['psnr']:.2f} dB, interior {m['psnr_interior']:.2f} dB, {m['object_pixels']} object "
                  f"pixels, {100 * m['share_off']:.2f} % off by more than 1/255")
    return 0


if __name__ == "__main__":
    sys.exit(main())
