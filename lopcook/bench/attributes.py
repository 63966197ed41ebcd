"""``lopcook bench --attributes``: total GPU bytes per vertex (positions + normals + UVs + colours)
against masked PSNR, for lopcook and for the peers' defaults and attribute sweeps.

Purnomo et al. 2005 ("Hardware-compatible vertex compression using quantization and
simplification", section 4.1) measure a quantization by rendering it against the original; here
every output is rendered with **its own decoded attributes** (the peers' quantized normals, UVs and
colours; lopcook's container's decoded attributes), unlike the position bench (``lopcook.bench.compare``),
which renders every tool with the source's attributes so that only positions differ.

Runs (``attribute_configs``), positions at each tool's default bits:

* **gltfpack** ``-kv -vp 14 -vn N -vt N -vc N``: its defaults (8, 12, 8), then ``-vn`` in
  ``NORMAL_SWEEP`` and ``-vt`` in ``UV_SWEEP`` with the other bits at their defaults.
* **glTF-Transform** ``quantize --quantize-position 14 --quantize-normal N --quantize-texcoord N
  --quantize-color 8``: its defaults (10, 12), then the same sweeps from 8 bits (it refuses fewer).
* **Draco** (DracoPy) ``qp 11 qn 8 qt 10`` (the draco_encoder defaults), then the sweeps over qn and qt.
  Draco is a transmission format: its GPU bytes are the float32 attributes it decodes to.
* **lopcook** ``cook`` (default) and, when the cook has ``--normal-bits`` / ``--uv-bits`` (the packed
  attribute record), the same sweeps, plus ``cook --target-psnr`` when asked.

The input. Every peer reads ``input.glb`` (``write_inputs``): the source's world-space float32 parts
with one shared textured material (a 1 x 1 white PNG) on the parts with UVs, so that gltfpack can
quantize UVs: it stores them normalized over the material's UV box and writes the box as the
material's ``KHR_texture_transform`` (offset, scale), which ``texture_transform`` reads back and
``_decoded_parts`` applies (uv = offset + scale * uv_q). Renders use the **source** textures: each
output vertex is matched to its source vertex (``lopcook.bench.metrics.match_vertices``) to find
its part (texture, part ID); its own normal, UV and colour are drawn where the tool kept them, the
source's where it dropped one.

GPU bytes per vertex (``gltf_attribute_bytes``): per glTF accessor, count times the element size
rounded up to 4 bytes (the glTF 2.0 vertex attribute alignment; 8-bit normals 4 B, 16-bit 8 B;
16-bit UVs 4 B; float UVs 8 B), summed over POSITION, NORMAL, TEXCOORD_0 and COLOR_0 of every
primitive and divided by the vertices. lopcook: CAP positions at the chart's level (the largest of
``--levels``; ``lopcook.lop.summary.memory_rows``) plus the bytes of every LOD-0 attribute section.
PSNR: min over views and levels of the masked PSNR (``lopcook.verify.metrics``), the same cameras as
``lopcook.verify.evaluate``.
"""

from __future__ import annotations

import json
import re
import time
from pathlib import Path

import numpy as np

from ..atomic import write_atomic
from ..lop.container import read
from ..emit.gltf_writer import write_gltf
from ..lop.summary import memory_rows
from ..ingest import load
from ..verify.evaluate import evaluate
from . import metrics as BM
from . import peers as P
from .charts import COLOURS, INF_DB, pyplot
from .common import Source, asset_name, glb_json, log, run_cook, write_csv
from .draco_run import decode_buffers, write_parts
from .render import Variant, render_variants

NORMAL_SWEEP = (6, 8, 10, 12, 14)
UV_SWEEP = (8, 10, 12, 14)
GLTFPACK_DEFAULTS = {"vp": 14, "vn": 8, "vt": 12, "vc": 8}
GLTF_TRANSFORM_DEFAULTS = {"vp": 14, "vn": 10, "vt": 12, "vc": 8}
DRACO_DEFAULTS = {"vp": 11, "vn": 8, "vt": 10}
#: the glTF attributes counted as GPU bytes (one set of UVs and colours, as lopcook stores)
GPU_ATTRIBUTES = ("POSITION", "NORMAL", "TEXCOORD_0", "COLOR_0")
_COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
_COMPONENT_BYTES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
TABLE_COLUMNS = ("asset", "tool", "config", "kind", "vertices", "bytes_per_vertex", "position_bytes_per_vertex",
                 "normal_bytes_per_vertex", "uv_bytes_per_vertex", "color_bytes_per_vertex", "psnr_min_db",
                 "psnr_mean_db", "normal_bits", "uv_bits", "color_bits", "position_bits", "wall_s", "error")


def _sweep(defaults: dict, least: int = 1, normals: bool = True, uvs: bool = True) -> list[tuple[str, dict]]:
    """[(kind, bits)]: the defaults, then each normal and UV bit count of the sweeps (others at
    default) from ``least`` bits up (glTF-Transform refuses fewer than 8); a sweep only for an
    attribute the scene has."""
    out = [("default", dict(defaults))]
    out += [("sweep", dict(defaults, vn=b)) for b in NORMAL_SWEEP if normals and b != defaults["vn"] and b >= least]
    out += [("sweep", dict(defaults, vt=b)) for b in UV_SWEEP if uvs and b != defaults["vt"] and b >= least]
    return out


def attribute_configs(avail: dict, normals: bool = True, uvs: bool = True) -> list[dict]:
    """Every peer run of the attribute chart: {"tool", "config" (the flags as text), "kind"
    ("default" or "sweep"), "bits" {"vp", "vn", "vt"[, "vc"]}}, in a fixed order; ``normals`` /
    ``uvs``: whether the scene has them (no sweep of an attribute it lacks)."""
    out = []
    kw = {"normals": normals, "uvs": uvs}
    if avail.get("gltfpack"):
        for kind, b in _sweep(GLTFPACK_DEFAULTS, **kw):
            out.append({"tool": "gltfpack", "kind": kind, "bits": b,
                        "config": f"-vp {b['vp']} -vn {b['vn']} -vt {b['vt']} -vc {b['vc']}"})
    if avail.get("gltf-transform"):
        for kind, b in _sweep(GLTF_TRANSFORM_DEFAULTS, least=8, **kw):
            out.append({"tool": "gltf-transform", "kind": kind, "bits": b,
                        "config": f"--quantize-normal {b['vn']} --quantize-texcoord {b['vt']}"})
    if avail.get("draco"):
        for kind, b in _sweep(DRACO_DEFAULTS, **kw):
            out.append({"tool": "draco", "kind": kind, "bits": b, "config": f"-qp {b['vp']} -qn {b['vn']} -qt {b['vt']}"})
    return out


def peer_argv(cfg: dict, avail: dict, glb: Path, npz: Path, out: Path) -> list:
    """The command line of one attribute run (``cfg`` from ``attribute_configs``)."""
    b = cfg["bits"]
    if cfg["tool"] == "gltfpack":
        return [avail["gltfpack"], "-i", str(glb), "-o", str(out), "-kv", "-vp", str(b["vp"]), "-vn", str(b["vn"]),
                "-vt", str(b["vt"]), "-vc", str(b["vc"])]
    if cfg["tool"] == "gltf-transform":
        return [avail["gltf-transform"], "quantize", str(glb), str(out), "--quantize-position", str(b["vp"]),
                "--quantize-normal", str(b["vn"]), "--quantize-texcoord", str(b["vt"]), "--quantize-color",
                str(b["vc"])]
    return [avail["draco"], "-m", "lopcook.bench.draco_run", str(npz), str(out), str(b["vp"]), str(b["vn"]),
            str(b["vt"])]


# ---- input and output -------------------------------------------------------------------------

#: a 1 x 1 white RGBA PNG (8-bit RGBA, no filter, zlib level 9): the texture of the peers' input.glb
WHITE_PNG = bytes.fromhex("89504e470d0a1a0a0000000d49484452000000010000000108060000001f15c4890000000b4944415478da63f80f"
                          "040009fb03fd68fa1ccc0000000049454e44ae426082")


def write_inputs(scene, adir: Path) -> tuple[Path, Path]:
    """``input.glb`` (float32 world-space parts; one shared textured material on the parts with UVs)
    and ``parts.npz`` (Draco's input, as ``lopcook.bench.compare.write_inputs``) in ``adir``."""
    meshes, textured = [], False
    for p in scene.parts:
        m = {"name": p.name, "positions": p.positions, "indices": p.indices, "normals": p.normals,
             "uvs": p.uvs, "colors": p.colors}
        if p.uvs is not None:
            m["material"] = 0
            textured = True
        meshes.append(m)
    materials = None
    if textured:
        materials = {"materials": [{"name": "bench", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
                     "textures": [{"source": 0}], "samplers": [],
                     "images": [{"name": "white", "mimeType": "image/png", "data": WHITE_PNG}]}
    glb = adir / "input.glb"
    write_gltf(glb, meshes, generator="lopcook bench --attributes", materials=materials)
    npz = adir / "parts.npz"
    write_parts(npz, scene.parts)
    return glb, npz


def texture_transform(gltf: dict) -> tuple[np.ndarray, np.ndarray] | None:
    """(offset (2,), scale (2,)) float64 of the first material's base-colour ``KHR_texture_transform``
    (gltfpack's UV dequantization), or None when there is none. A rotation other than 0 is an error
    (the bench's input has one axis-aligned UV box)."""
    for mat in gltf.get("materials", []):
        t = (mat.get("pbrMetallicRoughness", {}).get("baseColorTexture", {}).get("extensions", {})
             .get("KHR_texture_transform"))
        if t is None:
            continue
        if float(t.get("rotation", 0.0)) != 0.0:
            raise ValueError("KHR_texture_transform with a rotation is not supported by the bench")
        return (np.asarray(t.get("offset", [0.0, 0.0]), np.float64), np.asarray(t.get("scale", [1.0, 1.0]), np.float64))
    return None


def gltf_attribute_bytes(gltf: dict) -> tuple[dict, int]:
    """GPU bytes of each attribute of ``GPU_ATTRIBUTES`` over every mesh primitive and the vertex
    count (POSITION accessors): per accessor, count x (element size rounded up to 4 bytes), the
    glTF 2.0 vertex attribute alignment (also the share of an interleaved stride). Accessors used
    by several primitives count once. Returns ({"POSITION": bytes, ...}, vertices)."""
    accessors = gltf.get("accessors", [])
    seen: set = set()
    out = {a: 0 for a in GPU_ATTRIBUTES}
    verts = 0
    for mesh in gltf.get("meshes", []):
        for prim in mesh.get("primitives", []):
            for name in GPU_ATTRIBUTES:
                a = prim.get("attributes", {}).get(name)
                if a is None or a in seen:
                    continue
                seen.add(a)
                acc = accessors[a]
                elem = _COMPONENTS[acc["type"]] * _COMPONENT_BYTES[int(acc["componentType"])]
                out[name] += int(acc["count"]) * (4 * ((elem + 3) // 4))
                if name == "POSITION":
                    verts += int(acc["count"])
    return out, verts


def _decoded_parts(cfg: dict, out: Path) -> list[dict]:
    """Decoded parts of a peer output: [{"positions" (n, 3) f64, "indices" (m, 3), "normals", "uvs",
    "colors" (or None where the tool dropped them)}]."""
    if cfg["tool"] == "draco":
        return [{"positions": pts, "indices": tri, "normals": nrm, "uvs": uv, "colors": None}
                for pts, tri, nrm, uv in decode_buffers(out)]
    transform = texture_transform(glb_json(out)) if cfg["tool"] == "gltfpack" else None
    parts = []
    for p in load(out).parts:
        uvs = p.uvs
        if uvs is not None and transform is not None:
            uvs = (transform[0] + transform[1] * uvs.astype(np.float64)).astype(np.float32)
        parts.append({"positions": p.positions, "indices": p.indices,
                      "normals": None if p.normals_computed else p.normals, "uvs": uvs, "colors": p.colors})
    return parts


def peer_variant(cfg: dict, out: Path, src, asset: str):
    """(table row without PSNR, ``lopcook.bench.render.Variant`` with the output's own attributes)."""
    parts = _decoded_parts(cfg, out)
    pos = np.concatenate([p["positions"] for p in parts])
    feats = np.concatenate([BM.attribute_features(p["normals"], p["uvs"], p["positions"].shape[0]) for p in parts])
    match = BM.match_vertices(src.positions, pos, src.attr, feats)
    n = int(pos.shape[0])
    if cfg["tool"] == "draco":  # decoded to float32 on the GPU
        b = {"POSITION": 12 * n, "NORMAL": 12 * sum(p["positions"].shape[0] for p in parts if p["normals"] is not None),
             "TEXCOORD_0": 8 * sum(p["positions"].shape[0] for p in parts if p["uvs"] is not None), "COLOR_0": 0}
    else:
        b, _ = gltf_attribute_bytes(glb_json(out))
    row = table_row(asset=asset, tool=cfg["tool"], config=cfg["config"], kind=cfg["kind"], vertices=n,
                    position_bits=cfg["bits"]["vp"], normal_bits=cfg["bits"]["vn"], uv_bits=cfg["bits"]["vt"],
                    color_bits=cfg["bits"].get("vc"), bytes_per_vertex=round(sum(b.values()) / max(n, 1), 4),
                    position_bytes_per_vertex=round(b["POSITION"] / max(n, 1), 4),
                    normal_bytes_per_vertex=round(b["NORMAL"] / max(n, 1), 4),
                    uv_bytes_per_vertex=round(b["TEXCOORD_0"] / max(n, 1), 4),
                    color_bytes_per_vertex=round(b["COLOR_0"] / max(n, 1), 4))
    vparts, start = [], 0
    for p in parts:
        k = p["positions"].shape[0]
        mm = match[start:start + k]
        start += k
        part = int(np.bincount(src.part[mm]).argmax()) if mm.size else 0
        vparts.append((p["positions"].astype(np.float32), p["indices"].astype(np.uint32), part, mm,
                       {"normals": p["normals"], "uvs": p["uvs"], "colors": p["colors"]}))
    return row, Variant(key=f"{cfg['tool']} {cfg['config']}", parts=vparts)


def table_row(**kw) -> dict:
    r = {c: "" for c in TABLE_COLUMNS}
    r.update({k: v for k, v in kw.items() if v is not None})
    return r


# ---- lopcook ----------------------------------------------------------------------------------

def container_bytes_per_vertex(c, level: int) -> dict:
    """GPU bytes per vertex of a container's LOD 0 at ``level``: {"positions" (CAP at level),
    "attributes" (every LOD-0 attribute section: ``attributes``, or the older ``normals`` / ``uvs`` /
    ``colors``), "total", "vertices"}."""
    lengths = {s["name"]: int(s["length"]) for s in c.manifest["sections"]}
    attr = verts = 0
    for part in c.manifest["parts"]:
        lod = part["lods"][0]
        verts += int(lod["vertices"])
        for key in ("attributes", "normals", "uvs", "colors"):
            name = lod.get(key)
            if isinstance(name, str):
                attr += lengths.get(name, 0)
    cap = next(r["cap_bytes"] for r in memory_rows(c, levels=[level]) if int(r["level"]) == int(level))
    v = max(verts, 1)
    return {"positions": cap / v, "attributes": attr / v, "total": (cap + attr) / v, "vertices": verts}


def lopcook_configs(target_psnr: float | None, normals: bool = True, uvs: bool = True) -> list[dict]:
    """lopcook's runs: the default cook; the normal and UV sweeps (``--normal-bits N`` /
    ``--uv-bits N``, for the attributes the scene has); and ``--target-psnr DB`` when given."""
    out = [{"tool": "lopcook", "kind": "default", "config": "cook", "extra": []}]
    out += [{"tool": "lopcook", "kind": "sweep", "config": f"cook --normal-bits {b}", "extra": ["--normal-bits", str(b)]}
            for b in NORMAL_SWEEP if normals]
    out += [{"tool": "lopcook", "kind": "sweep", "config": f"cook --uv-bits {b}", "extra": ["--uv-bits", str(b)]}
            for b in UV_SWEEP if uvs]
    if target_psnr is not None:
        out.append({"tool": "lopcook", "kind": "searched", "config": f"cook --target-psnr {target_psnr:g}",
                    "extra": ["--target-psnr", f"{target_psnr:g}"]})
    return out


def _container_bits(c) -> dict:
    bits = {"normals": None, "uvs": None, "colors": None}
    for part in c.manifest["parts"]:
        for k, v in (part.get("attribute_bits") or {}).items():
            if v is not None:
                bits[k] = v if bits.get(k) is None else max(bits[k], v)
    return bits


# ---- the run ----------------------------------------------------------------------------------

def bench_asset(path, out_dir: Path, opts, avail: dict) -> list[dict]:
    """Table rows of one asset: every peer run and lopcook run, bytes per vertex and PSNR."""
    asset = asset_name(path)
    adir = out_dir / "attributes" / asset
    adir.mkdir(parents=True, exist_ok=True)
    log(opts, f"{asset}: ingest {path}")
    src = Source(load(path))
    glb, npz = write_inputs(src.scene, adir)
    level = max(opts.levels)
    rows, variants = [], []
    has = {"normals": any(p.normals is not None for p in src.scene.parts),
           "uvs": any(p.uvs is not None for p in src.scene.parts)}
    for cfg in attribute_configs(avail, **has):
        tag = re.sub(r"[^A-Za-z0-9]+", "_", f"{cfg['tool']}_{cfg['config']}").strip("_")
        out = adir / (tag + (".npz" if cfg["tool"] == "draco" else ".glb"))
        if out.exists():
            out.unlink()
        log(opts, f"{asset}: {cfg['tool']} {cfg['config']}")
        try:
            m = P.run_measured(peer_argv(cfg, avail, glb, npz, out), timeout_s=3600)
            if m.returncode != 0 or not out.exists():
                tail = (m.stderr.strip() or m.stdout.strip()).splitlines()
                raise RuntimeError(f"exit {m.returncode}: {tail[-1] if tail else 'no output'}")
            row, variant = peer_variant(cfg, out, src, asset)
            row["wall_s"] = round(m.wall_s, 3)
            variants.append(variant)
        except Exception as exc:  # noqa: BLE001 -- one row with the error, never a crash
            row = table_row(asset=asset, tool=cfg["tool"], config=cfg["config"], kind=cfg["kind"],
                            error=f"{type(exc).__name__}: {exc}")
        rows.append(row)
    if variants and not opts.skip_render:
        log(opts, f"{asset}: render {len(variants)} peer outputs with their own attributes")
        got = render_variants(src.scene, variants, levels=opts.levels, views=opts.views, resolution=opts.resolution,
                              extent=src.extent, own_attributes=True)
        for r in rows:
            g = got.get(f"{r['tool']} {r['config']}")
            if g:
                r["psnr_min_db"] = _min_db([v["psnr_min"] for v in g.values()])
                r["psnr_mean_db"] = _min_db([v["psnr_mean"] for v in g.values()])
    for cfg in lopcook_configs(getattr(opts, "attributes_target", None), **has):
        lop = adir / (re.sub(r"[^A-Za-z0-9]+", "_", cfg["config"]).strip("_") + ".lop")
        log(opts, f"{asset}: lopcook {cfg['config']}")
        m, desc = run_cook(path, lop, cfg["extra"])
        if desc is None:
            err = (m.stderr.strip().splitlines() or [f"exit {m.returncode}"])[-1]
            rows.append(table_row(asset=asset, tool="lopcook", config=cfg["config"], kind=cfg["kind"], error=err))
            continue
        c = read(lop)
        b = container_bytes_per_vertex(c, level)
        bits = _container_bits(c)
        row = table_row(asset=asset, tool="lopcook", config=cfg["config"], kind=cfg["kind"], vertices=b["vertices"],
                        bytes_per_vertex=round(b["total"], 4), position_bytes_per_vertex=round(b["positions"], 4),
                        normal_bits=bits["normals"], uv_bits=bits["uvs"], color_bits=bits["colors"],
                        position_bits=f"CAP at level {level}", wall_s=round(m.wall_s, 3))
        if not opts.skip_render:
            ev = evaluate(c, src.scene, levels=opts.levels, views=opts.views, resolution=opts.resolution,
                          variants=("cap",), attributes="container")
            row["psnr_min_db"] = _min_db([r["cap"]["psnr_min"] for r in ev["levels"]])
            row["psnr_mean_db"] = _min_db([r["cap"]["psnr_mean"] for r in ev["levels"]])
        rows.append(row)
    return rows


def _min_db(values) -> float:
    """Min over levels of a PSNR (None = identical images = inf)."""
    vals = [float("inf") if v is None else float(v) for v in values]
    return round(min(vals), 3) if vals else float("nan")


def attributes_chart(rows: list[dict], path) -> None:
    """``attributes.png``: total GPU bytes per vertex against PSNR (min over views and levels), one
    panel per asset; each tool's points, its Pareto front, and its default drawn as a star."""
    plt = pyplot()
    assets = list(dict.fromkeys(r["asset"] for r in rows))
    cols = min(2, max(1, len(assets)))
    nrows = -(-max(1, len(assets)) // cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(6.5 * cols, 4.6 * nrows), squeeze=False)
    for ax, asset in zip(axes.ravel(), assets):
        sub = [r for r in rows if r["asset"] == asset and not r.get("error") and r.get("psnr_min_db") not in ("", None)]
        for tool in dict.fromkeys(r["tool"] for r in sub):
            pts = [r for r in sub if r["tool"] == tool]
            x = np.array([float(r["bytes_per_vertex"]) for r in pts])
            y = np.array([float(r["psnr_min_db"]) for r in pts])
            y = np.where(np.isinf(y), INF_DB, y)
            colour = COLOURS.get(tool if tool != "lopcook" else "lopcook CAP")
            ax.scatter(x, y, s=12, alpha=0.45, color=colour)
            front = BM.pareto_front(x, y)
            ax.plot(x[front], y[front], "-o", ms=4, color=colour, label=tool)
            for r, xi, yi in zip(pts, x, y):
                if r["kind"] in ("default", "searched"):
                    ax.scatter([xi], [yi], marker="*", s=120, color=colour, edgecolor="black", zorder=5)
        ax.axhline(40.0, color="grey", lw=0.8, ls="--")
        ax.set_title(asset)
        ax.set_xlabel("GPU bytes / vertex (positions + normals + UVs + colours)")
        ax.set_ylabel("masked PSNR, min over views and levels (dB)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    for ax in axes.ravel()[len(assets):]:
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run(opts, assets: list[str], avail: dict) -> dict:
    """Every asset's rows into ``opts.output``: ``attributes.json`` (the table and the command),
    ``attributes.csv`` and ``attributes.png``. Returns the JSON object."""
    t0 = time.perf_counter()
    out_dir = Path(opts.output)
    rows = []
    for a in assets:
        try:
            rows += bench_asset(a, out_dir, opts, avail)
        except Exception as exc:  # noqa: BLE001 -- an unreadable asset is a row, not a crash
            rows.append(table_row(asset=asset_name(a), tool="lopcook", config="cook", error=f"{type(exc).__name__}: {exc}"))
        write_csv(out_dir / "attributes.csv", rows, TABLE_COLUMNS)
    chart = None
    try:
        if rows:
            attributes_chart(rows, out_dir / "attributes.png")
            chart = "attributes.png"
    except ImportError as exc:
        log(opts, f"no chart: {exc} (pip install 'lopcook[bench]')")
    doc = {"command": "lopcook bench " + " ".join(getattr(opts, "argv", [])), "levels": list(opts.levels),
           "views": opts.views, "resolution": list(opts.resolution), "chart": chart,
           "seconds": round(time.perf_counter() - t0, 1), "rows": rows}
    write_atomic(out_dir / "attributes.json", (json.dumps(doc, indent=1, sort_keys=True, default=str) + "\n").encode())
    return doc


__all__ = ["NORMAL_SWEEP", "UV_SWEEP", "GLTFPACK_DEFAULTS", "GLTF_TRANSFORM_DEFAULTS", "DRACO_DEFAULTS",
           "TABLE_COLUMNS", "attribute_configs", "peer_argv", "write_inputs", "texture_transform",
           "gltf_attribute_bytes", "peer_variant", "container_bytes_per_vertex", "lopcook_configs",
           "bench_asset", "attributes_chart", "run"]
