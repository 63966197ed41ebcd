"""Run a simplification backend in a forked child process: its memory goes when the child exits,
and a crash in native code becomes an error the LOD chain falls back from.

Why: a native simplifier's peak memory, and memory some libraries keep after they return (global
containers keep their capacity until the process ends), would stack in the parent with everything
that follows (docs/lod.md has the measured sizes). In a child it is returned to the system the moment the result is back. The child shares the parent's pages
(copy on write), so the system's memory at any time is the parent's plus the child's private
pages: the peak is not hidden, only no longer added to what comes after.

``call(fn, *args)`` forks (Linux only; elsewhere, and for small inputs where the ~10 ms of a fork
and the pickling are not worth it, the call runs in-process), runs ``fn(*args)`` in the child,
sends the result (or the exception) back through a pipe with pickle, and returns it (or raises it).
A child that dies without answering (a segmentation fault in a backend) raises ``ChildFailed``.
"""

from __future__ import annotations

import os
import pickle
import struct
import sys

from .memory import release_free_memory

#: inputs with at least this many faces are simplified in a child process
MIN_FACES = 200_000


class ChildFailed(RuntimeError):
    """The child process ended without a result (killed by a signal or exited abnormally)."""


def _quiet_child() -> None:
    """In the child: no faulthandler dump and no native chatter on stderr (a crash is reported by
    the parent as one ``ChildFailed`` message, which the LOD chain records as a note)."""
    import faulthandler

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
    if faces is None or faces < MIN_FACES or not _available():
        return fn(*args, **kwargs)
    release_free_memory()
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # child: never returns
        os.close(r)
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
            view = memoryview(struct.pack("<Q", len(payload)) + payload)
            while view:
                view = view[os.write(w, view):]
        except BaseException:  # noqa: BLE001
            code = 1
        finally:
            os._exit(code)
    os.close(w)
    try:
        head = _read_exact(r, 8)
        data = _read_exact(r, struct.unpack("<Q", head)[0]) if len(head) == 8 else b""
    finally:
        os.close(r)
        _, status = os.waitpid(pid, 0)
    if len(head) != 8 or len(data) != struct.unpack("<Q", head)[0]:
        why = (f"killed by signal {os.WTERMSIG(status)}" if os.WIFSIGNALED(status)
               else f"exit status {os.WEXITSTATUS(status)}")
        raise ChildFailed(f"the backend process ended without a result ({why})")
    ok, value = pickle.loads(data)
    if ok:
        return value
    raise value


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
    the signal or exit status. Costs an interpreter start and the imports (about a second)."""
    import multiprocessing as mp

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


__all__ = ["MIN_FACES", "ChildFailed", "call", "call_fresh"]
