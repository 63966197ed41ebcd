"""lopcook.hierarchy.select: view-dependent cuts are valid vertex-split states (no holes)."""

from __future__ import annotations

import numpy as np
import pytest

from hierarchy_meshes import canonical, grid, icosphere, net_edges
from lopcook.errors import LopcookError
from lopcook.hierarchy import PROPOSED, PROPOSED_PLUS, decode_hierarchy, encode_hierarchy, select_cut
from lopcook.hierarchy.select import cut_from_split


def _image(h, cut, tri_input):
    """The input triangles mapped through the cut's vertex clustering, degenerate ones dropped."""
    leaf_of_vertex = np.empty(h.n_leaves, np.int64)
    leaf_of_vertex[h.vertex_of_leaf] = np.arange(h.n_leaves)
    leaf = leaf_of_vertex[tri_input]
    lo = h.lo[cut.nodes]
    o = np.argsort(lo)
    f = o[np.searchsorted(lo[o], leaf, side="right") - 1]
    keep = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])
    return f[keep], f


def _cameras(p):
    c = p.mean(axis=0)
    ext = float(np.ptp(p, axis=0).max())
    return c, ext, [c + np.array([0.3, 0.2, 1.0]) * ext * k for k in (0.8, 3.0, 30.0)] + \
        [c + np.array([0.0, 0.0, -2.0]) * ext]


@pytest.mark.parametrize("variant", [PROPOSED, PROPOSED_PLUS])
def test_cut_of_a_closed_mesh_is_closed(variant):
    p, t = icosphere(4)
    h = decode_hierarchy(encode_hierarchy(p, t, variant=variant))
    c, ext, cams = _cameras(p)
    sizes = []
    for cam in cams:
        cut = select_cut(h, cam, c, fov=50, viewport=(640, 480), pixel_error=1.0)
        assert cut.triangles.shape[0] > 0
        assert net_edges(cut.triangles) == {}
        # the cut is exactly the clustered input
        img, _ = _image(h, cut, t)
        assert np.array_equal(canonical(cut.triangles), canonical(img))
        sizes.append(cut.triangles.shape[0])
    assert sizes[2] < sizes[0] < t.shape[0] or sizes[2] < sizes[1]


def test_cut_boundary_is_the_image_of_the_input_boundary():
    p, t = grid(20)
    h = decode_hierarchy(encode_hierarchy(p, t))
    c, ext, cams = _cameras(p)
    for cam in cams:
        cut = select_cut(h, cam, c, pixel_error=2.0)
        img, f = _image(h, cut, t)
        assert np.array_equal(canonical(cut.triangles), canonical(img))
        # the boundary chain maps onto the cut's boundary chain
        want = {}
        for (a, b), k in net_edges(t).items():
            fa, fb = int(f_vertex(h, cut, a)), int(f_vertex(h, cut, b))
            if fa == fb:
                continue
            key, s = ((fa, fb), k) if fa < fb else ((fb, fa), -k)
            want[key] = want.get(key, 0) + s
        want = {k: v for k, v in want.items() if v}
        assert net_edges(cut.triangles) == want


def f_vertex(h, cut, vertex):
    leaf = int(np.flatnonzero(h.vertex_of_leaf == vertex)[0])
    lo = h.lo[cut.nodes]
    o = np.argsort(lo)
    return o[np.searchsorted(lo[o], leaf, side="right") - 1]


def test_full_refinement_gives_the_input_mesh():
    p, t = icosphere(2)
    h = decode_hierarchy(encode_hierarchy(p, t))
    cut = cut_from_split(h, h.internal_nodes)
    assert cut.nodes.shape[0] == h.n_leaves
    vert = h.vertex_of_leaf[h.lo[cut.nodes]]
    assert np.array_equal(canonical(vert[cut.triangles]), canonical(t))
    assert np.allclose(cut.positions[np.argsort(vert)], p, atol=2 * h.step)


def test_frustum_and_backface_tests_coarsen_what_is_not_seen():
    p, t = icosphere(4)
    h = decode_hierarchy(encode_hierarchy(p, t))
    c = p.mean(axis=0)
    # looking away from the sphere: nothing is refined
    away = select_cut(h, c + [0, 0, 3.0], c + [0, 0, 6.0], pixel_error=0.5)
    assert away.split.shape[0] == 0 and away.triangles.shape[0] == 0
    # looking at it: the hemisphere facing the camera is finer than the one facing away
    cut = select_cut(h, c + [0, 0, 3.0], c, pixel_error=0.5, viewport=(1024, 1024))
    z = cut.positions[:, 2] - c[2]
    assert (z > 0.2).sum() > 3 * max((z < -0.2).sum(), 1)


def test_split_set_must_be_closed_under_ancestors():
    p, t = icosphere(1)
    h = decode_hierarchy(encode_hierarchy(p, t))
    deep = h.internal_nodes[h.depth[h.internal_nodes] >= 2][:1]
    with pytest.raises(LopcookError, match="closed under ancestors"):
        cut_from_split(h, deep)


def test_bad_camera_is_a_lopcook_error():
    p, t = icosphere(1)
    h = decode_hierarchy(encode_hierarchy(p, t))
    with pytest.raises(LopcookError, match="coincide"):
        select_cut(h, [0, 0, 1], [0, 0, 1])
    with pytest.raises(LopcookError, match="fov"):
        select_cut(h, [0, 0, 3], [0, 0, 0], fov=180)
    with pytest.raises(LopcookError, match="camera"):
        select_cut(h, [0, np.nan, 3], [0, 0, 0])


def test_bunny_cuts(corpus):
    import lopcook
    from lopcook.hierarchy import build_tree, drop_degenerate

    part = lopcook.load(corpus / "stanford-bunny.obj").parts[0]
    tri0 = drop_degenerate(part.indices)
    h = decode_hierarchy(encode_hierarchy(build_tree(part.positions, tri0), variant=PROPOSED_PLUS))
    c, ext, cams = _cameras(part.positions)
    counts = []
    for cam in cams[:3]:
        cut = select_cut(h, cam, c, fov=60, viewport=(1024, 768), pixel_error=1.0)
        img, _ = _image(h, cut, tri0)
        assert np.array_equal(canonical(cut.triangles), canonical(img))
        counts.append(cut.triangles.shape[0])
    assert counts[2] < counts[1] and counts[2] < tri0.shape[0] // 4


def _seam_split_sphere(subdivisions=4):
    """An icosphere whose lower half has its own copies of the vertices it shares with the
    upper half (a UV seam, as loaded parts have): topologically two open caps, geometrically
    one closed sphere."""
    p, t = icosphere(subdivisions)
    n = p.shape[0]
    low = p[t].mean(axis=1)[:, 2] < 0
    t = t.copy()
    t[low] += n
    return np.concatenate([p, p]), t


def _welded_chain(h, cut):
    """Oriented boundary chain of the cut with co-located cut vertices merged (cracks show)."""
    _, weld = np.unique(h.node_positions[cut.nodes], axis=0, return_inverse=True)
    return net_edges(weld.reshape(-1)[cut.triangles])


def test_boundary_vertices_mark_open_edges_seams_and_flips():
    from lopcook.hierarchy.tree import boundary_vertices

    p, t = icosphere(2)
    assert not boundary_vertices(t, p.shape[0]).any()  # closed and consistently oriented
    g, tg = grid(5)
    on = boundary_vertices(tg, g.shape[0])
    rim = (g[:, 0] == 0) | (g[:, 0] == 4) | (g[:, 1] == 0) | (g[:, 1] == 4)
    assert np.array_equal(on, rim)
    ps, ts = _seam_split_sphere(2)
    on = boundary_vertices(ts, ps.shape[0])
    n = p.shape[0]
    seam = np.isin(np.arange(n), ts[ts < n]) & np.isin(np.arange(n), ts[ts >= n] - n)
    assert seam.sum() > 0
    assert np.array_equal(on[:n], seam) and np.array_equal(on[n:], seam)  # both sides, nothing else
    flipped = t.copy()
    flipped[0] = flipped[0, ::-1]
    assert np.array_equal(np.flatnonzero(boundary_vertices(flipped, p.shape[0])), np.sort(t[0]))


@pytest.mark.parametrize("store_open", [True, False])
def test_backface_coarsening_does_not_open_seams(store_open):
    """The truck's failure mode on a procedural case. A back-facing region coarsened by Hoppe's
    test moves its seam vertices away from the other side of the seam, and the crack shows at
    the silhouette. With the boundary bits (as the container stores them) nodes above a seam
    vertex are left to the screen-space error, so at a vanishing pixel tolerance the cut is
    closed once co-located vertices are merged; without them it is not."""
    p, t = _seam_split_sphere(4)
    h = decode_hierarchy(encode_hierarchy(p, t, variant=PROPOSED_PLUS, store_reach=True, store_open=store_open))
    assert (h.open_leaf is not None) == store_open
    welded_input = {}
    cracks = 0
    for eye in ([0.0, 0.0, 4.0], [0.0, 3.0, 1.5], [2.0, -2.0, 2.0]):
        cut = select_cut(h, eye, [0.0, 0.0, 0.0], pixel_error=1e-9, viewport=(512, 512))
        assert cut.triangles.shape[0] < t.shape[0]  # back-facing regions are still coarsened
        chain = _welded_chain(h, cut)
        assert chain == welded_input or not store_open
        cracks += len(chain)
    assert (cracks == 0) == store_open
