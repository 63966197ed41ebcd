"""A memo of attribute codes by content, for searches that cook one scene many times.

Inside ``with code_memo():`` the record encoder (``lopcook.lop.record.record_codes``) keeps the
codes it computes, keyed by (attribute, bits, dtype, shape, BLAKE2b of the bytes), at most
``max_bytes`` of codes, least recently used dropped first. The codes are the same with or without
it; each thread has its own memo, and a nested ``code_memo`` uses the outer one.
"""

from __future__ import annotations

import functools
import hashlib
import threading

import numpy as np

#: the most bytes of codes a ``code_memo`` holds
CODE_MEMO_BYTES = 24 << 20


def _size(value) -> int:
    return sum(v.nbytes for v in value if isinstance(v, np.ndarray))


class _CodeMemo:
    def __init__(self, max_bytes: int):
        self.max_bytes, self.held, self.entries = int(max_bytes), 0, {}

    @staticmethod
    def key(name: str, bits: int, a) -> tuple:
        arr = np.ascontiguousarray(a)
        return (name, int(bits), arr.dtype.str, arr.shape, hashlib.blake2b(memoryview(arr).cast("B"),
                                                                         digest_size=20).digest())

    def get(self, key):
        got = self.entries.pop(key, None)
        if got is not None:
            self.entries[key] = got  # most recently used last
        return got

    def put(self, key, value) -> None:
        size = _size(value)
        if size > self.max_bytes:
            return
        self.entries[key] = value
        self.held += size
        while self.held > self.max_bytes:
            self.held -= _size(self.entries.pop(next(iter(self.entries))))


class _Active(threading.local):
    memo = None  # this thread's open ``_CodeMemo``, or None


_ACTIVE = _Active()


class code_memo:
    """Context manager: inside it, attribute codes are kept by content (module doc)."""

    def __init__(self, max_bytes: int = CODE_MEMO_BYTES):
        self.max_bytes = int(max_bytes)
        self._opened = False

    def __enter__(self):
        if _ACTIVE.memo is None:
            _ACTIVE.memo = _CodeMemo(self.max_bytes)
            self._opened = True
        return self

    def __exit__(self, *exc) -> None:
        if self._opened:
            _ACTIVE.memo = None
            self._opened = False


def with_code_memo(f):
    """Decorator: ``f`` runs inside a ``code_memo`` (a search that cooks one scene many times)."""

    @functools.wraps(f)
    def wrapped(*args, **kwargs):
        with code_memo():
            return f(*args, **kwargs)

    return wrapped


def memoised(name: str, bits: int, a, encode):
    """``encode()`` (a tuple of arrays and values), through the active ``code_memo`` if any."""
    memo = _ACTIVE.memo
    if memo is None:
        return encode()
    key = memo.key(name, bits, a)
    got = memo.get(key)
    if got is None:
        got = encode()
        memo.put(key, got)
    return got
