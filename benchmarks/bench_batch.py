"""The `lopcook batch` done-when checks on the corpus, in one run (results: docs/batch.md).

    PYTHONPATH=$PWD python benchmarks/bench_batch.py [--corpus DIR] [--repeat N] [--dask] [--ninja] [-o report.json]

1. reference: one ``lopcook cook SRC -o OUT`` process per asset;
2. ``lopcook batch CORPUS --jobs 1`` and ``--jobs 2`` into fresh folders, alternated ``--repeat``
   times (so a change in the machine's load hits both alike); wall time, our CPU time (every
   process the batch started) and the CPU time other processes used meanwhile (/proc/stat busy
   time minus ours), so a shared machine's interference is visible;
3. the outputs equal the references byte for byte; a second ``--jobs 2`` run cooks nothing (time);
4. a copy of the corpus plus one corrupt file: exit 2, the others cook, the summary names it;
   then the DamagedHelmet albedo texture's bytes change: only that asset re-cooks;
5. ``--dask``: a scheduler and two workers on 127.0.0.1: the same bytes;
6. ``--ninja``: ``--emit-ninja``, ninja twice (the second: "no work to do"), the same bytes.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
ENV = dict(os.environ, PYTHONPATH=os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])]))


def _proc_stat_busy() -> float:
    """Seconds of CPU time the whole machine has spent busy (all CPUs), from /proc/stat."""
    with open("/proc/stat") as fh:
        v = [int(x) for x in fh.readline().split()[1:]]
    idle = v[3] + (v[4] if len(v) > 4 else 0)
    return (sum(v[:8]) - idle) / os.sysconf("SC_CLK_TCK")


def timed(cmd, **kw) -> dict:
    """Run ``cmd``; wall, our CPU (it and its waited-for descendants), others' CPU meanwhile."""
    ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    busy0, t0 = _proc_stat_busy(), time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env=ENV, **kw)
    wall = time.perf_counter() - t0
    busy1, ru1 = _proc_stat_busy(), resource.getrusage(resource.RUSAGE_CHILDREN)
    ours = (ru1.ru_utime - ru0.ru_utime) + (ru1.ru_stime - ru0.ru_stime)
    return {"proc": proc, "wall_s": wall, "cpu_s": ours, "others_cpu_s": max(0.0, (busy1 - busy0) - ours),
            "load1": os.getloadavg()[0]}


def batch(*args) -> list[str]:
    return [sys.executable, "-m", "lopcook", "batch", *map(str, args)]


def _input_size(source: str) -> int:
    return os.path.getsize(source)


def _makespan(times, workers: int) -> float:
    """List scheduling: each task (in order) starts on the first free worker; the last finish."""
    free = [0.0] * workers
    for t in times:
        i = free.index(min(free))
        free[i] += t
    return max(free)


def lop_files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*.lop"))}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--corpus", default=os.environ.get("LOPCOOK_CORPUS", str(REPO.parent / "shared" / "corpus")))
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--dask", action="store_true")
    ap.add_argument("--ninja", action="store_true")
    ap.add_argument("-o", "--output", default=None, help="write the results as JSON here")
    a = ap.parse_args()
    corpus = Path(a.corpus).resolve()
    work = Path(tempfile.mkdtemp(prefix="bench-batch-"))
    report: dict = {"corpus": str(corpus), "cpus": len(os.sched_getaffinity(0))}
    try:
        # 1. one lopcook cook per asset
        from lopcook.batch.discover import discover

        assets = discover([corpus], work / "ref")
        ref = work / "ref"
        t = {"wall_s": 0.0, "cpu_s": 0.0}
        for asset in assets:
            os.makedirs(os.path.dirname(asset.output), exist_ok=True)
            r = timed([sys.executable, "-m", "lopcook", "cook", asset.source, "-o", asset.output, "-q"])
            assert r["proc"].returncode == 0, r["proc"].stderr
            t["wall_s"] += r["wall_s"]
            t["cpu_s"] += r["cpu_s"]
        report["one_cook_per_asset"] = dict(t, assets=len(assets))
        want = lop_files(ref)
        print(f"one lopcook cook per asset: {len(assets)} assets, {t['wall_s']:.1f} s wall, {t['cpu_s']:.1f} s CPU")

        # 2. serial and --jobs 2, alternated
        runs: dict[str, list] = {"1": [], "2": []}
        for i in range(a.repeat):
            for jobs in (("1", "2") if i % 2 == 0 else ("2", "1")):
                out = work / f"out-j{jobs}-{i}"
                r = timed(batch(corpus, "-o", out, "--jobs", jobs, "--json", "-q"))
                assert r["proc"].returncode == 0, r["proc"].stderr
                doc = json.loads(r["proc"].stdout)
                same = lop_files(out) == want
                # cooks running at once, on average: the sum of their wall times over the batch's
                concurrency = sum(x["time_s"] or 0.0 for x in doc["assets"]) / r["wall_s"]
                if jobs == "1":  # what 2 workers would take with these cook times, in the batch's order
                    times = [x["time_s"] for x in sorted(doc["assets"], key=lambda x: -_input_size(x["source"]))]
                    report.setdefault("schedule_2_workers", []).append(
                        {"serial_cooks_s": sum(times), "makespan_s": _makespan(times, 2)})
                runs[jobs].append({k: r[k] for k in ("wall_s", "cpu_s", "others_cpu_s", "load1")}
                                  | {"identical": same, "cook_cpu_s": doc["cpu_s"], "concurrency": concurrency})
                print(f"--jobs {jobs} (run {i + 1}): {r['wall_s']:.2f} s wall, {r['cpu_s']:.1f} s CPU ours, "
                      f"{r['others_cpu_s']:.1f} s CPU others, load {r['load1']:.2f}, cooks at once "
                      f"{concurrency:.2f}, identical to cook: {same}")
        best = {j: min(x["wall_s"] for x in v) for j, v in runs.items()}
        med = {j: statistics.median(x["wall_s"] for x in v) for j, v in runs.items()}
        report["runs"] = runs
        report["ratio_best"] = best["2"] / best["1"]
        report["ratio_median"] = med["2"] / med["1"]
        print(f"--jobs 2 / --jobs 1 wall: {report['ratio_best']:.2f} (best of {a.repeat}), "
              f"{report['ratio_median']:.2f} (median)")
        for m in report["schedule_2_workers"]:
            print(f"  model: the --jobs 1 cook times ({m['serial_cooks_s']:.1f} s) on 2 uncontended workers, "
                  f"largest first: {m['makespan_s']:.1f} s = {m['makespan_s'] / m['serial_cooks_s']:.2f}x")

        # 3. second run: nothing to cook
        out = work / "out-j2-0"
        r = timed(batch(corpus, "-o", out, "--jobs", "2"))
        report["second_run"] = {"wall_s": r["wall_s"], "stdout": r["proc"].stdout.strip(),
                                "exit": r["proc"].returncode}
        print(f"second run: {r['wall_s']:.2f} s: {r['proc'].stdout.strip()}")

        # 4. one corrupt file in a copy of the tree
        tree = work / "corpus-copy"
        shutil.copytree(corpus, tree)
        for p in tree.rglob("*"):
            os.chmod(p, 0o755 if p.is_dir() else 0o644)
        (tree / "broken.glb").write_bytes(b"glTF\x02\x00\x00\x00\x10\x00\x00\x00truncated")
        r = timed(batch(tree, "-o", work / "out-corrupt", "--jobs", "2"))
        lines = r["proc"].stdout.strip().splitlines()
        report["corrupt"] = {"exit": r["proc"].returncode, "summary": lines,
                             "identical_others": lop_files(work / "out-corrupt") == want}
        print(f"corrupt file: exit {r['proc'].returncode}; " + " | ".join(lines))
        # then: the corrupt file removed, one texture's bytes changed -> only its asset cooks
        (tree / "broken.glb").unlink()
        tex = tree / "DamagedHelmet" / "Default_albedo.jpg"
        tex.write_bytes(tex.read_bytes() + b"\0")
        r = timed(batch(tree, "-o", work / "out-corrupt", "--jobs", "2", "--json", "-q"))
        cooked = [x["relpath"] for x in json.loads(r["proc"].stdout)["assets"] if x["status"] == "cooked"]
        report["texture_change"] = {"cooked": cooked, "wall_s": r["wall_s"]}
        print(f"albedo texture changed: cooked {cooked} ({r['wall_s']:.1f} s)")

        if a.dask:
            report["dask"] = _dask(corpus, work, want)
        if a.ninja:
            report["ninja"] = _ninja(corpus, work, want)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    if a.output:
        with open(a.output, "w") as fh:
            json.dump(report, fh, indent=1, default=str)
    return 0


def _dask(corpus: Path, work: Path, want: dict) -> dict:
    sched_file = work / "scheduler.json"
    log = open(work / "dask.log", "wb")
    dask = lambda *args, cwd: subprocess.Popen([sys.executable, "-m", "dask", *args], cwd=cwd, env=ENV,
                                               stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    procs = [dask("scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard", "--scheduler-file",
                  str(sched_file), cwd=work)]
    try:
        while not sched_file.is_file():
            time.sleep(0.2)
        time.sleep(0.2)
        address = json.loads(sched_file.read_text())["address"]
        for i in range(2):
            (work / f"w{i}").mkdir()
            procs.append(dask("worker", address, "--nworkers", "1", "--nthreads", "1", "--host", "127.0.0.1",
                              "--no-dashboard", "--local-directory", str(work / f"w{i}"), cwd=work / f"w{i}"))
        from distributed import Client

        with Client(address, timeout=60) as c:
            c.wait_for_workers(2, timeout=90)
        r = timed(batch(corpus, "-o", work / "out-dask", "--scheduler", address, "--json", "-q"))
        doc = json.loads(r["proc"].stdout)
        res = {"exit": r["proc"].returncode, "wall_s": r["wall_s"], "workers": doc.get("workers"),
               "identical": lop_files(work / "out-dask") == want}
        print(f"dask (2 workers): exit {res['exit']}, {r['wall_s']:.1f} s, identical: {res['identical']}")
        return res
    finally:
        for p in procs:
            os.killpg(p.pid, signal.SIGTERM)
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait()
        log.close()


def _ninja(corpus: Path, work: Path, want: dict) -> dict:
    build = work / "build.ninja"
    subprocess.run(batch(corpus, "-o", work / "out-ninja", "--emit-ninja", build, "-q"), check=True, env=ENV)
    ninja = [sys.executable, "-m", "ninja", "-f", str(build), "-j", "2"]
    r1 = timed(ninja, cwd=work)   # ninja keeps .ninja_log / .ninja_deps in its working directory
    r2 = timed(ninja, cwd=work)
    res = {"first_exit": r1["proc"].returncode, "first_wall_s": r1["wall_s"], "second_stdout": r2["proc"].stdout.strip(),
           "identical": lop_files(work / "out-ninja") == want}
    print(f"ninja -j 2: {r1['wall_s']:.1f} s, exit {res['first_exit']}; second run: {res['second_stdout']!r}; "
          f"identical: {res['identical']}")
    return res


if __name__ == "__main__":
    sys.exit(main())
