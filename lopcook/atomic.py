"""Atomic file writes: every file lopcook produces appears whole or not at all."""

from __future__ import annotations

import os
import secrets
from pathlib import Path


def write_atomic(path, data: bytes) -> Path:
    """Write ``data`` to a temporary file beside ``path``, then ``os.replace`` it into place.

    The temporary file (``.<name>.<random>.tmp``, or ``.lopcook.<random>.tmp`` where that would be
    longer than the directory allows a name to be) is created with mode 0o666 minus the umask (like
    ``open(path, "wb")``), flushed to disk, and removed again if anything fails, so ``path`` either
    keeps its old content or gets the complete new one. The parent directory must exist.
    Returns ``Path(path)``.
    """
    path = Path(path)
    tmp = path.with_name(_temp_name(path))
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    return path


def name_max(directory) -> int:
    """The longest file name (bytes) ``directory``'s file system allows (255 where it cannot say)."""
    try:
        return int(os.pathconf(os.fspath(directory) or ".", "PC_NAME_MAX"))
    except (OSError, ValueError, AttributeError):
        return 255


def _temp_name(path: Path) -> str:
    token = secrets.token_hex(6)
    name = f".{path.name}.{token}.tmp"
    if len(os.fsencode(name)) > name_max(path.parent):
        name = f".lopcook.{token}.tmp"
    return name
