"""The ``lopcook`` command line as data: the argument parser (every command's flags, defaults and
help from ``lopcook.DEFAULTS``) and the mapping of parsed flags to one frozen ``Settings``.

``build_parser()`` -> ``argparse.ArgumentParser`` whose usage errors are one line (exit 2).
``settings_from_args(args)`` -> ``Settings`` for ``cook``, ``calibrate`` and ``analyse``; a value
out of range, or flags that do not combine, is one ``LopcookError`` ("usage", exit 2) naming the
flag, raised before any work. The ``check_*``/``parse_*`` helpers do the same for the flags of
the other commands. ``lopcook.batch`` validates a batch's cook options with this parser.
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from dataclasses import replace

from ..errors import LopcookError
from ..ingest import EXTENSIONS, describe_formats, formats_table
from ..isolate import cpus
from ..lop.codecs import CODECS
from ..progress import MODES
from ..settings import (CLUSTER_SIZE_RANGE, DEFAULTS, AnalyseSettings, AttributeSettings, BudgetScope, DepthMode,
                        EmitSettings, IngestSettings, LodBackend, PsnrStat, RenderSettings, SearchKnobs, SeamMode,
                        Settings, SimplifySettings, TuneSettings, budget_target, parse_lods, parse_resolution)
from ..verify.decoders import parse_levels
from ..verify.metrics import max_finite_psnr
from ..version import __version__
from ..viewing import Viewing

D = DEFAULTS


def _add_crease_angle(p: argparse.ArgumentParser) -> None:
    p.add_argument("--crease-angle", type=float, default=None, metavar="DEG",
                   help="dihedral angle above which computed normals split, degrees in [0, 180] "
                        f"(default {D.ingest.crease_angle_deg:g}; 180 = smooth)")
    p.add_argument("--max-triangles", type=int, default=D.ingest.max_triangles, metavar="N",
                   help="refuse (exit 2) a source placing more triangles than this over all its instances, "
                        f"counted before anything is expanded, in [1, {D.ingest.max_triangles:,}] "
                        f"(default {D.ingest.max_triangles:,})")


def levels_text(levels) -> str:
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


class _FormatsAction(argparse.Action):
    """``lopcook --formats``: list the input formats and whether each can be read here, exit 0."""

    def __init__(self, option_strings, dest, **kwargs) -> None:
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        print(formats_table())
        parser.exit(0)


class UsageExit(SystemExit):
    """A usage error of the argument parser: exit status 2, after its one line went to stderr.
    ``message`` is argparse's text alone (``unrecognized arguments: --lodz 1/2``) and ``prog`` the
    parser that raised it (``lopcook cook``), so that ``lopcook.cli.main`` can print it as JSON
    and ``lopcook.batch`` quote it once."""

    def __init__(self, prog: str, message: str) -> None:
        super().__init__(2)
        self.prog = prog
        self.message = message


#: a value that starts like a negative number: ``-1.2,0.3,4``, ``-.5``, ``-0.5m``, ``-1e-3``
_NEGATIVE_VALUE = re.compile(r"-\.?[0-9]")


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line (exit 2), like lopcook's own errors:
    ``lopcook cook: error: the following arguments are required: -o (see lopcook cook --help)``.
    Subcommand parsers are made of this class too.

    A flag that takes one value also takes one that starts with ``-`` and a digit (``refine
    --camera -1.2,0.3,4``, ``--nearest -0.5m``, ``--eps -1e-3``): argparse alone reads such a
    token as an unknown option and reports "expected one argument" (it knows only plain
    negative numbers such as ``-1`` or ``-0.5``). ``parse_known_args`` joins the two tokens into
    ``--flag=VALUE`` first, so the flag's own check judges the value."""

    def error(self, message: str):
        sys.stderr.write(f"{self.prog}: error: {message} (see {self.prog} --help)\n")
        raise UsageExit(self.prog, message)

    def parse_known_args(self, args=None, namespace=None):
        args = sys.argv[1:] if args is None else list(args)
        return super().parse_known_args(self._join_negative_values(args), namespace)

    def _join_negative_values(self, args: list[str]) -> list[str]:
        """``[..., "--camera", "-1,2,3", ...]`` -> ``[..., "--camera=-1,2,3", ...]`` for this
        parser's flags that take exactly one value; tokens after ``--`` are left alone."""
        out: list[str] = []
        i = 0
        while i < len(args):
            token = args[i]
            if token == "--":
                return out + args[i:]
            action = self._one_value_flag(token)
            if action is not None and i + 1 < len(args) and _NEGATIVE_VALUE.match(args[i + 1]):
                out.append(f"{token}={args[i + 1]}")
                i += 2
                continue
            out.append(token)
            i += 1
        return out

    def _one_value_flag(self, token: str):
        """The action of ``token`` when it is a long flag of this parser (or an unambiguous
        abbreviation of one) that takes exactly one value; else None."""
        if not token.startswith("--") or "=" in token:
            return None
        actions = self._option_string_actions
        action = actions.get(token)
        if action is None and self.allow_abbrev:
            found = {actions[s] for s in actions if s.startswith(token)}
            action = found.pop() if len(found) == 1 else None
        if action is None or action.nargs is not None:  # nargs None: exactly one value
            return None
        return action


def build_parser() -> argparse.ArgumentParser:
    """The ``lopcook`` parser: the global flags, one subparser per command (each also taking
    ``--debug``, ``-q`` and ``--progress`` after the command)."""
    parser = _Parser(
        prog="lopcook",
        description=f"Cook {describe_formats()} scenes into level-of-precision (LOP) vertex containers.",
    )
    parser.add_argument("--version", action="version", version=f"lopcook {__version__}")
    parser.add_argument("--formats", action=_FormatsAction,
                        help="list the input formats, their extensions and whether each can be read here")
    parser.add_argument("--debug", action="store_true", help="show Python tracebacks on errors")
    parser.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors (and --json output)")
    parser.add_argument("--progress", choices=MODES, default="auto",
                        help="progress on stderr: a bar with counts and ETA on a terminal (auto, the default; "
                             "nothing off a terminal), bar, plain (one line per stage with its time, for CI logs) "
                             "or none")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    _add_inspect_parser(sub)
    _add_cook_parser(sub)
    _add_calibrate_parser(sub)
    _add_decode_parser(sub)
    _add_web_parser(sub)
    _add_view_parser(sub)
    _add_refine_parser(sub)
    _add_analyse_parser(sub)
    _add_verify_parser(sub)
    _add_report_parser(sub)
    _add_bench_parser(sub)
    _add_batch_parser(sub)
    # the global flags also work after the command (lopcook cook x.glb -o x.lop -q)
    for command in sub.choices.values():
        command.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                             help="show Python tracebacks on errors")
        command.add_argument("-q", "--quiet", action="store_true", default=argparse.SUPPRESS,
                             help="print nothing but errors (and --json output)")
        command.add_argument("--progress", choices=MODES, default=argparse.SUPPRESS,
                             help="progress on stderr: auto, bar, plain or none (see lopcook --help)")
    return parser


def _add_inspect_parser(sub) -> None:
    """``lopcook inspect``: describe a source scene or a container."""
    p = sub.add_parser("inspect", help="describe a source scene or a .lop container")
    p.add_argument("source", metavar="FILE", help=f"{describe_formats(extensions=True)} file, or a .lop container")
    _add_crease_angle(p)
    _add_common(p)


def _add_cook_parser(sub) -> None:
    """``lopcook cook``: every option of a cook (``settings_from_args`` maps them to Settings)."""
    p = sub.add_parser("cook", help="ingest, analyse and write a .lop container")
    p.add_argument("source", metavar="SOURCE", help=f"{describe_formats()} file")
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
    p.add_argument("--stream", action="store_true",
                   help="write the streaming layout: coarsest LODs first, each stage's positions after its "
                        "indices and attributes, sections compressed where that saves 5 %% (container version "
                        "4.0; docs/format.md 14-15)")
    add_analyse_options(p)
    add_attribute_options(p)
    add_viewing_options(p)
    _add_crease_angle(p)
    add_calibration_options(p, cook=True)
    add_attribute_search_options(p)
    add_budget_options(p)
    _add_common(p)


def _add_calibrate_parser(sub) -> None:
    """``lopcook calibrate``: the k_f search on its own."""
    p = sub.add_parser("calibrate", help="measure k_f: the least memory whose CAP renders reach a target PSNR")
    p.add_argument("source", metavar="SOURCE", help=f"{describe_formats()} file")
    add_analyse_options(p)
    add_viewing_options(p)
    _add_crease_angle(p)
    add_calibration_options(p, cook=False)
    _add_common(p)


def _add_decode_parser(sub) -> None:
    """``lopcook decode``: a container at a level as glTF 2.0."""
    p = sub.add_parser("decode", help="decode a .lop container at a level into a standard glTF 2.0 file")
    p.add_argument("container", metavar="CONTAINER.lop", help="a .lop container")
    p.add_argument("--level", type=int, required=True, metavar="B", help="per-buffer level B in [1, 24]")
    p.add_argument("--lod", type=int, default=0, metavar="K", help="LOD to decode (default 0)")
    p.add_argument("-o", "--output", default=None, metavar="OUT.glb",
                   help=".glb, or .gltf (+ .bin); may be left out when --positions is given")
    p.add_argument("--positions", default=None, metavar="OUT.f32",
                   help="write the float32 xyz (little-endian) of every vertex of every part and placement at --level, "
                        "in manifest order, world metres: the layout runtime/c's lopdump writes, so that readers "
                        "compare byte for byte (docs/runtime-c.md)")
    p.add_argument("--source", metavar="SRC", default=None,
                   help="source asset to take materials and textures from (default: where the cook recorded it, "
                        "relative to the container, then the manifest's source file beside the container; used "
                        "only when its sha256 matches)")
    _add_common(p)


def _add_web_parser(sub) -> None:
    """``lopcook web``: the glTF of the source's materials whose geometry streams from the container."""
    p = sub.add_parser("web", help="a glTF 2.0 file of the source's materials whose geometry streams from the "
                                   "container (LOPCOOK_lop_geometry, for runtime/js/three-lop.js)")
    p.add_argument("container", metavar="CONTAINER.lop", help="a .lop container")
    p.add_argument("-o", "--output", required=True, metavar="OUT.gltf",
                   help=".gltf (+ .bin of its images) or .glb; it refers to the container by a relative URI")
    p.add_argument("--source", metavar="SRC", default=None,
                   help="source asset to take materials and textures from (default: where the cook recorded it, "
                        "relative to the container, then the manifest's source file beside the container; used "
                        "only when its sha256 matches)")
    _add_common(p)


def _add_view_parser(sub) -> None:
    """``lopcook view``: the streaming viewer on 127.0.0.1 (lopcook/view/, docs/viewer.md)."""
    p = sub.add_parser("view", help="serve a page on 127.0.0.1 that streams the container into three.js with its "
                                    "materials (HUD, bandwidth throttle, level colours); Ctrl-C stops it")
    p.add_argument("container", metavar="CONTAINER.lop", help="a .lop container")
    p.add_argument("--source", metavar="SRC", default=None,
                   help="source asset to take materials and textures from (default: where the cook recorded it, "
                        "relative to the container, then the manifest's source file beside the container; used "
                        "only when its sha256 matches)")
    p.add_argument("--port", type=int, default=0, metavar="N",
                   help="TCP port on 127.0.0.1, 1..65535 (default 0: any free port; the URL is printed)")
    _add_common(p)


def _add_refine_parser(sub) -> None:
    """``lopcook refine``: the view-dependent cut of a ``--hierarchy`` container."""
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


def _add_analyse_parser(sub) -> None:
    """``lopcook analyse``: per-vertex minimum levels."""
    p = sub.add_parser("analyse", help="per-vertex minimum bit levels (attribute error and depth constraints)")
    p.add_argument("source", metavar="SOURCE", help=f"{describe_formats()} file")
    add_analyse_options(p)
    _add_crease_angle(p)
    _add_common(p)


def _add_verify_parser(sub) -> None:
    """``lopcook verify``: the decoders against the CPU reference, renders against the source."""
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
                        f"(default: every level the file holds for --decoders, {levels_text(D.render.levels)} for --source)")
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


def _add_report_parser(sub) -> None:
    """``lopcook report``: the HTML validation report."""
    p = sub.add_parser("report", help="one self-contained HTML report (and report.json) of a container rendered "
                                      "against its float source")
    p.add_argument("container", metavar="CONTAINER.lop", help="a .lop container")
    p.add_argument("--source", metavar="SOURCE", required=True, help=f"the {describe_formats()} file it was cooked from")
    p.add_argument("-o", "--output", metavar="REPORT.html", required=True,
                   help="HTML file to write; the JSON goes beside it with the suffix .json")
    p.add_argument("--levels", default=None, metavar="LEVELS",
                   help=f"per-buffer levels in [1, 24], e.g. 6-12 (default {levels_text(D.render.levels)}, "
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
                        f"{cal.views} views, {cal.resolution_text}, levels {levels_text(cal.levels)} unless set)")
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


def _add_bench_parser(sub) -> None:
    """``lopcook bench``: lopcook against gltfpack, glTF-Transform and Draco (lopcook/bench/, docs/bench.md)."""
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
    p.add_argument("--streaming", action="store_true",
                   help="instead: PSNR of the three.js viewer's render against the float render as a function of "
                        "the bytes of the container received, three cameras, gltfpack -cc and Draco (gzip -9) as "
                        "points (streaming.csv/.json/.png; headless Chromium; default assets: bunny, DamagedHelmet, "
                        "the chess set)")
    p.add_argument("--assets", nargs="+", default=[], dest="more_assets", metavar="SRC",
                   help="source files, added to the ASSET arguments")
    p.add_argument("--cook-args", default="", metavar="ARGS",
                   help="with --streaming: extra lopcook cook flags of the streamed containers, e.g. '--lods 1/2'")
    _add_common(p)


def _add_batch_parser(sub) -> None:
    """``lopcook batch``: many assets, incremental, in parallel or on a Dask cluster (docs/batch.md)."""
    p = sub.add_parser("batch", help="cook every asset of a tree into OUTDIR: incremental, parallel (--jobs), on a "
                                     "Dask cluster (--scheduler) or as a Ninja file (--emit-ninja); see docs/batch.md")
    p.add_argument("sources", nargs="+", metavar="SOURCE",
                   help=f"source files, directories (searched recursively for {' '.join(EXTENSIONS)}) or "
                        "manifests (text, one path per line)")
    p.add_argument("-o", "--output", required=True, metavar="OUTDIR",
                   help="output folder: the source tree mirrored, each SOURCE.ext as SOURCE.lop")
    p.add_argument("--config", default=None, metavar="lopcook.toml",
                   help="per-glob cook options and excludes (default: ./lopcook.toml when present)")
    p.add_argument("--jobs", "-j", type=int, default=None, metavar="N",
                   help="cook N assets at a time, each in a fresh worker process (default: the CPUs available, "
                        f"here {cpus()})")
    p.add_argument("--worker-memory", default="4GB", metavar="SIZE",
                   help="address-space cap per worker process, e.g. 4GB, 1500MB, 2GiB or none (default 4GB); "
                        "an asset that needs more fails alone")
    p.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                   help="run the cooks on this Dask distributed scheduler's workers (needs a shared filesystem; "
                        "see docs/batch.md)")
    p.add_argument("--scheduler-timeout", type=float, default=30.0, metavar="SECONDS",
                   help="how long to wait for the scheduler and its first worker (default 30)")
    p.add_argument("--emit-ninja", default=None, metavar="build.ninja",
                   help="write a Ninja file with one `lopcook cook` edge per asset (depfiles, deps = gcc) "
                        "instead of cooking")
    p.add_argument("--force", action="store_true", help="cook every asset, even those up to date")
    p.add_argument("--json", action="store_true",
                   help="print the summary as JSON on stdout: per asset status, time, CPU time, bytes, peak memory")


def check_views(n: int, flag: str) -> int:
    if not 1 <= int(n) <= 20:
        raise LopcookError("usage", None, f"{flag} {n}: expected 1..20 icosahedron views")
    return int(n)


def parse_xyz(text: str, flag: str):
    try:
        v = [float(x) for x in text.split(",")]
    except ValueError:
        v = []
    if len(v) != 3 or not all(math.isfinite(x) for x in v):
        raise LopcookError("usage", None, f"{flag} {text!r}: expected three finite numbers X,Y,Z")
    return v


def viewing_settings(args):
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
    """``--<codec>-bits`` for every attribute codec (``--normal-bits``, ``--uv-bits``, ``--color-bits``,
    ...: ``lopcook.lop.codecs.CODECS``; ``lopcook.settings.AttributeSettings``)."""
    g = p.add_argument_group("vertex attributes (docs/format.md section 7.2; Purnomo et al. 2005)")
    for c in CODECS:
        g.add_argument(f"--{c.singular}-bits", type=int, default=None, metavar="B",
                       help=f"{c.description}, {c.bits[0]}..{c.bits[1]} (default: the bound-based choice per part: "
                            "the fewest bits whose error keeps the shading change within --eps)")


def attribute_settings(args):
    """``--<codec>-bits`` -> AttributeSettings; out of range: usage error naming the flag."""
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


def ingest_settings(args):
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


def source_ingest_settings(args, manifest: dict) -> IngestSettings:
    """``verify --source`` and ``report``: the ingest settings to read the source with: ``--crease-angle``,
    else the one recorded in the container's manifest, else the default; outside [0, 180]: usage error."""
    crease = args.crease_angle
    if crease is None:
        crease = ((manifest.get("options") or {}).get("ingest") or {}).get("crease_angle_deg")
    if crease is not None and not 0.0 <= float(crease) <= 180.0:
        raise LopcookError("usage", None, f"--crease-angle {crease} is outside [0, 180] degrees")
    return IngestSettings(crease_angle_deg=float(crease)) if crease is not None else IngestSettings()


def analyse_settings(args):
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


def tune_settings(args):
    """``cook``/``calibrate`` flags -> TuneSettings (usage errors before any work)."""
    prefix = "--calibration-" if args.command == "cook" else "--"
    if args.target_psnr is not None and not args.target_psnr > 0:
        raise LopcookError("usage", None, f"--target-psnr {args.target_psnr}: expected a positive number of dB")
    given = [getattr(args, k) for k in ("calibration_views", "calibration_resolution", "calibration_levels")]
    cal = D.tune.calibration
    views, res, lv = (cal.views if given[0] is None else given[0],
                      cal.resolution_text if given[1] is None else given[1],
                      levels_text(cal.levels) if given[2] is None else given[2])
    calibration = RenderSettings(views=check_views(views, f"{prefix}views"),
                                 resolution=parse_resolution(res, f"{prefix}resolution"), levels=tuple(parse_levels(lv)))
    direct = all(v is None for v in given)  # no reduced harness asked for: search on the gate's
    if args.target_psnr is not None:
        _check_reachable(args, [RenderSettings()] if direct else
                         [calibration] + ([RenderSettings()] if args.calibration_confirm else []))
    kw = {}
    if getattr(args, "target_bytes", None) is not None:
        budget_target(args.target_bytes)
        if args.budget_levels < 1:
            raise LopcookError("usage", None, f"--budget-levels {args.budget_levels}: expected 1 or more")
        kw = dict(target_bytes=args.target_bytes, budget_scope=args.budget_scope, budget_levels=args.budget_levels,
                  budget=RenderSettings(views=check_views(args.budget_views, "--budget-views"),
                                        resolution=parse_resolution(args.budget_resolution, "--budget-resolution")))
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


def _check_reachable(args, harnesses) -> None:
    """``--target-psnr`` above what every harness it must pass can show short of identical renders
    (``lopcook.verify.metrics.max_finite_psnr``; 8-bit images): usage error before any work."""
    mean = PsnrStat(args.psnr_stat) == PsnrStat.MEAN
    caps = [(max_finite_psnr(*h.resolution, h.views if mean else 1), h) for h in harnesses]
    cap, h = min(caps, key=lambda c: c[0])
    if args.target_psnr > cap:
        where = f"one of {h.views} views of {h.resolution_text}" if mean else h.resolution_text
        raise LopcookError("usage", None, f"--target-psnr {args.target_psnr:g}: no render can show it: one 8-bit colour "
                           f"code off in one pixel of {where} is already {cap:.1f} dB "
                           f"(--psnr-stat {args.psnr_stat}), and only a render identical to the float32 one scores more",
                           hint=f"give a target of at most {math.floor(cap)} dB; 40 to 50 dB is usual")


def settings_from_args(args):
    """The argparse namespace of ``cook``, ``calibrate`` or ``analyse`` -> one frozen Settings."""
    simplify = DEFAULTS.simplify
    if getattr(args, "lods", None) is not None:
        simplify = SimplifySettings(lods=parse_lods(args.lods), backend=args.lod_backend,
                                    seams=getattr(args, "lod_seams", DEFAULTS.simplify.seams.value))
    if getattr(args, "hierarchy", False):
        simplify = replace(simplify, hierarchy=True)
    if getattr(args, "instances", None) is not None:
        simplify = replace(simplify, instances=bool(args.instances))
    return Settings(ingest=ingest_settings(args), simplify=simplify, analyse=analyse_settings(args),
                    viewing=viewing_settings(args) if hasattr(args, "viewport") else DEFAULTS.viewing,
                    tune=tune_settings(args) if hasattr(args, "target_psnr") else DEFAULTS.tune,
                    attributes=attribute_settings(args), emit=emit_settings(args))


def emit_settings(args):
    """``--clusters N`` and ``--stream`` -> EmitSettings (``--clusters`` absent: the default,
    ``DEFAULT_CLUSTER_SIZE``; 0: unclustered); not 0 or an integer in [16, 1024]: usage error
    (exit 2)."""
    return replace(_cluster_settings(args), stream=bool(getattr(args, "stream", False)))


def _cluster_settings(args):
    """``--clusters`` and ``--cluster-all`` -> EmitSettings (``emit_settings``)."""
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


__all__ = ["UsageExit", "build_parser", "settings_from_args", "ingest_settings", "source_ingest_settings", "analyse_settings", "check_views", "parse_xyz",
           "levels_text"]
