"""The incremental key and the state file that decide whether an output is up to date.

Key
---
``asset_key(source, deps, options)`` is the SHA-256 over, in this order: a format tag, the
lopcook version, the resolved cook options (``config.resolve``, canonical JSON), and for every
file the cook's depfile lists (sorted, de-duplicated) its path relative to the source's
directory and the SHA-256 of its content, or a marker when it does not exist (the OBJ importer
lists a missing .mtl or texture: its appearance must re-cook). So a key changes exactly when an
input's content, the set of inputs, an option or the lopcook version changes; a ``touch`` that
does not change a file's bytes does not re-cook (ninja, which compares times, would). Paths are
relative to the source, so a tree moved as a whole keeps its keys.

State file
----------
``OUTDIR/.lopcook-batch.json`` (JSON, written atomically with ``lopcook.atomic.write_atomic``)
maps each output's path relative to OUTDIR to what the last successful cook recorded: source,
dependencies (absolute), key, the output's SHA-256 and size. An output is up to date when its
entry exists for the same source, the output file exists with that size and SHA-256, and the key
recomputed from the current dependency contents equals the recorded one. Anything else (no
entry, output missing or changed, key different, unreadable state) re-cooks.
"""

from __future__ import annotations

import hashlib
import json
import os

from ..atomic import write_atomic
from ..version import __version__
from . import STATE_FILE

KEY_FORMAT = "lopcook-batch-key/1"
STATE_FORMAT = "lopcook-batch-state/1"
_CHUNK = 1 << 20


def file_sha256(path: str) -> str | None:
    """Hex SHA-256 of a file's bytes, None when it cannot be read (missing, a directory, no
    permission): such a dependency counts as absent, so the asset re-cooks and the cook reports it."""
    h = hashlib.sha256()
    try:
        with open(path, "rb") as fh:
            while chunk := fh.read(_CHUNK):
                h.update(chunk)
    except OSError:
        return None
    return h.hexdigest()


def parse_depfile(text: str) -> tuple[str, list[str]]:
    """``(target, dependencies)`` of the first rule of a Make-style depfile.

    The inverse of ``lopcook.depfile.format_depfile``'s escaping: backslash-newline continues a
    line; ``2N+1`` backslashes before a space or tab are ``N`` backslashes and that blank (``2N``:
    ``N`` backslashes, then the blank separates); ``$$`` is ``$``; ``N+1`` backslashes before
    ``#`` or ``:`` are ``N`` backslashes and that character; other backslashes are literal. The
    target ends at the first unescaped ``:``; the rule ends at the first unescaped newline (the
    phony rules after it are ignored). Raises ``ValueError`` when there is no ``target:``.
    """
    words: list[str] = []
    cur: list[str] = []
    have = False
    target: str | None = None

    def flush() -> None:
        nonlocal cur, have
        if have:
            words.append("".join(cur))
        cur, have = [], False

    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if c == "\\":
            piece, has, i, ends = _backslashes(text, i)
            cur.append(piece)
            have = have or has
            if ends:
                flush()
            continue
        if c == "$" and text[i + 1:i + 2] == "$":
            cur.append("$")
            have = True
            i += 2
            continue
        if c == ":" and target is None:
            flush()
            target = " ".join(words)
            words = []
            i += 1
            continue
        if c in " \t":
            flush()
            i += 1
            continue
        if c in "\r\n":
            flush()
            if target is not None or words:
                break
            i += 1
            continue
        cur.append(c)
        have = True
        i += 1
    flush()
    if target is None:
        raise ValueError("not a depfile: no 'target:'")
    return target, words


def _backslashes(text: str, i: int) -> tuple[str, bool, int, bool]:
    """The run of backslashes at ``text[i]`` and what it escapes (``parse_depfile``'s rules):
    ``(text it adds to the word, whether it makes a word, index after it, whether the word ends)``."""
    n = len(text)
    j = i
    while j < n and text[j] == "\\":
        j += 1
    k = j - i
    nxt = text[j] if j < n else ""
    if nxt in (" ", "\t") and nxt:  # 2N+1: N backslashes and the blank; 2N: N backslashes, then a separator
        return "\\" * (k // 2) + (nxt if k % 2 else ""), k >= 2 or k % 2 == 1, j + 1 if k % 2 else j, not k % 2
    if nxt == "\n" or (nxt == "\r" and text[j + 1:j + 2] == "\n"):  # a line continuation
        return "\\" * (k - 1) if k > 1 else "", k > 1, j + (2 if nxt == "\r" else 1), True
    if nxt in ("#", ":") and nxt:
        return "\\" * (k - 1) + nxt, True, j + 1, False
    return "\\" * k, True, j, False


def read_depfile(path: str) -> list[str]:
    """The dependencies of a depfile written by ``lopcook cook --depfile``."""
    with open(path, encoding="utf-8", errors="surrogateescape") as fh:
        return parse_depfile(fh.read())[1]


def asset_key(source: str, deps, options: dict, version: str = __version__) -> str:
    """Hex SHA-256 key of one asset (module doc). ``deps`` are absolute paths; ``options`` is
    ``config.resolve``'s dict."""
    base = os.path.dirname(os.path.abspath(source))
    h = hashlib.sha256()
    header = {"format": KEY_FORMAT, "lopcook": version, "options": options}
    h.update(json.dumps(header, sort_keys=True, separators=(",", ":")).encode())
    for dep in sorted(set(os.path.abspath(d) for d in deps)):
        digest = file_sha256(dep)
        rel = os.path.relpath(dep, base).replace(os.sep, "/")
        h.update(b"\0dep\0" + rel.encode("utf-8", "surrogateescape") + b"\0"
                 + (digest.encode() if digest else b"absent"))
    return h.hexdigest()


def options_digest(options: dict) -> str:
    return hashlib.sha256(json.dumps(options, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


class State:
    """``OUTDIR/.lopcook-batch.json``: entries keyed by output path relative to OUTDIR."""

    def __init__(self, outdir: str, entries: dict | None = None) -> None:
        self.outdir = os.path.abspath(outdir)
        self.path = os.path.join(self.outdir, STATE_FILE)
        self.entries: dict[str, dict] = dict(entries or {})

    @classmethod
    def load(cls, outdir: str) -> State:
        """The recorded state; empty when the file is missing or unreadable (everything re-cooks)."""
        state = cls(outdir)
        try:
            with open(state.path, encoding="utf-8") as fh:
                data = json.load(fh)
            if data.get("format") == STATE_FORMAT and isinstance(data.get("outputs"), dict):
                state.entries = data["outputs"]
        except (OSError, ValueError, AttributeError):
            pass
        return state

    def rel(self, output: str) -> str:
        return os.path.relpath(output, self.outdir).replace(os.sep, "/")

    def up_to_date(self, source: str, output: str, options: dict) -> bool:
        """Whether ``output`` is current for ``source`` cooked with ``options`` (module doc)."""
        e = self.entries.get(self.rel(output))
        if not e or e.get("source") != source or not e.get("key"):
            return False
        try:
            if os.path.getsize(output) != e.get("bytes"):
                return False
        except OSError:
            return False
        if file_sha256(output) != e.get("output_sha256"):
            return False
        return asset_key(source, e.get("deps") or [source], options) == e["key"]

    def record(self, output: str, entry: dict) -> None:
        self.entries[self.rel(output)] = entry

    def forget(self, output: str) -> None:
        self.entries.pop(self.rel(output), None)

    def save(self) -> None:
        os.makedirs(self.outdir, exist_ok=True)
        data = {"format": STATE_FORMAT, "lopcook": __version__,
                "outputs": {k: self.entries[k] for k in sorted(self.entries)}}
        write_atomic(self.path, (json.dumps(data, indent=1, sort_keys=True) + "\n").encode())


__all__ = ["asset_key", "file_sha256", "parse_depfile", "read_depfile", "State", "options_digest"]
