"""The Python API: ``load(path) -> Scene``, ``cook(scene, settings) -> Container``,
``read(path) -> Container`` and ``Container.write(path)``.

``cook`` is what ``lopcook cook`` runs: the stages (``lopcook.pipeline.run``), preceded by the
k_f calibration when ``settings.tune.target_psnr`` is set (``lopcook.tune.calibrate``), or the
byte-budget fit when ``settings.tune.target_bytes`` is set (``lopcook.tune.budget``). The
returned Container holds its bytes (``.data``) and what the cook did (``.result``, a
``CookResult`` with ``calibration`` and ``budget`` records when those ran).

``import lopcook`` does not load this module (nor the stages it imports): the package's face
resolves ``lopcook.cook``, ``load`` and ``read`` when first used (PEP 562).
"""

from __future__ import annotations

import time
from dataclasses import replace

from .errors import EXIT_VERIFY_FAILED, LopcookError
from .lop.container import Container, from_bytes
from .lop.container import read as _read
from .lop.manifest import recorded_source_path
from .lop.memo import code_memo
from .memory import release_free_memory, small_pages
from .progress import NONE, Progress
from .settings import DEFAULTS, Settings
from .analyse.prepared import held
from .emit.stages import streamed
from .analyse.prepared import release_shared as release_prepared
from .ingest import load as _load
from .pipeline import account, plain, run
from .settings import budget_target
from .tune.attributes import allocate, format_probe, search_record
from .tune.attributes import require_reached as require_allocated
from .tune.budget import fit, float_bytes
from .tune.calibrate import CONFIRM_LEVELS, WATCH_DB, calibrate, calibration_record
from .tune.calibrate import require_reached as require_calibrated
from .types import Scene
from .verify.renderer import release_shared as release_harnesses


def load(path, settings: Settings = DEFAULTS) -> Scene:
    """Load a glTF/GLB, OBJ or USD file into a validated Scene (``settings.ingest``)."""
    with small_pages():
        return _load(str(path), settings.ingest)


def read(path, *, allow_prefix: bool = False) -> Container:
    """Read and check a .lop container (every corruption is one LopcookError)."""
    return _read(str(path), allow_prefix=allow_prefix)


def calibration(scene: Scene, settings: Settings, progress: Progress = NONE, complete: bool = True,
                loosen_edges: bool = True) -> dict:
    """``lopcook calibrate``: the k_f search of ``settings.tune`` (``lopcook.tune.calibrate``);
    its result says whether the target was reached. ``complete`` False: a direct search does not
    render its choice at every level (the attribute search that follows does); ``loosen_edges``
    False: the edges are loosened by the attribute search that follows (one of its knobs)."""
    with progress.stage("calibrate (probes)") as st:
        def on_probe(p):
            st.advance()
            progress(p)

        return _search(scene, settings, on_probe, complete, loosen_edges)


def search_harness(settings: Settings) -> tuple:
    """(views, (w, h), levels, direct) the ``target_psnr`` searches render on: the gate's harness
    (``tune.confirm``, verify's 20 views at 1280 x 720 by default) at its levels among 6..11
    (``CONFIRM_LEVELS``, the gate's ``verify --levels 6-11``) for a direct search (``tune.direct``),
    else the reduced ``tune.calibration``."""
    t = settings.tune
    if t.direct:
        gate = t.confirm if t.confirm is not None else settings.render
        levels = tuple(b for b in gate.levels if b in CONFIRM_LEVELS) or tuple(gate.levels)
        return gate.views, tuple(gate.resolution), levels, True
    return t.calibration.views, tuple(t.calibration.resolution), tuple(t.calibration.levels), False


def _search(scene: Scene, settings: Settings, on_probe, complete: bool = True, loosen_edges: bool = True) -> dict:
    """The k_f calibration of ``settings.tune`` (``calibration``)."""
    t = settings.tune
    views, resolution, levels, direct = search_harness(settings)
    confirm = None if t.confirm is None or direct else (t.confirm.views, t.confirm.resolution)
    cal = calibrate(scene, settings.analyse, target_psnr=t.target_psnr, levels=list(levels),
                    views=views, resolution=resolution, viewing=settings.viewing,
                    ingest_options={"crease_angle_deg": settings.ingest.crease_angle_deg}, progress=on_probe,
                    statistic=t.psnr_stat.value, search=None if t.search is None else t.search.value,
                    confirm=confirm, watch_db=WATCH_DB if direct else None,
                    complete=complete and t.confirm is not None,
                    clusters=(settings.emit.clusters, bool(settings.emit.cluster_all)),
                    loosen_edges=loosen_edges)
    return cal


def _calibrate(scene: Scene, settings: Settings, progress, complete: bool = True, loosen_edges: bool = True):
    """``tune.target_psnr``: the calibration, its manifest record and the settings it chose;
    LopcookError (exit 1) when the target is not reached."""
    cal = calibration(scene, settings, progress, complete, loosen_edges)
    require_calibrated(cal, scene.source)
    chosen = settings.with_(analyse={"eps": cal["eps"], "edge_eps": cal["edge_eps"]})
    return cal, calibration_record(cal), chosen


def _budget(scene: Scene, settings: Settings, options: dict, say):
    """``tune.target_bytes``: the fitted container's bytes, the chain's CookResult and the record."""
    t = settings.tune
    fsize = float_bytes(scene, t.budget_scope.value)
    target = budget_target(t.target_bytes, fsize)
    if target < 1:
        raise LopcookError("usage", scene.source, f"--target-bytes {t.target_bytes}: less than one byte of the "
                           f"float size {fsize:,} B")
    data, info = fit(scene, target, settings, scope=t.budget_scope.value, views=t.budget.views,
                     resolution=t.budget.resolution, levels_per_lod=t.budget_levels, options=options, progress=say)
    return data, info


def _attribute_search(scene: Scene, settings: Settings, progress, watch=None):
    """``tune.vertex_bits`` (a bit budget) or ``tune.target_psnr`` with ``tune.attribute_search``:
    Purnomo's greedy search over every attribute's bits (``lopcook.tune.attributes``). Returns
    (the record for ``cook --json``, the manifest record, the chosen Settings); LopcookError (exit
    1) when a target is missed even at the default bits, (exit 2) when the budget is unreachable."""
    t = settings.tune
    budget = t.vertex_bits is not None
    confirm = None if t.confirm is None else (t.confirm.views, t.confirm.resolution)
    harness = (t.calibration.views, t.calibration.resolution, tuple(t.calibration.levels))
    if not budget and watch is not None:  # a direct search: on the gate's harness, watching those levels
        views, resolution, levels, _ = search_harness(settings)
        harness = (views, resolution, levels)
        confirm = None if t.confirm is None else (views, resolution)
    with progress.stage("attribute search (probes)") as st:
        def on_probe(p):
            st.advance()
            progress(format_probe(p))

        res = allocate(scene, settings, mode="budget" if budget else "target",
                       goal=t.vertex_bits if budget else t.target_psnr, harness=harness, confirm=confirm,
                       statistic="mean" if budget else t.psnr_stat.value, progress=on_probe,
                       watch=None if budget else watch)
    chosen = res.pop("_settings")
    require_allocated(res, scene.source)
    return res, search_record(res), chosen


def cook(scene: Scene, settings: Settings = DEFAULTS, *, progress: Progress = NONE,
         output: str | None = None) -> Container:
    """Cook ``scene`` into a container (module doc). ``progress``: stage reporting
    (``lopcook.progress``). ``output``: the path the container will be written to; the manifest
    then records where the source lies relative to its folder (``source.path``, as ``lopcook
    cook`` does; ``decode`` looks there), else it records no path. Deterministic: the same scene,
    settings and relative layout give the same bytes. numpy allocates without huge pages
    meanwhile (``lopcook.memory.small_pages``)."""
    if output is not None:
        scene = replace(scene, recorded_path=recorded_source_path(scene.source, output))
    t = settings.tune
    with small_pages():
        if t.target_psnr is None and t.vertex_bits is None:
            return _cook(scene, settings, progress)
        # the searches cook the scene again and again, mostly with some attribute's bits unchanged
        with code_memo():
            return _cook(scene, settings, progress)


def _cook(scene: Scene, settings: Settings, progress: Progress) -> Container:
    """``cook``'s body."""
    say = progress
    timings: dict = {}
    calibration = record = None
    attributes = settings.tune.vertex_bits is not None or (settings.tune.target_psnr is not None
                                                           and settings.tune.attribute_search)
    # a direct search's k_f choice is rendered at every level by the attribute search that follows
    leave = attributes and settings.tune.target_psnr is not None and settings.tune.direct
    given = settings
    if settings.tune.target_psnr is not None:
        t0 = time.perf_counter()
        # the edges are a knob of the attribute search when it follows: loosened there, not here
        calibration, record, settings = _calibrate(scene, given, progress, complete=not leave,
                                                   loosen_edges=not attributes)
        timings["calibrate"] = time.perf_counter() - t0
    search = search_rec = None
    if attributes:
        t0 = time.perf_counter()
        watch = None if calibration is None else calibration.get("watch")
        try:
            search, search_rec, settings = _attribute_search(scene, settings, progress, watch)
        except LopcookError as exc:
            if not leave or exc.exit_code != EXIT_VERIFY_FAILED:
                raise
            # even the k_f choice missed a level nobody watched: the calibration completes its own
            # choice (moving toward the default cook), and the attribute search starts again from it
            calibration, record, settings = _calibrate(scene, given, progress, complete=True,
                                                       loosen_edges=not attributes)
            search, search_rec, settings = _attribute_search(scene, settings, progress, calibration.get("watch"))
        timings["attribute_search"] = time.perf_counter() - t0
    analysis = None
    if calibration is not None or search is not None:
        analysis = _after_searches(scene, settings, timings)
    options = settings.to_manifest()["options"]
    if record is not None:
        options["calibration"] = record
    if search_rec is not None:
        options["attribute_search"] = search_rec
    if settings.tune.target_bytes is not None:
        data, info = _budget(scene, settings, options, say)
        result = info["cook"]
        result.budget = info["budget"]
        result.timings_s = dict(result.timings_s, **{f"budget.{k}": v for k, v in info["timings_s"].items()
                                                     if k != "cook"})
        container = from_bytes(data, None)
    else:
        result = run(scene, settings, options=options, progress=progress, analysis=analysis)
        container = result.container
    if settings.emit.stream:  # the final container only: the searches' probes keep the default layout
        container = _streamed(result, container, timings)
    result.timings_s = dict(timings, **result.timings_s)
    result.calibration = calibration
    result.attribute_search = search
    result.settings = settings
    container.result = result
    return container


def _streamed(result, container: Container, timings: dict) -> Container:
    """``container`` in the streaming layout (``cook --stream``: ``lopcook.emit.stages.streamed``),
    set as ``result``'s, whose LOD rows then count the streaming file's stored section bytes."""
    t0 = time.perf_counter()
    result.container = streamed(container)
    account(result)
    timings["stream"] = time.perf_counter() - t0
    return result.container


def _after_searches(scene: Scene, settings: Settings, timings: dict):
    """Release what the searches held: their renders are not needed by the cook that follows, nor
    their prepared analysis once it gave the chosen thresholds' levels (the same as a fresh
    analysis: the same bytes). Returns that Analysis of ``scene`` at ``settings.analyse`` on the
    plain path (``lopcook.pipeline.plain``) without a byte budget, else None; its time goes to
    ``timings["analyse.prepared"]``."""
    analysis = None
    release_harnesses()
    prepared = held(scene, settings.analyse)
    if prepared is not None and plain(settings) and settings.tune.target_bytes is None:
        t0 = time.perf_counter()
        analysis = prepared.analyse(settings.analyse.eps, settings.analyse.edge_eps)
        timings["analyse.prepared"] = time.perf_counter() - t0
    del prepared
    release_prepared()
    release_free_memory()
    return analysis


__all__ = ["load", "cook", "read", "calibration", "budget_target", "Container", "Settings"]
