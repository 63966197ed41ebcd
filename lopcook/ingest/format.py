"""``Format``: what one input format module of ``lopcook.ingest`` tells the rest of lopcook.

Each format lives in one module (``ingest/gltf.py``, ``obj.py``, ``usd.py``, ``ply.py``) that
ends with ``FORMAT = Format(...)``; ``lopcook.ingest.FORMATS`` lists them, and everything that
needs to know the input formats (``ingest.load``/``sniff``, ``lopcook.outputs``,
``lopcook.batch.discover``, the CLI help and ``lopcook --formats``, ``lopcook decode``'s
materials) reads that tuple, so adding a format is one module and one registry line.

A *kind* is what the content of one file is (``"gltf"`` JSON or ``"glb"`` binary, ``"usda"``,
``"usdc"`` or ``"usdz"``, ``"obj"``, ``"ply"``): the value of ``Scene.format`` and of the
manifest's ``source.format``. A format reads one or more kinds.

Optional dependencies (trimesh's ``mesh_formats()``): ``requires`` names the module a format
needs. It is looked up (``importlib.util.find_spec``, never imported here) only when a file of
that format is loaded or ``lopcook --formats`` lists what can run, so a missing one fails only
when used, with ``install`` as the hint.
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass, field
from typing import Callable

#: bytes of a file's start handed to every ``Format.sniff``
SNIFF_BYTES = 64


@dataclass(frozen=True)
class Format:
    """One input format.

    name : str
        Short name, e.g. ``"gltf"`` (``lopcook --formats``).
    title : str
        How help text names it, e.g. ``"glTF/GLB"``.
    extensions : dict[str, tuple[str, ...]]
        Lower-case file extension (with the dot) -> the kinds a file so named may hold.
    load : Callable
        ``load(path, *, fmt=kind, settings=IngestSettings)``: the file as an unvalidated
        ``Scene``; every problem is one ``LopcookError("ingest", path, ...)``.
    sniff : Callable[[bytes], str | None] or None
        The kind the first ``SNIFF_BYTES`` bytes of a file show, or None when they are not this
        format. None for a format without a signature (OBJ): it claims a file that no other
        format's ``sniff`` claims, where the extension allows it.
    materials : Callable[[str, list[dict], MaterialSet], list] or None
        ``materials(path, parts, out)``: per manifest part (dicts with ``source``, ``mesh_key``)
        a glTF 2.0 material dict (its textures added to ``out``) or None for the default
        material; may raise ``OSError``/``ValueError``/``KeyError``/``TypeError``/``IndexError``/
        ``RuntimeError``/``struct.error`` for an unreadable source. None: the format has none.
    sidecars : tuple[str, ...]
        Extensions of files a source of this format reads beside itself (``.mtl``, ``.bin``):
        lopcook never writes an output so named.
    requires : str or None
        Top-level module of an optional dependency the loader imports; ``install`` the hint.
    """

    name: str
    title: str
    extensions: dict[str, tuple[str, ...]]
    load: Callable
    sniff: Callable[[bytes], str | None] | None = None
    materials: Callable | None = None
    sidecars: tuple[str, ...] = ()
    requires: str | None = None
    install: str = ""
    kinds: tuple[str, ...] = field(init=False)

    def __post_init__(self) -> None:
        kinds = dict.fromkeys(k for ks in self.extensions.values() for k in ks)
        object.__setattr__(self, "kinds", tuple(kinds))

    def missing(self) -> str | None:
        """None when the format can be read here; else what is missing, as one line."""
        if self.requires is None or importlib.util.find_spec(self.requires) is not None:
            return None
        return f"{self.title} support needs the Python module {self.requires!r}, which is not installed"


__all__ = ["Format", "SNIFF_BYTES"]
