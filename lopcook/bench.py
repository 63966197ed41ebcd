"""``lopcook bench``: lopcook against gltfpack, glTF-Transform and Draco on the same meshes, and how
the cook's cost grows with the mesh. Not collected by pytest; see docs/bench.md.

Steps, per asset (``bench_asset``):

1. Ingest the source (``lopcook.ingest.load``, default settings) and write it as ``input.glb``
   (``lopcook.emit.gltf_writer.write_gltf``: world-space float32 positions, normals, UVs,
   colours; no textures) and ``parts.npz`` (for Draco): every peer reads the same mesh.
2. lopcook: ``python -m lopcook cook SOURCE --json`` in a child process (default options; with
   ``--calibrated`` also ``--target-psnr 40``), then AP and CAP at each level: GPU bytes
   (``lopcook.lop.summary.memory_rows``), position error and cracks (CPU reference decoder,
   vertices matched by order), masked PSNR (``lopcook.verify.evaluate.evaluate``).
3. Each peer configuration in a child process; its output ingested back with lopcook's reader
   (Draco: decoded by DracoPy), matched to the source by nearest neighbour, measured, and
   rendered with float positions against the float source (``lopcook.benchkit.render``).
4. Scaling (``bench_scaling``): the Stanford bunny subdivided 0..3 times (trimesh midpoint
   subdivision, as ``benchmarks/bench_ingest.py``) and the chess set, as GLB; ``lopcook cook
   --lods 1/2,1/4`` and ``gltfpack -si 0.5 -vp 14`` on each.
5. CSVs, charts and ``summary.json`` / ``summary.md`` with the acceptance checks (``checks``, ``write_outputs``).
"""

from __future__ import annotations

import csv
import json
import math
import os
import re
import sys
import time
from pathlib import Path

import numpy as np

from .benchkit import metrics as BM
from .benchkit.draco_run import decode_buffers, write_parts
from .benchkit import peers as P

DEFAULT_ASSETS = ("stanford-bunny.obj", "fandisk.obj", "DamagedHelmet/DamagedHelmet.gltf", "chess_set_flat.usdc")
DEFAULT_LEVELS = (6, 7, 8, 9, 10, 11)
PEER_BITS = (10, 12, 14, 16)
SCALING_LODS = "1/2,1/4"
SCALING_GLTFPACK = {"bits": 14, "simplify": 0.5}
TARGET_PSNR_DB = 40.0
PEER_BYTES_16BIT = 8.0
ASSET_TIMEOUT_S = 3600

ROW_COLUMNS = ("asset", "tool", "config", "bits", "level", "vertices", "triangles", "file_bytes",
               "gpu_position_bytes", "gpu_bytes_per_vertex", "max_err_rel", "rms_err_rel", "cracks",
               "cracks_between_parts", "psnr_min_db", "psnr_mean_db", "depth_order_errors", "wall_s",
               "peak_rss_mb", "match", "accuracy_from", "cc_check", "error")
SCALING_COLUMNS = ("input", "triangles", "vertices", "tool", "config", "wall_s", "peak_rss_mb", "output_bytes",
                   "error")
STAGE_COLUMNS = ("cook", "triangles", "stage", "seconds")
STAGES = ("ingest", "lod", "E_v", "depth", "analyse other", "bins/planes", "write", "calibrate")


def _log(opts, msg: str) -> None:
    if not getattr(opts, "quiet", False):
        print(f"bench: {msg}", file=sys.stderr, flush=True)


def corpus_dir() -> Path | None:
    """``$LOPCOOK_CORPUS`` or ``<repo>/../shared/corpus`` (where it holds corpus.json)."""
    env = os.environ.get("LOPCOOK_CORPUS")
    for c in ([Path(env)] if env else []) + [P.REPO.parent / "shared" / "corpus"]:
        if (c / "corpus.json").is_file():
            return c
    return None


def asset_name(path) -> str:
    """Short stable name of an asset: the file stem, safe for paths."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", Path(path).stem)


def result_row(**kw) -> dict:
    """One results.csv row: every ``ROW_COLUMNS`` key, empty unless given (None counts as not given)."""
    r = {c: "" for c in ROW_COLUMNS}
    r.update({k: v for k, v in kw.items() if v is not None})
    return r


def _mb(nbytes) -> float:
    """Bytes in MiB (2^20 bytes), one decimal: the unit of every ``peak_rss_mb`` column."""
    return round(float(nbytes) / 2**20, 1)


# ---- the source -------------------------------------------------------------------------------

class Source:
    """The ingested source and what every measurement needs of it (all parts concatenated)."""

    def __init__(self, scene):
        self.scene = scene
        parts = scene.parts
        self.offsets = np.cumsum([0] + [p.n_vertices for p in parts])
        self.positions = np.concatenate([p.positions for p in parts])
        self.part = np.repeat(np.arange(len(parts)), [p.n_vertices for p in parts])
        self.attr = np.concatenate([BM.attribute_features(p.normals, p.uvs, p.n_vertices) for p in parts])
        self.classes = BM.colocation_classes(self.positions)
        lo, hi = scene.bounds()
        self.diagonal = float(np.linalg.norm(hi - lo))
        from .grid import Grid

        self.extent = float(Grid.fit([p.positions for p in parts]).extent)
        self.triangles = int(sum(p.n_triangles for p in parts))
        self.vertices = int(self.positions.shape[0])




def write_inputs(src: Source, adir: Path) -> tuple[Path, Path]:
    """input.glb (every peer's input) and parts.npz (Draco's) in ``adir``."""
    from .emit.gltf_writer import write_gltf

    glb = adir / "input.glb"
    write_gltf(glb, src.scene.parts, generator="lopcook bench")
    npz = adir / "parts.npz"
    write_parts(npz, src.scene.parts)
    return glb, npz


def glb_json(path) -> dict:
    """The JSON chunk of a .glb (or the whole .gltf)."""
    import struct

    data = Path(path).read_bytes()
    if data[:4] != b"glTF":
        return json.loads(data)
    length, kind = struct.unpack_from("<I4s", data, 12)
    return json.loads(data[20:20 + length])


# ---- lopcook ----------------------------------------------------------------------------------

def cook_stages(timings: dict) -> dict:
    """``lopcook cook --json`` timings_s -> the bench's stages (seconds). E_v and depth are the
    analysis of LOD 0; "analyse other" is the rest of the analysis (grid, co-located sharing,
    and the analysis of the other LODs)."""
    ev = float(timings.get("analyse.attribute_error", 0.0))
    depth = float(timings.get("analyse.depth", 0.0))
    out = {"ingest": timings.get("ingest", 0.0), "lod": timings.get("lod", 0.0), "E_v": ev, "depth": depth,
           "analyse other": max(0.0, float(timings.get("analyse", 0.0)) - ev - depth),
           "bins/planes": timings.get("emit", 0.0), "write": timings.get("write", 0.0),
           "calibrate": timings.get("calibrate", 0.0)}
    return {k: float(v) for k, v in out.items()}


def run_cook(source, out_lop, extra=(), timeout_s=ASSET_TIMEOUT_S) -> tuple[P.Measured, dict | None]:
    """``python -m lopcook cook SOURCE -o OUT --json`` in a child process; (measured, JSON or None)."""
    m = P.run_measured([sys.executable, "-m", "lopcook", "cook", str(source), "-o", str(out_lop), "--json",
                        *extra], timeout_s=timeout_s)
    desc = None
    if m.returncode == 0:
        try:
            desc = json.loads(m.stdout)
        except json.JSONDecodeError:
            desc = None
    return m, desc


def _lopcook_positions(c, src: Source, orders, level: int, variant: str) -> tuple[np.ndarray, np.ndarray]:
    """Decoded positions (float32 as the shaders compute them) of every vertex at ``level`` for AP or
    CAP, and the source vertex of each (the container keeps the source's vertices; binned order)."""
    from .lop.bitplane import decode, reconstruct_float32
    from .lop.reader import gpu_buffer
    from .verify.buffers import ap_buffer

    g = c.manifest["grid"]
    cell = g["extent"] / float(1 << 24)
    pos, match = [], []
    for i in range(len(c.manifest["parts"])):
        buf = (ap_buffer if variant == "AP" else gpu_buffer)(c, i, 0, level)
        values, widths = decode(buf.words, buf.vertex_id, buf.bit_id, level)
        pos.append(reconstruct_float32(values, widths, g["origin"], cell))
        match.append(src.offsets[i] + orders[i])
    return np.concatenate(pos), np.concatenate(match)


def lopcook_rows(asset: str, source_path, src: Source, adir: Path, opts, *, calibrated=False) -> tuple[list, dict]:
    """Rows for lopcook AP and CAP at each level, and {"stages": {...}, "cook": measured dict}."""
    from .lop.container import read
    from .lop.summary import memory_rows
    from .verify.buffers import source_order
    from .verify.evaluate import evaluate

    name = "CAP (calibrated)" if calibrated else "CAP"
    lop = adir / ("lopcook_cal.lop" if calibrated else "lopcook.lop")
    extra = ["--target-psnr", str(TARGET_PSNR_DB)] if calibrated else []
    _log(opts, f"{asset}: lopcook cook{' --target-psnr 40' if calibrated else ''}")
    m, desc = run_cook(source_path, lop, extra)
    if desc is None:
        err = (m.stderr.strip().splitlines() or [f"exit {m.returncode}"])[-1]
        return [result_row(asset=asset, tool="lopcook", config=name, error=err, wall_s=round(m.wall_s, 3))], {}
    info = {"stages": cook_stages(desc.get("timings_s", {})), "wall_s": m.wall_s, "peak_rss_bytes": m.peak_rss_bytes}
    c = read(lop)
    mem = {r["level"]: r for r in memory_rows(c, levels=opts.levels)}
    orders = source_order(c, src.scene)
    ev = None
    if not opts.skip_render:
        _log(opts, f"{asset}: render lopcook AP/CAP, levels {opts.levels[0]}-{opts.levels[-1]}, {opts.views} views")
        ev = evaluate(c, src.scene, levels=opts.levels, views=opts.views, resolution=opts.resolution,
                      variants=("cap",) if calibrated else ("ap", "cap"))
        ev = {r["level"]: r for r in ev["levels"]}
    rows = []
    for variant in (("CAP",) if calibrated else ("AP", "CAP")):
        for level in opts.levels:
            pos, match = _lopcook_positions(c, src, orders, level, variant)
            err = BM.position_errors(src.positions, pos, match, src.diagonal)
            cr = BM.count_cracks(src.classes, src.part, pos, match)
            gpu = mem[level]["ap_bytes" if variant == "AP" else "cap_bytes"]
            r = result_row(asset=asset, tool="lopcook", config=name if variant == "CAP" else "AP", bits=level,
                           level=level, vertices=src.vertices, triangles=src.triangles, file_bytes=lop.stat().st_size,
                           gpu_position_bytes=gpu, gpu_bytes_per_vertex=round(gpu / src.vertices, 4),
                           max_err_rel=err["max_rel"], rms_err_rel=err["rms_rel"], cracks=cr["cracks"],
                           cracks_between_parts=cr["cracks_between_parts"], wall_s=round(m.wall_s, 3),
                           peak_rss_mb=_mb(m.peak_rss_bytes), match="order")
            if ev is not None:
                e = ev[level][variant.lower()]
                r.update(psnr_min_db=_db(e["psnr_min"]), psnr_mean_db=_db(e["psnr_mean"]),
                         depth_order_errors=e["depth_order_errors"])
            rows.append(r)
    return rows, info


def _db(v):
    """PSNR for the CSV: None (identical images) is inf."""
    return float("inf") if v is None else round(float(v), 3)


# ---- peers ------------------------------------------------------------------------------------

def peer_configs(avail: dict, bits=PEER_BITS) -> list[dict]:
    """Every peer run of the accuracy part: {"tool", "config", "bits", "compress"}."""
    out = []
    for b in bits:
        if avail.get("gltfpack"):
            out.append({"tool": "gltfpack", "config": f"-vp {b}", "bits": b, "compress": False})
            out.append({"tool": "gltfpack", "config": f"-vp {b} -cc", "bits": b, "compress": True})
        if avail.get("gltf-transform"):
            out.append({"tool": "gltf-transform", "config": f"quantize --quantize-position {b}", "bits": b,
                        "compress": False})
        if avail.get("draco"):
            out.append({"tool": "draco", "config": f"qp {b}", "bits": b, "compress": False})
    return out


def _decoded_output(cfg: dict, out_path: Path):
    """Decoded parts of a peer output: list of (positions (n, 3) float64, indices (m, 3), attr (n, 5))."""
    if cfg["tool"] == "draco":
        return [(pts, tri, BM.attribute_features(nrm, uv, len(pts))) for pts, tri, nrm, uv in decode_buffers(out_path)]
    from .ingest import load

    scene = load(out_path)
    return [(p.positions, p.indices, BM.attribute_features(None if p.normals_computed else p.normals, p.uvs, p.n_vertices))
            for p in scene.parts]


def peer_run(cfg: dict, avail: dict, glb: Path, npz: Path, adir: Path) -> tuple[P.Measured, Path]:
    """Run one peer configuration ``cfg`` on the bench's ``input.glb`` (Draco: ``parts.npz``) in a child
    process; returns its wall time and peak RSS, and the output path in ``adir``."""
    tool = cfg["tool"]
    tag = re.sub(r"[^A-Za-z0-9]+", "_", f"{tool}_{cfg['config']}").strip("_")
    if tool == "gltfpack":
        out = adir / f"{tag}.glb"
        argv = P.gltfpack_argv(avail[tool], glb, out, cfg["bits"], compress=cfg["compress"])
    elif tool == "gltf-transform":
        out = adir / f"{tag}.glb"
        argv = P.gltf_transform_argv(avail[tool], glb, out, cfg["bits"])
    else:
        out = adir / f"{tag}.npz"
        argv = P.draco_argv(avail[tool], npz, out, cfg["bits"])
    if out.exists():
        out.unlink()
    return P.run_measured(argv, timeout_s=ASSET_TIMEOUT_S), out


def cc_check(cc_path: Path, cfg: dict, avail: dict | None) -> str:
    """Check that a gltfpack ``-cc`` file decodes to the same positions as the ``-cc``-free file of
    the same bits: glTF-Transform (``gltf-transform copy``, which decodes EXT_meshopt_compression
    with the meshoptimizer decoder) writes it uncompressed, lopcook's reader reads both, and the
    multisets of float positions and of triangles (as position triples) must be equal (gltfpack
    orders vertices differently with -cc). Returns "identical", "differ: ...", or "" when
    glTF-Transform is not installed."""
    exe = (avail or {}).get("gltf-transform")
    plain = cc_path.with_name(cc_path.name.replace("_cc.glb", ".glb"))
    if not exe or not plain.exists():
        return ""
    from .ingest import load

    dec = cc_path.with_name(cc_path.stem + "_decoded.glb")
    r = P.run_measured([exe, "copy", str(cc_path), str(dec)], timeout_s=ASSET_TIMEOUT_S)
    if r.returncode != 0 or not dec.exists():
        return f"differ: gltf-transform copy failed (exit {r.returncode})"

    def canon(path):
        """Sorted distinct positions with counts; triangles as sorted triples of distinct-position ids."""
        parts = load(path).parts
        pos = np.concatenate([p.positions for p in parts])
        offsets = np.cumsum([0] + [p.n_vertices for p in parts])
        uniq, inverse, counts = np.unique(pos, axis=0, return_inverse=True, return_counts=True)
        tri = np.sort(inverse.reshape(-1)[np.concatenate([p.indices.astype(np.int64) + o
                                                          for p, o in zip(parts, offsets)])], axis=1)
        return (uniq, counts), np.unique(tri, axis=0, return_counts=True)

    (pa, ca), (ta, tca) = canon(plain)
    (pb, cb), (tb, tcb) = canon(dec)
    same_pos = pa.shape == pb.shape and np.array_equal(pa, pb) and np.array_equal(ca, cb)
    same_tri = ta.shape == tb.shape and np.array_equal(ta, tb) and np.array_equal(tca, tcb)
    return "identical" if same_pos and same_tri else f"differ: positions {'=' if same_pos else '!='}, " \
                                                      f"triangles {'=' if same_tri else '!='}"


def peer_measure(cfg: dict, m: P.Measured, out: Path, src: Source, asset: str, avail: dict | None = None):
    """(row without PSNR, render Variant or None)."""
    from .benchkit.render import Variant

    base = dict(asset=asset, tool=cfg["tool"], config=cfg["config"], bits=cfg["bits"], wall_s=round(m.wall_s, 3),
                peak_rss_mb=_mb(m.peak_rss_bytes), triangles=src.triangles)
    if m.returncode != 0 or not out.exists():
        tail = (m.stderr.strip() or m.stdout.strip()).splitlines()
        return result_row(**base, error=f"exit {m.returncode}: {tail[-1] if tail else 'no output'}"), None
    if cfg["tool"] == "draco":
        with np.load(out) as z:
            file_bytes = int(sum(z[n].size for n in z.files))
    else:
        file_bytes = out.stat().st_size
    if cfg["compress"]:  # EXT_meshopt_compression: bytes from this file, accuracy from the -cc-free one
        gpu, verts = BM.gltf_position_bytes(glb_json(out))
        return result_row(**base, file_bytes=file_bytes, gpu_position_bytes=gpu, vertices=verts,
                    gpu_bytes_per_vertex=round(gpu / max(verts, 1), 4),
                    accuracy_from=cfg["config"].replace(" -cc", ""), cc_check=cc_check(out, cfg, avail)), None
    parts = _decoded_output(cfg, out)
    pos = np.concatenate([p[0] for p in parts])
    attr = np.concatenate([p[2] for p in parts])
    match = BM.match_vertices(src.positions, pos, src.attr, attr)
    if cfg["tool"] == "draco":
        gpu = 12 * pos.shape[0]  # decoded to float32 on the GPU
    else:
        gpu, _ = BM.gltf_position_bytes(glb_json(out))
    err = BM.position_errors(src.positions, pos, match, src.diagonal)
    cr = BM.count_cracks(src.classes, src.part, pos, match)
    row = result_row(**base, file_bytes=file_bytes, vertices=int(pos.shape[0]), gpu_position_bytes=gpu,
               gpu_bytes_per_vertex=round(gpu / max(pos.shape[0], 1), 4), max_err_rel=err["max_rel"],
               rms_err_rel=err["rms_rel"], cracks=cr["cracks"], cracks_between_parts=cr["cracks_between_parts"],
               match="nearest")
    vparts, start = [], 0
    for p_pos, p_idx, _ in parts:
        mm = match[start:start + p_pos.shape[0]]
        start += p_pos.shape[0]
        part = int(np.bincount(src.part[mm]).argmax()) if mm.size else 0
        vparts.append((p_pos.astype(np.float32), p_idx.astype(np.uint32), part, mm))
    return row, Variant(key=f"{cfg['tool']} {cfg['config']}", parts=vparts)


def bench_asset(path, out_dir: Path, opts, avail: dict) -> tuple[list, list]:
    """Accuracy rows and stage rows of one asset. Failures become rows with ``error``."""
    from .ingest import load

    asset = asset_name(path)
    adir = out_dir / "assets" / asset
    adir.mkdir(parents=True, exist_ok=True)
    t_asset = time.perf_counter()
    _log(opts, f"{asset}: ingest {path}")
    src = Source(load(path))
    _log(opts, f"{asset}: {len(src.scene.parts)} parts, {src.vertices:,} vertices, {src.triangles:,} triangles")
    glb, npz = write_inputs(src, adir)
    rows, stage_rows = [], []
    for calibrated in ((False, True) if opts.calibrated else (False,)):
        try:
            r, info = lopcook_rows(asset, path, src, adir, opts, calibrated=calibrated)
        except Exception as exc:  # noqa: BLE001 -- one row with the error, never a crash
            r, info = [result_row(asset=asset, tool="lopcook", config="CAP", error=f"{type(exc).__name__}: {exc}")], {}
        rows += r
        for st, sec in (info.get("stages") or {}).items():
            if st != "calibrate" or calibrated:
                stage_rows.append({"cook": asset + (" cal" if calibrated else ""), "triangles": src.triangles,
                                   "stage": st, "seconds": round(sec, 4)})
    variants, peer_rows = [], []
    for cfg in peer_configs(avail, opts.bits):
        _log(opts, f"{asset}: {cfg['tool']} {cfg['config']}")
        try:
            m, out = peer_run(cfg, avail, glb, npz, adir)
            row, variant = peer_measure(cfg, m, out, src, asset, avail)
        except Exception as exc:  # noqa: BLE001
            row, variant = result_row(asset=asset, tool=cfg["tool"], config=cfg["config"], bits=cfg["bits"],
                                error=f"{type(exc).__name__}: {exc}"), None
        if row["error"]:
            _log(opts, f"{asset}: {cfg['tool']} {cfg['config']} failed: {row['error']}")
        peer_rows.append(row)
        if variant is not None:
            variants.append(variant)
    renders = {}
    if variants and not opts.skip_render:
        _log(opts, f"{asset}: render {len(variants)} peer outputs, levels {opts.levels[0]}-{opts.levels[-1]}, "
                   f"{opts.views} views at {opts.resolution[0]}x{opts.resolution[1]}")
        from .benchkit.render import render_variants

        try:
            renders = render_variants(src.scene, variants, levels=opts.levels, views=opts.views,
                                      resolution=opts.resolution, extent=src.extent,
                                      progress=lambda s: _log(opts, f"{asset}: {s}"))
        except Exception as exc:  # noqa: BLE001
            _log(opts, f"{asset}: peer render failed: {type(exc).__name__}: {exc}")
    for row in peer_rows:
        key = f"{row['tool']} {row['accuracy_from'] or row['config']}"
        src_row = next((r for r in peer_rows if r["tool"] == row["tool"] and r["config"] == row["accuracy_from"]),
                       None) if row["accuracy_from"] else None
        for level in opts.levels:
            r = dict(row, level=level)
            if src_row is not None:
                for k in ("max_err_rel", "rms_err_rel", "cracks", "cracks_between_parts", "match"):
                    r[k] = src_row[k]
            got = renders.get(key, {}).get(level)
            if got is not None:
                r.update(psnr_min_db=_db(got["psnr_min"]), psnr_mean_db=_db(got["psnr_mean"]),
                         depth_order_errors=got["depth_order_errors"])
            rows.append(r)
    _log(opts, f"{asset}: done in {time.perf_counter() - t_asset:.1f} s")
    return rows, stage_rows


# ---- scaling ----------------------------------------------------------------------------------

def scaling_inputs(out_dir: Path, corpus: Path | None, max_triangles: int, opts) -> list[tuple[str, Path, int, int]]:
    """(name, GLB path, triangles, vertices): the bunny subdivided 0..3 times and the chess set,
    those with at most ``max_triangles`` triangles; written once into ``out_dir/scaling``."""
    import trimesh

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
        from .emit.gltf_writer import write_gltf
        from .ingest import load

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
            _log(opts, f"scaling: lopcook cook {name} ({tris:,} triangles) --lods {SCALING_LODS}")
            m, desc = run_cook(path, out_dir / "scaling" / f"{asset_name(path)}.lop", ["--lods", SCALING_LODS])
            if best is None or (desc is not None and m.wall_s < best[0].wall_s):
                best = (m, desc, max(m.peak_rss_bytes, best[0].peak_rss_bytes if best else 0))
        m, desc, rss = best
        err = "" if desc is not None else (m.stderr.strip().splitlines() or [f"exit {m.returncode}"])[-1]
        rows.append({"input": name, "triangles": tris, "vertices": verts, "tool": "lopcook",
                     "config": f"cook --lods {SCALING_LODS}", "wall_s": round(m.wall_s, 3), "peak_rss_mb": _mb(rss),
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
                _log(opts, f"scaling: gltfpack -si 0.5 -vp 14 {name}")
                g = P.run_measured(P.gltfpack_argv(avail["gltfpack"], path, out, SCALING_GLTFPACK["bits"],
                                                   simplify=SCALING_GLTFPACK["simplify"]), timeout_s=ASSET_TIMEOUT_S)
                if best is None or (g.returncode == 0 and g.wall_s < best[0].wall_s):
                    best = (g, max(g.peak_rss_bytes, best[1] if best else 0))
            g, rss = best
            tail = (g.stderr.strip().splitlines() or [f"exit {g.returncode}"])[-1] if g.returncode else ""
            rows.append({"input": name, "triangles": tris, "vertices": verts, "tool": "gltfpack",
                         "config": "-si 0.5 -vp 14", "wall_s": round(g.wall_s, 3), "peak_rss_mb": _mb(rss),
                         "output_bytes": out.stat().st_size if out.exists() else "", "error": tail})
    return rows, stage_rows


# ---- outputs ----------------------------------------------------------------------------------

def write_csv(path: Path, rows: list[dict], columns) -> None:
    """Write ``rows`` to the CSV ``path`` atomically with the header ``columns`` (missing keys empty,
    floats to 6 significant digits, infinity as ``inf``)."""
    from .atomic import write_atomic

    import io

    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(columns), extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: _csv_value(r.get(k, "")) for k in columns})
    write_atomic(path, buf.getvalue().encode())


def _csv_value(v):
    if isinstance(v, float):
        if math.isinf(v):
            return "inf"
        return f"{v:.6g}"
    return v


def _f(v) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return float("nan")


def checks(rows: list[dict], scaling: list[dict], assets: list[str], charts: dict, levels) -> list[dict]:
    """The bench's acceptance checks (docs/bench.md), computed from the rows: each {"check", "status"
    (pass / miss / not measured), "detail", numbers}."""
    out = []
    # (1) Pareto chart for each asset
    have = {r["asset"] for r in rows if r.get("psnr_min_db") not in ("", None)}
    missing = [a for a in dict.fromkeys([asset_name(d) for d in DEFAULT_ASSETS] + list(assets)) if a not in have]
    out.append({"check": "Pareto chart for bunny, fandisk, DamagedHelmet and the chess set",
                "status": "pass" if charts.get("pareto") and not missing else "miss",
                "detail": f"{charts.get('pareto') or 'no chart'}; assets with PSNR data: {sorted(have)}"
                          + (f"; missing: {missing}" if missing else "")})
    # (2) CAP bytes/vertex at >= 40 dB vs 8: per asset the CAP configuration (default k_f, or
    # calibrated with --calibrated) with the least bytes among those reaching 40 dB at every level
    per = {}
    for a in assets:
        options = {}
        for config in ("CAP", "CAP (calibrated)"):
            cap = [r for r in rows if r["asset"] == a and r["tool"] == "lopcook" and r["config"] == config
                   and r.get("psnr_min_db") not in ("", None) and int(r["level"]) in levels]
            if not cap:
                continue
            options[config] = {
                "config": config, "cap_psnr_min_db": min(_f(r["psnr_min_db"]) for r in cap),
                "cap_bytes_per_vertex_max": max(_f(r["gpu_bytes_per_vertex"]) for r in cap),
                "per_level": {int(r["level"]): [_f(r["gpu_bytes_per_vertex"]), _f(r["psnr_min_db"])] for r in cap}}
        if not options:
            continue
        reaching = [o for o in options.values() if o["cap_psnr_min_db"] >= TARGET_PSNR_DB]
        best = min(reaching or options.values(), key=lambda o: o["cap_bytes_per_vertex_max"])
        per[a] = dict(best, alternatives=sorted(options))
    limit = 0.5 * PEER_BYTES_16BIT
    ok = bool(per) and all(v["cap_psnr_min_db"] >= TARGET_PSNR_DB and v["cap_bytes_per_vertex_max"] <= limit
                           for v in per.values())
    out.append({"check": f"CAP GPU bytes/vertex <= {limit:g} (0.5 x the 16-bit peers' 8) at >= {TARGET_PSNR_DB:g} dB, "
                         f"levels {levels[0]}-{levels[-1]}",
                "status": ("pass" if ok else "miss") if per else "not measured",
                "detail": "; ".join(f"{a}: {v['config']} max {v['cap_bytes_per_vertex_max']:.2f} B/vertex "
                                    f"({v['cap_bytes_per_vertex_max'] / PEER_BYTES_16BIT:.2f}x), worst PSNR "
                                    f"{v['cap_psnr_min_db']:.1f} dB" for a, v in per.items()) or "no CAP renders",
                "assets": per})
    # (3) the cooks of the 1.1M and 4.4M GLBs with 3 LODs vs gltfpack -si 0.5 -vp 14 (issue 13)
    for name, label, rss_limit in (("bunny s2", "1.1M", 500.0), ("bunny s3", "4.4M", 1500.0)):
        out.extend(_speed_checks(scaling, name, label, rss_limit))
    # (4) log-log slope
    lp = [r for r in scaling if r["tool"] == "lopcook" and not r.get("error")]
    slope, _ = BM.loglog_slope([_f(r["triangles"]) for r in lp], [_f(r["wall_s"]) for r in lp])
    out.append({"check": "log-log slope of cook wall time vs triangles <= 1.1",
                "status": "not measured" if not math.isfinite(slope) else ("pass" if slope <= 1.1 else "miss"),
                "slope": slope, "detail": f"slope {slope:.3f} over {len(lp)} inputs "
                                          f"({', '.join(r['input'] for r in lp)})"})
    return out


#: largest cook / gltfpack wall-time ratio of the scaling checks (issue 13)
MAX_SPEED_RATIO = 3.0


def _speed_checks(scaling: list[dict], name: str, label: str, rss_limit_mb: float) -> list[dict]:
    """Two checks on scaling input ``name``: lopcook's cook within ``MAX_SPEED_RATIO`` x gltfpack's
    wall time in the same run, and its peak RSS within ``rss_limit_mb`` MB (10^6 bytes)."""
    rows = [r for r in scaling if r["input"] == name and not r.get("error")]
    lc = next((r for r in rows if r["tool"] == "lopcook"), None)
    gp = next((r for r in rows if r["tool"] == "gltfpack"), None)
    speed = f"cook of the {label}-triangle GLB (3 LODs, full analysis) within {MAX_SPEED_RATIO:g}x gltfpack -si 0.5 -vp 14"
    memory = f"peak RSS <= {rss_limit_mb:g} MB at {label} triangles"
    out = []
    if lc and gp:
        ratio = _f(lc["wall_s"]) / _f(gp["wall_s"])
        out.append({"check": speed, "status": "pass" if ratio <= MAX_SPEED_RATIO else "miss", "ratio": ratio,
                    "detail": f"lopcook {_f(lc['wall_s']):.2f} s vs gltfpack {_f(gp['wall_s']):.2f} s "
                              f"({lc['triangles']:,} triangles): {ratio:.2f}x"})
    else:
        out.append({"check": speed, "status": "not measured", "detail": f"needs the scaling run with {name} and gltfpack"})
    if lc:
        rss = _f(lc["peak_rss_mb"]) * 2**20 / 1e6
        out.append({"check": memory, "status": "pass" if rss <= rss_limit_mb else "miss", "peak_rss_MB": rss,
                    "detail": f"{rss:.0f} MB (10^6 bytes; {_f(lc['peak_rss_mb']):.0f} MiB) for lopcook cook "
                              f"--lods {SCALING_LODS}"})
    else:
        out.append({"check": memory, "status": "not measured", "detail": f"needs the scaling run with {name}"})
    return out


def results_table(rows: list[dict], levels) -> list[str]:
    """Markdown lines: one row per asset and configuration (peers: position bits; lopcook: AP/CAP
    over the levels) with GPU position bytes per vertex (range over camera levels), PSNR (min over
    views) at the farthest and nearest camera level, file bytes, wall time and peak RSS of the tool's
    process, and cracks between parts. ``-cc`` rows show their own file bytes (accuracy is that of
    the file without ``-cc``)."""
    lo, hi = min(levels), max(levels)
    out = ["| asset | tool | config | GPU B/vertex | PSNR dB at level "
           f"{lo} / {hi} | file KB | wall s | peak RSS MiB | cracks between parts |",
           "|---|---|---|---|---|---|---|---|---|"]
    groups: dict = {}
    for r in rows:
        if r.get("error"):
            continue
        groups.setdefault((r["asset"], r["tool"], r["config"]), []).append(r)

    def db(v):
        f_ = _f(v)
        return "-" if not math.isfinite(f_) and str(v) in ("", "nan") else ("inf" if math.isinf(f_) else f"{f_:.1f}")

    for (asset, tool, config), rs in groups.items():
        by_level = {int(r["level"]): r for r in rs if str(r.get("level", "")).strip()}
        bpv = [_f(r["gpu_bytes_per_vertex"]) for r in rs]
        bpv_text = f"{min(bpv):.2f}" if max(bpv) - min(bpv) < 0.005 else f"{min(bpv):.2f}-{max(bpv):.2f}"
        far, near = by_level.get(lo, {}), by_level.get(hi, {})
        first = rs[0]
        rss = _f(first.get("peak_rss_mb"))
        out.append(f"| {asset} | {tool} | {config} | {bpv_text} | {db(far.get('psnr_min_db', ''))} / "
                   f"{db(near.get('psnr_min_db', ''))} | {_f(first['file_bytes']) / 1024:,.0f} | "
                   f"{_f(first['wall_s']):.2f} | {rss:.0f} | {first.get('cracks_between_parts', '')} |")
    return out


def machine() -> dict:
    """The bench machine's description for the summary: Python version, platform, CPU count, and where
    /proc allows the CPU model and memory in GiB."""
    import platform

    info = {"python": platform.python_version(), "platform": platform.platform(), "cpus": os.cpu_count()}
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                info["cpu"] = line.split(":", 1)[1].strip()
                break
        mem = Path("/proc/meminfo").read_text().splitlines()[0].split()
        info["memory_gb"] = round(int(mem[1]) / 2**20, 1)
    except OSError:
        pass
    return info


def write_outputs(out_dir: Path, rows, scaling, stage_rows, assets, opts, meta: dict) -> dict:
    """Write results.csv, scaling.csv, stages.csv, the charts (when matplotlib is installed), summary.json
    and summary.md into ``out_dir``; returns the summary dict (``meta`` plus charts and checks)."""
    from .atomic import write_atomic
    from .benchkit import charts as C

    write_csv(out_dir / "results.csv", rows, ROW_COLUMNS)
    write_csv(out_dir / "scaling.csv", scaling, SCALING_COLUMNS)
    write_csv(out_dir / "stages.csv", stage_rows, STAGE_COLUMNS)
    made = {}
    try:
        if rows:
            C.pareto_chart(rows, out_dir / "pareto.png")
            made["pareto"] = "pareto.png"
        if scaling:
            C.scaling_chart(scaling, out_dir / "scaling.png")
            made["scaling"] = "scaling.png"
        if stage_rows:
            C.stages_chart(stage_rows, out_dir / "stages.png")
            made["stages"] = "stages.png"
    except ImportError as exc:
        _log(opts, f"no charts: {exc} (pip install 'lopcook[bench]')")
    results = checks(rows, scaling, assets, made, list(opts.levels))
    summary = dict(meta, charts=made, checks=results)
    write_atomic(out_dir / "summary.json", (json.dumps(summary, indent=1, sort_keys=True, default=str) + "\n").encode())
    lines = ["# lopcook bench summary", "", f"Command: `{meta['command']}`", "",
             f"Machine: {meta['machine'].get('cpu', '?')}, {meta['machine'].get('cpus')} CPUs, "
             f"{meta['machine'].get('memory_gb', '?')} GB; renderer at {opts.resolution[0]}x{opts.resolution[1]}, "
             f"{opts.views} views, levels {opts.levels[0]}-{opts.levels[-1]}; total {meta['seconds']:.0f} s", "",
             "Peers: " + ", ".join(f"{k}: {v}" for k, v in meta["peers"].items()), "",
             "| check | status | numbers |", "|---|---|---|"]
    lines += [f"| {c['check']} | {c['status']} | {c['detail']} |" for c in results]
    if rows:
        lines += ["", "## Results", "", *results_table(rows, list(opts.levels))]
    if scaling:
        lines += ["", "## Scaling", "", "| input | triangles | tool | config | wall s | peak RSS MiB |",
                  "|---|---|---|---|---|---|"]
        lines += [f"| {r['input']} | {int(_f(r['triangles'])):,} | {r['tool']} | {r['config']} | {_f(r['wall_s']):.2f} | "
                  f"{_f(r['peak_rss_mb']):.0f} |" for r in scaling if not r.get("error")]
    lines += ["", "Charts: " + ", ".join(made.values()), ""]
    write_atomic(out_dir / "summary.md", "\n".join(lines).encode())
    return summary


# ---- entry ------------------------------------------------------------------------------------

def run_connectivity(opts) -> dict:
    """``lopcook bench --connectivity``: ``lopcook.benchkit.connectivity`` on ``opts.assets`` (default
    every corpus asset) into ``opts.output`` (connectivity.json, connectivity_unit_size.png)."""
    from .benchkit.connectivity import ASSETS, main
    from .errors import LopcookError

    corpus = corpus_dir()
    if not opts.assets and corpus is None:
        raise LopcookError("usage", None, "no ASSETS given and no corpus found",
                           hint="give asset files, or set LOPCOOK_CORPUS to the shared corpus folder")
    argv = ["--out", str(opts.output), "--corpus", str(corpus or "."), "--assets"]
    argv += [str(Path(a).resolve()) for a in opts.assets] or list(ASSETS)
    return main(argv)


ATTRIBUTE_ASSETS = ("stanford-bunny.obj", "DamagedHelmet/DamagedHelmet.gltf", "Duck.glb")


def run_attributes(opts) -> dict:
    """``lopcook bench --attributes``: ``lopcook.benchkit.attributes`` on ``opts.assets`` (default
    ``ATTRIBUTE_ASSETS`` of the corpus) into ``opts.output`` (attributes.json, .csv, .png)."""
    from .benchkit import attributes as A
    from .errors import LopcookError

    corpus = corpus_dir()
    assets = [str(a) for a in opts.assets]
    if not assets:
        if corpus is None:
            raise LopcookError("usage", None, "no ASSETS given and no corpus found",
                               hint="give asset files, or set LOPCOOK_CORPUS to the shared corpus folder")
        assets = [str(corpus / a) for a in ATTRIBUTE_ASSETS if (corpus / a).is_file()]
    Path(opts.output).mkdir(parents=True, exist_ok=True)
    avail = P.availability(opts.peers)
    for peer in opts.peers:
        if avail.get(peer) is None:
            print(P.missing_line(peer), file=sys.stderr, flush=True)
    return A.run(opts, assets, avail)


def run(opts) -> dict:
    """Run the bench described by ``opts`` (the parsed ``lopcook bench`` arguments: assets, output,
    levels, views, resolution, bits, peers, scaling, scaling_max_triangles, skip_render,
    calibrated, repeat, quiet) and write everything into ``opts.output``. Returns the summary."""
    if getattr(opts, "connectivity", False):
        return run_connectivity(opts)
    if getattr(opts, "attributes", False):
        return run_attributes(opts)
    t0 = time.perf_counter()
    out_dir = Path(opts.output)
    out_dir.mkdir(parents=True, exist_ok=True)
    corpus = corpus_dir()
    assets = list(opts.assets)
    if not assets and not opts.no_accuracy:
        if corpus is None:
            from .errors import LopcookError

            raise LopcookError("usage", None, "no ASSETS given and no corpus found",
                               hint="give asset files, or set LOPCOOK_CORPUS to the shared corpus folder")
        assets = [str(corpus / a) for a in DEFAULT_ASSETS if (corpus / a).is_file()]
    avail = P.availability(opts.peers)
    for peer in opts.peers:
        if avail.get(peer) is None:
            print(P.missing_line(peer), file=sys.stderr, flush=True)
    versions = {p: (P.tool_version(avail[p], p) if p != "draco" else f"DracoPy {_dracopy_version()}")
                for p in opts.peers if avail.get(p)}
    rows, stage_rows = [], []
    for a in ([] if opts.no_accuracy else assets):
        try:
            r, s = bench_asset(a, out_dir, opts, avail)
        except Exception as exc:  # noqa: BLE001 -- an unreadable asset is a row, not a crash
            _log(opts, f"{asset_name(a)}: failed: {type(exc).__name__}: {exc}")
            r, s = [result_row(asset=asset_name(a), tool="lopcook", config="CAP", error=f"{type(exc).__name__}: {exc}")], []
        rows += r
        stage_rows += s
        write_csv(out_dir / "results.csv", rows, ROW_COLUMNS)  # partial results survive an interrupted run
    scaling = []
    if opts.scaling:
        s_rows, s_stages = bench_scaling(out_dir, corpus, opts, avail)
        scaling += s_rows
        stage_rows += s_stages
    meta = {"command": "lopcook bench " + " ".join(opts.argv), "machine": machine(), "peers": versions,
            "seconds": time.perf_counter() - t0, "assets": [asset_name(a) for a in assets],
            "levels": list(opts.levels), "views": opts.views, "resolution": list(opts.resolution),
            "peak_rss": "os.wait4 ru_maxrss of each child process", "match": {
                "lopcook": "order (the container keeps the source vertices)",
                "peers": "nearest source vertex (scipy cKDTree), ties between co-located vertices by normal/UV"}}
    summary = write_outputs(out_dir, rows, scaling, stage_rows, [asset_name(a) for a in assets], opts, meta)
    for c in summary["checks"]:
        _log(opts, f"{c['status']:>12}: {c['check']}: {c['detail']}")
    _log(opts, f"wrote {out_dir}/results.csv, scaling.csv, stages.csv, charts, summary.md in "
               f"{time.perf_counter() - t0:.0f} s")
    return summary


def _dracopy_version() -> str:
    try:
        from importlib.metadata import version

        return version("DracoPy")
    except Exception:  # noqa: BLE001
        return "unknown"


__all__ = ["DEFAULT_ASSETS", "DEFAULT_LEVELS", "PEER_BITS", "ROW_COLUMNS", "SCALING_COLUMNS", "STAGE_COLUMNS",
           "corpus_dir", "asset_name", "Source", "results_table", "write_inputs", "cook_stages", "run_cook", "lopcook_rows",
           "peer_configs", "peer_measure", "bench_asset", "scaling_inputs", "bench_scaling", "result_row", "write_csv", "checks",
           "write_outputs", "run"]
