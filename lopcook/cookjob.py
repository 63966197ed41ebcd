"""One cook of a source file into a container file: what ``lopcook cook`` does, and what every
``lopcook batch`` worker does for its asset, so a batch output has the bytes of one ``lopcook cook``
with the same flags.

``cook_file(source, settings, outputs)``:

1. checks the outputs (``lopcook.outputs``): ``-o`` and ``--depfile`` writable, distinct, named for
   what is written, and not the source; again, once ingest knows them, not one of the source's
   dependencies (textures, ``.mtl``, ``.bin``, referenced USD layers);
2. ingests (``lopcook.api.load``), formats the depfile text (a path Make cannot hold is a usage
   error before anything is written), and reports the scene's warnings;
3. cooks (``lopcook.api.cook``, given the container's final path: the manifest records where the
   source lies relative to its folder, ``source.path``, read by ``decode``) and reports the LOD
   chains' warnings (and their notes: ``lopcook.simplify.chain_notes``, a backend's fallback that
   reached its target);
4. writes the container and the depfile atomically (``lopcook.atomic``).

Warnings are lines ``warn(lines)`` receives; with ``CookOutputs.strict`` the first warning is an
error of the stage it arose in (``LopcookError``, exit 2) and nothing is written. Notes are lines
``note(lines)`` receives, information that never fails a cook, ``--strict`` or not. Returns ``(summary, result)``:
``summary`` is the ``lopcook cook --json`` dict (``describe_container`` plus stage timings in
seconds, warnings, touching and intersecting part pairs, the LOD reports, warnings and notes, and
the calibration, budget and attribute-search records when those ran); ``result`` is the
container's ``CookResult``.
Any failure is one ``LopcookError``, and leaves no output and an older output untouched.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from typing import Callable

from . import api
from .atomic import write_atomic
from .depfile import format_depfile
from .lop.summary import describe_container
from .errors import LopcookError
from .outputs import OTHER_OUTPUTS, SOURCE_EXTENSIONS, check_distinct, check_output
from .progress import NONE, Progress
from .settings import Settings
from .simplify import chain_notes, chain_warnings


@dataclass(frozen=True)
class CookOutputs:
    """What one cook writes, and how strictly it treats warnings."""

    output: str                 #: the container (``.lop``), written atomically
    depfile: str | None = None  #: a Make-style depfile listing every file read, or None
    strict: bool = False        #: every warning is an error (exit 2); nothing is written
    #: where the container ends up when ``output`` is a scratch file moved there afterwards (a
    #: batch worker); the manifest's ``source.path`` is relative to its folder (default ``output``)
    destination: str | None = None


def cook_file(source: str, settings: Settings, outputs: CookOutputs, *, progress: Progress = NONE,
              warn: Callable[[list[str]], None] | None = None,
              note: Callable[[list[str]], None] | None = None) -> tuple[dict, object]:
    """Cook ``source`` with ``settings`` into ``outputs`` (module doc); ``(summary, result)``."""
    report = _reporter(outputs, warn)
    _check_outputs(outputs, (source,), report)
    t0 = time.perf_counter()
    with progress.stage(f"ingest {os.path.basename(source)}"):
        scene = api.load(source, settings)
    ingest_s = time.perf_counter() - t0
    _check_outputs(outputs, tuple(scene.dependencies) + (source,), report)
    depfile = _depfile_text(outputs, source, scene)
    report([f"{source}: {w}" for w in scene.warnings], "ingest")
    container = api.cook(scene, settings, progress=progress, output=outputs.destination or outputs.output)
    report(chain_warnings(container.result.lod_reports), "simplify")
    notes = chain_notes(container.result.lod_reports)
    if notes and note is not None:
        note(notes)
    t0 = time.perf_counter()
    container.write(outputs.output)
    if depfile is not None:
        write_atomic(outputs.depfile, depfile.encode("utf-8"))
    write_s = time.perf_counter() - t0
    container.path = outputs.output
    return cook_summary(container, scene, ingest_s, write_s), container.result


def _reporter(outputs: CookOutputs, warn) -> Callable[[list[str], str], None]:
    """``report(lines, stage)``: nothing for no lines; under ``strict`` the first line as an error
    of ``stage`` (``ingest``, ``simplify``, ``output``: where the warning arose, never "usage"),
    with the count of the others; else ``warn(lines)``."""
    def report(lines: list[str], stage: str) -> None:
        if not lines:
            return
        if outputs.strict:
            more = f" (and {len(lines) - 1} more warnings)" if len(lines) > 1 else ""
            raise LopcookError(stage, None, f"{lines[0]}{more}",
                               hint="--strict treats every warning as an error; without it the cook warns and goes on")
        if warn is not None:
            warn(lines)
    return report


def _check_outputs(outputs: CookOutputs, inputs: tuple, report) -> None:
    """``-o`` and ``--depfile`` are writable files, distinct, not an input or a dependency of the
    source, and named for what is written (``lopcook.outputs``); a container not named ``.lop`` is
    a warning (reported on the first check, whose ``inputs`` are the source alone)."""
    check_output(outputs.output, "-o", extensions=(".lop",), what="a .lop container", inputs=inputs,
                 forbidden=SOURCE_EXTENSIONS + OTHER_OUTPUTS, required=False)
    if outputs.depfile:
        check_output(outputs.depfile, "--depfile", extensions=(".d",), what="a Make depfile", inputs=inputs,
                     forbidden=SOURCE_EXTENSIONS + (".lop",), required=False)
    check_distinct(("-o", outputs.output), ("--depfile", outputs.depfile))
    if len(inputs) == 1 and not outputs.output.lower().endswith(".lop"):
        report([f"{outputs.output}: a .lop container is written to a file not named .lop"], "output")


def _depfile_text(outputs: CookOutputs, source: str, scene) -> str | None:
    """The depfile's text, made before anything is written: a dependency path Make cannot hold (a
    newline) is a usage error that leaves every output untouched. Phony rules: a listed file that
    does not exist yet (a missing texture) reruns the cook instead of stopping make."""
    if not outputs.depfile:
        return None
    try:
        return format_depfile(outputs.output, scene.dependencies or (source,), phony=True)
    except ValueError as exc:
        raise LopcookError("usage", source, f"--depfile: {exc}",
                           hint="rename the file, or cook without --depfile") from None


def cook_summary(container, scene, ingest_s: float, write_s: float) -> dict:
    """``cook --json``: the container's description, stage timings (seconds), warnings, touching and
    intersecting part pairs, and the calibration, budget and attribute-search records when those ran."""
    result = container.result
    an = result.analysis
    timings = {"ingest": ingest_s}
    for k in ("calibrate", "attribute_search"):
        if k in result.timings_s:
            timings[k] = result.timings_s[k]
    timings.update({f"analyse.{k}": v for k, v in an.timings.items()})
    timings.update({k: v for k, v in result.timings_s.items() if k not in ("calibrate", "attribute_search")})
    timings["write"] = write_s
    desc = describe_container(container, file_bytes=len(container.data))
    desc.update(timings_s=timings, warnings=list(scene.warnings), touching=[list(p) for p in an.touching],
                intersecting=[list(p) for p in an.intersecting], lod_warnings=chain_warnings(result.lod_reports),
                lod_notes=chain_notes(result.lod_reports), lod_reports=result.lod_reports)
    if result.calibration is not None:
        desc["calibration"] = result.calibration
    if result.budget is not None:
        desc["budget"] = result.budget
    if result.attribute_search is not None:
        desc["attribute_search"] = result.attribute_search
    return desc


__all__ = ["CookOutputs", "cook_file", "cook_summary"]
