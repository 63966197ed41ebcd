"""USD (``.usd``, ``.usda``, ``.usdc``, ``.usdz``) -> ``Scene``; the USD ``FORMAT`` of the registry
(needs usd-core, ``pxr``, imported only where a stage is read).

``load(path, fmt="usda"|"usdc"|"usdz", settings) -> Scene`` (not yet validated):

* the stage is composed (``Usd.Stage.LoadAll``: references, payloads, variants, instanceable
  prims) in a child process (``lopcook.isolate``): a crash of the native library is one error.
  Composition errors carry USD's own diagnostic.
* every ``UsdGeom.Mesh`` a renderer draws is one ``MeshPart`` per placement: instance proxies
  followed; inactive, unloaded, undefined, abstract and invisible prims and ``guide``/``proxy``
  purposes skipped; prims under a ``PointInstancer`` drawn only through it, one part per visible
  instance and prototype mesh (named ``<instancer>[k]/...``, ``source`` ``<prim> [instance k]``),
  nested instancers followed. ``mesh_key`` is the prim path of the mesh data: placements of one
  mesh share it, and it is read, triangulated and split once.
* geometry: ``faceVertexCounts``/``faceVertexIndices`` polygons (``holeIndices`` dropped, faces
  of < 3 corners skipped and counted) triangulated by ``polygons.triangulate``; ``leftHanded``
  and mirroring placements flip the winding. Primvars: normals, one UV set (``UV_NAMES``, else
  the first ``texCoord2*``; ``v`` -> ``1 - v``), ``displayColor``/``displayOpacity`` as RGBA,
  ``tangents`` (float4 or float3, as glTF's TANGENT), in every interpolation, indexed or not. A
  vertex is one distinct (point, normal, uv, colour, tangent) over the kept corners. A subdivision scheme other than ``none`` is a warning (the control mesh is
  cooked).
* transforms and units: ``UsdGeom.XformCache`` (row vectors, ``p_world = p @ M``); ``upAxis Z``
  becomes +Y by ``(x, y, z) -> (x, z, -y)``; ``metersPerUnit`` scales to metres (USD's fallback
  0.01 when unauthored, a warning). Normals by the inverse transpose.
* time: ``settings.usd_time`` ``"default"`` (an attribute with samples but no default value is
  read at its earliest sample) or a time code.
* the ``UsdUVTexture`` feeding the bound ``UsdPreviewSurface``'s ``diffuseColor`` is the part's
  ``texture`` (read through the resolver, so ``.usdz`` works; unresolved: a warning).
* ``Scene.dependencies``: the source, the stage's used layers (first-use order), then each
  texture file; a file inside a ``.usdz`` counts as the ``.usdz``.

Refused, each as one ``LopcookError("ingest", path, ...)``: unreadable files and composition
errors, inconsistent topology, out-of-range indices, NaN/Inf points, primvars whose length does
not match their interpolation, more than ``build.MAX_PARTS`` placements or
``settings.max_triangles`` triangles (counted before expanding). Details: docs/ingest.md, "USD".
``materials(path, parts, out)`` reads the bound preview surfaces for ``lopcook decode``.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import sys
import tempfile
from dataclasses import dataclass

import numpy as np
from PIL import Image

from .. import isolate, memory
from ..depfile import DependencyList
from ..errors import LopcookError
from ..mesh import unique_rows
from ..settings import IngestSettings
from ..types import MeshPart, Scene, Texture
from .build import (MAX_PARTS, bad_path_characters, checked_texture, make_part, placed_tangents,
                    regular_file_problem, unique_names, usable_tangents)
from .format import Format
from .materials import BASE_FROM_VERTEX_COLOURS, MaterialSet, image_readable
from .polygons import PolygonTooComplex, triangulate

#: UV primvar names, in order of preference, before falling back to any texCoord2* primvar
UV_NAMES = ("st", "st0", "UVMap", "map1", "uv")
_UV_TYPES = {"texCoord2f", "texCoord2d", "texCoord2h", "float2", "double2", "half2"}
_SKIPPED_PURPOSES = ("guide", "proxy")
#: (x, y, z) -> (x, z, -y) as a row-vector matrix: +Z up becomes +Y up, handedness kept
_Z_UP_TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
_DIAG_RE = re.compile(r"^(?:[A-Za-z ]*Error|Warning|Status)?:? ?in \S+ at line \d+ of \S+ -- (.*)$")


@dataclass(frozen=True, eq=False)
class _LocalMesh:
    """One Mesh prim read, triangulated and split into vertices, in its own object space.

    points : (n, 3) float64 object-space position of each vertex (source units)
    tris : (m, 3) int64 vertex indices, counter-clockwise for a placement with det > 0
    normals : (n, 3) float32 object-space normals, or None
    uvs : (n, 2) float32, origin top-left (USD ``v`` flipped), or None
    colors : (n, 4) float32 linear RGBA, or None
    tangents : (n, 4) float64 object-space tangents (xyz, handedness w = +-1), or None
    double_sided : the Mesh's ``doubleSided`` (USD's default: false)
    """

    key: str
    points: np.ndarray
    tris: np.ndarray
    normals: np.ndarray | None
    uvs: np.ndarray | None
    colors: np.ndarray | None
    texture: Texture | None
    double_sided: bool = False
    tangents: np.ndarray | None = None


@dataclass(frozen=True)
class _Context:
    """Where a subtree is drawn from.

    root : None for the stage (world transforms from the XformCache); else the prototype root prim
    matrix : (4, 4) float64 row-vector matrix applied after the transform relative to ``root``
        (instance transform x instancer transform); None for the stage
    label : name prefix replacing ``root``'s path in part names, e.g. ``/Set/Pawns[3]/Pawn``
    instance : text appended to ``source``, e.g. `` [instance 3]``
    """

    root: object = None
    matrix: np.ndarray | None = None
    label: str = ""
    instance: str = ""


@contextlib.contextmanager
def _captured_stderr():
    """Redirect file descriptor 2 (where USD prints its diagnostics) into a list of lines."""
    lines: list[str] = []
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError, AttributeError):
        yield lines
        return
    with tempfile.TemporaryFile() as buf:
        os.dup2(buf.fileno(), 2)
        try:
            yield lines
        finally:
            try:
                sys.stderr.flush()
            except (OSError, ValueError):
                pass
            os.dup2(saved, 2)
            os.close(saved)
            buf.seek(0)
            text = buf.read().decode("utf-8", "replace")
            lines.extend(ln.strip() for ln in text.splitlines() if ln.strip())


def _diagnostic_text(line: str) -> str:
    """USD's 'Warning: in F at line N of file.cpp -- message' -> 'message'."""
    m = _DIAG_RE.match(line)
    return m.group(1).strip() if m else line.strip()


def _tf_text(exc) -> str:
    """The messages of a Tf.ErrorException, joined; robust to undecodable bytes in them."""
    texts = []
    for arg in exc.args:
        try:
            text = getattr(arg, "commentary", None)
            text = str(arg) if text is None else text
        except UnicodeDecodeError:
            text = "(a USD diagnostic with undecodable bytes)"
        if str(text).strip():
            texts.append(str(text).strip())
    return "; ".join(texts) or "no diagnostic text"


def _one_line(text: str, path: str) -> str:
    text = " ".join(str(text).split())
    absolute = os.path.abspath(path)
    if absolute != path:  # messages name files as the user gave them, not with absolute prefixes
        text = text.replace(absolute, path)
        folder, given = os.path.dirname(absolute), os.path.dirname(path)
        text = text.replace(folder + os.sep, given + os.sep if given else "")
    return text


class _Loader:
    def __init__(self, path: str, fmt: str, settings: IngestSettings) -> None:
        from pxr import Usd  # usd-core: heavy and optional, imported where a stage is read

        self.path = path
        self.fmt = fmt
        self.settings = settings
        self.warnings: list[str] = []
        self.meshes: dict[str, _LocalMesh | None] = {}
        self.textures: dict[str, Texture | None] = {}
        self.parts: list[tuple[str, str, _LocalMesh, np.ndarray]] = []  # name, source, mesh, (4,4)
        self.deps = DependencyList(path)  # Scene.dependencies: layers, then textures as used
        self.absolute_refs: set[str] = set()  # asset paths authored absolute (kept absolute)
        text = str(settings.usd_time).strip()
        if text.lower() == "default":
            self.time = None
        else:
            try:
                value = float(text)
            except ValueError:
                raise LopcookError("ingest", path, f"usd_time must be 'default' or a number, got {text!r}",
                                   hint="pass e.g. usd_time='default' or usd_time='1'") from None
            if not np.isfinite(value):
                raise LopcookError("ingest", path, f"usd_time must be finite, got {text!r}")
            self.time = Usd.TimeCode(value)

    # ------------------------------------------------------------------ helpers
    def fail(self, message: str, hint: str | None = None):
        raise LopcookError("ingest", self.path, message, hint=hint)

    def time_of(self, attr):
        """Time code to read ``attr`` at (see the module doc: default, else earliest sample)."""
        from pxr import Usd  # usd-core: heavy and optional, imported where a stage is read

        if self.time is not None:
            return self.time
        if attr and attr.Get(Usd.TimeCode.Default()) is None and attr.GetNumTimeSamples() > 0:
            return Usd.TimeCode.EarliestTime()
        return Usd.TimeCode.Default()

    def get(self, attr):
        """Value of ``attr`` at the settings' time, or None (unauthored, blocked, invalid attr)."""
        if not attr:
            return None
        return attr.Get(self.time_of(attr))

    # ------------------------------------------------------------------ open
    def open(self):
        from pxr import Tf, Usd, UsdGeom  # usd-core: heavy and optional, imported where a stage is read

        error = None
        with _captured_stderr() as lines:
            try:
                stage = Usd.Stage.Open(self.path, Usd.Stage.LoadAll)
            except Tf.ErrorException as exc:
                error = _tf_text(exc)
                stage = None
            except Exception as exc:  # pxr raises a few plain exceptions (e.g. undecodable text)
                error = " ".join(str(exc).split()) or "unreadable data"
                stage = None
        if stage is None:
            detail = error or "; ".join(_diagnostic_text(ln) for ln in lines) or "unknown error"
            self.fail(f"USD cannot open the file: {_one_line(detail, self.path)}",
                      hint="the file is corrupt or not a USD layer")
        comp = list(stage.GetCompositionErrors())
        if comp:
            more = f" (and {len(comp) - 1} more)" if len(comp) > 1 else ""
            self.fail(f"USD composition error: {_one_line(str(comp[0]), self.path)}{more}",
                      hint="fix or ship the referenced layers/assets next to the file")
        self.warnings.extend(f"USD: {_one_line(_diagnostic_text(ln), self.path)}" for ln in lines)
        self.stage = stage
        self.add_layer_dependencies()
        self.up_axis = str(UsdGeom.GetStageUpAxis(stage))
        self.meters_per_unit = float(UsdGeom.GetStageMetersPerUnit(stage))
        if not UsdGeom.StageHasAuthoredMetersPerUnit(stage):
            self.warnings.append(f"metersPerUnit is not authored: using USD's fallback {self.meters_per_unit:g}")
        if not (self.meters_per_unit > 0 and np.isfinite(self.meters_per_unit)):
            self.fail(f"metersPerUnit is {self.meters_per_unit}, expected a positive number")
        if self.up_axis not in ("Y", "Z"):
            self.fail(f"upAxis is {self.up_axis!r}, expected 'Y' or 'Z'")
        stage_m = np.eye(4)
        if self.up_axis == "Z":
            stage_m[:3, :3] = _Z_UP_TO_Y_UP
        stage_m[:3, :3] *= self.meters_per_unit
        stage_m[3, :3] = 0.0
        self.stage_matrix = stage_m
        self.xf_cache = {}
        self.earliest_xf: dict[str, bool] = {}
        self.placed_triangles = 0  # over all placements so far (MAX_TRIANGLES)
        self.proto_meshes: dict[str, int] = {}
        self.active_instancers: set[str] = set()  # instancers being expanded (cycle check)

    # ------------------------------------------------------------------ dependencies
    def add_dependency(self, file: str) -> None:
        """Add an absolute file path (a layer's or asset's file) to ``self.deps``."""
        self.deps.add_resolved(file, keep_absolute=os.path.normpath(file) in self.absolute_refs)

    def add_layer_dependencies(self) -> None:
        """Every file layer the composed stage used, in a deterministic first-use order.

        ``GetUsedLayers`` is unordered, so the files are ordered: the root layer stack (strength
        order), then the order in which a prim traversal (instance proxies and all prims included)
        first meets an opinion from them, then any left (layers that hold no prim opinion, e.g.
        only metadata) sorted by path. Layers inside a .usdz package count as the .usdz file.
        """
        from pxr import Usd  # usd-core: heavy and optional, imported where a stage is read

        stage = self.stage
        root = stage.GetRootLayer()
        files: list[str] = []
        for layer in stage.GetUsedLayers():
            if layer.anonymous:
                continue
            for ref in getattr(layer, "GetCompositionAssetDependencies", lambda: ())():
                if os.path.isabs(ref):
                    self.absolute_refs.add(os.path.normpath(ref))
            if layer == root:
                continue
            file = _layer_file(layer)
            if file:
                files.append(file)
        root_file = _layer_file(root)
        pending = set(files) - {root_file}
        ordered: list[str] = []

        def meet(layer) -> None:
            file = _layer_file(layer)
            if file in pending:
                pending.discard(file)
                ordered.append(file)

        for layer in stage.GetLayerStack(includeSessionLayers=False):
            meet(layer)
        if len(pending) > 1:
            pred = Usd.TraverseInstanceProxies(Usd.PrimAllPrimsPredicate)
            for prim in Usd.PrimRange.Stage(stage, pred):
                for spec in prim.GetPrimStack():
                    meet(spec.layer)
                if len(pending) <= 1:
                    break
        ordered.extend(sorted(pending))
        for file in ordered:
            self.add_dependency(file)

    def add_asset_dependency(self, attr, authored: str, resolved: str) -> None:
        """A texture file: its resolved file, or (missing) the path anchored to the layer that
        authored it, so that a build reruns when it appears. UDIM patterns are not files."""
        from pxr import Ar  # usd-core: heavy and optional, imported where a stage is read

        if os.path.isabs(authored):
            self.absolute_refs.add(os.path.normpath(authored))
        if resolved:
            file = _package_outer(resolved)
        elif "<UDIM>" in authored:
            return
        else:
            layer = None
            try:
                for spec in attr.GetPropertyStack(self.time_of(attr)):
                    if spec.HasDefaultValue() or spec.layer.GetNumTimeSamplesForPath(spec.path):
                        layer = spec.layer
                        break
            except Exception:  # noqa: BLE001 - no anchor: list nothing rather than fail the load
                layer = None
            if layer is None or layer.anonymous:
                return
            home = _layer_file(layer)
            if Ar.IsPackageRelativePath(layer.realPath) or layer.GetFileFormat().IsPackage():
                file = home  # a file missing inside a .usdz: the package is the dependency
            else:
                anchored = layer.ComputeAbsolutePath(authored)
                if Ar.IsPackageRelativePath(anchored):
                    file = _package_outer(anchored)
                elif os.path.isabs(anchored):
                    file = anchored
                else:  # a search-path form ("tex.png") that did not resolve: next to the layer
                    file = os.path.join(os.path.dirname(home), anchored)
        if file:
            self.add_dependency(file)

    # ------------------------------------------------------------------ transforms
    def xform_cache(self, prim):
        """The XformCache for ``prim``: at the settings' time, or at the earliest sample when an
        xformOp of ``prim`` or an ancestor has time samples and no default (usd_time 'default')."""
        from pxr import Usd, UsdGeom  # usd-core: heavy and optional, imported where a stage is read

        if self.time is not None:
            t = self.time
        elif self._needs_earliest(prim):
            t = Usd.TimeCode.EarliestTime()
        else:
            t = Usd.TimeCode.Default()
        key = t.GetValue() if not t.IsDefault() else "default"
        if key not in self.xf_cache:
            self.xf_cache[key] = UsdGeom.XformCache(t)
        return self.xf_cache[key]

    def _needs_earliest(self, prim) -> bool:
        """Whether an xformOp of ``prim`` or of an ancestor has time samples and no default
        (walked iteratively up the ancestors, so any depth of hierarchy works)."""
        from pxr import Usd, UsdGeom  # usd-core: heavy and optional, imported where a stage is read

        chain = []  # prim, parent, ... up to the first one already known (or the root)
        p = prim
        while p and not p.IsPseudoRoot() and str(p.GetPath()) not in self.earliest_xf:
            chain.append(p)
            p = p.GetParent()
        result = bool(p) and not p.IsPseudoRoot() and self.earliest_xf[str(p.GetPath())]
        for q in reversed(chain):
            if not result and q.IsA(UsdGeom.Xformable):
                for op in UsdGeom.Xformable(q).GetOrderedXformOps():
                    attr = op.GetAttr()
                    if attr.GetNumTimeSamples() > 0 and attr.Get(Usd.TimeCode.Default()) is None:
                        result = True
                        break
            self.earliest_xf[str(q.GetPath())] = result
        return result

    def matrix(self, prim, ctx: _Context) -> np.ndarray:
        """(4, 4) float64 row-vector matrix: object space of ``prim`` -> world metres, +Y up."""
        cache = self.xform_cache(prim)
        if ctx.root is None:
            m = np.array(cache.GetLocalToWorldTransform(prim), dtype=np.float64)
        else:
            if prim == ctx.root:
                rel = np.eye(4)
            else:
                rel = np.array(cache.ComputeRelativeTransform(prim, ctx.root)[0], dtype=np.float64)
            m = rel @ ctx.matrix
        return m @ self.stage_matrix

    # ------------------------------------------------------------------ traversal
    def run(self) -> None:
        from pxr import Usd  # usd-core: heavy and optional, imported where a stage is read

        pred = Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)
        for child in self.stage.GetPseudoRoot().GetFilteredChildren(pred):
            self.walk(child, pred, "default", _Context())

    def walk(self, prim, pred, purpose: str, ctx: _Context) -> None:
        """Draw ``prim`` and its subtree in depth-first pre-order (an explicit stack: any depth of
        hierarchy works; only nested PointInstancers recurse, once per nesting level)."""
        from pxr import UsdGeom  # usd-core: heavy and optional, imported where a stage is read

        stack = [(prim, purpose)]
        while stack:
            prim, purpose = stack.pop()
            if prim.IsA(UsdGeom.Imageable):
                img = UsdGeom.Imageable(prim)
                if self.get(img.GetVisibilityAttr()) == UsdGeom.Tokens.invisible:
                    continue  # visibility is inherited: nothing beneath is drawn
                attr = img.GetPurposeAttr()
                if attr and attr.HasAuthoredValue():
                    purpose = str(self.get(attr) or purpose)
                if prim.IsA(UsdGeom.PointInstancer):
                    if purpose not in _SKIPPED_PURPOSES:
                        self.instancer(prim, purpose, ctx)
                    continue  # prototypes are drawn only through the instancer
                if prim.IsA(UsdGeom.Mesh) and purpose not in _SKIPPED_PURPOSES:
                    self.mesh(prim, ctx)
            children = list(prim.GetFilteredChildren(pred))
            stack.extend((child, purpose) for child in reversed(children))

    def name_of(self, prim, ctx: _Context) -> str:
        path = str(prim.GetPath())
        if ctx.root is None:
            return path
        root = str(ctx.root.GetPath())
        return ctx.label + path[len(root):]

    def mesh(self, prim, ctx: _Context) -> None:
        key = str(prim.GetPrimInPrototype().GetPath()) if prim.IsInstanceProxy() else str(prim.GetPath())
        if key not in self.meshes:
            self.meshes[key] = self.read_mesh(prim, key)
        local = self.meshes[key]
        if local is None:
            return
        self.placed_triangles += int(local.tris.shape[0])
        if len(self.parts) >= MAX_PARTS or self.placed_triangles > self.settings.max_triangles:
            self._refuse_size(len(self.parts) + 1, self.placed_triangles)
        source = str(prim.GetPath()) + ctx.instance
        self.parts.append((self.name_of(prim, ctx), source, local, self.matrix(prim, ctx)))

    def _refuse_size(self, parts: int, triangles: int, where: str = "") -> None:
        at = f" ({where})" if where else ""
        self.fail(f"the stage places at least {parts:,} meshes with {triangles:,} triangles{at}; lopcook accepts "
                  f"at most {MAX_PARTS:,} parts and {self.settings.max_triangles:,} triangles (--max-triangles)",
                  hint="reduce the instancing or split the stage")

    def _meshes_below(self, proto) -> int:
        """How many drawable meshes one placement of ``proto`` places at least (meshes under it;
        a nested PointInstancer counts as one): the multiplier for counting before expanding."""
        from pxr import Usd, UsdGeom  # usd-core: heavy and optional, imported where a stage is read

        key = str(proto.GetPath())
        if key not in self.proto_meshes:
            n = 0
            it = iter(Usd.PrimRange(proto, Usd.TraverseInstanceProxies(Usd.PrimIsActive & Usd.PrimIsLoaded)))
            for p in it:
                if p.IsA(UsdGeom.PointInstancer):
                    n += 1
                    it.PruneChildren()
                elif p.IsA(UsdGeom.Mesh):
                    n += 1
            self.proto_meshes[key] = n
        return self.proto_meshes[key]

    def instancer(self, prim, purpose: str, ctx: _Context) -> None:
        from pxr import Tf, Usd, UsdGeom  # usd-core: heavy and optional, imported where a stage is read

        pi = UsdGeom.PointInstancer(prim)
        where = str(prim.GetPath())
        if where in self.active_instancers:
            self.fail(f"PointInstancer {where} places itself (a prototype contains the instancer)",
                      hint="point the prototypes relationship at prims outside the instancer's own path")
        protos = [self.stage.GetPrimAtPath(p) for p in pi.GetPrototypesRel().GetForwardedTargets()]
        attr = pi.GetPositionsAttr() if pi.GetPositionsAttr().HasAuthoredValue() else pi.GetProtoIndicesAttr()
        t = self.time_of(attr)
        proto_indices = self.get(pi.GetProtoIndicesAttr())
        if proto_indices is None or len(proto_indices) == 0:
            return
        proto_indices = np.asarray(proto_indices, dtype=np.int64)
        bad = (proto_indices < 0) | (proto_indices >= len(protos))
        if bad.any():
            self.fail(f"PointInstancer {where}: protoIndices value {int(proto_indices[bad][0])} out of range "
                      f"for {len(protos)} prototypes", hint="fix the instancer's prototypes or protoIndices")
        try:
            xforms = pi.ComputeInstanceTransformsAtTime(t, t, UsdGeom.PointInstancer.IncludeProtoXform,
                                                        UsdGeom.PointInstancer.IgnoreMask)
        except Tf.ErrorException as exc:
            self.fail(f"PointInstancer {where}: cannot compute instance transforms: "
                      f"{_one_line(_tf_text(exc), self.path)}")
        xforms = np.asarray(xforms, dtype=np.float64).reshape(-1, 4, 4)
        self._refuse_nonfinite_instances(pi, where, xforms)
        if xforms.shape[0] != proto_indices.size:
            self.fail(f"PointInstancer {where}: {xforms.shape[0]} instance transforms for "
                      f"{proto_indices.size} protoIndices (positions/orientations/scales lengths differ?)",
                      hint="give every per-instance array one entry per protoIndices entry")
        mask = list(pi.ComputeMaskAtTime(t))
        # count the placements before expanding them (a small file can describe millions)
        visible = np.ones(proto_indices.size, bool) if not mask else np.asarray(mask, bool)
        per_proto = np.array([self._meshes_below(p) if p else 0 for p in protos], dtype=np.int64)
        placing = int(per_proto[proto_indices[visible]].sum()) if protos else 0
        if len(self.parts) + placing > MAX_PARTS:
            self._refuse_size(len(self.parts) + placing, self.placed_triangles, f"PointInstancer {where}")
        if ctx.root is None:
            base = np.array(self.xform_cache(prim).GetLocalToWorldTransform(prim), dtype=np.float64)
        else:
            cache = self.xform_cache(prim)
            rel = np.eye(4) if prim == ctx.root else np.array(
                cache.ComputeRelativeTransform(prim, ctx.root)[0], dtype=np.float64)
            base = rel @ ctx.matrix
        label = self.name_of(prim, ctx)
        pred = Usd.TraverseInstanceProxies(Usd.PrimIsActive & Usd.PrimIsLoaded)
        for k in range(proto_indices.size):
            if mask and not mask[k]:
                continue
            proto = protos[int(proto_indices[k])]
            if not proto:
                continue
            proto_path, inst_path = str(proto.GetPath()), where
            if proto_path.startswith(inst_path + "/"):
                proto_label = f"{label}[{k}]{proto_path[len(inst_path):]}"
            else:
                proto_label = f"{label}[{k}]/{proto.GetName()}"
            sub = _Context(root=proto, matrix=xforms[k] @ base, label=proto_label,
                           instance=f"{ctx.instance} [instance {k}]")
            self.active_instancers.add(where)
            try:
                self.walk(proto, pred, purpose, sub)
            finally:
                self.active_instancers.discard(where)

    def _refuse_nonfinite_instances(self, pi, where: str, xforms: np.ndarray) -> None:
        """Refuse (one ``LopcookError``) a PointInstancer whose instance transforms (``xforms``,
        (n, 4, 4)) hold NaN or Inf, naming the first such instance and the per-instance array
        that holds it: no placement can be made of it, and dropping the instance silently (it
        would look like a zero scale) hides the defect."""
        bad = ~np.isfinite(xforms).all(axis=(1, 2))
        if not bad.any():
            return
        k = int(np.argmax(bad))
        for name in ("positions", "orientations", "orientationsf", "scales", "velocities", "angularVelocities"):
            getter = getattr(pi, f"Get{name[0].upper()}{name[1:]}Attr", None)
            value = self.get(getter()) if getter is not None else None
            if value is None or len(value) == 0:
                continue
            arr = np.asarray(value, dtype=np.float64).reshape(len(value), -1)
            rows = np.flatnonzero(~np.isfinite(arr).all(axis=1))
            if rows.size:
                k = int(rows[0])
                what = "NaN" if np.isnan(arr[k]).any() else "Inf"
                self.fail(f"PointInstancer {where}: {name}[{k}] is {what} {_one_line(str(value[k]), self.path)}; "
                          f"{int(rows.size)} of {len(value)} instances are not finite",
                          hint="fix or remove those instances in the authoring tool")
        self.fail(f"PointInstancer {where}: the transform of instance {k} is NaN or Inf",
                  hint="fix the instancer's positions, orientations and scales in the authoring tool")

    # ------------------------------------------------------------------ mesh data
    def read_mesh(self, prim, key: str) -> _LocalMesh | None:
        """The mesh ``prim`` in its own space, triangulated and split into vertices (one per
        distinct point and per-corner attributes); None (and a warning) without faces."""
        from pxr import UsdGeom  # usd-core: heavy and optional, imported where a stage is read

        mesh = UsdGeom.Mesh(prim)
        where = str(prim.GetPath())
        topology = self.topology(mesh, where)
        if topology is None:
            return None
        points, counts, fvi = topology
        n_faces = counts.size
        keep_face = counts >= 3
        small = int(n_faces - keep_face.sum())
        if small:
            self.warnings.append(f"{where}: {small} faces with fewer than 3 corners skipped")
        holes = self.get(mesh.GetHoleIndicesAttr())
        if holes is not None and len(holes):
            holes = np.asarray(holes, dtype=np.int64).ravel()
            valid = (holes >= 0) & (holes < n_faces)
            if not valid.all():
                self.warnings.append(f"{where}: {int((~valid).sum())} holeIndices out of range ignored")
            keep_face[holes[valid]] = False
        face_of_corner = np.repeat(np.arange(n_faces, dtype=np.int64), counts)
        kept = np.flatnonzero(keep_face[face_of_corner])  # corner ids of kept faces
        if kept.size == 0:
            self.warnings.append(f"{where}: mesh has no faces with 3 or more corners, skipped")
            return None
        k_point = fvi[kept]
        try:
            tri_local, _ = triangulate(counts[keep_face], points[k_point])  # (T, 3) into ``kept``
        except PolygonTooComplex as exc:
            self.fail(f"{where}: {exc}", hint=exc.hint)
        geom = dict(where=where, n_faces=n_faces, n_points=points.shape[0], n_corners=fvi.size,
                    face=face_of_corner[kept], point=k_point, kept=kept)
        (normals, nvary), (uvs, uvvary), (colors, cvary) = self.primvars(prim, mesh, geom)
        tangents, tvary = self.tangents(prim, normals, geom)
        # split: one vertex per distinct (point, per-corner attributes) over the kept corners
        cols = [k_point[:, None]]
        for values, vary in ((normals, nvary), (uvs, uvvary), (colors, cvary), (tangents, tvary)):
            if values is not None and vary:
                cols.append(_bits64(values))
        first, inverse = unique_rows(np.concatenate(cols, axis=1) if len(cols) > 1 else cols[0])
        tris = inverse[tri_local]
        if str(self.get(mesh.GetOrientationAttr()) or "rightHanded") == "leftHanded":
            tris = tris[:, [0, 2, 1]]
        return _LocalMesh(
            key=key,
            points=points[k_point[first]],
            tris=np.ascontiguousarray(tris),
            normals=None if normals is None else normals[first],
            uvs=None if uvs is None else uvs[first],
            colors=None if colors is None else colors[first],
            texture=self.texture(prim),
            double_sided=self.get(mesh.GetDoubleSidedAttr()) is True,
            tangents=None if tangents is None else tangents[first],
        )

    def topology(self, mesh, where: str):
        """``(points (n, 3) float64, faceVertexCounts (F,) int64, faceVertexIndices (C,) int64)``
        checked (finite points, counts >= 0 summing to C, indices in range), or None (and a
        warning) for a mesh without points or faces. A subdivision scheme is a warning."""
        from pxr import UsdGeom  # usd-core: heavy and optional, imported where a stage is read

        pts = self.get(mesh.GetPointsAttr())
        counts = self.get(mesh.GetFaceVertexCountsAttr())
        fvi = self.get(mesh.GetFaceVertexIndicesAttr())
        if pts is None or len(pts) == 0 or counts is None or len(counts) == 0 or fvi is None:
            self.warnings.append(f"{where}: mesh has no points or faces, skipped")
            return None
        points = np.asarray(pts, dtype=np.float64).reshape(-1, 3)
        counts = np.asarray(counts, dtype=np.int64).ravel()
        fvi = np.asarray(fvi, dtype=np.int64).ravel()
        n_points = points.shape[0]
        scheme_attr = mesh.GetSubdivisionSchemeAttr()
        if scheme_attr and scheme_attr.HasAuthoredValue():
            scheme = str(scheme_attr.Get())
            if scheme != UsdGeom.Tokens.none:
                self.warnings.append(f"{where}: subdivisionScheme is {scheme}: its control mesh is cooked, not the "
                                     f"subdivided surface (lopcook does not subdivide; re-export it subdivided, or "
                                     f"set subdivisionScheme to none if the mesh is polygonal)")
        finite = np.isfinite(points).all(axis=1)
        if not finite.all():
            self.fail(f"{where}: {int((~finite).sum())} of {n_points} points are NaN or Inf "
                      f"(first at point {int(np.flatnonzero(~finite)[0])})",
                      hint="fix the mesh in the authoring tool")
        if (counts < 0).any():
            self.fail(f"{where}: faceVertexCounts has a negative count ({int(counts.min())})")
        n_corners = int(counts.sum())
        if n_corners != fvi.size:
            self.fail(f"{where}: sum(faceVertexCounts) = {n_corners} but faceVertexIndices has {fvi.size} entries",
                      hint="the topology arrays are inconsistent; re-export the mesh")
        if fvi.size and (fvi.min() < 0 or fvi.max() >= n_points):
            bad = int(fvi.max()) if fvi.max() >= n_points else int(fvi.min())
            self.fail(f"{where}: faceVertexIndices has index {bad} out of range for {n_points} points "
                      f"(max index {int(fvi.max())})",
                      hint="the topology does not match the points; re-export the mesh")
        return points, counts, fvi

    def primvars(self, prim, mesh, geom: dict):
        """``((normals, vary), (uvs, vary), (colors, vary))``: per kept corner values (or None)
        and whether they vary per corner (then they split vertices). UVs as ``(u, 1 - v)``; colours
        RGBA in [0, 1] from ``displayColor`` and ``displayOpacity``."""
        from pxr import UsdGeom  # usd-core: heavy and optional, imported where a stage is read

        api = UsdGeom.PrimvarsAPI(prim)
        where = geom["where"]
        normals = uvs = colors = None
        nvary = uvvary = cvary = False
        pv = api.GetPrimvar("normals")
        if pv and pv.HasAuthoredValue():
            normals, nvary = self.corner_values(pv, "primvars:normals", 3, **geom)
        else:
            attr = mesh.GetNormalsAttr()
            if attr.HasAuthoredValue():
                value = self.get(attr)
                if value is not None:
                    normals, nvary = self.spread("normals", np.asarray(value), None,
                                                 str(mesh.GetNormalsInterpolation()), 3, **geom)
        if normals is not None:
            length = np.linalg.norm(np.asarray(normals, dtype=np.float64), axis=1)
            bad = int((~(length > 1e-20)).sum())
            if bad:  # as the glTF and OBJ readers: said, not silently replaced
                self.warnings.append(f"{where}: {bad} normals are zero or not finite (replaced by +Y)")
        uv_pv = self.uv_primvar(api)
        if uv_pv is not None:
            uvs, uvvary = self.corner_values(uv_pv, uv_pv.GetName(), 2, **geom)
            if uvs is not None:
                uvs[:, 1] = 1.0 - uvs[:, 1]
        pv = api.GetPrimvar("displayColor")
        if pv and pv.HasAuthoredValue():
            rgb, cvary = self.corner_values(pv, "primvars:displayColor", 3, **geom)
            if rgb is not None:
                alpha = np.ones((rgb.shape[0], 1), np.float32)
                opv = api.GetPrimvar("displayOpacity")
                if opv and opv.HasAuthoredValue():
                    a, avary = self.corner_values(opv, "primvars:displayOpacity", 1, **geom)
                    if a is not None:
                        alpha, cvary = a, cvary or avary
                colors = np.clip(np.concatenate([rgb, alpha], axis=1), 0.0, 1.0).astype(np.float32)
        return (normals, nvary), (uvs, uvvary), (colors, cvary)

    def tangents(self, prim, normals, geom: dict):
        """``primvars:tangents`` per kept corner, ``((C, 4) float64, varies-per-corner)`` or
        ``(None, False)``. USD has no schema for tangents; lopcook reads this primvar as glTF's
        TANGENT: 4 components (xyz, handedness w), or 3 (handedness +1). Made usable by the rule
        every loader shares (``build.usable_tangents``: dropped without normals)."""
        from pxr import UsdGeom  # usd-core: heavy and optional, imported where a stage is read

        pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar("tangents")
        if not (pv and pv.HasAuthoredValue()):
            return None, False
        kind = str(pv.GetTypeName())
        width = _TANGENT_TYPES.get(kind)
        if width is None:
            self.warnings.append(f"{geom['where']}: primvars:tangents has type {_one_line(kind, self.path)}, not "
                                 "float3[] or float4[]; ignored")
            return None, False
        values, vary = self.corner_values(pv, "primvars:tangents", width, **geom)
        if values is None:
            return None, False
        if width == 3:
            values = np.concatenate([values, np.ones((values.shape[0], 1))], axis=1)
        return usable_tangents(values, normals, self.warnings.append, geom["where"]), vary

    def uv_primvar(self, api):
        """The UV-set primvar (see UV_NAMES), or None."""
        candidates = []
        for pv in api.GetPrimvarsWithAuthoredValues():
            tn = pv.GetTypeName()
            if tn.isArray and str(tn.scalarType) in _UV_TYPES:
                candidates.append(pv)
        by_name = {str(pv.GetPrimvarName()): pv for pv in candidates}
        for name in UV_NAMES:
            if name in by_name:
                return by_name[name]
        for pv in candidates:
            if pv.GetTypeName().role == "TextureCoordinate":
                return pv
        return None

    def corner_values(self, pv, label: str, width: int, **geom):
        """Primvar -> ((C, width) float32 per kept corner, varies-per-corner) or (None, False)."""
        where = geom["where"]
        if pv.GetElementSize() != 1:
            self.fail(f"{where}: {label} has elementSize {pv.GetElementSize()}, only 1 is supported")
        value = self.get(pv.GetAttr())
        if value is None:
            return None, False
        indices = self.get(pv.GetIndicesAttr())  # None when not authored or blocked
        return self.spread(label, np.asarray(value), None if indices is None else np.asarray(indices),
                           str(pv.GetInterpolation()), width, **geom)

    def spread(self, label, values, indices, interp, width, *, where, n_faces, n_points, n_corners,
               face, point, kept):
        """Expand primvar ``values`` (indexed by ``indices`` if given) to the kept corners."""
        values = np.asarray(values, dtype=np.float64)
        if values.ndim == 0 or (values.ndim == 1 and width > 1 and values.size == width):
            values = values.reshape(1, width)  # a scalar (non-array) primvar, e.g. color3f displayColor
        elif values.ndim == 1 and width == 1:
            values = values[:, None]
        if values.ndim != 2 or values.shape[1] != width:
            self.fail(f"{where}: {label} has values of shape {values.shape}, expected (n, {width})")
        if indices is not None:
            indices = np.asarray(indices, dtype=np.int64).ravel()
            if indices.size and (indices.min() < 0 or indices.max() >= values.shape[0]):
                bad = int(indices.max()) if indices.max() >= values.shape[0] else int(indices.min())
                self.fail(f"{where}: {label}:indices has index {bad} out of range for {values.shape[0]} values",
                          hint="the primvar indices do not match its values; re-export the mesh")
            values = values[indices]
        required = {"constant": 1, "uniform": n_faces, "vertex": n_points, "varying": n_points,
                    "faceVarying": n_corners}.get(interp)
        if required is None:
            self.warnings.append(f"{where}: {label} has unknown interpolation {interp!r}, ignored")
            return None, False
        n = values.shape[0]
        if (interp == "constant" and n < 1) or (interp != "constant" and n != required):
            self.fail(f"{where}: {label} has {n} values for {interp} interpolation, expected {required}",
                      hint="the primvar length does not match the mesh topology; re-export the mesh")
        values = values.astype(np.float32)
        if interp == "constant":
            return np.repeat(values[:1], kept.size, axis=0), False
        if interp == "uniform":
            return values[face], True
        if interp in ("vertex", "varying"):
            return values[point], False
        return values[kept], True

    # ------------------------------------------------------------------ textures
    def texture(self, prim) -> Texture | None:
        from pxr import Ar, UsdShade  # usd-core: heavy and optional, imported where a stage is read

        try:
            material = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()[0]
        except Exception:  # noqa: BLE001 - a broken binding only loses the texture
            return None
        if not material:
            return None
        mkey = str(material.GetPath())
        if mkey in self.textures:
            return self.textures[mkey]
        tex = None
        shader = material.ComputeSurfaceSource()[0]
        if shader and shader.GetShaderId() == "UsdPreviewSurface" and shader.GetInput("diffuseColor"):
            for attr in shader.GetInput("diffuseColor").GetValueProducingAttributes():
                src = UsdShade.Shader(attr.GetPrim())
                if not src or src.GetShaderId() != "UsdUVTexture" or not src.GetInput("file"):
                    continue
                asset = self.get(src.GetInput("file").GetAttr())
                if asset is None or not asset.path:
                    continue
                resolved = asset.resolvedPath
                self.add_asset_dependency(src.GetInput("file").GetAttr(), asset.path, resolved)
                if bad_path_characters(asset.path):
                    self.fail(f"{mkey}: texture @{asset.path!r}@ names a file with a line break or NUL",
                              hint="rename the file and the asset path: such a name cannot be listed in a depfile")
                data = None
                problem = None
                if resolved and not Ar.IsPackageRelativePath(resolved):
                    problem = regular_file_problem(resolved)  # never open a FIFO or a device
                if resolved and problem is None:
                    try:
                        handle = Ar.GetResolver().OpenAsset(Ar.ResolvedPath(resolved))
                        data = bytes(handle.GetBuffer()) if handle else None
                    except Exception:  # noqa: BLE001 - unreadable texture: warn below
                        data = None
                if data:
                    tex = checked_texture(os.path.basename(asset.path), data, self.warnings.append,
                                          f"{mkey}: texture @{asset.path}@")
                elif problem is not None and problem != "not found":
                    self.warnings.append(f"{mkey}: texture @{asset.path}@ {problem}, ignored")
                else:
                    self.warnings.append(f"{mkey}: texture @{asset.path}@ not found or unreadable, ignored")
                break
        self.textures[mkey] = tex
        return tex

    # ------------------------------------------------------------------ parts
    def build(self) -> Scene:
        names = unique_names([n for n, _, _, _ in self.parts])
        parts: list[MeshPart] = []
        for name, (_, source, local, m) in zip(names, self.parts):
            if not np.isfinite(m).all():  # a NaN or Inf xformOp: no placement can be made of it
                self.fail(f"{source}: its world transform holds NaN or Inf (an xformOp of it or of an ancestor)",
                          hint="fix the transform in the authoring tool")
            det = float(np.linalg.det(m[:3, :3]))
            if det == 0.0 or not np.isfinite(det):  # as the glTF reader: nothing to draw, no grid to stretch
                self.warnings.append(f"{source}: world transform is singular (zero scale); its mesh is skipped")
                continue
            parts.append(_place(name, source, local, m, self.settings))
        return Scene(parts=tuple(parts), source=self.path, format=self.fmt, unit_scale=self.meters_per_unit,
                     up_axis=self.up_axis, warnings=tuple(dict.fromkeys(self.warnings)),
                     dependencies=self.deps.paths())


def _package_outer(path: str) -> str:
    """``/a/b.usdz[c/d.usdc]`` -> ``/a/b.usdz`` (the outermost package file); other paths as given."""
    from pxr import Ar  # usd-core: heavy and optional, imported where a stage is read

    if Ar.IsPackageRelativePath(path):
        return Ar.SplitPackageRelativePathOuter(path)[0]
    return path


def _layer_file(layer) -> str:
    """The file a (non-anonymous) layer was read from; the .usdz file for a layer in a package."""
    return _package_outer(layer.realPath) if layer.realPath else ""


#: the value types a ``primvars:tangents`` is read from, and their components
_TANGENT_TYPES = {f"{t}{k}[]": k for t in ("float", "double", "half") for k in (3, 4)} | {
    f"{t}3{p}[]": 3 for t in ("vector", "normal") for p in ("f", "d", "h")}


def _bits64(values: np.ndarray) -> np.ndarray:
    """(C, k) float32 -> (C, ceil(k/2)) int64 holding the bit patterns (-0.0 folded into 0.0)."""
    v = np.asarray(values, dtype=np.float32) + np.float32(0.0)
    if v.shape[1] % 2:
        v = np.concatenate([v, np.zeros((v.shape[0], 1), np.float32)], axis=1)
    return np.ascontiguousarray(v).view(np.int64)


def _place(name: str, source: str, local: _LocalMesh, m: np.ndarray, settings: IngestSettings) -> MeshPart:
    """One placement of a mesh: ``m`` (4, 4) row-vector matrix, object -> world metres +Y up."""
    lin = m[:3, :3]
    positions = local.points @ lin + m[3, :3]
    det = float(np.linalg.det(lin))
    tris = local.tris if det >= 0 else local.tris[:, [0, 2, 1]]
    normals = tangents = None
    if local.normals is not None and det != 0 and np.isfinite(det):
        normals = local.normals.astype(np.float64) @ np.linalg.inv(lin).T
        if local.tangents is not None:
            tangents = placed_tangents(local.tangents, lin, det)
    return make_part(name, positions, tris, settings=settings, normals=normals, uvs=local.uvs,
                     colors=local.colors, extra={"tangents": tangents}, source=source, texture=local.texture,
                     mesh_key=local.key, double_sided=local.double_sided)


def load(path: str, *, fmt: str, settings: IngestSettings) -> Scene:
    """Load a USD stage into an unvalidated Scene (``ingest.load`` validates it).

    Parameters
    ----------
    path : str
        The file as the user gave it (used in messages and ``Scene.source``).
    fmt : str
        ``"usda"``, ``"usdc"`` or ``"usdz"``, decided from the content by the caller (a ``.usd`` file
        may hold text or crate; USD itself also decides from the content).
    settings : IngestSettings
        ``usd_time`` selects the time code (see the module doc); ``crease_angle_deg`` is used when a
        mesh has no normals.

    Returns
    -------
    Scene with one part per drawn mesh placement: positions (n, 3) float64 world metres +Y up,
    indices (m, 3) uint32 counter-clockwise, optional normals (n, 3), uvs (n, 2, origin top-left)
    and colors (n, 4). ``parts`` is empty when nothing is drawn (validation then raises).

    Raises
    ------
    LopcookError for an unreadable file, composition errors, inconsistent topology, out-of-range
    indices, NaN/Inf points and primvars whose length does not match their interpolation.
    """
    if not isolate._available():
        return _load_here(path, fmt, settings)
    try:  # USD's native parsers in a child: a crash (e.g. a stack overflow) becomes one clear error
        if _usd_started_here():
            return isolate.call_fresh(_load_in_child, path, fmt, settings)
        return isolate.call(_load_in_child, path, fmt, settings, faces=isolate.MIN_FACES)
    except isolate.ChildFailed as exc:
        why = str(exc).rsplit("(", 1)[-1].rstrip(")")
        cap = memory.address_space_limit()
        if cap is not None:  # under a memory cap the USD library crashes when an allocation fails
            raise LopcookError("ingest", path, f"USD crashed while reading the file ({why}) under a "
                               f"{cap / 1e9:.2g} GB address-space limit: the file may need more memory than "
                               "that, or be corrupt", hint="raise the limit (ulimit -v, lopcook batch "
                               "--worker-memory), or check the file with usdchecker") from None
        raise LopcookError("ingest", path, f"USD crashed while reading the file ({why}); the file is corrupt "
                           "or nests its hierarchy too deeply for the USD library",
                           hint="check the file with usdchecker, or flatten and re-export it") from None


def _usd_started_here() -> bool:
    """Whether this process has loaded USD (``pxr``): its TBB thread pool may then be running, and
    a forked child would wait forever for workers that were not copied (seen as a hung test run:
    ``arena::request_workers`` in the child), even with ``Work.SetConcurrencyLimit(1)``. Such a
    process (a library user, a test run) reads USD in a freshly spawned interpreter instead; the
    CLI never loads USD in its own process, so it keeps the cheap fork."""
    return "pxr" in sys.modules


def _load_in_child(path: str, fmt: str, settings: IngestSettings) -> Scene:
    """In the child process (forked from a process without USD, or freshly spawned): ``load`` there."""
    return _load_here(path, fmt, settings)


def _load_here(path: str, fmt: str, settings: IngestSettings) -> Scene:
    """``load`` in this process."""
    try:
        from pxr import Tf, Usd  # noqa: F401 - usd-core: heavy and optional, imported where a stage is read
    except ImportError as exc:  # pragma: no cover - usd-core is a dependency
        raise LopcookError("ingest", path, f"USD support needs usd-core: {exc}",
                           hint="pip install usd-core") from None
    loader = _Loader(path, fmt, settings)
    loader.open()
    try:
        with _captured_stderr() as lines:
            loader.run()
    except Tf.ErrorException as exc:
        raise LopcookError("ingest", path, f"USD error while reading the stage: {_one_line(_tf_text(exc), path)}",
                           hint="the file is corrupt or uses data lopcook cannot read") from None
    loader.warnings.extend(f"USD: {_one_line(_diagnostic_text(ln), path)}" for ln in lines)
    return loader.build()


# ---------------------------------------------------------------------------------------------
# Materials for decoded previews (docs/format.md 9.2)
# ---------------------------------------------------------------------------------------------

#: UsdPreviewSurface's diffuseColor default (linear)
USD_DEFAULT_DIFFUSE = 0.18
#: UsdUVTexture wrap token -> glTF sampler wrap mode
_WRAP_GLTF = {"repeat": 10497, "clamp": 33071, "mirror": 33648}


def materials(path: str, parts: list[dict], out: MaterialSet) -> list[dict | None]:
    """The ``UsdPreviewSurface`` bound to each manifest part's prim (its ``source`` without the
    ``[instance k]`` suffix) as glTF 2.0 core; None where the prim is not on the stage.

    ``diffuseColor`` (value or ``UsdUVTexture``), ``metallic`` and ``roughness`` (values; textures
    packed into one metallic-roughness image, G = roughness, B = metallic, from the channel each
    connection reads), ``opacity`` (< 1: BLEND) and ``opacityThreshold`` (> 0: MASK with that
    cutoff), ``normal``, ``emissiveColor`` and ``occlusion`` textures; the mesh's ``doubleSided``.
    A prim without a bound preview surface gets UsdPreviewSurface's defaults (metallic 0,
    roughness 0.5) and asks for its vertex colours, else ``USD_DEFAULT_DIFFUSE`` grey, as base
    colour (``materials.BASE_FROM_VERTEX_COLOURS``). A broken shading network costs only that
    part's material (a warning). Raises ``ValueError`` when the stage does not open.
    """
    reader = _UsdMaterials(path, out)
    per_part = []
    cache: dict = {}
    for p in parts:
        prim_path = re.sub(r" \[instance \d+\]$", "", str(p.get("source", "")))
        if prim_path not in cache:
            prim = reader.stage.GetPrimAtPath(prim_path) if prim_path.startswith("/") else None
            try:
                cache[prim_path] = reader.material(prim) if prim else None
            except Exception as exc:  # noqa: BLE001 - a broken shading network only loses the material
                why = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
                out.warn(f"{prim_path}: material unreadable ({why}); default material")
                cache[prim_path] = None
        per_part.append(cache[prim_path])
    return per_part


class _UsdMaterials:
    """One opened stage, its preview surfaces read as glTF materials into ``out``."""

    def __init__(self, path: str, out: MaterialSet) -> None:
        from pxr import Usd  # usd-core: heavy and optional, imported where a stage is read

        self.stage = Usd.Stage.Open(path)
        if self.stage is None:
            raise ValueError("the stage does not open")
        self.out = out

    def read_asset(self, asset) -> tuple[bytes, str] | None:
        """``(bytes, file name)`` of a texture asset through the resolver (``.usdz`` too), or None."""
        from pxr import Ar  # usd-core: heavy and optional, imported where a stage is read

        resolved = asset.resolvedPath
        if not resolved:
            self.out.warn(f"texture @{asset.path}@ not found; left out of the preview")
            return None
        handle = Ar.GetResolver().OpenAsset(Ar.ResolvedPath(resolved))
        data = bytes(handle.GetBuffer()) if handle else b""
        if not data:
            self.out.warn(f"texture @{asset.path}@ unreadable; left out of the preview")
            return None
        return data, os.path.basename(asset.path)

    @staticmethod
    def source_of(shader, name: str):
        """(value, None) or (None, (UsdUVTexture shader, output channel name)) for an input."""
        from pxr import UsdShade  # usd-core: heavy and optional, imported where a stage is read

        inp = shader.GetInput(name)
        if not inp:
            return None, None
        for attr in inp.GetValueProducingAttributes():
            prim = attr.GetPrim()
            if prim.IsA(UsdShade.Shader) and attr.GetName().startswith("outputs:"):
                src = UsdShade.Shader(prim)
                if src.GetShaderId() == "UsdUVTexture":
                    return None, (src, attr.GetName().split(":", 1)[1])
                continue
            return attr.Get(), None
        return None, None

    def texture(self, src) -> int | None:
        """The preview texture of a ``UsdUVTexture`` (its file and wrap modes), or None."""
        shader, _ = src
        f = shader.GetInput("file")
        asset = f.Get() if f else None
        if asset is None or not asset.path:
            return None
        smp = {}
        for key in ("wrapS", "wrapT"):
            w = shader.GetInput(key)
            v = w.Get() if w else None
            if v in _WRAP_GLTF:
                smp[key] = _WRAP_GLTF[v]
        return self.out.texture(self.out.image(("usd", asset.resolvedPath or asset.path),
                                               lambda: self.read_asset(asset)), smp or None)

    def packed_mr(self, metal_src, rough_src) -> int | None:
        """One metallic-roughness PNG (G roughness, B metallic) from USD's separate textures."""
        chans = {}
        for label, src in (("metallic", metal_src), ("roughness", rough_src)):
            if src is None:
                continue
            f = src[0].GetInput("file")
            asset = f.Get() if f else None
            got = self.read_asset(asset) if asset is not None and asset.path else None
            if got is None or not image_readable(got[0]):
                continue
            with Image.open(io.BytesIO(got[0])) as im:
                band = "rgba".find(src[1]) if src[1] in ("r", "g", "b", "a") else 0
                im = im.convert("RGBA")
                chans[label] = (np.asarray(im)[:, :, band], got[1])
        if not chans:
            return None
        h = max(c[0].shape[0] for c in chans.values())
        w = max(c[0].shape[1] for c in chans.values())
        img = np.full((h, w, 3), 255, np.uint8)
        for label, slot in (("roughness", 1), ("metallic", 2)):
            if label in chans:
                band = Image.fromarray(chans[label][0]).resize((w, h), Image.BILINEAR) \
                    if chans[label][0].shape != (h, w) else Image.fromarray(chans[label][0])
                img[:, :, slot] = np.asarray(band)
        buf = io.BytesIO()
        Image.fromarray(img, "RGB").save(buf, format="PNG", optimize=False)
        key = ("usd-mr",) + tuple(sorted(c[1] for c in chans.values()))
        return self.out.texture(self.out.image(key, lambda: (buf.getvalue(), "metallicRoughness.png")), None)

    def material(self, prim) -> dict:
        """The glTF material of ``prim``'s bound preview surface (see ``materials``)."""
        from pxr import UsdGeom, UsdShade  # usd-core: heavy and optional, imported where a stage is read

        mat = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()[0]
        shader = mat.ComputeSurfaceSource()[0] if mat else None
        double = bool(UsdGeom.Mesh(prim).GetDoubleSidedAttr().Get()) if prim.IsA(UsdGeom.Mesh) else False
        if not shader or shader.GetShaderId() != "UsdPreviewSurface":
            res = {BASE_FROM_VERTEX_COLOURS: USD_DEFAULT_DIFFUSE,
                   "pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 0.5}}
            if double:
                res["doubleSided"] = True
            return res
        pbr: dict = {}
        res: dict = {"name": mat.GetPrim().GetName(), "pbrMetallicRoughness": pbr}
        alpha, osrc = self.base_colour(shader, pbr)
        self.metallic_roughness(shader, pbr)
        for usd_name, key in (("normal", "normalTexture"), ("occlusion", "occlusionTexture"),
                              ("emissiveColor", "emissiveTexture")):
            v, s = self.source_of(shader, usd_name)
            if s is not None:
                t = self.texture(s)
                if t is not None:
                    res[key] = {"index": t}
                    if key == "emissiveTexture":
                        res["emissiveFactor"] = [1.0, 1.0, 1.0]
            elif usd_name == "emissiveColor" and v is not None and any(float(c) > 0 for c in v):
                res["emissiveFactor"] = [float(np.clip(c, 0, 1)) for c in v]
        threshold, _ = self.source_of(shader, "opacityThreshold")
        if threshold is not None and float(threshold) > 0 and (alpha < 1.0 or osrc is not None):
            res["alphaMode"], res["alphaCutoff"] = "MASK", float(threshold)
        elif alpha < 1.0:
            res["alphaMode"] = "BLEND"
        if double:
            res["doubleSided"] = True
        return res

    def base_colour(self, shader, pbr: dict) -> tuple[float, object]:
        """Set ``pbr``'s base colour factor and texture from ``diffuseColor`` and ``opacity``;
        return (alpha, the opacity's texture source or None)."""
        value, src = self.source_of(shader, "diffuseColor")
        rgb = [1.0, 1.0, 1.0] if src is not None else \
            [float(x) for x in (value if value is not None else (0.18, 0.18, 0.18))]
        opacity, osrc = self.source_of(shader, "opacity")
        alpha = 1.0 if opacity is None else float(np.clip(opacity, 0.0, 1.0))
        pbr["baseColorFactor"] = [float(np.clip(c, 0, 1)) for c in rgb] + [alpha]
        if src is not None:
            t = self.texture(src)
            if t is not None:
                pbr["baseColorTexture"] = {"index": t}
        return alpha, osrc

    def metallic_roughness(self, shader, pbr: dict) -> None:
        """Set ``pbr``'s metallic and roughness factors and packed texture."""
        mv, msrc = self.source_of(shader, "metallic")
        rv, rsrc = self.source_of(shader, "roughness")
        pbr["metallicFactor"] = 1.0 if msrc is not None else float(np.clip(0.0 if mv is None else mv, 0, 1))
        pbr["roughnessFactor"] = 1.0 if rsrc is not None else float(np.clip(0.5 if rv is None else rv, 0, 1))
        if msrc is not None or rsrc is not None:
            t = self.packed_mr(msrc, rsrc)
            if t is not None:
                pbr["metallicRoughnessTexture"] = {"index": t}
            else:  # textures unreadable: back to the defaults
                pbr["metallicFactor"] = 0.0 if msrc is not None else pbr["metallicFactor"]
                pbr["roughnessFactor"] = 0.5 if rsrc is not None else pbr["roughnessFactor"]


# ---------------------------------------------------------------------------------------------
# The format
# ---------------------------------------------------------------------------------------------

#: extension -> the kinds a file so named may hold (USD itself decides text or crate from content)
EXTENSIONS = {
    ".usd": ("usda", "usdc", "usdz"),
    ".usda": ("usda", "usdc"),
    ".usdc": ("usdc", "usda"),
    ".usdz": ("usdz",),
}


def sniff(head: bytes) -> str | None:
    """``"usdc"`` (crate magic ``PXR-USDC``), ``"usdz"`` (a zip: ``PK\\x03\\x04``) or ``"usda"``
    (``#usda`` after whitespace)."""
    if head.startswith(b"PXR-USDC"):
        return "usdc"
    if head.startswith(b"PK\x03\x04"):
        return "usdz"
    if head.lstrip().startswith(b"#usda"):
        return "usda"
    return None


FORMAT = Format(name="usd", title="USD", extensions=EXTENSIONS, load=load, sniff=sniff, materials=materials,
                requires="pxr", install="pip install usd-core")

__all__ = ["load", "materials", "sniff", "UV_NAMES", "EXTENSIONS", "FORMAT", "USD_DEFAULT_DIFFUSE"]
