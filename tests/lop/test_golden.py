"""Golden containers (fixtures/golden/): pinned bytes, re-cooked bytes, and what the reader decodes.

A failure of ``test_recook_gives_the_golden_bytes`` means ``lopcook cook`` now writes different
bytes for a fixture. If the change is intended (a format or algorithm change), regenerate with
``python tests/golden_update.py`` and name the change in the commit; otherwise it is a regression.
"""

from __future__ import annotations

import numpy as np
import pytest

import golden_update as G
from lopcook.lop.container import read
from lopcook.lop.reader import decode_positions, lod_attributes
from lopcook.grid import Grid
from lopcook.ingest import load
from lopcook.simplify.error import hausdorff
from lopcook.types import MeshPart

GOLDENS = G.entries()
IDS = [g.name for g in GOLDENS]


def test_sums_list_every_golden_file_once_with_a_hash():
    names = [g.name for g in GOLDENS]
    assert len(names) == len(set(names)) >= 6
    assert all(g.sha256 is not None for g in GOLDENS), "run python tests/golden_update.py"
    on_disk = sorted(p.name for p in G.GOLDEN.glob("*.lop"))
    assert on_disk == sorted(names), "every fixtures/golden/*.lop is listed in SHA256SUMS and vice versa"
    # the fixtures named in the brief are covered, with and without LODs and --nearest
    sources = {g.argv[1] for g in GOLDENS}
    assert {"fixtures/two_plates.glb", "fixtures/seamed_cube.glb", "fixtures/unit_sphere.obj",
            "fixtures/point_instancer.usda"} <= sources
    assert any("--lods" in g.argv for g in GOLDENS) and any("--nearest" in g.argv for g in GOLDENS)
    assert any(g.argv[g.argv.index("--lods") + 1] == "auto" for g in GOLDENS if "--lods" in g.argv)


def test_sums_parser_rejects_malformed_lines():
    with pytest.raises(ValueError, match="neither a comment"):
        G.entries("not a hash line\n")
    with pytest.raises(ValueError, match="without a"):
        G.entries("0" * 64 + "  lonely.lop\n")
    with pytest.raises(ValueError, match="must write -o a.lop"):
        G.entries("# a.lop: lopcook cook fixtures/x.glb -o b.lop\n")


@pytest.mark.parametrize("golden", GOLDENS, ids=IDS)
def test_pinned_file_matches_its_sha256(golden):
    assert G.sha256(G.GOLDEN / golden.name) == golden.sha256, \
        f"{golden.name} was edited: restore it or regenerate with python tests/golden_update.py"


@pytest.mark.parametrize("golden", GOLDENS, ids=IDS)
def test_recook_gives_the_golden_bytes(golden, tmp_path):
    out = G.cook(golden, tmp_path)
    assert out.read_bytes() == (G.GOLDEN / golden.name).read_bytes(), (
        f"lopcook {' '.join(golden.argv)} no longer writes the golden bytes; if intended, "
        f"run python tests/golden_update.py and name the format change")


@pytest.fixture(scope="module")
def sources():
    cache = {}

    def get(path):
        if path not in cache:
            cache[path] = load(path)
        return cache[path]

    return get


def _source_order(container_indices: np.ndarray, source_indices: np.ndarray, n: int) -> np.ndarray:
    """The source vertex of every container vertex: the container keeps the triangle order and
    corner order and only renumbers vertices (binned order), so ``order[container] == source``."""
    order = np.full(n, -1, dtype=np.int64)
    order[container_indices.ravel()] = source_indices.ravel()
    assert np.all(order >= 0), "a container vertex no triangle uses"
    np.testing.assert_array_equal(order[container_indices], source_indices)
    assert np.unique(order).size == n, "container vertices are a permutation of the source's"
    return order


@pytest.mark.parametrize("golden", GOLDENS, ids=IDS)
def test_reader_decodes_lod0_as_the_quantized_source(golden, sources):
    """Level 24 (or, where --nearest drops planes, the highest level the file holds) decodes to
    the source quantized on the manifest's grid: every kept bit equals the source's."""
    c = read(str(G.GOLDEN / golden.name))
    scene = sources(golden.source)
    g = c.manifest["grid"]
    grid = Grid(origin=tuple(g["origin"]), extent=g["extent"])
    level = c.available_level
    if "--nearest" not in golden.argv:
        assert level == 24
    assert len(c.manifest["parts"]) == len(scene.parts)
    for i, part in enumerate(scene.parts):
        q, widths, _ = decode_positions(c, i, 0, level)
        a = lod_attributes(c, i, 0)
        order = _source_order(a["indices"].astype(np.int64), part.indices.astype(np.int64), part.n_vertices)
        src = grid.quantize(part.positions)[order]
        assert np.all(widths >= level)
        s = (24 - widths)[:, None].astype(np.uint32)
        np.testing.assert_array_equal(q, (src >> s) << s)
        if level == 24:
            np.testing.assert_array_equal(q, src)


@pytest.mark.parametrize("golden", [g for g in GOLDENS if "--lods" in g.argv], ids=lambda g: g.name)
def test_decoded_lods_are_within_their_recorded_error(golden, sources):
    c = read(str(G.GOLDEN / golden.name))
    scene = sources(golden.source)
    g = c.manifest["grid"]
    level = c.available_level  # 24, or less where --nearest leaves the finest planes out
    cell_err = float(Grid(origin=tuple(g["origin"]), extent=g["extent"]).dx(level))
    for i, part in enumerate(scene.parts):
        lods = c.manifest["parts"][i]["lods"]
        assert len(lods) > 1
        previous = 0.0
        for k in range(1, len(lods)):
            _, _, p = decode_positions(c, i, k, level, float32=False)
            a = lod_attributes(c, i, k)
            assert a["indices"].shape == (lods[k]["triangles"], 3) and p.shape == (lods[k]["vertices"], 3)
            assert lods[k]["triangles"] < lods[k - 1]["triangles"]
            h = hausdorff(MeshPart(name="lod", positions=p, indices=a["indices"]), part)[0]
            recorded = lods[k]["geometric_error_m"]
            assert recorded >= previous  # the recorded error is non-decreasing along the chain
            # decoding at that level moves a vertex by at most dx(level): the measured distance of
            # the decoded LOD to the source is the recorded one up to that (the first LOD's
            # recorded error is its own measurement; later ones are the running maximum)
            assert h <= recorded + 2 * cell_err
            if k == 1:
                assert h == pytest.approx(recorded, abs=2 * cell_err)
            previous = recorded
