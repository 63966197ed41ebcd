"""How the cook's cost grows with the mesh (``lopcook bench --scaling``): the Stanford bunny
subdivided 0..3 times (trimesh midpoint subdivision, as ``benchmarks/bench_ingest.py``) and the
chess set, as GLB; ``lopcook cook --lods 1/2,1/4`` and ``gltfpack -si 0.5 -vp 14`` on each, in
child processes (wall seconds, peak RSS in MiB). Rows have the ``SCALING_COLUMNS`` keys.
"""

from __future__ import annotations

import json
from pathlib import Path

from ..emit.gltf_writer import write_gltf
from ..ingest import load
from . import peers as P
from .common import ASSET_TIMEOUT_S, asset_name, cook_stages, log, mib, run_cook

SCALING_LODS = "1/2,1/4"


SCALING_GLTFPACK = {"bits": 14, "simplify": 0.5}


SCALING_COLUMNS = ("input", "triangles", "vertices", "tool", "config", "wall_s", "peak_rss_mb", "output_bytes",
                   "error")


def scaling_inputs(out_dir: Path, corpus: Path | None, max_triangles: int, opts) -> list[tuple[str, Path, int, int]]:
    """(name, GLB path, triangles, vertices): the bunny subdivided 0..3 times and the chess set,
    those with at most ``max_triangles`` triangles; written once into ``out_dir/scaling``."""
    import trimesh  # heavy (it loads scipy): imported by the one step that subdivides
    sdir = out_dir / "scaling"
    sdir.mkdir(parents=True, exist_ok=True)
    out = []
    if corpus is None:
        return out
    bunny = corpus / "stanford-bunny.obj"
    if bunny.is_file():
        mesh = trimesh.load(bunny, process=False)
        for k in range(4):
            tris, verts = len(mesh.faces), len(mesh.vertices)
            if tris > max_triangles:
                break
            path = sdir / f"bunny_s{k}.glb"
            if not path.exists():
                mesh.export(path)
            out.append((f"bunny s{k}", path, tris, verts))
            if k == 3 or 4 * tris > max_triangles:  # midpoint subdivision: 4x the triangles
                break
            mesh = mesh.subdivide()
    chess = corpus / "chess_set_flat.usdc"
    if chess.is_file():
        path = sdir / "chess_set.glb"
        meta = sdir / "chess_set.json"
        if not path.exists() or not meta.exists():
            scene = load(chess)
            write_gltf(path, scene.parts, generator="lopcook bench")
            meta.write_text(json.dumps({"triangles": scene.n_triangles, "vertices": scene.n_vertices}))
        m = json.loads(meta.read_text())
        if m["triangles"] <= max_triangles:
            out.append(("chess set", path, int(m["triangles"]), int(m["vertices"])))
    return sorted(out, key=lambda t: t[2])


def bench_scaling(out_dir: Path, corpus, opts, avail: dict) -> tuple[list, list]:
    """Scaling rows (lopcook cook --lods 1/2,1/4 and gltfpack -si 0.5 -vp 14 per input; best wall
    time of ``opts.repeat`` runs, largest peak RSS) and stage rows of the best cook."""
    rows, stage_rows = [], []
    for name, path, tris, verts in scaling_inputs(out_dir, corpus, opts.scaling_max_triangles, opts):
        best = None
        for _ in range(opts.repeat):
            log(opts, f"scaling: lopcook cook {name} ({tris:,} triangles) --lods {SCALING_LODS}")
            m, desc = run_cook(path, out_dir / "scaling" / f"{asset_name(path)}.lop", ["--lods", SCALING_LODS])
            if best is None or (desc is not None and m.wall_s < best[0].wall_s):
                best = (m, desc, max(m.peak_rss_bytes, best[0].peak_rss_bytes if best else 0))
        m, desc, rss = best
        err = "" if desc is not None else (m.stderr.strip().splitlines() or [f"exit {m.returncode}"])[-1]
        rows.append({"input": name, "triangles": tris, "vertices": verts, "tool": "lopcook",
                     "config": f"cook --lods {SCALING_LODS}", "wall_s": round(m.wall_s, 3), "peak_rss_mb": mib(rss),
                     "output_bytes": desc.get("file_bytes") if desc else "", "error": err})
        if desc is not None:
            for st, sec in cook_stages(desc.get("timings_s", {})).items():
                if st != "calibrate":
                    stage_rows.append({"cook": f"{name} 3 LODs", "triangles": tris, "stage": st,
                                       "seconds": round(sec, 4)})
        if avail.get("gltfpack"):
            best = None
            out = out_dir / "scaling" / f"{asset_name(path)}_gltfpack.glb"
            for _ in range(opts.repeat):
                log(opts, f"scaling: gltfpack -si 0.5 -vp 14 {name}")
                g = P.run_measured(P.gltfpack_argv(avail["gltfpack"], path, out, SCALING_GLTFPACK["bits"],
                                                   simplify=SCALING_GLTFPACK["simplify"]), timeout_s=ASSET_TIMEOUT_S)
                if best is None or (g.returncode == 0 and g.wall_s < best[0].wall_s):
                    best = (g, max(g.peak_rss_bytes, best[1] if best else 0))
            g, rss = best
            tail = (g.stderr.strip().splitlines() or [f"exit {g.returncode}"])[-1] if g.returncode else ""
            rows.append({"input": name, "triangles": tris, "vertices": verts, "tool": "gltfpack",
                         "config": "-si 0.5 -vp 14", "wall_s": round(g.wall_s, 3), "peak_rss_mb": mib(rss),
                         "output_bytes": out.stat().st_size if out.exists() else "", "error": tail})
    return rows, stage_rows


__all__ = ["SCALING_LODS", "SCALING_GLTFPACK", "SCALING_COLUMNS", "scaling_inputs", "bench_scaling"]
