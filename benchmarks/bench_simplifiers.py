"""Time and error of the three simplifiers: meshoptimizer, fast-simplification and pymeshlab.

Not a test (pytest does not collect benchmarks/). Usage::

    PYTHONPATH=. .venv/bin/python benchmarks/bench_simplifiers.py [--corpus ../shared/corpus]
        [--out bench-out/simplifiers] [--ratios 0.5,0.25,0.125,0.0625] [--no-big]

Inputs: the Stanford bunny, fandisk, DamagedHelmet, three chess pieces of chess_set_flat.usdc
(``CHESS``: BishopL, King, a pawn) and the bunny subdivided
twice (1,111,216 triangles, trimesh midpoint subdivision, written once as a GLB into ``--out``, as
``benchmarks/bench_ingest.py`` and ``lopcook bench --scaling`` make it).

Each part is simplified from LOD 0 to ``round(ratio * triangles)`` at every ratio by each backend
through ``lopcook.simplify.backends``' own preparation (``prepare``) and backend call
(``_run_backend``, the arguments lopcook uses) in two modes:

* ``geometry``: the mesh welded by position (seams ignored), borders locked;
* ``seams`` (parts with UVs): ``seams="simplify"`` (meshoptimizer and pymeshlab collapse the UV
  seams along themselves; fast-simplification cannot, so it has no row).

Recorded per run: backend seconds (the simplifier call only, wall clock, best of ``--repeat``),
triangles reached, the measured symmetric Hausdorff distance to LOD 0 (``lod.hausdorff``:
vertices and face centroids of each mesh against the other) and, for meshoptimizer, its own
error estimate (``MeshoptResult.error_m``). Writes ``simplifiers.json``, ``simplifiers.md`` and
``simplifiers.png`` (time against measured error, one panel per mesh) into ``--out``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
BACKENDS = ("meshopt", "fast", "pymeshlab")
#: chess pieces: the bishop (no LODs with locked seams today), the king and a pawn
CHESS = ("/ChessSet/White/BishopL/Geom/Render", "/ChessSet/White/King/Geom/Render",
         "/ChessSet/White/Pawns[0]/Pawn/Geom_Body/Render")


def big_mesh(out: Path) -> Path:
    import trimesh

    path = out / "bunny_s2.glb"
    if not path.exists():
        src = REPO.parent / "shared" / "corpus" / "stanford-bunny.obj"
        out.mkdir(parents=True, exist_ok=True)
        trimesh.load(src, process=False).subdivide().subdivide().export(path)
    return path


def inputs(corpus: Path, out: Path, big: bool, wanted: set) -> list[tuple[str, object]]:
    from lopcook.ingest import load

    if wanted:
        return [(name, part) for name, part in inputs(corpus, out, big and "bunny 1.1M" in wanted, set())
                if name in wanted]

    parts = [("bunny", load(corpus / "stanford-bunny.obj").parts[0]),
             ("fandisk", load(corpus / "fandisk.obj").parts[0]),
             ("DamagedHelmet", load(corpus / "DamagedHelmet" / "DamagedHelmet.gltf").parts[0])]
    chess = {p.name: p for p in load(corpus / "chess_set_flat.usdc").parts}
    for piece in CHESS:
        parts.append((f"chess {piece.split('/')[3]}", chess[piece]))
    if big:
        parts.append(("bunny 1.1M", load(big_mesh(out)).parts[0]))
    return parts


def run_one(L, part, backend: str, mode: str, target: int, repeat: int):
    from lopcook.types import MeshPart

    work, _ = B.prepare(part, mode)
    best, raw = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        raw = B.run_backend(backend, work, min(target, work.faces.shape[0] - 1), True, True)
        best = min(best, time.perf_counter() - t0)
    lod = MeshPart(name="lod", positions=np.asarray(raw.positions, dtype=np.float64),
                   indices=np.asarray(raw.faces).astype(np.uint32))
    h = E.hausdorff(part, lod)[0]
    own = getattr(raw, "error_m", None)
    return {"seconds": best, "triangles": int(lod.n_triangles), "hausdorff_m": h,
            "own_error_m": None if own is None else float(own)}


def _merge(old: list[dict], new: list[dict]) -> list[dict]:
    """``old`` with the rows of ``new`` replacing those of the same (mesh, mode, backend, ratio)."""
    key = lambda r: (r["mesh"], r["mode"], r["backend"], r["ratio"])  # noqa: E731
    fresh = {key(r): r for r in new}
    out = [fresh.pop(key(r), r) for r in old]
    return out + [r for r in new if key(r) in fresh]


def table(rows: list[dict]) -> str:
    out = ["| mesh | triangles | mode | ratio | backend | seconds | triangles reached | Hausdorff (m) | "
           "own error (m) | Hausdorff / pymeshlab's |", "|---|---:|---|---:|---|---:|---:|---:|---:|---:|"]
    ref = {(r["mesh"], r["mode"], r["ratio"]): r["hausdorff_m"] for r in rows if r["backend"] == "pymeshlab"}
    for r in rows:
        base = ref.get((r["mesh"], r["mode"], r["ratio"]))
        rel = f"{r['hausdorff_m'] / base:.2f}" if base else "-"
        own = "-" if r["own_error_m"] is None else f"{r['own_error_m']:.3g}"
        out.append(f"| {r['mesh']} | {r['n0']:,} | {r['mode']} | 1/{round(1 / r['ratio'])} | {r['backend']} | "
                   f"{r['seconds']:.3f} | {r['triangles']:,} | {r['hausdorff_m']:.3g} | {own} | {rel} |")
    return "\n".join(out) + "\n"


def chart(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    meshes = list(dict.fromkeys(r["mesh"] for r in rows))
    cols = 3
    nrow = (len(meshes) + cols - 1) // cols
    fig, axes = plt.subplots(nrow, cols, figsize=(5 * cols, 4 * nrow), squeeze=False)
    style = {"meshopt": ("tab:green", "o"), "fast": ("tab:blue", "s"), "pymeshlab": ("tab:red", "^")}
    for ax, mesh in zip(axes.ravel(), meshes):
        for (backend, mode), ls in [((b, m), "-" if m == "geometry" else "--") for b in BACKENDS
                                    for m in ("geometry", "seams")]:
            sel = [r for r in rows if r["mesh"] == mesh and r["backend"] == backend and r["mode"] == mode]
            if not sel:
                continue
            c, mk = style[backend]
            ax.plot([r["seconds"] for r in sel], [r["hausdorff_m"] for r in sel], ls, color=c, marker=mk,
                    label=f"{backend} ({mode})")
            for r in sel:
                ax.annotate(f"1/{round(1 / r['ratio'])}", (r["seconds"], r["hausdorff_m"]), fontsize=6,
                            xytext=(2, 2), textcoords="offset points")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.yaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        n0 = next(r["n0"] for r in rows if r["mesh"] == mesh)
        ax.set_title(f"{mesh} ({n0:,} triangles)", fontsize=9)
        ax.set_xlabel("simplifier seconds")
        ax.set_ylabel("symmetric Hausdorff to LOD 0 (m)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6)
    for ax in axes.ravel()[len(meshes):]:
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


CHAINS = (("spot.obj", "simplify"), ("spot.obj", "lock"), ("DamagedHelmet/DamagedHelmet.gltf", "simplify"),
          ("DamagedHelmet/DamagedHelmet.gltf", "lock"), ("stanford-bunny.obj", "lock"))


def chains(L, corpus: Path, out: Path) -> int:
    """``lod.lod_chain`` (default ratios 1/2, 1/4, ... from the previous LOD, no fallback) with
    meshopt and pymeshlab; "meshopt" is added to ``lod.BACKENDS`` for the run."""
    from lopcook.ingest import load

    if "meshopt" not in B.BACKENDS:
        B.BACKENDS = B.BACKENDS + ("meshopt",)
    rows = []
    for name, seams in CHAINS:
        part = load(corpus / name).parts[0]
        for backend in ("meshopt", "pymeshlab"):
            t0 = time.perf_counter()
            lods, report = L.lod_chain(part, backend=backend, seams=seams, fallback=False)
            rows.append({"mesh": name, "seams": seams, "backend": backend, "seconds": time.perf_counter() - t0,
                         "triangles": [lod.triangles for lod in lods], "error_m": [lod.error_m for lod in lods],
                         "stop": report.stop_reason})
            print(f"{name:<34} {seams:<8} {backend:<9} {rows[-1]['seconds']:6.1f} s  "
                  + " ".join(f"{t}:{e:.3g}" for t, e in zip(rows[-1]["triangles"][1:], rows[-1]["error_m"][1:]))
                  + f"  ({report.stop_reason})", flush=True)
    (out / "chains.json").write_text(json.dumps(rows, indent=1))
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--corpus", default=os.environ.get("LOPCOOK_CORPUS", str(REPO.parent / "shared" / "corpus")))
    ap.add_argument("--out", default=str(REPO / "bench-out" / "simplifiers"))
    ap.add_argument("--ratios", default="0.5,0.25,0.125,0.0625")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--no-big", action="store_true", help="skip the 1.1M-triangle mesh")
    ap.add_argument("--backends", default=",".join(BACKENDS), help="comma-separated subset of " + ", ".join(BACKENDS))
    ap.add_argument("--meshes", default="", help="comma-separated mesh names to run (default: all)")
    ap.add_argument("--update", action="store_true",
                    help="replace the rows measured now in an existing simplifiers.json, keep the others")
    ap.add_argument("--chart-only", action="store_true", help="redraw table and chart from simplifiers.json")
    ap.add_argument("--chains", action="store_true",
                    help="instead: full lod_chain runs (each LOD from the previous one), meshopt vs pymeshlab")
    args = ap.parse_args()
    from lopcook.simplify import backends as B
    from lopcook.simplify import chain as L
    from lopcook.simplify import error as E

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.chains:
        return chains(L, Path(args.corpus), out)
    ratios = [float(r) for r in args.ratios.split(",")]
    backends = [b for b in args.backends.split(",") if b]
    wanted = {m for m in args.meshes.split(",") if m}
    old = json.loads((out / "simplifiers.json").read_text()) if (args.update or args.chart_only) else []
    if args.chart_only:
        (out / "simplifiers.md").write_text(table(old))
        chart(old, out / "simplifiers.png")
        return 0
    rows = []
    for mesh, part in inputs(Path(args.corpus), out, not args.no_big, wanted):
        modes = ["geometry"] + (["seams"] if part.uvs is not None else [])
        for mode in modes:
            for backend in backends:
                if mode == "seams" and backend == "fast":
                    continue
                for r in ratios:
                    target = int(round(r * part.n_triangles))
                    try:
                        res = run_one(L, part, backend, "ignore" if mode == "geometry" else "simplify", target,
                                      args.repeat)
                    except Exception as exc:  # noqa: BLE001 - a crash is a measurement too
                        res = {"seconds": float("nan"), "triangles": 0, "hausdorff_m": float("nan"),
                               "own_error_m": None, "error": f"{type(exc).__name__}: {exc}"}
                    row = {"mesh": mesh, "n0": part.n_triangles, "mode": mode, "backend": backend, "ratio": r,
                           "target": target, **res}
                    rows.append(row)
                    own = "" if res["own_error_m"] is None else f" own {res['own_error_m']:.3g}"
                    print(f"{mesh:<16} {mode:<8} {backend:<9} 1/{round(1 / r):<3} {res['seconds']:8.3f} s "
                          f"{res['triangles']:>8,} tris  H {res['hausdorff_m']:.3g} m{own}", flush=True)
                    (out / "simplifiers.json").write_text(json.dumps(_merge(old, rows), indent=1))
    rows = _merge(old, rows)
    (out / "simplifiers.md").write_text(table(rows))
    chart(rows, out / "simplifiers.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
