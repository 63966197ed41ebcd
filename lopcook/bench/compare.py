"""lopcook against the peers on one asset (``bench_asset``): the accuracy rows of ``lopcook bench``.

1. Ingest the source (``lopcook.ingest.load``, default settings) and write it as ``input.glb``
   (``lopcook.emit.gltf_writer.write_gltf``: world-space float32 positions, normals, UVs,
   colours; no textures) and ``parts.npz`` (for Draco): every peer reads the same mesh.
2. lopcook: ``python -m lopcook cook SOURCE --json`` in a child process (default options; with
   ``--calibrated`` also ``--target-psnr 40``), then AP and CAP at each level: GPU bytes
   (``lopcook.lop.summary.memory_rows``), position error and cracks (CPU reference decoder,
   vertices matched by order), masked PSNR (``lopcook.verify.evaluate.evaluate``).
3. Each peer configuration in a child process; its output ingested back with lopcook's reader
   (Draco: decoded by DracoPy), matched to the source by nearest neighbour, measured, and
   rendered with float positions against the float source (``lopcook.bench.render``).

Every row has the ``ROW_COLUMNS`` keys; a failure is a row with ``error``, never an exception.
"""

from __future__ import annotations

import re
import time
from pathlib import Path

import numpy as np

from ..lop.bitplane import decode, reconstruct_float32
from ..lop.container import read
from ..emit.gltf_writer import write_gltf
from ..lop.reader import gpu_buffer
from ..lop.summary import memory_rows
from ..ingest import load
from ..verify.buffers import ap_buffer, source_order
from ..verify.evaluate import evaluate
from . import metrics as BM
from . import peers as P
from .common import ASSET_TIMEOUT_S, Source, asset_name, cook_stages, glb_json, log, mib, run_cook
from .draco_run import decode_buffers, write_parts
from .render import Variant, render_variants

DEFAULT_ASSETS = ("stanford-bunny.obj", "fandisk.obj", "DamagedHelmet/DamagedHelmet.gltf", "chess_set_flat.usdc")


DEFAULT_LEVELS = (6, 7, 8, 9, 10, 11)


PEER_BITS = (10, 12, 14, 16)


TARGET_PSNR_DB = 40.0


PEER_BYTES_16BIT = 8.0


ROW_COLUMNS = ("asset", "tool", "config", "bits", "level", "vertices", "triangles", "file_bytes",
               "gpu_position_bytes", "gpu_bytes_per_vertex", "max_err_rel", "rms_err_rel", "cracks",
               "cracks_between_parts", "psnr_min_db", "psnr_mean_db", "depth_order_errors", "wall_s",
               "peak_rss_mb", "match", "accuracy_from", "cc_check", "error")


STAGE_COLUMNS = ("cook", "triangles", "stage", "seconds")


def result_row(**kw) -> dict:
    """One results.csv row: every ``ROW_COLUMNS`` key, empty unless given (None counts as not given)."""
    r = {c: "" for c in ROW_COLUMNS}
    r.update({k: v for k, v in kw.items() if v is not None})
    return r


def write_inputs(src: Source, adir: Path) -> tuple[Path, Path]:
    """input.glb (every peer's input) and parts.npz (Draco's) in ``adir``."""
    glb = adir / "input.glb"
    write_gltf(glb, src.scene.parts, generator="lopcook bench")
    npz = adir / "parts.npz"
    write_parts(npz, src.scene.parts)
    return glb, npz


def _lopcook_positions(c, src: Source, orders, level: int, variant: str) -> tuple[np.ndarray, np.ndarray]:
    """Decoded positions (float32 as the shaders compute them) of every vertex at ``level`` for AP or
    CAP, and the source vertex of each (the container keeps the source's vertices; binned order)."""
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
    name = "CAP (calibrated)" if calibrated else "CAP"
    lop = adir / ("lopcook_cal.lop" if calibrated else "lopcook.lop")
    extra = ["--target-psnr", str(TARGET_PSNR_DB)] if calibrated else []
    log(opts, f"{asset}: lopcook cook{' --target-psnr 40' if calibrated else ''}")
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
        log(opts, f"{asset}: render lopcook AP/CAP, levels {opts.levels[0]}-{opts.levels[-1]}, {opts.views} views")
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
                           peak_rss_mb=mib(m.peak_rss_bytes), match="order")
            if ev is not None:
                e = ev[level][variant.lower()]
                r.update(psnr_min_db=_db(e["psnr_min"]), psnr_mean_db=_db(e["psnr_mean"]),
                         depth_order_errors=e["depth_order_errors"])
            rows.append(r)
    return rows, info


def _db(v):
    """PSNR for the CSV: None (identical images) is inf."""
    return float("inf") if v is None else round(float(v), 3)


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
    base = dict(asset=asset, tool=cfg["tool"], config=cfg["config"], bits=cfg["bits"], wall_s=round(m.wall_s, 3),
                peak_rss_mb=mib(m.peak_rss_bytes), triangles=src.triangles)
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
    asset = asset_name(path)
    adir = out_dir / "assets" / asset
    adir.mkdir(parents=True, exist_ok=True)
    t_asset = time.perf_counter()
    log(opts, f"{asset}: ingest {path}")
    src = Source(load(path))
    log(opts, f"{asset}: {len(src.scene.parts)} parts, {src.vertices:,} vertices, {src.triangles:,} triangles")
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
        log(opts, f"{asset}: {cfg['tool']} {cfg['config']}")
        try:
            m, out = peer_run(cfg, avail, glb, npz, adir)
            row, variant = peer_measure(cfg, m, out, src, asset, avail)
        except Exception as exc:  # noqa: BLE001
            row, variant = result_row(asset=asset, tool=cfg["tool"], config=cfg["config"], bits=cfg["bits"],
                                error=f"{type(exc).__name__}: {exc}"), None
        if row["error"]:
            log(opts, f"{asset}: {cfg['tool']} {cfg['config']} failed: {row['error']}")
        peer_rows.append(row)
        if variant is not None:
            variants.append(variant)
    renders = {}
    if variants and not opts.skip_render:
        log(opts, f"{asset}: render {len(variants)} peer outputs, levels {opts.levels[0]}-{opts.levels[-1]}, "
                   f"{opts.views} views at {opts.resolution[0]}x{opts.resolution[1]}")

        try:
            renders = render_variants(src.scene, variants, levels=opts.levels, views=opts.views,
                                      resolution=opts.resolution, extent=src.extent,
                                      progress=lambda s: log(opts, f"{asset}: {s}"))
        except Exception as exc:  # noqa: BLE001
            log(opts, f"{asset}: peer render failed: {type(exc).__name__}: {exc}")
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
    log(opts, f"{asset}: done in {time.perf_counter() - t_asset:.1f} s")
    return rows, stage_rows


__all__ = ["DEFAULT_ASSETS", "DEFAULT_LEVELS", "PEER_BITS", "TARGET_PSNR_DB", "PEER_BYTES_16BIT", "ROW_COLUMNS",
           "STAGE_COLUMNS", "result_row", "write_inputs", "lopcook_rows", "peer_configs", "peer_run", "cc_check",
           "peer_measure", "bench_asset"]
