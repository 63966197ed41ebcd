"""meshoptimizer bindings side by side on the corpus: the pinned ``meshoptimizer==0.2.30a0`` (its
bundled C library called through lopcook's own prototype, ``lopcook.simplify.meshopt``) against
``almeshopt`` (a binding of meshoptimizer >= 0.25, whose ``meshopt_SimplifyPermissive`` collapses
across attribute seams except at vertices marked ``meshopt_SimplifyVertex_Protect``). Not a test
(pytest does not collect benchmarks/). Usage::

    pip install --no-deps --target /tmp/almeshopt almeshopt==0.1.12      # only where it can run
    PYTHONPATH=.:/tmp/almeshopt .venv/bin/python benchmarks/bench_meshopt_binding.py \\
        [--meshes spot,DamagedHelmet] [--out bench-out/meshopt_binding.json]

Every distinct mesh of each corpus asset (``instances.copies``) is simplified from LOD 0 to
1/2, 1/4, ..., 1/64 of its triangles with the input the chain's ``seams="simplify"`` mode gives
meshoptimizer (``backends.prepare``: zero-area faces dropped, the part's own vertices, UVs in the
attribute metric at ``meshopt.UV_WEIGHT``, open borders locked), by three variants:

* ``pinned``: ``lopcook.simplify.meshopt.simplify_meshopt(..., weld=True)``, what cooks run today;
* ``new``: almeshopt, the same call (options ``ErrorAbsolute | LockBorder``): the newer library alone;
* ``permissive``: almeshopt with ``meshopt_SimplifyPermissive``, and ``Protect`` on every vertex
  whose position another vertex shares with different UVs (a UV seam); copies split only by
  normals (creases) are not protected.

Per result: triangles reached, the full symmetric Hausdorff distance to LOD 0 (``error.hausdorff``,
metres) and the UV seams (``topology.seam_stats``: seam edges, seam vertices, UV islands; LOD 0's
for comparison). Every output vertex is an input vertex, so the LOD is the input's vertex subset.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
ASSETS = {"bunny": "stanford-bunny.obj", "fandisk": "fandisk.obj", "spot": "spot.obj", "Duck": "Duck.glb",
          "DamagedHelmet": "DamagedHelmet/DamagedHelmet.gltf", "CesiumMilkTruck": "CesiumMilkTruck.glb",
          "UtahTeapot": "UtahTeapot.usd", "chess": "chess_set_flat.usdc"}
RATIOS = [1 / 2 ** k for k in range(1, 7)]
VARIANTS = ("pinned", "new", "permissive")


def _uv_seam_vertices(positions: np.ndarray, uvs: np.ndarray) -> np.ndarray:
    """(n,) bool: vertices whose exact position is shared by a vertex with other UVs."""
    from lopcook.mesh import unique_rows, weld_labels

    w, k = weld_labels(positions, np.int64)
    uvbits = np.ascontiguousarray(uvs, dtype=np.float32).view(np.int32).astype(np.int64)
    first, _ = unique_rows(np.concatenate([w[:, None], uvbits], axis=1))
    per_label = np.bincount(w[first], minlength=k)  # distinct (position, UV) pairs per position
    return per_label[w] > 1


def _almeshopt(p: np.ndarray, f: np.ndarray, uvs, target: int, permissive: bool) -> np.ndarray:
    """almeshopt's ``simplify_with_attributes`` on the chain's input; (t, 3) int64 faces."""
    import almeshopt as A

    from lopcook.simplify.meshopt import UV_WEIGHT, border_vertices

    n = p.shape[0]
    if uvs is not None:
        attr, w = np.ascontiguousarray(uvs, dtype=np.float32), np.full(2, UV_WEIGHT, dtype=np.float32)
    else:
        attr, w = np.zeros((n, 1), dtype=np.float32), np.zeros(1, dtype=np.float32)
    lock = np.where(border_vertices(p, f), A.SIMPLIFY_VERTEX_LOCK, 0).astype(np.uint8)
    options = A.SIMPLIFY_ERROR_ABSOLUTE | A.SIMPLIFY_LOCK_BORDER
    if permissive:
        options |= A.SIMPLIFY_PERMISSIVE
        if uvs is not None:
            lock |= np.where(_uv_seam_vertices(p, uvs), A.SIMPLIFY_VERTEX_PROTECT, 0).astype(np.uint8)
    out, _ = A.simplify_with_attributes(np.ascontiguousarray(f, dtype=np.uint32).reshape(-1),
                                        np.ascontiguousarray(p, dtype=np.float32), attr, w, 3 * max(int(target), 1),
                                        float(np.finfo(np.float32).max), lock, options)
    return out.astype(np.int64).reshape(-1, 3)


def _lod(part, faces: np.ndarray):
    """The LOD as a MeshPart: ``part``'s vertices that ``faces`` use, renumbered."""
    from lopcook.mesh import used_ids

    keep = used_ids(faces, part.n_vertices)
    remap = np.full(part.n_vertices, -1, dtype=np.int64)
    remap[keep] = np.arange(keep.size)
    return replace(part, positions=part.positions[keep], indices=remap[faces].astype(np.uint32),
                   attributes={k: v[keep] for k, v in part.attributes.items()})


def one(part, variant: str, target: int) -> tuple:
    """(LOD MeshPart, seconds) of ``variant`` for ``target`` triangles."""
    from lopcook.mesh import degenerate_mask
    from lopcook.simplify.meshopt import simplify_meshopt

    faces = part.indices.astype(np.int64)
    faces = faces[~degenerate_mask(part.positions, faces)]
    uvs = part.uvs
    t0 = time.perf_counter()
    if variant == "pinned":
        res = simplify_meshopt(part.positions, faces, target, uvs=uvs, weld=True, lock_border=True)
        out = res.vertex_source[res.faces]
    else:
        out = _almeshopt(part.positions, faces, uvs, target, permissive=variant == "permissive")
    return _lod(part, out), time.perf_counter() - t0


def run(corpus: Path, meshes: list[str]) -> list[dict]:
    from lopcook.ingest import load
    from lopcook.simplify.error import hausdorff
    from lopcook.simplify.instances import copies
    from lopcook.simplify.topology import seam_stats

    rows = []
    for name in meshes:
        scene = load(corpus / ASSETS[name])
        for lead, _ in copies(scene.parts):
            part = scene.parts[lead]
            if part.n_triangles < 16:
                continue
            base = None if part.uvs is None else seam_stats(part).as_dict()
            row = {"asset": name, "part": part.name, "triangles": part.n_triangles, "seams": base, "lods": []}
            for r in RATIOS:
                target = int(round(r * part.n_triangles))
                if target < 4:
                    break
                cell = {"ratio": r, "target": target}
                for v in VARIANTS:
                    lod, sec = one(part, v, target)
                    cell[v] = {"triangles": lod.n_triangles, "full_m": hausdorff(lod, part)[0], "seconds": sec,
                               "seams": None if part.uvs is None else seam_stats(lod).as_dict()}
                row["lods"].append(cell)
                print(f"{name:<15} {part.name[-24:]:<24} {target:>7} " + "  ".join(
                    f"{v}: {cell[v]['triangles']:>6} {cell[v]['full_m']:.3g} m"
                    + ("" if cell[v]["seams"] is None else f" seams {cell[v]['seams']['seam_edges']}")
                    for v in VARIANTS), flush=True)
            rows.append(row)
    return rows


def _near(cell: dict, v: str) -> bool:
    return abs(cell[v]["triangles"] - cell["target"]) <= 0.05 * cell["target"]


def summarise(rows: list[dict], variant: str = "permissive") -> list[str]:
    """Per part: targets both reached within 5 % and the largest and median error ratio
    ``variant`` / pinned there; targets only ``variant`` (or only pinned) reached; the fewest
    triangles each reached; and whether every UV island of LOD 0 survives (``uv_islands`` equal)."""
    out = [f"{'asset':<15} {'part':<26} {'both':>4} {'worst':>6} {'median':>6} {'only this':>9} {'only pinned':>11} "
           f"{'fewest pinned':>13} {'fewest this':>11} {'islands kept pinned/this':>25}"]
    for r in rows:
        both = [c for c in r["lods"] if _near(c, "pinned") and _near(c, variant)]
        ratios = [c[variant]["full_m"] / c["pinned"]["full_m"] for c in both if c["pinned"]["full_m"] > 1e-12]
        isl = "-"
        if r["seams"] is not None:
            keep = [sum(c[v]["seams"]["uv_islands"] == r["seams"]["uv_islands"] for c in r["lods"])
                    for v in ("pinned", variant)]
            isl = f"{keep[0]}/{keep[1]} of {len(r['lods'])}"
        out.append(f"{r['asset']:<15} {r['part'][-26:]:<26} {len(both):>4} "
                   f"{max(ratios) if ratios else float('nan'):>6.2f} {float(np.median(ratios)) if ratios else float('nan'):>6.2f} "
                   f"{sum(_near(c, variant) and not _near(c, 'pinned') for c in r['lods']):>9} "
                   f"{sum(_near(c, 'pinned') and not _near(c, variant) for c in r['lods']):>11} "
                   f"{min(c['pinned']['triangles'] for c in r['lods']):>13,} "
                   f"{min(c[variant]['triangles'] for c in r['lods']):>11,} {isl:>25}")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--corpus", default=str(REPO.parent / "shared" / "corpus"))
    ap.add_argument("--meshes", default=",".join(ASSETS))
    ap.add_argument("--out", default=None, help="write the rows as JSON here")
    ap.add_argument("--summary", default=None, metavar="JSON", help="print the summary of an --out file and stop")
    args = ap.parse_args(argv)
    if args.summary:
        rows = json.loads(Path(args.summary).read_text())
        for v in ("new", "permissive"):
            print(f"{v} against pinned:")
            print("\n".join(summarise(rows, v)))
        return 0
    rows = run(Path(args.corpus), [m for m in args.meshes.split(",") if m])
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps(rows, indent=1, sort_keys=True))
    return 0


if __name__ == "__main__":
    sys.exit(main())
