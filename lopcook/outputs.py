"""Output paths checked before any work: every file a command will write is named, writable, not
one of its inputs, and carries the extension of what is written.

``check_output`` is called by the CLI before a cook, decode or report starts, so a bad ``-o``
is one usage error (exit 2) in milliseconds instead of an internal error after the whole cook,
and ``check_not_input`` again once the source's dependencies (textures, .mtl, .bin, referenced
USD layers) are known, before anything is written. Every file is then written atomically
(``lopcook.atomic``): a failed run leaves no file and an older output untouched.
"""

from __future__ import annotations

import os
from pathlib import Path

from .atomic import name_max
from .errors import LopcookError
from .ingest import SOURCE_EXTENSIONS  # noqa: F401 (re-exported)

# SOURCE_EXTENSIONS: the extensions of the sources lopcook reads, sidecars (.mtl, .bin) included
# (lopcook.ingest.FORMATS): a container or depfile must never be named like one


def _same(a: str, b: str) -> bool:
    """True when paths ``a`` and ``b`` name one file (same inode, or the same resolved path)."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.realpath(a) == os.path.realpath(b)


#: extensions of files lopcook writes besides containers: never a container's name either
OTHER_OUTPUTS = (".png", ".jpg", ".jpeg", ".html", ".htm", ".json", ".d")


def check_output(path: str, flag: str, *, extensions: tuple[str, ...], what: str,
                 inputs: tuple[str, ...] = (), forbidden: tuple[str, ...] = (), required: bool = True) -> str:
    """Refuse (LopcookError "usage", exit 2) an output path that cannot or must not be written:
    empty, a directory (or ending in a separator), in a directory that does not exist or is not
    writable, a name longer than the file system allows, not a regular file where it exists, one
    of ``inputs``, ending in one of ``forbidden``, or (``required``) without one of ``extensions``
    (the first is the one to use). Returns ``path``."""
    if not path:
        raise LopcookError("usage", None, f"{flag} is empty", hint=f"name the file, e.g. {flag} out{extensions[0]}")
    if path.endswith(("/", os.sep)) or os.path.isdir(path):
        raise LopcookError("usage", path or None, f"{flag} is a directory, not a file",
                           hint=f"name the file, e.g. {flag} out{extensions[0]}")
    if path.lower().endswith(forbidden) and not path.lower().endswith(extensions):
        raise LopcookError("usage", path, f"{flag} ends in {Path(path).suffix!r}, but {what} is written there",
                           hint=f"name it {Path(path).stem}{extensions[0]}")
    if required and not path.lower().endswith(extensions):
        raise LopcookError("usage", path, f"{flag} must name a{'n' if extensions[0][1] in 'aeiou' else ''} "
                           f"{'/'.join(extensions)} file ({what} is written there)",
                           hint=f"e.g. {flag} {Path(path).stem or 'out'}{extensions[0]}")
    parent = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(parent):
        raise LopcookError("usage", path, f"directory {os.path.dirname(path) or '.'!r} does not exist",
                           hint="create it first")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise LopcookError("usage", path, f"directory {os.path.dirname(path) or '.'!r} is not writable",
                           hint="write somewhere you may create files, or fix the directory's permissions")
    limit = name_max(parent)
    length = len(os.fsencode(os.path.basename(path)))
    if length > limit:
        raise LopcookError("usage", path, f"{flag}'s file name is {length} bytes long; this file system allows "
                           f"{limit}", hint="choose a shorter name")
    if os.path.lexists(path) and not os.path.isfile(path):
        raise LopcookError("usage", path, f"{flag} exists and is not a regular file")
    if os.path.isfile(path) and not os.access(path, os.W_OK):
        raise LopcookError("usage", path, f"{flag} exists and is not writable",
                           hint="make it writable, or choose another output path")
    check_not_input(path, flag, inputs)
    return path


def check_not_input(path: str, flag: str, inputs) -> None:
    """Refuse an output that is one of ``inputs`` (the source, the container read, or any file
    the source depends on): lopcook never overwrites what it reads."""
    for src in inputs:
        if src and os.path.exists(src) and _same(path, src):
            raise LopcookError("usage", path, f"{flag} is an input of this run ({src}); lopcook never overwrites "
                               "its inputs", hint="write the output elsewhere")


def check_distinct(*named: tuple[str, str | None]) -> None:
    """Refuse two outputs of one run that name the same file (e.g. ``--depfile`` = ``-o``)."""
    seen: list[tuple[str, str]] = []
    for flag, path in named:
        if path is None:
            continue
        for other_flag, other in seen:
            if os.path.abspath(path) == os.path.abspath(other) or (os.path.exists(path) and _same(path, other)):
                raise LopcookError("usage", path, f"{flag} and {other_flag} name the same file")
        seen.append((flag, path))


__all__ = ["SOURCE_EXTENSIONS", "OTHER_OUTPUTS", "check_output", "check_not_input", "check_distinct"]
