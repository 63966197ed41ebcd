"""The chess set's pieces round-trip exactly through the coded hierarchy (issue 14, round trip).

The chess set (49 placed parts, 1.43 M triangles) is too big to cook with ``--hierarchy`` inside
the test budget, so each part's tree is built directly and coded as the container codes it
(``lopcook.hierarchy.container.VARIANT``, positions outside, reach radii stored). A tree is a
deterministic function of the part's grid positions and triangles, so parts whose quantised
grid positions and index buffer are identical bit for bit (the 16 pawns, the left and right
bishops...) give the same blob, and each such group is built and checked once.
"""

from __future__ import annotations

import hashlib

import numpy as np

from lopcook import api
from lopcook.hierarchy import build_tree, decode_hierarchy, drop_degenerate, encode_hierarchy
from lopcook.hierarchy.container import VARIANT
from lopcook.hierarchy.tree import quantize
from lopcook.mesh import canonical_triangles as canonical


def test_every_chess_piece_round_trips_through_the_coded_hierarchy(corpus):
    scene = api.load(corpus / "chess_set_flat.usdc")
    assert len(scene.parts) == 49
    groups = {}
    for part in scene.parts:
        tri = drop_degenerate(np.asarray(part.indices, np.int64))
        grid = quantize(np.asarray(part.positions, np.float64))[0]
        key = hashlib.sha256(tri.tobytes() + grid.tobytes()).hexdigest()
        groups.setdefault(key, (grid, tri, []))[2].append(part.name)
    assert sum(len(g[2]) for g in groups.values()) == 49
    assert len(groups) >= 9  # board, king, queen, bishop, knight(s), rook, pawn top and body
    checked = 0
    for grid, tri, names in groups.values():
        blob = encode_hierarchy(build_tree(grid, tri), variant=VARIANT, store_positions=False,
                                store_reach=True)
        h = decode_hierarchy(blob, positions=grid)
        assert h.n_triangles == tri.shape[0], names
        assert np.array_equal(canonical(h.triangles()), canonical(tri)), names
        checked += tri.shape[0] * len(names)
    assert checked == sum(drop_degenerate(np.asarray(p.indices)).shape[0] for p in scene.parts)
