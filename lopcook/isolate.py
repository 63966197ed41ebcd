"""Run a simplification backend in a forked child process: its memory goes when the child exits,
and a crash in native code becomes an error the LOD chain falls back from.

Why: a native simplifier's peak memory, and memory some libraries keep after they return (global
containers keep their capacity until the process ends), would stack in the parent with everything
that follows (docs/lod.md has the measured sizes). In a child it is returned to the system the
moment the result is back. The child shares the parent's pages (copy on write), so the system's
memory at any time is the parent's plus the child's private pages: the peak is not hidden, only
no longer added to what comes after.

``start(fn, *args)`` forks the same way but returns at once: the child computes while the parent
goes on, and ``Child.result()`` collects the value. ``fork_map(fn, items)`` uses it to spread
independent pieces of work over two cores. Both give exactly the in-process results.

``call(fn, *args)`` forks (Linux only; elsewhere, and for inputs under ``MIN_FACES`` faces, where
a fork and the pickling cost more than they save, the call runs in-process), runs ``fn(*args)`` in
the child, sends the result (or the exception) back with pickle, and returns it (or raises it): it
is ``begin(...).result()``.
A child that dies without answering (a segmentation fault in a backend) raises ``ChildFailed``.
"""

from __future__ import annotations

import faulthandler
import multiprocessing as mp
import os
import pickle
import signal
import struct
import sys
import tempfile

from .memory import release_free_memory

#: inputs with at least this many faces are simplified in a child process
MIN_FACES = 200_000


class ChildFailed(RuntimeError):
    """The child process ended without a result (killed by a signal or exited abnormally)."""


def _quiet_child() -> None:
    """In the child: no faulthandler dump and no native chatter on stderr (a crash is reported by
    the parent as one ``ChildFailed`` message, which the LOD chain records as a note)."""
    faulthandler.disable()
    try:
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, 2)
        os.close(null)
    except OSError:
        pass


def _available() -> bool:
    """Linux only: on macOS a fork after the Objective-C runtime started (pymeshlab's Qt) may abort
    the child, which would turn every large simplification into a fallback."""
    return hasattr(os, "fork") and sys.platform.startswith("linux")


def _serve(fn, args, kwargs, w: int) -> None:
    """In the child: ``fn(*args, **kwargs)``, its value or exception pickled to ``w``; never returns."""
    code = 0
    _quiet_child()
    try:
        try:
            payload = pickle.dumps((True, fn(*args, **kwargs)), protocol=pickle.HIGHEST_PROTOCOL)
        except BaseException as exc:  # noqa: BLE001 - every failure goes back to the parent
            try:
                payload = pickle.dumps((False, exc), protocol=pickle.HIGHEST_PROTOCOL)
            except Exception:  # noqa: BLE001 - an exception that does not pickle
                payload = pickle.dumps((False, RuntimeError(f"{type(exc).__name__}: {exc}")))
        for part in (struct.pack("<Q", len(payload)), payload):  # no copy of the payload
            view = memoryview(part)
            while view:
                view = view[os.write(w, view):]
    except BaseException:  # noqa: BLE001
        code = 1
    finally:
        os._exit(code)


def _unpack(head: bytes, data: bytes, status: int, what: str):
    if len(head) != 8 or len(data) != struct.unpack("<Q", head)[0]:
        why = (f"killed by signal {os.WTERMSIG(status)}" if os.WIFSIGNALED(status)
               else f"exit status {os.WEXITSTATUS(status)}")
        raise ChildFailed(f"the {what} process ended without a result ({why})")
    ok, value = pickle.loads(data)
    if ok:
        return value
    raise value


class Child:
    """A computation started by ``start``: ``result()`` returns its value (or raises its
    exception, or ``ChildFailed``); ``cancel()`` stops it. In-process (``start`` without a fork),
    the value is computed by the first ``result()``."""

    def __init__(self, fn, args, kwargs, fork: bool, what: str = "worker"):
        self._fn, self._args, self._kwargs, self._what = fn, args, kwargs, what
        self._pid = self._fd = None
        self._done, self._value = False, None
        if fork:
            release_free_memory()
            # the result goes to an unlinked file, not a pipe: the child writes it and exits at
            # once, its memory freed, however long the parent takes to ask for it
            with tempfile.TemporaryFile() as spool:
                fd = os.dup(spool.fileno())
            pid = os.fork()
            if pid == 0:
                _serve(fn, args, kwargs, fd)
            self._pid, self._fd = pid, fd
            self._fn = self._args = self._kwargs = None  # the child has them
        self._forked = fork

    @property
    def forked(self) -> bool:
        """Whether the computation runs (or ran) in a child process."""
        return self._forked

    def result(self):
        if not self._done:
            if self._pid is not None:
                pid, fd = self._pid, self._fd
                self._pid = self._fd = None
                try:
                    _, status = os.waitpid(pid, 0)
                    os.lseek(fd, 0, os.SEEK_SET)
                    head = _read_exact(fd, 8)
                    data = _read_exact(fd, struct.unpack("<Q", head)[0]) if len(head) == 8 else b""
                finally:
                    os.close(fd)
                self._value = _unpack(head, data, status, self._what)
            else:
                self._value = self._fn(*self._args, **self._kwargs)
                self._fn = self._args = self._kwargs = None
            self._done = True
        return self._value

    def cancel(self) -> None:
        """Stop the child (if it still runs) and drop its result."""
        if self._pid is not None:
            try:
                os.kill(self._pid, signal.SIGKILL)
            except OSError:
                pass
            os.waitpid(self._pid, 0)
            os.close(self._fd)
            self._pid = self._fd = None
        self._done, self._value = True, None
        self._fn = self._args = self._kwargs = None


def start(fn, *args, fork: bool = True, **kwargs) -> Child:
    """``fn(*args, **kwargs)`` started in a forked child (when ``fork`` and the platform allows;
    else it runs in-process at ``result()``). The child shares the parent's pages copy on write;
    the arguments must not change in the parent before ``result()`` matters (the child sees
    them as they were at the fork). Results and exceptions must pickle."""
    return Child(fn, args, kwargs, bool(fork) and _available())


def begin(fn, *args, faces: int | None = None, **kwargs) -> Child:
    """``call`` started: forked when ``call`` would fork (``faces`` at least ``MIN_FACES``), else
    computed in-process at ``result()``; ``Child.forked`` says which. The caller may work while
    the child runs; ``result()`` returns or raises as ``call`` does."""
    return Child(fn, args, kwargs, faces is not None and faces >= MIN_FACES and _available(), "backend")


def cpus() -> int:
    """CPUs this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def fork_map(fn, items: list, weights: list | None = None, workers: int | None = None) -> list:
    """``[fn(x) for x in items]``, the items split between this process and one forked child when
    there are two or more items and ``workers`` (default: ``cpus()``, at most 2) is 2 or more. The
    split balances ``weights`` (default 1 each): the child takes a contiguous run of items from
    the front, the parent the rest. Same values as the serial list, in item order."""
    n = len(items)
    k = min(2, cpus()) if workers is None else int(workers)
    if n < 2 or k < 2 or not _available():
        return [fn(x) for x in items]
    w = [1.0] * n if weights is None else [float(x) for x in weights]
    total, acc, cut = sum(w), 0.0, 1
    for i in range(n - 1):  # the smallest front run holding at least half the weight, leaving one item
        acc += w[i]
        cut = i + 1
        if acc >= total / 2:
            break
    front = start(_map, fn, items[:cut])
    try:
        back = [fn(x) for x in items[cut:]]
    except BaseException:
        front.cancel()
        raise
    return front.result() + back


def _map(fn, items):
    return [fn(x) for x in items]


def _read_exact(fd: int, n: int) -> bytes:
    chunks, got = [], 0
    while got < n:
        b = os.read(fd, min(n - got, 1 << 24))
        if not b:
            break
        chunks.append(b)
        got += len(b)
    return b"".join(chunks)


def call(fn, *args, faces: int | None = None, **kwargs):
    """``fn(*args, **kwargs)`` in a forked child when ``faces`` is at least ``MIN_FACES`` (else, or
    without ``fork``, in this process). Results and exceptions must pickle."""
    return begin(fn, *args, faces=faces, **kwargs).result()


def _fresh_child(conn, fn, args, kwargs) -> None:
    """In the spawned interpreter: ``fn(*args, **kwargs)``, the result or exception sent on ``conn``."""
    try:
        payload = (True, fn(*args, **kwargs))
    except BaseException as exc:  # noqa: BLE001 - every failure goes back to the parent
        payload = (False, exc)
    try:
        conn.send(payload)
    except Exception as exc:  # noqa: BLE001 - an exception that does not pickle
        conn.send((False, RuntimeError(f"{type(exc).__name__}: {exc}")))
    conn.close()


def call_fresh(fn, *args, **kwargs):
    """``fn(*args, **kwargs)`` in a freshly started interpreter (multiprocessing "spawn"), for
    libraries whose thread pools do not survive a fork once started (USD's TBB: a forked child
    waits forever for workers that were not copied). ``fn`` must be importable by name; results
    and exceptions must pickle. A child that dies without answering raises ``ChildFailed``, with
    the signal or exit status. Costs an interpreter start and the imports."""
    ctx = mp.get_context("spawn")
    recv, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_fresh_child, args=(send, fn, args, kwargs), daemon=True)
    proc.start()
    send.close()
    try:
        try:
            ok, value = recv.recv()
        except EOFError:
            ok, value = None, None
    finally:
        recv.close()
        proc.join()
    if ok is None:
        code = proc.exitcode
        why = f"killed by signal {-code}" if code is not None and code < 0 else f"exit status {code}"
        raise ChildFailed(f"the backend process ended without a result ({why})")
    if ok:
        return value
    raise value


__all__ = ["MIN_FACES", "ChildFailed", "Child", "begin", "call", "call_fresh", "start", "fork_map", "cpus"]
