"""``lopcook bench``'s entry: ``run(opts)`` runs what the parsed flags ask for (the accuracy runs per
asset, the scaling runs, or instead ``--attributes``, ``--connectivity`` or ``--streaming``) and
writes everything into ``opts.output``; it returns the summary dict.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from ..errors import LopcookError
from . import attributes as A
from . import peers as P
from .common import asset_name, corpus_dir, dracopy_version, log, machine, write_csv
from .compare import DEFAULT_ASSETS, ROW_COLUMNS, bench_asset, result_row
from .connectivity import ASSETS, main
from .scaling import bench_scaling
from .streaming import run_streaming
from .summary import write_outputs


def run_connectivity(opts) -> dict:
    """``lopcook bench --connectivity``: ``lopcook.bench.connectivity`` on ``opts.assets`` (default
    every corpus asset) into ``opts.output`` (connectivity.json, connectivity_unit_size.png)."""
    corpus = corpus_dir()
    if not opts.assets and corpus is None:
        raise LopcookError("usage", None, "no ASSETS given and no corpus found",
                           hint="give asset files, or set LOPCOOK_CORPUS to the shared corpus folder")
    argv = ["--out", str(opts.output), "--corpus", str(corpus or "."), "--assets"]
    argv += [str(Path(a).resolve()) for a in opts.assets] or list(ASSETS)
    return main(argv)


ATTRIBUTE_ASSETS = ("stanford-bunny.obj", "DamagedHelmet/DamagedHelmet.gltf", "Duck.glb")


def run_attributes(opts) -> dict:
    """``lopcook bench --attributes``: ``lopcook.bench.attributes`` on ``opts.assets`` (default
    ``ATTRIBUTE_ASSETS`` of the corpus) into ``opts.output`` (attributes.json, .csv, .png)."""
    corpus = corpus_dir()
    assets = [str(a) for a in opts.assets]
    if not assets:
        if corpus is None:
            raise LopcookError("usage", None, "no ASSETS given and no corpus found",
                               hint="give asset files, or set LOPCOOK_CORPUS to the shared corpus folder")
        assets = [str(corpus / a) for a in ATTRIBUTE_ASSETS if (corpus / a).is_file()]
    Path(opts.output).mkdir(parents=True, exist_ok=True)
    avail = P.availability(opts.peers)
    for peer in opts.peers:
        if avail.get(peer) is None:
            print(P.missing_line(peer), file=sys.stderr, flush=True)
    return A.run(opts, assets, avail)


def run(opts) -> dict:
    """Run the bench described by ``opts`` (the parsed ``lopcook bench`` arguments: assets, output,
    levels, views, resolution, bits, peers, scaling, scaling_max_triangles, skip_render,
    calibrated, repeat, quiet) and write everything into ``opts.output``. Returns the summary."""
    if getattr(opts, "connectivity", False):
        return run_connectivity(opts)
    if getattr(opts, "attributes", False):
        return run_attributes(opts)
    if getattr(opts, "streaming", False):
        return run_streaming(opts)
    t0 = time.perf_counter()
    out_dir = Path(opts.output)
    out_dir.mkdir(parents=True, exist_ok=True)
    corpus = corpus_dir()
    assets = list(opts.assets)
    if not assets and not opts.no_accuracy:
        if corpus is None:
            raise LopcookError("usage", None, "no ASSETS given and no corpus found",
                               hint="give asset files, or set LOPCOOK_CORPUS to the shared corpus folder")
        assets = [str(corpus / a) for a in DEFAULT_ASSETS if (corpus / a).is_file()]
    avail = P.availability(opts.peers)
    for peer in opts.peers:
        if avail.get(peer) is None:
            print(P.missing_line(peer), file=sys.stderr, flush=True)
    versions = {p: (P.tool_version(avail[p], p) if p != "draco" else f"DracoPy {dracopy_version()}")
                for p in opts.peers if avail.get(p)}
    rows, stage_rows = [], []
    for a in ([] if opts.no_accuracy else assets):
        try:
            r, s = bench_asset(a, out_dir, opts, avail)
        except Exception as exc:  # noqa: BLE001 -- an unreadable asset is a row, not a crash
            log(opts, f"{asset_name(a)}: failed: {type(exc).__name__}: {exc}")
            r, s = [result_row(asset=asset_name(a), tool="lopcook", config="CAP", error=f"{type(exc).__name__}: {exc}")], []
        rows += r
        stage_rows += s
        write_csv(out_dir / "results.csv", rows, ROW_COLUMNS)  # partial results survive an interrupted run
    scaling = []
    if opts.scaling:
        s_rows, s_stages = bench_scaling(out_dir, corpus, opts, avail)
        scaling += s_rows
        stage_rows += s_stages
    meta = {"command": "lopcook bench " + " ".join(opts.argv), "machine": machine(), "peers": versions,
            "seconds": time.perf_counter() - t0, "assets": [asset_name(a) for a in assets],
            "levels": list(opts.levels), "views": opts.views, "resolution": list(opts.resolution),
            "peak_rss": "os.wait4 ru_maxrss of each child process", "match": {
                "lopcook": "order (the container keeps the source vertices)",
                "peers": "nearest source vertex (scipy cKDTree), ties between co-located vertices by normal/UV"}}
    summary = write_outputs(out_dir, rows, scaling, stage_rows, [asset_name(a) for a in assets], opts, meta)
    for c in summary["checks"]:
        log(opts, f"{c['status']:>12}: {c['check']}: {c['detail']}")
    log(opts, f"wrote {out_dir}/results.csv, scaling.csv, stages.csv, charts, summary.md in "
               f"{time.perf_counter() - t0:.0f} s")
    return summary


__all__ = ["ATTRIBUTE_ASSETS", "run", "run_attributes", "run_connectivity"]
