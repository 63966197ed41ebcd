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
    return parser


def _ingest_settings(args):
    from .settings import IngestSettings

    kw = {}
    if getattr(args, "crease_angle", None) is not None:
        if not 0.0 <= args.crease_angle <= 180.0:
            raise LopcookError("usage", None, f"--crease-angle {args.crease_angle} is outside [0, 180] degrees")
        kw["crease_angle_deg"] = args.crease_angle
    return IngestSettings(**kw)


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


COMMANDS = {"inspect": cmd_inspect}


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
