"""The peer tools of ``lopcook bench``: where they are found, how they are run and measured.

Peers (each optional; a missing one is skipped with one line):

* **gltfpack** (npm ``gltfpack``, the WASM build run by node): ``-vp N -kv -vtf`` for N in the
  position bit counts (UVs kept as float32, see ``gltfpack_argv``), with ``-noq``-free defaults otherwise (normals 8 bits, UVs 12 bits) and without
  simplification (``-si`` stays 1), plus the same with ``-cc`` (meshopt compression). For the
  scaling chart, ``-si 0.5 -vp 14``.
* **glTF-Transform** (npm ``@gltf-transform/cli``): ``quantize --quantize-position N``.
* **Draco** (pip ``DracoPy``): ``encode(points, faces, quantization_bits=N)`` per part, in a child
  Python process (``python -m lopcook.bench.draco_run``).

Where the tools are looked for: ``$LOPCOOK_PEERS/node_modules/.bin`` (default ``<repo>/.peers``,
filled by ``benchmarks/install_peers.sh``), then ``$PATH``. DracoPy is imported by the child
process of the interpreter running the bench (``pip install lopcook[bench]``).

Wall time and peak RSS (``run_measured``): each tool runs as one child process under GNU time
(``/usr/bin/time -f %M``: the tool's ``ru_maxrss``, its peak resident set, kilobytes on Linux);
wall time is ``time.perf_counter`` from just before the start to the reaping, so it includes
process start-up (node and the WASM module, or the Python interpreter and its imports).
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
GLTFPACK_VERSION = "1.3.0"
GLTF_TRANSFORM_VERSION = "4.5.1"
DRACOPY_VERSION = "2.2.0"
PEERS = ("gltfpack", "gltf-transform", "draco")


@dataclass
class Measured:
    """One child process: argv, exit status, wall seconds, peak RSS in bytes, stderr tail."""

    argv: list
    returncode: int
    wall_s: float
    peak_rss_bytes: int
    stdout: str
    stderr: str


GNU_TIME = "/usr/bin/time"


def _gnu_time() -> str | None:
    """GNU time, if installed (its ``-f %M`` is the peak RSS of the command, in kilobytes)."""
    if not os.access(GNU_TIME, os.X_OK):
        return None
    try:
        r = subprocess.run([GNU_TIME, "-f", "%M", "true"], capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.TimeoutExpired):
        return None
    return GNU_TIME if r.returncode == 0 and r.stderr.strip().isdigit() else None


def run_measured(argv, timeout_s: float | None = None, env=None) -> Measured:
    """Run ``argv`` as a child process; wall time (seconds, ``time.perf_counter`` around start and
    reaping) and peak RSS (bytes). A child running past ``timeout_s`` is killed with its process
    group (returncode -9).

    Peak RSS: Linux carries a process's RSS high-water mark across ``fork`` and ``exec``, so the
    ``ru_maxrss`` of a child forked straight from the bench (hundreds of MB once a scene is
    loaded) is at least the bench's own RSS. The command therefore runs under GNU time
    (``/usr/bin/time -f %M``): time is the small process that forks and execs the tool, and
    reports the tool's ``ru_maxrss`` from ``wait4``. Without GNU time, ``os.wait4``'s
    ``ru_maxrss`` of the direct child is used (an upper bound: it includes the bench's RSS at fork)."""
    gnu = _gnu_time()
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err, \
            tempfile.NamedTemporaryFile("r", suffix=".rss") as rss_file:
        cmd = [str(a) for a in argv]
        if gnu:
            cmd = [gnu, "-f", "%M", "-o", rss_file.name, *cmd]
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=out, stderr=err, env=env, start_new_session=True)
        deadline = None if timeout_s is None else t0 + float(timeout_s)
        while True:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid == proc.pid:
                break
            if deadline is not None and time.perf_counter() > deadline:
                os.killpg(proc.pid, signal.SIGKILL)
                pid, status, usage = os.wait4(proc.pid, 0)
                break
            time.sleep(0.005)
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        peak = int(usage.ru_maxrss) * 1024
        if gnu:
            lines = [ln.strip() for ln in open(rss_file.name).read().splitlines() if ln.strip()]
            if lines and lines[-1].isdigit():
                peak = int(lines[-1]) * 1024
        out.seek(0)
        err.seek(0)
        return Measured(argv=[str(a) for a in argv], returncode=proc.returncode, wall_s=wall, peak_rss_bytes=peak,
                        stdout=out.read().decode("utf-8", "replace"), stderr=err.read().decode("utf-8", "replace"))


def peers_dir() -> Path:
    """``$LOPCOOK_PEERS`` or ``<repo>/.peers`` (npm prefix of ``benchmarks/install_peers.sh``)."""
    return Path(os.environ.get("LOPCOOK_PEERS") or (REPO / ".peers"))


def find_tool(name: str, path: str | None = None) -> str | None:
    """Executable of an npm peer: ``peers_dir()/node_modules/.bin/NAME`` then ``$PATH`` (or
    ``path`` when given). None when absent."""
    local = peers_dir() / "node_modules" / ".bin" / name
    if local.is_file() and os.access(local, os.X_OK):
        return str(local)
    return shutil.which(name, path=path)


def draco_available(python: str = sys.executable) -> bool:
    """Whether DracoPy imports in ``python`` (checked in a child process, as the bench runs it)."""
    try:
        return subprocess.run([python, "-c", "import DracoPy"], capture_output=True, timeout=60).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        return False


def availability(peers=PEERS, path: str | None = None, python: str = sys.executable) -> dict:
    """{peer: executable path (or python for draco) or None}."""
    out = {}
    for p in peers:
        if p == "draco":
            out[p] = python if draco_available(python) else None
        else:
            out[p] = find_tool(p, path)
    return out


def missing_line(peer: str) -> str:
    """The one line printed for a peer that is not installed."""
    how = {"gltfpack": f"npm install --prefix .peers gltfpack@{GLTFPACK_VERSION} (or benchmarks/install_peers.sh)",
           "gltf-transform": f"npm install --prefix .peers @gltf-transform/cli@{GLTF_TRANSFORM_VERSION} "
                             "(or benchmarks/install_peers.sh)",
           "draco": f"pip install 'lopcook[bench]' (DracoPy=={DRACOPY_VERSION})"}[peer]
    where = f"{peers_dir() / 'node_modules' / '.bin'} or PATH" if peer != "draco" else "this Python"
    return f"bench: skip {peer}: not installed (looked in {where}); install: {how}"


def tool_version(exe: str, peer: str) -> str:
    """Version string of an npm peer (gltfpack -v prints 'gltfpack 1.3'; gltf-transform --version)."""
    argv = [exe, "-v"] if peer == "gltfpack" else [exe, "--version"]
    try:
        r = subprocess.run(argv, capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        return "unknown"
    text = (r.stdout + r.stderr).strip().splitlines()
    return text[0].strip() if text else "unknown"


def gltfpack_argv(exe: str, src, out, bits: int, compress: bool = False, simplify: float | None = None) -> list:
    """gltfpack command line: ``-vp bits`` (positions), ``-kv -vtf`` (keep UVs, as float32: the bench's
    input GLB has no material, so without ``-kv`` gltfpack drops UVs and merges vertices across UV
    seams, and its quantized UVs would need a material's KHR_texture_transform to dequantize),
    ``-cc`` when compressing, ``-si`` only when asked (the accuracy runs
    never simplify)."""
    argv = [exe, "-i", str(src), "-o", str(out), "-vp", str(int(bits)), "-kv", "-vtf"]
    if compress:
        argv.append("-cc")
    if simplify is not None:
        argv += ["-si", f"{float(simplify):g}"]
    return argv


def gltf_transform_argv(exe: str, src, out, bits: int) -> list:
    """glTF-Transform ``quantize`` with ``--quantize-position bits`` (other attributes at their
    defaults: normals 10, UVs 12, colours 8 bits; quantization volume per mesh)."""
    return [exe, "quantize", str(src), str(out), "--quantize-position", str(int(bits))]


def draco_argv(python: str, npz, out, bits: int) -> list:
    """Child process encoding every part of ``npz`` with DracoPy at ``bits`` and decoding it back."""
    return [python, "-m", "lopcook.bench.draco_run", str(npz), str(out), str(int(bits))]


__all__ = ["PEERS", "Measured", "run_measured", "peers_dir", "find_tool", "draco_available", "availability",
           "missing_line", "tool_version", "gltfpack_argv", "gltf_transform_argv", "draco_argv"]
