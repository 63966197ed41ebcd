"""runtime/js/lop.js on the streaming layout and encoded sections (docs/format.md 14-15) against
lopcook's reader: identical decodes of every corpus container rewritten in the streaming layout
(``lopcook.emit.stages.streamed``, what ``cook --stream`` writes) at levels 6, 11, 16 and 24; the
same verdict and stage levels on every cut of a streaming file and on the hostile files of
``tests.support.streamcases``; a LopStream whose stage levels after every chunk are those of the
same prefix, with one event per stage that improves; and the same verdict as zlib and
meshoptimizer on mutated DEFLATE and triangle streams (runtime/js/lop-codecs.js).
"""

from __future__ import annotations

import struct

import numpy as np
import pytest

import runtime_support as rs
from lopcook.errors import LopcookError
from lopcook.lop.container import from_bytes
from lopcook.lop.encoding import deflate
from lopcook.emit.stages import streamed
from test_js_reader import NAMES, compare, js_verdicts, run_js
from tests.support import streamcases as sc


@pytest.fixture(scope="module")
def stream_files(corpus_containers, tmp_path_factory) -> dict:
    """{name: path} of every cooked container in the streaming layout."""
    out = tmp_path_factory.mktemp("streamed")
    files = {}
    for name, path in corpus_containers.items():
        files[name] = out / f"{name}.lop"
        files[name].write_bytes(streamed(from_bytes(path.read_bytes())).data)
    return files


@pytest.mark.parametrize("name", NAMES)
def test_stream_decodes_equal_the_python_reader(node, stream_files, tmp_path, name):
    path = stream_files[name]
    c = from_bytes(path.read_bytes(), str(path))
    got = run_js(node, [{"id": name, "file": str(path), "decode": True, "levels": list(rs.LEVELS)}], tmp_path)[name]
    assert got["ok"], got["error"]
    assert got["version"] == [4, 0] and got["stage_levels"] == c.stage_levels
    compare(got["buffers"], rs.reference(c, rs.LEVELS), name)


def _stage_levels(data: bytes) -> list | None:
    try:
        return from_bytes(data, allow_prefix=True).stage_levels
    except LopcookError:
        return None


def _cuts(data: bytes) -> list[int]:
    ends = sorted(set(sc._ends(data).values()))
    cuts = {e + d for e in ends for d in (-1, 0)} | {31, 32, 33}
    return sorted(x for x in cuts if 0 < x < len(data))


@pytest.mark.parametrize("name", ["duck-lods", "chess_set_flat"])
def test_stream_prefixes_get_the_python_verdict(node, stream_files, tmp_path, name):
    """Every section boundary of a streaming file (and a byte before it): lop.js accepts what
    lopcook accepts, with the same stage levels, and decodes every buffer that arrived as lopcook
    does; the refusals are one line naming the file."""
    data = stream_files[name].read_bytes()
    cuts = _cuts(data)[:: max(1, len(_cuts(data)) // 150)]
    cases = []
    for cut in cuts:
        f = tmp_path / f"cut{cut}.lop"
        f.write_bytes(data[:cut])
        cases.append((f"cut{cut}", f, rs.verdict(data[:cut], allow_prefix=True)))
    assert any(ok for _, _, (ok, _, _) in cases) and any(not ok for _, _, (ok, _, _) in cases)
    js_verdicts(node, cases, tmp_path, allow_prefix=True)
    got = run_js(node, [{"id": str(cut), "file": str(tmp_path / f"cut{cut}.lop"), "allow_prefix": True, "decode": True,
                         "levels": [1, 6, 11, 24]} for cut in cuts[::7]], tmp_path)
    for cut in cuts[::7]:
        g, want = got[str(cut)], _stage_levels(data[:cut])
        assert (g["stage_levels"] if g["ok"] else None) == want, cut
        if want is not None:
            compare(g["buffers"], rs.reference(from_bytes(data[:cut], allow_prefix=True), [1, 6, 11, 24]), f"cut {cut}")


def test_stream_events_follow_the_stages(node, stream_files, tmp_path):
    """LopStream over chunks of 1 byte to 16 KiB: after each chunk its stage levels are lopcook's
    for the same prefix; the events are 'manifest', 'renderable' (stage 0), one 'lod' per later
    stage as it becomes renderable, in stage order, 'plane' for every later rise, 'complete'."""
    path = stream_files["duck-lods"]
    data = path.read_bytes()
    rng = np.random.default_rng(9)
    ends = sorted({int(x) for x in np.cumsum(np.minimum(rng.geometric(1 / 2000, 2000), 16384)) if x < len(data)}
                  | {len(data)})
    got = run_js(node, [{"id": "s", "file": str(path), "chunks": ends}], tmp_path)["s"]["stream"]
    assert got["error"] is None, got["error"]
    stages = len(from_bytes(data).stage_levels)
    head = 32 + struct.unpack_from("<I", data, 12)[0]  # before it, no manifest: one level 0
    want = [_stage_levels(data[:e]) or [0] * (stages if e >= head else 1) for e in ends]
    assert got["stages"] == want
    events = got["events"]
    assert events[0][0] == "manifest" and events[1][0] == "renderable" and events[1][3] == 0 and events[-1][0] == "complete"
    lods = [e[3] for e in events if e[0] == "lod"]
    assert lods == list(range(1, len(want[-1])))
    seen: dict = {}
    for kind, level, _, stage in events[1:-1]:
        assert level > seen.get(stage, 0) and (kind == "plane") == (stage in seen)
        seen[stage] = level


def test_hostile_stream_files_get_the_python_verdict(node, tmp_path):
    cases = []
    for name, data, covers, _ in sc.stream_invalid_cases():
        (tmp_path / name).write_bytes(data)
        cases.append((name, tmp_path / name, rs.verdict(data)))
    for name, data, covers, _ in sc.stream_prefix_cases():
        (tmp_path / name).write_bytes(data)
    assert not any(ok for _, _, (ok, _, _) in cases)
    js_verdicts(node, cases, tmp_path)
    prefixes = [(n, tmp_path / n, rs.verdict(d, allow_prefix=True)) for n, d, _, _ in sc.stream_prefix_cases()]
    js_verdicts(node, prefixes, tmp_path, allow_prefix=True)


def test_mutated_streams_get_zlib_and_meshoptimizers_verdict(node, tmp_path):
    """Bytes of a deflate section and a meshopt-deflate section (its DEFLATE stream, and the
    triangle stream inside it) changed at random, checksums recomputed: lop-codecs.js accepts and
    refuses exactly what zlib and meshoptimizer do, and decodes what they accept identically."""
    data = sc.cooked("stream_plates.lop")
    rng = np.random.default_rng(11)
    _, secs = sc.stored_sections(data)
    cases = []
    for enc in ("deflate", "meshopt-deflate"):
        name = sc.encoded(data, enc)
        stored, fields = next((s, f) for n, s, f in secs if n == name)
        inner = sc.triangles_stream(data, name) if enc == "meshopt-deflate" else None
        for j in range(120):
            if inner is not None and j % 2:
                tri = bytearray(inner)
                tri[int(rng.integers(0, len(tri)))] = int(rng.integers(0, 256))
                blob = sc.with_section(data, name, deflate(bytes(tri)), fields)
            else:
                raw = bytearray(stored)
                at = int(rng.integers(0, len(raw)))
                raw[at] ^= 1 << int(rng.integers(0, 8))
                blob = sc.with_section(data, name, bytes(raw), fields)
            f = tmp_path / f"{enc}-{j}.lop"
            f.write_bytes(blob)
            cases.append((f.stem, f, rs.verdict(blob)))
    assert sum(ok for _, _, (ok, _, _) in cases) >= 3 and sum(not ok for _, _, (ok, _, _) in cases) >= 60
    js_verdicts(node, cases, tmp_path)
