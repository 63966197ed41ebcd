"""The ``lopcook batch`` subcommand: flags (``add_batch_parser``) and ``cmd_batch``.

Kept out of ``lopcook/cli.py`` (which only registers it) and light to import: nothing heavy is
imported until the command runs.
"""

from __future__ import annotations

import json
import os
import sys

from ..errors import EXIT_BAD_INPUT, EXIT_OK, LopcookError
from ..ingest import EXTENSIONS


def _default_jobs() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def add_batch_parser(sub) -> None:
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
                        f"here {_default_jobs()})")
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


def cmd_batch(args) -> int:
    from .config import load_config
    from .worker import parse_bytes

    jobs = args.jobs if args.jobs is not None else _default_jobs()
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
    from .run import default_config_path

    config = load_config(args.config if args.config is not None else default_config_path())
    if args.emit_ninja:
        return _emit_ninja(args, config)
    from .run import format_summary, run_batch

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
    from .ninja import write_ninja
    from .run import plan

    from ..outputs import OTHER_OUTPUTS, SOURCE_EXTENSIONS, check_output

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


__all__ = ["add_batch_parser", "cmd_batch"]
