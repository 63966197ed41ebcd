"""``lopcook.verify.baselines``: the uniform 16-bit quantization (KHR_mesh_quantization normalized
SHORT over each part's bounding cube) and the minimum-level colours of the report's Fig. 7 image."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import FIXTURES
from lopcook.analyse import analyse
from lopcook.emit import build
from lopcook.lop.container import from_bytes
from lopcook.ingest import load
from lopcook.verify.baselines import (container_levels, level_colours, level_scene, uniform_quantize,
                                      uniform_quantized_scene)
from lopcook.verify.buffers import source_order


def test_uniform_quantize_error_bound_and_grid(rng):
    p = rng.uniform([-3.0, 1.0, 10.0], [5.0, 2.0, 10.5], size=(5000, 3))
    d = uniform_quantize(p)
    lo, hi = p.min(axis=0), p.max(axis=0)
    c, h = 0.5 * (lo + hi), 0.5 * float((hi - lo).max())
    # every decoded value is a normalized SHORT code in [-32767, 32767] over the cube
    q = (d - c) / h * 32767.0
    assert np.allclose(q, np.rint(q), atol=1e-6) and np.abs(np.rint(q)).max() <= 32767
    # round to nearest: at most half a step per axis (h / 32767 / 2 metres), plus float rounding
    assert np.abs(d - p).max() <= h / 32767.0 / 2.0 * (1 + 1e-9) + 1e-12
    # the largest side spans the whole code range; the corners of that side are exact
    axis = int(np.argmax(hi - lo))
    assert d[:, axis].min() == pytest.approx(lo[axis], abs=1e-12)
    assert d[:, axis].max() == pytest.approx(hi[axis], abs=1e-12)
    # fewer bits, larger error: 8 bits allow h / 127 / 2
    assert np.abs(uniform_quantize(p, 8) - p).max() <= h / 127.0 / 2.0 * (1 + 1e-9)
    assert np.abs(uniform_quantize(p, 8) - p).max() > np.abs(d - p).max()
    with pytest.raises(ValueError):
        uniform_quantize(p, 17)


def test_uniform_quantized_scene_changes_positions_only():
    scene = load(str(FIXTURES / "seamed_cube.glb"))
    q = uniform_quantized_scene(scene)
    for a, b in zip(scene.parts, q.parts):
        assert np.array_equal(a.indices, b.indices) and np.array_equal(a.normals, b.normals)
        assert np.array_equal(a.uvs, b.uvs)
        assert np.abs(a.positions - b.positions).max() <= 0.5 * np.ptp(a.positions, axis=0).max() / 65534 * 1.0001


def test_level_colours_ramp():
    c = level_colours(np.array([1, 6, 12, 18, 24]), 1, 24)
    assert c.dtype == np.float32 and c.shape == (5, 4)
    assert np.all((c >= 0) & (c <= 1)) and np.all(c[:, 3] == 1)
    assert c[0, 2] > c[0, 0]  # the low end is blue
    assert c[-1, 0] > c[-1, 2]  # the high end is red
    assert np.array_equal(level_colours(np.array([0, 30]), 1, 24), level_colours(np.array([1, 24]), 1, 24))


@pytest.mark.parametrize("name", ["glossy_crease.glb", "two_plates.glb", "seamed_cube.glb"])
def test_container_levels_are_the_analysis_levels(name):
    scene = load(str(FIXTURES / name))
    an = analyse(scene)
    c = from_bytes(build(scene, an))
    for i, (order, pa) in enumerate(zip(source_order(c, scene), an.parts)):
        lv = container_levels(c, i)
        assert lv.size == pa.min_level.size
        assert np.array_equal(pa.min_level[order], lv)
    coloured, lo, hi = level_scene(c, scene)
    levels = np.concatenate([pa.min_level for pa in an.parts])
    assert (lo, hi) == (int(levels.min()), int(levels.max()))
    for part, pa in zip(coloured.parts, an.parts):
        assert part.texture is None and part.uvs is None
        assert np.array_equal(part.colors, level_colours(pa.min_level, lo, hi))
