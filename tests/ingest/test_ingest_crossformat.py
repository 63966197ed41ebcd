"""The same fixture written as glTF, OBJ and USD imports to equal scenes.

Compared per triangle corner (importers may number vertices differently): the canonical form of a
triangle is its three (position, normal, uv) corners rotated so the smallest position comes first
(winding kept), and the list of triangles is sorted. Positions must agree within 1e-6 relative to
the scene extent; they are in fact bit-identical because every fixture number is a float32 value.
"""

from __future__ import annotations

import numpy as np
import pytest

from conftest import FIXTURES
from tests.support import fixtures as fx
from lopcook.ingest import load


def corner_soup(part):
    """(m, 3, k) per-corner rows [x y z nx ny nz u v], each triangle rotated to start at its
    lexicographically smallest corner, triangles sorted."""
    cols = [part.positions]
    if part.normals is not None:
        cols.append(part.normals.astype(np.float64))
    if part.uvs is not None:
        cols.append(part.uvs.astype(np.float64))
    rows = np.concatenate(cols, axis=1)[part.indices.astype(np.int64)]  # (m, 3, k)
    keys = [tuple(np.round(r[:3], 9)) for tri in rows for r in tri]
    keys = np.array(keys, dtype=object).reshape(-1, 3)
    out = []
    for tri, key in zip(rows, keys):
        first = min(range(3), key=lambda i: key[i])
        out.append(np.roll(tri, -first, axis=0))
    out = np.array(out)
    order = np.lexsort(out.reshape(len(out), -1).T[::-1])
    return out[order]


CASES = {
    "seamed_cube": ["seamed_cube.obj", "seamed_cube.gltf", "seamed_cube.glb", "seamed_cube.usda",
                    "seamed_cube.usdc", "seamed_cube_facevarying.usda"],
    "two_plates": ["two_plates.obj", "two_plates.gltf", "two_plates.glb", "two_plates.usda"],
    "unit_sphere": ["unit_sphere.obj", "unit_sphere.glb", "unit_sphere.usda"],
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_formats_import_equal(case):
    scenes = [load(FIXTURES / f) for f in CASES[case]]
    ref = scenes[0]
    extent = float(np.max(ref.bounds()[1] - ref.bounds()[0]))
    for name, scene in zip(CASES[case][1:], scenes[1:]):
        # part names follow each format's naming (OBJ "cube", glTF "node/mesh", USD prim path)
        assert len(scene.parts) == len(ref.parts), name
        for a, b in zip(ref.parts, scene.parts):
            assert a.n_triangles == b.n_triangles, name
            assert a.n_vertices == b.n_vertices, name
            sa, sb = corner_soup(a), corner_soup(b)
            assert sa.shape == sb.shape, name
            np.testing.assert_allclose(sb[..., :3], sa[..., :3], rtol=0, atol=1e-6 * extent, err_msg=name)
            np.testing.assert_allclose(sb[..., 3:], sa[..., 3:], rtol=0, atol=1e-6, err_msg=name)


def test_formats_match_the_generator_data():
    """Not only equal to each other: equal to the analytic fixture (glTF corner soup vs Python data)."""
    for make, file in ((fx.seamed_cube, "seamed_cube.glb"), (fx.two_plates, "two_plates.glb")):
        expect = [p.as_mesh_part() for p in make()]
        got = load(FIXTURES / file).parts
        for e, g in zip(expect, got):
            np.testing.assert_allclose(corner_soup(g), corner_soup(e), atol=1e-7)


@pytest.mark.parametrize("file", ["concave_ngon.obj", "concave_ngon.gltf", "concave_ngon.usda"])
def test_concave_ngon_same_surface(file):
    part = load(FIXTURES / file).parts[0]
    assert part.n_triangles == 4
    tri = part.positions[part.indices.astype(np.int64)]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    assert np.all(cross[:, 1] > 0)  # every triangle faces +Y: none flipped by the concave corner
    assert 0.5 * cross[:, 1].sum() == pytest.approx(3.0, abs=1e-12)
    expect = {(-1, 0, 1), (1, 0, 1), (1, 0, 0), (0, 0, 0), (0, 0, -1), (-1, 0, -1)}
    assert {tuple(np.round(p, 9)) for p in part.positions} == expect
