"""Make-style dependency files (``--depfile``) and the dependency paths importers record.

A build system (GNU make with ``-include OUT.d``, ninja with ``depfile = OUT.d``) reruns
``lopcook cook SOURCE -o OUT.lop --depfile OUT.d`` when any file the cook read changes. The
importers list those files in ``Scene.dependencies`` (see ``lopcook.types.Scene``);
``write_depfile`` writes them as one Make rule::

    out/helmet.lop: assets/DamagedHelmet/DamagedHelmet.gltf \\
      assets/DamagedHelmet/DamagedHelmet.bin \\
      assets/DamagedHelmet/Default_albedo.jpg

Path spelling (``DependencyList``)
----------------------------------
Paths are written as the user would write them in a Makefile: when the source path is relative,
a dependency is the source's directory joined with the reference (relative to the current working
directory) and normalised with ``os.path.normpath``; when the source path is absolute, every
dependency is absolute. A reference that is itself absolute (``mtllib /lib/a.mtl``, a USD
``@/abs/layer.usda@``) stays absolute. No symlinks are resolved.

Escaping (``escape``)
---------------------
What GNU make and ninja (>= 1.10 depfile parser; GCC/Clang ``-MD`` conventions) both read back
unchanged: a space or tab becomes backslash + the character (backslashes directly before it are
doubled), ``$`` becomes ``$$``, ``#`` becomes ``\\#`` and ``:`` becomes ``\\:``. A newline (or a
NUL) cannot be written in a Make rule: ``escape`` raises ``ValueError`` for it. Ninja cannot
represent some other characters in depfiles (e.g. ``&``, ``'``, ``"``, ``;``, ``*``, ``|``); they
are written as is (fine for make).
"""

from __future__ import annotations

import os
from collections.abc import Iterable

from .atomic import write_atomic

__all__ = ["write_depfile", "format_depfile", "escape", "DependencyList"]


class DependencyList:
    """Ordered, de-duplicated dependency paths of one source file, spelt as documented above.

    The source (``os.path.normpath`` of the path as given) is always the first entry.
    """

    def __init__(self, source: str | os.PathLike) -> None:
        self.source = os.fspath(source)
        self._absolute = os.path.isabs(self.source)
        self._dir = os.path.dirname(self.source)
        self._abs_dir = os.path.dirname(os.path.abspath(self.source))
        self._paths: dict[str, None] = {os.path.normpath(self.source): None}

    def add(self, reference: str) -> str:
        """Add a file named relative to the source's directory (or absolute); return its spelling."""
        if self._absolute:
            path = os.path.normpath(os.path.join(self._abs_dir, reference))
        else:
            path = os.path.normpath(os.path.join(self._dir, reference))
        self._paths.setdefault(path, None)
        return path

    def add_path(self, path: str) -> str:
        """Add a path already spelt from the source's own path (``os.path.join(os.path.dirname(
        source), ...)``): relative to the current directory or absolute. Return its spelling."""
        path = os.path.normpath(os.path.abspath(path) if self._absolute else path)
        self._paths.setdefault(path, None)
        return path

    def add_resolved(self, absolute: str, keep_absolute: bool = False) -> str:
        """Add a file known by its absolute path (e.g. a USD layer's ``realPath``).

        For a relative source it is spelt relative to the source's directory, joined with that
        directory (as ``add``), unless ``keep_absolute`` (the reference was written absolute).
        """
        absolute = os.path.normpath(absolute)
        if self._absolute or keep_absolute or not os.path.isabs(absolute):
            return self.add(absolute)
        return self.add(os.path.relpath(absolute, self._abs_dir))

    def paths(self) -> tuple[str, ...]:
        return tuple(self._paths)


def escape(path: str) -> str:
    """One path as a Make/ninja depfile word (see the module doc)."""
    if "\n" in path or "\r" in path or "\0" in path:
        raise ValueError(f"cannot write a path containing a newline or NUL in a depfile: {path!r}")
    out: list[str] = []
    backslashes = 0
    for ch in path:
        if ch == "\\":
            backslashes += 1
            out.append(ch)
            continue
        if ch in " \t":
            out.append("\\" * backslashes + "\\" + ch)  # 2N+1 backslashes: N literal ones + blank
        elif ch == "$":
            out.append("$$")
        elif ch in "#:":
            out.append("\\" + ch)
        else:
            out.append(ch)
        backslashes = 0
    return "".join(out)


def format_depfile(target: str, dependencies: Iterable[str], phony: bool = False) -> str:
    """The depfile text: ``target: dep1 \\`` then one dependency per line, duplicates dropped.

    ``phony`` adds an empty rule per dependency (like ``gcc -MP``) so that make does not stop with
    "No rule to make target" when a listed file is deleted or was missing (ninja >= 1.10 accepts
    such rules too).
    """
    deps = [escape(d) for d in dict.fromkeys(os.fspath(d) for d in dependencies)]
    head = escape(os.fspath(target)) + ":"
    if not deps:
        text = head + "\n"
    else:
        text = head + " " + " \\\n  ".join(deps) + "\n"
    if phony:
        text += "".join(f"\n{d}:\n" for d in deps)
    return text


def write_depfile(path: str | os.PathLike, target: str | os.PathLike, dependencies: Iterable[str],
                  *, phony: bool = False) -> None:
    """Write ``target``'s Make rule (``format_depfile``) to ``path`` atomically.

    The text goes to a temporary file in the same directory (created with the process umask), is
    flushed to disk, then renamed over ``path`` with ``os.replace``: readers see the old file or
    the complete new one, never a partial one. Same arguments, same bytes (UTF-8, ``\\n`` line ends).
    """
    data = format_depfile(os.fspath(target), dependencies, phony=phony).encode("utf-8", "surrogateescape")
    write_atomic(path, data)
