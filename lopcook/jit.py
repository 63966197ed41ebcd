"""Compiled kernels: numba's ``njit`` with its on-disk cache, and the one switch between a kernel
and the numpy code it replaces.

Every kernel lives in a ``kernels`` module beside the numpy code it replaces (``simplify/kernels.py``
beside ``reference.py`` and ``topology.py``); the numpy function stays and is the test oracle: a kernel
returns the same values bit for bit (``tests/test_kernels_*.py`` compare them), or its module
states the difference (the closest-point hierarchy: among equally close faces, the lowest id). A stage asks
``use(n)`` with the size of its input and calls the kernel when it says so. The ``kernels``
modules import numba at their top, so only ``use`` decides whether numba is loaded at all.

``$LOPCOOK_KERNELS``: ``off`` (default, numpy and libigl only), ``auto`` kernels for inputs of at least ``MIN_ELEMENTS`` elements
(below it numpy is as fast and the cook does not pay numba's start-up; a stage whose kernel saves
less than that start-up asks for more unless numba is loaded already: ``use``'s ``pays_from``);
``on`` for every size; ``off`` never. Without numba (not installed, or it fails to load) everything runs on numpy.

Compiled code is cached on disk (numba's cache: ``$NUMBA_CACHE_DIR`` when set, else ``__pycache__``
beside the module, else the user's cache directory): the first cook on a fresh install compiles
(docs/performance.md, "The cost of compiling"), later ones load. Where no cache location is
writable (a read-only install and home) kernels compile in memory each run (``njit``).
Kernels release the GIL (``nogil``): ``parallel_ranges`` runs one over row ranges in threads; a
forked child starts its own threads.
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor

#: ``$LOPCOOK_KERNELS=auto`` uses a kernel from this many elements (vertices, faces, points) on
MIN_ELEMENTS = 1 << 15

#: ``parallel_ranges`` splits work of at least this many rows over threads
PARALLEL_ROWS = 1 << 14

_STATE: dict = {}
_LOCK = threading.Lock()


def _after_fork_in_child() -> None:
    """A forked child (``lopcook.isolate``) has none of the parent's threads: it starts its own pool
    (submitting to the inherited one would wait forever) and a fresh lock (another thread may have
    held it at the fork)."""
    global _LOCK
    _LOCK = threading.Lock()
    _STATE.pop("pool", None)


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_after_fork_in_child)


def mode() -> str:
    """``$LOPCOOK_KERNELS`` as ``auto``, ``on`` or ``off``: ``off`` when unset (the kernels are
    opt-in until every stage has run under them in the whole test suite), anything unknown counts
    as ``auto``."""
    v = os.environ.get("LOPCOOK_KERNELS", "off").strip().lower()
    if v in ("0", "off", "no", "false", "numpy"):
        return "off"
    if v in ("1", "on", "yes", "true", "always"):
        return "on"
    return "auto"


def available() -> bool:
    """Whether numba loads (checked once per process; the import costs about half a second)."""
    with _LOCK:
        if "numba" not in _STATE:
            try:
                import numba  # heavy (LLVM): loaded only when a kernel is first wanted
                _STATE["numba"] = numba
            except Exception:  # noqa: BLE001 - not installed or broken: numpy everywhere
                _STATE["numba"] = None
    return _STATE["numba"] is not None


def loaded() -> bool:
    """Whether numba is already loaded in this process (a kernel then costs no start-up)."""
    return _STATE.get("numba") is not None


def use(n: int, pays_from: int = MIN_ELEMENTS) -> bool:
    """Whether a stage with an input of ``n`` elements calls its kernel (module doc). ``auto``
    also asks for ``n >= pays_from`` unless numba is loaded already: a stage whose kernel saves
    less than numba's start-up below that size (docs/performance.md) passes it."""
    m = mode()
    if m == "off" or (m == "auto" and (n < MIN_ELEMENTS or (n < pays_from and not loaded()))):
        return False
    return available()


def njit(fn=None, **options):
    """``numba.njit`` with the kernels' options: ``nogil``, ``error_model="numpy"`` (a division by
    zero gives inf/nan as in numpy, no exception) and ``cache`` where a cache location is
    writable (else compiled in memory). No ``fastmath``: IEEE operations in source order, so
    results equal numpy's. Usable as ``@njit`` or ``@njit(inline="always")``."""
    import numba  # heavy: only kernels modules call this, and they are imported only when used

    opts = dict(nogil=True, error_model="numpy", cache=True)
    opts.update(options)

    def wrap(f):
        if opts.get("cache"):
            try:
                return numba.njit(**opts)(f)
            except RuntimeError:  # "cannot cache function": no writable cache location
                opts["cache"] = False
        return numba.njit(**opts)(f)

    return wrap if fn is None else wrap(fn)


def _pool(workers: int) -> ThreadPoolExecutor:
    with _LOCK:
        pool = _STATE.get("pool")
        if pool is None or pool._max_workers < workers:
            pool = _STATE["pool"] = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="lopcook-kernel")
    return pool


def threads() -> int:
    """Threads a kernel may use: ``$LOPCOOK_THREADS`` when set (at least 1), else the CPUs this
    process may use, at most 2."""
    env = os.environ.get("LOPCOOK_THREADS", "").strip()
    if env:
        try:
            return max(1, int(env))
        except ValueError:
            return 1
    try:
        n = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        n = os.cpu_count() or 1
    return max(1, min(2, n))


def parallel_ranges(fn, n: int, *args) -> None:
    """``fn(*args, lo, hi)`` over ``[0, n)`` cut into ``threads()`` contiguous ranges run in
    threads (one range, in this thread, below ``PARALLEL_ROWS`` rows). ``fn`` is a kernel that
    writes rows ``lo..hi`` of its outputs and nothing else, so the result does not depend on the
    number of threads."""
    t = threads() if n >= PARALLEL_ROWS else 1
    if t <= 1:
        fn(*args, 0, n)
        return
    cuts = [n * k // t for k in range(t + 1)]
    pool = _pool(t - 1)
    futs = [pool.submit(fn, *args, cuts[k], cuts[k + 1]) for k in range(1, t)]
    fn(*args, cuts[0], cuts[1])
    for f in futs:
        f.result()


__all__ = ["MIN_ELEMENTS", "PARALLEL_ROWS", "mode", "available", "loaded", "use", "njit", "threads", "parallel_ranges"]
