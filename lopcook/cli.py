"""Command-line interface: parse flags, call one stage function, map errors to exit codes.

Exit codes: 0 ok, 1 verification failed, 2 bad input or usage (one line on stderr, no traceback
unless ``--debug``), 3 internal error (a bug: please report it with the ``--debug`` output).
"""

from __future__ import annotations

import argparse
import json
import sys

from . import __version__
from .errors import EXIT_BAD_INPUT, EXIT_OK, LopcookError

EXIT_INTERNAL = 3


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

    p = sub.add_parser("inspect", help="describe a source scene (parts, counts, attributes, bounds, defects)")
    p.add_argument("source", metavar="SOURCE", help="glTF/GLB, OBJ or USD (.usd/.usda/.usdc/.usdz) file")
    p.add_argument("--crease-angle", type=float, default=None, metavar="DEG",
                   help="dihedral angle in degrees above which computed normals split (default 60; 180 = smooth)")
    _add_common(p)

    p = sub.add_parser("analyse", help="per-vertex minimum bit levels (attribute error and depth constraints)")
    p.add_argument("source", metavar="SOURCE", help="glTF/GLB, OBJ or USD file")
    add_analyse_options(p)
    p.add_argument("--crease-angle", type=float, default=None, metavar="DEG",
                   help="dihedral angle in degrees above which computed normals split (default 60)")
    _add_common(p)
    return parser


def add_analyse_options(p: argparse.ArgumentParser) -> None:
    from .settings import DEFAULT_ANALYSE as d

    g = p.add_argument_group("analysis (Meyer et al. 2011, section 5)")
    g.add_argument("--eps", type=float, default=d.eps, metavar="COLOUR",
                   help=f"largest shading error a vertex may cause, colour units in [0,1] (default 1/255)")
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
                               depth_ceiling=args.depth_ceiling)
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


def cmd_inspect(args) -> int:
    from .ingest import load
    from .inspect import describe_scene, format_scene

    scene = load(args.source, _ingest_settings(args))
    desc = describe_scene(scene)
    if args.json:
        print(json.dumps(desc, indent=1, sort_keys=True))
    elif not args.quiet:
        print(format_scene(desc))
    return EXIT_OK


COMMANDS = {"inspect": cmd_inspect, "analyse": cmd_analyse}


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
