"""The discontinuity constraint (lopcook.analyse.discontinuity): hard edges, folds, open boundaries
and colour seams get m >= B_v + ceil(log2(0.5 * J / edge_eps)); flat interiors stay low."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest

from tests.support import fixtures as fx
from lopcook.analyse import analyse
from lopcook.analyse import discontinuity as D
from lopcook.analyse.result import REASON_CODE
from lopcook.settings import AnalyseSettings
from lopcook.types import MeshPart, Scene, Texture


def scene_of(parts):
    return Scene(parts=tuple(parts), source="test", format="obj").validate()


def flat_cube(cells: int = 8, side: float = 1.0) -> MeshPart:
    """A CAD-like cube: six flat faces, each a cells x cells grid of its own vertices with the face
    normal (split normals along every edge: a hard edge), closed, CCW outward."""
    t = np.linspace(-0.5 * side, 0.5 * side, cells + 1)
    a, b = np.meshgrid(t, t, indexing="ij")
    k = cells + 1
    i, j = np.meshgrid(np.arange(cells), np.arange(cells), indexing="ij")
    v00 = (i * k + j).ravel()
    quad = np.concatenate([np.stack([v00, v00 + k, v00 + k + 1], 1), np.stack([v00, v00 + k + 1, v00 + 1], 1)])
    pos, nrm, tri = [], [], []
    for f, (ax, ra, ua, sign) in enumerate([(0, 1, 2, 1.0), (0, 2, 1, -1.0), (1, 2, 0, 1.0), (1, 0, 2, -1.0),
                                            (2, 0, 1, 1.0), (2, 1, 0, -1.0)]):
        p = np.zeros((k * k, 3))
        p[:, ax] = sign * 0.5 * side
        p[:, ra] = a.ravel()
        p[:, ua] = b.ravel()
        n = np.zeros((k * k, 3))
        n[:, ax] = sign
        pos.append(p)
        nrm.append(n)
        tri.append(quad + f * k * k)
    return MeshPart("cube", np.concatenate(pos), np.concatenate(tri).astype(np.uint32),
                    normals=np.concatenate(nrm).astype(np.float32))


def edge_distance(positions, half=0.5):
    """Distance (metres) from each point on the cube surface to the nearest cube edge."""
    d = half - np.abs(positions)  # per axis, distance to the face planes
    s = np.sort(d, axis=1)  # s[:, 0] = 0 (on a face), s[:, 1] = distance to the nearest edge
    return s[:, 1]


def expected(edge_level, jump, edge_eps):
    return min(24, edge_level + math.ceil(math.log2(0.5 * jump / edge_eps) - 1e-9))


# ---- the formula on analytic cases ------------------------------------------------------------------

@pytest.mark.parametrize("edge_eps", [1 / 8, 1 / 32, 0.3])
@pytest.mark.parametrize("edge_level", [11, 12])
def test_hard_edge_cube_levels(edge_eps, edge_level):
    cube = flat_cube()
    s = AnalyseSettings(edge_eps=edge_eps, edge_level=edge_level, depth="off")
    an = analyse(scene_of([cube]), s)
    p = an.parts[0]
    dist = edge_distance(cube.positions)
    on_edge = dist < 1e-9
    want = expected(edge_level, 1.0, edge_eps)  # split normals: a fold at every level, J = 1
    assert np.all(p.min_level[on_edge] == want)
    assert np.all(p.reason[on_edge] == REASON_CODE["edge"])
    # flat interiors: E_v = 0 and farther from the edge than one cell of the coarsest lattice
    # (level edge_level - 8: one pixel there), so no cell of theirs holds the fold
    far = dist > 2.0 ** D._cell_shift(edge_level - D.FOLD_LEVEL_SPAN) * an.grid.cell
    assert far.sum() > 0
    assert np.all(p.min_level[far] == 1)
    assert np.all(p.reason[far] == REASON_CODE["none"])
    # between: a fold within a pixel at some coarser level B_v < edge_level, so fewer bits
    assert np.all(p.min_level <= want)
    # the paper's analysis alone leaves the whole cube at level 1
    off = analyse(scene_of([cube]), AnalyseSettings(edges=False, depth="off"))
    assert np.all(off.parts[0].min_level == 1)
    assert np.all(p.e_v["normal"] == 0.0)


def test_fold_level_falls_with_distance_from_the_edge():
    cube = flat_cube(cells=16)
    an = analyse(scene_of([cube]), AnalyseSettings(depth="off"))
    p = an.parts[0]
    dist = np.round(edge_distance(cube.positions), 9)
    levels = [int(p.min_level[dist == d].max()) for d in np.unique(dist)]
    assert levels[0] == expected(12, 1.0, 1 / 8)
    assert all(a >= b for a, b in zip(levels, levels[1:]))  # non-increasing away from the edge
    assert levels[-1] == 1


def test_no_constraint_when_edge_eps_allows_the_jump():
    # 0.5 * J / edge_eps <= 1: the per-buffer level already keeps the edge within edge_eps
    an = analyse(scene_of([flat_cube()]), AnalyseSettings(edge_eps=0.5, depth="off"))
    assert np.all(an.parts[0].min_level == 1)


def test_open_boundary_of_a_flat_plate():
    plate = fx.two_plates()[0].as_mesh_part()
    an = analyse(scene_of([plate]), AnalyseSettings(depth="off"))
    p = an.parts[0]
    x, z = plate.positions[:, 0], plate.positions[:, 2]
    rim = (np.abs(np.abs(x) - 0.5) < 1e-9) | (np.abs(np.abs(z) - 0.5) < 1e-9)
    assert np.all(p.min_level[rim] == expected(12, 1.0, 1 / 8))
    assert np.all(p.reason[rim] == REASON_CODE["edge"])
    centre = (np.abs(x) < 0.3) & (np.abs(z) < 0.3)
    assert centre.sum() > 0 and np.all(p.min_level[centre] == 1)
    flags = D.discontinuity_levels([plate], [an.parts[0].quantized], edge_eps=1 / 8, edge_level=12,
                                   edge_angle_deg=45.0)
    np.testing.assert_array_equal(flags.boundary[0], rim)


def test_smooth_sphere_has_no_fold_at_the_edge_level():
    s = fx.unit_sphere(3)[0]
    v = s.positions / np.linalg.norm(s.positions, axis=1)[:, None]
    part = MeshPart("sphere", v, s.indices, normals=v.astype(np.float32))
    an = analyse(scene_of([part]), AnalyseSettings(depth="off"))
    d = D.discontinuity_levels([part], [an.parts[0].quantized], edge_eps=1 / 8, edge_level=12, edge_angle_deg=45.0)
    # closed, smooth: a one-pixel cell never holds a 45-degree normal spread at levels 4..12
    assert np.all(d.fold_level[0] == 0) and not d.boundary[0].any()
    assert np.all(an.parts[0].reason != REASON_CODE["edge"])


def _quad_pair(uvs=None, colors=None, texture=None):
    """Two unit quads side by side (x in [0, 1] and [1, 2], z = 0), four vertices each: the two
    vertices at x = 1 are co-located (a seam), normals all +Z (no fold across the seam). The plate is
    open all round (its rim, the seam's ends included, is a boundary), so the seam is judged by its
    flag and jump."""
    pos = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                    [1, 0, 0], [2, 0, 0], [2, 1, 0], [1, 1, 0]], np.float64)
    tri = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]], np.uint32)
    n = np.tile([0.0, 0.0, 1.0], (8, 1)).astype(np.float32)
    return MeshPart("quads", pos, tri, normals=n, uvs=uvs, colors=colors, texture=texture)


def _png(rgb_rows):
    from PIL import Image

    img = Image.fromarray(np.asarray(rgb_rows, np.uint8), "RGB")
    buf = io.BytesIO()
    img.save(buf, format="PNG")
    return Texture("two.png", buf.getvalue())


@pytest.mark.parametrize("right,jump", [((255, 255, 255), 1.0), ((0, 0, 0), 0.0), ((64, 0, 0), 64 / 255)])
def test_uv_seam_jump_is_the_texture_difference(right, jump):
    tex = _png([[(0, 0, 0), right]])  # 2 x 1 texels: left black, right as given
    uv = np.array([[0.1, 0.5], [0.4, 0.5], [0.4, 0.5], [0.1, 0.5],
                   [0.6, 0.5], [0.9, 0.5], [0.9, 0.5], [0.6, 0.5]], np.float32)  # seam: u 0.4 vs 0.6
    part = _quad_pair(uvs=uv, texture=tex)
    q = analyse(scene_of([part]), AnalyseSettings(depth="off")).parts[0].quantized
    d = D.discontinuity_levels([part], [q], edge_eps=1 / 32, edge_level=12, edge_angle_deg=45.0)
    seam = np.array([0, 1, 1, 0, 1, 0, 0, 1], bool)
    np.testing.assert_array_equal(d.seam[0], seam if jump > 0 else np.zeros(8, bool))
    np.testing.assert_allclose(D.seam_jumps(D.colocated_groups(q), D.base_colours([part]))[seam], jump, atol=1e-6)


def test_vertex_colour_seam_level():
    colors = np.ones((8, 4), np.float32)
    colors[4:, :3] = 0.75  # right quad darker by 0.25
    part = _quad_pair(colors=colors)
    q = analyse(scene_of([part]), AnalyseSettings(depth="off")).parts[0].quantized
    seam = np.array([0, 1, 1, 0, 1, 0, 0, 1], bool)
    # J = 0.25: edge_eps 1/32 -> 12 + ceil(log2(0.5 * 0.25 * 32)) = 14; edge_eps 1/8 -> log2(1) = 0: none
    d = D.discontinuity_levels([part], [q], edge_eps=1 / 32, edge_level=12, edge_angle_deg=45.0)
    np.testing.assert_allclose(d.jump[0][seam], 1.0)  # the seam vertices lie on the open rim too (J = 1)
    lv = D.required_level(np.where(seam, 12, 0), np.where(seam, 0.25, 0.0), 1 / 32)
    assert np.all(lv[seam] == 14) and np.all(lv[~seam] == 1)
    assert np.all(D.required_level(np.full(8, 12), np.full(8, 0.25), 1 / 8) == 1)
    np.testing.assert_allclose(D.seam_jumps(D.colocated_groups(q), D.base_colours([part]))[seam], 0.25, atol=1e-6)


def test_colocated_groups_and_boundary_helpers():
    q = np.array([[1, 2, 3], [0, 0, 0], [1, 2, 3], [0, 0, 1]], np.uint32)
    g = D.colocated_groups(q)
    assert g[0] == g[2] and len(set(g.tolist())) == 3
    # one triangle: every edge open; two triangles sharing an edge: the shared edge is not
    tri = np.array([[0, 1, 2], [0, 2, 3]])
    b = D.boundary_vertices(np.arange(4), tri)
    assert b.all()
    quad = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6]])
    assert D.boundary_vertices(np.arange(7), quad).all()


def test_settings_validation():
    for bad in ({"edge_eps": 0.0}, {"edge_eps": 1.5}, {"edge_level": 0}, {"edge_level": 25},
                {"edge_angle_deg": 0.0}, {"edge_angle_deg": 181.0}):
        with pytest.raises(ValueError):
            AnalyseSettings(**bad)


def test_deterministic():
    cube = flat_cube()
    a = analyse(scene_of([cube]))
    b = analyse(scene_of([cube]))
    np.testing.assert_array_equal(a.parts[0].min_level, b.parts[0].min_level)
    np.testing.assert_array_equal(a.parts[0].reason, b.parts[0].reason)


# ---- CLI ------------------------------------------------------------------------------------------

def test_cli_edge_options(tmp_path):
    import json
    import subprocess
    import sys

    from conftest import FIXTURES, REPO

    import jsonschema

    schema = json.loads((REPO / "schema" / "analysis.schema.json").read_text())

    def run(*args):
        proc = subprocess.run([sys.executable, "-m", "lopcook", "analyse", FIXTURES / "seamed_cube.gltf", "--json",
                               "--depth", "off", *args], capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr
        d = json.loads(proc.stdout)
        jsonschema.validate(d, schema)
        return d

    on = run()
    # 24 corner vertices, split normals (a cube): every one on a hard edge, 12 + 2 bits
    assert on["totals"]["histogram"][14] == 24 and on["totals"]["reasons"]["edge"] == 24
    assert on["settings"]["edges"] is True and on["settings"]["edge_eps"] == 0.125
    strict = run("--edge-eps", "0.03125", "--edge-level", "10")
    assert strict["totals"]["histogram"][14] == 24 and strict["settings"]["edge_level"] == 10
    off = run("--no-edges")
    assert off["totals"]["histogram"][1] == 24 and off["totals"]["reasons"]["edge"] == 0
    bad = subprocess.run([sys.executable, "-m", "lopcook", "analyse", FIXTURES / "seamed_cube.gltf",
                          "--edge-eps", "2"], capture_output=True, text=True)
    assert bad.returncode == 2 and "--edge-eps" in bad.stderr and "Traceback" not in bad.stderr


# ---- render: the constraint removes the hard-edge error AP and plain CAP leave --------------------

# Measured on llvmpipe (Mesa 22.3.6), flat_cube, views 0/5/10/15, 320x180, CAP PSNR min:
# level 6: 46.9 dB with edges, 24.7 without (= AP: every vertex at level 1); level 9: 48.5 vs 31.4.
EDGE_MARGIN_DB = 12.0


def test_cap_with_edges_beats_cap_without(gl):
    from lopcook.emit import build
    from lopcook.lop.container import from_bytes
    from lopcook.verify.evaluate import evaluate

    scene = scene_of([flat_cube()])

    def cook(settings):
        a = analyse(scene, settings)
        return from_bytes(build(scene, a, options={"analyse": settings.to_record()}), None)

    with_edges = cook(AnalyseSettings())
    without = cook(AnalyseSettings(edges=False))
    kw = dict(levels=[6, 9], views=[0, 5, 10, 15], resolution=(320, 180), variants=("cap",))
    on = evaluate(with_edges, scene, **kw)
    off = evaluate(without, scene, **kw)
    for r_on, r_off in zip(on["levels"], off["levels"]):
        assert r_on["cap"]["psnr_min"] is None or r_on["cap"]["psnr_min"] >= r_off["cap"]["psnr_min"] + EDGE_MARGIN_DB
        assert r_on["cap"]["psnr_min"] is None or r_on["cap"]["psnr_min"] >= 40.0


# ---- calibration searches the edge constraint ------------------------------------------------------

def test_calibration_searches_edge_eps(gl):
    from lopcook.tune.calibrate import calibrate, calibrated_settings, require_reached

    from lopcook.errors import LopcookError

    scene = scene_of([flat_cube()])
    kw = dict(target_psnr=40.0, levels=[6], views=[0, 10], resolution=(160, 90), confirm=None)
    # the paper's CAP: flat faces have E_v = 0, no k_f moves a bit, the hard edges stay at level 1
    paper = calibrate(scene, AnalyseSettings(edges=False), **kw)
    assert paper["reached"] is False and paper["search"] == "kf" and len(paper["curve"]) == 2
    with pytest.raises(LopcookError):
        require_reached(paper)
    # with the constraint, k_f then the loosest edge_eps that still passes
    cal = calibrate(scene, AnalyseSettings(), **kw)
    assert cal["reached"] is True and cal["search"] == "kf+edge"
    assert cal["edge_scale"] <= 0.0 and cal["edge_eps"] == pytest.approx(0.125 / 2.0 ** cal["edge_scale"])
    chosen = cal["chosen"]
    assert chosen["psnr_min"] is None or chosen["psnr_min"] >= 40.0
    looser = [p for p in cal["curve"] if p["sigma"] == cal["sigma"] and p["edge_eps"] > cal["edge_eps"]]
    assert all(p["psnr_min"] is not None and p["psnr_min"] < 40.0 for p in looser)  # the loosest passing one
    s = calibrated_settings(AnalyseSettings(), cal)
    assert s.edge_eps == cal["edge_eps"] and s.eps == pytest.approx(cal["eps"])


def _fold_levels_direct(q, normals, has_normal, boundary, top, angle_deg):
    """The module doc's fold rule, cell by cell with dictionaries: per level from ``top`` down, a
    vertex's one-pixel cell in either lattice (the second moved by half a cell) is an edge when it
    holds a boundary vertex or a normal more than half the angle from the cell's mean normal."""
    cos_half = math.cos(math.radians(angle_deg) / 2.0)
    n = q.shape[0]
    out = np.zeros(n, dtype=np.int64)
    pending = np.ones(n, dtype=bool)
    for level in range(top, max(1, top - D.FOLD_LEVEL_SPAN) - 1, -1):
        shift = D._cell_shift(level)
        hit = np.zeros(n, dtype=bool)
        for offset in ([0] + ([1 << (shift - 1)] if shift > 0 else [])):
            cells: dict = {}
            for i, key in enumerate(map(tuple, ((q + offset) >> shift).tolist())):
                cells.setdefault(key, []).append(i)
            for members in cells.values():
                s = sum((normals[i] for i in members if has_normal[i]), np.zeros(3))
                mean = s / np.linalg.norm(s) if np.linalg.norm(s) > 0 else s
                dots = [float(normals[i] @ mean) if has_normal[i] else 1.0 for i in members]
                if min(dots) < cos_half or any(boundary[i] for i in members):
                    hit[members] = True
        new = hit & pending
        out[new] = level
        pending &= ~hit
    return out


def test_fold_levels_match_the_rule_cell_by_cell():
    # axis-aligned normals: every cell's sum is exact, so any summation order gives the same mean
    rng = np.random.default_rng(5)
    axes = np.concatenate([np.eye(3), -np.eye(3)])
    for case in range(60):
        n = int(rng.integers(1, 400))
        scale = int(rng.integers(8, 24))
        q = rng.integers(0, 1 << scale, size=(n, 3)) + int(rng.integers(0, (1 << 24) - (1 << scale)))
        if case % 3 == 0:  # clusters and repeated points
            q = q[rng.integers(0, max(1, n // 4), size=n)] + rng.integers(0, 3, size=(n, 3))
        q = np.clip(q, 0, (1 << 24) - 1).astype(np.uint32)
        nrm = axes[rng.integers(0, 6 if case % 2 else 2, size=n)]
        has = rng.random(n) < (1.0 if case % 4 else 0.8)
        bnd = rng.random(n) < (0.0 if case % 5 else 0.02)
        top, angle = int(rng.integers(1, 25)), float(rng.choice([40.0, 100.0, 170.0]))
        got = D.fold_levels(q, nrm, has, bnd, top, angle)
        np.testing.assert_array_equal(got, _fold_levels_direct(q.astype(np.int64), nrm, has, bnd, top, angle))


def test_seam_jumps_are_the_largest_difference_within_each_group():
    # brute force over every pair of a group; one group of 600 co-located vertices (a file of
    # duplicated faces) is one pass of minima and maxima, not a pass per member
    rng = np.random.default_rng(3)
    groups = np.concatenate([np.zeros(600, np.int64), rng.integers(1, 40, size=300)])
    rng.shuffle(groups)
    colours = rng.random((groups.size, 3))
    want = np.zeros(groups.size)
    for i in range(groups.size):
        same = groups == groups[i]
        want[i] = np.abs(colours[same] - colours[i]).max()
    np.testing.assert_array_equal(D.seam_jumps(groups, colours), want)
    assert D.seam_jumps(np.zeros(0, np.int64), np.zeros((0, 3))).shape == (0,)
