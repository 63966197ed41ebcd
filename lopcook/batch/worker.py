"""One cook in a fresh process under a memory cap: what every batch runner executes.

``run_isolated(task)`` (called by the local runner's threads and, on a Dask worker, by the
cluster runner) starts ``python -m lopcook.batch.worker TASK.json`` with the interpreter it runs
under, waits for it with ``os.wait4`` (so its CPU time and peak resident memory are known even
when it dies) and returns the result dict. The child:

1. sets ``RLIMIT_AS`` (address space) to ``task["memory_cap"]`` bytes when given: an asset that
   needs more fails (``MemoryError``, or a native library that does not check ``malloc`` dies
   with a signal) instead of taking the machine down;
2. calls ``lopcook.cli.main(["cook", SOURCE, "-o", SCRATCH/out.lop, "--depfile", SCRATCH/out.d,
   "--json", *options])``, the very code ``lopcook cook`` runs, with stdout and stderr captured;
3. on success computes the incremental key over the files the depfile lists
   (``lopcook.batch.keys.asset_key``), hashes the output and ``os.replace``s it to its final
   path (same filesystem: atomic), then writes the result JSON.

A failure (non-zero exit, an exception, a signal) leaves nothing at the final path: the cook only
ever wrote inside the scratch folder, which ``run_isolated`` removes in every case. The error is
the cook's one-line ``lopcook: error: ...`` message when there is one, else the last stderr line,
else the signal's name.

Result keys: ``status`` ("cooked" | "failed"), ``error``, ``time_s`` (wall, in the child),
``cpu_s`` (user + system of the child and the processes it waited for), ``peak_rss_bytes``
(the child's ``VmHWM``, or of a process it forked if larger), ``bytes``, ``output_sha256``,
``key``, ``deps``, ``exit_code``, ``signal``, and ``host`` / ``runner_pid``: the machine and the
process that launched the child (the batch itself, or a Dask worker).
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time

def _cook_in_child(task: dict) -> dict:
    import contextlib
    import io

    from .. import cli
    from .keys import asset_key, file_sha256, read_depfile

    scratch = task["scratch"]
    tmp_out = os.path.join(scratch, "out.lop")
    tmp_d = os.path.join(scratch, "out.d")
    start_ns = time.time_ns()
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = cli.main(["cook", task["source"], "-o", tmp_out, "--depfile", tmp_d, "--json", *task["options"]])
        except SystemExit as exc:  # argparse (the options were validated up front: should not happen)
            rc = exc.code if isinstance(exc.code, int) else 2
    if rc != 0:
        return {"status": "failed", "exit_code": rc, "error": error_line(err.getvalue(), rc)}
    info = json.loads(out.getvalue())
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


def error_line(stderr: str, rc: int | None = None) -> str:
    """The one line that explains a failed cook: ``lopcook: error: X`` -> ``X``; else the last line."""
    lines = [ln.strip() for ln in stderr.splitlines() if ln.strip()]
    for ln in reversed(lines):
        for prefix in ("lopcook: error: ", "lopcook: internal error: "):
            if ln.startswith(prefix):
                return ln[len(prefix):] if prefix == "lopcook: error: " else "internal error: " + ln[len(prefix):]
    if lines:
        return lines[-1][:500]
    return f"lopcook cook exited with status {rc}"


def child_main(argv: list[str]) -> int:
    """``python -m lopcook.batch.worker TASK.json``: cook, write ``TASK.json``'s ``result`` file."""
    with open(argv[0], encoding="utf-8") as fh:
        task = json.load(fh)
    cap = task.get("memory_cap")
    if cap:
        import resource

        resource.setrlimit(resource.RLIMIT_AS, (int(cap), int(cap)))
    t0 = time.perf_counter()
    try:
        result = _cook_in_child(task)
    except MemoryError:
        result = {"status": "failed", "exit_code": 3,
                  "error": f"out of memory under the worker memory cap ({format_bytes(cap)})" if cap else
                  "out of memory"}
    except Exception as exc:  # noqa: BLE001 - reported as this asset's failure
        result = {"status": "failed", "exit_code": 3, "error": f"internal error: {type(exc).__name__}: {exc}"}
    result["time_s"] = time.perf_counter() - t0
    result["peak_rss_bytes"] = _own_peak_rss()
    from ..atomic import write_atomic

    write_atomic(task["result"], json.dumps(result).encode())
    return 0


def _own_peak_rss() -> int | None:
    """Peak resident memory of this process (``VmHWM``, which restarts at ``exec``, so it does not
    include the launching process) or of a child it forked (the cook forks its simplifier;
    ``RUSAGE_CHILDREN``, which for a fork includes this process's RSS at the fork), in bytes."""
    import resource

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


def format_bytes(n) -> str:
    n = float(n)
    for unit in ("B", "KB", "MB", "GB", "TB"):
        if n < 1000 or unit == "TB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.3g} {unit}"
        n /= 1000
    return f"{n} B"


def parse_bytes(text: str) -> int | None:
    """``--worker-memory``: ``4GB``, ``512MB``, ``2GiB``, ``1e9``; ``0``/``none``/``off`` -> None (no cap)."""
    t = str(text).strip().lower().replace("_", "").replace(" ", "")
    if t in ("0", "none", "off", "unlimited"):
        return None
    units = {"kib": 1 << 10, "mib": 1 << 20, "gib": 1 << 30, "tib": 1 << 40,
             "kb": 10 ** 3, "mb": 10 ** 6, "gb": 10 ** 9, "tb": 10 ** 12, "k": 10 ** 3, "m": 10 ** 6,
             "g": 10 ** 9, "t": 10 ** 12, "b": 1}
    for u in sorted(units, key=len, reverse=True):
        if t.endswith(u):
            num, mult = t[:-len(u)], units[u]
            break
    else:
        num, mult = t, 1
    try:
        value = float(num) * mult
    except ValueError:
        raise ValueError(f"expected a size such as 4GB, 512MB or 2GiB (or none), got {text!r}") from None
    if not value >= 1:
        raise ValueError(f"expected a positive size such as 4GB (or none), got {text!r}")
    return int(value)


def run_isolated(task: dict) -> dict:
    """Cook ``task`` in a fresh ``python -m lopcook.batch.worker`` process; the result dict (module doc).

    ``task``: ``source``, ``output`` (absolute), ``options`` (cook flags), ``resolved`` (their
    ``config.resolve`` dict), ``memory_cap`` (bytes or None), ``scratch_root`` (a directory on the
    output's filesystem). Never raises for a failed cook: the failure is in the result.
    """
    t0 = time.perf_counter()
    os.makedirs(task["scratch_root"], exist_ok=True)
    scratch = tempfile.mkdtemp(prefix="cook-", dir=task["scratch_root"])
    try:
        child_task = dict(task, scratch=scratch, result=os.path.join(scratch, "result.json"))
        task_path = os.path.join(scratch, "task.json")
        with open(task_path, "w", encoding="utf-8") as fh:
            json.dump(child_task, fh)
        with open(os.path.join(scratch, "stderr.txt"), "wb") as errf:
            proc = subprocess.Popen([sys.executable, "-m", "lopcook.batch.worker", task_path],
                                    stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=errf,
                                    env=_child_env())
            try:
                if hasattr(os, "wait4"):
                    _, status, ru = os.wait4(proc.pid, 0)
                    proc.returncode = os.waitstatus_to_exitcode(status)
                else:  # not POSIX: no resource usage of the child
                    proc.wait()
                    ru = None
            except BaseException:
                proc.kill()
                proc.wait()
                raise
        wall = time.perf_counter() - t0
        # wait4 sees the child even when it crashed; its ru_maxrss is an upper bound (Linux carries
        # the launching process's RSS high-water mark across fork + exec): the child's own figure wins
        usage = ({"cpu_s": ru.ru_utime + ru.ru_stime, "peak_rss_bytes": ru.ru_maxrss * 1024} if ru is not None
                 else {"cpu_s": None, "peak_rss_bytes": None})
        try:
            with open(child_task["result"], encoding="utf-8") as fh:
                result = json.load(fh)
        except (OSError, ValueError):
            with open(os.path.join(scratch, "stderr.txt"), encoding="utf-8", errors="replace") as fh:
                stderr = fh.read()
            rc = proc.returncode
            if rc < 0:
                name = signal.Signals(-rc).name if -rc in signal.valid_signals() else f"signal {-rc}"
                cap = task.get("memory_cap")
                error = f"worker crashed: killed by {name}" + (
                    f" (memory cap {format_bytes(cap)}: raise --worker-memory if the asset needs more)" if cap else "")
                result = {"status": "failed", "exit_code": rc, "signal": name, "error": error}
            else:
                result = {"status": "failed", "exit_code": rc,
                          "error": f"worker exited with status {rc}: {error_line(stderr, rc)}"}
            result["time_s"] = wall
        result["cpu_s"] = usage["cpu_s"]
        if not result.get("peak_rss_bytes"):
            result["peak_rss_bytes"] = usage["peak_rss_bytes"]
        result["wall_s"] = wall
        result["host"] = socket.gethostname()
        result["runner_pid"] = os.getpid()
        return result
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def _child_env() -> dict:
    """The child's environment: ours, with the directory lopcook is imported from first on
    PYTHONPATH (so the child cooks with this very lopcook, installed or not)."""
    import lopcook

    env = dict(os.environ)
    root = os.path.dirname(os.path.dirname(os.path.abspath(lopcook.__file__)))
    parts = [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p]
    if root not in parts and os.path.basename(root) not in ("site-packages", "dist-packages"):
        env["PYTHONPATH"] = os.pathsep.join([root, *parts])
    return env


if __name__ == "__main__":  # pragma: no cover - exercised through run_isolated
    sys.exit(child_main(sys.argv[1:]))
