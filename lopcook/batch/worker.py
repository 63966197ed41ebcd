"""One cook in a fresh process under a memory cap: what every batch runner executes.

``run_isolated(task)`` (called by the local runner's threads and, on a Dask worker, by the
cluster runner) starts ``python -m lopcook.batch.child TASK.json`` (``lopcook.batch.child``: the
memory cap, the cook, the key) with the interpreter it runs under, waits for it with ``os.wait4``
(so its CPU time and peak resident memory are known even when it dies) and returns the result
dict.

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
    """Cook ``task`` in a fresh ``python -m lopcook.batch.child`` process; the result dict (module doc).

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
            proc = subprocess.Popen([sys.executable, "-m", "lopcook.batch.child", task_path],
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
    env = dict(os.environ)
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # holds lopcook/
    parts = [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p]
    if root not in parts and os.path.basename(root) not in ("site-packages", "dist-packages"):
        env["PYTHONPATH"] = os.pathsep.join([root, *parts])
    return env
