"""The child side of one batch cook: ``python -m lopcook.batch.child TASK.json``, started by
``lopcook.batch.worker.run_isolated``.

1. sets ``RLIMIT_AS`` (address space) to ``task["memory_cap"]`` bytes when given: an asset that
   needs more fails (``MemoryError``, or a native library that does not check ``malloc`` dies
   with a signal) instead of taking the machine down;
2. cooks as ``lopcook cook SOURCE -o SCRATCH/out.lop --depfile SCRATCH/out.d [options]`` does:
   the options through the CLI's parser (``lopcook.cli.parser``), the cook through
   ``lopcook.cookjob.cook_file``, the very code ``lopcook cook`` runs;
3. on success computes the incremental key over the files the depfile lists
   (``lopcook.batch.keys.asset_key``), hashes the output and ``os.replace``s it to its final
   path (same filesystem: atomic), then writes the result JSON (``TASK.json``'s ``result``).

A failed cook's error is the one line ``lopcook cook`` prints after ``lopcook: error:``.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import resource  # POSIX only, as the batch runner (os.wait4): the memory cap and peak memory
import sys
import time

from ..atomic import write_atomic
from ..cli.parser import build_parser, settings_from_args
from ..cookjob import CookOutputs, cook_file
from ..errors import EXIT_INTERNAL, LopcookError, internal_error
from ..memory import small_pages
from .keys import asset_key, file_sha256, read_depfile
from .worker import error_line, format_bytes


def _cook_in_child(task: dict) -> dict:
    """Cook ``task``'s source into its scratch folder exactly as ``lopcook cook SOURCE -o OUT
    --depfile OUT.d [options]`` does (``lopcook.cli.parser``, ``lopcook.cookjob``), then move the
    output to its final path; the result dict (module doc)."""
    scratch = task["scratch"]
    tmp_out = os.path.join(scratch, "out.lop")
    tmp_d = os.path.join(scratch, "out.d")
    start_ns = time.time_ns()
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            args = build_parser().parse_args(["cook", task["source"], "-o", tmp_out, "--depfile", tmp_d,
                                              *task["options"]])
    except SystemExit as exc:  # argparse (the options were validated up front: should not happen)
        rc = exc.code if isinstance(exc.code, int) else 2
        return {"status": "failed", "exit_code": rc, "error": error_line(err.getvalue(), rc)}
    try:
        with small_pages():
            info, _ = cook_file(task["source"], settings_from_args(args),
                                CookOutputs(tmp_out, tmp_d, strict=bool(args.strict), destination=task["output"]))
    except LopcookError as exc:
        return {"status": "failed", "exit_code": exc.exit_code, "error": str(exc)}
    except MemoryError:  # over the memory cap: child_main words it
        raise
    except Exception as exc:  # noqa: BLE001 - a bug, worded as lopcook cook words it
        return {"status": "failed", "exit_code": EXIT_INTERNAL, "error": internal_error(exc)}
    deps = [os.path.abspath(d) for d in read_depfile(tmp_d)] or [task["source"]]
    key = asset_key(task["source"], deps, task["resolved"])
    for d in deps:  # an input written while we cooked: do not claim this output is current
        try:
            if os.stat(d).st_mtime_ns > start_ns:
                key = None
                break
        except OSError:
            pass
    digest = file_sha256(tmp_out)
    size = os.path.getsize(tmp_out)
    os.makedirs(os.path.dirname(task["output"]), exist_ok=True)
    os.replace(tmp_out, task["output"])
    return {"status": "cooked", "exit_code": 0, "error": None, "bytes": size, "output_sha256": digest, "key": key,
            "deps": deps, "cook_timings_s": info.get("timings_s", {}), "warnings": info.get("warnings", [])}


def child_main(argv: list[str]) -> int:
    """``python -m lopcook.batch.child TASK.json``: cook, write ``TASK.json``'s ``result`` file."""
    with open(argv[0], encoding="utf-8") as fh:
        task = json.load(fh)
    cap = task.get("memory_cap")
    if cap:
        resource.setrlimit(resource.RLIMIT_AS, (int(cap), int(cap)))
    t0 = time.perf_counter()
    try:
        result = _cook_in_child(task)
    except MemoryError:
        result = {"status": "failed", "exit_code": EXIT_INTERNAL,
                  "error": f"out of memory under the worker memory cap ({format_bytes(cap)})" if cap else
                  "out of memory"}
    except Exception as exc:  # noqa: BLE001 - reported as this asset's failure
        result = {"status": "failed", "exit_code": EXIT_INTERNAL, "error": f"internal error: {type(exc).__name__}: {exc}"}
    result["time_s"] = time.perf_counter() - t0
    result["peak_rss_bytes"] = _own_peak_rss()
    write_atomic(task["result"], json.dumps(result).encode())
    return 0


def _own_peak_rss() -> int | None:
    """Peak resident memory of this process (``VmHWM``, which restarts at ``exec``, so it does not
    include the launching process) or of a child it forked (the cook forks its simplifier;
    ``RUSAGE_CHILDREN``, which for a fork includes this process's RSS at the fork), in bytes."""
    peak = None
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    peak = int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    children = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024
    return max(peak or 0, children) or None


if __name__ == "__main__":  # pragma: no cover - exercised through lopcook.batch.worker.run_isolated
    sys.exit(child_main(sys.argv[1:]))
