"""Corpus render check with calibrated k_f: the Table-1 rows (Meyer et al. 2011) per asset.

Not a test (pytest does not collect benchmarks/). Usage::

    .venv/bin/python benchmarks/bench_verify_corpus.py [--assets NAME ...] [--target-psnr 40]
        [--statistic min mean] [--levels 6-11] [--cal-views 8] [--cal-resolution 640x360]
        [--views 20] [--resolution 1280x720] [--search kf+edge] [--no-edges]
        [--out bench-out/verify_corpus]
    .venv/bin/python benchmarks/bench_verify_corpus.py --diagnose [--assets ...] [--levels 6,8,11]
        [--views 8] [--resolution 640x360] [--kf-scale S] [--no-edges] [--fixed 10,14]

Per asset (default: bunny, fandisk, DamagedHelmet, CesiumMilkTruck, chess set):

1. ingest (default settings);
2. ``lopcook.tune.calibrate.calibrate``, once per ``--statistic`` (default both ``min``: every view
   must reach the target, and ``mean``: the PSNR of the view-averaged MSE must): the least k_f scale
   (and, with ``--search kf+edge``, the default, the loosest edge_eps of the discontinuity
   constraint) whose CAP renders reach the target PSNR at every level, with the reduced harness
   (``--cal-views``, ``--cal-resolution``); ``--no-edges`` turns the constraint off (the paper's CAP);
3. for each distinct choice, cook with the chosen settings (eps / sigma, edge_eps) and render float vs AP vs CAP with
   the full harness
   (``--views``, ``--resolution``; default 20 views at 1280 x 720) at ``--levels`` (default 6-11,
   the paper's Table 1);
4. rows: level, AP memory % of float32, AP PSNR (min / mean over views), CAP memory %, CAP PSNR,
   depth-order error pixels (AP / CAP), and the interior PSNR (pixels fully covered in both images:
   shading error without silhouette coverage); the calibrated k_f and edge_eps; the minimum-level
   memory (sum of 3 m_v bits over 96 bits per vertex: what the container's mandatory bits cost, the
   floor of CAP memory at any level); seconds per stage.

``--diagnose`` (no calibration): cook each asset at k_f scale ``--kf-scale`` (default 1) and split
the squared CAP error against float by pixel class, within 2 pixels of: silhouettes (object or
part-ID boundary of the float render), occlusion edges (neighbouring float depths more than 8 pixel
footprints apart), hard edges (neighbouring float normals more than 40 degrees apart), elsewhere.
Normals and depths come from an extra float render (1 sample). ``--fixed 10,14`` adds the same split
with every vertex at one level (the ceiling of a uniform precision). docs/analyse.md quotes it.

Writes ``OUT/results.json`` (everything, images excluded) and ``OUT/table.md`` and prints the table.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402

from lopcook.analyse import analyse  # noqa: E402
from lopcook.emit import build  # noqa: E402
from lopcook.lop.container import from_bytes  # noqa: E402
from lopcook.ingest import load  # noqa: E402
from lopcook.settings import DEFAULT_ANALYSE, DEFAULT_INGEST  # noqa: E402
from lopcook.tune.calibrate import calibrate, calibrated_settings, format_calibration  # noqa: E402
from lopcook.verify.decoders import parse_levels  # noqa: E402
from lopcook.verify.evaluate import evaluate, harness_evaluate  # noqa: E402
from lopcook.verify.tables import format_table  # noqa: E402
from lopcook.viewing import Viewing  # noqa: E402

ASSETS = ["stanford-bunny.obj", "fandisk.obj", "DamagedHelmet/DamagedHelmet.gltf", "CesiumMilkTruck.glb",
          "chess_set_flat.usdc"]


def _wh(text: str) -> tuple[int, int]:
    w, h = (int(v) for v in text.lower().split("x"))
    return w, h


def _psnr(v) -> str:
    return "inf" if v is None else f"{v:.1f}"


def run_asset(path: Path, args) -> list[dict]:
    levels = parse_levels(args.levels)
    t0 = time.perf_counter()
    scene = load(str(path), DEFAULT_INGEST)
    t_ingest = time.perf_counter() - t0
    viewing = Viewing()

    def progress(p):
        print(f"    probe log2 sigma {p['log2_sigma']:+.3f}: CAP min {_psnr(p['psnr_min'])} / mean "
              f"{_psnr(p['psnr_mean'])} dB, mem {min(p['cap_percent']):.1f}-{max(p['cap_percent']):.1f}% "
              f"({p['seconds']:.1f} s)", flush=True)

    out, rendered = [], {}
    for statistic in args.statistic:
        t0 = time.perf_counter()
        base = replace(DEFAULT_ANALYSE, edges=not args.no_edges)
        cal = calibrate(scene, base, target_psnr=args.target_psnr, levels=levels, views=args.cal_views,
                        resolution=_wh(args.cal_resolution), viewing=viewing,
                        ingest_options={"crease_angle_deg": DEFAULT_INGEST.crease_angle_deg}, progress=progress,
                        statistic=statistic, search=args.search)
        t_cal = time.perf_counter() - t0
        print(format_calibration(cal), flush=True)
        t_cook = t_eval = 0.0
        key = (cal["sigma"], cal["edge_eps"])
        if key not in rendered:
            t0 = time.perf_counter()
            settings = calibrated_settings(base, cal)
            an = analyse(scene, settings)
            hist = an.histogram()
            min_level_percent = 100.0 * float(sum(b * int(hist[b]) for b in range(len(hist)))) / (32.0 * hist.sum())
            data = build(scene, an, options={"analyse": settings.to_record()}, viewing=viewing)
            c = from_bytes(data, path.name)
            t_cook = time.perf_counter() - t0
            t0 = time.perf_counter()
            res = evaluate(c, scene, levels=levels, views=args.views, resolution=_wh(args.resolution))
            res["min_level_percent"] = min_level_percent
            res["reasons"] = an.reason_counts()
            rendered[key] = res
            t_eval = time.perf_counter() - t0
            print(format_table(res), flush=True)
            print(f"  minimum-level memory {min_level_percent:.1f}% of float32; reasons {res['reasons']}", flush=True)
        out.append({"asset": path.name, "statistic": statistic, "vertices": scene.n_vertices,
                    "triangles": scene.n_triangles, "parts": len(scene.parts),
                    "textured_parts": sum(p.texture is not None for p in scene.parts), "calibration": cal,
                    "render": rendered[key],
                    "seconds": {"ingest": t_ingest, "calibrate": t_cal, "cook": t_cook, "evaluate": t_eval}})
    return out


# ---- --diagnose: where the CAP error lies --------------------------------------------------------

_NORMAL_FS = """#version 450
in vec3 v_pos; in vec3 v_normal; in vec2 v_uv; in vec4 v_color;
uniform vec3 u_eye;
layout(location = 0) out vec4 o;
void main() {
    vec3 N = length(v_normal) > 1e-12 ? normalize(v_normal) : normalize(cross(dFdx(v_pos), dFdy(v_pos)));
    o = vec4(N, length(v_pos - u_eye));
}
"""


class _NormalDepth:
    """Float render of unit normals (RGB) and eye distance in metres (A; -1 = background), 1 sample."""

    def __init__(self, h):
        from lopcook.verify.glsl import vertex_shader_source

        ctx = self.ctx = h.ctx
        self.prog = ctx.program(vertex_shader=vertex_shader_source(False), fragment_shader=_NORMAL_FS)
        self.size = w, hh = h.renderer.size
        self.tex = ctx.texture((w, hh), 4, dtype="f4")
        self.depth = ctx.depth_renderbuffer((w, hh))
        self.fbo = ctx.framebuffer([self.tex], self.depth)
        self.vaos, self.own = [], [self.prog, self.tex, self.depth, self.fbo]
        for p in h.scene.parts:
            bufs = [ctx.buffer(np.ascontiguousarray(p.positions, dtype="<f4").tobytes()),
                    ctx.buffer(np.ascontiguousarray(p.indices, dtype="<u4").tobytes())]
            specs = [(bufs[0], "3f", "in_position")]
            if p.normals is not None:
                bufs.append(ctx.buffer(np.ascontiguousarray(p.normals, dtype="<f4").tobytes()))
                specs.append((bufs[2], "3f", "in_normal"))
            vao = ctx.vertex_array(self.prog, specs, index_buffer=bufs[1], index_element_size=4)
            self.vaos.append(vao)
            self.own += bufs + [vao]

    def draw(self, cam) -> np.ndarray:
        import moderngl

        from lopcook.verify import gpu

        self.prog["u_mvp"].write(cam.mvp.T.astype("<f4").tobytes())
        if "u_eye" in self.prog:
            self.prog["u_eye"].value = tuple(float(v) for v in cam.eye)
        self.fbo.use()
        self.fbo.clear(0.0, 0.0, 0.0, -1.0, depth=1.0)
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.disable(moderngl.CULL_FACE)
        for vao in self.vaos:
            vao.render(moderngl.TRIANGLES)
        w, h = self.size
        out = np.frombuffer(self.tex.read(), "<f4").reshape(h, w, 4)[::-1].copy()
        gpu.use_default_framebuffer()
        return out

    def release(self) -> None:
        for r in self.own:
            r.release()


def _neighbour(a: np.ndarray, differs) -> np.ndarray:
    """(h, w) bool: ``differs(a[p], a[q])`` for some 4-neighbour q of p (vectorised shifts)."""
    out = np.zeros(a.shape[:2], bool)
    d = differs(a[1:], a[:-1])
    out[1:] |= d
    out[:-1] |= d
    d = differs(a[:, 1:], a[:, :-1])
    out[:, 1:] |= d
    out[:, :-1] |= d
    return out


def _dilate(m: np.ndarray, r: int = 2) -> np.ndarray:
    h, w = m.shape
    pad = np.pad(m, r)
    out = np.zeros_like(m)
    for dy in range(2 * r + 1):
        for dx in range(2 * r + 1):
            out |= pad[dy:dy + h, dx:dx + w]
    return out


CLASSES = ("silhouette", "occlusion", "hard_edge", "elsewhere")


def pixel_classes(rgba, ids, normal_depth, pixel_m: float, angle_deg: float = 40.0, r: int = 2) -> dict:
    """(h, w) bool masks, disjoint, in priority order ``CLASSES`` (module doc)."""
    sil = _neighbour(ids, lambda a, b: a != b) | ((rgba[..., 3] > 0) & (rgba[..., 3] < 255))
    depth = normal_depth[..., 3]
    occl = _neighbour(depth, lambda a, b: (np.abs(a - b) > 8 * pixel_m) & (a > 0) & (b > 0))
    cos = np.cos(np.radians(angle_deg))
    hard = _neighbour(normal_depth[..., :3], lambda a, b: np.einsum("...k,...k->...", a, b) < cos) & (ids != 0)
    sil = _dilate(sil, r)
    occl = _dilate(occl, r) & ~sil
    hard = _dilate(hard, r) & ~sil & ~occl
    return {"silhouette": sil, "occlusion": occl, "hard_edge": hard, "elsewhere": ~(sil | occl | hard)}


def _split(h, nd, c, levels, views) -> list[dict]:
    from lopcook.verify import cameras as C
    from lopcook.verify import metrics as M

    viewing = C.render_viewing(c.manifest, h.renderer.size)
    rows = []
    for level in levels:
        acc = dict.fromkeys(CLASSES, 0.0)
        pixels = dict.fromkeys(CLASSES, 0)
        psnrs, mem = [], None
        for view in C.select_views(views):
            res = harness_evaluate(h, c, levels=[level], views=[view], variants=("cap",), keep_images=True, image_view=view)
            im, row = res["images"], res["levels"][0]
            mem = row["cap"]["percent_of_float32"]
            psnrs.append(row["cap"]["psnr_min"])
            cam = C.make_camera(view, h.lo, h.hi, row["camera_distance_m"], viewing)
            masks = pixel_classes(im["float"], im["float_ids"], nd.draw(cam), float(viewing.pixel_size(
                row["camera_distance_m"])))
            obj = M.object_mask(im["float"]) | M.object_mask(im["cap"])
            sq = ((im["float"][..., :3].astype(np.float64) - im["cap"][..., :3]) / 255.0) ** 2
            sq = sq.sum(axis=2)
            for k, m in masks.items():
                acc[k] += float(sq[m & obj].sum())
                pixels[k] += int(np.count_nonzero(m & obj))
        finite = [p for p in psnrs if p is not None]
        rows.append({"level": level, "cap_percent": mem, "psnr_min": min(finite) if finite else None,
                     "sum_sq": acc, "pixels": pixels})
    return rows


def _print_split(rows) -> None:
    for r in rows:
        total = sum(r["sum_sq"].values()) or 1.0
        parts = "  ".join(f"{k} {100 * r['sum_sq'][k] / total:5.1f}% ({r['pixels'][k]} px)" for k in CLASSES)
        print(f"  level {r['level']:2d}  CAP {r['cap_percent']:5.1f}%  PSNR min {_psnr(r['psnr_min']):>5}  | {parts}",
              flush=True)


def diagnose(path: Path, args) -> None:
    """Print where the CAP error lies for one asset (module doc, ``--diagnose``)."""
    from lopcook.verify import renderer

    levels = parse_levels(args.levels)
    scene = load(str(path), DEFAULT_INGEST)
    settings = replace(DEFAULT_ANALYSE, eps=DEFAULT_ANALYSE.eps / args.kf_scale, edges=not args.no_edges)
    viewing = Viewing()
    with renderer.Harness(scene, _wh(args.resolution), cache_float=True) as h:
        nd = _NormalDepth(h)
        try:
            an = analyse(scene, settings)
            c = from_bytes(build(scene, an, options={"analyse": settings.to_record()}, viewing=viewing), None)
            print(f"== {path.name}: k_f scale {args.kf_scale:g}, edges {'on' if settings.edges else 'off'}, "
                  f"{args.views} views, {args.resolution}; reasons {an.reason_counts()}", flush=True)
            _print_split(_split(h, nd, c, levels, args.views))
            for f in [int(v) for v in args.fixed.split(",") if v]:
                for pa in an.parts:
                    pa.min_level = np.full_like(pa.min_level, f)
                c = from_bytes(build(scene, an, options={"analyse": settings.to_record()}, viewing=viewing), None)
                print(f"  every vertex at level {f}:", flush=True)
                _print_split(_split(h, nd, c, levels, args.views))
        finally:
            nd.release()


def table(results: list[dict]) -> str:
    lines = []
    for r in results:
        cal = r["calibration"]
        kfn = "-" if cal["kf_normal"] is None else f"{cal['kf_normal']:.3g}"
        res = r["render"]
        edge = f"edge_eps = {cal['edge_eps']:.3g}" if cal.get("edges") else "edges off"
        lines += [f"### {r['asset']}  ({r['vertices']:,} vertices, {r['parts']} parts), calibrated on the "
                  f"{r['statistic']} over views",
                  "",
                  f"calibrated: k_f scale sigma = {cal['sigma']:.3g} (2^{cal['log2_sigma']:.2f}), k_f normal = {kfn}, "
                  f"eps = {cal['eps']:.3g}, {edge}; minimum-level memory {res['min_level_percent']:.1f}%; "
                  f"target {cal['target_psnr']:g} dB "
                  f"{'reached' if cal['reached'] else 'NOT reached'} "
                  f"in calibration ({cal['views']} views, {cal['resolution'][0]}x{cal['resolution'][1]}, "
                  f"{len(cal['curve'])} probes, {r['seconds']['calibrate']:.0f} s); final check "
                  f"{len(res['views'])} views, {res['resolution'][0]}x{res['resolution'][1]} "
                  f"({r['seconds']['evaluate']:.0f} s)",
                  "",
                  "| level | AP mem % | AP PSNR min / mean | CAP mem % | CAP PSNR min / mean | depth-order px AP / CAP "
                  "| interior PSNR min AP / CAP |",
                  "|---|---|---|---|---|---|---|"]
        for row in res["levels"]:
            ap, cp = row["ap"], row["cap"]
            lines.append(f"| {row['level']} | {ap['percent_of_float32']:.1f} | {_psnr(ap['psnr_min'])} / "
                         f"{_psnr(ap['psnr_mean'])} | {cp['percent_of_float32']:.1f} | {_psnr(cp['psnr_min'])} / "
                         f"{_psnr(cp['psnr_mean'])} | {ap['depth_order_errors']} / {cp['depth_order_errors']} "
                         f"| {_psnr(ap['psnr_interior_min'])} / {_psnr(cp['psnr_interior_min'])} |")
        lines.append("")
    return "\n".join(lines)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--corpus", default=os.environ.get("LOPCOOK_CORPUS", str(REPO.parent / "shared" / "corpus")))
    ap.add_argument("--assets", nargs="*", default=ASSETS)
    ap.add_argument("--target-psnr", type=float, default=40.0)
    ap.add_argument("--statistic", nargs="+", choices=("min", "mean"), default=["min", "mean"])
    ap.add_argument("--levels", default="6-11")
    ap.add_argument("--cal-views", type=int, default=8)
    ap.add_argument("--cal-resolution", default="640x360")
    ap.add_argument("--views", type=int, default=20)
    ap.add_argument("--resolution", default="1280x720")
    ap.add_argument("--search", choices=("kf", "kf+edge"), default="kf+edge")
    ap.add_argument("--no-edges", action="store_true", help="the paper's CAP: no discontinuity constraint")
    ap.add_argument("--diagnose", action="store_true", help="error split by pixel class instead (module doc)")
    ap.add_argument("--kf-scale", type=float, default=1.0, help="--diagnose: k_f scale sigma (eps / sigma)")
    ap.add_argument("--fixed", default="", help="--diagnose: also every vertex at these levels, e.g. 10,14")
    ap.add_argument("--out", default=str(REPO / "bench-out" / "verify_corpus"))
    args = ap.parse_args()
    if args.diagnose:
        for name in args.assets:
            diagnose(Path(args.corpus) / name, args)
        return 0
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    results = []
    for name in args.assets:
        print(f"== {name}", flush=True)
        t0 = time.perf_counter()
        results += run_asset(Path(args.corpus) / name, args)
        results[-1]["seconds"]["asset_total"] = time.perf_counter() - t0
        (out / "results.json").write_text(json.dumps(results, indent=1, sort_keys=True))
    text = table(results)
    (out / "table.md").write_text(text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
