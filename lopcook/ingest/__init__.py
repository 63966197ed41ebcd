"""Ingest: any supported source file -> one validated ``Scene``.

``load(path)`` decides the format from the file's content (magic bytes), not from the extension,
among the formats the extension allows (a ``.usd`` may be text or crate; a ``.gltf`` may even hold
GLB bytes), calls the loader from ``LOADERS`` and validates the result.
"""

from __future__ import annotations

import os

from ..errors import LopcookError
from ..memory import release_free_memory
from ..settings import DEFAULT_INGEST, IngestSettings
from ..types import Scene

#: extension -> formats that extension may hold
EXTENSIONS = {
    ".gltf": ("gltf", "glb"),
    ".glb": ("glb", "gltf"),
    ".obj": ("obj",),
    ".usd": ("usda", "usdc", "usdz"),
    ".usda": ("usda", "usdc"),
    ".usdc": ("usdc", "usda"),
    ".usdz": ("usdz",),
}


def _load_gltf(path, fmt, settings):
    from . import gltf

    return gltf.load(path, fmt=fmt, settings=settings)


def _load_obj(path, fmt, settings):
    from . import obj

    return obj.load(path, fmt=fmt, settings=settings)


def _load_usd(path, fmt, settings):
    from . import usd

    return usd.load(path, fmt=fmt, settings=settings)


#: format -> loader(path: str, fmt: str, settings: IngestSettings) -> Scene (not yet validated)
LOADERS = {
    "gltf": _load_gltf,
    "glb": _load_gltf,
    "obj": _load_obj,
    "usda": _load_usd,
    "usdc": _load_usd,
    "usdz": _load_usd,
}


def sniff(path: str) -> str:
    """Return the format of ``path`` from its extension and first bytes.

    Raises LopcookError (exit 2) for a missing file, a directory, an unknown extension, an empty
    file, or content that matches none of the formats the extension allows.
    """
    ext = os.path.splitext(path)[1].lower()
    if ext not in EXTENSIONS:
        raise LopcookError("ingest", path, f"unknown extension {ext or '(none)'!r}",
                           hint="expected one of " + ", ".join(sorted(EXTENSIONS)))
    if not os.path.exists(path):
        raise LopcookError("ingest", path, "file not found", hint="check the path")
    if os.path.isdir(path):
        raise LopcookError("ingest", path, "is a directory, not a file", hint="give the path of a scene file")
    with open(path, "rb") as fh:
        head = fh.read(64)
    if not head:
        raise LopcookError("ingest", path, "file is empty (0 bytes)", hint="re-export the asset")
    allowed = EXTENSIONS[ext]
    if head.startswith(b"glTF"):
        found = "glb"
    elif head.startswith(b"PXR-USDC"):
        found = "usdc"
    elif head.startswith(b"PK\x03\x04"):
        found = "usdz"
    elif head.lstrip().startswith(b"#usda"):
        found = "usda"
    elif head.lstrip(b"\xef\xbb\xbf \t\r\n").startswith(b"{"):
        found = "gltf"
    else:
        found = "obj" if "obj" in allowed else None
    if found not in allowed:
        what = found or "unrecognised content"
        raise LopcookError("ingest", path, f"content is {what}, which a {ext} file cannot hold",
                           hint="the file is corrupt or has the wrong extension")
    return found


def load(path: str | os.PathLike, settings: IngestSettings = DEFAULT_INGEST) -> Scene:
    """Load a glTF/GLB, OBJ or USD(A/C/Z) file into a validated Scene (metres, +Y up, CCW)."""
    path = os.fspath(path)
    fmt = sniff(path)
    try:
        scene = LOADERS[fmt](path, fmt, settings)
    except LopcookError:
        raise
    except MemoryError:
        raise LopcookError("ingest", path, "out of memory while reading the file",
                           hint="split the scene or use a machine with more memory") from None
    except Exception as exc:  # a parser failure we did not anticipate: still one clear line
        raise LopcookError("ingest", path, f"cannot read {fmt} file: {type(exc).__name__}: {exc}",
                           hint="the file is malformed; re-export it (run with --debug for details)") from exc
    release_free_memory()  # the parsers' and normal computation's temporaries
    return scene.validate()


__all__ = ["load", "sniff", "LOADERS", "EXTENSIONS"]
