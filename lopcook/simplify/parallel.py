"""LOD chains of independent parts in parallel worker processes, with the serial result.

``run_chains(parts, workers, **kwargs)`` returns ``[lod_chain(p, **kwargs) for p in parts]``,
exactly (every chain is deterministic and computed whole in one process; results are placed by
part index, whatever order the workers finish in). With ``workers > 1`` on Linux the chains run
in a pool of forked processes, largest part first; the parts reach the workers through the fork
(copy on write, not pickled) and each chain comes back pickled, with texture references that are
the input's own restored in the parent (a texture is not sent back per LOD). A worker that dies
(the memory killer, a crash in a simplifier) raises LopcookError. Elsewhere, with one worker, one
part or fewer than ``MIN_TRIANGLES`` triangles in all, the chains run in-process.

``workers()`` (``lopcook.simplify.workers``) is the default worker count; a chain run in a worker
sees 1 there. Measurements: docs/lod.md.
"""

from __future__ import annotations

import multiprocessing
import os
import sys
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import replace

from ..errors import LopcookError
from .chain import lod_chain
from .workers import enter_worker, workers

#: below this many triangles in all, the fork and pickling cost more than they save
MIN_TRIANGLES = 20_000

_JOBS: list = []


def _one(i: int):
    enter_worker()
    part, chain, kwargs = _JOBS[i]
    lods, report = chain(part, **kwargs)
    own = []
    for lod in lods:  # the input part (LOD 0) and its texture stay in the parent
        if lod.part is part:
            own.append("input")
            lod.part = None
        elif lod.part.texture is not None and lod.part.texture is part.texture:
            own.append("texture")
            lod.part = _without_texture(lod.part)
        else:
            own.append("")
    return i, lods, report, own


def _collect(pending: set, parts, out: list, progress) -> None:
    """Place each finished chain at its part's index (whatever order they finish in), with LOD 0
    and textures the input's own again."""
    while pending:
        done, pending = wait(pending, return_when=FIRST_COMPLETED)
        for fut in done:
            i, lods, report, own = fut.result()
            for lod, o in zip(lods, own):
                if o == "input":
                    lod.part = parts[i]
                elif o == "texture":
                    lod.part = replace(lod.part, texture=parts[i].texture)
            out[i] = (lods, report)
            if progress:
                progress()


def _without_texture(part):
    return replace(part, texture=None)


def run_chains(parts, n_workers: int | None = None, progress=None, chain=lod_chain, **kwargs) -> list:
    """``[chain(p, **kwargs) for p in parts]`` (``chain``: ``lod_chain`` or a function of its
    signature, reaching the workers through the fork; see the module doc); ``progress()`` is
    called once per finished chain."""
    n = len(parts)
    k = workers() if n_workers is None else max(1, int(n_workers))
    total = sum(p.n_triangles for p in parts)
    if k <= 1 or n <= 1 or total < MIN_TRIANGLES or not (hasattr(os, "fork") and sys.platform.startswith("linux")):
        out = []
        for p in parts:
            out.append(chain(p, **kwargs))
            if progress:
                progress()
        return out
    global _JOBS
    _JOBS = [(p, chain, kwargs) for p in parts]
    order = sorted(range(n), key=lambda i: -parts[i].n_triangles)
    out: list = [None] * n
    try:
        # an executor, not a multiprocessing Pool: a worker that dies (the memory killer, a crash in
        # a simplifier) breaks it and raises here, where a Pool would wait for its task forever
        with ProcessPoolExecutor(min(k, n), mp_context=multiprocessing.get_context("fork")) as pool:
            pending = {pool.submit(_one, i) for i in order}
            try:
                _collect(pending, parts, out, progress)
            except BaseException:
                pool.shutdown(wait=False, cancel_futures=True)  # the chains not started are dropped
                raise
    except BrokenProcessPool:
        raise LopcookError("simplify", None, "a LOD worker process died without a result (killed: out of memory, "
                           "or a crash in a simplifier)",
                           hint="give the cook more memory, or run the chains in one process with "
                                "LOPCOOK_LOD_WORKERS=1") from None
    finally:
        _JOBS = []
    return out


__all__ = ["run_chains", "MIN_TRIANGLES"]
