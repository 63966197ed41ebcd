"""Command-line interface: parse flags, call one stage function, map errors to exit codes.

Exit codes: 0 ok, 1 verification failed, 2 bad input or usage (one line on stderr, no traceback
unless ``--debug``), 3 internal error (a bug: please report it with the ``--debug`` output).
"""

from __future__ import annotations

import argparse
import math
import json
import sys
from pathlib import Path

from .batch.cli import add_batch_parser, cmd_batch
from .errors import EXIT_OK, LopcookError
from .memory import small_pages
from .progress import MODES
from .settings import DEFAULTS as D
from .settings import BudgetScope, LodBackend, PsnrStat, SearchKnobs, SeamMode
from .version import __version__

EXIT_INTERNAL = 3


def _add_crease_angle(p: argparse.ArgumentParser) -> None:
    p.add_argument("--crease-angle", type=float, default=None, metavar="DEG",
                   help="dihedral angle above which computed normals split, degrees in [0, 180] "
                        f"(default {D.ingest.crease_angle_deg:g}; 180 = smooth)")
    p.add_argument("--max-triangles", type=int, default=D.ingest.max_triangles, metavar="N",
                   help="refuse (exit 2) a source placing more triangles than this over all its instances, "
                        f"counted before anything is expanded, in [1, {D.ingest.max_triangles:,}] "
                        f"(default {D.ingest.max_triangles:,})")


def _levels_text(levels) -> str:
    """(6, 7, ..., 12) -> "6-12"; other sets as a comma list."""
    lv = sorted(int(b) for b in levels)
    return f"{lv[0]}-{lv[-1]}" if lv == list(range(lv[0], lv[-1] + 1)) else ",".join(map(str, lv))


def _add_harness(g) -> None:
    """--views and --resolution of the render harness, defaults from DEFAULTS.render."""
    g.add_argument("--views", type=int, default=D.render.views, metavar="N",
                   help=f"icosahedron views, 1..20 (default {D.render.views})")
    g.add_argument("--resolution", default=D.render.resolution_text, metavar="WxH",
                   help=f"render size in pixels (default {D.render.resolution_text})")


def _add_common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--json", action="store_true", help="print the result as JSON on stdout instead of text")


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line (exit 2), like lopcook's own errors:
    ``lopcook cook: error: the following arguments are required: -o (see lopcook cook --help)``.
    Subcommand parsers are made of this class too."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="lopcook",
        description="Cook glTF/OBJ/USD scenes into level-of-precision (LOP) vertex containers.",
    )
    parser.add_argument("--version", action="version", version=f"lopcook {__version__}")
    parser.add_argument("--debug", action="store_true", help="show Python tracebacks on errors")
    parser.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors (and --json output)")
    parser.add_argument("--progress", choices=MODES, default="auto",
                        help="progress on stderr: a bar with counts and ETA on a terminal (auto, the default; "
                             "nothing off a terminal), bar, plain (one line per stage with its time, for CI logs) "
                             "or none")
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
    p.add_argument("--strict", action="store_true",
                   help="treat every warning (unreadable texture, LOD shortfall, ...) as an error: exit 2 and "
                        "write nothing")
    p.add_argument("--lods", default=None, metavar="auto|R1,R2,...",
                   help="also write LODs: auto (the default chain 1/2, 1/4, 1/8, ... until a LOD's error exceeds "
                        "what the farthest view can show, given --nearest, or its target falls under 4 triangles) "
                        "or these fractions of the triangles, e.g. 1/2,1/4,1/8 (default: LOD 0 only)")
    p.add_argument("--lod-backend", default=D.simplify.backend.value, choices=[b.value for b in LodBackend],
                   help="simplifier: pymeshlab quadric collapse (seam-aware), fast-simplification, "
                        "meshoptimizer's attribute-aware collapse, or auto: meshoptimizer, and pymeshlab as well "
                        "on inputs of up to 100,000 triangles, the lower measured error kept (docs/lod.md) "
                        f"(default {D.simplify.backend.value})")
    p.add_argument("--lod-seams", default=D.simplify.seams.value, choices=[m.value for m in SeamMode],
                   help="UV seams in LODs: lock (kept exactly; stops early on densely seamed meshes), simplify "
                        "(collapsed along themselves), ignore, xatlas, or auto: simplify, and where that stops "
                        "short the mesh welded by position (docs/lod.md) "
                        f"(default {D.simplify.seams.value})")
    p.add_argument("--hierarchy", action="store_true",
                   help="also write each part's view-dependent vertex hierarchy (coded connectivity, read by "
                        "lopcook refine; docs/hierarchy.md)")
    copies = p.add_mutually_exclusive_group()
    copies.add_argument("--instances", action="store_true", default=None,
                        help="store each group of copies of one mesh once, on a grid of its own, with one "
                             "transform per placement; copies that share a vertex with another part stay on the "
                             "scene grid (docs/instances.md). Default: wherever the scene has copies, except "
                             "with --hierarchy or --target-bytes (given with those: exit 2)")
    copies.add_argument("--no-instances", dest="instances", action="store_false",
                        help="store every placed copy as a part of its own on the scene grid")
    p.add_argument("--clusters", default=None, metavar="N",
                   help="clustered position buffers of N vertices per cluster, N in [16, 1024]: per-cluster "
                        "anchors store the top bits a cluster's vertices share once (container version 3.0; "
                        f"docs/clusters.md); 0: unclustered (version 2.0) (default {D.emit.clusters}); a buffer "
                        "is clustered only where that makes it smaller (docs/clusters.md, Per-buffer choice)")
    p.add_argument("--cluster-all", action="store_true",
                   help="with clusters: cluster every buffer, even where the unclustered layout is smaller")
    add_analyse_options(p)
    add_attribute_options(p)
    add_viewing_options(p)
    _add_crease_angle(p)
    add_calibration_options(p, cook=True)
    add_attribute_search_options(p)
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
    p.add_argument("container", metavar="CONTAINER.lop", help="a .lop container")
    p.add_argument("--level", type=int, required=True, metavar="B", help="per-buffer level B in [1, 24]")
    p.add_argument("--lod", type=int, default=0, metavar="K", help="LOD to decode (default 0)")
    p.add_argument("-o", "--output", required=True, metavar="OUT.glb", help=".glb, or .gltf (+ .bin)")
    p.add_argument("--source", metavar="SRC", default=None,
                   help="source asset to take materials and textures from (default: the manifest's source file "
                        "beside the container; used only when its sha256 matches)")
    _add_common(p)

    p = sub.add_parser("refine", help="the view-dependent cut of a --hierarchy container for one camera, as glTF 2.0")
    p.add_argument("container", metavar="CONTAINER.lop", help="a .lop container cooked with --hierarchy")
    p.add_argument("--camera", required=True, metavar="X,Y,Z", help="eye position, metres")
    p.add_argument("--target", required=True, metavar="X,Y,Z", help="point looked at, metres")
    p.add_argument("--fov", type=float, default=60.0, metavar="DEG", help="vertical field of view (default 60)")
    p.add_argument("--viewport", default="1920x1080", metavar="WxH", help="pixels (default 1920x1080)")
    p.add_argument("--pixel-error", type=float, default=0.5, metavar="PX",
                   help="tolerated projected error, pixels (default 0.5)")
    p.add_argument("--no-backface", dest="backface", action="store_false",
                   help="also refine back-facing regions (no Hoppe 1997 back-face test): more triangles, but no "
                        "coarse back-facing triangles showing at silhouettes of thin or multi-part assets")
    p.add_argument("-o", "--output", required=True, metavar="OUT.glb", help=".glb, or .gltf (+ .bin)")
    _add_common(p)

    p = sub.add_parser("analyse", help="per-vertex minimum bit levels (attribute error and depth constraints)")
    p.add_argument("source", metavar="SOURCE", help="glTF/GLB, OBJ or USD file")
    add_analyse_options(p)
    _add_crease_angle(p)
    _add_common(p)

    p = sub.add_parser("verify", help="check a .lop container (--decoders: the GPU shaders against the CPU reference; "
                                      "--source: renders against the float source)")
    p.add_argument("container", metavar="CONTAINER.lop", help="a .lop container")
    g = p.add_argument_group("checks (give at least one)")
    g.add_argument("--decoders", action="store_true",
                   help="decode every part/LOD with the GLSL and HLSL shaders of shaders/ (moderngl through EGL; "
                        "HLSL via glslang + spirv-cross), decode its packed attribute record (normals, UVs, colours) "
                        "and walk the adaption kernels through the levels; every integer, float bit and packed word "
                        "must equal the CPU reference")
    g.add_argument("--source", metavar="SOURCE", default=None,
                   help="render the float SOURCE, AP and CAP (positions decoded by the shipped GLSL decoder) from "
                        "icosahedron views at the distance where each level is selected; print a Table-1-like "
                        "table and fail (exit 1) when CAP's PSNR is below --min-psnr")
    p.add_argument("--levels", default=None, metavar="LEVELS",
                   help="per-buffer levels to check: a range or list in [1, 24], e.g. 1-24 or 6,8,12 "
                        f"(default: every level the file holds for --decoders, {_levels_text(D.render.levels)} for --source)")
    r = p.add_argument_group("render check (--source)")
    r.add_argument("--min-psnr", type=float, default=40.0, metavar="DB",
                   help="CAP PSNR (dB) every level must reach (default 40); see --psnr-stat")
    r.add_argument("--psnr-stat", choices=[v.value for v in PsnrStat], default=D.tune.psnr_stat.value,
                   help="PSNR over views compared with --min-psnr: min (every view, default) or mean (PSNR of "
                        "the view-averaged MSE)")
    r.add_argument("--max-depth-errors", type=int, default=None, metavar="PIXELS",
                   help="fail when CAP shows more depth-order error pixels than this at a level (default: not checked)")
    _add_harness(r)
    r.add_argument("--crease-angle", type=float, default=None, metavar="DEG",
                   help="ingest setting for SOURCE (default: the one recorded in the container, else 60)")
    p.add_argument("--languages", default="glsl,hlsl", metavar="glsl,hlsl",
                   help="shader languages to run (default: glsl,hlsl)")
    p.add_argument("--no-adapt", action="store_true",
                   help="with --decoders: skip the compute-shader adaption check (decode only)")
    _add_common(p)

    p = sub.add_parser("report", help="one self-contained HTML report (and report.json) of a container rendered "
                                      "against its float source")
    p.add_argument("container", metavar="CONTAINER.lop", help="a .lop container")
    p.add_argument("--source", metavar="SOURCE", required=True, help="the glTF/GLB, OBJ or USD file it was cooked from")
    p.add_argument("-o", "--output", metavar="REPORT.html", required=True,
                   help="HTML file to write; the JSON goes beside it with the suffix .json")
    p.add_argument("--levels", default=None, metavar="LEVELS",
                   help=f"per-buffer levels in [1, 24], e.g. 6-12 (default {_levels_text(D.render.levels)}, "
                        "those the file holds)")
    p.add_argument("--min-psnr", type=float, default=40.0, metavar="DB",
                   help="the verdict's threshold: PASS when CAP's PSNR reaches DB at every rendered level and "
                        "view, else FAIL and exit 1 (default 40)")
    _add_harness(p)
    _add_crease_angle(p)
    p.add_argument("--no-analyse", action="store_true",
                   help="do not re-cook the source (no stage timings, no determinism check, no warnings from the "
                        "analysis: touching/intersecting parts, degenerate triangles)")
    _add_common(p)
    _add_bench_parser(sub)
    add_batch_parser(sub)
    # the global flags also work after the command (lopcook cook x.glb -o x.lop -q)
    for command in sub.choices.values():
        command.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                             help="show Python tracebacks on errors")
        command.add_argument("-q", "--quiet", action="store_true", default=argparse.SUPPRESS,
                             help="print nothing but errors (and --json output)")
        command.add_argument("--progress", choices=MODES, default=argparse.SUPPRESS,
                             help="progress on stderr: auto, bar, plain or none (see lopcook --help)")
    return parser


def add_viewing_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("viewing conditions (recorded in the container)")
    v = D.viewing
    g.add_argument("--viewport", default=f"{v.viewport[0]}x{v.viewport[1]}", metavar="WxH",
                   help=f"viewport in pixels (default {v.viewport[0]}x{v.viewport[1]})")
    g.add_argument("--fov", type=float, default=v.fov_y_deg, metavar="DEG",
                   help=f"vertical field of view, degrees in (0, 180) (default {v.fov_y_deg:g})")
    g.add_argument("--nearest", default=None, metavar="METRES",
                   help="closest camera distance to the scene, metres > 0 (e.g. 0.5 or 0.5m; default unknown)")
    g.add_argument("--pixel-error", type=float, default=v.pixel_error, metavar="PX",
                   help=f"allowed screen-space error, pixels > 0 (default {v.pixel_error:g}, the paper's half pixel)")


def add_attribute_search_options(p: argparse.ArgumentParser) -> None:
    """cook's --vertex-bits and --no-attribute-search (``lopcook.tune.attributes``)."""
    g = p.add_argument_group("attribute bits search (renders everything quantized; see lopcook.tune.attributes)")
    g.add_argument("--vertex-bits", type=float, default=None, metavar="N",
                   help="choose every part's normal, UV and colour bits and the positions' k_f scale for the least "
                        "image error with at most N bits per vertex at level 11 (positions' CAP bits included; "
                        "Purnomo et al. 2005's greedy search)")
    g.add_argument("--no-attribute-search", dest="attribute_search", action="store_false",
                   help="with --target-psnr: search k_f only, keep the default attribute bits")


def add_calibration_options(p: argparse.ArgumentParser, cook: bool) -> None:
    cal = D.tune.calibration
    g = p.add_argument_group("k_f calibration (renders CAP against the source; see lopcook.tune.calibrate)")
    if cook:
        g.add_argument("--target-psnr", type=float, default=None, metavar="DB",
                       help="first search the k_f scale with the least memory whose CAP renders reach DB dB at "
                            "every level (see --psnr-stat), then cook with it; the curve is recorded in the "
                            "container options")
    else:
        g.add_argument("--target-psnr", type=float, required=True, metavar="DB",
                       help="CAP PSNR (dB) to reach at every level (see --psnr-stat)")
    prefix = "calibration-" if cook else ""
    gate = D.render
    g.add_argument(f"--{prefix}views", dest="calibration_views", type=int, default=None, metavar="N",
                   help=f"search on a reduced harness of N icosahedron views per probe, 1..20, confirmed on "
                        f"the gate's (default: search on the gate's own {gate.views} views at "
                        f"{gate.resolution_text}, levels 6-11, rendering the levels where the default cook has "
                        f"the least margin first; a reduced harness given by any of these three flags has "
                        f"{cal.views} views, {cal.resolution_text}, levels {_levels_text(cal.levels)} unless set)")
    g.add_argument(f"--{prefix}resolution", dest="calibration_resolution", default=None,
                   metavar="WxH", help="render size per probe of the reduced harness, pixels")
    g.add_argument(f"--{prefix}levels", dest="calibration_levels", default=None,
                   metavar="LEVELS", help="per-buffer levels every probe of the reduced harness must pass")
    g.add_argument("--psnr-stat", choices=[v.value for v in PsnrStat], default=D.tune.psnr_stat.value,
                   help="PSNR over views that must reach the target: min (every view, default) or mean "
                        "(PSNR of the view-averaged MSE, as Purnomo et al. average errors)")
    g.add_argument("--search", choices=[v.value for v in SearchKnobs], default=None,
                   help="knobs to search: the k_f scale only (kf), or also the edge constraint's --edge-eps "
                        "(kf+edge, the default when --edges is on)")
    g.add_argument("--no-calibration-confirm", dest="calibration_confirm", action="store_false",
                   help=f"do not confirm the choice with lopcook verify's {D.render.views} views at "
                        f"{D.render.resolution_text} (by default the k_f scale is raised until it passes there too)")


def add_budget_options(p: argparse.ArgumentParser) -> None:
    t = D.tune
    g = p.add_argument_group("byte budget (Purnomo et al. 2005, section 5; see docs/budget.md)")
    g.add_argument("--target-bytes", default=None, metavar="N|P/Q",
                   help="cook the LOD chain (--lods, default 1/2, 1/4, ...), render every (LOD, level) that fits "
                        "in N bytes and write only the one with the least image error; P/Q = that fraction of the "
                        "float size (e.g. 1/6). Fails (exit 2) when nothing fits")
    g.add_argument("--budget-scope", choices=[v.value for v in BudgetScope], default=t.budget_scope.value,
                   help="what the bytes count: positions (GPU position buffer; float size 12 B/vertex, default), "
                        "vertices (+ stored normals/UVs/colours), all (+ index buffer)")
    g.add_argument("--budget-views", type=int, default=t.budget.views, metavar="N",
                   help=f"icosahedron views per candidate, 1..20 (default {t.budget.views})")
    g.add_argument("--budget-resolution", default=t.budget.resolution_text, metavar="WxH",
                   help=f"render size per candidate, pixels (default {t.budget.resolution_text})")
    g.add_argument("--budget-levels", type=int, default=t.budget_levels, metavar="N",
                   help=f"levels rendered per LOD, >= 1: the largest that fits and N-1 below (default {t.budget_levels})")


def _resolution(text: str, flag: str) -> tuple[int, int]:
    from .settings import parse_resolution

    return parse_resolution(text, flag)


def _views(n: int, flag: str) -> int:
    if not 1 <= int(n) <= 20:
        raise LopcookError("usage", None, f"{flag} {n}: expected 1..20 icosahedron views")
    return int(n)


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
        flag = {"nearest": "--nearest", "pixel": "--pixel-error", "fov": "--fov", "viewport": "--viewport"}[
            str(exc).split(" ", 1)[0]]
        raise LopcookError("usage", None, f"{flag}: {exc}") from None


def add_attribute_options(p: argparse.ArgumentParser) -> None:
    """``--<codec>-bits`` for every attribute codec (``--normal-bits``, ``--uv-bits``, ``--color-bits``, ...:
    lopcook.lop.codecs.CODECS, lopcook.settings.AttributeSettings)."""
    from .lop.codecs import CODECS

    g = p.add_argument_group("vertex attributes (docs/format.md section 7.2; Purnomo et al. 2005)")
    for c in CODECS:
        g.add_argument(f"--{c.singular}-bits", type=int, default=None, metavar="B",
                       help=f"{c.description}, {c.bits[0]}..{c.bits[1]} (default: the bound-based choice per part: "
                            "the fewest bits whose error keeps the shading change within --eps)")


def _attribute_settings(args):
    """``--<codec>-bits`` -> AttributeSettings; out of range: usage error naming the flag."""
    from .lop.codecs import CODECS
    from .settings import AttributeSettings

    try:
        return AttributeSettings(bits=tuple(getattr(args, f"{c.singular}_bits", None) for c in CODECS))
    except ValueError as exc:
        raise LopcookError("usage", None, f"--{str(exc).split(' ', 1)[0]}-bits: {exc}") from None


def add_analyse_options(p: argparse.ArgumentParser) -> None:
    d = D.analyse

    g = p.add_argument_group("analysis (Meyer et al. 2011, section 5)")
    g.add_argument("--eps", type=float, default=d.eps, metavar="COLOUR",
                   help=f"largest shading error a vertex may cause, colour units in (0, 1] (default 1/255 = {d.eps:.6g})")
    g.add_argument("--ks", type=float, default=d.ks, help=f"Phong specular coefficient, >= 0 (default {d.ks:g})")
    g.add_argument("--shininess", type=float, default=d.shininess,
                   help=f"Phong exponent n, >= 0 (default {d.shininess:g}); normals use k_f = ks * n")
    g.add_argument("--kf", type=float, default=None,
                   help="override k_f for every attribute, colour per attribute unit >= 0 (default: from the shading)")
    g.add_argument("--texture-kf", default=d.texture_kf.value, metavar="image|off|VALUE",
                   help="k_f of UVs: the base-colour texture's maximum slope (image), off, or colour per UV unit "
                        f">= 0 (default {d.texture_kf.value})")
    g.add_argument("--depth", default=d.depth_text, metavar="auto|off|fixed:N",
                   help="depth constraints: from distances to other parts (auto), none, or the paper's mode: "
                        f"vertices closer than --depth-threshold get level N in [1, 24] (default {d.depth_text})")
    g.add_argument("--depth-threshold", type=float, default=d.depth_threshold, metavar="METRES",
                   help="distance under which a vertex is depth-critical in fixed:N mode, metres > 0 "
                        f"(default {d.depth_threshold:g}: must be given with fixed:N)")
    g.add_argument("--depth-ceiling", type=int, default=d.depth_ceiling, metavar="N",
                   help=f"highest level a depth constraint may impose, in [1, 24]; touching parts are capped there "
                        f"(default {d.depth_ceiling})")
    g.add_argument("--edges", action=argparse.BooleanOptionalAction, default=d.edges,
                   help="discontinuity constraint: raise vertices on hard edges, sub-pixel folds, open boundaries "
                        "and colour seams, which E_v cannot see (default on; docs/analyse.md)")
    g.add_argument("--edge-eps", type=float, default=d.edge_eps, metavar="COLOUR",
                   help=f"colour change an edge may cause in a pixel, colour units in (0, 1] (default {d.edge_eps:g}: "
                        "a full-range jump costs 2 bits above the level)")
    g.add_argument("--edge-level", type=int, default=d.edge_level, metavar="N",
                   help=f"highest per-buffer level the edge bound is kept at, in [1, 24] (default {d.edge_level})")
    g.add_argument("--edge-angle", type=float, default=d.edge_angle_deg, metavar="DEGREES",
                   help=f"normal spread within one pixel that makes a fold, degrees in (0, 180] (default {d.edge_angle_deg:g})")
    g.add_argument("--position-margin", type=float, default=d.position_margin, metavar="M",
                   help="the positions' E_v constraint holds with eps x M: k_f * E_v * dx(m_v) <= eps * M, M in "
                        f"[1/4096, 4096]; 1 is the paper's worst-case bound (default {d.position_margin:g}; "
                        "docs/analyse.md, Position margin, has measured margins)")


def _ingest_settings(args):
    from .settings import IngestSettings

    kw = {}
    if getattr(args, "crease_angle", None) is not None:
        if not 0.0 <= args.crease_angle <= 180.0:
            raise LopcookError("usage", None, f"--crease-angle {args.crease_angle} is outside [0, 180] degrees")
        kw["crease_angle_deg"] = args.crease_angle
    if getattr(args, "max_triangles", None) is not None:
        kw["max_triangles"] = args.max_triangles
    try:
        return IngestSettings(**kw)
    except ValueError as exc:
        raise LopcookError("usage", None, _flag_message(str(exc))) from None


def _analyse_settings(args):
    from .settings import AnalyseSettings, DepthMode

    depth, level = args.depth, None
    if depth.startswith("fixed:"):
        try:
            level = int(depth.split(":", 1)[1])
        except ValueError:
            level = -1
        if not 1 <= level <= 24:
            raise LopcookError("usage", None, f"--depth {depth}: N must be an integer level in [1, 24]")
        if not args.depth_threshold > 0:
            raise LopcookError("usage", None, f"--depth {depth} needs --depth-threshold METRES > 0")
        depth = DepthMode.FIXED
    elif depth not in ("auto", "off"):
        raise LopcookError("usage", None, f"--depth {depth!r}: expected auto, off or fixed:N")
    if not 0 < args.eps <= 1:
        raise LopcookError("usage", None, f"--eps {args.eps}: expected colour units in (0, 1], e.g. 0.0039 (1/255)")
    tk = args.texture_kf
    if tk not in ("image", "off"):
        try:
            tk = float(tk)
        except ValueError:
            raise LopcookError("usage", None, f"--texture-kf {tk!r}: expected image, off or a number") from None
    try:
        return AnalyseSettings(eps=args.eps, ks=args.ks, shininess=args.shininess, kf=args.kf, texture_kf=tk,
                               depth=depth, depth_level=level, depth_threshold=args.depth_threshold,
                               depth_ceiling=args.depth_ceiling, edges=args.edges, edge_eps=args.edge_eps,
                               edge_level=args.edge_level, edge_angle_deg=args.edge_angle,
                               position_margin=args.position_margin)
    except ValueError as exc:
        raise LopcookError("usage", None, _flag_message(str(exc))) from None


#: AnalyseSettings fields whose flag is not the field name with dashes
_FLAGS = {"edge_angle_deg": "--edge-angle", "depth_level": "--depth fixed:N"}


def _flag_message(text: str) -> str:
    """A settings error in the CLI's terms: ``texture_kf must ...`` -> ``--texture-kf must ...``."""
    field = text.split(" ", 1)[0]
    if field.isidentifier() and field.islower() and " must " in text:
        return _FLAGS.get(field, "--" + field.replace("_", "-")) + text[len(field):]
    return text


def _tune_settings(args):
    """``cook``/``calibrate`` flags -> TuneSettings (usage errors before any work)."""
    from .api import budget_target
    from .settings import RenderSettings, TuneSettings
    from .verify.decoders import parse_levels

    prefix = "--calibration-" if args.command == "cook" else "--"
    if args.target_psnr is not None and not args.target_psnr > 0:
        raise LopcookError("usage", None, f"--target-psnr {args.target_psnr}: expected a positive number of dB")
    given = [getattr(args, k) for k in ("calibration_views", "calibration_resolution", "calibration_levels")]
    cal = D.tune.calibration
    views, res, lv = (cal.views if given[0] is None else given[0],
                      cal.resolution_text if given[1] is None else given[1],
                      _levels_text(cal.levels) if given[2] is None else given[2])
    calibration = RenderSettings(views=_views(views, f"{prefix}views"),
                                 resolution=_resolution(res, f"{prefix}resolution"), levels=tuple(parse_levels(lv)))
    direct = all(v is None for v in given)  # no reduced harness asked for: search on the gate's
    kw = {}
    if getattr(args, "target_bytes", None) is not None:
        budget_target(args.target_bytes)
        if args.budget_levels < 1:
            raise LopcookError("usage", None, f"--budget-levels {args.budget_levels}: expected 1 or more")
        kw = dict(target_bytes=args.target_bytes, budget_scope=args.budget_scope, budget_levels=args.budget_levels,
                  budget=RenderSettings(views=_views(args.budget_views, "--budget-views"),
                                        resolution=_resolution(args.budget_resolution, "--budget-resolution")))
    vb = getattr(args, "vertex_bits", None)
    if vb is not None:
        if not (math.isfinite(vb) and vb > 0):
            raise LopcookError("usage", None, f"--vertex-bits {vb:g}: expected a positive number of bits per vertex")
        if args.target_psnr is not None or kw:
            raise LopcookError("usage", None, "--vertex-bits is a goal of its own: give it without --target-psnr "
                               "and --target-bytes")
        kw["vertex_bits"] = float(vb)
    if hasattr(args, "attribute_search"):
        kw["attribute_search"] = bool(args.attribute_search)
    try:
        return TuneSettings(target_psnr=args.target_psnr, psnr_stat=args.psnr_stat, search=args.search,
                            calibration=calibration, confirm=RenderSettings() if args.calibration_confirm else None,
                            direct=direct, **kw)
    except ValueError as exc:
        raise LopcookError("usage", None, str(exc)) from None


def settings_from_args(args):
    """The argparse namespace of ``cook``, ``calibrate`` or ``analyse`` -> one frozen Settings."""
    from dataclasses import replace

    from .settings import DEFAULTS, Settings, SimplifySettings, parse_lods

    simplify = DEFAULTS.simplify
    if getattr(args, "lods", None) is not None:
        simplify = SimplifySettings(lods=parse_lods(args.lods), backend=args.lod_backend,
                                    seams=getattr(args, "lod_seams", DEFAULTS.simplify.seams.value))
    if getattr(args, "hierarchy", False):
        simplify = replace(simplify, hierarchy=True)
    if getattr(args, "instances", None) is not None:
        simplify = replace(simplify, instances=bool(args.instances))
    return Settings(ingest=_ingest_settings(args), simplify=simplify, analyse=_analyse_settings(args),
                    viewing=_viewing(args) if hasattr(args, "viewport") else DEFAULTS.viewing,
                    tune=_tune_settings(args) if hasattr(args, "target_psnr") else DEFAULTS.tune,
                    attributes=_attribute_settings(args), emit=_emit_settings(args))


def _emit_settings(args):
    """``--clusters N`` -> EmitSettings (absent: the default, ``DEFAULT_CLUSTER_SIZE``; 0: unclustered);
    not 0 or an integer in [16, 1024]: usage error (exit 2)."""
    from .settings import CLUSTER_SIZE_RANGE, EmitSettings

    text = getattr(args, "clusters", None)
    every = bool(getattr(args, "cluster_all", False))
    if text is None:
        return EmitSettings(cluster_all=every)
    lo, hi = CLUSTER_SIZE_RANGE
    try:
        n = int(str(text).strip())
    except ValueError:
        n = None
    if n == 0:
        if every:
            raise LopcookError("usage", None, "--cluster-all does not combine with --clusters 0",
                               hint="drop one of them")
        return EmitSettings(clusters=None)
    if n is None or not lo <= n <= hi:
        raise LopcookError("usage", None, f"--clusters {text!r}: expected an integer number of vertices per "
                           f"cluster in [{lo}, {hi}], or 0 for unclustered buffers",
                           hint=f"e.g. --clusters {D.emit.clusters} (the default), or --clusters 0")
    return EmitSettings(clusters=n, cluster_all=every)


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


def _progress(args):
    """The run's Progress (``--progress``; lopcook.progress): a bar on a terminal unless --quiet or
    --json, nothing off a terminal, plain lines for CI logs."""
    if getattr(args, "_progress", None) is None:
        from .progress import make

        args._progress = make(getattr(args, "progress", "auto"), quiet=args.quiet, json=getattr(args, "json", False))
    return args._progress


def _is_container(path: str) -> bool:
    """Whether ``path`` names a container: a ``.lop`` name, or a regular file that starts with the
    container's magic (a FIFO or device is not opened here: reading it could block; the loaders
    reject it with their own message)."""
    from .ingest.build import regular_file_problem

    if path.lower().endswith(".lop"):
        return True
    if regular_file_problem(path) is not None:
        return False
    try:
        with open(path, "rb") as fh:
            return fh.read(4) == b"LOPC"
    except OSError:
        return False


def cmd_cook(args) -> int:
    import os
    import time

    from . import api

    settings = settings_from_args(args)
    _check_cook_outputs(args, (args.source,))
    t0 = time.perf_counter()
    with _progress(args).stage(f"ingest {os.path.basename(args.source)}"):
        scene = api.load(args.source, settings)
    ingest_s = time.perf_counter() - t0
    _check_cook_outputs(args, tuple(scene.dependencies) + (args.source,))
    depfile = _depfile_text(args, scene)
    _warn(args, [f"{args.source}: {w}" for w in scene.warnings])
    container = api.cook(scene, settings, progress=_progress(args))
    from .simplify import chain_warnings

    _warn(args, chain_warnings(container.result.lod_reports))
    t0 = time.perf_counter()
    container.write(args.output)
    if depfile is not None:
        from .atomic import write_atomic

        write_atomic(args.depfile, depfile.encode("utf-8"))
    write_s = time.perf_counter() - t0
    container.path = args.output
    desc = _cook_summary(container, scene, ingest_s, write_s)
    _print_cook(args, desc, container.result)
    return EXIT_OK


def _check_cook_outputs(args, inputs: tuple) -> None:
    """``-o`` and ``--depfile`` are writable files, distinct, not an input or a dependency of the
    source, and named for what is written (lopcook.outputs); a container not named ``.lop`` is a
    warning."""
    from .outputs import OTHER_OUTPUTS, SOURCE_EXTENSIONS, check_distinct, check_output

    check_output(args.output, "-o", extensions=(".lop",), what="a .lop container", inputs=inputs,
                 forbidden=SOURCE_EXTENSIONS + OTHER_OUTPUTS, required=False)
    if args.depfile:
        check_output(args.depfile, "--depfile", extensions=(".d",), what="a Make depfile", inputs=inputs,
                     forbidden=SOURCE_EXTENSIONS + (".lop",), required=False)
    check_distinct(("-o", args.output), ("--depfile", args.depfile))
    if len(inputs) == 1 and not args.output.lower().endswith(".lop"):
        _warn(args, [f"{args.output}: a .lop container is written to a file not named .lop"])


def _depfile_text(args, scene) -> str | None:
    """The depfile's text, made before anything is written: a dependency path Make cannot hold (a
    newline) is a usage error that leaves every output untouched. Phony rules: a listed file that
    does not exist yet (a missing texture) reruns the cook instead of stopping make."""
    if not args.depfile:
        return None
    from .depfile import format_depfile

    try:
        return format_depfile(args.output, scene.dependencies or (args.source,), phony=True)
    except ValueError as exc:
        raise LopcookError("usage", args.source, f"--depfile: {exc}",
                           hint="rename the file, or cook without --depfile") from None


def _warn(args, lines: list[str]) -> None:
    """Warnings on stderr (``lopcook: warning: ...``) unless --quiet; with --strict the first
    warning is an error (exit 2) before anything is written."""
    if not lines:
        return
    if getattr(args, "strict", False):
        raise LopcookError("usage", None, f"--strict: {lines[0]}" + (f" (and {len(lines) - 1} more warnings)"
                                                                      if len(lines) > 1 else ""))
    if not args.quiet:
        for line in lines:
            print(f"lopcook: warning: {line}", file=sys.stderr)
        sys.stderr.flush()


def _cook_summary(container, scene, ingest_s: float, write_s: float) -> dict:
    """``cook --json``: the container's description, stage timings, warnings, touching and
    intersecting part pairs, and the calibration and budget records when those ran."""
    from .lop.summary import describe_container

    result = container.result
    an = result.analysis
    timings = {"ingest": ingest_s}
    for k in ("calibrate", "attribute_search"):
        if k in result.timings_s:
            timings[k] = result.timings_s[k]
    timings.update({f"analyse.{k}": v for k, v in an.timings.items()})
    timings.update({k: v for k, v in result.timings_s.items() if k not in ("calibrate", "attribute_search")})
    timings["write"] = write_s
    desc = describe_container(container, file_bytes=len(container.data))
    from .simplify import chain_warnings

    desc.update(timings_s=timings, warnings=list(scene.warnings), touching=[list(p) for p in an.touching],
                intersecting=[list(p) for p in an.intersecting], lod_warnings=chain_warnings(result.lod_reports),
                lod_reports=result.lod_reports)
    if result.calibration is not None:
        desc["calibration"] = result.calibration
    if result.budget is not None:
        desc["budget"] = result.budget
    if result.attribute_search is not None:
        desc["attribute_search"] = result.attribute_search
    return desc


def _print_cook(args, desc: dict, result) -> None:
    from .lop.summary import format_container

    if args.json:
        print(json.dumps(desc, indent=1, sort_keys=True))
        return
    if args.quiet:
        return
    if result.calibration is not None:
        from .tune.calibrate import format_calibration

        print(format_calibration(result.calibration))
    if result.budget is not None:
        from .tune.budget import format_budget

        print(format_budget(result.budget))
    if result.attribute_search is not None:
        from .tune.attributes import format_search

        print(format_search(result.attribute_search))
    print(format_container(dict(desc, lod_warnings=[]), timings=desc["timings_s"]))  # warnings went to stderr
    an = result.analysis
    if an.touching or an.intersecting:
        print(f"  note: {len(an.touching)} touching and {len(an.intersecting)} intersecting part "
              f"pairs (depth levels capped at {an.settings.depth_ceiling}; see lopcook analyse)")


def cmd_calibrate(args) -> int:
    from .api import calibration, load
    from .errors import EXIT_VERIFY_FAILED
    from .tune.calibrate import format_calibration

    settings = settings_from_args(args)
    scene = load(args.source, settings)
    cal = calibration(scene, settings, _progress(args))
    if args.json:
        print(json.dumps(cal, indent=1, sort_keys=True))
    elif not args.quiet or not cal["reached"]:
        print(format_calibration(cal))
        if cal["reached"]:
            print(f"  apply it: lopcook cook {args.source} -o OUT.lop --eps {cal['eps']:.6g} "
                  f"--edge-eps {cal['edge_eps']:.6g} (or cook --target-psnr {cal['target_psnr']:g} to search again)")
    return EXIT_OK if cal["reached"] else EXIT_VERIFY_FAILED


def _check_gltf_output(args) -> None:
    """``decode``/``refine -o``: a .glb, or a .gltf and its .bin, never the container read."""
    from .outputs import check_output

    check_output(args.output, "-o", extensions=(".glb", ".gltf"), what="a glTF 2.0 file", inputs=(args.container,))
    if args.output.lower().endswith(".gltf"):
        check_output(str(Path(args.output).with_suffix(".bin")), "-o's .bin", extensions=(".bin",),
                     what="the glTF buffer", inputs=(args.container,))


def cmd_decode(args) -> int:
    from .lop.container import read
    from .emit.gltf_writer import write_gltf
    from .lop.codecs import CODECS
    from .lop.reader import decode_positions, lod_attributes, world_attributes

    if not 1 <= args.level <= 24:
        raise LopcookError("usage", None, f"--level {args.level} is outside [1, 24]")
    _check_gltf_output(args)
    c = read(args.container)
    from .emit.preview import preview, source_candidate
    from .outputs import check_not_input

    source_in = (source_candidate(args.container, c.manifest, args.source),)  # materials are read from it
    check_not_input(args.output, "-o", source_in)
    if args.output.lower().endswith(".gltf"):
        check_not_input(str(Path(args.output).with_suffix(".bin")), "-o's .bin", source_in)
    parts = c.manifest["parts"]
    deepest = max(len(p["lods"]) for p in parts)
    if not 0 <= args.lod < deepest:
        raise LopcookError("usage", args.container, f"--lod {args.lod}: no part has LOD {args.lod} (the container has "
                           f"LODs 0..{deepest - 1})")
    meshes, coarsest, lods = [], [], []
    for i, part in enumerate(parts):
        # a part whose chain stopped early (too few triangles, or a LOD no distance selects) is
        # drawn with its coarsest LOD at every farther distance: decode that, as a renderer would
        lod = min(args.lod, len(part["lods"]) - 1)
        lods.append(lod)
        if lod != args.lod:
            coarsest.append(part["name"])
        _, _, pos = decode_positions(c, i, lod, args.level)
        a = lod_attributes(c, i, lod, unit_directions=True)
        meshes.append({"name": part["name"], "positions": pos, "indices": a["indices"],
                       **world_attributes(c, i, {x.name: a[x.name] for x in CODECS})})
    if coarsest and not args.quiet and not args.json:
        print(f"lopcook: note: {len(coarsest)} of {len(parts)} parts have no LOD {args.lod}; their coarsest LOD is "
              f"used ({', '.join(coarsest[:3])}{', ...' if len(coarsest) > 3 else ''})", file=sys.stderr)
    pv = preview(c, args.container, meshes, lods, args.source)
    if not args.quiet:
        for w in pv["warnings"]:
            print(f"lopcook: warning: {w}", file=sys.stderr)
    written = write_gltf(args.output, pv["meshes"], generator=f"lopcook {__version__}", materials=pv["materials"],
                         nodes=pv["nodes"], extras={"lopcook": {"level": args.level, "lod": args.lod,
                                                               "source": c.manifest["source"]["file"]}})
    if args.json:
        print(json.dumps({"written": [str(w) for w in written], "level": args.level, "lod": args.lod,
                          "parts": len(meshes), "parts_at_coarsest_lod": coarsest,
                          "materials": len((pv["materials"] or {}).get("materials", [])),
                          "instances": pv["instances"], "max_instancing_offset_m": pv["max_instancing_offset_m"],
                          "warnings": pv["warnings"]}, sort_keys=True))
    elif not args.quiet:
        print(f"{args.output}: {len(meshes)} meshes decoded at level {args.level}, LOD {args.lod}")
    return EXIT_OK


def _xyz(text: str, flag: str):
    import math

    try:
        v = [float(x) for x in text.split(",")]
    except ValueError:
        v = []
    if len(v) != 3 or not all(math.isfinite(x) for x in v):
        raise LopcookError("usage", None, f"{flag} {text!r}: expected three finite numbers X,Y,Z")
    return v


def cmd_refine(args) -> int:
    import math

    from .lop.container import read
    from .emit.gltf_writer import write_gltf
    from .hierarchy.container import refine

    camera, target = _xyz(args.camera, "--camera"), _xyz(args.target, "--target")
    viewport = _resolution(args.viewport, "--viewport")
    for flag, v, ok in (("--fov", args.fov, 0 < args.fov < 180), ("--pixel-error", args.pixel_error, args.pixel_error > 0)):
        if not (math.isfinite(v) and ok):
            raise LopcookError("usage", None, f"{flag} {v}: out of range (fov in (0, 180) degrees, pixel error > 0)")
    _check_gltf_output(args)
    c = read(args.container)
    meshes = refine(c, camera, target, fov=args.fov, viewport=viewport, pixel_error=args.pixel_error,
                    backface=args.backface)
    stats = [dict(m.pop("stats"), part=m["name"]) for m in meshes]
    written = write_gltf(args.output, meshes, generator=f"lopcook {__version__}",
                         extras={"lopcook": {"refine": {"camera": camera, "target": target, "fov": args.fov,
                                                        "viewport": list(viewport), "pixel_error": args.pixel_error,
                                                        "backface": args.backface},
                                             "source": c.manifest["source"]["file"]}})
    tri, full = sum(s["triangles"] for s in stats), sum(s["lod0_triangles"] for s in stats)
    if args.json:
        print(json.dumps({"written": [str(w) for w in written], "triangles": tri, "lod0_triangles": full,
                          "parts": stats}, sort_keys=True))
    elif not args.quiet:
        print(f"{args.output}: {len(meshes)} meshes, {tri:,} of {full:,} LOD 0 triangles "
              f"(levels {min(s['level'] for s in stats)}-{max(s['level'] for s in stats)})")
    return EXIT_OK


def cmd_inspect(args) -> int:
    from .ingest import load
    from .ingest.summary import describe_scene, format_scene

    if _is_container(args.source):
        import os

        from .lop.container import read
        from .lop.summary import describe_container, format_container

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
    from .verify.evaluate import evaluate

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
    from .lop.container import read
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
        from .verify.evaluate import levels_in_file

        render = _render_check(args, c, levels if levels is not None else levels_in_file(D.render.levels,
                                                                                          c.available_level))
        report["render"] = render
        ok = ok and render["ok"]
    report["ok"] = bool(ok)
    if args.json:
        print(json.dumps(report, indent=1, sort_keys=True))
    elif not args.quiet or not report["ok"]:
        if "decoders" in report:
            print(format_report(report["decoders"]))
        if "render" in report:
            from .verify.tables import format_table

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

    from .lop.container import read
    from .lop.summary import describe_container
    from .ingest import load
    from .report import analysis_warnings, build_report, render_for_report, write_html
    from .settings import IngestSettings
    from .verify.decoders import parse_levels

    from .outputs import check_output

    out = args.output
    inputs = (args.container, args.source)
    check_output(out, "-o", extensions=(".html", ".htm"), what="the HTML report (its JSON beside it)", inputs=inputs)
    check_output(str(Path(out).with_suffix(".json")), "-o's .json", extensions=(".json",), what="the report JSON",
                 inputs=inputs)
    views = _views(args.views, "--views")
    resolution = _resolution(args.resolution, "--resolution")
    levels = parse_levels(args.levels, args.container) if args.levels is not None else None
    if not math.isfinite(args.min_psnr):
        raise LopcookError("usage", None, f"--min-psnr {args.min_psnr}: expected a number of dB")
    from .ingest import sniff

    sniff(args.source)  # a missing file, a directory, a FIFO or device: its own one-line reason
    c = read(args.container, allow_prefix=True)
    if levels is None:
        from .verify.evaluate import levels_in_file

        levels = levels_in_file(D.render.levels, c.available_level)
    crease = args.crease_angle
    if crease is None:
        crease = ((c.manifest.get("options") or {}).get("ingest") or {}).get("crease_angle_deg")
    if crease is not None and not 0.0 <= float(crease) <= 180.0:
        raise LopcookError("usage", None, f"--crease-angle {crease} is outside [0, 180] degrees")
    ingest = IngestSettings(crease_angle_deg=float(crease)) if crease is not None else IngestSettings()
    progress = _progress(args)
    with progress.stage(f"ingest {os.path.basename(args.source)}"):
        t0 = time.perf_counter()
        scene = load(args.source, ingest)
        ingest_s = time.perf_counter() - t0
    warnings = cook = None
    if not args.no_analyse:
        # before the renders, and only its record kept: the re-cook's arrays are freed before the
        # renders' images accumulate, so the two peaks do not add up
        from .memory import release_free_memory
        from .tune.recook import recook

        with progress.stage("re-cook (stage timings, warnings, determinism)"):
            cook = recook(c, scene, ingest_s=ingest_s, progress=progress)
            warnings = analysis_warnings(scene, cook.pop("analysis"))
        release_free_memory()
    ev, ev16, level_range = render_for_report(c, scene, levels=levels, views=views, resolution=resolution,
                                              progress=progress)
    desc = describe_container(c, file_bytes=os.path.getsize(args.container))
    with progress.stage("page"):
        rep = build_report(c, scene, ev, desc, warnings=warnings, uniform16=ev16, cook=cook, level_range=level_range,
                           min_psnr=args.min_psnr)
        html_path, json_path = write_html(rep, ev.get("images"), out)
    passed = rep["verdict"]["result"] == "PASS"
    if args.json:
        print(json.dumps(rep, indent=1, sort_keys=True))
    elif not args.quiet or not passed:
        from .report.verdict import verdict_line
        from .verify.tables import format_table

        if not args.quiet:
            print(format_table(ev))
        print(f"  {verdict_line(rep['verdict'])}")
        print(f"  wrote {html_path} and {json_path}")
    from .errors import EXIT_VERIFY_FAILED

    return EXIT_OK if passed else EXIT_VERIFY_FAILED


def _add_bench_parser(sub) -> None:
    """``lopcook bench``: lopcook against gltfpack, glTF-Transform and Draco (lopcook/bench.py, docs/bench.md)."""
    p = sub.add_parser("bench", help="speed and accuracy against gltfpack, glTF-Transform and Draco, and how the "
                                     "cook's cost grows (needs pip install 'lopcook[bench]'; see docs/bench.md)")
    p.add_argument("assets", nargs="*", metavar="ASSET",
                   help="source files (default: bunny, fandisk, DamagedHelmet and the chess set from "
                        "$LOPCOOK_CORPUS or ../shared/corpus)")
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="folder for CSVs, charts and summary")
    p.add_argument("--levels", default="6-11", metavar="LEVELS", help="camera levels, e.g. 6-11 (default 6-11)")
    _add_harness(p)
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
    p.add_argument("--attributes", action="store_true",
                   help="instead: total GPU bytes per vertex (positions + normals + UVs + colours) against PSNR, "
                        "every output rendered with its own decoded attributes (gltfpack -vn/-vt, glTF-Transform "
                        "quantize, Draco -qn/-qt sweeps and lopcook; attributes.json/.csv/.png; default assets: "
                        "bunny, DamagedHelmet, Duck)")
    p.add_argument("--attributes-target", type=float, default=None, metavar="DB",
                   help="with --attributes: also cook --target-psnr DB")
    p.add_argument("--connectivity", action="store_true",
                   help="instead: the hierarchy connectivity benchmark (bits per triangle of every coding variant, "
                        "meshoptimizer and Draco, throughput, and the chart against the random-access unit size; "
                        "default assets: the corpus)")
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


COMMANDS = {"inspect": cmd_inspect, "analyse": cmd_analyse, "cook": cmd_cook, "decode": cmd_decode, "refine": cmd_refine,
            "verify": cmd_verify, "calibrate": cmd_calibrate, "report": cmd_report,
            "bench": cmd_bench, "batch": cmd_batch}


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra:  # an unknown flag after a command: that command's usage, not the top level's
        sub = parser._subparsers._group_actions[0].choices[args.command]
        sub.error(f"unrecognized arguments: {' '.join(extra)}")
    try:
        with small_pages():
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
