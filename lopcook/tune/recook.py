"""Re-cook a container from its source with the options it records: the cook's stage timings for
``lopcook report`` and a byte-for-byte determinism check.

A container holds no timings (the same input and options must give the same bytes, and a clock
would break that), so ``lopcook report`` measures them again: it runs the cook's pipeline
(``lopcook.pipeline.run``) on the already ingested source with the recorded analysis
settings (``options.analyse``), LOD options (``options.lods``) and viewing conditions (``viewing``), read by
``Settings.from_manifest``, and records the options and the source's recorded path verbatim,
exactly as ``lopcook cook`` did. The bytes it produces are then compared with the file's:

* ``"identical"``: same bytes (deterministic output, and the report describes what this lopcook
  version writes for that source);
* ``"prefix"``: the file is a prefix of the re-cooked bytes (a truncated download: the prefix
  property lets it decode lower levels);
* ``"differs"``: the container was written by another lopcook or library version, from another
  source, or with options this version cannot read back -- reported as a warning, never an error;
* ``"not re-cooked"``: a ``cook --target-bytes`` container is one candidate of a fit that renders
  dozens of candidates; only its analysis is re-run (for the warnings) and timed.

``cook --target-psnr`` containers record the calibrated eps and edge_eps in ``options.analyse``, so
they re-cook exactly; the calibration itself is not re-run (its cost is not in the timings).

Timings (seconds, wall clock of this process): ``ingest`` (as measured by the caller), ``lod``
(LOD chains, when the container has LODs), ``analyse`` (every LOD; with ``analyse.<stage>`` the
LOD 0 breakdown: grid, attribute_error, discontinuity, depth, co-located), ``emit`` (bins, planes,
container bytes).
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

from ..analyse import analyse
from ..analyse.bitlevel import clear_slope_cache
from ..errors import LopcookError
from ..pipeline import run
from ..progress import NONE, Progress
from ..settings import Settings


def recorded_settings(manifest: dict, path: str | None = None) -> Settings:
    """The Settings a container records (``Settings.from_manifest``); LopcookError when the
    record does not parse."""
    return Settings.from_manifest(manifest, path)


def recook(container, scene, *, ingest_s: float | None = None, file_bytes: bytes | None = None,
           progress: Progress = NONE) -> dict:
    """Re-cook ``container`` (``lopcook.lop.container.Container``) from ``scene`` (its ingested
    source) and compare (see module doc).

    Returns ``{"status": "identical" | "prefix" | "differs" | "not re-cooked", "detail": str,
    "timings_s": {stage: seconds}, "bytes": int or None (re-cooked size), "analysis": Analysis
    (LOD 0 of every part: warnings), "lod_reports": [per part LodReport dict] (empty without
    LODs)}``. ``file_bytes``: the container file's bytes (default: read from ``container.path``).
    """
    clear_slope_cache()  # time what a fresh cook pays
    m = container.manifest
    options = m.get("options") or {}
    timings = {} if ingest_s is None else {"ingest": float(ingest_s)}
    try:
        settings = recorded_settings(m, container.path)
    except LopcookError as exc:
        return {"status": "not re-cooked", "detail": exc.message, "timings_s": timings, "bytes": None,
                "analysis": analyse(scene), "lod_reports": []}
    if options.get("budget") is not None:
        t0 = time.perf_counter()
        an = analyse(scene, settings.analyse)
        timings["analyse"] = time.perf_counter() - t0
        timings.update({f"analyse.{k}": float(v) for k, v in an.timings.items()})
        return {"status": "not re-cooked", "detail": "cooked with --target-bytes: the byte-budget fit renders "
                "every candidate and is not re-run; only the analysis is timed", "timings_s": timings,
                "bytes": None, "analysis": an, "lod_reports": []}
    recorded = (m.get("source") or {}).get("path") if isinstance(m.get("source"), dict) else None
    if isinstance(recorded, str):  # where the cook found the source: recorded again, as the cook did
        scene = replace(scene, recorded_path=recorded)
    result = run(scene, settings, options=options, progress=progress)
    data, an = result.data, result.analysis
    timings.update({k: float(v) for k, v in result.timings_s.items()})
    timings.update({f"analyse.{k}": float(v) for k, v in an.timings.items()})
    if file_bytes is None and container.path is not None and Path(container.path).is_file():
        file_bytes = Path(container.path).read_bytes()
    if file_bytes is None:
        status, detail = "differs", "the container's bytes are not available to compare"
    elif file_bytes == data:
        status, detail = "identical", f"re-cooking the source gives the same {len(data):,} bytes"
    elif len(file_bytes) < len(data) and data.startswith(file_bytes):
        status, detail = "prefix", (f"the file ({len(file_bytes):,} bytes) is a prefix of the re-cooked "
                                    f"{len(data):,} bytes")
    else:
        status, detail = "differs", (f"re-cooking gives {len(data):,} bytes that differ from the file's "
                                     f"{len(file_bytes):,} (another lopcook or library version, another source, "
                                     "or options this version does not read back)")
    if options.get("calibration") is not None:
        detail += "; the k_f calibration (cook --target-psnr) is not re-run or timed"
    return {"status": status, "detail": detail, "timings_s": timings, "bytes": len(data), "analysis": an,
            "lod_reports": result.lod_reports}


__all__ = ["recorded_settings", "recook"]
