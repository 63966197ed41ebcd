"""How many processes the LOD stage may use.

``workers()`` is ``$LOPCOOK_LOD_WORKERS`` when set (1 = serial; a value that is not a positive
integer counts as 1), else the CPUs this process may use (``lopcook.isolate.cpus``), at most
``MAX_WORKERS``; 1 inside a LOD worker process (``enter_worker``), so the work a chain splits over
two processes when it runs alone (``lopcook.simplify.reference``, ``lopcook.pipeline.parallel``)
stays in the worker. The chains' results do not depend on it (docs/lod.md).
"""

from __future__ import annotations

import os

from ..isolate import cpus

#: at most this many worker processes by default
MAX_WORKERS = 2

#: set in a LOD worker process: its chain runs serially inside (the workers already fill the CPUs)
_IN_WORKER = False


def workers() -> int:
    """Worker processes for the LOD stage (see the module doc); 1 inside a worker."""
    if _IN_WORKER:
        return 1
    env = os.environ.get("LOPCOOK_LOD_WORKERS", "").strip()
    if env:
        try:
            return max(1, int(env))
        except ValueError:
            return 1
    return max(1, min(MAX_WORKERS, cpus()))


def enter_worker() -> None:
    """Mark this process as a LOD worker (``workers()`` is 1 from now on); called in the forked child."""
    global _IN_WORKER
    _IN_WORKER = True


__all__ = ["MAX_WORKERS", "workers", "enter_worker"]
