"""LOD chains: simplify each part to a chain of coarser meshes and measure each one's error.

This work is based on: Garland and Heckbert, "Surface Simplification Using Quadric Error
Metrics", SIGGRAPH 1997 (every backend is a quadric edge collapse). The whole description, with
the reasons for each rule: docs/lod.md, "The chain driver in full".

``lod_chain(part, ratios, backend, ...) -> (lods, report)``: ``lods[0]`` is the part itself
(error 0), then simplifications to ``round(ratio * n0)`` triangles for ratios 1/2, 1/4, 1/8, ...
(or those given). The chain stops at the first LOD whose error exceeds ``max_error_m`` (metres: no
distance would select it; it is not kept) or the limit of ``stop_rule`` (``--lods auto``:
``lopcook.simplify.stop``), when a target falls below ``min_triangles``, or when no backend can
make a LOD; ``LodReport.stop`` records why.

- Backends (``SELECTABLE``): ``"pymeshlab"`` (MeshLab's quadric collapse, texture-aware with
  UVs), ``"fast"`` (fast-simplification), ``"meshopt"`` (meshoptimizer: output vertices are input
  vertices), ``"auto"`` (meshoptimizer, and on inputs of at most ``AUTO_BOTH_TRIANGLES``
  triangles pymeshlab too, the lower measured error kept).
- UV seams (``SEAM_MODES``): ``"lock"`` keeps every seam exactly (``SeamStats`` equal, a failure
  otherwise); ``"simplify"`` simplifies them with the mesh; ``"auto"`` simplifies them and,
  where that misses its target, also ignores them (the better kept); ``"ignore"`` transfers UVs
  from LOD 0; ``"xatlas"`` makes a
  fresh atlas (the texture is dropped: re-bake it).
- Attributes: copied bit for bit from LOD 0 where every LOD vertex is a LOD 0 vertex, else the
  closest-point transfer from LOD 0 with corners split again at creases and seams
  (``lopcook.simplify.transfer``); normals unit length, colours in [0, 1].
- Error (metres, against LOD 0 whatever ``chain``): ``Lod.hausdorff_m`` the measured symmetric
  Hausdorff distance (the LOD's vertices and centroids, a deterministic sample of LOD 0's
  vertices: a lower bound of the continuous distance); ``Lod.error_bound_m`` an upper bound of the
  distance of every LOD vertex and centroid and every LOD 0 vertex to the other mesh;
  ``Lod.error_m`` = max(hausdorff_m, previous error_m), non-decreasing along the chain.
- Failures never raise for mesh-quality reasons: a backend that raises, returns unusable data,
  flips more than ``max_flipped_fraction`` of the faces or misses its target by more than 2x falls
  back to the others; a LOD none can make ends the chain (``Lod.failed``); each is a note. Inputs
  of ``isolate.MIN_FACES`` faces or more are simplified in a forked child (a crash is a failure).
- Deterministic: the same part and arguments give the same chain.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from .. import isolate
from ..memory import release_free_memory
from ..mesh import degenerate_mask
from ..settings import DEFAULT_LOD_LEVELS, halvings
from ..types import MeshPart
from .backends import BACKENDS, SELECTABLE, TOPOLOGY_BLIND, check_result, parametrise_xatlas, prepare, run_backend
from .error import hausdorff, sampled_ref_to_lod
from .reference import Reference
from .stop import StopRule, breach_text, limit, part_extent
from .topology import SeamStats, mesh_defects, seam_stats
from .transfer import transfer_attributes
from .types import BackendFailure

SEAM_MODES = ("lock", "simplify", "ignore", "xatlas", "auto")

#: a LOD whose triangle count is off its target by more than this fraction gets a note
TARGET_TOLERANCE = 0.05

#: with locked seams, a LOD that runs into them is redone at this many times the count reached
_SHORT_OF_WALL = 1.1

#: parts with fewer triangles are never simplified
MIN_SIMPLIFY_TRIANGLES = 4

#: a result with more flipped faces than this fraction counts as a failure
MAX_FLIPPED_FRACTION = 0.02

#: ``backend="auto"`` runs pymeshlab as well as meshoptimizer on inputs of at most this many
#: triangles (where pymeshlab costs well under a second and can measure lower: docs/lod.md)
AUTO_BOTH_TRIANGLES = 100_000
#: ``backend="auto"``: LODs of at most ``AUTO_TINY_TARGET`` triangles are also made from LOD 0
#: when it has at most ``AUTO_TINY_LOD0`` (one simplification of LOD 0 per such LOD: docs/lod.md)
AUTO_TINY_TARGET = 64
AUTO_TINY_LOD0 = 20_000

#: a LOD the chain makes again from LOD 0 (its target missed from the previous LOD) falls back to
#: the other backends only where LOD 0 has at most this many triangles; above it they would spend
#: minutes on a LOD the same backends have just failed to make from the previous LOD (measured:
#: docs/lod.md)
RETRY_FALLBACK_TRIANGLES = 100_000


@dataclass
class Lod:
    """One level of detail of a part.

    part : MeshPart  the simplified mesh (positions float64, indices uint32 CCW, attributes
        carried over); for LOD 0 the input part itself
    target_ratio : float  requested fraction of LOD 0's triangles
    target_triangles : int  ``round(target_ratio * n0)``
    triangles : int  triangles actually produced
    hausdorff_m : float  measured symmetric Hausdorff distance to LOD 0, metres: the LOD's vertices
        and centroids against LOD 0, and a deterministic sample of LOD 0's vertices against the
        LOD (a lower bound of the continuous distance; see the module doc)
    error_m : float  monotone envelope along the chain (``max`` with the previous LOD's error_m)
    backend : str  ``"pymeshlab"``, ``"fast"``, ``"meshopt"``, ``"source"`` (LOD 0 / not simplified) or ``"none"``
        (every backend failed)
    seams : str  the seam mode actually used (``"lock"``, ``"simplify"``, ``"ignore"``,
        ``"xatlas"``; ``"-"`` without UVs)
    seconds : float  wall time of simplification, transfer and measurement
    notes : list[str]  fallbacks, warnings, missed targets
    one_sided_m : (float, float)  (LOD -> LOD 0, LOD 0 -> LOD) distances, metres
    flipped : int  faces facing away from LOD 0's nearby faces (kept when under the threshold)
    failed : bool  no backend produced this LOD; ``part`` is then the input it started from
    seam_stats : SeamStats or None  UV seams of the result (None without UVs)
    error_bound_m : float  an upper bound of the distance from every LOD vertex and centroid and
        every LOD 0 vertex to the other mesh (what the sample of LOD 0 can miss is at most
        ``error_bound_m - hausdorff_m``; ``lopcook.simplify.error.sampled_ref_to_lod``)
    """

    part: MeshPart
    target_ratio: float
    target_triangles: int
    triangles: int
    hausdorff_m: float
    error_m: float
    backend: str
    seams: str
    seconds: float
    notes: list = field(default_factory=list)
    one_sided_m: tuple = (0.0, 0.0)
    flipped: int = 0
    failed: bool = False
    seam_stats: "SeamStats | None" = None
    error_bound_m: float = 0.0

    def summary(self) -> dict:
        """JSON-friendly description (no arrays)."""
        return {
            "target_ratio": self.target_ratio, "target_triangles": self.target_triangles,
            "triangles": self.triangles, "vertices": self.part.n_vertices,
            "hausdorff_m": self.hausdorff_m, "error_m": self.error_m,
            "one_sided_m": list(self.one_sided_m), "error_bound_m": self.error_bound_m, "backend": self.backend, "seams": self.seams,
            "seconds": round(self.seconds, 6), "flipped": self.flipped, "failed": self.failed,
            "seam_stats": None if self.seam_stats is None else self.seam_stats.as_dict(),
            "notes": list(self.notes),
        }


@dataclass
class LodReport:
    """What ``lod_chain`` did for one part. ``max_error_m``: the largest error a kept LOD could have
    (the tighter of the view cap and the stop rule; None: no limit); ``stop`` (a
    ``lopcook.simplify.stop.STOP_CODES`` code) and ``stop_reason`` (words): why the chain ended;
    ``dropped``: ``{"triangles", "error_m", "target_ratio"}`` of the LOD made and then dropped, or
    None; ``extent_m``: the part's largest extent (metres, ``stop.part_extent``)."""

    part: str
    backend: str
    seams: str
    chain: str
    triangles: int
    max_error_m: float | None
    stop_reason: str = ""
    fallbacks: int = 0
    seconds: float = 0.0
    defects: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    lods: list = field(default_factory=list)
    stop: str = ""
    dropped: dict | None = None
    extent_m: float = 0.0

    def as_dict(self) -> dict:
        return {"part": self.part, "backend": self.backend, "seams": self.seams, "chain": self.chain,
                "triangles": self.triangles, "max_error_m": self.max_error_m,
                "stop_reason": self.stop_reason, "stop": self.stop, "dropped": self.dropped,
                "extent_m": self.extent_m, "fallbacks": self.fallbacks,
                "seconds": round(self.seconds, 6), "defects": dict(self.defects),
                "notes": list(self.notes), "lods": list(self.lods)}

    def ended(self, code: str, reason: str, dropped: dict | None = None) -> None:
        """Record why the chain ended: a ``STOP_CODES`` code, its words, the LOD made and dropped."""
        self.stop, self.stop_reason, self.dropped = code, reason, dropped


def _xatlas_part(part: MeshPart) -> MeshPart:
    vmap, ind, uv = parametrise_xatlas(part.positions, part.indices)
    attrs = {k: v[vmap] for k, v in part.attributes.items()}
    attrs["uvs"] = uv
    return replace(part, positions=np.ascontiguousarray(part.positions[vmap]), indices=ind.astype(np.uint32),
                   attributes=attrs, texture=None)


def parametrise(part: MeshPart) -> MeshPart:
    """``part`` with a fresh xatlas atlas as its UVs (vertices split at the atlas seams; the other
    attributes copied). Any texture is dropped: it does not match the new atlas (re-bake it)."""
    return _xatlas_part(part)


def _unchanged(part: MeshPart, ref: Reference, ratio: float, target: int, t0: float, notes: list,
               seams: str, failed: bool = False, backend: str = "source") -> Lod:
    if part is ref.part:
        h = (0.0, 0.0, 0.0)
    else:
        h = hausdorff(part, ref.part)
    mode = "-" if part.uvs is None else seams
    return Lod(part=part, target_ratio=ratio, target_triangles=target, triangles=part.n_triangles,
               hausdorff_m=h[0], error_m=h[0], backend=backend, seams=mode, seconds=time.perf_counter() - t0,
               notes=notes, one_sided_m=(h[1], h[2]), failed=failed, error_bound_m=h[0],
               seam_stats=seam_stats(part) if part.uvs is not None else None)


def _better(a: Lod, b: Lod) -> bool:
    """Whether LOD ``a`` is better than ``b`` for the same target: one produced, then one within
    ``TARGET_TOLERANCE`` of it, then the lower measured error (``b`` on ties)."""
    if a.failed != b.failed:
        return not a.failed
    near_a = abs(a.triangles - a.target_triangles) <= TARGET_TOLERANCE * a.target_triangles
    near_b = abs(b.triangles - b.target_triangles) <= TARGET_TOLERANCE * b.target_triangles
    if near_a != near_b:
        return near_a
    return a.hausdorff_m < b.hausdorff_m


def _simplify_auto(part: MeshPart, ratio: float, target: int, seams: str, ref: Reference,
                   preserve_boundary: bool, fallback: bool, max_flipped_fraction: float,
                   on_part=None) -> tuple[Lod, int]:
    """``backend="auto"``: meshoptimizer; on inputs of at most ``AUTO_BOTH_TRIANGLES`` triangles
    pymeshlab too (falling back to fast as usual when ``fallback``), keeping the better
    (``_better``) with a note giving both errors."""
    t0 = time.perf_counter()
    alone = part.n_triangles > AUTO_BOTH_TRIANGLES  # meshopt's LOD is the only candidate
    lod, used = _simplify(part, ratio, target, "meshopt", seams, ref, preserve_boundary, fallback,
                          max_flipped_fraction, on_part=on_part if alone else None)
    if alone or lod.backend == "source":
        return lod, used
    # pymeshlab with its usual fallback (fast), as a pymeshlab chain would make this LOD
    other, used2 = _simplify(part, ratio, target, "pymeshlab", seams, ref, preserve_boundary, fallback,
                             max_flipped_fraction)
    if seams == "auto" and part.uvs is not None and part is ref.part:
        # and, for a LOD made from LOD 0 (a chain's first LOD, or a retry from LOD 0),
        # fast-simplification with the seams locked, which keeps every seam exactly: kept where it
        # reaches the target with a lower error (the Chessboard at 1/2: docs/lod.md). Locked seams
        # reach a target most easily at the first halving.
        locked, used3 = _simplify(part, ratio, target, "fast", "lock", ref, preserve_boundary, False,
                                  max_flipped_fraction, _retry=True)
        if _better(locked, other):
            other, used2 = locked, used3
    keep, drop = (other, lod) if _better(other, lod) else (lod, other)
    what = "failed" if drop.failed else f"{drop.triangles} triangles, {drop.hausdorff_m:.3g} m"
    keep.notes.append(f"auto: {keep.backend} kept ({keep.triangles} triangles, {keep.hausdorff_m:.3g} m); "
                      f"{drop.backend if not drop.failed else ('meshopt' if keep is other else 'pymeshlab')} {what}")
    keep.seconds = time.perf_counter() - t0
    return keep, used + (used2 if keep is other else 0)


def _seams_auto(part: MeshPart, ratio: float, target: int, backend: str, ref: Reference,
                preserve_boundary: bool, fallback: bool, max_flipped_fraction: float,
                on_part=None) -> tuple[Lod, int]:
    """``seams="auto"``: ``"simplify"``; where that misses its target by more than
    ``TARGET_TOLERANCE`` (seam vertices the backend will not collapse) also ``"ignore"``, keeping
    the better (``_better``) with a note."""
    t0 = time.perf_counter()
    lod, used = _simplify(part, ratio, target, backend, "simplify", ref, preserve_boundary, fallback,
                          max_flipped_fraction, on_part=on_part if part.uvs is None else None)
    if part.uvs is None or lod.backend == "source" or (
            not lod.failed and abs(lod.triangles - target) <= TARGET_TOLERANCE * target):
        return lod, used
    other, used2 = _simplify(part, ratio, target, backend, "ignore", ref, preserve_boundary, fallback,
                             max_flipped_fraction)
    if not _better(other, lod):
        return lod, used
    what = "failed" if lod.failed else f"stopped at {lod.triangles} triangles ({lod.hausdorff_m:.3g} m)"
    other.notes = [n for n in other.notes if not n.startswith("UV seams changed")] + [
        f"seams: simplify {what}; the mesh welded by position reached {other.triangles} triangles "
        f"({other.hausdorff_m:.3g} m), its UVs transferred from LOD 0 (kept)"]
    other.seconds = time.perf_counter() - t0
    return other, used + used2


def _simplify(part: MeshPart, ratio: float, target: int, backend: str, seams: str, ref: Reference,
              preserve_boundary: bool, fallback: bool, max_flipped_fraction: float,
              _retry: bool = False, on_part=None) -> tuple[Lod, int]:
    """One LOD; returns (lod, fallbacks used). ``on_part(part)``: called with the LOD's mesh as
    soon as its attributes are transferred, before its error is measured (the cook starts the
    LOD's analysis then; the chain may still drop or replace it).

    (1) ``"auto"`` backend or seams: the choice between two runs (``_simplify_auto``,
    ``_seams_auto``); (2) inputs too small to simplify, or a target at or above the input: the
    input unchanged; (3) each backend in turn (the one asked for, then the others when
    ``fallback``) until one gives a usable result (``_attempt``), measured (``_measured``) and,
    with locked seams, stopped short of the wall it ran into (``_short_of_wall``); (4) none did:
    a failed LOD (the input)."""
    t0 = time.perf_counter()
    notes: list = []
    if backend not in SELECTABLE:
        raise ValueError(f"backend must be one of {SELECTABLE}, got {backend!r}")
    if backend == "auto":
        return _simplify_auto(part, ratio, target, seams, ref, preserve_boundary, fallback, max_flipped_fraction,
                              on_part)
    if seams == "auto":
        return _seams_auto(part, ratio, target, backend, ref, preserve_boundary, fallback, max_flipped_fraction,
                           on_part)
    if seams not in SEAM_MODES:
        raise ValueError(f"seams must be one of {SEAM_MODES}, got {seams!r}")
    if part.n_triangles < MIN_SIMPLIFY_TRIANGLES:
        notes.append(f"{part.n_triangles} triangles (< {MIN_SIMPLIFY_TRIANGLES}): not simplified")
        return _unchanged(part, ref, ratio, target, t0, notes, seams), 0
    if target >= part.n_triangles:
        notes.append(f"target {target} >= {part.n_triangles} input triangles: not simplified")
        return _unchanged(part, ref, ratio, target, t0, notes, seams), 0
    attempts = [backend] + ([b for b in BACKENDS if b != backend] if fallback else [])
    source = _Input(part, ref, notes)
    used_fallbacks = 0
    for i, name in enumerate(attempts):
        mode = seams if part.uvs is not None else "-"
        if mode == "simplify" and name == "fast":
            notes.append("fast cannot simplify seams with the mesh: seams='ignore' used")
            mode = "ignore"
        try:
            lod_part, info, stats = _attempt(source, name, mode, target, preserve_boundary, max_flipped_fraction)
        except Exception as exc:  # noqa: BLE001 - any backend failure falls back, never raises
            what = str(exc) if isinstance(exc, BackendFailure) else f"{type(exc).__name__}: {exc}"
            nxt = attempts[i + 1] if i + 1 < len(attempts) else None
            notes.append(f"{name} failed: {what}; " + (f"falling back to {nxt}" if nxt else "keeping the previous LOD"))
            used_fallbacks += 1 if nxt else 0
            continue
        lod = _measured(lod_part, info, stats, ref, ratio, target, name, mode, t0, notes, max_flipped_fraction,
                        on_part)
        if not _retry:
            alt = _short_of_wall(part, lod, seams, ref, preserve_boundary, max_flipped_fraction, t0)
            if alt is not None:
                return alt, used_fallbacks
        return lod, used_fallbacks
    source.nonmanifold()  # the note, where no backend ran
    lod = _unchanged(part, ref, ratio, target, t0, notes, seams, failed=True, backend="none")
    return lod, used_fallbacks


class _Input:
    """What every backend's try at one LOD shares about its input ``part``, each computed once:
    its zero-area face mask (``degenerate``, (faces,) bool), whether it is non-manifold
    (``nonmanifold``, which also puts the note first in ``notes``) and its UV seams (``seams``)."""

    def __init__(self, part: MeshPart, ref: Reference, notes: list):
        self.part, self.ref, self.notes = part, ref, notes
        # one zero-area mask for the defect counts and the backend's input
        self.degenerate = (ref.degenerate if part is ref.part
                           else degenerate_mask(part.positions, part.indices.astype(np.int64)))
        self._note_at = len(notes)
        self._bad: bool | None = None
        self._seams: SeamStats | None = None

    def nonmanifold(self) -> bool:
        """Whether the input has edges of more than two faces or bow-tie vertices (counted once;
        the note goes where it was when this object was made)."""
        if self._bad is None:
            part, ref = self.part, self.ref
            defects = ref.defects if part is ref.part else mesh_defects(part.positions, part.indices, self.degenerate)
            self._bad = defects["nonmanifold_edges"] > 0 or defects["nonmanifold_vertices"] > 0
            if self._bad:
                self.notes.insert(self._note_at, f"non-manifold input: {defects['nonmanifold_edges']} edges with "
                                                 f"more than two faces, {defects['nonmanifold_vertices']} bow-tie "
                                                 f"vertices (topology preservation off)")
        return self._bad

    def seams(self) -> SeamStats:
        """The input's ``SeamStats`` (it has UVs)."""
        if self._seams is None:
            self._seams = self.ref.seams if self.part is self.ref.part else seam_stats(self.part)
        return self._seams


def _attempt(source: _Input, name: str, mode: str, target: int, preserve_boundary: bool,
             max_flipped_fraction: float):
    """Backend ``name``'s LOD of ``source.part`` in seam mode ``mode``: ``(LOD mesh, the transfer's
    info dict, its SeamStats or None)``; BackendFailure (or any exception) when it is unusable.

    (1) the input welded or split for the mode (``prepare``), zero-area faces dropped; (2) the
    backend run, in a forked child for large inputs (``isolate.begin``), while this process counts
    the defects and builds LOD 0's search structures; (3) its result checked (``check_result``);
    (4) the attributes transferred from LOD 0 (``transfer_attributes``); (5) with ``"xatlas"`` a
    fresh atlas; (6) with ``"lock"`` every seam must be kept."""
    part, ref, notes = source.part, source.ref, source.notes
    work_mode = "ignore" if mode in ("-", "xatlas") else mode
    work, dropped = prepare(part, work_mode, source.degenerate)
    msg = f"{dropped} zero-area faces dropped before simplification"
    if dropped and msg not in notes:
        notes.append(msg)
    if work.faces.shape[0] < MIN_SIMPLIFY_TRIANGLES:
        raise BackendFailure(f"only {work.faces.shape[0]} non-degenerate triangles")
    tgt = min(target, work.faces.shape[0] - 1)
    # large inputs: in a child process (its memory is freed on return; a crash is a failure). The
    # defect counts decide pymeshlab's topology flag; the other backends ignore it, so for them the
    # counts are made while the backend runs in its child (the note keeps its place)
    job = isolate.begin(run_backend, name, work, tgt, preserve_boundary,
                        topology=True if name in TOPOLOGY_BLIND else not source.nonmanifold(),
                        faces=work.faces.shape[0])
    try:  # forked: the defect counts and LOD 0's search structures, made while this process would only wait
        source.nonmanifold()  # first: its temporaries are freed before the structures are built
        if job.forked:
            ref.warm()
    except BaseException:
        job.cancel()
        raise
    raw = job.result()
    del job  # it holds the result too
    res, dropped_out = check_result(raw, tgt, work.faces.shape[0])
    del raw  # check_result copied what it keeps: the result's arrays are freed here
    if work.mode != "lock":
        # only the locked seams' UVs (transfer.lock_uvs) read the work mesh past the
        # backend: otherwise its arrays (welded positions, int64 faces) are freed before
        # the transfer and measurement, where the LOD's peak is
        work = replace(work, positions=None, faces=None, uvs=None)
    if dropped_out:
        notes.append(f"{name}: {dropped_out} degenerate faces dropped from its result")
    lod_part, info = transfer_attributes(res, ref, part, work, mode, max_flipped_fraction)
    del res, work  # not needed past the transfer; freed before the LOD's error tree is built
    if mode == "xatlas":
        try:
            lod_part = _xatlas_part(lod_part)
            notes.append("xatlas atlas: the source texture does not match it (texture dropped; re-bake)")
        except Exception as exc:  # noqa: BLE001 - a parametriser failure keeps transferred UVs
            notes.append(f"xatlas failed ({type(exc).__name__}: {exc}); UVs transferred instead")
    lod_part.validate()
    stats = seam_stats(lod_part)
    if mode == "lock" and stats != source.seams():
        raise BackendFailure(f"UV seams not kept with seams='lock' ({source.seams().as_dict()} -> "
                             f"{stats.as_dict()})")
    return lod_part, info, stats


def _measured(lod_part: MeshPart, info: dict, stats, ref: Reference, ratio: float, target: int, name: str,
              mode: str, t0: float, notes: list, max_flipped_fraction: float, on_part=None) -> Lod:
    """The ``Lod`` of a usable result ``lod_part`` (``_attempt``'s): its error measured against
    LOD 0 in both directions (metres: the transfer's LOD -> LOD 0 distance, the sampled LOD 0 ->
    LOD one, ``sampled_ref_to_lod``), with the notes on flipped faces, a missed target and changed
    seams. ``on_part(lod_part)`` is called first (before the measurement)."""
    if info["flipped"]:
        notes.append(f"{info['flipped']} faces face against the source surface (under the "
                     f"{max_flipped_fraction:.0%} threshold; kept)")
    if on_part is not None:
        on_part(lod_part)
    ref_to_lod, ref_to_lod_bound, _ = sampled_ref_to_lod(ref, lod_part, on_ref=info.pop("on_ref", None))
    release_free_memory()  # the transfer's and the LOD tree's temporaries
    h = max(info["lod_to_ref"], ref_to_lod)
    tri = lod_part.n_triangles
    if abs(tri - target) > TARGET_TOLERANCE * target:
        why = " (seams locked: faces touching a UV seam cannot be simplified)" if mode == "lock" else ""
        notes.append(f"{tri} triangles for a target of {target} ({(tri - target) / target:+.1%}){why}")
    if stats is not None and ref.seams is not None and stats != ref.seams and mode != "xatlas":
        notes.append(f"UV seams changed ({mode}): {ref.seams.as_dict()} -> {stats.as_dict()}")
    return Lod(part=lod_part, target_ratio=ratio, target_triangles=target, triangles=tri, hausdorff_m=h,
               error_m=h, backend=name, seams=mode, seconds=time.perf_counter() - t0, notes=notes,
               one_sided_m=(info["lod_to_ref"], ref_to_lod), flipped=info["flipped"], seam_stats=stats,
               error_bound_m=max(info["lod_to_ref"], ref_to_lod_bound))


def _short_of_wall(part: MeshPart, lod: Lod, seams: str, ref: Reference, preserve_boundary: bool,
                   max_flipped_fraction: float, t0: float) -> Lod | None:
    """With locked seams, a ``lod`` of ``part`` that stopped more than ``TARGET_TOLERANCE`` above
    its target ran into the seams: its last collapses were forced ones. The same backend is run
    again to ``_SHORT_OF_WALL`` times the count reached (no fallback); that LOD, with the notes
    merged, when its error is under half of ``lod``'s, else None."""
    tri, target, h, notes = lod.triangles, lod.target_triangles, lod.hausdorff_m, lod.notes
    short = int(round(tri * _SHORT_OF_WALL))
    if not (lod.seams == "lock" and tri > (1 + TARGET_TOLERANCE) * target and short < part.n_triangles):
        return None
    alt, _ = _simplify(part, lod.target_ratio, short, lod.backend, seams, ref, preserve_boundary, False,
                       max_flipped_fraction, _retry=True)
    if alt.failed or not alt.hausdorff_m < 0.5 * lod.hausdorff_m:
        return None
    miss = " triangles for a target of "
    alt.notes = ([n for n in notes if miss not in n and " faces face against " not in n]
                 + [f"seams locked: the backend stopped at {tri} triangles with error {h:.3g} m; "
                    f"stopping short at {alt.triangles} triangles gives {alt.hausdorff_m:.3g} m (kept); "
                    f"{alt.triangles} triangles for a target of {target} "
                    f"({(alt.triangles - target) / target:+.1%})"]
                 + [n for n in alt.notes if n not in notes and miss not in n])
    alt.target_triangles = target
    alt.seconds = time.perf_counter() - t0
    return alt


def simplify(part: MeshPart, ratio: float, backend: str = "pymeshlab", *, seams: str = "lock",
             reference: MeshPart | None = None, preserve_boundary: bool = True, fallback: bool = True,
             max_flipped_fraction: float = MAX_FLIPPED_FRACTION) -> Lod:
    """Simplify ``part`` to ``round(ratio * reference.n_triangles)`` triangles (``reference``
    defaults to ``part``; it is LOD 0 for error measurement and attribute transfer).

    Never raises for mesh-quality reasons: failures fall back to the other backend (when
    ``fallback``) and are recorded in ``Lod.notes``; when nothing works ``Lod.failed`` is True
    and ``Lod.part`` is ``part``. ``preserve_boundary`` locks open-boundary vertices in both
    backends (always on with ``seams="lock"``, where seams are boundaries). ``seams`` is one of
    ``SEAM_MODES`` (see the module doc); it matters only for parts with UVs.
    """
    ref = Reference(reference if reference is not None else part)
    target = int(round(ratio * ref.part.n_triangles))
    return _simplify(part, float(ratio), target, backend, seams, ref, preserve_boundary, fallback,
                     max_flipped_fraction)[0]


def lod_chain(part: MeshPart, ratios=None, backend: str = "pymeshlab", *, max_error_m: float | None = None,
              min_triangles: int = MIN_SIMPLIFY_TRIANGLES, seams: str = "lock", chain: str = "previous",
              parametrise: bool = False, preserve_boundary: bool = True, fallback: bool = True,
              max_flipped_fraction: float = MAX_FLIPPED_FRACTION, max_levels: int = DEFAULT_LOD_LEVELS,
              on_lod=None, stop_rule: StopRule | None = None):
    """A LOD chain for one part: ``(lods, report)`` with ``lods[0]`` = LOD 0 (the part, error 0).

    ratios : fractions of LOD 0's triangles in decreasing order (default 1/2, 1/4, 1/8, ... while
        the target is at least ``min_triangles``; at most ``max_levels`` LODs)
    max_error_m : the largest error any kept LOD may have (metres): the error the farthest view
        can still show. The first LOD above it is dropped and ends the chain. None: no limit.
    stop_rule : ``lopcook.simplify.stop.StopRule`` or None: the ``--lods auto`` rule, a limit of
        its own from the part's extent (the tighter limit applies; ``report.stop`` says which)
    chain : ``"previous"`` simplifies each LOD from the one before, ``"source"`` from LOD 0
    parametrise : give a part without UVs an xatlas atlas first (LOD 0 then has UVs)
    on_lod : ``on_lod(k, part)`` is called as LOD k (k >= 1) joins the chain, before the next is
        made; it may also be called earlier with a candidate for LOD k, as soon as that mesh
        exists (before its error is measured, so the chain may still drop or replace it): the cook
        starts its analysis then
    Other arguments as for ``simplify``. ``error_m`` is non-decreasing along the returned chain.

    Per ratio: (1) the LOD from the previous one (or from LOD 0) (``_simplify``); (2) made from
    LOD 0 as well where that missed its target or, with ``"auto"``, is tiny (``_again_from_lod0``);
    (3) kept, or the chain ends (``_accept``).
    """
    if chain not in ("previous", "source"):
        raise ValueError(f"chain must be 'previous' or 'source', got {chain!r}")
    t0 = time.perf_counter()
    extent = part_extent(part.positions)
    max_error_m, breach = limit(extent, max_error_m, stop_rule)
    report = LodReport(part=part.name, backend=backend, seams=seams, chain=chain, triangles=part.n_triangles,
                       max_error_m=max_error_m, extent_m=extent)
    if parametrise and part.uvs is None:
        try:
            part = _xatlas_part(part)
            report.notes.append("no UVs: LOD 0 parametrised with xatlas (no texture to carry)")
        except Exception as exc:  # noqa: BLE001
            report.notes.append(f"xatlas parametrisation failed ({type(exc).__name__}: {exc}); no UVs")
    ref = Reference(part)
    lod0 = Lod(part=part, target_ratio=1.0, target_triangles=part.n_triangles, triangles=part.n_triangles,
               hausdorff_m=0.0, error_m=0.0, backend="source", seams="-" if part.uvs is None else seams,
               seconds=0.0, seam_stats=ref.seams)
    lods = [lod0]
    n0 = part.n_triangles
    args = (backend, seams, ref, preserve_boundary, fallback, max_flipped_fraction)
    if n0 < MIN_SIMPLIFY_TRIANGLES:
        report.ended("small", f"{n0} triangles (< {MIN_SIMPLIFY_TRIANGLES}): LOD 0 only")
        report.notes.append(report.stop_reason)
    else:
        for ratio in _ratios(ratios, n0, min_triangles, max_levels, report):
            target = int(round(ratio * n0))
            if target < min_triangles:
                report.ended("min_triangles", f"target {target} below min_triangles {min_triangles}")
                break
            start = lods[-1].part if chain == "previous" else part
            # the cook's analysis of this LOD starts as soon as its mesh exists (``on_lod`` again
            # below keeps that start when the chain accepts the same mesh)
            early = None if on_lod is None else (lambda p, k=len(lods): on_lod(k, p))
            lod, used = _simplify(start, ratio, target, *args, on_part=early)
            report.fallbacks += used
            if start is not part:
                lod = _again_from_lod0(lod, part, ratio, target, args, early, report)
            if not _accept(lod, lods, ratio, (max_error_m, breach, stop_rule), min_triangles, report):
                break
            lods.append(lod)
            if on_lod is not None:
                on_lod(len(lods) - 1, lod.part)
            report.notes.extend(f"LOD {ratio:g}: {n}" for n in lod.notes)
        else:
            if not report.stop_reason:
                report.ended("ratios", "all ratios done")
    report.defects = dict(ref.defects)  # counted during the first LOD's backend run where it forks
    report.lods = [lod.summary() for lod in lods]
    report.seconds = time.perf_counter() - t0
    return lods, report


def _ratios(ratios, n0: int, min_triangles: int, max_levels: int, report: LodReport) -> list[float]:
    """The chain's ratios, distinct, in (0, 1) and decreasing: ``ratios``, or by default the
    halvings of ``n0`` triangles down to ``min_triangles`` (at most ``max_levels``; none: the
    report's stop reason says so)."""
    if ratios is None:
        ratios = halvings(max_levels, n0, min_triangles)
        if not ratios:
            report.ended("min_triangles", f"no target of at least {min_triangles} triangles")
    return sorted({float(r) for r in ratios if 0 < float(r) < 1}, reverse=True)


def _again_from_lod0(lod: Lod, part: MeshPart, ratio: float, target: int, args: tuple, early,
                     report: LodReport) -> Lod:
    """``lod``, made from the previous LOD, or the same target made from LOD 0 ``part``: the
    previous LOD's collapses may block the target (``lod`` failed or missed it by more than
    ``TARGET_TOLERANCE``: the one nearer the target is kept) or, with ``backend="auto"``, decide a
    tiny LOD's shape (at most ``AUTO_TINY_TARGET`` triangles of a LOD 0 of at most
    ``AUTO_TINY_LOD0``: LOD 0's own collapse order is kept where it is better, or no larger and
    lower in error). ``args`` = (backend, seams, ref, preserve_boundary, fallback,
    max_flipped_fraction) as ``_simplify`` takes them; the fallbacks run from LOD 0 only where it
    has at most ``RETRY_FALLBACK_TRIANGLES`` triangles."""
    backend, seams, ref, preserve_boundary, fallback, max_flipped_fraction = args
    n0 = part.n_triangles
    missed = lod.failed or abs(lod.triangles - target) > TARGET_TOLERANCE * target
    # backend auto, a few dozen triangles: the previous LODs' collapses decide the shape, and
    # LOD 0's own collapse order can do much better (docs/lod.md)
    tiny = backend == "auto" and target <= AUTO_TINY_TARGET and n0 <= AUTO_TINY_LOD0
    if not (missed or tiny):
        return lod
    again, used2 = _simplify(part, ratio, target, backend, seams, ref, preserve_boundary,
                             fallback and n0 <= RETRY_FALLBACK_TRIANGLES, max_flipped_fraction, on_part=early)
    nearer = missed and not again.failed and (
        lod.failed or abs(again.triangles - target) < abs(lod.triangles - target))
    # a tiny LOD: kept when better, or no larger and lower in error (a triangle short of
    # a tiny target is not "near" it, yet no worse a LOD)
    lower = not nearer and tiny and (_better(again, lod) or (
        not again.failed and again.triangles <= lod.triangles and again.hausdorff_m < lod.hausdorff_m))
    if missed or lower:
        report.fallbacks += used2
    if nearer:
        again.notes.insert(0, f"simplified from LOD 0: from the previous LOD it "
                              f"{'failed' if lod.failed else f'gave {lod.triangles} triangles'}")
    elif lower:
        again.notes.insert(0, f"simplified from LOD 0: {again.hausdorff_m:.3g} m against "
                              f"{lod.hausdorff_m:.3g} m from the previous LOD")
    return again if nearer or lower else lod


def _accept(lod: Lod, lods: list, ratio: float, limit_of: tuple, min_triangles: int, report: LodReport) -> bool:
    """Whether ``lod`` joins the chain after ``lods[-1]``; setting its ``error_m`` to the monotone
    envelope max(hausdorff_m, previous error_m). ``limit_of`` = (the largest error a kept LOD may
    have or None, the stop code of a breach, the StopRule or None: ``stop.limit``). False (the
    chain ends, ``report.ended`` says why) when it failed, has no fewer triangles than the
    previous LOD, an error above the limit or fewer than ``min_triangles`` triangles."""
    previous, k = lods[-1], len(lods)
    max_error_m, breach, rule = limit_of
    made = {"triangles": int(lod.triangles), "error_m": float(max(lod.hausdorff_m, previous.error_m)),
            "target_ratio": float(ratio)}
    if lod.failed:
        report.ended("failed", f"LOD {k} (ratio {ratio:g}) could not be produced; previous LODs kept")
        report.notes.extend(f"LOD {ratio:g}: {n}" for n in lod.notes)
        return False
    if lod.triangles >= previous.triangles:
        report.ended("no_fewer", f"LOD {k} has {lod.triangles} triangles, no fewer than the previous "
                                 f"LOD's {previous.triangles}; dropped", made)
        report.notes.extend(f"LOD {ratio:g}: {n}" for n in lod.notes)
        return False
    if lod.hausdorff_m < previous.error_m:
        lod.notes.append(f"measured error {lod.hausdorff_m:.3g} m below the previous LOD's "
                         f"{previous.error_m:.3g} m: error_m raised to keep the chain monotone")
    lod.error_m = max(lod.hausdorff_m, previous.error_m)
    if max_error_m is not None and lod.error_m > max_error_m:
        report.ended(breach, breach_text(breach, f"LOD {k}", lod.triangles, lod.error_m, max_error_m,
                                         report.extent_m, rule), made)
        report.notes.extend(f"LOD {ratio:g}: {n}" for n in lod.notes)
        return False
    if lod.triangles < min_triangles:
        report.ended("min_triangles", f"LOD {k} has {lod.triangles} triangles (< {min_triangles}); dropped", made)
        return False
    return True


#: stop codes by which a chain ends where it should: a part with no LOD then is no shortfall
_BY_RULE = ("pixels", "relative_error", "view")

_MISSED = " triangles for a target of "


def _grouped(found: dict[str, list[str]]) -> list[str]:
    """``{line: [part, ...]}`` -> ``part 'A': line`` or ``part 'A' and 3 more: line``."""
    out = []
    for line, parts in found.items():
        who = f"part {parts[0]!r}" + (f" and {len(parts) - 1} more" if len(parts) > 1 else "")
        out.append(f"{who}: {line}")
    return out


def chain_warnings(reports: list[dict]) -> list[str]:
    """The LOD shortfalls a user must see, one line each, from ``LodReport.as_dict()`` records:
    LODs that missed their triangle target by more than ``TARGET_TOLERANCE`` (with the backend
    failures behind them), and parts that got no LODs although they could be simplified and no
    rule ended their chain at LOD 0 (``_BY_RULE``). A backend that failed where its fallback
    reached the target is information (``chain_notes``). Copies of one mesh share one line
    (``part A and 3 more``)."""
    found: dict[str, list[str]] = {}
    for rep in reports:
        lines = []
        for k, lod in enumerate(rep.get("lods") or []):
            notes = lod.get("notes") or []
            if any(_MISSED in n for n in notes):
                lines += [f"LOD {k}: {n}" for n in notes if " failed: " in n or _MISSED in n]
        if (len(rep.get("lods") or []) <= 1 and rep.get("triangles", 0) >= MIN_SIMPLIFY_TRIANGLES
                and rep.get("stop") not in _BY_RULE):
            lines.append(f"no LODs ({rep.get('stop_reason') or 'none produced'})")
        for line in lines:
            found.setdefault(line, []).append(rep["part"])
    return _grouped(found)


def chain_notes(reports: list[dict]) -> list[str]:
    """Information on the chains, one line each (``chain_warnings``' grouping): backends that failed
    on a LOD whose fallback reached its target."""
    found: dict[str, list[str]] = {}
    for rep in reports:
        for k, lod in enumerate(rep.get("lods") or []):
            notes = lod.get("notes") or []
            if not any(_MISSED in n for n in notes):
                for n in notes:
                    if " failed: " in n:
                        found.setdefault(f"LOD {k}: {n}", []).append(rep["part"])
    return _grouped(found)


__all__ = ["Lod", "LodReport", "simplify", "lod_chain", "chain_warnings", "chain_notes", "parametrise", "SEAM_MODES", "TARGET_TOLERANCE",
           "MIN_SIMPLIFY_TRIANGLES"]
