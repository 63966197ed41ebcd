"""Process memory housekeeping for the cook's large temporaries."""

from __future__ import annotations

import ctypes
import ctypes.util
import os
from contextlib import contextmanager

try:
    import resource  # POSIX only: address_space_limit is None elsewhere
except ImportError:  # pragma: no cover - not POSIX
    resource = None

# numpy's switch for madvise(MADV_HUGEPAGE), a private function that moved in numpy 2 (None where absent)
try:
    from numpy._core.multiarray import _set_madvise_hugepage as _MADVISE_HUGEPAGE
except ImportError:  # numpy 1.x
    try:
        from numpy.core.multiarray import _set_madvise_hugepage as _MADVISE_HUGEPAGE
    except ImportError:
        _MADVISE_HUGEPAGE = None

_LIBC = None


@contextmanager
def small_pages():
    """Within the block numpy allocates its large arrays without ``madvise(MADV_HUGEPAGE)``; the
    previous setting comes back on exit (forked children inherit the block's). Where the user set
    ``$NUMPY_MADVISE_HUGEPAGE`` numpy keeps that choice.

    numpy asks for transparent huge pages for every array of 4 MiB or more. The cook allocates and
    frees hundreds of megabytes of temporaries per stage and forks children beside them (a write
    to a shared page after a fork copies the whole page), so the advice costs more kernel time
    than it saves (measurements: docs/performance.md, "numpy's huge pages off"). The bytes
    written do not depend on it."""
    setter = None if "NUMPY_MADVISE_HUGEPAGE" in os.environ else _MADVISE_HUGEPAGE
    before = setter(False) if setter is not None else None
    try:
        yield
    finally:
        if setter is not None:
            setter(before)


def release_free_memory() -> None:
    """Return the C heap's free pages to the system (glibc ``malloc_trim(0)``; a no-op elsewhere).
    numpy and the native libraries free large temporaries into the heap, which glibc keeps; after
    a large ingest that is resident but unused memory (docs/performance.md). Called before a
    fork (the child would otherwise start with it resident) and between the cook's stages."""
    global _LIBC
    if _LIBC is None:
        try:
            _LIBC = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
            _LIBC.malloc_trim  # noqa: B018 - glibc only
        except (OSError, AttributeError):
            _LIBC = False
    if _LIBC:
        _LIBC.malloc_trim(0)


def available_bytes() -> int | None:
    """The system's ``MemAvailable`` (Linux ``/proc/meminfo``; within a cgroup limit
    ``memory.max`` minus ``memory.current`` when that is lower), bytes; None where unknown."""
    avail = None
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    avail = int(line.split()[1]) * 1024
                    break
    except (OSError, ValueError, IndexError):
        return None
    try:
        with open("/sys/fs/cgroup/memory.max") as f:
            limit = f.read().strip()
        with open("/sys/fs/cgroup/memory.current") as f:
            used = int(f.read().strip())
        if limit != "max":
            room = int(limit) - used
            avail = room if avail is None else min(avail, room)
    except (OSError, ValueError):
        pass
    return avail


def address_space_limit() -> int | None:
    """This process's address-space limit (``ulimit -v``, ``RLIMIT_AS``; what ``lopcook batch
    --worker-memory`` sets), bytes; None when there is none or it cannot be read."""
    if resource is None:
        return None
    try:
        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
    except (OSError, ValueError, AttributeError):
        return None
    return None if soft == resource.RLIM_INFINITY or soft < 0 else int(soft)


__all__ = ["address_space_limit", "available_bytes", "release_free_memory"]
