"""The one orchestrator of the stages: Scene + Settings -> CookResult (a container and what was done).

``run(scene, settings)`` goes ingest's Scene -> simplify -> analyse -> emit:

1. LOD chains per part (``lopcook.simplify.lod_chain``) when ``settings.simplify.lods`` is set;
   a chain's ``max_error_m`` is the error the farthest useful view can show (``far_error_m``:
   the distance at which the whole scene spans one pixel; no cap without ``viewing.nearest_m``),
   and ``--lods auto`` chains also stop by ``stop_rule`` (``lopcook.simplify.stop``), recorded
   per part in ``options.lods`` (``recorded``).
2. ONE grid fitted over every position of every part and every LOD.
3. Every LOD index k analysed on that grid (``analyse(scene_k, settings, grid=grid)``, scene_k =
   the parts that have a LOD k); then co-located vertices (same quantized position, any part,
   any LOD) share the maximum of their minimum levels, so no two buffers can crack apart.
4. LODs whose selection range is empty are dropped (``lopcook.selection.selection_ranges``); the
   others record ``min_distance_m``.
5. With ``viewing.nearest_m`` the highest level any view can use is
   ``required_level(nearest_m, extent, viewing)``; ``max_level`` = the larger of it and the
   highest minimum level of any vertex (no vertex clamped, no guarantee lost); planes above it
   are not written.
6. Emit: every buffer encoded once (``lopcook.emit.encode_buffer``); the savings record (planes
   not written, LODs dropped, bytes saved against the same container without them) is computed
   from the encoded buffers' sizes, without writing the larger container.

With ``simplify.hierarchy`` every part's LOD 0 buffer also gets its vertex hierarchy section
(``lopcook.hierarchy.container.add_hierarchy``), before the position sections.

LOD cooks of large scenes (``parallel``) use a second process: LOD 0 is analysed in a child while
the chains run (``speculate``), and the other analyses and the encodes are split by
``lopcook.isolate.fork_map``; the bytes are the one-process ones.

Without LODs and ``nearest_m`` (and ``max_level``) the bytes are exactly those of
``lopcook.emit.build(scene, analyse(scene, settings.analyse), viewing=settings.viewing)``.
Stages never change their inputs: the co-located sharing returns new level arrays.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from . import isolate, memory  # memory.available_bytes: read at call time
from .analyse import Analysis, analyse, colocated_max
from .analyse.result import REASON_CODE
from .analyse.attribute_bits import part_bits
from .emit import BufferInput, assemble, encode_buffer, plane_payload
from .lop.codecs import CODECS, AttributeBits
from .lop.container import Container, built, file_size, section_table
from .lop.placement import level_shift, local_level, mesh_grid, resident_level, sigma, touching_parts, transform_f32
from .errors import LopcookError
from .grid import BITS, Grid
from .hierarchy.container import add_hierarchy
from .memory import release_free_memory
from .progress import NONE, Progress
from .selection import selection_ranges
from .settings import DEFAULTS, Settings
from .simplify import lod_chain
from .simplify.instances import copies, placed_chain
from .simplify.stop import StopRule, manifest_record
from .simplify.parallel import run_chains
from .simplify.workers import workers as lod_workers
from .types import Scene
from .viewing import Viewing, required_level

#: LOD cooks of at least this many LOD 0 vertices analyse and encode in two processes (``parallel``)
PARALLEL_VERTICES = 100_000

#: ... and when the system has at least this much memory available per LOD 0 vertex: twice what the
#: analysis and encoding children add to the process tree per vertex (measured: docs/lod.md)
PARALLEL_BYTES_PER_VERTEX = 1600


def far_error_m(extent: float, viewing: Viewing) -> float:
    """The largest geometric error (metres) any useful view can show: at the distance where the
    whole scene (``extent`` metres) spans one pixel, ``pixel_error`` pixels are
    ``pixel_error * extent`` metres. A LOD with a larger error would only be selected for a
    sub-pixel scene."""
    return float(viewing.pixel_error) * float(extent)


def view_level(extent: float, viewing: Viewing) -> int | None:
    """Highest per-buffer level any view can use: ``required_level(nearest_m)``; None when
    ``viewing.nearest_m`` is unknown."""
    if viewing.nearest_m is None:
        return None
    return int(np.asarray(required_level(float(viewing.nearest_m), extent, viewing)))


@dataclass
class LodRow:
    """One buffer of the cook: triangles, vertices, ``error_m`` (metres from LOD 0),
    ``min_distance_m`` (None: dropped, no distance selects it), and, for kept buffers, its stored
    bytes (``lopcook.lop.manifest.LodEntry``'s accounting)."""

    triangles: int
    vertices: int
    error_m: float
    min_distance_m: float | None
    lod: int | None = None
    mandatory_position_bytes: int = 0
    plane_position_bytes: int = 0
    attribute_bytes: int = 0
    index_bytes: int = 0

    @property
    def kept(self) -> bool:
        return self.min_distance_m is not None

    def as_dict(self) -> dict:
        d = {"triangles": self.triangles, "vertices": self.vertices, "error_m": self.error_m,
             "min_distance_m": self.min_distance_m, "kept": self.kept}
        if self.lod is not None:
            d.update(lod=self.lod, mandatory_position_bytes=self.mandatory_position_bytes,
                     plane_position_bytes=self.plane_position_bytes, attribute_bytes=self.attribute_bytes,
                     index_bytes=self.index_bytes)
        return d


@dataclass
class CookResult:
    """What ``run`` did. ``container``: the parsed container with its bytes (``.data``);
    ``analysis``: the Analysis of LOD 0 of every part (warnings, touching pairs, stage timings);
    ``timings_s``: stage -> seconds; ``lods``: per part, its LodRows; ``lod_reports``: per part,
    the chain's ``LodReport.as_dict()`` (empty without LODs); ``buffers``: per part, the kept
    BufferInputs (only with ``keep_buffers``)."""

    container: Container
    analysis: Analysis
    timings_s: dict
    lods: list
    lod_reports: list = field(default_factory=list)
    grid_extent_m: float = 0.0
    lod_max_error_m: float | None = None
    view_level: int | None = None
    highest_min_level: int = 0
    max_level: int = BITS
    planes_dropped: list = field(default_factory=list)
    lods_dropped: int = 0
    bytes_without_savings: int = 0
    colocated_raised_across_lods: int = 0
    buffers: list | None = None
    calibration: dict | None = None
    budget: dict | None = None
    attribute_search: dict | None = None
    settings: Settings | None = None

    @property
    def data(self) -> bytes:
        return self.container.data

    @property
    def bytes(self) -> int:
        return len(self.container.data)

    @property
    def bytes_saved(self) -> int:
        return self.bytes_without_savings - self.bytes

    @property
    def vertices_clamped_to_max_level(self) -> int:
        return int(self.container.manifest["stats"]["vertices_clamped_to_max_level"])


def chains(scene: Scene, settings: Settings, max_error_m: float | None, progress: Progress = NONE,
           on_lod=None):
    """LOD chain and report of every part, in part order. Copies of one mesh
    (``lopcook.simplify.instances.copies``: same triangles and attributes, positions related by one
    affine map) are simplified once and the chain placed on every copy. Distinct meshes run in
    worker processes (``lopcook.simplify.parallel``; threads would not help: pymeshlab is not
    thread-safe, and fast-simplification and libigl hold the GIL); the result is the serial one.
    ``on_lod(k, part)``: called as a one-part scene's chain accepts its LOD k (``lod_chain``)."""
    ratios, backend = settings.simplify.lods.resolved(), settings.simplify.backend.value
    seams = settings.simplify.seams.value
    rule = stop_rule(settings)
    out, reports = [None] * len(scene.parts), [None] * len(scene.parts)
    groups = copies(scene.parts)
    with progress.stage("LOD chains", total=len(groups)) as st:
        # distinct meshes in parallel worker processes (lopcook.simplify.parallel: the serial result)
        done = run_chains([scene.parts[lead] for lead, _ in groups], progress=st.advance, chain=lod_chain,
                          ratios=list(ratios),
                          backend=backend, seams=seams, max_error_m=max_error_m, stop_rule=rule,
                          **({"on_lod": on_lod} if on_lod is not None and len(scene.parts) == 1 else {}))
        for (lead, members), (lods, report) in zip(groups, done):
            out[lead], reports[lead] = lods, report
            for i, a, t in members:
                out[i], reports[i] = placed_chain(lods, report, scene.parts[i], a, t, max_error_m, rule)
    return out, reports


def stop_rule(settings: Settings) -> StopRule | None:
    """The stop rule of ``settings``' chain (``lopcook.simplify.stop``): ``--lods auto``'s, under the
    cook's viewing conditions; None for explicit ratios (every LOD asked for is made) or no LODs."""
    lods = settings.simplify.lods
    return StopRule(settings.viewing) if lods is not None and lods.auto else None


def recorded(options: dict, reports: list[dict], settings: Settings) -> dict:
    """``options`` with ``options.lods`` holding the stop rule and, per part, where and why its
    chain stopped (``lopcook.simplify.stop.manifest_record``) for a ``--lods auto`` cook whose
    options record its LODs; else ``options`` as given."""
    rule = stop_rule(settings)
    if rule is None or not isinstance(options.get("lods"), dict):
        return options
    return dict(options, lods=dict(options["lods"], **manifest_record(reports, rule)))


def parallel(scene: Scene) -> bool:
    """Whether a LOD cook of ``scene`` analyses and encodes in forked processes beside its own
    (``lopcook.isolate``): two or more LOD workers (``lopcook.simplify.workers``,
    ``$LOPCOOK_LOD_WORKERS=1`` turns it off), at least ``PARALLEL_VERTICES`` LOD 0 vertices, and
    the system's available memory at least ``PARALLEL_BYTES_PER_VERTEX`` per vertex (the children
    add their working memory to the cook's; docs/performance.md). The bytes are the same either way."""
    n = sum(p.n_vertices for p in scene.parts)
    if lod_workers() < 2 or n < PARALLEL_VERTICES:
        return False
    avail = memory.available_bytes()
    return avail is None or avail >= PARALLEL_BYTES_PER_VERTEX * n


class Speculation:
    """Analyses started in forked children before their levels are final (``speculate``), each on
    ``grid``, the grid of LOD 0 alone: LOD 0's (every part) before the chains run, and, for a
    one-part scene, each further LOD's as its chain accepts it (``started``). ``take`` returns one
    only for exactly the parts it was started on and only when the cook's grid is ``grid``
    (meshoptimizer's LODs reuse LOD 0's vertices, so it is); otherwise the level is analysed as
    without it. The results are the ones analysing in place would give."""

    def __init__(self, scene: Scene, settings: Settings, grid: Grid):
        self.scene, self.settings, self.grid = scene, settings, grid
        self._children: dict = {0: (tuple(scene.parts), isolate.start(analyse, scene, settings.analyse, grid))}

    def started(self, k: int, part) -> None:
        """The one-part chain has ``part`` for its LOD ``k`` (a candidate, or the LOD it accepted):
        start its analysis, unless it was started on that very part already."""
        old = self._children.get(k)
        if old is not None and len(old[0]) == 1 and old[0][0] is part:
            return
        old = self._children.pop(k, None)
        if old is not None:
            old[1].cancel()
        sub = replace(self.scene, parts=(part,))
        self._children[k] = ((part,), isolate.start(analyse, sub, self.settings.analyse, self.grid))

    def take(self, k: int, parts, grid: Grid):
        """LOD ``k``'s Analysis if it was started on exactly ``parts`` (the same objects) on
        ``grid``; else None. Its child is gone either way."""
        got = self._children.pop(k, None)
        if got is None:
            return None
        own, child = got
        try:
            if grid == self.grid and len(own) == len(parts) and all(a is b for a, b in zip(own, parts)):
                return child.result()
        except isolate.ChildFailed:  # killed (memory): analysed in place instead
            return None
        finally:
            child.cancel()  # nothing once the result is in
        return None

    def cancel(self) -> None:
        for _, child in self._children.values():
            child.cancel()
        self._children = {}


def speculate(scene: Scene, settings: Settings) -> Speculation | None:
    """A ``Speculation`` for a ``parallel`` scene with LODs (LOD 0's analysis started), else None."""
    if settings.simplify.lods is None or not parallel(scene):
        return None
    return Speculation(scene, settings, Grid.fit([p.positions for p in scene.parts]))


def analyse_lods(scene: Scene, parts_chain, settings=DEFAULTS.analyse, grid: Grid | None = None,
                 progress: Progress = NONE, first: Speculation | None = None):
    """Analyse every LOD level on one grid, then share levels between co-located vertices.

    parts_chain: per part, its list of MeshParts (LOD 0 first). ``first``: the analyses
    ``speculate`` started, or None. Returns ``(grid, analyses, levels, raised)``: ``analyses[k]`` the
    Analysis of LOD index k (parts that have one, in part order; its ``min_level`` and ``reason``
    include the sharing), ``levels[i][k]`` the final (n,) uint8 minimum levels of part i's LOD k,
    ``raised`` how many vertices the sharing raised. Levels are analysed in forked processes for
    ``parallel`` scenes, with the same results."""
    grid = grid or Grid.fit([p.positions for chain in parts_chain for p in chain])
    depth = max(len(c) for c in parts_chain)
    members = [[i for i, c in enumerate(parts_chain) if len(c) > k] for k in range(depth)]
    scenes = [replace(scene, parts=tuple(parts_chain[i][k] for i in idx)) for k, idx in enumerate(members)]
    analyses: list = [None] * depth
    with progress.stage("analyse", total=depth) as st:
        if first is not None:
            try:
                for k in range(depth):
                    analyses[k] = first.take(k, scenes[k].parts, grid)
                    if analyses[k] is not None:
                        st.advance()
            finally:
                first.cancel()
        todo = [k for k in range(depth) if analyses[k] is None]
        workers = 2 if parallel(scene) else 1
        done = isolate.fork_map(lambda k: analyse(scenes[k], settings, grid=grid), todo,
                                weights=[sum(p.n_vertices for p in scenes[k].parts) for k in todo],
                                workers=workers)
        for k, an in zip(todo, done):
            analyses[k] = an
            st.advance()
    allq = np.concatenate([pa.quantized for an in analyses for pa in an.parts])
    alll = np.concatenate([pa.min_level.astype(np.int64) for an in analyses for pa in an.parts])
    shared = colocated_max(allq, alll)
    raised = int(np.count_nonzero(shared > alll))
    levels = [[None] * len(c) for c in parts_chain]
    start = 0
    for k, (an, idx) in enumerate(zip(analyses, members)):
        new_parts = []
        for i, pa in zip(idx, an.parts):
            final = shared[start:start + pa.min_level.shape[0]].astype(np.uint8)
            start += final.shape[0]
            if np.any(final > pa.min_level):
                reason = np.where(final > pa.min_level, np.uint8(REASON_CODE["co-located"]), pa.reason)
                pa = replace(pa, min_level=final, reason=reason.astype(pa.reason.dtype))
            new_parts.append(pa)
            levels[i][k] = final
        analyses[k] = replace(an, parts=new_parts)
    return grid, analyses, levels, raised


def _plain(scene: Scene, settings: Settings, options: dict, keep_buffers: bool, progress: Progress,
           analysis=None) -> CookResult:
    """No LODs, no viewing savings: one analysis (or the one given), one build."""
    timings: dict = {}
    t0 = time.perf_counter()
    with progress.stage("analyse", total=1) as st:
        if analysis is None:
            analysis = analyse(scene, settings.analyse)
        st.advance()
    timings["analyse"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    buffers = [[BufferInput(quantized=pa.quantized, min_level=pa.min_level, indices=p.indices,
                            attributes=dict(p.attributes), attribute_bits=part_bits(settings, i, p, pa))]
               for i, (p, pa) in enumerate(zip(scene.parts, analysis.parts))]
    encoded = [[encode_buffer(b, BITS, settings.emit.clusters, cluster_all=settings.emit.cluster_all) for b in bufs]
               for bufs in buffers]
    manifest, sections = assemble(scene, analysis.grid, encoded, max_level=BITS, options=options,
                                  viewing=settings.viewing)
    if settings.simplify.hierarchy:
        manifest, sections = add_hierarchy(manifest, sections, [e[0] for e in encoded], analysis.grid)
    container = built(manifest, sections)
    timings["emit"] = time.perf_counter() - t0
    rows = [[LodRow(triangles=p.n_triangles, vertices=p.n_vertices, error_m=0.0, min_distance_m=0.0)]
            for p in scene.parts]
    result = CookResult(container=container, analysis=analysis, timings_s=timings, lods=rows,
                        grid_extent_m=float(analysis.grid.extent),
                        highest_min_level=int(max(int(pa.min_level.max()) for pa in analysis.parts)),
                        bytes_without_savings=len(container.data), buffers=buffers if keep_buffers else None)
    account(result)
    return result


def _lod_stage(scene: Scene, settings: Settings, timings: dict, progress: Progress):
    """(1): per part its MeshParts and errors (LOD 0 alone without LODs), the reports, the cap,
    and the analyses ``speculate`` started (or None)."""
    first = speculate(scene, settings)
    try:
        return _lod_chains(scene, settings, timings, progress, first) + (first,)
    except BaseException:
        if first is not None:
            first.cancel()
        raise


def _lod_chains(scene: Scene, settings: Settings, timings: dict, progress: Progress,
                first: Speculation | None = None):
    t0 = time.perf_counter()
    cap = None
    if settings.viewing.nearest_m is not None:
        cap = far_error_m(Grid.fit([p.positions for p in scene.parts]).extent, settings.viewing)
    if settings.simplify.lods is not None:
        lods, reports = chains(scene, settings, cap, progress, on_lod=first.started if first is not None else None)
        parts_chain = [[lod.part for lod in c] for c in lods]
        errors = [[float(lod.error_m) for lod in c] for c in lods]
    else:
        parts_chain, errors, reports = [[p] for p in scene.parts], [[0.0] for _ in scene.parts], []
    release_free_memory()  # the chains' temporaries: back to the system before the analysis
    timings["lod"] = time.perf_counter() - t0
    return parts_chain, errors, [r.as_dict() for r in reports], cap


def _select(parts_chain, errors, analyses, levels, settings: Settings):
    """(4): per part every buffer (kept or not) and its LodRow; LODs no distance selects are
    dropped (LOD 0 is always kept)."""
    quantized = [[None] * len(c) for c in parts_chain]
    for k, an in enumerate(analyses):
        idx = [i for i, c in enumerate(parts_chain) if len(c) > k]
        for i, pa in zip(idx, an.parts):
            quantized[i][k] = pa.quantized
    with_lods = settings.simplify.lods is not None
    all_buffers, rows = [], []
    first = {i: pa for i, pa in zip([i for i, c in enumerate(parts_chain) if c], analyses[0].parts)}
    for i, chain in enumerate(parts_chain):
        ranges = selection_ranges(errors[i], [p.n_triangles for p in chain], settings.viewing)
        ranges[0] = 0.0
        bits = part_bits(settings, i, chain[0], first.get(i))  # one allocation for all LODs of a part
        all_buffers.append([BufferInput(quantized=quantized[i][k], min_level=levels[i][k], indices=p.indices,
                                        attributes=dict(p.attributes), attribute_bits=bits,
                                        geometric_error_m=errors[i][k],
                                        min_distance_m=ranges[k] if with_lods else None)
                            for k, p in enumerate(chain)])
        rows.append([LodRow(triangles=p.n_triangles, vertices=p.n_vertices, error_m=errors[i][k],
                            min_distance_m=ranges[k]) for k, p in enumerate(chain)])
    return all_buffers, rows


def _emit_with_savings(scene, grid, first: Analysis, all_buffers, rows, settings, options, max_level, vlevel,
                       highest_min):
    """(6): the container of the kept buffers up to ``max_level``; the savings record states the
    bytes saved against the container of every buffer with every plane. Each buffer is encoded
    once; the larger container's size comes from its manifest and section table."""
    kept_mask = [[r.kept for r in rs] for rs in rows]
    n, every = settings.emit.clusters, settings.emit.cluster_all
    flat = [b for bufs in all_buffers for b in bufs]  # encoded in two processes for parallel scenes
    done = iter(isolate.fork_map(lambda b: encode_buffer(b, BITS, n, cluster_all=every), flat,
                                 weights=[b.quantized.shape[0] for b in flat],
                                 workers=2 if parallel(scene) else 1))
    full_enc = [[next(done) for _ in bufs] for bufs in all_buffers]
    kept_enc = [[encode_buffer(b, max_level, n, cluster_all=every) if b.min_level.max() > max_level else e
                 for b, e, k in zip(bufs, encs, ks) if k]
                for bufs, encs, ks in zip(all_buffers, full_enc, kept_mask)]
    planes_dropped = list(range(max_level + 1, BITS + 1))
    lods_dropped = sum(not k for ks in kept_mask for k in ks)
    same = lods_dropped == 0 and all(a is b for ea, eb in zip(full_enc, kept_enc) for a, b in zip(ea, eb))
    kept_planes = {p: plane_payload([e for es in kept_enc for e in es], p) for p in range(2, max_level + 1)}
    full_manifest, full_sections = assemble(scene, grid, full_enc, max_level=BITS, options=options,
                                            viewing=settings.viewing, planes=kept_planes if same else None)
    trees: dict = {}  # one hierarchy per distinct LOD 0 encoding, shared by both containers
    if settings.simplify.hierarchy:
        full_manifest, full_sections = add_hierarchy(full_manifest, full_sections, [e[0] for e in full_enc],
                                                     grid, trees)
    full_size = file_size(full_manifest, section_table(full_sections)[0])
    del full_sections
    savings = None
    if planes_dropped or lods_dropped:  # recorded only when something was left out
        savings = {"planes_dropped": planes_dropped, "lods_dropped": int(lods_dropped), "bytes_saved": 0,
                   "bytes_without_savings": full_size, "view_level": vlevel, "highest_min_level": highest_min}
    manifest, sections = assemble(scene, grid, kept_enc, max_level=max_level, options=options,
                                  viewing=settings.viewing, savings=savings, planes=kept_planes)
    if settings.simplify.hierarchy:
        manifest, sections = add_hierarchy(manifest, sections, [e[0] for e in kept_enc], grid, trees)
    table = section_table(sections)[0]
    for _ in range(4):  # the record's own digits change the manifest size: settle to a fixed point
        saved = full_size - file_size(manifest, table)
        if savings is None or savings["bytes_saved"] == saved:
            break
        savings = dict(savings, bytes_saved=saved)
        manifest = dict(manifest, savings=savings)
    kept_buffers = [[b for b, k in zip(bufs, ks) if k] for bufs, ks in zip(all_buffers, kept_mask)]
    return built(manifest, sections), full_size, planes_dropped, lods_dropped, kept_buffers


def account(result: CookResult) -> None:
    """Fill every kept LodRow's byte counts from the container's typed manifest (the one
    accounting, ``lopcook.lop.manifest.LodEntry``)."""
    entries = result.container.entries
    for part, rows in zip(entries.parts, result.lods):
        for k, (row, e) in enumerate(zip([r for r in rows if r.kept], part.lods)):
            row.lod = k
            row.mandatory_position_bytes = e.mandatory_bytes
            row.plane_position_bytes = e.plane_bytes(entries.max_level)
            row.attribute_bytes = e.attribute_bytes
            row.index_bytes = e.index_bytes


def resolve_instances(scene: Scene, settings: Settings, *, budget: bool = False) -> Settings:
    """``settings`` with ``simplify.instances`` decided: the default (None) becomes True where the
    scene has copies of one mesh (``lopcook.simplify.instances.copies``: a group with a second
    member), at least two of which share no LOD 0 scene-grid cell with another part (the rest stay
    on the scene grid: ``placement_groups``), and the cook can store them once (no
    ``simplify.hierarchy``, no byte budget: ``budget`` or ``tune.target_bytes``); False otherwise.
    True and False are kept as given. Deterministic: it depends on the parts' contents only. (The
    cook's own grouping also looks at the LODs; where it then stores nothing once, ``run`` writes
    every copy as a part of its own, with no ``options.instances`` record.)"""
    if settings.simplify.instances is not None:
        return settings
    want = (len(scene.parts) >= 2 and not settings.simplify.hierarchy and not budget
            and settings.tune.target_bytes is None)
    if want:
        groups = [[lead] + [i for i, _, _ in members] for lead, members in copies(scene.parts) if members]
        if groups:
            grid = Grid.fit([p.positions for p in scene.parts])
            touching = touching_parts([grid.quantize(p.positions) for p in scene.parts], list(range(len(scene.parts))))
            want = any(int(np.count_nonzero(~touching[g])) >= 2 for g in groups)
        else:
            want = False
    return replace(settings, simplify=replace(settings.simplify, instances=want))


def plain(settings: Settings, max_level: int | None = None) -> bool:
    """Whether ``run`` cooks ``settings`` from one analysis of the scene as given (no LODs, no
    viewing savings; copies stored once or not): then ``run`` can take that analysis."""
    return settings.simplify.lods is None and settings.viewing.nearest_m is None and max_level is None


def run(scene: Scene, settings: Settings = DEFAULTS, *, options: dict | None = None, max_level: int | None = None,
        keep_buffers: bool = False, progress: Progress = NONE, analysis=None) -> CookResult:
    """Cook ``scene`` with ``settings`` (see module doc). ``options``: the manifest's options
    record (default ``settings.to_manifest()["options"]``). ``max_level``: highest plane to
    write (default from ``viewing.nearest_m``, 24 when unknown); given explicitly it is used as
    is (vertices above it are clamped and counted). ``keep_buffers``: also return the kept
    BufferInputs (for the byte-budget fit). ``progress``: stage reporting (``lopcook.progress``).
    ``analysis``: on the plain path (``plain``), the Analysis of ``scene`` and ``settings.analyse``
    already made (e.g. ``lopcook.analyse.prepared.PreparedAnalysis.analyse``, the same minimum
    levels as ``analyse``); ValueError on another path. ``simplify.instances`` None (the default) is
    decided here (``resolve_instances``; ``keep_buffers`` counts as a byte budget); where it stores
    copies once, ``options`` gets ``instances: true``."""
    options = settings.to_manifest()["options"] if options is None else options
    auto = settings.simplify.instances is None
    settings = resolve_instances(scene, settings, budget=keep_buffers)
    if auto and settings.simplify.instances:
        options = dict(options, instances=True)  # the default stores copies once: the record says so
    if analysis is not None and not plain(settings, max_level):
        raise ValueError("an analysis can be given only for a cook without LODs or viewing savings")
    if settings.simplify.instances:
        result = _instanced(scene, settings, options, max_level, keep_buffers, progress, auto=auto,
                            analysis=analysis)
        if result is not None:
            return result
        # the default, and the cook's grouping stored nothing once: every copy a part of its own,
        # no record (the bytes of the default before copies were stored once)
        settings = replace(settings, simplify=replace(settings.simplify, instances=False))
        options = {k: v for k, v in options.items() if k != "instances"}
    if plain(settings, max_level):
        return _plain(scene, settings, options, keep_buffers, progress, analysis)
    timings: dict = {}
    parts_chain, errors, reports, cap, first = _lod_stage(scene, settings, timings, progress)
    options = recorded(options, reports, settings)
    t0 = time.perf_counter()
    grid, analyses, levels, raised = analyse_lods(scene, parts_chain, settings.analyse, progress=progress,
                                                  first=first)
    release_free_memory()
    timings["analyse"] = time.perf_counter() - t0
    all_buffers, rows = _select(parts_chain, errors, analyses, levels, settings)
    highest_min = int(max(int(np.max(b.min_level)) for bufs, rs in zip(all_buffers, rows)
                          for b, r in zip(bufs, rs) if r.kept))
    vlevel = view_level(grid.extent, settings.viewing)
    if max_level is None:
        max_level = BITS if vlevel is None else max(vlevel, highest_min)
    t0 = time.perf_counter()
    container, full_size, planes_dropped, lods_dropped, kept = _emit_with_savings(
        scene, grid, analyses[0], all_buffers, rows, settings, options, int(max_level), vlevel, highest_min)
    timings["emit"] = time.perf_counter() - t0
    result = CookResult(container=container, analysis=analyses[0], timings_s=timings, lods=rows,
                        lod_reports=reports, grid_extent_m=float(grid.extent), lod_max_error_m=cap,
                        view_level=vlevel, highest_min_level=highest_min, max_level=int(max_level),
                        planes_dropped=planes_dropped, lods_dropped=int(lods_dropped),
                        bytes_without_savings=full_size, colocated_raised_across_lods=raised,
                        buffers=kept if keep_buffers else None)
    account(result)
    return result


def placement_groups(scene: Scene, parts_chain, quantized, rows) -> list[dict]:
    """The groups of copies ``--instances`` stores once (``lopcook.lop.placement``): per group
    ``{"lead": i, "members": [(part, A, t), ...]}`` (part order, at least two members; the lead's
    own entry is ``(lead, I, 0)`` when it is a member). A copy is left out (it stays on the scene
    grid) when one of its vertices shares a 24-bit scene-grid cell with another part's
    (``placement.touching_parts``, any LOD); members must have the same LOD chain length and the
    same kept LODs (``rows``), so that their LOD entries can name one buffer set."""
    flat, owner = [], []
    for i, qs in enumerate(quantized):
        for q in qs:
            flat.append(q)
            owner.append(i)
    touching = touching_parts(flat, owner)
    out = []
    for lead, members in copies(scene.parts):
        cands = [(lead, np.eye(3), np.zeros(3))] + list(members)
        by_key: dict = {}
        for i, a, t in cands:
            if touching[i]:
                continue
            key = (len(parts_chain[i]), tuple(r.kept for r in rows[i]))
            by_key.setdefault(key, []).append((i, a, t))
        for key in sorted(by_key, key=lambda k: by_key[k][0][0]):
            if len(by_key[key]) >= 2:
                out.append({"lead": lead, "members": by_key[key]})
    return out


def _instanced(scene: Scene, settings: Settings, options: dict, max_level: int | None, keep_buffers: bool,
               progress: Progress, auto: bool = False, analysis=None) -> CookResult | None:
    """``run`` with ``simplify.instances``: steps (1)-(4) as without it, then every group of copies
    (``placement_groups``) encoded once on its mesh grid, its minimum levels the maximum over its
    placements of the converted world levels (``lopcook.lop.placement`` states the bound), and
    every placement written as a part entry naming the group's buffers (attribute bits: the most
    any placement chose, ``_max_bits``). Parts not grouped are
    encoded on the scene grid exactly as without ``--instances``. No savings record is written.
    ``auto`` (the default decided ``instances``): None when no group is stored once, for ``run`` to
    cook the scene as without ``--instances``. ``analysis``: ``run``'s, on its ``plain`` path (LOD 0
    only): used for the scene's levels instead of analysing it again (the same levels: the
    co-located sharing ``analyse_lods`` applies is the one ``analyse`` made)."""
    if settings.simplify.hierarchy:
        raise LopcookError("usage", scene.source, "--instances does not combine with --hierarchy",
                           hint="cook with one of them")
    if keep_buffers:
        raise LopcookError("usage", scene.source, "--instances does not combine with a byte budget (--target-bytes)",
                           hint="cook without --instances")
    timings: dict = {}
    parts_chain, errors, reports, cap, grid, analyses, levels, raised = _instanced_levels(
        scene, settings, timings, progress, analysis)
    options = recorded(options, reports, settings)
    all_buffers, rows = _select(parts_chain, errors, analyses, levels, settings)
    t0 = time.perf_counter()
    groups = placement_groups(scene, parts_chain, [[b.quantized for b in bufs] for bufs in all_buffers], rows)
    placement, mesh_grids, group_buffers, shifts_of = _shared_buffers(groups, parts_chain, levels, all_buffers,
                                                                      grid)
    if auto and not placement:
        return None
    kept = [[b for b, r in zip(bufs, rs) if r.kept] for bufs, rs in zip(all_buffers, rows)]
    for owner, bufs in group_buffers.items():
        kept[owner] = [b for b, r in zip(bufs, rows[owner]) if r.kept]
    stored = [kept[i] for i in range(len(kept)) if placement.get(i, (i,))[0] == i]
    highest_min = int(max(int(np.max(b.min_level)) for bufs in stored for b in bufs))
    vlevel = view_level(grid.extent, settings.viewing)
    if max_level is None:
        if vlevel is None:
            max_level = BITS
        else:
            res = [resident_level(vlevel, sh) for sh in shifts_of.values()]
            max_level = max([vlevel, highest_min] + res)
    max_level = int(max_level)
    # shared mesh-grid buffers and the parts left on the scene grid are clustered as any buffer
    encoded = [[] if placement.get(i, (i,))[0] != i else [encode_buffer(b, max_level, settings.emit.clusters,
                                                                        cluster_all=settings.emit.cluster_all)
                                                          for b in kept[i]]
               for i in range(len(kept))]
    manifest, sections = assemble(scene, grid, encoded, max_level=max_level, options=options,
                                  viewing=settings.viewing)
    manifest = _placement_manifest(manifest, placement, mesh_grids, kept, encoded)
    container = built(manifest, sections)
    timings["emit"] = time.perf_counter() - t0
    result = CookResult(container=container, analysis=analyses[0], timings_s=timings, lods=rows,
                        lod_reports=reports, grid_extent_m=float(grid.extent), lod_max_error_m=cap,
                        view_level=vlevel, highest_min_level=highest_min, max_level=max_level,
                        planes_dropped=list(range(max_level + 1, BITS + 1)),
                        lods_dropped=int(sum(not r.kept for rs in rows for r in rs)),
                        bytes_without_savings=len(container.data), colocated_raised_across_lods=raised)
    account(result)
    return result


def _instanced_levels(scene: Scene, settings: Settings, timings: dict, progress: Progress, analysis=None):
    """``_instanced``'s steps (1)-(3): ``(parts_chain, errors, reports, cap, grid, analyses, levels,
    raised)`` as ``_lod_stage`` and ``analyse_lods`` give them, or from ``analysis`` (LOD 0 only,
    analysed on the scene grid) when it is given; the analysis time goes to ``timings``."""
    if analysis is not None:
        parts_chain, errors, reports, cap = [[p] for p in scene.parts], [[0.0] for _ in scene.parts], [], None
        grid, analyses, raised = analysis.grid, [analysis], 0
        levels = [[pa.min_level] for pa in analysis.parts]
        return parts_chain, errors, reports, cap, grid, analyses, levels, raised
    parts_chain, errors, reports, cap, first = _lod_stage(scene, settings, timings, progress)
    t0 = time.perf_counter()
    grid, analyses, levels, raised = analyse_lods(scene, parts_chain, settings.analyse, progress=progress,
                                                  first=first)
    timings["analyse"] = time.perf_counter() - t0
    return parts_chain, errors, reports, cap, grid, analyses, levels, raised


def _shared_buffers(groups: list[dict], parts_chain, levels, all_buffers, grid: Grid):
    """The buffers each group of copies (``placement_groups``) shares on its mesh grid
    (``lopcook.lop.placement.mesh_grid``): per LOD the lead's chain quantized there, its minimum
    levels the maximum over the placements of their world levels converted (``local_level`` by
    each placement's ``level_shift``), then shared between co-located vertices. A copy that would
    need more than 24 mesh-grid bits stays on the scene grid; a group left with fewer than two
    placements stores nothing once.

    Returns ``(placement, mesh_grids, group_buffers, shifts_of)``: part -> (owner, the manifest's
    3 x 4 transform, level shift); owner -> its mesh Grid; owner -> [BufferInput per LOD]; owner ->
    the level shift of each of its placements."""
    placement: dict = {}  # part -> (owner, transform, shift)
    mesh_grids: dict = {}  # owner -> Grid
    group_buffers: dict = {}  # owner -> [BufferInput per LOD]
    shifts_of: dict = {}  # owner -> [shift of each placement]
    for g in groups:
        lead = g["lead"]
        chain = parts_chain[lead][:len(parts_chain[g["members"][0][0]])]
        mgrid, lo = mesh_grid([p.positions for p in chain])
        local = [mgrid.quantize(np.asarray(p.positions, np.float64) - lo) for p in chain]
        members, mlevels = [], [np.zeros(q.shape[0], np.int64) for q in local]
        for i, a, t in g["members"]:
            tf = transform_f32(a, np.asarray(t, np.float64) + np.asarray(a, np.float64) @ lo)
            s = level_shift(sigma(tf), mgrid.extent, grid.extent)
            need = [np.asarray(levels[i][k], np.int64) + s for k in range(len(chain))]
            if max(int(n.max()) for n in need) > BITS:
                continue  # a vertex would need more than 24 mesh-grid bits: stays on the scene grid
            members.append((i, tf, s))
            mlevels = [np.maximum(m, local_level(levels[i][k], s)) for k, m in enumerate(mlevels)]
        if len(members) < 2:
            continue
        shared = colocated_max(np.concatenate(local), np.concatenate(mlevels))
        owner = members[0][0]
        bits = _max_bits([all_buffers[i][0].bits() for i, _, _ in members])
        bufs, start = [], 0
        for k, (q, lod) in enumerate(zip(local, chain)):
            ref = all_buffers[owner][k]
            n = q.shape[0]
            bufs.append(replace(ref, quantized=q, min_level=shared[start:start + n].astype(np.uint8),
                                indices=lod.indices, attributes=dict(lod.attributes),
                                attribute_bits=bits))
            start += n
        group_buffers[owner] = bufs
        mesh_grids[owner] = mgrid
        shifts_of[owner] = [s for _, _, s in members]
        for i, tf, s in members:
            placement[i] = (owner, tf, s)
    return placement, mesh_grids, group_buffers, shifts_of


def _max_bits(bits):
    """The attribute bits a group's shared buffers are packed with: per attribute the most bits any
    placement chose (``lopcook.lop.codecs.AttributeBits``; copies have the same attributes, so
    None for one is None for all)."""

    def top(key):
        vals = [b.get(key) for b in bits if b.get(key) is not None]
        return max(vals) if vals else None

    return AttributeBits(**{c.name: top(c.name) for c in CODECS})


def _placement_manifest(manifest: dict, placement: dict, mesh_grids: dict, kept, encoded) -> dict:
    """``manifest`` (assembled with empty buffer lists for placements that do not own their
    buffers) with every placement's ``placement`` and ``grid`` records and LOD entries: the
    owner's buffer fields, the placement's own ``geometric_error_m`` / ``min_distance_m``."""
    if not placement:
        return manifest
    parts = [dict(p) for p in manifest["parts"]]
    for i, (owner, tf, s) in sorted(placement.items()):
        g = mesh_grids[owner]
        part = parts[i]
        lods = []
        for k, e in enumerate(parts[owner]["lods"]):
            e = dict(e)
            b = kept[i][k]
            e["geometric_error_m"] = float(b.geometric_error_m)
            if b.min_distance_m is not None:
                e["min_distance_m"] = float(b.min_distance_m)
            lods.append(e)
        part["lods"] = lods
        part["attribute_bits"] = parts[owner]["attribute_bits"]
        part["grid"] = {"origin": [float(v) for v in g.origin], "extent": float(g.extent)}
        part["placement"] = {"of": int(owner), "transform": tf, "level_shift": int(s)}
    stats = dict(manifest["stats"])
    stats["placements"] = {"parts": len(placement), "groups": len(mesh_grids),
                           "vertices_all_copies": int(sum(e["vertices"] for p in parts for e in p["lods"])),
                           "triangles_all_copies": int(sum(e["triangles"] for p in parts for e in p["lods"]))}
    return dict(manifest, parts=parts, stats=stats)


__all__ = ["run", "placement_groups", "CookResult", "LodRow", "chains", "analyse_lods", "far_error_m", "view_level"]
