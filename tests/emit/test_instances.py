"""``lopcook.simplify.instances``: copies of one mesh are found by content and affine fit, simplified
once, and their LOD chains placed with the exact (similarity) or measured (affine) error."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from tests.support import fixtures as F
from lopcook.simplify import instances as I
from lopcook.simplify import hausdorff, lod_chain
from lopcook.types import MeshPart, Scene


def _sphere(name="s") -> MeshPart:
    p = F.unit_sphere(3)[0]
    return MeshPart(name, p.positions * np.array([1.0, 0.7, 1.3]), p.indices, normals=None, source=name)


def _with_normals(part: MeshPart) -> MeshPart:
    from lopcook.ingest.normals import compute_normals

    r = compute_normals(part.positions, part.indices, 180.0)
    assert r.normals.shape[0] == part.n_vertices  # no creases at 180 degrees: one normal per vertex
    return replace(part, normals=r.normals.astype(np.float32))


def _rotation(rng) -> np.ndarray:
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))


def test_similarity_copy_found_and_mapped_exactly(rng):
    rep = _with_normals(_sphere("a"))
    a = 2.5 * _rotation(rng)
    t = np.array([3.0, -1.0, 0.5])
    copy = replace(rep, name="b", positions=rep.positions @ a.T + t, normals=I.map_normals(rep.normals, a))
    got = I.affine_map(rep, copy)
    assert got is not None
    assert np.allclose(got[0], a, atol=1e-12) and np.allclose(got[1], t, atol=1e-12)
    assert I.similarity_scale(got[0]) == pytest.approx(2.5, rel=1e-12)
    assert I.groups([rep, copy]) == [[0, 1]]
    # one vertex moved: not a copy; other triangles: not a copy
    moved = copy.positions.copy()
    moved[7] += 1e-6
    assert I.affine_map(rep, replace(copy, positions=moved)) is None
    flipped = replace(copy, indices=np.ascontiguousarray(copy.indices[:, ::-1]))
    assert I.affine_map(rep, flipped) is None
    assert I.groups([rep, replace(copy, positions=moved), copy]) == [[0, 2], [1]]
    # normals that do not follow A^-T: not a copy
    assert I.affine_map(rep, replace(copy, normals=rep.normals)) is None


def test_copies_answers_again_for_the_same_parts_only(rng, monkeypatch):
    """The last answer is reused for the very same part objects (one cook asks several times),
    never for other objects, even of equal content, and its arrays cannot be changed."""
    rep = _sphere("a")
    copy = replace(rep, name="b", positions=rep.positions @ _rotation(rng).T + 1.0)
    first = I.copies((rep, copy))
    calls = []
    monkeypatch.setattr(I, "affine_map", lambda *a, **k: calls.append(1))  # would find no copy
    again = I.copies([rep, copy])
    assert not calls and [(g, [m[0] for m in ms]) for g, ms in again] == [(0, [1])]
    assert again[0][1][0][1] is first[0][1][0][1] and not again[0][1][0][1].flags.writeable
    assert I.copies([rep, replace(copy)]) == [(0, []), (1, [])] and calls  # new objects: asked again


def test_placed_chain_errors_scale_and_match_measurement(rng):
    rep = _with_normals(_sphere("a"))
    a = 2.0 * _rotation(rng)
    t = np.array([0.0, 5.0, 0.0])
    copy = replace(rep, name="b", positions=rep.positions @ a.T + t, normals=I.map_normals(rep.normals, a))
    lods, report = lod_chain(rep, ratios=[0.5, 0.25], backend="fast")
    placed, prep = I.placed_chain(lods, report, copy, a, t)
    assert placed[0].part is copy and len(placed) == len(lods) == 3
    assert prep.part == "b" and "copy of part 'a'" in prep.notes[0]
    for lp, lr in zip(placed[1:], lods[1:]):
        assert np.allclose(lp.part.positions, lr.part.positions @ a.T + t, atol=1e-12)
        assert np.array_equal(lp.part.indices, lr.part.indices)
        assert lp.error_m == pytest.approx(2.0 * lr.error_m, rel=1e-12)
        # the scaled error is what measuring the placed LOD gives (same sampled Hausdorff)
        assert hausdorff(lp.part, copy)[0] == pytest.approx(lp.hausdorff_m, rel=1e-6)
    # a cap on the error cuts the copy's chain where its (scaled) error exceeds it
    cut, crep = I.placed_chain(lods, report, copy, a, t, max_error_m=1.5 * lods[1].error_m)
    assert len(cut) == 1 and "exceeds max_error_m" in crep.stop_reason


def test_affine_copy_errors_are_measured():
    rep = _sphere("a")
    a = np.diag([1.0, 3.0, 0.5])
    t = np.zeros(3)
    copy = replace(rep, name="b", positions=rep.positions @ a.T)
    assert I.similarity_scale(I.affine_map(rep, copy)[0]) is None
    lods, report = lod_chain(rep, ratios=[0.5], backend="fast")
    placed, prep = I.placed_chain(lods, report, copy, a, t)
    assert placed[1].hausdorff_m == hausdorff(placed[1].part, copy)[0]
    assert "errors measured" in prep.notes[0]


def test_flat_parts_are_not_matched():
    quad = MeshPart("q", np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.0]]),
                    np.array([[0, 1, 2], [0, 2, 3]], np.uint32))
    assert I.affine_map(quad, replace(quad, name="r", positions=quad.positions + 1.0)) is None


def test_pipeline_simplifies_each_distinct_mesh_once(rng, monkeypatch):
    from lopcook import pipeline

    rep = _with_normals(_sphere("a"))
    a = _rotation(rng)
    parts = [rep] + [replace(rep, name=f"c{k}", positions=rep.positions @ a.T + np.array([3.0 * (k + 1), 0, 0]),
                             normals=I.map_normals(rep.normals, a)) for k in range(3)]
    calls = []
    real = pipeline.lod_chain

    def counting(part, **kw):
        calls.append(part.name)
        return real(part, **kw)

    monkeypatch.setattr(pipeline, "lod_chain", counting)
    chains, reports = pipeline.chains(Scene(tuple(parts), "copies", "glb"), _lod_settings([0.5, 0.25]), None)
    assert calls == ["a"] and len(chains) == 4
    for k in range(1, 4):
        assert [lod.triangles for lod in chains[k]] == [lod.triangles for lod in chains[0]]
        assert chains[k][1].error_m == pytest.approx(chains[0][1].error_m, rel=1e-12)
        assert reports[k].part == f"c{k - 1}"


def _lod_settings(ratios):
    from lopcook.settings import LodSpec, Settings, SimplifySettings

    return Settings(simplify=SimplifySettings(lods=LodSpec(auto=False, ratios=tuple(ratios)), backend="fast"))
