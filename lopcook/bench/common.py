"""What every ``lopcook bench`` run shares: the corpus, asset names, the ingested source, child cooks
(``python -m lopcook cook --json``, measured by ``peers.run_measured``), CSV files and the machine.

Units: seconds, bytes (``mib`` gives MiB, 2^20 bytes), metres (the scene's).
"""

from __future__ import annotations

import csv
import importlib.metadata
import io
import json
import math
import os
import platform
import re
import struct
import sys
from pathlib import Path

import numpy as np

from ..atomic import write_atomic
from ..grid import Grid
from . import metrics as BM
from . import peers as P

ASSET_TIMEOUT_S = 3600


def log(opts, msg: str) -> None:
    if not getattr(opts, "quiet", False):
        print(f"bench: {msg}", file=sys.stderr, flush=True)


def corpus_dir() -> Path | None:
    """``$LOPCOOK_CORPUS`` or ``<repo>/../shared/corpus`` (where it holds corpus.json)."""
    env = os.environ.get("LOPCOOK_CORPUS")
    for c in ([Path(env)] if env else []) + [P.REPO.parent / "shared" / "corpus"]:
        if (c / "corpus.json").is_file():
            return c
    return None


def asset_name(path) -> str:
    """Short stable name of an asset: the file stem, safe for paths."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", Path(path).stem)


def mib(nbytes) -> float:
    """Bytes in MiB (2^20 bytes), one decimal: the unit of every ``peak_rss_mb`` column."""
    return round(float(nbytes) / 2**20, 1)


class Source:
    """The ingested source and what every measurement needs of it (all parts concatenated)."""

    def __init__(self, scene):
        self.scene = scene
        parts = scene.parts
        self.offsets = np.cumsum([0] + [p.n_vertices for p in parts])
        self.positions = np.concatenate([p.positions for p in parts])
        self.part = np.repeat(np.arange(len(parts)), [p.n_vertices for p in parts])
        self.attr = np.concatenate([BM.attribute_features(p.normals, p.uvs, p.n_vertices) for p in parts])
        self.classes = BM.colocation_classes(self.positions)
        lo, hi = scene.bounds()
        self.diagonal = float(np.linalg.norm(hi - lo))

        self.extent = float(Grid.fit([p.positions for p in parts]).extent)
        self.triangles = int(sum(p.n_triangles for p in parts))
        self.vertices = int(self.positions.shape[0])


def glb_json(path) -> dict:
    """The JSON chunk of a .glb (or the whole .gltf)."""
    data = Path(path).read_bytes()
    if data[:4] != b"glTF":
        return json.loads(data)
    length, kind = struct.unpack_from("<I4s", data, 12)
    return json.loads(data[20:20 + length])


def cook_stages(timings: dict) -> dict:
    """``lopcook cook --json`` timings_s -> the bench's stages (seconds). E_v and depth are the
    analysis of LOD 0; "analyse other" is the rest of the analysis (grid, co-located sharing,
    and the analysis of the other LODs)."""
    ev = float(timings.get("analyse.attribute_error", 0.0))
    depth = float(timings.get("analyse.depth", 0.0))
    out = {"ingest": timings.get("ingest", 0.0), "lod": timings.get("lod", 0.0), "E_v": ev, "depth": depth,
           "analyse other": max(0.0, float(timings.get("analyse", 0.0)) - ev - depth),
           "bins/planes": timings.get("emit", 0.0), "write": timings.get("write", 0.0),
           "calibrate": timings.get("calibrate", 0.0)}
    return {k: float(v) for k, v in out.items()}


def run_cook(source, out_lop, extra=(), timeout_s=ASSET_TIMEOUT_S) -> tuple[P.Measured, dict | None]:
    """``python -m lopcook cook SOURCE -o OUT --json`` in a child process; (measured, JSON or None)."""
    m = P.run_measured([sys.executable, "-m", "lopcook", "cook", str(source), "-o", str(out_lop), "--json",
                        *extra], timeout_s=timeout_s)
    desc = None
    if m.returncode == 0:
        try:
            desc = json.loads(m.stdout)
        except json.JSONDecodeError:
            desc = None
    return m, desc


def write_csv(path: Path, rows: list[dict], columns) -> None:
    """Write ``rows`` to the CSV ``path`` atomically with the header ``columns`` (missing keys empty,
    floats to 6 significant digits, infinity as ``inf``)."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(columns), extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: _csv_value(r.get(k, "")) for k in columns})
    write_atomic(path, buf.getvalue().encode())


def _csv_value(v):
    if isinstance(v, float):
        if math.isinf(v):
            return "inf"
        return f"{v:.6g}"
    return v


def machine() -> dict:
    """The bench machine's description for the summary: Python version, platform, CPU count, and where
    /proc allows the CPU model and memory in GiB."""
    info = {"python": platform.python_version(), "platform": platform.platform(), "cpus": os.cpu_count()}
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                info["cpu"] = line.split(":", 1)[1].strip()
                break
        mem = Path("/proc/meminfo").read_text().splitlines()[0].split()
        info["memory_gb"] = round(int(mem[1]) / 2**20, 1)
    except OSError:
        pass
    return info


def dracopy_version() -> str:
    try:
        return importlib.metadata.version("DracoPy")
    except Exception:  # noqa: BLE001
        return "unknown"


__all__ = ["ASSET_TIMEOUT_S", "log", "corpus_dir", "asset_name", "mib", "Source", "glb_json", "cook_stages", "run_cook",
           "write_csv", "machine", "dracopy_version"]
