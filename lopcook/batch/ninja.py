"""``--emit-ninja build.ninja``: the batch as a Ninja file, so ninja (or any build system that
reads Ninja files, e.g. samurai) schedules the cooks and decides what to rebuild.

One rule, one build edge per asset::

    ninja_required_version = 1.10
    lopcook = /usr/bin/python3 -m lopcook

    rule lopcook_cook
      command = $lopcook cook $src -o $dst --depfile $dst.d -q $options
      depfile = $out.d
      deps = gcc
      description = lopcook cook $in

    build /abs/out/props/chair.lop: lopcook_cook /abs/assets/props/chair.glb
      src = /abs/assets/props/chair.glb
      dst = /abs/out/props/chair.lop
      options = --lods auto

``deps = gcc`` makes ninja read each cook's depfile (every .bin, texture, .mtl or USD layer the
cook opened) into its ``.ninja_deps`` log and delete it, so editing a texture rebuilds exactly
the assets that read it. The options are those ``lopcook.toml`` gives each asset, as for
``lopcook batch``, so the outputs have the same bytes. Paths are absolute (the file works from
any directory; regenerate it after moving the tree); ``src``/``dst`` are shell-quoted copies for
the command. ``lopcook`` is the interpreter that wrote the file running ``-m lopcook``: ninja
passes its environment on, so a PYTHONPATH needed to import lopcook must be set when ninja runs.
Ninja compares modification times, not contents (``lopcook batch``'s own check hashes contents).
"""

from __future__ import annotations

import shlex
import sys

from ..atomic import write_atomic
from ..version import __version__


def ninja_path(path: str) -> str:
    """A path as a word of a Ninja ``build`` line: ``$``, space and ``:`` escaped with ``$``."""
    if "\n" in path or "\r" in path:
        raise ValueError(f"a Ninja file cannot name a path containing a newline: {path!r}")
    return path.replace("$", "$$").replace(" ", "$ ").replace(":", "$:")


def ninja_value(text: str) -> str:
    """Text as a Ninja variable value (``$`` escaped)."""
    if "\n" in text or "\r" in text:
        raise ValueError(f"a Ninja variable cannot hold a newline: {text!r}")
    return text.replace("$", "$$")


def format_ninja(edges, lopcook_command: str | None = None) -> str:
    """The Ninja file text for ``edges``: ``(source, output, options)`` with absolute paths."""
    if lopcook_command is None:
        lopcook_command = f"{shlex.quote(sys.executable)} -m lopcook"
    lines = [f"# written by lopcook {__version__} batch --emit-ninja: one `lopcook cook` per asset",
             "ninja_required_version = 1.10",
             f"lopcook = {ninja_value(lopcook_command)}",
             "",
             "rule lopcook_cook",
             "  command = $lopcook cook $src -o $dst --depfile $dst.d -q $options",
             "  depfile = $out.d",
             "  deps = gcc",
             "  description = lopcook cook $in",
             ""]
    for source, output, options in edges:
        lines.append(f"build {ninja_path(output)}: lopcook_cook {ninja_path(source)}")
        lines.append(f"  src = {ninja_value(shlex.quote(source))}")
        lines.append(f"  dst = {ninja_value(shlex.quote(output))}")
        if options:
            lines.append(f"  options = {ninja_value(shlex.join(options))}")
    lines.append("")
    return "\n".join(lines)


def write_ninja(path: str, edges, lopcook_command: str | None = None) -> None:
    """Write ``format_ninja(edges)`` to ``path`` atomically."""
    write_atomic(path, format_ninja(edges, lopcook_command).encode("utf-8"))


__all__ = ["format_ninja", "write_ninja", "ninja_path", "ninja_value"]
