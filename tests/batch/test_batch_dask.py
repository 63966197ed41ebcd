"""lopcook batch --scheduler: a real `dask scheduler` and two `dask worker` processes on
127.0.0.1 (random ports), the same batch as locally, byte for byte."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time

import pytest

from conftest import FIXTURES, REPO, require


def _dask(*args, cwd, log):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])]))
    return subprocess.Popen([sys.executable, "-m", "dask", *args], cwd=cwd, env=env, stdout=log,
                            stderr=subprocess.STDOUT, start_new_session=True)


def _stop(procs):
    for p in procs:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGTERM)
    deadline = time.monotonic() + 20
    for p in procs:
        try:
            p.wait(timeout=max(0.1, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()


@pytest.fixture
def cluster(tmp_path):
    """tcp address of a scheduler with two single-threaded workers, each in its own directory."""
    try:
        from distributed import Client
    except ImportError:
        require("the distributed package is not installed (pip install 'lopcook[test]')")

    sched_file = tmp_path / "scheduler.json"
    procs = []
    logs = tmp_path / "dask-logs.txt"
    with open(logs, "wb") as log:
        try:
            procs.append(_dask("scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                               "--scheduler-file", str(sched_file), cwd=tmp_path, log=log))
            deadline = time.monotonic() + 60
            while not sched_file.is_file() and time.monotonic() < deadline:
                assert procs[0].poll() is None, logs.read_text()
                time.sleep(0.2)
            assert sched_file.is_file(), logs.read_text()
            time.sleep(0.2)
            address = json.loads(sched_file.read_text())["address"]
            for i in range(2):
                wdir = tmp_path / f"worker{i}"   # workers run elsewhere: the batch passes absolute paths
                wdir.mkdir()
                procs.append(_dask("worker", address, "--nworkers", "1", "--nthreads", "1", "--host", "127.0.0.1",
                                   "--no-dashboard", "--local-directory", str(wdir), "--name", f"w{i}",
                                   cwd=wdir, log=log))
            with Client(address, timeout=60) as c:
                c.wait_for_workers(2, timeout=90)
            yield address
        finally:
            _stop(procs)
    assert all(p.poll() is not None for p in procs)


def test_dask_batch_gives_the_local_bytes(cluster, corpus, tmp_path):
    root = tmp_path / "assets"
    (root / "sub").mkdir(parents=True)
    shutil.copy(corpus / "Duck.glb", root / "Duck.glb")
    shutil.copy(corpus / "fandisk.obj", root / "sub/fandisk.obj")
    shutil.copy(FIXTURES / "seamed_cube.usda", root / "sub/cube.usda")
    shutil.copy(FIXTURES / "two_plates.gltf", root / "plates.gltf")
    shutil.copy(FIXTURES / "two_plates.bin", root / "two_plates.bin")
    (root / "bad.obj").write_text("v 0 0 0\nf 1 2 3\n")
    cfg = tmp_path / "lopcook.toml"
    cfg.write_text('[[rules]]\nglob = "sub/**"\noptions = ["--lods", "1/2"]\n')
    run = lambda *a: subprocess.run([sys.executable, "-m", "lopcook", "batch", str(root), "--config", str(cfg),
                                     "--json", *a], capture_output=True, text=True)
    local = run("-o", str(tmp_path / "local"), "--jobs", "2")
    remote = run("-o", str(tmp_path / "dask"), "--scheduler", cluster)
    assert local.returncode == remote.returncode == 2, remote.stderr   # bad.obj fails on both
    ls, ds = json.loads(local.stdout), json.loads(remote.stdout)
    assert ds["scheduler"] == cluster and ds["workers"] == 2
    by = lambda doc: {a["relpath"]: a for a in doc["assets"]}
    assert {k: a["status"] for k, a in by(ds).items()} == {k: a["status"] for k, a in by(ls).items()} == {
        "Duck.glb": "cooked", "plates.gltf": "cooked", "sub/fandisk.obj": "cooked", "sub/cube.usda": "cooked",
        "bad.obj": "failed"}
    assert by(ds)["bad.obj"]["error"] == by(ls)["bad.obj"]["error"]
    # the cooks ran in the Dask workers, not in the batch process
    runners = {a["runner_pid"] for a in ds["assets"]}
    assert ds["pid"] not in runners and all(a["runner_pid"] == ls["pid"] for a in ls["assets"])
    files = sorted(p.relative_to(tmp_path / "local") for p in (tmp_path / "local").rglob("*.lop"))
    assert len(files) == 4
    assert files == sorted(p.relative_to(tmp_path / "dask") for p in (tmp_path / "dask").rglob("*.lop"))
    for f in files:
        assert (tmp_path / "local" / f).read_bytes() == (tmp_path / "dask" / f).read_bytes(), f
    # incremental on the cluster too
    again = run("-o", str(tmp_path / "dask"), "--scheduler", cluster)
    assert {a["relpath"] for a in json.loads(again.stdout)["assets"] if a["status"] == "cooked"} == set()


def test_unreachable_scheduler_is_one_usage_error(tmp_path):
    import socket

    with socket.socket() as s:       # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    (tmp_path / "a").mkdir()
    shutil.copy(FIXTURES / "seamed_cube.glb", tmp_path / "a/cube.glb")
    proc = subprocess.run([sys.executable, "-m", "lopcook", "batch", str(tmp_path / "a"), "-o", str(tmp_path / "o"),
                           "--scheduler", f"tcp://127.0.0.1:{port}", "--scheduler-timeout", "2"],
                          capture_output=True, text=True)
    assert proc.returncode == 2 and proc.stdout == ""
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("lopcook: error: usage: --scheduler tcp://127.0.0.1:")
    assert "cannot connect" in lines[0] and not (tmp_path / "o/cube.lop").exists()
