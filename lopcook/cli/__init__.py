"""Command-line interface: ``lopcook COMMAND [flags]`` (docs/cli.md).

``main(argv)`` parses the flags (``lopcook.cli.parser``), runs one command (``lopcook.cli.commands``;
``batch``: ``lopcook.batch.command``) and maps errors to exit codes: 0 ok, 1 verification failed,
2 bad input or usage (one line on stderr, no traceback unless ``--debug``), 3 internal error (a
bug: please report it with the ``--debug`` output), 130 interrupted. With ``--json`` a failing run
also prints ``{"error": {"exit_code": N, "message": "..."}}`` on stdout (docs/cli.md).
"""

from __future__ import annotations

import json
import sys

from ..errors import EXIT_BAD_INPUT, EXIT_INTERNAL, EXIT_OK, LopcookError, internal_error, one_line
from ..memory import small_pages
from .parser import UsageExit, build_parser


def main(argv: list[str] | None = None) -> int:
    """Run ``lopcook`` with ``argv`` (default ``sys.argv[1:]``); returns the exit code (a usage
    error of the parser raises ``SystemExit(2)``, as argparse does). With ``--json``, a failing
    run also prints one JSON object on stdout: ``{"error": {"exit_code": N, "message": "..."}}``,
    the message being the stderr line without its ``lopcook: error:`` prefix."""
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser()
    try:
        args, extra = parser.parse_known_args(argv)
        if extra:  # an unknown flag after a command: that command's usage, not the top level's
            sub = parser._subparsers._group_actions[0].choices[args.command]
            sub.error(f"unrecognized arguments: {' '.join(extra)}")
    except UsageExit as exc:
        if _json_asked(argv):
            _print_error(EXIT_BAD_INPUT, f"usage: {exc.message} (see {exc.prog} --help)")
        raise
    as_json = bool(getattr(args, "json", False))
    try:
        with small_pages():
            return _command(args.command)(args)
    except LopcookError as exc:
        if args.debug:
            raise
        print(f"lopcook: error: {exc}", file=sys.stderr)
        return _print_error(exc.exit_code, str(exc)) if as_json else exc.exit_code
    except KeyboardInterrupt:
        print("lopcook: interrupted", file=sys.stderr)
        return _print_error(EXIT_INTERRUPTED, "interrupted") if as_json else EXIT_INTERRUPTED
    except BrokenPipeError:
        return EXIT_OK
    except Exception as exc:  # a bug, not bad input
        if args.debug:
            raise
        print(f"lopcook: {internal_error(exc)}", file=sys.stderr)
        return _print_error(EXIT_INTERNAL, internal_error(exc)) if as_json else EXIT_INTERNAL


#: exit status of a run stopped by Ctrl-C (128 + SIGINT)
EXIT_INTERRUPTED = 130


def _json_asked(argv: list[str]) -> bool:
    """Whether ``--json`` is among ``argv`` (before a ``--``): how a run whose flags did not
    parse knows that it was asked for JSON."""
    return "--json" in (argv[:argv.index("--")] if "--" in argv else argv)


def _print_error(exit_code: int, message: str) -> int:
    """``--json``'s error object on stdout (one line); returns ``exit_code``."""
    print(json.dumps({"error": {"exit_code": int(exit_code), "message": one_line(message)}}, sort_keys=True),
          flush=True)
    return exit_code


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
