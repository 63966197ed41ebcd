"""runtime/js/lop.js against lopcook's reader: identical decodes of every corpus asset at levels 6,
11, 16 and 24 (positions as float32 bits, grid integers, packed P, clustered P and records,
indices, normals, UVs, colours), the same verdict on every hostile container and prefix, the
streaming reader at every chunk equal to a prefix read, range requests that fetch nothing twice,
and the tangents of container version 4.0 (runtime_support.with_tangents).

lop.js runs in node (``tests/runtime/js_reader.mjs``), one process per batch of files;
``js_verdicts`` is the one function that runs it over a list of (file, expected outcome).
"""

from __future__ import annotations

import copy
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

import runtime_support as rs
from tests.support import fuzzcases as fz
from lopcook.lop import reader
from lopcook.lop.container import from_bytes

HERE = Path(__file__).resolve().parent
DRIVER = HERE / "js_reader.mjs"


def run_js(node: str, cases: list[dict], tmp: Path) -> dict:
    """Run lop.js over ``cases`` (js_reader.mjs jobs); results by id."""
    jobs = tmp / f"jobs-{len(list(tmp.glob('jobs-*')))}.json"
    jobs.write_text(json.dumps({"cases": cases}))
    out = subprocess.run([node, str(DRIVER), str(jobs)], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    results = {}
    for line in out.stdout.splitlines():
        r = json.loads(line)
        assert not (r["error"] or "").startswith("NOT A LopError"), r["error"]
        results[r["id"]] = r
    return results


def js_verdicts(node: str, cases: list[tuple[str, Path, tuple]], tmp: Path, *, allow_prefix: bool = False) -> None:
    """Assert that lop.js gives each file the expected outcome: ``cases`` are (name, file,
    (accepted, available level or None, message or None)); a refusal must be one line naming the file.
    The expected outcome is the Python reader's (``runtime_support.verdict``) or a conformance
    fixture's."""
    got = run_js(node, [{"id": name, "file": str(f), "allow_prefix": allow_prefix, "decode": True,
                         "levels": []} for name, f, _ in cases], tmp)
    wrong = []
    for name, f, (ok, level, msg) in cases:
        r = got[name]
        if r["ok"] != ok or (ok and r["available_level"] != level):
            wrong.append(f"{name}: python {'accepts at level %s' % level if ok else 'refuses: ' + str(msg)}; "
                         f"lop.js {'accepts at level %s' % r.get('available_level') if r['ok'] else 'refuses: ' + r['error']}")
        elif not ok:
            assert "\n" not in r["error"] and str(f) in r["error"], r["error"]
    assert not wrong, "\n".join(wrong[:20]) + f"\n({len(wrong)} of {len(cases)} differ)"


def compare(js: list[dict], py: list[dict], label: str) -> None:
    assert len(js) == len(py), label
    for a, b in zip(js, py):
        where = f"{label} part {b['part']} LOD {b['lod']}"
        for key in ("indices", "normals", "uvs", "colors", "tangents"):
            assert a[key] == b[key], f"{where}: {key} differ"
        assert a["levels"].keys() == b["levels"].keys(), where
        for level, ref in b["levels"].items():
            assert a["levels"][level] == ref, f"{where} level {level}: " + ", ".join(
                k for k in ref if a["levels"][level].get(k) != ref[k])


NAMES = [rs.stem(a) for a in rs.CORPUS_ASSETS] + list(rs.VARIANTS) + ["colored"]


@pytest.mark.parametrize("name", NAMES)
def test_decodes_equal_the_python_reader(node, corpus_containers, tmp_path, name):
    path = corpus_containers[name]
    c = from_bytes(path.read_bytes(), str(path))
    got = run_js(node, [{"id": name, "file": str(path), "decode": True, "levels": list(rs.LEVELS)}], tmp_path)[name]
    assert got["ok"], got["error"]
    assert got["version"] == list(np.frombuffer(c.data[4:8], "<u2")) and got["available_level"] == c.available_level
    compare(got["buffers"], rs.reference(c, rs.LEVELS), name)


def test_layouts_are_covered(corpus_containers):
    """The cooked set reaches 2.0 and 3.0 files, clustered and unclustered buffers, placements,
    LOD chains, a hierarchy section and every attribute (normals, UVs, colours)."""
    ms = {n: from_bytes(p.read_bytes()).manifest for n, p in corpus_containers.items()}
    lods = [e for m in ms.values() for p in m["parts"] for e in p["lods"]]
    assert {from_bytes(p.read_bytes()).data[4] for p in corpus_containers.values()} == {2, 3}
    assert any("cluster_size" in e for e in lods) and any("cluster_size" not in e for e in lods)
    assert any("placement" in p and p["placement"]["of"] != i for m in ms.values() for i, p in enumerate(m["parts"]))
    assert any(len(p["lods"]) > 1 for m in ms.values() for p in m["parts"])
    assert any("hierarchy" in p for m in ms.values() for p in m["parts"])
    for key in ("normals", "uvs", "colors"):
        assert any(e["attribute_bits"][key] for e in lods), key


def test_tangents_decode_as_written(node, tangent_files, tmp_path):
    got = run_js(node, [{"id": n, "file": str(p), "decode": True, "levels": [11, 24]} for n, p, _, _ in tangent_files],
                 tmp_path)
    for name, _, original, expected in tangent_files:
        r = got[name]
        assert r["ok"] and r["version"] == [4, 0], r["error"]
        ref = rs.reference(original, (11, 24))
        with_tangents = 0
        for b in ref:
            t = expected.get((b["part"], b["lod"]))
            b["tangents"] = rs.sha(t)
            with_tangents += t is not None
        assert with_tangents and (name != "chess-tangents" or with_tangents < len(ref))  # chess: mixed parts
        compare(r["buffers"], ref, name)


def test_tangent_version_rules(node, tangent_files, tmp_path):
    """A tangents key needs version 4.x; b_t in [4, 16] on the part and every LOD, record_bits with
    2 b_t + 1; majors 2, 3 and 4 are read, 5 is refused; a 4.0 file without tangents is read."""
    name, path, original, _ = tangent_files[0]
    blob = path.read_bytes()

    def lod_bits(v):
        def fn(m):
            m["parts"][0]["lods"][0]["attribute_bits"]["tangents"] = v
            m["parts"][0]["attribute_bits"]["tangents"] = v
        return fn

    cases = {"as_3.0": (rs.set_version(blob, 3, 0), False), "as_2.0": (rs.set_version(blob, 2, 0), False),
             "as_4.1": (rs.set_version(blob, 4, 1), True), "as_5.0": (rs.set_version(blob, 5, 0), False),
             "plain_as_4.0": (rs.set_version(original.data, 4, 0), True),
             "bits_17": (rs.replace_manifest(blob, lod_bits(17)), False),
             "bits_3": (rs.replace_manifest(blob, lod_bits(3)), False),
             "bits_null": (rs.replace_manifest(blob, lod_bits(None)), False),
             "bits_float": (rs.replace_manifest(blob, lambda m: (lod_bits(10)(m), m["parts"][0]["lods"][0]
                                                                 ["attribute_bits"].update(tangents=10.0))), False),
             "record_bits_without": (rs.replace_manifest(blob, lambda m: m["parts"][0]["lods"][0].update(
                 record_bits=m["parts"][0]["lods"][0]["record_bits"] - 21)), False),
             "part_lacks_tangents": (rs.replace_manifest(blob, lambda m: m["parts"][0]["attribute_bits"].pop("tangents")),
                                     False)}
    files = []
    for label, (data, ok) in cases.items():
        (tmp_path / f"{label}.lop").write_bytes(data)
        files.append((label, tmp_path / f"{label}.lop", (ok, 24 if ok else None, None)))
    js_verdicts(node, files, tmp_path)
    # the refusals of the version rule name it
    got = run_js(node, [{"id": "v", "file": str(tmp_path / "as_3.0.lop")}], tmp_path)["v"]
    assert "must not hold tangents (they need 4.x)" in got["error"]


def test_hostile_containers_get_the_python_verdict(node, tmp_path):
    """Every container lie of tests/support/fuzzcases.py (checksums recomputed, so only the checks catch
    them), and every byte of a small container flipped: lop.js refuses what lopcook's reader
    refuses and accepts what it accepts, at the same level."""
    w = fz._Writer(tmp_path / "hostile")
    fz._lop_cases(w, np.random.default_rng(17))
    dirs = sorted({Path(c.directory) for c in w.cases})
    cases = [(d.name, d / "a.lop", rs.verdict((d / "a.lop").read_bytes())) for d in dirs]
    base = fz._lop_base(tmp_path / "base")
    for at in range(0, len(base), max(1, len(base) // 400)):
        blob = bytearray(base)
        blob[at] ^= 0x5A
        (tmp_path / f"flip{at}.lop").write_bytes(blob)
        cases.append((f"flip{at}", tmp_path / f"flip{at}.lop", rs.verdict(bytes(blob))))
    assert sum(ok for _, _, (ok, _, _) in cases) >= 2 and sum(not ok for _, _, (ok, _, _) in cases) > 100
    js_verdicts(node, cases, tmp_path)


def _cuts(c) -> list[int]:
    """Cut points of a container: around every section boundary and the manifest, plus a spread."""
    base = 32 + len(json.dumps(c.manifest, sort_keys=True, separators=(",", ":")))
    size = len(c.data)
    cuts = {0, 1, 31, 32, 33, base - 1, base, base + 1, size - 1}
    for s in c.manifest["sections"]:
        for d in (-1, 0, 1):
            cuts.add(base + s["offset"] + d)
            cuts.add(base + s["offset"] + s["length"] + d)
    cuts |= set(np.linspace(0, size, 60).astype(int).tolist())
    return sorted(x for x in cuts if 0 <= x < size)


@pytest.mark.parametrize("name", ["DamagedHelmet", "bunny-unclustered", "CesiumMilkTruck", "spot-hierarchy"])
def test_prefixes_get_the_python_verdict(node, corpus_containers, tmp_path, name):
    data = corpus_containers[name].read_bytes()
    c = from_bytes(data)
    cases = []
    for cut in _cuts(c):
        (tmp_path / f"cut{cut}.lop").write_bytes(data[:cut])
        cases.append((f"cut{cut}", tmp_path / f"cut{cut}.lop", rs.verdict(data[:cut], allow_prefix=True)))
    assert any(ok for _, _, (ok, _, _) in cases) and any(not ok for _, _, (ok, _, _) in cases)
    js_verdicts(node, cases, tmp_path, allow_prefix=True)


def _prefix_level(data: bytes, end: int) -> int:
    ok, level, _ = rs.verdict(data[:end], allow_prefix=True, decode=False)
    return level if ok else 0


@pytest.mark.parametrize("name", ["chess_set_flat", "bunny-unclustered"])
def test_stream_levels_equal_prefix_levels(node, corpus_containers, tmp_path, name):
    """Streaming in chunks of 1 byte to 64 KiB: after each chunk, the level lop.js's LopStream
    offers is the level lopcook reads from the same prefix; the events are 'manifest', then
    'renderable', then one 'plane' per rise of the level, then 'complete'."""
    data = corpus_containers[name].read_bytes()
    rng = np.random.default_rng(5)
    sizes = np.minimum(rng.geometric(1 / 8000, 4000), 65536)
    ends = sorted({int(x) for x in np.cumsum(sizes) if x < len(data)} | {len(data)})
    got = run_js(node, [{"id": "s", "file": str(corpus_containers[name]), "chunks": ends}], tmp_path)["s"]["stream"]
    assert got["error"] is None, got["error"]
    levels = got["levels"]
    want = [_prefix_level(data, e) for e in ends]
    assert levels == want
    events = [e[0] for e in got["events"]]
    rises = sum(1 for a, b in zip([0] + want, want) if b > a)
    assert events == ["manifest", "renderable"] + ["plane"] * (rises - 1) + ["complete"]
    assert [e[1] for e in got["events"] if e[0] in ("renderable", "plane")] == sorted({x for x in want if x})


def test_range_reader_fetches_nothing_twice(node, corpus_containers, tmp_path):
    """LopRangeReader over a fake server: open() then fetchLevel(1), (8), (24): the requests are
    disjoint and contiguous, each level is the level lopcook reads from the prefix fetched, and the
    complete container decodes as lopcook's."""
    path = corpus_containers["DamagedHelmet"]
    data = path.read_bytes()
    got = run_js(node, [{"id": "r", "file": str(path), "range_levels": [1, 8, 24], "first_bytes": 4096}], tmp_path)
    r = got["r"]["ranges"]
    assert r["error"] is None, r["error"]
    reqs = r["requests"]
    assert reqs[0][0] == 0 and all(a[1] == b[0] for a, b in zip(reqs, reqs[1:])) and reqs[-1][1] == len(data)
    assert len(reqs) >= 4  # header + manifest, then one per level asked
    for level, have, got_level in r["steps"]:
        assert got_level == _prefix_level(data, have) >= level
    assert r["positions24"] == rs.sha(reader.decode_positions(from_bytes(data), 0, 0, 24)[2])
    # a file shorter than the first request: one request, cut at the end of the file
    small = corpus_containers["colored"]
    r = run_js(node, [{"id": "s", "file": str(small), "range_levels": [1, 24]}], tmp_path)["s"]["ranges"]
    assert r["error"] is None and r["requests"] == [[0, small.stat().st_size]], r
    assert r["steps"][-1][1:] == [small.stat().st_size, 24]


def test_a_recorded_source_path_is_an_informative_field(node, tmp_path):
    """``source.path`` (where ``lopcook cook`` found the source, relative to the container's
    folder) is a field lop.js does not need: the file reads and decodes as lopcook's reader does."""
    for folder in ("assets", "build"):
        (tmp_path / folder).mkdir()
    src = tmp_path / "assets" / "two_plates.glb"
    src.write_bytes((rs.REPO / "fixtures" / "two_plates.glb").read_bytes())
    out = rs.cook(src, tmp_path / "build" / "plates.lop")
    c = from_bytes(out.read_bytes(), str(out))
    assert c.manifest["source"]["path"] == "../assets/two_plates.glb"
    got = run_js(node, [{"id": "p", "file": str(out), "decode": True, "levels": list(rs.LEVELS)}], tmp_path)["p"]
    assert got["ok"], got["error"]
    compare(got["buffers"], rs.reference(c, rs.LEVELS), "source.path")
