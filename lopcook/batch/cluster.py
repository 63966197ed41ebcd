"""``--scheduler tcp://HOST:PORT``: the batch's cooks on a Dask distributed cluster.

Each asset is one Dask task, ``lopcook.batch.worker.run_isolated(task)``, so on the worker it
runs exactly as locally: a fresh ``python -m lopcook.batch.child`` process under the memory
cap, which cooks with ``lopcook cook``'s own code and moves the output into place.

The cluster needs a **shared filesystem**: every worker must see the sources and OUTDIR at the
same absolute paths as the client (NFS, a cluster filesystem, or one machine). Workers read the
sources and write the outputs there themselves; only the small result dicts travel back to the
client, which keeps the state file. Workers need lopcook (same version) installed, or
importable through PYTHONPATH, in the Python environment that runs ``dask worker``. Tasks are
submitted largest input first with ``pure=False`` (a re-run cooks again) and no retries (a
deterministic failure would only fail again); a task whose Dask worker dies fails only its
asset.
"""

from __future__ import annotations

import os
import uuid
from collections.abc import Callable, Iterable

from ..errors import LopcookError
from .worker import run_isolated


def run_cluster(tasks: Iterable[dict], scheduler: str, on_result: Callable[[dict, dict], None],
                timeout_s: float = 30.0) -> dict:
    """Run every task on the cluster at ``scheduler``; ``on_result(task, result)`` as each
    finishes. Returns ``{"scheduler": address, "workers": n}``. Raises ``LopcookError`` when the
    scheduler cannot be reached within ``timeout_s`` or has no workers."""
    try:
        from distributed import Client, as_completed  # optional (lopcook[cluster]): only --scheduler needs it
    except ImportError:
        raise LopcookError("usage", None, "--scheduler needs the distributed package",
                           hint="pip install distributed") from None
    tasks = list(tasks)
    try:
        client = Client(scheduler, timeout=timeout_s)
    except (OSError, TimeoutError) as exc:
        raise LopcookError("usage", None, f"--scheduler {scheduler}: cannot connect: {exc}",
                           hint="start it with `dask scheduler` and give its tcp://HOST:PORT") from None
    try:
        try:
            client.wait_for_workers(1, timeout=timeout_s)
        except (TimeoutError, OSError):
            raise LopcookError("usage", None, f"--scheduler {scheduler}: no workers joined within {timeout_s:g} s",
                               hint="start workers with `dask worker " + scheduler + "`") from None
        n_workers = len(client.scheduler_info()["workers"])
        if not tasks:
            return {"scheduler": scheduler, "workers": n_workers}
        futures = {}
        for i, t in enumerate(tasks):
            f = client.submit(run_isolated, t, pure=False, retries=0, priority=len(tasks) - i,
                              key=f"lopcook-cook-{os.path.basename(t['output'])}-{uuid.uuid4().hex[:12]}")
            futures[f.key] = (f, t)
        for fut in as_completed([f for f, _ in futures.values()]):
            task = futures[fut.key][1]
            try:
                result = fut.result()
            except Exception as exc:  # noqa: BLE001 - the Dask worker died or the task could not run
                result = {"status": "failed", "exit_code": None,
                          "error": f"dask task failed: {type(exc).__name__}: {exc}"}
            on_result(task, result)
        return {"scheduler": scheduler, "workers": n_workers}
    finally:
        client.close()


__all__ = ["run_cluster"]
