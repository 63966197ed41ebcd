"""Exact attribute copy against the closest-point transfer, on meshoptimizer LODs.

Not a test (pytest does not collect benchmarks/). Usage::

    PYTHONPATH=. .venv/bin/python benchmarks/bench_lod_transfer.py MESH [--ratios 1/2,1/4]

For each LOD of a meshoptimizer chain (each from the previous LOD, as ``lod_chain`` does) the
backend result is transferred twice, ``transfer_attributes(..., exact=True)`` (copy from the
LOD 0 vertex each vertex is) and ``exact=False`` (closest-point queries of every vertex and
centroid). Printed per LOD: CPU seconds of each, their ``lod_to_ref``, the largest angle between
the two paths' normals at the same corner, the corners where they differ by more than 10 degrees
("corners > 10 deg") and, of those, how many have the exact path's normal nearer the LOD face's
own normal than the closest-point path's ("exact nearer"), and whether every corner's attributes
equal a LOD 0 vertex's at its position bit for bit (exact path). The closest-point timing leaves
out its tree over LOD 0 (built once per chain, before the loop); the exact path's includes its
chunk trees (built per LOD), so the two CPU columns are not the stage's difference.
"""

from __future__ import annotations

import argparse
import time
from fractions import Fraction

import numpy as np

from lopcook.ingest import load
from lopcook.mesh import face_normals
from lopcook.simplify.backends import check_result, prepare, run_backend
from lopcook.simplify.reference import Reference
from lopcook.simplify.transfer import exact_sources, transfer_attributes


def corner_values(part, name):
    return getattr(part, name)[part.indices.ravel()]


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("mesh")
    ap.add_argument("--ratios", default="1/2,1/4")
    args = ap.parse_args()
    part = max(load(args.mesh).parts, key=lambda p: p.n_triangles)
    ref = Reference(part)
    ref.query(part.positions[:1])  # build the tree outside the timings
    cur = part
    n0 = part.n_triangles
    print(f"{args.mesh}: {n0:,} triangles, {part.n_vertices:,} vertices")
    print("ratio  triangles  exact cpu s  closest cpu s  lod_to_ref exact  closest  max normal angle deg  "
          "corners > 10 deg  exact nearer  bitwise")
    for r in args.ratios.split(","):
        target = int(round(float(Fraction(r)) * n0))
        mode = "simplify" if cur.uvs is not None else "ignore"
        work, _ = prepare(cur, mode)
        res, _ = check_result(run_backend("meshopt", work, target, True, True), target, work.faces.shape[0])
        t = time.process_time()
        a, ia = transfer_attributes(res, ref, cur, work, mode if cur.uvs is not None else "-", 0.02, exact=True)
        ta = time.process_time() - t
        t = time.process_time()
        b, ib = transfer_attributes(res, ref, cur, work, mode if cur.uvs is not None else "-", 0.02, exact=False)
        tb = time.process_time() - t
        ang, differ, nearer = float("nan"), 0, 0
        if a.normals is not None:
            # same corners: both keep the face order of the backend result
            na, nb = corner_values(a, "normals").astype(np.float64), corner_values(b, "normals").astype(np.float64)
            per = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", na, nb), -1, 1)))
            ang = float(per.max())
            fn = face_normals(a.positions, a.indices.astype(np.int64))
            fn = np.repeat(fn / np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-300), 3, axis=0)
            big = per > 10.0
            differ = int(big.sum())
            nearer = int((np.einsum("ij,ij->i", na[big], fn[big]) > np.einsum("ij,ij->i", nb[big], fn[big])).sum())
        count, start, order = exact_sources(ref, a.positions)
        ok = True
        for name in ("normals", "uvs", "colors"):
            if getattr(a, name) is None or getattr(part, name) is None:
                continue
            va = getattr(a, name)
            # every vertex's value equals one of the co-located LOD 0 vertices' values, bit for bit
            pair = np.repeat(np.arange(a.n_vertices), count)
            offs = np.arange(pair.size) - np.repeat(np.cumsum(count) - count, count)
            cand = order[start[pair] + offs]
            eq = (getattr(part, name)[cand].view(np.uint32) == va[pair].view(np.uint32)).all(axis=1)
            ok &= bool(np.bincount(pair, weights=eq, minlength=a.n_vertices).min() >= 1)
        print(f"{r:5}  {a.n_triangles:9,}  {ta:11.2f}  {tb:13.2f}  {ia['lod_to_ref']:.3e}  "
              f"{ib['lod_to_ref']:.3e}  {ang:10.4f}  {differ:,} of {3 * a.n_triangles:,}  {nearer:,}  {ok}")
        cur = a
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
