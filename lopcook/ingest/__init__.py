"""Ingest: any supported source file -> one validated ``Scene``.

Every input format is one module of this package that ends with ``FORMAT = Format(...)``
(``lopcook.ingest.format``): its extensions, content sniffing, loader and material reader.
``FORMATS`` lists them; everything else reads it (``EXTENSIONS``, ``KINDS``,
``SOURCE_EXTENSIONS`` and ``describe_formats`` are views of it).

``load(path)`` decides the format from the file's content (its first ``SNIFF_BYTES`` bytes), not
from the extension, among the kinds the extension allows (a ``.usd`` may be text or crate; a
``.gltf`` may even hold GLB bytes), calls that format's loader and validates the result.
"""

from __future__ import annotations

import os
import re
import warnings
from importlib import import_module

import numpy as np

from ..errors import LopcookError
from ..grid import Grid
from .. import memory
from ..mesh import degenerate_mask
from ..settings import DEFAULT_INGEST, IngestSettings
from ..types import Scene
from .build import MAX_PARTS, MAX_TEXTURE_PIXELS, MAX_TRIANGLES, bad_path_characters, regular_file_problem
from .format import SNIFF_BYTES, Format

#: The input formats, one module each (``lopcook/ingest/<name>.py`` exporting ``FORMAT``), in the
#: order help text and ``lopcook --formats`` list them. Adding a format adds one line here.
FORMATS: tuple[Format, ...] = tuple(import_module(f"{__name__}.{name}").FORMAT for name in (
    "gltf",
    "obj",
    "usd",
    "ply",
))

#: extension (lower case, with the dot) -> the kinds a file so named may hold
EXTENSIONS: dict[str, tuple[str, ...]] = {ext: kinds for f in FORMATS for ext, kinds in f.extensions.items()}
#: kind (``Scene.format``) -> its format
KINDS: dict[str, Format] = {kind: f for f in FORMATS for kind in f.kinds}
#: every extension a source is read from, sidecar files (.mtl, .bin) included
SOURCE_EXTENSIONS: tuple[str, ...] = tuple(EXTENSIONS) + tuple(
    dict.fromkeys(ext for f in FORMATS for ext in f.sidecars if ext not in EXTENSIONS))


def format_of(kind: str) -> Format | None:
    """The format that reads content of ``kind`` (``Scene.format``, the manifest's
    ``source.format``), or None for a kind no format reads."""
    return KINDS.get((kind or "").lower())


def describe_formats(extensions: bool = False) -> str:
    """The formats for help text: ``"glTF/GLB, OBJ or USD"``, or with ``extensions``
    ``"glTF/GLB (.gltf .glb), OBJ (.obj) or USD (.usd .usda .usdc .usdz)"``."""
    names = [f.title + (f" ({' '.join(f.extensions)})" if extensions else "") for f in FORMATS]
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " or " + names[-1]


def formats_table() -> str:
    """``lopcook --formats``: one line per format with its extensions and whether it can be read
    here (else what is missing and how to install it)."""
    rows = []
    for f in FORMATS:
        problem = f.missing()
        state = "available" if problem is None else f"unavailable: {problem} ({f.install})"
        rows.append((f.name, f.title, " ".join(f.extensions), state))
    widths = [max(len(r[i]) for r in rows) for i in range(3)]
    return "\n".join("  ".join(c.ljust(w) for c, w in zip(r[:3], widths)) + "  " + r[3] for r in rows)


def sniff(path: str) -> str:
    """Return the format of ``path`` from its extension and first bytes.

    Raises LopcookError (exit 2) for a missing file, a directory, a file that is not regular (a
    device, FIFO or socket, also through a symlink: never opened, so a FIFO cannot block), a name
    with a line break or NUL, an unknown extension, an empty file, or content that matches none of
    the formats the extension allows.
    """
    ext = os.path.splitext(path)[1].lower()
    if ext not in EXTENSIONS:
        raise LopcookError("ingest", path, f"unknown extension {ext or '(none)'!r}",
                           hint="expected one of " + ", ".join(sorted(EXTENSIONS)))
    if bad_path_characters(path):
        raise LopcookError("ingest", repr(path), "the file name contains a line break or NUL",
                           hint="rename the file (such a name cannot be listed in a depfile)")
    problem = regular_file_problem(path)
    if problem == "not found":
        raise LopcookError("ingest", path, "file not found", hint="check the path")
    if problem == "is a directory":
        raise LopcookError("ingest", path, "is a directory, not a file", hint="give the path of a scene file")
    if problem is not None:
        raise LopcookError("ingest", path, problem, hint="give the path of a scene file on disk")
    try:
        with open(path, "rb") as fh:
            head = fh.read(SNIFF_BYTES)
    except OSError as exc:
        raise LopcookError("ingest", path, f"cannot read the file ({exc.strerror or 'error'})",
                           hint="check the path and permissions") from None
    if not head:
        raise LopcookError("ingest", path, "file is empty (0 bytes)", hint="re-export the asset")
    allowed = EXTENSIONS[ext]
    found = _kind_of(head, allowed)
    if found not in allowed:
        what = f"content is {found}" if found else f"content is not {describe_formats()}"
        raise LopcookError("ingest", path, f"{what}, which a {ext} file cannot hold",
                           hint="the file is corrupt or has the wrong extension")
    return found


def _kind_of(head: bytes, allowed: tuple[str, ...]) -> str | None:
    """The kind a signature in ``head`` shows; else the kind of a format without a signature
    (OBJ) that ``allowed`` holds; else None."""
    for f in FORMATS:
        found = f.sniff(head) if f.sniff is not None else None
        if found is not None:
            return found
    return next((k for f in FORMATS if f.sniff is None for k in f.kinds if k in allowed), None)


def load(path: str | os.PathLike, settings: IngestSettings = DEFAULT_INGEST) -> Scene:
    """Load a source file of any of ``FORMATS`` into a validated Scene (metres, +Y up, CCW).

    A format whose optional dependency is not installed is refused with its install hint.
    Hostile input gives one ``LopcookError`` (exit 2), never a traceback: besides the loaders' own
    checks, a dependency whose name holds a line break or NUL is refused (before anything is
    written), and scenes over ``MAX_TRIANGLES`` triangles or ``MAX_PARTS`` parts are refused
    (``Scene.validate``; the loaders count placements before expanding them).
    """
    path = os.fspath(path)
    fmt = sniff(path)
    missing = KINDS[fmt].missing()
    if missing is not None:
        raise LopcookError("ingest", path, missing, hint=KINDS[fmt].install)
    try:
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # overflow etc.: reported as errors instead
            scene = KINDS[fmt].load(path, fmt=fmt, settings=settings)
    except LopcookError:
        raise
    except MemoryError:
        raise LopcookError("ingest", path, "the file needs more memory than is available",
                           hint="split the scene or use a machine with more memory") from None
    except RecursionError:
        raise LopcookError("ingest", path, f"the {fmt} file is nested too deeply to read",
                           hint="flatten the hierarchy or re-export the file") from None
    except Exception as exc:  # a parser failure we did not anticipate: still one clear line
        detail = " ".join(str(exc).split())[:200] or "malformed data"
        cap = memory.address_space_limit()
        if cap is not None and re.search(r"map segment|[Cc]annot allocate memory|out of memory", detail):
            raise LopcookError("ingest", path, f"reading the file ran out of memory under a {cap / 1e9:.2g} GB "
                               f"address-space limit ({detail})", hint="raise the limit (ulimit -v, lopcook batch "
                               "--worker-memory)") from None
        raise LopcookError("ingest", path, f"cannot read the {fmt} file ({detail})",
                           hint="the file is malformed; re-export it (run with --debug for details)") from exc
    memory.release_free_memory()  # the parsers' and normal computation's temporaries
    for dep in scene.dependencies:
        if bad_path_characters(dep):
            raise LopcookError("ingest", path, f"refers to a file whose name contains a line break or NUL "
                               f"({dep!r})", hint="rename the file and the reference: such a name cannot "
                               "be listed in a depfile")
    with np.errstate(all="ignore"):
        scene.validate(settings.max_triangles)
    _refuse_all_degenerate(scene)
    return scene


#: triangles per part checked before the full pass of _refuse_all_degenerate
_DEGENERATE_SAMPLE = 4096


def _refuse_all_degenerate(scene: Scene) -> None:
    """Refuse a scene none of whose triangles has area and spans two cells of its 24-bit grid
    (``mesh.degenerate_mask``: repeated indices, coincident or collinear corners; or every corner
    in one cell): there is no surface to cook and no edge to analyse. Such triangles among good
    ones are cooked as usual (``inspect`` counts degenerate triangles)."""
    grid = Grid.fit([p.positions for p in scene.parts])

    def surface(q: np.ndarray, positions: np.ndarray, tris: np.ndarray) -> bool:
        """Whether one of ``tris`` (k, 3), with corners on the grid ``q`` (k, 3, 3), has area and
        spans two grid cells."""
        if tris.size == 0:
            return False
        spans = np.any(q[:, 0] != q[:, 1], axis=1) | np.any(q[:, 1] != q[:, 2], axis=1)
        if not spans.any():
            return False
        return bool((spans & ~degenerate_mask(positions, tris.astype(np.int64))).any())

    # a sample of each part's first triangles settles every ordinary scene without quantising it
    # whole; only a scene whose sampled triangles all collapse pays for the full pass
    for part in scene.parts:
        tris = np.asarray(part.indices[:_DEGENERATE_SAMPLE])
        if surface(grid.quantize(part.positions[tris.ravel()]).reshape(-1, 3, 3), part.positions, tris):
            return
    for part in scene.parts:
        tris = np.asarray(part.indices)
        if surface(grid.quantize(part.positions)[tris], part.positions, tris):
            return
    raise LopcookError("ingest", scene.source, f"all {scene.n_triangles:,} triangles are degenerate: each has no "
                       "area (repeated, coincident or collinear corners) or its corners fall in one cell of "
                       "the 24-bit grid", hint="export a mesh whose triangles have area")


__all__ = ["load", "sniff", "FORMATS", "Format", "format_of", "describe_formats", "formats_table",
           "EXTENSIONS", "KINDS", "SOURCE_EXTENSIONS", "MAX_TRIANGLES", "MAX_PARTS", "MAX_TEXTURE_PIXELS"]
