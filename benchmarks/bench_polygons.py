"""Concave polygon triangulation (``lopcook/ingest/polygons.py``): the ear clipper against earcut,
and earcut's growth with the corners.

Not a test (pytest does not collect benchmarks/). Usage::

    .venv/bin/python benchmarks/bench_polygons.py 16 64 512 2000 10000 [--shapes comb,star]
    .venv/bin/python benchmarks/bench_polygons.py 30000 60000 100000 --shapes comb,star,jitter

For each corner count k and shape, in this process, one run each: earcut's time
(``mapbox_earcut.triangulate_float64``), its triangle count and whether its unsigned areas sum to
the shoelace area (``tiles``: else lopcook fans the polygon), and, for k <= 512, the ear clipper's
time (``polygons._ear_clip``). Shapes, all counter-clockwise in the plane: ``comb`` a base edge
and k - 2 teeth corners alternating between heights 4 and 2 (every other corner reflex), ``star``
radii alternating 1 and 0.5, ``jitter`` radii uniform in [0.5, 1], ``spiral`` a strip wound 10
times, ``random`` uniform points (self-intersecting). Results: docs/ingest.md, "Polygons".
"""

from __future__ import annotations

import argparse
import time

import mapbox_earcut
import numpy as np

from lopcook.ingest.polygons import _ear_clip, _signed_areas


def comb(k: int) -> np.ndarray:
    x = np.arange(k - 3, -1, -1)
    top = np.stack([x, np.where(np.arange(k - 2) % 2 == 0, 4, 2)], axis=1)
    return np.vstack([[[0, 0], [k - 3, 0]], top]).astype(float)


def star(k: int) -> np.ndarray:
    a = np.linspace(0, 2 * np.pi, k, endpoint=False)
    r = np.where(np.arange(k) % 2 == 0, 1.0, 0.5)
    return np.stack([r * np.cos(a), r * np.sin(a)], axis=1)


def jitter(k: int) -> np.ndarray:
    a = np.linspace(0, 2 * np.pi, k, endpoint=False)
    r = np.random.default_rng(1).uniform(0.5, 1.0, k)
    return np.stack([r * np.cos(a), r * np.sin(a)], axis=1)


def spiral(k: int) -> np.ndarray:
    t = np.linspace(0, 20 * np.pi, k // 2)
    outer = np.stack([(1.5 + t) * np.cos(t), (1.5 + t) * np.sin(t)], axis=1)
    inner = np.stack([(1 + t) * np.cos(t), (1 + t) * np.sin(t)], axis=1)[::-1]
    return np.vstack([outer, inner])


def random(k: int) -> np.ndarray:
    return np.random.default_rng(2).uniform(0, 1, (k, 2))


SHAPES = {"comb": comb, "star": star, "jitter": jitter, "spiral": spiral, "random": random}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("corners", type=int, nargs="+")
    ap.add_argument("--shapes", default="comb,star", help="comma-separated: " + ", ".join(SHAPES))
    args = ap.parse_args()
    for k in args.corners:
        for name in args.shapes.split(","):
            pts = SHAPES[name](k)
            t0 = time.perf_counter()
            tris = mapbox_earcut.triangulate_float64(pts, np.array([len(pts)], np.uint32))
            t_cut = time.perf_counter() - t0
            tris = tris.astype(np.int64).reshape(-1, 3)
            areas = np.abs(_signed_areas(pts, tris)).sum()
            shoelace = abs(0.5 * np.sum(pts[:, 0] * np.roll(pts[:, 1], -1) - np.roll(pts[:, 0], -1) * pts[:, 1]))
            line = (f"{name:6s} k={k:>9,}  earcut {t_cut * 1e3:10.2f} ms  {tris.shape[0]:>9,} triangles  "
                    f"tiles={abs(areas - shoelace) <= 1e-9 * shoelace}")
            if k <= 512:
                t0 = time.perf_counter()
                _ear_clip(pts)
                line += f"  ear clipper {(time.perf_counter() - t0) * 1e3:8.1f} ms"
            print(line, flush=True)


if __name__ == "__main__":
    main()
