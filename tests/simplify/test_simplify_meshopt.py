"""meshoptimizer backend (lopcook.simplify.meshopt): targets, closed seams, determinism, chain error."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import open_edges, position_ids
from lopcook.simplify import backends as B
from lopcook.simplify import chain as L
from lopcook.simplify import error as E
from lopcook.ingest import load
from lopcook.simplify.meshopt import MeshoptResult, accumulate, border_vertices, seam_vertices, simplify_meshopt
from lopcook.types import MeshPart

RATIOS = (0.5, 0.25, 0.125, 0.0625)


def _part(corpus, name, index=0) -> MeshPart:
    return load(corpus / name).parts[index]


def _lod_part(res: MeshPart | MeshoptResult) -> MeshPart:
    return MeshPart(name="lod", positions=res.positions, indices=res.faces.astype(np.uint32))


@pytest.mark.parametrize("name, ratios", [("stanford-bunny.obj", RATIOS), ("fandisk.obj", RATIOS),
                                          ("spot.obj", RATIOS), ("Duck.glb", RATIOS[:3])])
def test_targets_reached(corpus, name, ratios):
    # (the Duck's UV seams and borders stop it at 386 triangles for a 1/16 target of 263)
    part = _part(corpus, name)
    for r in ratios:
        target = int(round(r * part.n_triangles))
        res = simplify_meshopt(part.positions, part.indices, target, uvs=part.uvs, weld=True, normals=part.normals)
        assert abs(res.faces.shape[0] - target) <= L.TARGET_TOLERANCE * target, (r, res.faces.shape[0], target)
        # output vertices are input vertices, bit for bit
        assert np.array_equal(res.positions, part.positions[res.vertex_source])
        assert res.faces.min() >= 0 and res.faces.max() < res.positions.shape[0]
        assert res.error_m > 0 and np.isfinite(res.error_m)


@pytest.mark.parametrize("name", ["spot.obj", "Duck.glb", "DamagedHelmet/DamagedHelmet.gltf", "CesiumMilkTruck.glb"])
def test_seams_stay_closed(corpus, name):
    # co-located seam vertices collapse together: the mesh welded by position gets no open edge
    # that the input did not have (borders are locked), at every ratio
    part = _part(corpus, name)
    assert seam_vertices(part.positions).any()
    for r in RATIOS:
        res = simplify_meshopt(part.positions, part.indices, int(round(r * part.n_triangles)), uvs=part.uvs,
                               weld=True, normals=part.normals)
        ids_in, ids_out = position_ids(part.positions, res.positions)
        assert open_edges(ids_out, res.faces) <= open_edges(ids_in, part.indices), r
        # every corner keeps the UV of the input vertex it is (no texture swimming)
        np.testing.assert_array_equal(res.wedge_uvs, part.uvs.astype(np.float64)[res.vertex_source][res.faces])


def test_closed_seamed_mesh_stays_watertight(corpus):
    part = _part(corpus, "spot.obj")
    ids_in, = position_ids(part.positions)
    assert not open_edges(ids_in, part.indices)
    res = simplify_meshopt(part.positions, part.indices, part.n_triangles // 16, uvs=part.uvs, weld=True)
    ids_in, ids_out = position_ids(part.positions, res.positions)
    assert not open_edges(ids_out, res.faces)


def test_locked_seams_and_borders_survive(corpus):
    part = _part(corpus, "DamagedHelmet/DamagedHelmet.gltf")
    seam = np.flatnonzero(seam_vertices(part.positions))
    border = np.flatnonzero(border_vertices(part.positions, part.indices))
    assert border.size and seam.size
    res = simplify_meshopt(part.positions, part.indices, part.n_triangles // 2, uvs=part.uvs, weld=False)
    used = np.unique(part.indices)
    assert np.isin(np.intersect1d(seam, used), res.vertex_source).mean() > 0.99
    res = simplify_meshopt(part.positions, part.indices, part.n_triangles // 2, uvs=part.uvs, weld=True,
                           lock_border=True)
    assert np.isin(np.intersect1d(border, used), res.vertex_source).mean() > 0.99
    # without the lock the border is simplified too
    free = simplify_meshopt(part.positions, part.indices, part.n_triangles // 2, uvs=part.uvs, weld=True,
                            lock_border=False)
    assert np.isin(border, free.vertex_source).mean() < np.isin(border, res.vertex_source).mean()


def test_border_vertices_of_a_grid():
    k = 6
    x, y = np.meshgrid(np.arange(k + 1.0), np.arange(k + 1.0))
    p = np.c_[x.ravel(), y.ravel(), np.zeros(x.size)]
    i = np.arange(k * (k + 1)).reshape(k, k + 1)[:, :k].ravel()
    f = np.r_[np.c_[i, i + 1, i + k + 2], np.c_[i, i + k + 2, i + k + 1]]
    expect = (p[:, 0] == 0) | (p[:, 0] == k) | (p[:, 1] == 0) | (p[:, 1] == k)
    assert np.array_equal(border_vertices(p, f), expect)
    # a seam (the column x = 3 duplicated for the faces on its right) is not a border, although
    # its edges are open in the index topology
    col = np.flatnonzero(p[:, 0] == 3)
    dup = np.full(p.shape[0], -1)
    dup[col] = p.shape[0] + np.arange(col.size)
    p2 = np.vstack([p, p[col]])
    right = p[f].mean(axis=1)[:, 0] > 3
    f2 = f.copy()
    f2[right] = np.where(dup[f[right]] >= 0, dup[f[right]], f[right])
    assert np.array_equal(border_vertices(p2, f2), np.r_[expect, expect[col]])


def test_deterministic(corpus):
    part = _part(corpus, "DamagedHelmet/DamagedHelmet.gltf")
    a = simplify_meshopt(part.positions, part.indices, 4000, uvs=part.uvs, weld=True, normals=part.normals)
    b = simplify_meshopt(part.positions, part.indices, 4000, uvs=part.uvs, weld=True, normals=part.normals)
    assert a.faces.tobytes() == b.faces.tobytes() and a.positions.tobytes() == b.positions.tobytes()
    assert a.error_m == b.error_m


@pytest.mark.parametrize("name", ["stanford-bunny.obj", "fandisk.obj"])
def test_chain_from_previous_lod_error_grows(corpus, name):
    lod0 = _part(corpus, name)
    cur = lod0
    steps, measured, tris = [], [], []
    for r in RATIOS:
        target = int(round(r * lod0.n_triangles))
        res = simplify_meshopt(cur.positions, cur.indices, target, lock_border=True)
        cur = _lod_part(res)
        steps.append(res.error_m)
        measured.append(E.hausdorff(lod0, cur)[0])
        tris.append(cur.n_triangles)
    acc = accumulate(steps)
    assert all(s > 0 for s in steps)
    assert all(b >= a for a, b in zip(acc, acc[1:]))
    assert all(b > a for a, b in zip(measured, measured[1:])), measured  # coarser LODs are farther
    assert all(b < a for a, b in zip(tris, tris[1:]))
    # the estimate is of the right size: within 10x of the measured distance either way
    for a, m in zip(acc, measured):
        assert m / 10 < a < 10 * m, (acc, measured)


def test_runs_through_lod_backend_dispatch(corpus):
    # lod._run_backend("meshopt", ...) with pymeshlab's arguments, then lod's own result check
    part = _part(corpus, "spot.obj")
    for mode in ("simplify", "lock", "ignore"):
        work, _ = B.prepare(part, mode)
        target = part.n_triangles // 4
        raw = B.run_backend("meshopt", work, target, True, True)
        assert isinstance(raw, B.BackendResult) and isinstance(raw, MeshoptResult)
        res, dropped = B.check_result(raw, target, work.faces.shape[0])
        assert res.faces.shape[0] <= 1.05 * target or mode == "lock"
        assert np.array_equal(res.positions, work.positions[res.vertex_source])


def test_lod_chain_with_meshopt_keeps_seams_closed(corpus, monkeypatch):
    # the whole lod_chain (prepare, backend, result check, attribute transfer, error) once
    # "meshopt" is an accepted backend name: each LOD from the previous one, seams simplified
    monkeypatch.setattr(L, "BACKENDS", B.BACKENDS + ("meshopt",))
    part = _part(corpus, "spot.obj")
    lods, report = L.lod_chain(part, ratios=RATIOS, backend="meshopt", seams="simplify", fallback=False)
    assert len(lods) == 1 + len(RATIOS) and not any(lod.failed for lod in lods)
    assert all(lod.backend == "meshopt" for lod in lods[1:])
    errors = [lod.error_m for lod in lods]
    assert all(b >= a for a, b in zip(errors, errors[1:])) and errors[-1] > 0
    for lod in lods[1:]:
        assert abs(lod.triangles - lod.target_triangles) <= L.TARGET_TOLERANCE * lod.target_triangles
        ids, = position_ids(lod.part.positions)
        assert not open_edges(ids, lod.part.indices)  # spot is closed: no crack at any LOD
        assert lod.part.uvs is not None and np.isfinite(lod.part.uvs).all()


def test_cook_with_the_meshopt_backend(corpus, tmp_path):
    """``cook --lods ... --lod-backend meshopt`` writes a chain that reaches its targets, with the
    error growing along it; the fallback order of the other backends is unchanged."""
    from lopcook.cli import main
    from lopcook.lop.container import read

    assert B.BACKENDS == ("pymeshlab", "fast") and "meshopt" in B.SELECTABLE
    out = tmp_path / "spot.lop"
    assert main(["-q", "cook", str(corpus / "spot.obj"), "-o", str(out), "--lods", "1/2,1/4", "--lod-backend",
                 "meshopt"]) == 0
    lods = read(str(out)).manifest["parts"][0]["lods"]
    n0 = lods[0]["triangles"]
    assert [round(e["triangles"] / n0, 2) for e in lods] == [1.0, 0.5, 0.25]
    err = [e["geometric_error_m"] for e in lods]
    assert err[0] == 0 < err[1] <= err[2]
