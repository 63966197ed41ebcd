"""Batch SOURCES -> the assets to cook, each with its root-relative path and output path.

A SOURCE is one of:

* a **directory**: searched recursively for files with a supported extension (those of
  ``lopcook.ingest.FORMATS``, any case); entries whose name starts with ``.`` and the output
  directory itself are skipped. The asset root is the directory.
* a **source file** (supported extension): the asset root is its directory.
* a **manifest**: any other file, read as UTF-8 text with one path per line (blank lines and
  lines starting with ``#`` ignored), each relative to the manifest's directory (or absolute) and
  itself a directory or a source file as above. The asset root is the manifest's directory; an
  entry outside it is an error.

Output paths mirror the tree: ``ROOT/props/chair.glb`` -> ``OUTDIR/props/chair.lop`` (the source
suffix replaced by ``.lop``). Two sources that would write the same output (``chair.glb`` and
``chair.obj`` side by side, or two roots holding ``chair.glb``) are a ``LopcookError`` naming
both; exclude one in ``lopcook.toml``. Config excludes and rules match the root-relative path.
Every path handed on is absolute, so workers may run in any directory (or on another machine
with the same shared filesystem mounted at the same path).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from ..errors import LopcookError
from ..ingest import EXTENSIONS
from .config import BatchConfig

#: the extensions ``lopcook.ingest.load`` accepts (those of ``lopcook.ingest.FORMATS``)
SOURCE_EXTENSIONS = tuple(EXTENSIONS)
#: the same, as help and messages list them
_LISTED = " ".join(SOURCE_EXTENSIONS)


@dataclass(frozen=True)
class Asset:
    """One source file of a batch. ``source`` and ``output`` are absolute; ``relpath`` is the
    source relative to its root with ``/`` separators (what config globs match)."""

    source: str
    relpath: str
    output: str


def is_source_file(path: str) -> bool:
    return os.path.splitext(path)[1].lower() in SOURCE_EXTENSIONS


def _walk(root: str, skip: set[str]):
    """Source files under ``root`` (absolute), sorted, hidden entries and ``skip`` dirs pruned."""
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith(".")
                             and os.path.realpath(os.path.join(dirpath, d)) not in skip)
        for name in sorted(filenames):
            if not name.startswith(".") and is_source_file(name):
                yield os.path.join(dirpath, name)


def _read_manifest(path: str) -> list[str]:
    try:
        with open(path, encoding="utf-8") as fh:
            text = fh.read()
    except UnicodeDecodeError:
        raise LopcookError("usage", path, f"not a supported source file ({_LISTED}) and not a manifest (UTF-8 "
                           "text, one path per line)") from None
    except OSError as exc:
        raise LopcookError("usage", path, f"cannot read the manifest: {exc.strerror}") from None
    base = os.path.dirname(path)
    entries = []
    for line in text.splitlines():
        line = line.strip()
        if line and not line.startswith("#"):
            entries.append(os.path.normpath(os.path.join(base, line)))
    return entries


def discover(sources, outdir: str, config: BatchConfig | None = None) -> list[Asset]:
    """The assets of ``sources`` (module doc), sorted by output path; excludes applied.

    Raises ``LopcookError`` for a missing SOURCE or manifest entry, a manifest entry outside the
    manifest's directory, or two sources mapping to one output.
    """
    config = config or BatchConfig()
    outdir = os.path.abspath(outdir)
    skip = {os.path.realpath(outdir)}
    found: list[tuple[str, str]] = []  # (absolute source, root)

    def add(path: str, root: str, origin: str | None) -> None:
        if os.path.isdir(path):
            found.extend((f, root) for f in _walk(path, skip))
        elif os.path.isfile(path):
            if not is_source_file(path):
                raise LopcookError("usage", origin or path, f"{path}: not a supported source file ({_LISTED})")
            found.append((path, root))
        else:
            raise LopcookError("usage", origin, f"{path}: no such file or directory" if origin else
                               "no such file or directory")

    for src in sources:
        src = os.path.abspath(os.fspath(src))
        if os.path.isdir(src):
            add(src, src, None)
        elif os.path.isfile(src) and is_source_file(src):
            add(src, os.path.dirname(src), None)
        elif os.path.isfile(src):
            base = os.path.dirname(src)
            for entry in _read_manifest(src):
                if os.path.relpath(entry, base).split(os.sep)[0] == os.pardir:
                    raise LopcookError("usage", src, f"entry {entry} is outside the manifest's directory {base}",
                                       hint="move the manifest up, or give that tree as its own SOURCE")
                add(entry, base, src)
        else:
            raise LopcookError("usage", src, "no such file or directory")

    by_output: dict[str, Asset] = {}
    seen: set[str] = set()
    for path, root in found:
        if path in seen:
            continue
        seen.add(path)
        rel = os.path.relpath(path, root).replace(os.sep, "/")
        if config.excluded(rel):
            continue
        out = os.path.join(outdir, os.path.splitext(rel)[0].replace("/", os.sep) + ".lop")
        other = by_output.get(out)
        if other is not None:
            raise LopcookError("usage", path, f"writes the same output {out} as {other.source}",
                               hint="exclude one of them in lopcook.toml (exclude = [\"...\"]) or move it")
        by_output[out] = Asset(source=path, relpath=rel, output=out)
    return [by_output[k] for k in sorted(by_output)]


__all__ = ["Asset", "discover", "is_source_file", "SOURCE_EXTENSIONS"]
