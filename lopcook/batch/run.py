"""Plan, execute, record and summarise one batch (``lopcook batch``; docs/batch.md).

1. Read ``lopcook.toml`` (``config.load_config``) and find the assets (``discover.discover``).
2. Resolve each asset's cook options and check it against the state file
   (``keys.State.up_to_date``): up-to-date assets are not cooked.
3. Cook the rest, largest input first (the longest cooks start first, so the last to finish is
   not a big one started late), locally (``local.run_local``) or on a Dask cluster
   (``cluster.run_cluster``).
4. As each cook finishes: record a success in the state (saved atomically at most every 2 s and
   at the end, also after an interrupt); for a failure, remove any older output of that asset
   and its state entry, so OUTDIR never holds an output that does not match the current
   sources and options. Other assets' state entries (from other batches into the same OUTDIR)
   are kept.
"""

from __future__ import annotations

import os
import shutil
import time
from dataclasses import dataclass

try:
    import fcntl  # POSIX only: the OUTDIR lock is taken where the platform has it
except ImportError:  # pragma: no cover - not POSIX: no lock
    fcntl = None

from ..errors import LopcookError
from ..version import __version__
from . import SCRATCH_DIR
from .cluster import run_cluster
from .config import BatchConfig, load_config, resolve
from .discover import Asset, discover
from .keys import State, options_digest
from .local import run_local
from .progress import Progress

DEFAULT_MEMORY_CAP = 4 * 10 ** 9
_SAVE_EVERY_S = 2.0


@dataclass(frozen=True)
class Planned:
    asset: Asset
    options: tuple[str, ...]
    resolved: dict


def default_config_path() -> str | None:
    """``./lopcook.toml`` when it exists (the batch's default ``--config``), else None."""
    return "lopcook.toml" if os.path.isfile("lopcook.toml") else None


def plan(sources, outdir: str, config: BatchConfig) -> list[Planned]:
    """Every asset of ``sources`` with its cook flags and their resolved values."""
    cache: dict[tuple[str, ...], dict] = {}
    out = []
    for a in discover(sources, outdir, config):
        opts = config.options_for(a.relpath)
        if opts not in cache:
            cache[opts] = resolve(opts)
        out.append(Planned(a, opts, cache[opts]))
    return out


def _input_bytes(p: Planned, state: State) -> int:
    entry = state.entries.get(state.rel(p.asset.output)) or {}
    total = 0
    for d in entry.get("deps") or [p.asset.source]:
        try:
            total += os.path.getsize(d)
        except OSError:
            pass
    return total


def _lock(outdir: str):
    """An exclusive ``flock`` on ``OUTDIR/.lopcook-batch.lock`` (released when the returned file
    closes): two batches writing one OUTDIR at once would lose each other's state entries."""
    fh = open(os.path.join(outdir, ".lopcook-batch.lock"), "a+b")
    if fcntl is None:  # not POSIX: no lock
        return fh
    try:
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        fh.close()
        raise LopcookError("usage", outdir, "another lopcook batch is writing this OUTDIR",
                           hint="wait for it to finish, or give another -o") from None
    return fh


def run_batch(sources, outdir: str, *, config: BatchConfig | None = None, jobs: int = 1,
              scheduler: str | None = None, memory_cap: int | None = DEFAULT_MEMORY_CAP, force: bool = False,
              scheduler_timeout_s: float = 30.0, progress: str | None = "quiet") -> dict:
    """Cook what is out of date; return the summary (the ``--json`` document, docs/batch.md).

    ``progress``: ``progress.Progress``'s mode: "bar", "lines", "quiet" (default) or None (a bar
    when stderr is a terminal, else lines). Raises ``LopcookError`` for usage problems (bad SOURCE, config, scheduler) before
    any cook; a failing asset is reported in the summary, never raised.
    """
    t0 = time.perf_counter()
    config = config if config is not None else load_config(default_config_path())
    outdir = os.path.abspath(outdir)
    planned = plan(sources, outdir, config)
    _make_outdir(outdir)
    lock = _lock(outdir)
    state = State.load(outdir)
    records, todo = _up_to_date(planned, state, force)
    todo.sort(key=lambda p: (-_input_bytes(p, state), p.asset.output))
    scratch_root = os.path.join(outdir, SCRATCH_DIR)
    # what a killed earlier batch left there (its cooks' scratch folders): no batch holds it now
    shutil.rmtree(scratch_root, ignore_errors=True)
    tasks = [{"source": p.asset.source, "output": p.asset.output, "relpath": p.asset.relpath,
              "options": list(p.options), "resolved": p.resolved, "memory_cap": memory_cap,
              "scratch_root": scratch_root} for p in todo]

    bar = Progress(len(tasks), progress)
    last_save = [time.perf_counter()]
    cluster_info = None

    def on_result(task: dict, result: dict) -> None:
        _record(records[task["output"]], state, task, result)
        bar.advance(task["relpath"], result)
        if time.perf_counter() - last_save[0] > _SAVE_EVERY_S:
            state.save()
            last_save[0] = time.perf_counter()

    try:
        if scheduler and tasks:  # nothing to cook: no need to reach the cluster
            cluster_info = run_cluster(tasks, scheduler, on_result, timeout_s=scheduler_timeout_s)
        elif not scheduler:
            run_local(tasks, jobs, on_result)
    finally:
        bar.close()
        state.save()
        try:
            os.rmdir(scratch_root)
        except OSError:
            pass
        lock.close()
    assets = [records[p.asset.output] for p in planned]
    counts = {s: sum(1 for a in assets if a["status"] == s) for s in ("cooked", "up-to-date", "failed")}
    summary = {"lopcook": __version__, "pid": os.getpid(), "outdir": outdir, "config": config.path, "jobs": None if scheduler else jobs,
               "scheduler": scheduler, "memory_cap_bytes": memory_cap, "assets": assets,
               "counts": counts, "ok": counts["failed"] == 0,
               "wall_s": time.perf_counter() - t0,
               "cpu_s": sum(a["cpu_s"] or 0.0 for a in assets)}
    if cluster_info:
        summary["workers"] = cluster_info["workers"]
    return summary


def _make_outdir(outdir: str) -> None:
    """Create OUTDIR (its parent must exist); usage error when it cannot be made or written."""
    try:
        os.makedirs(outdir, exist_ok=True)
    except OSError as exc:
        raise LopcookError("usage", outdir, f"cannot create the output folder ({exc.strerror or exc})",
                           hint="give -o a folder whose parent exists and is writable") from None
    if not os.access(outdir, os.W_OK | os.X_OK):
        raise LopcookError("usage", outdir, "the output folder is not writable")


def _up_to_date(planned: list, state: State, force: bool) -> tuple[dict, list]:
    """``({output: summary record}, [Planned to cook])``: the records of up-to-date assets are
    complete; the others are cooked (all of them with ``force``)."""
    records: dict[str, dict] = {}
    todo: list[Planned] = []
    for p in planned:
        rec = {"source": p.asset.source, "relpath": p.asset.relpath, "output": p.asset.output,
               "options": list(p.options)}
        records[p.asset.output] = rec
        if not force and state.up_to_date(p.asset.source, p.asset.output, p.resolved):
            e = state.entries[state.rel(p.asset.output)]
            rec.update(status="up-to-date", bytes=e.get("bytes"), time_s=None, cpu_s=None, peak_rss_bytes=None,
                       error=None, warnings=[])
        else:
            todo.append(p)
    return records, todo


def _record(rec: dict, state: State, task: dict, result: dict) -> None:
    """One finished cook into its summary record and the state: a success is recorded; a failure
    forgets the asset and removes its older output (OUTDIR never holds an output that does not
    match the current sources and options)."""
    ok = result.get("status") == "cooked"
    rec.update(status="cooked" if ok else "failed", error=result.get("error"), bytes=result.get("bytes"),
               time_s=result.get("wall_s", result.get("time_s")), cpu_s=result.get("cpu_s"),
               peak_rss_bytes=result.get("peak_rss_bytes"), host=result.get("host"),
               runner_pid=result.get("runner_pid"), warnings=result.get("warnings", []))
    if result.get("signal"):
        rec["signal"] = result["signal"]
    if ok:
        state.record(task["output"], {"source": task["source"], "deps": result["deps"], "key": result["key"],
                                      "output_sha256": result["output_sha256"], "bytes": result["bytes"],
                                      "options_sha256": options_digest(task["resolved"]),
                                      "lopcook": __version__})
    else:
        state.forget(task["output"])
        try:
            os.unlink(task["output"])
        except FileNotFoundError:
            pass


def format_summary(summary: dict) -> str:
    """The text summary: one line of counts, then one line per failed asset."""
    c = summary["counts"]
    n = len(summary["assets"])
    where = (f"on {summary['scheduler']} ({summary.get('workers', '?')} workers)" if summary["scheduler"]
             else f"--jobs {summary['jobs']}")
    if c["cooked"] == 0 and c["failed"] == 0:
        return (f"lopcook batch: nothing to cook: {'all ' if n else ''}{n} asset{'s' if n != 1 else ''} up to date "
                f"in {summary['outdir']} ({summary['wall_s']:.2f} s)")
    lines = [f"lopcook batch: {n} asset{'s' if n != 1 else ''}: {c['cooked']} cooked, {c['up-to-date']} up to date, {c['failed']} failed "
             f"({summary['wall_s']:.1f} s wall, {summary['cpu_s']:.1f} s CPU in cooks, {where}) -> "
             f"{summary['outdir']}"]
    for a in summary["assets"]:
        if a["status"] == "failed":
            lines.append(f"  FAILED {a['relpath']}: {a['error']}")
    return "\n".join(lines)


__all__ = ["run_batch", "plan", "format_summary", "default_config_path", "DEFAULT_MEMORY_CAP"]
