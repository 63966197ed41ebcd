"""Per-stage wall time, CPU time and peak RSS of ``lopcook cook`` (fresh process per run).

Not a test (pytest does not collect benchmarks/). Usage::

    .venv/bin/python benchmarks/profile_cook.py SOURCE [--lods 1/2,1/4] [--lod-backend auto|meshopt|pymeshlab|fast]
        [--repeat 3] [--cprofile N] [--json OUT.json]

Each run is a child process that does what ``lopcook cook SOURCE -o OUT --lods ...`` does (ingest,
``lopcook.pipeline.run``, ``write_atomic``) with the stages wrapped by a recorder. Stages: ``ingest``;
``lod`` (LOD chains, all parts); ``grid``, ``E_v`` (attribute error and level), ``depth``,
``co_located`` (inside ``analyse``, summed over LODs; ``co_located`` also holds the cross-LOD
sharing of ``analyse_lods``); ``emit`` (binning, attributes, bit planes, container bytes; in LOD
mode, see ``lopcook.pipeline.run``); ``write``. ``total`` is the whole
ingest..write span.

Columns: wall seconds, CPU seconds (user + system of every thread of the process, so a stage
that uses two cores shows CPU > wall), and peak RSS in MB during the stage: VmHWM, reset at the
start of every stage through ``/proc/self/clear_refs`` (Linux) so each stage reports its own
high-water mark; the ``total`` row's peak RSS is the whole process's, imports included, or the
largest forked simplification child's (``lopcook.isolate``) when that is higher. With
``--repeat N`` the row of the run with the best total wall time is printed (the machine is
shared, so single timings are noisy); peak RSS does not depend on timing. ``--cprofile N``
prints the N most expensive functions (cumulative) of one extra run. The sha256 of the
container is printed so a speed change can be checked for unchanged bytes.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

STAGES = ["ingest", "lod", "analyse", "grid", "E_v", "depth", "co_located", "emit", "write", "total"]


def _hwm_kb() -> int:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmHWM"):
                return int(line.split()[1])
    return 0


def _reset_hwm() -> None:
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
    except OSError:  # not Linux / not permitted: peaks are then cumulative
        pass


def _cpu() -> float:
    """User + system CPU seconds of this process and of its reaped children (large simplifications
    run in forked children, ``lopcook.isolate``)."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    c = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime + c.ru_utime + c.ru_stime


class Recorder:
    """Nested stage timer: wall and CPU seconds summed per stage name, peak RSS (kB) max per name.
    Before each reset of VmHWM the current mark is folded into every open stage, so an outer stage
    keeps the peaks of its inner ones."""

    def __init__(self):
        self.rows: dict = {}
        self.open: list = []  # [name, wall0, cpu0, peak_kb]

    def _fold(self):
        h = _hwm_kb()
        for s in self.open:
            s[3] = max(s[3], h)

    @contextmanager
    def stage(self, name: str):
        self._fold()
        _reset_hwm()
        rec = [name, time.perf_counter(), _cpu(), _hwm_kb()]
        self.open.append(rec)
        try:
            yield
        finally:
            self._fold()
            self.open.pop()
            row = self.rows.setdefault(name, {"wall_s": 0.0, "cpu_s": 0.0, "peak_rss_mb": 0.0})
            row["wall_s"] += time.perf_counter() - rec[1]
            row["cpu_s"] += _cpu() - rec[2]
            row["peak_rss_mb"] = max(row["peak_rss_mb"], rec[3] / 1024.0)

    def add_time(self, name: str, seconds: float):
        row = self.rows.setdefault(name, {"wall_s": 0.0, "cpu_s": float("nan"), "peak_rss_mb": float("nan")})
        row["wall_s"] += seconds


def _wrap(rec: Recorder, module, attr: str, stage: str):
    fn = getattr(module, attr)

    def wrapped(*a, **k):
        with rec.stage(stage):
            return fn(*a, **k)

    setattr(module, attr, wrapped)


def child(args) -> dict:
    """One cook in this process, stages recorded; returns the result dict."""
    import lopcook.analyse as an
    import lopcook.pipeline as pl
    from lopcook.lop.container import write_atomic
    from lopcook.ingest import load
    from lopcook.memory import small_pages
    from lopcook.settings import Settings, SimplifySettings, parse_lods

    rec = Recorder()
    _wrap(rec, pl, "chains", "lod")
    _wrap(rec, an, "triangle_frames", "E_v")
    _wrap(rec, an, "triangle_gradient_norms", "E_v")
    _wrap(rec, an, "vertex_max", "E_v")
    _wrap(rec, an, "attribute_level", "E_v")
    _wrap(rec, an, "depth_levels", "depth")
    _wrap(rec, an, "colocated_max", "co_located")
    _wrap(rec, pl, "colocated_max", "co_located")
    for attr in ("encode_buffer", "to_bytes", "assemble", "built"):  # names differ between versions
        if hasattr(pl, attr):
            _wrap(rec, pl, attr, "emit")
    if hasattr(pl, "analyse_lods"):
        _wrap(rec, pl, "analyse_lods", "analyse")
    orig_analyse = an.analyse

    def analyse(*a, **k):  # grid = the part of analyse's own "grid" timing
        out = orig_analyse(*a, **k)
        rec.add_time("grid", out.timings["grid"])
        return out

    pl.analyse = analyse
    settings = Settings(simplify=SimplifySettings(lods=parse_lods(args.lods), backend=args.lod_backend))
    out = tempfile.mktemp(suffix=".lop", dir=args.tmp)
    import_hwm = _hwm_kb()
    with rec.stage("total"), small_pages():  # as the CLI runs (lopcook.memory.small_pages)
        with rec.stage("ingest"):
            scene = load(args.source)
        data = pl.run(scene, settings).data
        with rec.stage("write"):
            write_atomic(out, data)
    os.unlink(out)
    rows = rec.rows
    rows["total"]["peak_rss_mb"] = max(rows["total"]["peak_rss_mb"], import_hwm / 1024.0,
                                       resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0)
    return {"source": args.source, "lods": args.lods, "backend": args.lod_backend,
            "triangles": scene.n_triangles, "vertices": scene.n_vertices,
            "sha256": hashlib.sha256(data).hexdigest(), "bytes": len(data), "stages": rows}


def run_child(args, extra: list[str]) -> dict:
    cmd = [sys.executable, __file__, args.source, "--child", "--lod-backend", args.lod_backend, "--tmp", args.tmp]
    if args.lods:
        cmd += ["--lods", args.lods]
    proc = subprocess.run(cmd + extra, capture_output=True, text=True)
    if proc.returncode:
        sys.exit(f"child failed:\n{proc.stderr}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("source")
    ap.add_argument("--lods", default=None, help="as lopcook cook --lods, e.g. 1/2,1/4")
    ap.add_argument("--lod-backend", default="auto", choices=["auto", "meshopt", "pymeshlab", "fast"],
                    help="as lopcook cook --lod-backend (default auto, the CLI default)")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--cprofile", type=int, default=0, metavar="N")
    ap.add_argument("--json", default=None, help="write every run's rows here")
    ap.add_argument("--tmp", default=tempfile.gettempdir())
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--child-cprofile", type=int, default=0, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        if args.child_cprofile:
            import cProfile
            import io
            import pstats

            prof = cProfile.Profile()
            prof.enable()
            res = child(args)
            prof.disable()
            buf = io.StringIO()
            pstats.Stats(prof, stream=buf).sort_stats(os.environ.get("PROFILE_SORT", "cumulative")).print_stats(args.child_cprofile)
            print(buf.getvalue(), file=sys.stderr)
        else:
            res = child(args)
        print(json.dumps(res))
        return 0

    runs = [run_child(args, []) for _ in range(max(1, args.repeat))]
    best = min(runs, key=lambda r: r["stages"]["total"]["wall_s"])
    hashes = {r["sha256"] for r in runs}
    walls = ", ".join(f"{r['stages']['total']['wall_s']:.2f}" for r in runs)
    print(f"{Path(args.source).name}: {best['triangles']:,} triangles, {best['vertices']:,} vertices, "
          f"lods={args.lods or '-'} backend={args.lod_backend if args.lods else '-'}, "
          f"best of {len(runs)} (total wall {walls})")
    print(f"{'stage':<12} {'wall s':>8} {'cpu s':>8} {'peak RSS MB':>12}")
    for name in STAGES:
        row = best["stages"].get(name)
        if row is None:
            continue
        print(f"{name:<12} {row['wall_s']:>8.2f} {row['cpu_s']:>8.2f} {row['peak_rss_mb']:>12.0f}")
    print(f"bytes {best['bytes']:,}  sha256 {' '.join(sorted(hashes))}")
    if args.cprofile:
        cmd = [sys.executable, __file__, args.source, "--child", "--child-cprofile", str(args.cprofile),
               "--lod-backend", args.lod_backend, "--tmp", args.tmp] + (["--lods", args.lods] if args.lods else [])
        proc = subprocess.run(cmd, capture_output=True, text=True)
        print(proc.stderr)
    if args.json:
        Path(args.json).write_text(json.dumps(runs, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
