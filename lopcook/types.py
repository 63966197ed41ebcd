"""The scene model every importer produces and every later stage consumes.

Conventions (all importers normalise to these):

* positions: world space, **metres**, right-handed, **+Y up** (USD ``upAxis = Z`` is rotated
  -90 degrees about X; ``metersPerUnit`` and glTF/OBJ units are applied as given: glTF is metres
  by specification, OBJ has no units and is taken as metres).
* triangles: counter-clockwise seen from the outside (front face), ``uint32`` indices.
* uvs: glTF convention, origin at the **top-left** of the image (OBJ/USD ``v`` is flipped to ``1 - v``).
* normals: unit length, float32; ``normals_computed`` says whether the source supplied them.
* colors: linear RGBA float32 in [0, 1].
* attributes are keyed by codec name (``lopcook.lop.codecs``), absent ones have no key.
"""

from __future__ import annotations

import hashlib
import io
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from .errors import LopcookError
from .lop.codecs import CODECS


#: Largest scene ingest accepts, in triangles over all placements (instances counted once per
#: placement). Importers count before they expand (glTF node placements, USD PointInstancer
#: placements) and refuse past it with exit 2. A module constant until the CLI passes
#: ``--max-triangles``; 50 M triangles need about 3 GB in the later stages.
MAX_TRIANGLES = 50_000_000

#: Largest number of parts (mesh placements) ingest accepts: every part costs Python objects and
#: per-part work in every later stage (a cook of 20,000 one-cube parts took 68 s), so a file with
#: more placements is refused before it is expanded. The corpus's largest scene has 21 parts.
MAX_PARTS = 10_000

#: Largest distance from the origin of any position, metres (2^100, about 1.3e30 m): beyond it the
#: grid's origin + extent cannot be represented in float32 (which tops out at 3.4e38) with room
#: for the decoders' arithmetic. Float32 max, 1e300 scales and similar corruption are refused.
MAX_COORDINATE = 2.0 ** 100

#: A scene may lie at most this many times its own extent from the origin (2^24): at distance D
#: the float32 spacing is about D * 2^-24, so beyond 2^24 extents it exceeds the whole scene and
#: float32 (what the decoders compute in) cannot tell any two of its positions apart. Example: a
#: 1 m part 1e20 m from the origin is refused.
FLOAT32_RESOLUTION = float(1 << 24)


@dataclass(frozen=True, eq=False)
class Texture:
    """An encoded image (PNG/JPEG bytes) used as the base-colour texture of some parts.

    ``name`` is the file name or ``"<embedded N>"``; ``data`` is the encoded file content.
    """

    name: str
    data: bytes

    def image(self):
        """Decode to a PIL image (RGB/RGBA, 8 bits per channel)."""
        from PIL import Image  # optional at import time: only textured parts decode images

        return Image.open(io.BytesIO(self.data))

    @property
    def digest(self) -> str:
        """sha256 of the encoded bytes (stable identity for reports and containers)."""
        return hashlib.sha256(self.data).hexdigest()


@dataclass(frozen=True, eq=False, init=False)
class MeshPart:
    """One drawable mesh: a glTF primitive under a node, an OBJ object/group, a placed USD Mesh.

    Attributes
    ----------
    name : str
        Human-readable, unique within the scene (importers de-duplicate with ``#k`` suffixes).
    positions : (n, 3) float64
        World-space positions in metres, +Y up.
    indices : (m, 3) uint32
        Counter-clockwise triangles, each index in [0, n).
    attributes : Mapping[str, (n, k) float32]
        The per-vertex attributes the source has, by codec name (``lopcook.lop.codecs.CODECS``;
        k is the codec's ``components``): ``"normals"`` (n, 3) unit normals (world space),
        ``"uvs"`` (n, 2) texture coordinates, origin top-left (glTF convention), ``"colors"``
        (n, 4) linear RGBA in [0, 1], and any later codec's. An absent attribute has no key.
        ``part.normals``, ``part.uvs``, ``part.colors`` read it (None when absent). The
        constructor also takes each attribute as a keyword named as its codec
        (``MeshPart(name, p, t, normals=n, uvs=u)``, None: absent), merged over ``attributes``.
    source : str
        Where it came from: glTF ``node/mesh/primitive``, OBJ ``o``/``g`` name, USD prim path
        (with ``[instance k]`` for instancer placements).
    normals_computed : bool
        True when the source had no normals and lopcook computed them (area-weighted,
        crease-aware; see ``lopcook.ingest.normals``).
    texture : Texture or None
        Base-colour texture, if the source names one for this part.
    mesh_key : str
        Identity of the source mesh data: parts that instance the same mesh share it.
    double_sided : bool
        True when the source marks the surface two-sided (glTF material ``doubleSided``, USD
        ``doubleSided``). Otherwise only its front faces (counter-clockwise) are visible, as in
        glTF and USD renderers: the render harness culls back faces of single-sided parts.
    """

    name: str
    positions: np.ndarray
    indices: np.ndarray
    attributes: Mapping[str, np.ndarray] = field(default_factory=dict)
    source: str = ""
    normals_computed: bool = False
    texture: Texture | None = None
    mesh_key: str = ""
    double_sided: bool = False

    def __init__(self, name: str, positions: np.ndarray, indices: np.ndarray,
                 attributes: Mapping[str, np.ndarray] | None = None, source: str = "", normals_computed: bool = False,
                 texture: Texture | None = None, mesh_key: str = "", double_sided: bool = False,
                 **by_name: np.ndarray | None) -> None:
        if attributes is not None and not isinstance(attributes, Mapping):
            raise TypeError(f"MeshPart attributes must be a mapping of codec name to array, got {type(attributes)}")
        attrs = {**(attributes or {}), **by_name}
        known = [c.name for c in CODECS]
        unknown = sorted(set(attrs) - set(known))
        if unknown:
            raise TypeError(f"MeshPart got unknown attributes {unknown} (known: {known})")
        for key, value in (("name", name), ("positions", positions), ("indices", indices), ("source", source),
                           ("normals_computed", normals_computed), ("texture", texture), ("mesh_key", mesh_key),
                           ("double_sided", double_sided),
                           ("attributes", {k: attrs[k] for k in known if attrs.get(k) is not None})):
            object.__setattr__(self, key, value)

    @property
    def normals(self) -> np.ndarray | None:
        return self.attributes.get("normals")

    @property
    def uvs(self) -> np.ndarray | None:
        return self.attributes.get("uvs")

    @property
    def colors(self) -> np.ndarray | None:
        return self.attributes.get("colors")

    @property
    def n_vertices(self) -> int:
        return int(self.positions.shape[0])

    @property
    def n_triangles(self) -> int:
        return int(self.indices.shape[0])

    def validate(self, path: str | None = None) -> None:
        """Raise LopcookError("ingest", path, ...) unless shapes, dtypes, ranges and values hold."""

        def fail(msg: str, hint: str | None = None) -> None:
            raise LopcookError("ingest", path, f"part {self.name!r}: {msg}", hint=hint)

        p = self.positions
        if not isinstance(p, np.ndarray) or p.dtype != np.float64 or p.ndim != 2 or p.shape[1] != 3:
            fail(f"positions must be (n, 3) float64, got {getattr(p, 'dtype', type(p))} {getattr(p, 'shape', '')}")
        if p.shape[0] == 0:
            fail("has no vertices", "remove the empty mesh or export it with geometry")
        if not np.isfinite(p).all():
            bad = int((~np.isfinite(p)).any(axis=1).sum())
            fail(f"{bad} vertex positions are NaN or Inf", "fix the mesh in the authoring tool")
        t = self.indices
        if not isinstance(t, np.ndarray) or t.dtype != np.uint32 or t.ndim != 2 or t.shape[1] != 3:
            fail(f"indices must be (m, 3) uint32, got {getattr(t, 'dtype', type(t))} {getattr(t, 'shape', '')}")
        if t.shape[0] == 0:
            fail("has no triangles", "remove the empty mesh or export it with faces")
        if int(t.max()) >= p.shape[0]:
            fail(f"index {int(t.max())} out of range for {p.shape[0]} vertices")
        n = p.shape[0]
        for codec in CODECS:
            arr, name, width = self.attributes.get(codec.name), codec.name, codec.components
            if arr is None:
                continue
            if not isinstance(arr, np.ndarray) or arr.dtype != np.float32 or arr.shape != (n, width):
                fail(f"{name} must be ({n}, {width}) float32, got {getattr(arr, 'dtype', type(arr))} "
                     f"{getattr(arr, 'shape', '')}")
            if not np.isfinite(arr).all():
                rows = np.flatnonzero(~np.isfinite(arr).all(axis=1))
                fail(f"{name} are NaN or Inf at {rows.size} of {n} vertices (first at vertex {int(rows[0])})",
                     "fix or remove the attribute in the authoring tool")
            problem = codec.problem(arr)
            if problem:
                fail(f"{name} {problem}")


@dataclass(frozen=True, eq=False)
class Scene:
    """Everything an importer read from one source file.

    Attributes
    ----------
    parts : tuple[MeshPart, ...]
        Drawable parts in a deterministic order (source order).
    source : str
        The path as the user gave it (used in messages; never written with absolute prefixes).
    format : str
        ``"gltf"``, ``"glb"``, ``"obj"``, ``"usda"``, ``"usdc"`` or ``"usdz"`` (decided from content).
    unit_scale : float
        Metres per source unit that was applied to positions.
    up_axis : str
        The source's up axis before normalisation (``"Y"`` or ``"Z"``).
    warnings : tuple[str, ...]
        Things the importer tolerated (missing .mtl, skipped non-triangle primitives, ...).
    dependencies : tuple[str, ...]
        Every file the importer opened or resolved, for build systems (``lopcook.depfile``):
        the source itself first, then its sidecars in first-use order, de-duplicated and
        deterministic. glTF: external ``.bin`` buffers and image files that were read; OBJ: the
        ``mtllib`` files and the ``map_Kd`` images of the materials the parts use; USD: every
        layer the composed stage used (``Usd.Stage.GetUsedLayers``: sublayers, references,
        payloads; anonymous layers skipped, a layer inside a ``.usdz`` package listed as the
        ``.usdz`` file) and the texture files read through the asset resolver. A file that was
        referenced but missing (tolerated with a warning, e.g. a missing texture or ``.mtl``) is
        still listed, so that a build reruns when it appears. Data URIs, GLB chunks and remote
        URLs are not files and are not listed. Paths are spelt as in a Makefile: relative to the
        current directory (the source's directory joined with the reference, ``os.path.normpath``)
        when ``source`` is relative, absolute when it is absolute; an absolute reference stays
        absolute. Empty for a Scene not made by an importer.
    recorded_path : str or None
        The manifest's ``source.path``: where the source is, relative to the folder of the
        container being written (``lopcook.lop.manifest.recorded_source_path``), so that
        ``decode`` finds it there. Set by ``lopcook.cook(..., output=PATH)`` (``lopcook cook``
        and batch give it); None (``cook`` without ``output``): no ``source.path``.
    """

    parts: tuple[MeshPart, ...]
    source: str
    format: str
    unit_scale: float = 1.0
    up_axis: str = "Y"
    warnings: tuple[str, ...] = field(default_factory=tuple)
    dependencies: tuple[str, ...] = field(default_factory=tuple)
    recorded_path: str | None = None

    @property
    def n_vertices(self) -> int:
        return sum(p.n_vertices for p in self.parts)

    @property
    def n_triangles(self) -> int:
        return sum(p.n_triangles for p in self.parts)

    def bounds(self) -> np.ndarray:
        """(2, 3) float64: min and max corner of all positions, metres."""
        lo = np.min([p.positions.min(axis=0) for p in self.parts], axis=0)
        hi = np.max([p.positions.max(axis=0) for p in self.parts], axis=0)
        return np.stack([lo, hi])

    def validate(self, max_triangles: int = MAX_TRIANGLES) -> "Scene":
        """Check every part (see MeshPart.validate), that the scene is not empty and that it is
        within ingest's limits (the module constants below): at most ``MAX_PARTS`` parts and
        ``MAX_TRIANGLES`` triangles over all placements, every coordinate within
        ``MAX_COORDINATE`` metres of the origin, and the scene's distance from the origin at most
        ``FLOAT32_RESOLUTION`` times its extent (1 m for a scene of one point), so float32 decoders
        can resolve it; return self."""
        if not self.parts:
            why = f" ({self.warnings[0]}" + (f"; and {len(self.warnings) - 1} more" if len(self.warnings) > 1 else "") \
                + ")" if self.warnings else ""
            raise LopcookError("ingest", self.source, f"the scene has no triangle meshes{why}",
                               hint="export at least one mesh with triangles or polygons")
        if len(self.parts) > MAX_PARTS:
            raise LopcookError("ingest", self.source, f"the scene has {len(self.parts):,} parts, more than "
                               f"the {MAX_PARTS:,} lopcook accepts", hint="merge parts or split the scene")
        if self.n_triangles > max_triangles:
            raise LopcookError("ingest", self.source, f"the scene has {self.n_triangles:,} triangles, more "
                               f"than the {max_triangles:,} lopcook accepts",
                               hint="simplify or split the scene, or raise --max-triangles")
        names = [p.name for p in self.parts]
        if len(set(names)) != len(names):
            raise LopcookError("ingest", self.source, "part names are not unique")
        for part in self.parts:
            part.validate(self.source)
        lo, hi = self.bounds()
        far = float(np.max(np.abs(np.stack([lo, hi]))))
        if far > MAX_COORDINATE:
            raise LopcookError("ingest", self.source, f"a position is {far:.3g} m from the origin, beyond the "
                               f"{MAX_COORDINATE:.3g} m lopcook accepts (the decoders compute in float32)",
                               hint="check the units and transforms, or move the scene near the origin")
        extent = float(np.max(hi - lo))
        if far > FLOAT32_RESOLUTION * (extent if extent > 0 else 1.0):
            raise LopcookError("ingest", self.source, f"the scene spans {extent:.3g} m at {far:.3g} m from the "
                               "origin: float32, which the decoders compute in, cannot tell its positions apart",
                               hint="move the scene near the origin (or check the units and transforms)")
        return self
