"""``--jobs N``: the batch's cooks on this machine, at most N at a time.

Each cook is its own fresh process (``worker.run_isolated``), so one asset's memory, crash or
leaked state cannot touch another's, and each result carries that process's own CPU time and
peak memory. N threads each wait on one child process at a time; the threads only wait, the
cooking happens in the children.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor, as_completed

from .worker import run_isolated


def run_local(tasks: Iterable[dict], jobs: int, on_result: Callable[[dict, dict], None]) -> None:
    """Run every task with at most ``jobs`` worker processes; call ``on_result(task, result)`` in
    this thread as each finishes (in completion order). Tasks start in the order given."""
    tasks = list(tasks)
    if not tasks:
        return
    with ThreadPoolExecutor(max_workers=max(1, min(jobs, len(tasks))), thread_name_prefix="lopcook-batch") as pool:
        futures = {pool.submit(run_isolated, t): t for t in tasks}
        try:
            for fut in as_completed(futures):
                on_result(futures[fut], fut.result())
        except BaseException:
            for fut in futures:
                fut.cancel()
            raise


__all__ = ["run_local"]
