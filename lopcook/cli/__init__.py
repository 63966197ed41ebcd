"""Command-line interface: ``lopcook COMMAND [flags]`` (docs/cli.md).

``main(argv)`` parses the flags (``lopcook.cli.parser``), runs one command (``lopcook.cli.commands``;
``batch``: ``lopcook.batch.command``) and maps errors to exit codes: 0 ok, 1 verification failed,
2 bad input or usage (one line on stderr, no traceback unless ``--debug``), 3 internal error (a
bug: please report it with the ``--debug`` output), 130 interrupted.
"""

from __future__ import annotations

import sys

from ..errors import EXIT_INTERNAL, EXIT_OK, LopcookError, internal_error
from ..memory import small_pages
from .parser import build_parser


def main(argv: list[str] | None = None) -> int:
    """Run ``lopcook`` with ``argv`` (default ``sys.argv[1:]``); returns the exit code."""
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra:  # an unknown flag after a command: that command's usage, not the top level's
        sub = parser._subparsers._group_actions[0].choices[args.command]
        sub.error(f"unrecognized arguments: {' '.join(extra)}")
    try:
        with small_pages():
            return _command(args.command)(args)
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
        print(f"lopcook: {internal_error(exc)}", file=sys.stderr)
        return EXIT_INTERNAL


def _command(name: str):
    """The function that runs command ``name``, imported when it runs. ``lopcook.batch`` parses its
    cook flags with ``lopcook.cli.parser``, and importing that runs this module first: imported at
    the top here, batch would import itself half-made. A batch worker, which needs only the
    parser, so loads no command either."""
    if name == "batch":
        from ..batch.command import cmd_batch  # lazy: batch imports cli.parser (docstring)

        return cmd_batch
    from .commands import COMMANDS  # lazy: it loads every stage; --help and --version stay fast

    return COMMANDS[name]


__all__ = ["main", "build_parser"]

if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
