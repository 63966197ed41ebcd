"""``lopcook.toml``: which cook options each asset of a batch gets (format in docs/batch.md).

::

    # options every asset gets (first), as on the lopcook cook command line
    options = ["--crease-angle", "45"]
    # sources to leave out (globs, matched like the rules' globs)
    exclude = ["**/_wip/**", "**/*_layer.usda"]

    [[rules]]
    glob = "props/**"
    options = ["--lods", "auto"]

    [[rules]]
    glob = "hero/**"
    options = "--target-psnr 40"        # a string is split as a POSIX shell would

An asset's options are the top-level ``options`` followed by those of every rule whose glob
matches, in file order; a flag given twice keeps the last value (argparse), so a later rule wins.

Globs are matched against the asset's path relative to its root (the directory SOURCE, or the
manifest's directory), with ``/`` separators: ``*`` and ``?`` stay within one path segment,
``**`` spans any number of segments (``props/**`` is everything under ``props/``; ``**/x.obj``
is ``x.obj`` at any depth), ``[abc]`` / ``[!abc]`` are character classes. A glob without ``/``
matches the file name at any depth (``*.obj`` = ``**/*.obj``).

The options are validated up front with ``lopcook cook``'s own parser: an unknown flag or bad
value, or one the batch sets itself (``-o``, ``--depfile``, ``--json``, a second SOURCE), is one
``LopcookError`` naming the file and the rule. ``resolve`` turns them into every cook option's
final value, which is what the incremental key hashes (``--lods=auto`` and ``--lods auto`` give
the same key; so do a default spelt out and left out).
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import shlex
import tomllib
from dataclasses import dataclass, field

from ..cli.parser import UsageExit, build_parser
from ..errors import LopcookError

#: Namespace entries of ``lopcook cook`` that are not cook options (the batch sets or ignores them)
_NOT_OPTIONS = ("command", "source", "output", "depfile", "json", "quiet", "debug")
_SENTINEL_SOURCE = "\0source"
_SENTINEL_OUTPUT = "\0output.lop"


def glob_regex(pattern: str) -> re.Pattern:
    """The compiled regular expression of one glob (semantics in the module doc)."""
    pat = pattern.strip().replace("\\", "/")
    if pat.startswith("./"):
        pat = pat[2:]
    if "/" not in pat:
        pat = "**/" + pat
    out, i, n = [], 0, len(pat)
    while i < n:
        c = pat[i]
        if pat.startswith("**/", i):
            out.append("(?:[^/]*/)*")
            i += 3
            continue
        if pat.startswith("**", i):
            out.append(".*")
            i += 2
            continue
        if c == "*":
            out.append("[^/]*")
        elif c == "?":
            out.append("[^/]")
        elif c == "[":
            j = pat.find("]", i + 2 if pat.startswith("[!", i) else i + 1)
            if j < 0:
                out.append(re.escape(c))
            else:
                body = pat[i + 1:j]
                neg = body.startswith("!")
                body = body[1:] if neg else body
                out.append("[" + ("^/" if neg else "") + body.replace("\\", "\\\\") + "]")
                i = j + 1
                continue
        else:
            out.append(re.escape(c))
        i += 1
    return re.compile("".join(out))


def glob_match(pattern: str, relpath: str) -> bool:
    """Whether ``relpath`` (``/``-separated, relative to the asset root) matches ``pattern``."""
    return glob_regex(pattern).fullmatch(relpath.replace(os.sep, "/")) is not None


@dataclass(frozen=True)
class Rule:
    glob: str
    options: tuple[str, ...]
    regex: re.Pattern = field(compare=False, repr=False)


@dataclass(frozen=True)
class BatchConfig:
    """A parsed ``lopcook.toml`` (``path`` None: no config file, every asset gets the defaults)."""

    path: str | None = None
    options: tuple[str, ...] = ()
    exclude: tuple[str, ...] = ()
    rules: tuple[Rule, ...] = ()

    def excluded(self, relpath: str) -> bool:
        return any(glob_match(g, relpath) for g in self.exclude)

    def options_for(self, relpath: str) -> tuple[str, ...]:
        """The cook flags of the asset at ``relpath``: top-level options, then each matching rule's."""
        rel = relpath.replace(os.sep, "/")
        opts = list(self.options)
        for rule in self.rules:
            if rule.regex.fullmatch(rel):
                opts.extend(rule.options)
        return tuple(opts)


def _option_list(value, where: str, path: str) -> tuple[str, ...]:
    if isinstance(value, str):
        try:
            return tuple(shlex.split(value))
        except ValueError as exc:
            raise LopcookError("usage", path, f"{where}: {exc}") from None
    if isinstance(value, list) and all(isinstance(v, (str, int, float)) and not isinstance(v, bool) for v in value):
        return tuple(str(v) for v in value)
    raise LopcookError("usage", path, f"{where}: expected a list of strings such as [\"--lods\", \"auto\"] or one "
                       f"string, got {value!r}")


def load_config(path: str | os.PathLike | None) -> BatchConfig:
    """Read and validate ``lopcook.toml`` (None: the empty config). Raises ``LopcookError``."""
    if path is None:
        return BatchConfig()
    path = os.fspath(path)
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except FileNotFoundError:
        raise LopcookError("usage", path, "config file not found") from None
    except OSError as exc:
        raise LopcookError("usage", path, f"cannot read the config file: {exc.strerror}") from None
    except tomllib.TOMLDecodeError as exc:
        raise LopcookError("usage", path, f"not valid TOML: {exc}", hint="see docs/batch.md for the format") from None
    unknown = sorted(set(data) - {"options", "exclude", "rules"})
    if unknown:
        raise LopcookError("usage", path, f"unknown key(s) {', '.join(unknown)}: expected options, exclude, [[rules]]",
                           hint="see docs/batch.md for the format")
    options = _option_list(data.get("options", []), "options", path)
    exclude = data.get("exclude", [])
    if not isinstance(exclude, list) or not all(isinstance(g, str) and g.strip() for g in exclude):
        raise LopcookError("usage", path, f"exclude: expected a list of glob strings, got {exclude!r}")
    rules_raw = data.get("rules", [])
    if not isinstance(rules_raw, list):
        raise LopcookError("usage", path, "rules: expected an array of tables ([[rules]] glob = ..., options = ...)")
    rules = []
    for i, r in enumerate(rules_raw, 1):
        where = f"rule {i}"
        if not isinstance(r, dict) or not isinstance(r.get("glob"), str) or not r["glob"].strip():
            raise LopcookError("usage", path, f"{where}: needs glob = \"PATTERN\" (e.g. \"props/**\")")
        extra = sorted(set(r) - {"glob", "options"})
        if extra:
            raise LopcookError("usage", path, f"{where} ({r['glob']}): unknown key(s) {', '.join(extra)}: expected "
                               "glob and options")
        opts = _option_list(r.get("options", []), f"{where} ({r['glob']}) options", path)
        rules.append(Rule(r["glob"], opts, glob_regex(r["glob"])))
    cfg = BatchConfig(path=path, options=options, exclude=tuple(exclude), rules=tuple(rules))
    check_options(cfg.options, f"{path}: options")
    for i, rule in enumerate(cfg.rules, 1):
        check_options(rule.options, f"{path}: rule {i} ({rule.glob})")
    return cfg


def _parse_cook(options) -> dict:
    """``lopcook cook``'s parser over ``options`` -> the Namespace as a dict; ``ValueError`` with
    argparse's message alone (``unrecognized arguments: --lodz 1/2``) when they do not parse."""
    try:
        with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):  # --help prints
            ns = build_parser().parse_args(["cook", _SENTINEL_SOURCE, "-o", _SENTINEL_OUTPUT, *options])
    except UsageExit as exc:
        raise ValueError(exc.message) from None
    except SystemExit:  # --help or --version among the options
        raise ValueError("--help and --version are not cook options") from None
    return vars(ns)


def check_options(options, where: str) -> None:
    """Raise ``LopcookError`` (usage) unless ``options`` are valid ``lopcook cook`` flags a batch may
    pass; the message quotes the options once (argparse's own text may already show them)."""
    try:
        ns = _parse_cook(options)
    except ValueError as exc:
        shown = " ".join(options)
        text = str(exc) if shown in str(exc) else f"{shown}: {exc}"
        raise LopcookError("usage", None, f"{where}: {text}", hint="see lopcook cook --help") from None
    if ns["source"] != _SENTINEL_SOURCE or ns["output"] != _SENTINEL_OUTPUT or ns.get("depfile") is not None \
            or ns.get("json"):
        raise LopcookError("usage", None, f"{where}: {' '.join(options)}: the batch sets the source, -o, --depfile "
                           "and --json of each cook itself", hint="give only cook options such as --lods auto")


def resolve(options) -> dict:
    """Every cook option's final value for these flags (JSON-ready; the key hashes it)."""
    ns = _parse_cook(options)
    return {k: v for k, v in sorted(ns.items()) if k not in _NOT_OPTIONS}


__all__ = ["BatchConfig", "Rule", "load_config", "check_options", "resolve", "glob_match", "glob_regex"]
