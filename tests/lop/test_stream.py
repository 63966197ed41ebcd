"""The streaming layout and encoded sections (docs/format.md sections 14 and 15).

A streaming file decodes, buffer for buffer and at every level, to exactly the default layout's
vertices and attributes, and to its triangles with their winding (in another order, each perhaps
rotated); ``cook --stream`` is ``streamed`` (the stages rewrite) of the default cook; every prefix is read per stage
(stage levels, decodes equal to the complete file's, a prefix before stage 0 refused with one
line); stage levels are the selection distances' required levels; hostile encoded sections and
layout lies are refused with one line (``tests.support.streamcases``); the encoders and decoders
round-trip; ``inspect`` and ``decode`` read prefixes.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from lopcook.errors import LopcookError
from lopcook.lop import encoding, reader
from lopcook.lop.container import from_bytes, manifest_of
from lopcook.emit.stages import buffer_level, streamed
from tests.support import streamcases as sc

#: the cases decoded against their default-layout cook (the others are read, not compared)
COMPARED = ("stream_plates.lop", "stream_wedges.lop", "stream_cube_clustered.lop")


def _default_cook(name: str) -> bytes:
    fixture, flags = next((f, fl) for n, f, fl, _ in sc.VALID if n == name)
    return sc._cook(fixture, tuple(x for x in flags if x != "--stream"))


def _triangles(idx) -> list:
    """Triangles as sorted tuples each rotated to start at its smallest index (winding kept)."""
    t = np.asarray(idx).reshape(-1, 3)
    first = np.argmin(t, axis=1)
    rolled = np.stack([t[np.arange(len(t)), (first + j) % 3] for j in range(3)], axis=1)
    return sorted(map(tuple, rolled.tolist()))


@pytest.fixture(scope="module")
def pairs():
    """{name: (default container, streaming container)} of the compared cases."""
    return {name: (from_bytes(_default_cook(name)), from_bytes(sc.cooked(name))) for name in COMPARED}


@pytest.mark.parametrize("name", COMPARED)
def test_stream_decodes_as_the_default_layout(pairs, name):
    d, s = pairs[name]
    assert s.data[4:8] == b"\x04\x00\x00\x00" and s.stream and s.manifest["options"]["stream"] is True
    assert d.data[4] in (2, 3) and "stream" not in d.manifest["options"] and not d.stream
    for i, part in enumerate(d.manifest["parts"]):
        for k in range(len(part["lods"])):
            for b in range(1, d.manifest["positions"]["max_level"] + 1):
                gd, wd, pd = reader.decode_positions(d, i, k, b)
                gs, ws, ps = reader.decode_positions(s, i, k, b)
                assert np.array_equal(gd, gs) and np.array_equal(wd, ws) and np.array_equal(pd.view(np.uint32),
                                                                                         ps.view(np.uint32))
            ad, as_ = reader.lod_attributes(d, i, k), reader.lod_attributes(s, i, k)
            assert _triangles(ad["indices"]) == _triangles(as_["indices"])
            for key, v in ad.items():
                if key != "indices":
                    assert (v is None and as_[key] is None) or np.array_equal(v, as_[key]), key


@pytest.mark.parametrize("name", COMPARED[:2])
def test_cook_stream_is_the_rewrite_of_the_default(pairs, name):
    """The same sections and manifest; only ``savings.bytes_without_savings`` (the default layout's
    size of the same cook) counts the options record's ``"stream": true`` in the --stream cook."""
    d, s = pairs[name]
    t = streamed(d)
    assert [(x["name"], x["crc32"]) for x in t.manifest["sections"]] == [(x["name"], x["crc32"]) for x in s.manifest["sections"]]
    a, b = dict(t.manifest), dict(s.manifest)
    sa, sb = a.pop("savings", None), b.pop("savings", None)
    assert a == b
    if sa is not None:
        assert sb["bytes_without_savings"] - sa["bytes_without_savings"] == len(',"stream":true')
        assert {**sa, "bytes_without_savings": 0} == {**sb, "bytes_without_savings": 0}
    with pytest.raises(LopcookError, match="default layout"):
        streamed(s)  # already streaming


def test_stage_levels_follow_the_selection_distances():
    """L_s = the largest over the stage's buffers of min(max_level, required_level(min_distance_m))
    (with a placement's level shift); a LOD 0 on the scene grid (distance 0) makes its stage max_level."""
    for name, data, _ in sc.stream_cases():
        c = from_bytes(data)
        m, lay = c.manifest, c.layout
        for st in lay.stages:
            want = max(buffer_level(m, i, k) for i, k, _ in st.buffers)
            assert st.level == want, (name, st.index)
            if any(k == 0 and "placement" not in m["parts"][i] for i, k, _ in st.buffers):
                assert st.level == m["positions"]["max_level"]  # a placement's shift may lower its LOD 0's
        assert [st["level"] for st in m["positions"]["stages"]] == [st.level for st in lay.stages]


def test_named_prefixes_read_per_stage():
    whole = from_bytes(sc.cooked("stream_sphere.lop"))
    for name, data, covers, levels in sc.stream_prefix_cases():
        if levels is None:
            with pytest.raises(LopcookError) as exc:
                from_bytes(data, name, allow_prefix=True)
            assert "\n" not in str(exc.value) and name in str(exc.value), covers
            continue
        c = from_bytes(data, name, allow_prefix=True)
        assert c.stage_levels == levels, covers
        for st in c.layout.stages:
            for i, k, _ in st.buffers:
                b = c.level_of(i, k)
                if b:
                    assert np.array_equal(reader.decode_positions(c, i, k, b)[2], reader.decode_positions(whole, i, k, b)[2])
                if b < c.layout.max_level:
                    with pytest.raises(LopcookError, match="not in this file"):
                        reader.decode_positions(c, i, k, b + 1)


def test_every_cut_is_a_prefix_of_coarse_to_fine_stages():
    """At every section boundary (and one byte before it): stages arrive in order, levels never
    fall as the cut moves on, and a cut refused is one before stage 0's mandatory bits."""
    data = sc.cooked("stream_sphere.lop")
    ends = sorted(set(sc._ends(data).values()))
    first = sc._ends(data)["positions/stage0/mandatory"]
    last = None
    for cut in sorted({e for x in ends for e in (x - 1, x)}):
        try:
            levels = from_bytes(data[:cut], allow_prefix=True).stage_levels
        except LopcookError as exc:
            assert cut < first and "first stage" in str(exc) or "truncated" in str(exc)
            continue
        assert cut >= first
        assert all(a >= 1 for a in levels[:max((s for s, v in enumerate(levels) if v), default=0)])
        if last is not None:
            assert all(a >= b for a, b in zip(levels, last))
        last = levels
    assert last == [24] * len(last)


@pytest.mark.parametrize("case", [c[0] for c in sc.VALID])
def test_valid_cases_read_and_hold_their_features(case):
    c = from_bytes(sc.cooked(case))
    encs = {t.get("encoding") for t in c.manifest["sections"]}
    assert c.stream and c.available_level == c.manifest["positions"]["max_level"]
    assert [t["name"] for t in c.manifest["sections"]] == c.layout.expected_sections()
    if case == "stream_sphere.lop":
        assert "meshopt-deflate" in encs and any(st.deferred for st in c.layout.stages)
    if case == "stream_cube_clustered.lop":
        assert all(st.clusters for st in c.layout.stages)
    if case == "stream_wedges.lop":
        assert any((p.get("placement") or {}).get("of", i) != i for i, p in enumerate(c.manifest["parts"]))


def test_stream_manifests_follow_the_schema():
    import jsonschema  # test extra

    schema = json.loads((sc.REPO / "schema" / "container.schema.json").read_text())
    check = jsonschema.Draft202012Validator(schema)
    for name, data, _ in sc.stream_cases():
        assert not [e.message for e in check.iter_errors(from_bytes(data).manifest)], name
    bad = manifest_of(sc.cooked("stream_plates.lop"))
    bad["sections"][0]["encoding"] = "lzma"
    assert list(check.iter_errors(bad))


MARKERS = {"version": "must not hold", "manifest": "manifest", "section_table": "section"}


def test_hostile_stream_files_are_refused_with_one_line():
    cases = sc.stream_invalid_cases()
    assert {k for *_, k in cases} == {"version", "manifest", "encoding", "section_table"}
    for name, data, covers, klass in cases:
        with pytest.raises(LopcookError) as exc:
            from_bytes(data, name)
        msg = str(exc.value)
        assert "\n" not in msg and name in msg, covers
        if klass == "encoding":
            assert "deflate" in msg, (covers, msg)  # the codec named: (deflate), (meshopt-deflate), the deflate stream
        else:
            assert MARKERS[klass] in msg, (covers, msg)


# ---- the codecs ----------------------------------------------------------------------------------

def test_deflate_round_trips_and_inflate_is_bounded():
    rng = np.random.default_rng(3)
    for size in (0, 4, 1000, 70000):
        raw = (rng.integers(0, 4, size, dtype=np.uint8)).tobytes()
        stored = encoding.deflate(raw)
        padded = stored + b"\0" * (-len(stored) % 4)
        assert encoding.inflate(padded, len(raw), exact=True) == raw
        with pytest.raises(encoding.EncodingError, match="expands beyond"):
            if raw:
                encoding.inflate(padded, len(raw) - 1, exact=True)
            else:
                raise encoding.EncodingError("expands beyond (nothing to cut)")
        if len(stored) % 4:
            bad = stored + b"\x01" + b"\0" * (-(len(stored) + 1) % 4)
            with pytest.raises(encoding.EncodingError, match="zero padding"):
                encoding.inflate(bad, len(raw), exact=True)
        with pytest.raises(encoding.EncodingError, match="zero padding"):
            encoding.inflate(padded + b"\0\0\0\0", len(raw), exact=True)


def test_triangle_codec_keeps_every_triangle_and_its_winding():
    rng = np.random.default_rng(4)
    tris = rng.integers(0, 500, (2000, 3)).astype(np.uint32)
    tris = tris[(tris[:, 0] != tris[:, 1]) & (tris[:, 1] != tris[:, 2]) & (tris[:, 0] != tris[:, 2])]
    stream, decoded = encoding.encode_triangles(tris)
    assert stream[0] == encoding.TRIANGLES_HEADER
    assert _triangles(decoded) == _triangles(tris)
    fields, stored, payload = encoding.encode_index_section(tris, 2)
    assert payload == encoding.decoded_index_bytes(decoded, 2)
    lod = (len(tris), 2, 500)
    if fields:
        assert encoding.decode_section(dict(fields), stored, lod) == payload


def test_writer_encodes_only_what_saves_five_percent():
    rng = np.random.default_rng(5)
    noise = rng.integers(0, 256, 4000, dtype=np.uint8).tobytes()
    assert encoding.encode_section(noise) == ({}, noise)
    zeros = bytes(4000)
    fields, stored = encoding.encode_section(zeros)
    assert fields == {"encoding": "deflate", "size": 4000} and len(stored) % 4 == 0
    assert encoding.decode_section(fields, stored) == zeros


def test_encoded_sections_in_the_default_layout_are_read():
    """A 4.x reader decodes encoded sections in either layout: a default-layout file with its
    sections deflated (written by hand) decodes as the file it came from, labelled 4.0."""
    d = from_bytes(_default_cook("stream_plates.lop"))
    m, secs = sc.stored_sections(d.data)
    blob = sc.rebuild(m, [(n, *encoding.encode_section(s)[::-1]) if not f else (n, s, f) for n, s, f in secs])
    c = from_bytes(blob)
    assert c.data[4] == 4 and not c.stream and any("encoding" in t for t in c.manifest["sections"])
    for i, part in enumerate(d.manifest["parts"]):
        for k in range(len(part["lods"])):
            assert np.array_equal(reader.decode_positions(c, i, k, 24)[2], reader.decode_positions(d, i, k, 24)[2])


# ---- the CLI reads prefixes ------------------------------------------------------------------------

def _lopcook(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "lopcook", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, timeout=300)


def test_inspect_and_decode_read_prefixes(tmp_path):
    data = sc.cooked("stream_sphere.lop")
    m = manifest_of(data)
    cut = sc._ends(data)[sc._last_of_stage(m, 1)]  # stages 0 and 1 at their levels
    f = tmp_path / "cut.lop"
    f.write_bytes(data[:cut])
    r = _lopcook("inspect", f, "--json")
    assert r.returncode == 0, r.stderr
    desc = json.loads(r.stdout)
    assert desc["prefix"] and desc["layout"] == "stream" and desc["file_size"] == len(data)
    assert [e["available_level"] for e in desc["parts"][0]["lods"]] == [0, 0, 7, 6]
    assert [s["available_level"] for s in desc["stages"]] == [6, 7, 0, 0]
    text = _lopcook("inspect", f).stdout
    assert "a prefix" in text and "available level of each buffer" in text
    ok = _lopcook("decode", f, "--lod", "2", "--level", "7", "-o", tmp_path / "a.glb")
    assert ok.returncode == 0 and (tmp_path / "a.glb").read_bytes()[:4] == b"glTF", ok.stderr
    for args in (("--lod", "2", "--level", "8"), ("--lod", "0", "--level", "1")):
        bad = _lopcook("decode", f, *args, "-o", tmp_path / "b.glb")
        assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1 and "cut.lop" in bad.stderr
        assert not (tmp_path / "b.glb").exists()
    short = tmp_path / "short.lop"
    short.write_bytes(data[:sc._ends(data)["positions/stage0/mandatory"] - 1])
    for cmd in (("inspect", short), ("decode", short, "--level", "1", "-o", tmp_path / "c.glb")):
        r = _lopcook(*cmd)
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "first stage" in r.stderr


def test_the_default_layout_reads_prefixes_in_the_cli(tmp_path):
    d = _default_cook("stream_plates.lop")
    c = from_bytes(d)
    cut = c.section_end(c.manifest["positions"]["mandatory"])
    f = tmp_path / "cut.lop"
    f.write_bytes(d[:cut])
    level = from_bytes(d[:cut], allow_prefix=True).available_level
    r = _lopcook("inspect", f, "--json")
    assert r.returncode == 0 and json.loads(r.stdout)["available_level"] == level
    assert _lopcook("decode", f, "--level", level, "-o", tmp_path / "a.glb").returncode == 0
    bad = _lopcook("decode", f, "--level", level + 1, "-o", tmp_path / "b.glb")
    assert bad.returncode == 2 and f"holds levels up to {level}" in bad.stderr
