"""lopcook's PLY reader (``lopcook/ingest/ply.py``) against trimesh's (``trimesh.exchange.ply``).

Not a test (pytest does not collect benchmarks/). Usage::

    .venv/bin/python benchmarks/bench_ply.py write OUTDIR          # the bunny as PLY, 3 encodings
    .venv/bin/python benchmarks/bench_ply.py compare OUTDIR        # in-process timings + what each keeps
    .venv/bin/python benchmarks/bench_ply.py load lopcook|trimesh FILE [--repeat N]   # for farm-bench

``write`` turns the corpus ``stanford-bunny.obj`` (``$LOPCOOK_CORPUS`` or ../shared/corpus) into
``bunny_ascii.ply``, ``bunny_binary_little_endian.ply`` and ``bunny_binary_big_endian.ply``
(float32 ``x y z``, ``uchar int`` face lists, as the Stanford scans ship) and ``lhex.ply`` (an
L-shaped hexagon with UVs and vertex colours). ``compare`` times, best of ``--repeat`` in this
process, the parse alone (lopcook: header and element data; trimesh: ``trimesh.load(...,
process=False)``) and lopcook's whole ``ply.load`` (which also computes normals), and prints what
each reader makes of ``lhex.ply``. ``load`` loads FILE N times: run it under ``farm-bench`` with
the other reader as ``--vs`` for the whole-process ratio.
"""

from __future__ import annotations

import argparse
import io
import os
import struct
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
ENCODINGS = ("ascii", "binary_little_endian", "binary_big_endian")
#: an L-shaped hexagon (area 3): a fan from its corner 0, (2, 1), crosses the notch
L_HEX = np.array([[2, 1, 0], [1, 1, 0], [1, 2, 0], [0, 2, 0], [0, 0, 0], [2, 0, 0]], float)


def _corpus() -> Path:
    return Path(os.environ.get("LOPCOOK_CORPUS") or REPO.parent / "shared" / "corpus")


def _ply(encoding: str, positions: np.ndarray, faces: list[list[int]], extra=()) -> bytes:
    """A PLY of float32 ``x y z`` (+ ``extra`` (name, struct code, ply type, values)) and faces."""
    props = [("x", "f", "float", positions[:, 0]), ("y", "f", "float", positions[:, 1]),
             ("z", "f", "float", positions[:, 2]), *extra]
    head = [f"ply\nformat {encoding} 1.0\nelement vertex {positions.shape[0]}"]
    head += [f"property {t} {name}" for name, _, t, _ in props]
    head += [f"element face {len(faces)}", "property list uchar int vertex_indices", "end_header\n"]
    out = "\n".join(head).encode()
    if encoding == "ascii":
        rows = zip(*(v for *_, v in props))
        out += "".join(" ".join(repr(float(x)) if c == "f" else str(int(x)) for x, (_, c, _, _) in zip(row, props))
                       + "\n" for row in rows).encode()
        return out + "".join(f"{len(f)} " + " ".join(map(str, f)) + "\n" for f in faces).encode()
    order = "<" if encoding == "binary_little_endian" else ">"
    rec = np.rec.fromarrays([v for *_, v in props], dtype=[(n, order + ("f4" if c == "f" else "u1"))
                                                          for n, c, _, _ in props])
    out += rec.tobytes()
    return out + b"".join(struct.pack(f"{order}B{len(f)}i", len(f), *f) for f in faces)


def write(outdir: Path) -> None:
    outdir.mkdir(parents=True, exist_ok=True)
    v, f = [], []
    for line in open(_corpus() / "stanford-bunny.obj"):
        if line.startswith("v "):
            v.append(line.split()[1:4])
        elif line.startswith("f "):
            f.append([int(c.split("/")[0]) - 1 for c in line.split()[1:]])
    positions = np.array(v, dtype=np.float32)
    for enc in ENCODINGS:
        (outdir / f"bunny_{enc}.ply").write_bytes(_ply(enc, positions, f))
    extra = [("s", "f", "float", L_HEX[:, 0] / 2), ("t", "f", "float", L_HEX[:, 1] / 2),
             ("red", "B", "uchar", np.full(6, 255)), ("green", "B", "uchar", np.zeros(6, int)),
             ("blue", "B", "uchar", np.zeros(6, int))]
    (outdir / "lhex.ply").write_bytes(_ply("ascii", L_HEX, [[0, 1, 2, 3, 4, 5]], extra))
    print(f"wrote {outdir}")


def _best(fn, repeat: int) -> float:
    fn()
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def compare(outdir: Path, repeat: int) -> None:
    import trimesh

    from lopcook.ingest import ply
    from lopcook.settings import DEFAULT_INGEST

    print(f"trimesh {trimesh.__version__}; best of {repeat} in one process; ratio = trimesh / lopcook")
    for enc in ENCODINGS:
        path = outdir / f"bunny_{enc}.ply"
        data = path.read_bytes()

        def ours():
            header = ply._read_header(data)
            ply._elements(data, header)

        t_ours = _best(ours, repeat)
        t_tm = _best(lambda: trimesh.load(io.BytesIO(data), file_type="ply", process=False), repeat)
        t_full = _best(lambda: ply.load(str(path), settings=DEFAULT_INGEST), repeat)
        print(f"{enc:22s} parse: lopcook {t_ours * 1e3:7.2f} ms, trimesh {t_tm * 1e3:7.2f} ms, ratio "
              f"{t_tm / t_ours:5.2f}; lopcook ply.load with normals {t_full * 1e3:7.2f} ms")
    path = outdir / "lhex.ply"
    m = trimesh.load(str(path), process=False)
    tri = m.vertices[m.faces]
    area = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])[:, 2] / 2
    print(f"L hexagon, trimesh: signed areas {area.tolist()} (sum of |area| {np.abs(area).sum():g}); "
          f"visual {m.visual.kind!r}: UVs {getattr(m.visual, 'uv', None) is not None}, "
          f"vertex colours {m.visual.kind == 'vertex'}")
    part = ply.load(str(path), settings=DEFAULT_INGEST).parts[0]
    q = part.positions[part.indices.astype(np.int64)]
    area = np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0])[:, 2] / 2
    print(f"L hexagon, lopcook: signed areas {area.tolist()} (sum {area.sum():g}); UVs {part.uvs is not None}, "
          f"vertex colours {part.colors is not None}")


def load(reader: str, path: str, repeat: int) -> None:
    if reader == "trimesh":
        import trimesh

        for _ in range(repeat):
            trimesh.load(path, process=False)
    else:
        from lopcook.ingest import ply
        from lopcook.settings import DEFAULT_INGEST

        for _ in range(repeat):
            ply.load(path, settings=DEFAULT_INGEST)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    sub.add_parser("write").add_argument("outdir", type=Path)
    c = sub.add_parser("compare")
    c.add_argument("outdir", type=Path)
    c.add_argument("--repeat", type=int, default=7)
    ld = sub.add_parser("load")
    ld.add_argument("reader", choices=("lopcook", "trimesh"))
    ld.add_argument("file")
    ld.add_argument("--repeat", type=int, default=10)
    args = p.parse_args(argv)
    if args.cmd == "write":
        write(args.outdir)
    elif args.cmd == "compare":
        compare(args.outdir, args.repeat)
    else:
        load(args.reader, args.file, args.repeat)
    return 0


if __name__ == "__main__":
    sys.exit(main())
