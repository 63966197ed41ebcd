"""The ``lopcook batch`` command: ``cmd_batch(args)`` runs a batch (or writes its Ninja file) from
the parsed flags (``lopcook.cli.parser``) and prints its summary; the exit code is 0 when every
asset is up to date or cooked, 2 otherwise.
"""

from __future__ import annotations

import json
import os
import sys

from ..errors import EXIT_BAD_INPUT, EXIT_OK, LopcookError
from ..isolate import cpus
from ..outputs import OTHER_OUTPUTS, SOURCE_EXTENSIONS, check_output
from .config import load_config
from .ninja import write_ninja
from .run import default_config_path, format_summary, plan, run_batch
from .worker import parse_bytes


def cmd_batch(args) -> int:
    jobs = args.jobs if args.jobs is not None else max(1, cpus())
    if jobs < 1:
        raise LopcookError("usage", None, f"--jobs {jobs}: expected 1 or more")
    try:
        memory_cap = parse_bytes(args.worker_memory)
    except ValueError as exc:
        raise LopcookError("usage", None, f"--worker-memory: {exc}") from None
    if args.scheduler is not None and "://" not in args.scheduler:
        raise LopcookError("usage", None, f"--scheduler {args.scheduler!r}: expected an address such as "
                           "tcp://10.0.0.5:8786")
    if not args.scheduler_timeout > 0:
        raise LopcookError("usage", None, f"--scheduler-timeout {args.scheduler_timeout}: expected seconds > 0")
    if os.path.exists(args.output) and not os.path.isdir(args.output):
        raise LopcookError("usage", args.output, "-o must be a directory (OUTDIR)")

    config = load_config(args.config if args.config is not None else default_config_path())
    if args.emit_ninja:
        return _emit_ninja(args, config)

    summary = run_batch(args.sources, args.output, config=config, jobs=jobs, scheduler=args.scheduler,
                        memory_cap=memory_cap, force=args.force, scheduler_timeout_s=args.scheduler_timeout,
                        progress="quiet" if args.quiet else None)
    if args.json:
        print(json.dumps(summary, indent=1, sort_keys=True))
    elif not args.quiet:
        print(format_summary(summary))
    else:
        for a in summary["assets"]:
            if a["status"] == "failed":
                print(f"lopcook: error: {a['relpath']}: {a['error']}", file=sys.stderr)
    return EXIT_OK if summary["ok"] else EXIT_BAD_INPUT


def _emit_ninja(args, config) -> int:
    planned = plan(args.sources, args.output, config)
    inputs = tuple(args.sources) + tuple(p.asset.source for p in planned) + ((args.config,) if args.config else ())
    check_output(args.emit_ninja, "--emit-ninja", extensions=(".ninja",), what="a Ninja build file", inputs=inputs,
                 forbidden=SOURCE_EXTENSIONS + OTHER_OUTPUTS + (".lop", ".toml"), required=False)
    write_ninja(args.emit_ninja, [(p.asset.source, p.asset.output, p.options) for p in planned])
    if args.json:
        print(json.dumps({"ninja": os.path.abspath(args.emit_ninja), "assets": len(planned),
                          "outdir": os.path.abspath(args.output)}, indent=1, sort_keys=True))
    elif not args.quiet:
        print(f"lopcook batch: wrote {args.emit_ninja}: {len(planned)} assets -> {os.path.abspath(args.output)} "
              f"(run: ninja -f {args.emit_ninja})")
    return EXIT_OK


__all__ = ["cmd_batch"]
