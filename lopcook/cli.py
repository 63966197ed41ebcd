"""Command-line interface: parse flags, call one stage function, map errors to exit codes.

Exit codes: 0 ok, 1 verification failed, 2 bad input or usage (one line on stderr, no traceback
unless ``--debug``), 3 internal error (a bug: please report it with the ``--debug`` output).
"""

from __future__ import annotations

import argparse
import json
import sys

from . import __version__
from .batch.cli import _add_batch_parser, cmd_batch
from .errors import EXIT_OK, LopcookError

EXIT_INTERNAL = 3


def _add_crease_angle(p: argparse.ArgumentParser) -> None:
    p.add_argument("--crease-angle", type=float, default=None, metavar="DEG",
                   help="dihedral angle in degrees above which computed normals split (default 60; 180 = smooth)")


def _add_common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--json", action="store_true", help="print the result as JSON on stdout instead of text")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="lopcook",
        description="Cook glTF/OBJ/USD scenes into level-of-precision (LOP) vertex containers.",
    )
    parser.add_argument("--version", action="version", version=f"lopcook {__version__}")
    parser.add_argument("--debug", action="store_true", help="show Python tracebacks on errors")
    parser.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors (and --json output)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    p = sub.add_parser("inspect", help="describe a source scene or a .lop container")
    p.add_argument("source", metavar="FILE", help="glTF/GLB, OBJ or USD (.usd/.usda/.usdc/.usdz) file, or a .lop container")
    _add_crease_angle(p)
    _add_common(p)

    p = sub.add_parser("cook", help="ingest, analyse and write a .lop container")
    p.add_argument("source", metavar="SOURCE", help="glTF/GLB, OBJ or USD file")
    p.add_argument("-o", "--output", required=True, metavar="OUT.lop", help="container to write (atomically)")
    p.add_argument("--depfile", metavar="OUT.d", help="write a Make-style depfile listing every file read")
    p.add_argument("--lods", default=None, metavar="auto|R1,R2,...",
                   help="also write LODs: auto (the default chain 1/2, 1/4, 1/8, ... until a LOD's error exceeds "
                        "what the farthest view can show, given --nearest, or its target falls under 4 triangles) "
                        "or these fractions of the triangles, e.g. 1/2,1/4,1/8 (default: LOD 0 only)")
    p.add_argument("--lod-backend", default="pymeshlab", choices=["pymeshlab", "fast"],
                   help="simplifier: pymeshlab quadric collapse (seam-aware, default) or fast-simplification")
    add_analyse_options(p)
    add_viewing_options(p)
    _add_crease_angle(p)
    add_calibration_options(p, cook=True)
    add_budget_options(p)
    _add_common(p)

    p = sub.add_parser("calibrate", help="measure k_f: the least memory whose CAP renders reach a target PSNR")
    p.add_argument("source", metavar="SOURCE", help="glTF/GLB, OBJ or USD file")
    add_analyse_options(p)
    add_viewing_options(p)
    _add_crease_angle(p)
    add_calibration_options(p, cook=False)
    _add_common(p)

    p = sub.add_parser("decode", help="decode a .lop container at a level into a standard glTF 2.0 file")
    p.add_argument("container", metavar="OUT.lop")
    p.add_argument("--level", type=int, required=True, metavar="B", help="per-buffer level B in [1, 24]")
    p.add_argument("--lod", type=int, default=0, metavar="K", help="LOD to decode (default 0)")
    p.add_argument("-o", "--output", required=True, metavar="OUT.glb", help=".glb, or .gltf (+ .bin)")
    _add_common(p)

    p = sub.add_parser("analyse", help="per-vertex minimum bit levels (attribute error and depth constraints)")
    p.add_argument("source", metavar="SOURCE", help="glTF/GLB, OBJ or USD file")
    add_analyse_options(p)
    _add_crease_angle(p)
    _add_common(p)

    p = sub.add_parser("verify", help="check a .lop container (--decoders: the GPU shaders against the CPU reference; "
                                      "--source: renders against the float source)")
    p.add_argument("container", metavar="OUT.lop")
    g = p.add_argument_group("checks (give at least one)")
    g.add_argument("--decoders", action="store_true",
                   help="decode every part/LOD with the GLSL and HLSL shaders of shaders/ (moderngl through EGL; "
                        "HLSL via glslang + spirv-cross) and walk the adaption kernels through the levels; every "
                        "integer, float bit and packed word must equal the CPU reference")
    g.add_argument("--source", metavar="SOURCE", default=None,
                   help="render the float SOURCE, AP and CAP (positions decoded by the shipped GLSL decoder) from "
                        "icosahedron views at the distance where each level is selected; print a Table-1-like "
                        "table and fail (exit 1) when CAP's PSNR is below --min-psnr")
    p.add_argument("--levels", default=None, metavar="LEVELS",
                   help="per-buffer levels to check: a range or list in [1, 24], e.g. 1-24 or 6,8,12 "
                        "(default: every level the file holds for --decoders, 6-12 for --source)")
    r = p.add_argument_group("render check (--source)")
    r.add_argument("--min-psnr", type=float, default=40.0, metavar="DB",
                   help="CAP PSNR (dB) every level must reach (default 40); see --psnr-stat")
    r.add_argument("--psnr-stat", choices=("min", "mean"), default="min",
                   help="PSNR over views compared with --min-psnr: min (every view, default) or mean (PSNR of "
                        "the view-averaged MSE)")
    r.add_argument("--max-depth-errors", type=int, default=None, metavar="PIXELS",
                   help="fail when CAP shows more depth-order error pixels than this at a level (default: not checked)")
    r.add_argument("--views", type=int, default=20, metavar="N", help="icosahedron views, 1..20 (default 20)")
    r.add_argument("--resolution", default="1280x720", metavar="WxH", help="render size in pixels (default 1280x720)")
    r.add_argument("--crease-angle", type=float, default=None, metavar="DEG",
                   help="ingest setting for SOURCE (default: the one recorded in the container, else 60)")
    p.add_argument("--languages", default="glsl,hlsl", metavar="glsl,hlsl",
                   help="shader languages to run (default: glsl,hlsl)")
    p.add_argument("--no-adapt", action="store_true",
                   help="with --decoders: skip the compute-shader adaption check (decode only)")
    _add_common(p)

    p = sub.add_parser("report", help="one self-contained HTML report (and report.json) of a container rendered "
                                      "against its float source")
    p.add_argument("container", metavar="OUT.lop")
    p.add_argument("--source", metavar="SOURCE", required=True, help="the glTF/GLB, OBJ or USD file it was cooked from")
    p.add_argument("-o", "--output", metavar="REPORT.html", required=True,
                   help="HTML file to write; the JSON goes beside it with the suffix .json")
    p.add_argument("--levels", default=None, metavar="LEVELS", help="per-buffer levels, e.g. 6-12 (default 6-12)")
    p.add_argument("--views", type=int, default=20, metavar="N", help="icosahedron views, 1..20 (default 20)")
    p.add_argument("--resolution", default="1280x720", metavar="WxH", help="render size in pixels (default 1280x720)")
    _add_crease_angle(p)
    p.add_argument("--no-analyse", action="store_true",
                   help="do not re-cook the source (no stage timings, no determinism check, no warnings from the "
                        "analysis: touching/intersecting parts, degenerate triangles)")
    _add_common(p)
    _add_bench_parser(sub)
    _add_batch_parser(sub)
    # the global flags also work after the command (lopcook cook x.glb -o x.lop -q)
    for command in sub.choices.values():
        command.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                             help="show Python tracebacks on errors")
        command.add_argument("-q", "--quiet", action="store_true", default=argparse.SUPPRESS,
                             help="print nothing but errors (and --json output)")
    return parser


def add_viewing_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("viewing conditions (recorded in the container)")
    g.add_argument("--viewport", default="1920x1080", metavar="WxH", help="viewport in pixels (default 1920x1080)")
    g.add_argument("--fov", type=float, default=60.0, metavar="DEG", help="vertical field of view, degrees (default 60)")
    g.add_argument("--nearest", default=None, metavar="METRES",
                   help="closest camera distance to the scene, metres (e.g. 0.5 or 0.5m; default unknown)")
    g.add_argument("--pixel-error", type=float, default=0.5, metavar="PX",
                   help="allowed screen-space error in pixels (default 0.5, the paper's half pixel)")


def add_calibration_options(p: argparse.ArgumentParser, cook: bool) -> None:
    from .verify.calibrate import CAL_RESOLUTION, CAL_VIEWS

    g = p.add_argument_group("k_f calibration (renders CAP against the source; see lopcook.verify.calibrate)")
    if cook:
        g.add_argument("--target-psnr", type=float, default=None, metavar="DB",
                       help="first search the k_f scale with the least memory whose CAP renders reach DB dB at "
                            "every level (see --psnr-stat), then cook with it; the curve is recorded in the "
                            "container options")
    else:
        g.add_argument("--target-psnr", type=float, required=True, metavar="DB",
                       help="CAP PSNR (dB) to reach at every level (see --psnr-stat)")
    prefix = "calibration-" if cook else ""
    g.add_argument(f"--{prefix}views", dest="calibration_views", type=int, default=CAL_VIEWS, metavar="N",
                   help=f"icosahedron views per probe, 1..20 (default {CAL_VIEWS})")
    g.add_argument(f"--{prefix}resolution", dest="calibration_resolution",
                   default=f"{CAL_RESOLUTION[0]}x{CAL_RESOLUTION[1]}", metavar="WxH",
                   help=f"render size per probe (default {CAL_RESOLUTION[0]}x{CAL_RESOLUTION[1]})")
    g.add_argument(f"--{prefix}levels", dest="calibration_levels", default="6-12", metavar="LEVELS",
                   help="per-buffer levels every probe must pass (default 6-12)")
    g.add_argument("--psnr-stat", choices=("min", "mean"), default="min",
                   help="PSNR over views that must reach the target: min (every view, default) or mean "
                        "(PSNR of the view-averaged MSE, as Purnomo et al. average errors)")
    g.add_argument("--search", choices=("kf", "kf+edge"), default=None,
                   help="knobs to search: the k_f scale only (kf), or also the edge constraint's --edge-eps "
                        "(kf+edge, the default when --edges is on)")
    g.add_argument("--no-calibration-confirm", dest="calibration_confirm", action="store_false",
                   help="do not confirm the choice with lopcook verify's 20 views at 1280x720 (by default the "
                        "k_f scale is raised until it passes there too)")


def add_budget_options(p: argparse.ArgumentParser) -> None:
    from .budget import DEFAULT_LEVELS_PER_LOD, DEFAULT_RESOLUTION, DEFAULT_SCOPE, DEFAULT_VIEWS, SCOPES

    g = p.add_argument_group("byte budget (Purnomo et al. 2005, section 5; see docs/budget.md)")
    g.add_argument("--target-bytes", default=None, metavar="N|P/Q",
                   help="cook the LOD chain (--lods, default 1/2, 1/4, ...), render every (LOD, level) that fits "
                        "in N bytes and write only the one with the least image error; P/Q = that fraction of the "
                        "float size (e.g. 1/6). Fails (exit 2) when nothing fits")
    g.add_argument("--budget-scope", choices=SCOPES, default=DEFAULT_SCOPE,
                   help="what the bytes count: positions (GPU position buffer; float size 12 B/vertex, default), "
                        "vertices (+ stored normals/UVs/colours), all (+ index buffer)")
    g.add_argument("--budget-views", type=int, default=DEFAULT_VIEWS, metavar="N",
                   help=f"icosahedron views per candidate, 1..20 (default {DEFAULT_VIEWS})")
    g.add_argument("--budget-resolution", default=f"{DEFAULT_RESOLUTION[0]}x{DEFAULT_RESOLUTION[1]}", metavar="WxH",
                   help=f"render size per candidate (default {DEFAULT_RESOLUTION[0]}x{DEFAULT_RESOLUTION[1]})")
    g.add_argument("--budget-levels", type=int, default=DEFAULT_LEVELS_PER_LOD, metavar="N",
                   help=f"levels rendered per LOD: the largest that fits and N-1 below (default {DEFAULT_LEVELS_PER_LOD})")


def _budget_target(text: str, float_size: int | None = None) -> int | None:
    """``--target-bytes``: an integer number of bytes, or P/Q of ``float_size`` (rounded down).
    With ``float_size`` None only the syntax is checked (returns None for a fraction)."""
    from fractions import Fraction

    t = str(text).strip().replace("_", "").replace(",", "")
    try:
        value = Fraction(t)
    except (ValueError, ZeroDivisionError):
        raise LopcookError("usage", None, f"--target-bytes {text!r}: expected a number of bytes (e.g. 150000) "
                           "or a fraction of the float size (e.g. 1/6)") from None
    if "/" not in t:
        if value.denominator != 1 or value <= 0:
            raise LopcookError("usage", None, f"--target-bytes {text!r}: expected a positive whole number of bytes")
        return int(value)
    if not value > 0:
        raise LopcookError("usage", None, f"--target-bytes {text!r}: the fraction must be positive")
    return None if float_size is None else int(value * float_size)


def _run_budget(args, scene, settings, viewing, lod_ratios, options):
    """``cook --target-bytes``: ``lopcook.budget.fit`` -> (data, info as ``cook_bytes`` gives it, record)."""
    from .budget import fit, float_bytes

    target = _budget_target(args.target_bytes, float_bytes(scene, args.budget_scope))
    if target < 1:
        raise LopcookError("usage", args.source, f"--target-bytes {args.target_bytes}: less than one byte of the "
                           f"float size {float_bytes(scene, args.budget_scope):,} B")
    data, binfo = fit(scene, target, settings, viewing, lod_ratios=lod_ratios, lod_backend=args.lod_backend,
                      scope=args.budget_scope, views=args.budget_views,
                      resolution=_resolution(args.budget_resolution, "--budget-resolution"),
                      levels_per_lod=args.budget_levels, options=options, progress=lambda m: _progress(args, m))
    info = dict(binfo["cook"], analysis=binfo["analysis"])
    info["timings_s"] = {k: v for k, v in binfo["cook"]["timings_s"].items() if k != "total"}
    info["timings_s"].update({f"budget.{k}": v for k, v in binfo["timings_s"].items() if k != "cook"})
    return data, info, binfo["budget"]


def _resolution(text: str, flag: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in str(text).lower().split("x"))
    except ValueError:
        raise LopcookError("usage", None, f"{flag} {text!r}: expected WIDTHxHEIGHT, e.g. 1280x720") from None
    if not (1 <= w <= 16384 and 1 <= h <= 16384):
        raise LopcookError("usage", None, f"{flag} {text!r}: width and height must be in [1, 16384] pixels")
    return w, h


def _views(n: int, flag: str) -> int:
    if not 1 <= int(n) <= 20:
        raise LopcookError("usage", None, f"{flag} {n}: expected 1..20 icosahedron views")
    return int(n)


def _run_calibration(args, scene, settings, viewing, ingest_settings) -> dict:
    from .verify.calibrate import calibrate
    from .verify.decoders import parse_levels

    prefix = "--calibration-" if args.command == "cook" else "--"
    levels = parse_levels(args.calibration_levels)
    views = _views(args.calibration_views, f"{prefix}views")
    resolution = _resolution(args.calibration_resolution, f"{prefix}resolution")
    if not args.target_psnr > 0:
        raise LopcookError("usage", None, f"--target-psnr {args.target_psnr}: expected a positive number of dB")

    def progress(p):
        ps = "inf" if p["psnr_min"] is None else f"{p['psnr_min']:.1f} dB"
        what = "confirm" if p.get("confirm") else "calibrate"
        _progress(args, f"{what}: k_f scale 2^{p['log2_sigma']:.3g}, edge eps {p['edge_eps']:.3g}: CAP {ps}, "
                        f"{max(p['cap_percent']):.1f}% of float32 ({p['seconds']:.1f} s)")

    from .verify.calibrate import CONFIRM

    return calibrate(scene, settings, target_psnr=args.target_psnr, levels=levels, views=views, resolution=resolution,
                     viewing=viewing, ingest_options={"crease_angle_deg": ingest_settings.crease_angle_deg},
                     progress=progress, statistic=args.psnr_stat, search=args.search,
                     confirm=CONFIRM if args.calibration_confirm else None)


def _viewing(args):
    from .viewing import Viewing

    try:
        w, h = (int(v) for v in args.viewport.lower().split("x"))
    except ValueError:
        raise LopcookError("usage", None, f"--viewport {args.viewport!r}: expected WIDTHxHEIGHT, e.g. 1920x1080") from None
    nearest = None
    if args.nearest is not None:
        text = args.nearest.strip().lower()
        try:
            nearest = float(text[:-1] if text.endswith("m") else text)
        except ValueError:
            raise LopcookError("usage", None, f"--nearest {args.nearest!r}: expected metres, e.g. 0.5m") from None
    try:
        return Viewing(viewport=(w, h), fov_y_deg=args.fov, nearest_m=nearest, pixel_error=args.pixel_error)
    except ValueError as exc:
        raise LopcookError("usage", None, str(exc)) from None


def add_analyse_options(p: argparse.ArgumentParser) -> None:
    from .settings import DEFAULT_ANALYSE as d

    g = p.add_argument_group("analysis (Meyer et al. 2011, section 5)")
    g.add_argument("--eps", type=float, default=d.eps, metavar="COLOUR",
                   help="largest shading error a vertex may cause, colour units in [0,1] (default 1/255)")
    g.add_argument("--ks", type=float, default=d.ks, help=f"Phong specular coefficient (default {d.ks})")
    g.add_argument("--shininess", type=float, default=d.shininess, help=f"Phong exponent n (default {d.shininess:g}); "
                   "normals use k_f = ks * n")
    g.add_argument("--kf", type=float, default=None,
                   help="override k_f for every attribute (colour per attribute unit)")
    g.add_argument("--texture-kf", default="image", metavar="image|off|VALUE",
                   help="k_f of UVs: the base-colour texture's maximum slope (image, default), off, or colour per UV unit")
    g.add_argument("--depth", default="auto", metavar="auto|off|fixed:N",
                   help="depth constraints: from distances to other parts (auto, default), none, or the paper's "
                        "mode: vertices closer than --depth-threshold get level N")
    g.add_argument("--depth-threshold", type=float, default=0.0, metavar="METRES",
                   help="distance under which a vertex is depth-critical in fixed:N mode")
    g.add_argument("--depth-ceiling", type=int, default=d.depth_ceiling, metavar="N",
                   help=f"highest level a depth constraint may impose; touching parts are capped there (default {d.depth_ceiling})")
    g.add_argument("--edges", action=argparse.BooleanOptionalAction, default=d.edges,
                   help="discontinuity constraint: raise vertices on hard edges, sub-pixel folds, open boundaries "
                        "and colour seams, which E_v cannot see (default on; docs/analyse.md)")
    g.add_argument("--edge-eps", type=float, default=d.edge_eps, metavar="COLOUR",
                   help=f"colour change an edge may cause in a pixel, colour units in (0,1] (default {d.edge_eps:g}: "
                        "a full-range jump costs 2 bits above the level)")
    g.add_argument("--edge-level", type=int, default=d.edge_level, metavar="N",
                   help=f"highest per-buffer level the edge bound is kept at, in [1,24] (default {d.edge_level})")
    g.add_argument("--edge-angle", type=float, default=d.edge_angle_deg, metavar="DEGREES",
                   help=f"normal spread within one pixel that makes a fold, in (0,180] (default {d.edge_angle_deg:g})")


def _ingest_settings(args):
    from .settings import IngestSettings

    kw = {}
    if getattr(args, "crease_angle", None) is not None:
        if not 0.0 <= args.crease_angle <= 180.0:
            raise LopcookError("usage", None, f"--crease-angle {args.crease_angle} is outside [0, 180] degrees")
        kw["crease_angle_deg"] = args.crease_angle
    return IngestSettings(**kw)


def _analyse_settings(args):
    from .settings import AnalyseSettings

    depth = args.depth
    if depth.startswith("fixed:"):
        try:
            level = int(depth.split(":", 1)[1])
        except ValueError:
            level = -1
        if not 1 <= level <= 24:
            raise LopcookError("usage", None, f"--depth {depth}: N must be an integer level in [1, 24]")
        if not args.depth_threshold > 0:
            raise LopcookError("usage", None, f"--depth {depth} needs --depth-threshold METRES > 0")
        depth = ("fixed", level)
    elif depth not in ("auto", "off"):
        raise LopcookError("usage", None, f"--depth {depth!r}: expected auto, off or fixed:N")
    tk = args.texture_kf
    if tk not in ("image", "off"):
        try:
            tk = float(tk)
        except ValueError:
            raise LopcookError("usage", None, f"--texture-kf {tk!r}: expected image, off or a number") from None
    try:
        return AnalyseSettings(eps=args.eps, ks=args.ks, shininess=args.shininess, kf=args.kf, texture_kf=tk,
                               depth=depth, depth_threshold=args.depth_threshold,
                               depth_ceiling=args.depth_ceiling, edges=args.edges, edge_eps=args.edge_eps,
                               edge_level=args.edge_level, edge_angle_deg=args.edge_angle)
    except ValueError as exc:
        raise LopcookError("usage", None, str(exc)) from None


def cmd_analyse(args) -> int:
    from .analyse import analyse
    from .analyse.summary import describe_analysis, format_analysis
    from .ingest import load

    settings = _analyse_settings(args)
    scene = load(args.source, _ingest_settings(args))
    desc = describe_analysis(analyse(scene, settings), args.source)
    if args.json:
        print(json.dumps(desc, indent=1, sort_keys=True))
    elif not args.quiet:
        print(format_analysis(desc))
    return EXIT_OK


def _progress(args, message: str) -> None:
    """Stage lines on stderr, only on a terminal and without --quiet/--json (build logs stay clean)."""
    if not args.quiet and not args.json and sys.stderr.isatty():
        print(f"lopcook: {message}", file=sys.stderr, flush=True)


def _is_container(path: str) -> bool:
    if path.lower().endswith(".lop"):
        return True
    try:
        with open(path, "rb") as fh:
            return fh.read(4) == b"LOPC"
    except OSError:
        return False


def _lod_ratios(text):
    """``--lods``: see ``lopcook.pipeline.parse_lod_ratios``."""
    from .pipeline import parse_lod_ratios

    return parse_lod_ratios(text)


def cmd_cook(args) -> int:
    import os
    import time

    from .emit.container import from_bytes, write_atomic
    from .emit.summary import describe_container, format_container
    from .ingest import load

    settings = _analyse_settings(args)
    viewing = _viewing(args)
    lod_ratios = _lod_ratios(args.lods)
    ingest_settings = _ingest_settings(args)
    if os.path.isdir(args.output):
        raise LopcookError("usage", args.output, "output is a directory", hint="give a file name, e.g. out.lop")
    if args.target_bytes is not None:  # usage errors before any work
        _budget_target(args.target_bytes)
        _views(args.budget_views, "--budget-views")
        _resolution(args.budget_resolution, "--budget-resolution")
        if args.budget_levels < 1:
            raise LopcookError("usage", None, f"--budget-levels {args.budget_levels}: expected 1 or more")
    timings = {}
    t0 = time.perf_counter()
    _progress(args, f"ingest {args.source}")
    scene = load(args.source, ingest_settings)
    timings["ingest"] = time.perf_counter() - t0
    calibration = None
    if args.target_psnr is not None:
        from dataclasses import replace

        from .verify.calibrate import require_reached

        t0 = time.perf_counter()
        calibration = _run_calibration(args, scene, settings, viewing, ingest_settings)
        timings["calibrate"] = time.perf_counter() - t0
        require_reached(calibration, args.source)
        settings = replace(settings, eps=calibration["eps"], edge_eps=calibration["edge_eps"])
    _progress(args, f"analyse and emit {len(scene.parts)} parts, {scene.n_vertices:,} vertices")
    from .analyse.summary import _settings_dict
    from .pipeline import cook_bytes

    options = {"analyse": _settings_dict(settings), "ingest": {"crease_angle_deg": ingest_settings.crease_angle_deg}}
    if lod_ratios is not None:
        options["lods"] = {"ratios": args.lods, "backend": args.lod_backend}
    if calibration is not None:
        options["calibration"] = _calibration_record(calibration)
    budget = None
    if args.target_bytes is not None:
        data, info, budget = _run_budget(args, scene, settings, viewing, lod_ratios, options)
    else:
        data, info = cook_bytes(scene, settings, viewing, lod_ratios=lod_ratios, lod_backend=args.lod_backend,
                                options=options)
    analysis = info["analysis"]
    timings.update({f"analyse.{k}": v for k, v in analysis.timings.items()})
    timings.update({k: v for k, v in info["timings_s"].items() if k != "total"})
    t0 = time.perf_counter()
    write_atomic(args.output, data)
    if args.depfile:
        from .depfile import write_depfile

        # phony rules: a listed file that does not exist yet (a missing texture) reruns the cook
        # instead of stopping make with "no rule to make target"
        write_depfile(args.depfile, args.output, scene.dependencies or (args.source,), phony=True)
    timings["write"] = time.perf_counter() - t0
    desc = describe_container(from_bytes(data, args.output), file_bytes=len(data))
    desc["timings_s"] = timings
    desc["warnings"] = list(scene.warnings)
    desc["touching"] = [list(p) for p in analysis.touching]
    desc["intersecting"] = [list(p) for p in analysis.intersecting]
    if calibration is not None:
        desc["calibration"] = calibration
    if budget is not None:
        desc["budget"] = budget
    if args.json:
        print(json.dumps(desc, indent=1, sort_keys=True))
    elif not args.quiet:
        if calibration is not None:
            from .verify.calibrate import format_calibration

            print(format_calibration(calibration))
        if budget is not None:
            from .budget import format_budget

            print(format_budget(budget))
        print(format_container(desc, timings=timings))
        if analysis.touching or analysis.intersecting:
            print(f"  note: {len(analysis.touching)} touching and {len(analysis.intersecting)} intersecting part "
                  f"pairs (depth levels capped at {settings.depth_ceiling}; see lopcook analyse)")
    return EXIT_OK


def _calibration_record(cal: dict) -> dict:
    """What the container records of a calibration (manifest options are free-form JSON): target,
    the chosen k_f (scale sigma, eps, per-attribute k_f) and the curve (memory vs PSNR over k_f)."""
    keep = ("sigma", "log2_sigma", "eps", "edge_eps", "kf", "kf_normal", "psnr_min", "psnr_mean", "psnr_min_per_level",
            "psnr_mean_per_level", "cap_percent")
    return {"target_psnr": cal["target_psnr"], "statistic": cal["statistic"], "reached": cal["reached"],
            "kf": cal["kf_normal"], "kf_per_attribute": cal["kf"], "kf_scale": cal["sigma"], "eps": cal["eps"],
            "edge_eps": cal["edge_eps"],
            "base_eps": cal["base_eps"], "levels": cal["levels"], "views": cal["views"],
            "resolution": cal["resolution"], "curve": [{k: p[k] for k in keep} for p in cal["curve"]],
            "confirmation": None if not cal.get("confirmation") else {
                "views": cal["confirmation"]["views"], "resolution": cal["confirmation"]["resolution"],
                "passed": cal["confirmation"]["passed"],
                "probes": [{k: p[k] for k in keep} for p in cal["confirmation"]["probes"]]}}


def cmd_calibrate(args) -> int:
    from .errors import EXIT_VERIFY_FAILED
    from .ingest import load
    from .verify.calibrate import format_calibration

    settings = _analyse_settings(args)
    viewing = _viewing(args)
    ingest_settings = _ingest_settings(args)
    scene = load(args.source, ingest_settings)
    cal = _run_calibration(args, scene, settings, viewing, ingest_settings)
    if args.json:
        print(json.dumps(cal, indent=1, sort_keys=True))
    elif not args.quiet or not cal["reached"]:
        print(format_calibration(cal))
    return EXIT_OK if cal["reached"] else EXIT_VERIFY_FAILED


def cmd_decode(args) -> int:
    from .emit.container import read
    from .emit.gltf_writer import write_gltf
    from .emit.reader import decode_positions, lod_attributes

    c = read(args.container)
    if not 1 <= args.level <= 24:
        raise LopcookError("usage", None, f"--level {args.level} is outside [1, 24]")
    parts = c.manifest["parts"]
    deepest = max(len(p["lods"]) for p in parts)
    if not 0 <= args.lod < deepest:
        raise LopcookError("usage", args.container, f"--lod {args.lod}: no part has LOD {args.lod} (the container has "
                           f"LODs 0..{deepest - 1})")
    meshes, coarsest = [], []
    for i, part in enumerate(parts):
        # a part whose chain stopped early (too few triangles, or a LOD no distance selects) is
        # drawn with its coarsest LOD at every farther distance: decode that, as a renderer would
        lod = min(args.lod, len(part["lods"]) - 1)
        if lod != args.lod:
            coarsest.append(part["name"])
        _, _, pos = decode_positions(c, i, lod, args.level)
        a = lod_attributes(c, i, lod)
        meshes.append({"name": part["name"], "positions": pos, "indices": a["indices"], "normals": a["normals"],
                       "uvs": a["uvs"], "colors": a["colors"]})
    if coarsest and not args.quiet and not args.json:
        print(f"lopcook: note: {len(coarsest)} of {len(parts)} parts have no LOD {args.lod}; their coarsest LOD is "
              f"used ({', '.join(coarsest[:3])}{', ...' if len(coarsest) > 3 else ''})", file=sys.stderr)
    written = write_gltf(args.output, meshes, generator=f"lopcook {__version__}",
                         extras={"lopcook": {"level": args.level, "lod": args.lod,
                                             "source": c.manifest["source"]["file"]}})
    if args.json:
        print(json.dumps({"written": [str(w) for w in written], "level": args.level, "lod": args.lod,
                          "parts": len(meshes), "parts_at_coarsest_lod": coarsest}, sort_keys=True))
    elif not args.quiet:
        print(f"{args.output}: {len(meshes)} meshes decoded at level {args.level}, LOD {args.lod}")
    return EXIT_OK


def cmd_inspect(args) -> int:
    from .ingest import load
    from .inspect import describe_scene, format_scene

    if _is_container(args.source):
        import os

        from .emit.container import read
        from .emit.summary import describe_container, format_container

        c = read(args.source)
        desc = describe_container(c, file_bytes=os.path.getsize(args.source))
        if args.json:
            print(json.dumps(desc, indent=1, sort_keys=True))
        elif not args.quiet:
            print(format_container(desc))
        return EXIT_OK
    scene = load(args.source, _ingest_settings(args))
    desc = describe_scene(scene)
    if args.json:
        print(json.dumps(desc, indent=1, sort_keys=True))
    elif not args.quiet:
        print(format_scene(desc))
    return EXIT_OK


def _render_check(args, c, levels) -> dict:
    """``verify --source``: evaluate() + the thresholds; JSON-ready (images dropped)."""
    from .ingest import load
    from .settings import IngestSettings
    from .verify.render import evaluate

    if args.min_psnr is None or not args.min_psnr == args.min_psnr:
        raise LopcookError("usage", None, "--min-psnr must be a number of dB")
    if args.max_depth_errors is not None and args.max_depth_errors < 0:
        raise LopcookError("usage", None, f"--max-depth-errors {args.max_depth_errors}: expected >= 0 pixels")
    views = _views(args.views, "--views")
    resolution = _resolution(args.resolution, "--resolution")
    crease = args.crease_angle
    if crease is None:
        crease = ((c.manifest.get("options") or {}).get("ingest") or {}).get("crease_angle_deg")
    if crease is not None and not 0.0 <= float(crease) <= 180.0:
        raise LopcookError("usage", None, f"--crease-angle {crease} is outside [0, 180] degrees")
    ingest = IngestSettings(crease_angle_deg=float(crease)) if crease is not None else IngestSettings()
    scene = load(args.source, ingest)
    result = evaluate(c, scene, levels=levels, views=views, resolution=resolution)
    failures = []
    for row in result["levels"]:
        cap = row["cap"]
        value = cap[f"psnr_{args.psnr_stat}"]
        if value is not None and value < args.min_psnr:
            failures.append(f"level {row['level']}: CAP PSNR ({args.psnr_stat} over views) {value:.1f} dB < "
                            f"{args.min_psnr:g} dB")
        if args.max_depth_errors is not None and cap["depth_order_errors"] > args.max_depth_errors:
            failures.append(f"level {row['level']}: {cap['depth_order_errors']} CAP depth-order error pixels > "
                            f"{args.max_depth_errors}")
    result["thresholds"] = {"min_psnr": args.min_psnr, "psnr_stat": args.psnr_stat,
                            "max_depth_errors": args.max_depth_errors}
    result["failures"] = failures
    result["ok"] = not failures
    return result


def cmd_verify(args) -> int:
    from .errors import EXIT_VERIFY_FAILED

    if not args.decoders and args.source is None:
        raise LopcookError("usage", args.container, "nothing to verify: give --decoders and/or --source SOURCE",
                           hint="lopcook verify OUT.lop --decoders checks the GLSL/HLSL decoders bit for bit; "
                                "--source SOURCE renders AP and CAP against the float source")
    from .emit.container import read
    from .verify.decoders import format_report, parse_levels, verify_decoders

    levels = parse_levels(args.levels, args.container) if args.levels is not None else None
    languages = tuple(v.strip().lower() for v in args.languages.split(",") if v.strip())
    if not languages or any(v not in ("glsl", "hlsl") for v in languages):
        raise LopcookError("usage", None, f"--languages {args.languages!r}: expected glsl, hlsl or glsl,hlsl")
    if args.source is not None:  # usage errors before any work
        _views(args.views, "--views")
        _resolution(args.resolution, "--resolution")
    c = read(args.container, allow_prefix=True)
    report = {"container": args.container}
    ok = True
    if args.decoders:
        dec_levels = levels if levels is not None else list(range(1, c.available_level + 1))
        report["decoders"] = verify_decoders(c, dec_levels, languages, adapt=not args.no_adapt)
        ok = ok and report["decoders"]["ok"]
    if args.source is not None:
        from .verify.render import DEFAULT_LEVELS

        render = _render_check(args, c, levels if levels is not None else list(DEFAULT_LEVELS))
        report["render"] = render
        ok = ok and render["ok"]
    report["ok"] = bool(ok)
    if args.json:
        print(json.dumps(report, indent=1, sort_keys=True))
    elif not args.quiet or not report["ok"]:
        if "decoders" in report:
            print(format_report(report["decoders"]))
        if "render" in report:
            from .verify.render import format_table

            r = report["render"]
            print(format_table(r))
            verdict = "ok" if r["ok"] else "FAILED: " + "; ".join(r["failures"])
            print(f"  thresholds: CAP PSNR ({args.psnr_stat} over views) >= {args.min_psnr:g} dB"
                  + ("" if args.max_depth_errors is None else f", depth-order errors <= {args.max_depth_errors}")
                  + f": {verdict}")
    return EXIT_OK if report["ok"] else EXIT_VERIFY_FAILED


def cmd_report(args) -> int:
    import os
    import time

    from .emit.container import read
    from .emit.summary import describe_container
    from .ingest import load
    from .report import analysis_warnings, build_report, render_for_report, write_html
    from .settings import IngestSettings
    from .verify.decoders import parse_levels
    from .verify.render import DEFAULT_LEVELS

    out = args.output
    if os.path.isdir(out):
        raise LopcookError("usage", out, "-o is a directory", hint="give a file name, e.g. report.html")
    if not out.lower().endswith((".html", ".htm")):
        raise LopcookError("usage", out, "-o must name an .html file (the JSON is written beside it)")
    parent = os.path.dirname(os.path.abspath(out))
    if not os.path.isdir(parent):
        raise LopcookError("usage", out, f"directory {os.path.dirname(out)!r} does not exist")
    views = _views(args.views, "--views")
    resolution = _resolution(args.resolution, "--resolution")
    levels = parse_levels(args.levels, args.container) if args.levels is not None else list(DEFAULT_LEVELS)
    if not os.path.isfile(args.source):
        raise LopcookError("usage", args.source, "source file not found")
    c = read(args.container, allow_prefix=True)
    crease = args.crease_angle
    if crease is None:
        crease = ((c.manifest.get("options") or {}).get("ingest") or {}).get("crease_angle_deg")
    if crease is not None and not 0.0 <= float(crease) <= 180.0:
        raise LopcookError("usage", None, f"--crease-angle {crease} is outside [0, 180] degrees")
    ingest = IngestSettings(crease_angle_deg=float(crease)) if crease is not None else IngestSettings()
    _progress(args, f"ingest {args.source}")
    t0 = time.perf_counter()
    scene = load(args.source, ingest)
    ingest_s = time.perf_counter() - t0
    _progress(args, f"render levels {levels}, {views} views at {resolution[0]}x{resolution[1]} (float, AP, CAP, "
                    "uniform 16-bit, minimum levels)")
    ev, ev16, level_range = render_for_report(c, scene, levels=levels, views=views, resolution=resolution)
    warnings = cook = None
    if not args.no_analyse:
        from .verify.reproduce import recook

        _progress(args, "re-cook the source (stage timings, warnings, determinism)")
        cook = recook(c, scene, ingest_s=ingest_s)
        warnings = analysis_warnings(scene, cook["analysis"])
    desc = describe_container(c, file_bytes=os.path.getsize(args.container))
    rep = build_report(c, scene, ev, desc, warnings=warnings, uniform16=ev16, cook=cook, level_range=level_range)
    html_path, json_path = write_html(rep, ev.get("images"), out)
    if args.json:
        print(json.dumps(rep, indent=1, sort_keys=True))
    elif not args.quiet:
        from .verify.render import format_table

        print(format_table(ev))
        print(f"  wrote {html_path} and {json_path}")
    return EXIT_OK


def _add_bench_parser(sub) -> None:
    """``lopcook bench``: lopcook against gltfpack, glTF-Transform and Draco (lopcook/bench.py, docs/bench.md)."""
    p = sub.add_parser("bench", help="speed and accuracy against gltfpack, glTF-Transform and Draco, and how the "
                                     "cook's cost grows (needs pip install 'lopcook[bench]'; see docs/bench.md)")
    p.add_argument("assets", nargs="*", metavar="ASSET",
                   help="source files (default: bunny, fandisk, DamagedHelmet and the chess set from "
                        "$LOPCOOK_CORPUS or ../shared/corpus)")
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="folder for CSVs, charts and summary")
    p.add_argument("--levels", default="6-11", metavar="LEVELS", help="camera levels, e.g. 6-11 (default 6-11)")
    p.add_argument("--views", type=int, default=20, metavar="N", help="icosahedron views, 1..20 (default 20)")
    p.add_argument("--resolution", default="1280x720", metavar="WxH", help="render size in pixels (default 1280x720)")
    p.add_argument("--bits", default="10,12,14,16", metavar="N,...",
                   help="position bits of the peers' runs (default 10,12,14,16)")
    p.add_argument("--peers", default="gltfpack,gltf-transform,draco", metavar="LIST",
                   help="peers to run, a subset of gltfpack,gltf-transform,draco (default all; 'none' for none)")
    p.add_argument("--skip-render", action="store_true", help="no PSNR (no renders): bytes, errors, cracks, times")
    p.add_argument("--no-accuracy", action="store_true", help="skip the per-asset accuracy runs (scaling only)")
    p.add_argument("--scaling", action="store_true",
                   help="also time cooks (--lods 1/2,1/4) and gltfpack -si 0.5 -vp 14 on the bunny subdivided 0-3 "
                        "times and the chess set (GLB) for the log-log chart")
    p.add_argument("--scaling-max-triangles", type=int, default=5_000_000, metavar="N",
                   help="largest scaling input in triangles (default 5000000: all; 1200000 skips the 4.4M bunny)")
    p.add_argument("--repeat", type=int, default=1, metavar="N", help="scaling runs per input, best wall time (default 1)")
    p.add_argument("--calibrated", action="store_true",
                   help="also cook with --target-psnr 40 (slow on the chess set)")
    _add_common(p)


def cmd_bench(args) -> int:
    from .bench import DEFAULT_LEVELS, run
    from .benchkit.peers import PEERS
    from .verify.decoders import parse_levels

    args.levels = parse_levels(args.levels) if args.levels else list(DEFAULT_LEVELS)
    args.views = _views(args.views, "--views")
    args.resolution = _resolution(args.resolution, "--resolution")
    try:
        args.bits = [int(b) for b in args.bits.split(",") if b.strip()]
    except ValueError:
        raise LopcookError("usage", None, f"--bits {args.bits!r}: expected integers such as 10,12,14,16") from None
    if not args.bits or any(not 1 <= b <= 16 for b in args.bits):
        raise LopcookError("usage", None, f"--bits {args.bits}: each must be in [1, 16]")
    peers = [v.strip().lower() for v in args.peers.split(",") if v.strip() and v.strip().lower() != "none"]
    if any(v not in PEERS for v in peers):
        raise LopcookError("usage", None, f"--peers {args.peers!r}: expected a subset of {','.join(PEERS)}")
    args.peers = peers
    if args.repeat < 1 or args.scaling_max_triangles < 1:
        raise LopcookError("usage", None, "--repeat and --scaling-max-triangles must be positive")
    args.argv = sys.argv[sys.argv.index("bench") + 1:] if "bench" in sys.argv else []
    summary = run(args)
    if args.json:
        print(json.dumps(summary, indent=1, sort_keys=True, default=str))
    return EXIT_OK


COMMANDS = {"inspect": cmd_inspect, "analyse": cmd_analyse, "cook": cmd_cook, "decode": cmd_decode,
            "verify": cmd_verify, "calibrate": cmd_calibrate, "report": cmd_report,
            "bench": cmd_bench, "batch": cmd_batch}


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return COMMANDS[args.command](args)
    except LopcookError as exc:
        if args.debug:
            raise
        print(f"lopcook: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print("lopcook: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return EXIT_OK
    except Exception as exc:  # a bug, not bad input
        if args.debug:
            raise
        print(f"lopcook: internal error: {type(exc).__name__}: {exc} "
              f"(run with --debug for the traceback and report it)", file=sys.stderr)
        return EXIT_INTERNAL


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
