"""Procedural test fixtures and deterministic writers for OBJ, glTF/GLB and USD.

Every fixture is plain data first (``FixturePart`` lists, in lopcook's scene conventions: metres,
+Y up, counter-clockwise triangles, glTF UVs with the origin at the top-left; see
``lopcook.types``) and files second. The writers produce the same bytes for the same call (no
timestamps, no absolute paths), so the files in the repository's ``fixtures/`` folder can be
regenerated and compared byte for byte::

    python -m tests.support.fixtures [OUTDIR]      # from the repository root; default OUTDIR: ./fixtures

Exactness: every coordinate, normal and UV of the fixtures is exactly representable in float32
(multiples of 2**-10 or simpler), except the icosphere, whose float64 positions lie on the unit
sphere within 1e-15 and are rounded to float32 (relative error <= 6e-8) when written. All
writers write the float32 value, OBJ included (as the shortest decimal that reads back to that
float32 value in float64), so the same fixture reads back to identical numbers from every format.
Transformed fixtures (``nested_transforms``, ``zup_cm``, ``point_instancer``) have analytic
world-space results (``*_expected``) that importers reproduce to about 1e-15 relative (float64
matrix products), except where a file format itself stores less (see ``point_instancer``).

Determinism was checked for every format, ``.usdc`` (crate) included: writing twice, in one or in
separate processes, gives identical bytes with usd-core 26.11 (USD bytes may change with the
usd-core version).

Fixtures (``write_all`` writes each in every format listed; details in ``fixtures/README.md``):

=====================  ===========================================  =================================
fixture                what it is                                   files
=====================  ===========================================  =================================
seamed_cube            1 m cube, 24 vertices, UV cross atlas        .obj .gltf+.bin .glb .usda .usdc,
                                                                    seamed_cube_facevarying.usda
two_plates             two 1 m plates 2**-10 m apart (8x8 quads)    .obj .gltf+.bin .glb .usda
unit_sphere            icosphere r = 1, 642 vertices                .obj .glb .usda
concave_ngon           L-shaped hexagon, area 3 m^2, one polygon    .obj .gltf+.bin .usda
nested_transforms      glTF node chain (TRS + matrix) + instance    .gltf+.bin
zup_cm                 USD upAxis Z, metersPerUnit 0.01             .usda
point_instancer        USD PointInstancer, 4 instances x 2 meshes   .usda
glossy_crease          1 m cube, sharp edges, normals bent across   .glb
                       1/16 m bands, turned (render harness)
=====================  ===========================================  =================================
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass, replace
from pathlib import Path
from typing import NamedTuple

import numpy as np

from lopcook.emit.gltf_writer import (ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER, FLOAT, TRIANGLES, UNSIGNED_INT,
                               UNSIGNED_SHORT, BufferBuilder, gltf_json_text, pack_glb)
from lopcook.mesh import icosahedron
from lopcook.viewing import VIEW_ROTATION as GLOSSY_CREASE_ROTATION

GENERATOR = "lopcook fixtures"
"""``asset.generator`` of the glTF files and the signature in OBJ/USD headers."""


# ---------------------------------------------------------------------------------------------
# Plain data
# ---------------------------------------------------------------------------------------------


class Polygons(NamedTuple):
    """Polygonal faces as OBJ ``f`` lines / USD ``faceVertexCounts`` + ``faceVertexIndices``.

    counts : (f,) int32, corners per face (>= 3)
    corners : (sum(counts),) uint32, vertex indices, faces one after another, counter-clockwise
    """

    counts: np.ndarray
    corners: np.ndarray


@dataclass(frozen=True, eq=False)
class FixturePart:
    """One mesh of a fixture.

    Attributes
    ----------
    name : str
        Valid as an OBJ object name, a glTF name and a USD prim name.
    positions : (n, 3) float64
        Metres, +Y-up world frame (for ``zup_cm()``: the file's own Z-up centimetre frame).
    indices : (m, 3) uint32
        Counter-clockwise triangles. For a part with ``polygons`` this is its triangulation
        (what glTF carries).
    uvs : (n, 2) float32 or None
        glTF convention (origin top-left); OBJ/USD files store ``v = 1 - v_gltf``.
    normals : (n, 3) float32 or None
        Unit length.
    polygons : Polygons or None
        When set, OBJ and USD write these faces instead of the triangles (n-gons kept).
    """

    name: str
    positions: np.ndarray
    indices: np.ndarray
    uvs: np.ndarray | None = None
    normals: np.ndarray | None = None
    polygons: Polygons | None = None

    @property
    def faces(self) -> Polygons:
        """The faces OBJ/USD write: ``polygons`` if set, else the triangles as 3-corner faces."""
        if self.polygons is not None:
            return self.polygons
        return Polygons(np.full(len(self.indices), 3, np.int32), self.indices.reshape(-1).astype(np.uint32))

    def area(self) -> float:
        """Total triangle area, m^2 (float64)."""
        a, b, c = (self.positions[self.indices[:, k]] for k in range(3))
        return float(0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum())

    def signed_volume(self) -> float:
        """Signed enclosed volume, m^3 (positive for a closed mesh with outward CCW faces)."""
        a, b, c = (self.positions[self.indices[:, k]] for k in range(3))
        return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)

    def as_mesh_part(self, source: str = ""):
        """This part as a ``lopcook.types.MeshPart`` (positions float64, indices uint32)."""
        from lopcook.types import MeshPart

        return MeshPart(name=self.name, positions=self.positions, indices=self.indices,
                        attributes={"normals": self.normals, "uvs": self.uvs}, source=source)


def _part(name, positions, indices, uvs=None, normals=None, polygons=None) -> FixturePart:
    """Build a FixturePart with canonical dtypes; ``+ 0.0`` turns -0.0 into 0.0 (stable text)."""
    positions = np.asarray(positions, np.float64) + 0.0
    indices = np.asarray(indices, np.uint32).reshape(-1, 3)
    uvs = None if uvs is None else np.asarray(uvs, np.float32) + np.float32(0.0)
    normals = None if normals is None else np.asarray(normals, np.float32) + np.float32(0.0)
    if polygons is not None:
        polygons = Polygons(np.asarray(polygons[0], np.int32), np.asarray(polygons[1], np.uint32))
    return FixturePart(name, positions, indices, uvs, normals, polygons)


def _transform_part(part: FixturePart, matrix: np.ndarray, name: str | None = None) -> FixturePart:
    """Apply a (4, 4) float64 affine transform: positions by M, normals by the inverse transpose.

    Winding is kept (all fixture transforms have a positive determinant).
    """
    m3 = matrix[:3, :3]
    assert np.linalg.det(m3) > 0, "fixture transforms keep orientation"
    pos = part.positions @ m3.T + matrix[:3, 3]
    normals = None
    if part.normals is not None:
        n = part.normals.astype(np.float64) @ np.linalg.inv(m3)  # (M^-T n)^T = n^T M^-1
        normals = (n / np.linalg.norm(n, axis=1, keepdims=True)).astype(np.float32)
    return replace(part, name=name or part.name, positions=pos + 0.0,
                   normals=None if normals is None else normals + np.float32(0.0))


def _trs(translation=(0.0, 0.0, 0.0), rotation=np.eye(3), scale=(1.0, 1.0, 1.0)) -> np.ndarray:
    """(4, 4) float64 matrix T * R * S (the glTF / USD ``xformOp`` order for a point)."""
    m = np.eye(4)
    m[:3, :3] = np.asarray(rotation, np.float64) @ np.diag(np.asarray(scale, np.float64))
    m[:3, 3] = translation
    return m


# Exact 90/180 degree rotation matrices (right-handed, counter-clockwise about the axis).
_ROT_X180 = np.diag([1.0, -1.0, -1.0])
_ROT_Y90 = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
_ROT_Z90 = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
_SQRT_HALF = float(np.sqrt(0.5))


# ---------------------------------------------------------------------------------------------
# Fixtures
# ---------------------------------------------------------------------------------------------

# Cube faces: outward normal n, image-right r, image-up u with r x u = n (so r, u, -r, -u runs
# counter-clockwise seen from outside), and the (column, row) of the face in a 4 x 4 grid of
# 0.25 x 0.25 UV cells laid out as a cross (glTF rows, top row first):
#        +Y
#   -X   +Z   +X   -Z
#        -Y
_CUBE_FACES = (
    # name,  n,           r,            u,           cell
    ("+X", (1, 0, 0), (0, 0, -1), (0, 1, 0), (2, 1)),
    ("-X", (-1, 0, 0), (0, 0, 1), (0, 1, 0), (0, 1)),
    ("+Y", (0, 1, 0), (1, 0, 0), (0, 0, -1), (1, 0)),
    ("-Y", (0, -1, 0), (1, 0, 0), (0, 0, 1), (1, 2)),
    ("+Z", (0, 0, 1), (1, 0, 0), (0, 1, 0), (1, 1)),
    ("-Z", (0, 0, -1), (-1, 0, 0), (0, 1, 0), (3, 1)),
)


def seamed_cube(side: float = 1.0, name: str = "cube") -> list[FixturePart]:
    """Axis-aligned cube of edge ``side`` metres centred at the origin, one part.

    24 vertices (4 per face: every corner position appears 3 times, a UV and normal seam),
    12 CCW outward triangles (signed volume = side**3), flat per-face normals, UVs in a cross
    atlas on a 4 x 4 grid of 0.25-wide cells (glTF rows from the top: +Y; -X +Z +X -Z; -Y; the
    bottom row is empty). Face order +X, -X, +Y, -Y, +Z, -Z; corners per face
    (-r,-u), (+r,-u), (+r,+u), (-r,+u) with r/u the face's image right/up axes.

    Returns
    -------
    [FixturePart] with positions (24, 3), indices (12, 3), uvs (24, 2), normals (24, 3).
    """
    n, r, u = (np.array([f[k] for f in _CUBE_FACES], np.float64) for k in (1, 2, 3))  # (6, 3)
    cell = np.array([f[4] for f in _CUBE_FACES], np.float64)  # (6, 2) column, row
    sr = np.array([-1.0, 1.0, 1.0, -1.0])  # corner signs along r and u
    su = np.array([-1.0, -1.0, 1.0, 1.0])
    h = 0.5 * side
    pos = h * (n[:, None, :] + sr[None, :, None] * r[:, None, :] + su[None, :, None] * u[:, None, :])
    uv = np.empty((6, 4, 2))
    uv[..., 0] = 0.25 * (cell[:, None, 0] + 0.5 * (1.0 + sr[None, :]))
    uv[..., 1] = 0.25 * (cell[:, None, 1] + 0.5 * (1.0 - su[None, :]))  # image up = smaller v
    base = 4 * np.arange(6)[:, None]
    tris = np.stack([base + [0, 1, 2], base + [0, 2, 3]], axis=1).reshape(-1, 3)
    normals = np.repeat(n, 4, axis=0)
    return [_part(name, pos.reshape(-1, 3), tris, uv.reshape(-1, 2), normals)]


def _grid_plate(name: str, y: float, quads: int = 8, size: float = 1.0) -> FixturePart:
    """Square plate in the plane Y = y, centred on the Y axis, facing +Y, quads x quads cells."""
    t = np.linspace(-0.5 * size, 0.5 * size, quads + 1)
    z, x = np.meshgrid(t, t, indexing="ij")  # row index along z, column along x
    k = quads + 1
    pos = np.stack([x.ravel(), np.full(k * k, float(y)), z.ravel()], axis=1)
    # Seen from +Y (x right, -z up) the corners (i,j), (i+1,j), (i+1,j+1), (i,j+1) in (row z,
    # column x) run counter-clockwise when listed as v00, v10 (next row = +z), v11, v01.
    i, j = np.meshgrid(np.arange(quads), np.arange(quads), indexing="ij")
    v00 = (i * k + j).ravel()
    v01, v10, v11 = v00 + 1, v00 + k, v00 + k + 1
    tris = np.stack([np.stack([v00, v10, v11], 1), np.stack([v00, v11, v01], 1)], axis=1).reshape(-1, 3)
    uv = np.stack([(x.ravel() / size + 0.5), (z.ravel() / size + 0.5)], axis=1)  # v grows towards +z
    normals = np.tile([0.0, 1.0, 0.0], (k * k, 1))
    return _part(name, pos, tris, uv, normals)


def two_plates(gap: float = 2.0**-10) -> list[FixturePart]:
    """Two parallel 1 m x 1 m plates, both facing +Y, ``gap`` metres apart (depth-critical test).

    Each plate: x, z in [-0.5, 0.5], a regular grid of 8 x 8 quads = 81 vertices, 128 CCW
    triangles, area 1 m^2, normals +Y, UVs u = x + 0.5, v = z + 0.5 (glTF). "plate_lower" lies
    at y = 0, "plate_upper" at y = gap. The default gap 2**-10 m (0.9765625 mm, "1 mm") is exact
    in float32 and float64, so every format carries exactly the same gap (0.001 is not).

    Returns
    -------
    [plate_lower, plate_upper]
    """
    return [_grid_plate("plate_lower", 0.0), _grid_plate("plate_upper", gap)]


def unit_sphere(subdivisions: int = 3) -> list[FixturePart]:
    """Icosphere of radius 1 m centred at the origin, one part "sphere", no UVs.

    Each subdivision splits every triangle into 4 at its edge midpoints, projected to the
    sphere: V = 10 * 4**s + 2 vertices, 20 * 4**s CCW outward triangles (s = 3: 642 and 1280).
    Positions are float64 with | |p| - 1 | < 1e-15; normals are the positions in float32 (the
    exact analytic normal, rounded). Files carry float32 positions (relative rounding <= 6e-8).

    Returns
    -------
    [FixturePart] with positions (V, 3), indices (F, 3), normals (V, 3), uvs None.
    """
    v, f = icosahedron()
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    for _ in range(subdivisions):
        m = len(f)
        edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        unique, inverse = np.unique(edges, axis=0, return_inverse=True)
        mid = v[unique[:, 0]] + v[unique[:, 1]]
        mid /= np.linalg.norm(mid, axis=1, keepdims=True)
        ab, bc, ca = inverse.reshape(3, m) + len(v)
        a, b, c = f.T
        f = np.stack([np.stack([a, ab, ca], 1), np.stack([ab, b, bc], 1),
                      np.stack([ca, bc, c], 1), np.stack([ab, bc, ca], 1)], axis=1).reshape(-1, 3)
        v = np.vstack([v, mid])
    return [_part("sphere", v, f, None, v.astype(np.float32))]


# GLOSSY_CREASE_ROTATION: Ry(45 deg) Rx(34 deg), the turn of the render harness's 20 icosahedron
# views (lopcook.viewing.VIEW_ROTATION), so the crease is seen the same way from every view set.


def glossy_crease(band: float = 2.0**-4, cells: int = 8, steps: int = 4) -> list[FixturePart]:
    """A 1 m cube with geometrically sharp edges whose vertex normals bend smoothly across every edge
    and corner: a sharp crease under a glossy highlight (render-harness test, Meyer et al. 2011,
    section 5.1 and Fig. 13). One part "crease", no UVs.

    Construction, in the cube's own frame (half side h = 0.5 m, a = h - ``band``): each face is a
    grid of (cells + 1 + 2 steps)^2 points ``s`` on the cube surface, with ``cells`` equal cells over
    [-a, a] and ``steps`` finer cells on each side in the band [a, h] at a + band * tan(pi/4 * k /
    steps) (k = 1..steps). Positions are the points themselves (flat faces, sharp edges); the normal
    at s is that of a cube rounded with radius ``band``, ``normalize(s - clamp(s, -a, a))``: the face
    normal inside [-a, a]^2 and, across the band, turning in equal 45/steps-degree steps to the
    bisector at the edge (corners: the sphere octant). Points shared by faces are welded (np.unique
    of s, lexicographic order): V = 6 (cells + 2 steps)^2 + 2, F = 12 (cells + 2 steps)^2 CCW
    outward triangles (defaults: 1538 vertices, 3072 triangles), area 6 m^2, volume 1 m^3.

    The cube is then turned by ``GLOSSY_CREASE_ROTATION``: in the harness's view set, 12 of the 20
    views then look along the normal arc of an edge (a Phong headlight highlight runs along that
    whole edge) and 8 straight at a corner. Positions and normals are rounded to float32 (like the
    sphere, they are not exact: the rotation is irrational); normals are renormalised in float64
    first.

    What it shows: the band normals vary fast (E_v about 16 per metre), so CAP pins the band
    vertices at high levels (about 15 bits with the default analysis), while flat-face vertices stay
    at level 1; AP at level 6 moves the band's vertices by up to half a pixel and visibly shifts and
    reshapes the highlight on the crease.

    Returns
    -------
    [FixturePart] with positions (V, 3), indices (F, 3), normals (V, 3), uvs None.
    """
    h = 0.5
    a = h - float(band)
    inner = np.linspace(-a, a, cells + 1)
    outer = a + float(band) * np.tan(np.pi / 4.0 * np.arange(1, steps + 1) / steps)
    outer[-1] = h
    t = np.concatenate([-outer[::-1], inner, outer])
    k = len(t)
    # (normal axis, r axis, u axis, sign) with e_r x e_u = outward normal
    faces = [(0, 1, 2, 1.0), (0, 2, 1, -1.0), (1, 2, 0, 1.0), (1, 0, 2, -1.0), (2, 0, 1, 1.0), (2, 1, 0, -1.0)]
    tu, tr = np.meshgrid(t, t, indexing="ij")
    i, j = np.meshgrid(np.arange(k - 1), np.arange(k - 1), indexing="ij")
    v00 = (i * k + j).ravel()
    v01, v10 = v00 + 1, v00 + k
    v11 = v10 + 1
    quad_tris = np.concatenate([np.stack([v00, v01, v11], 1), np.stack([v00, v11, v10], 1)])
    points, tris = [], []
    for f, (ax, ra, ua, sign) in enumerate(faces):
        s = np.zeros((k * k, 3))
        s[:, ax] = sign * h
        s[:, ra] = tr.ravel()
        s[:, ua] = tu.ravel()
        points.append(s)
        tris.append(quad_tris + f * k * k)
    s = np.concatenate(points)
    unique, inverse = np.unique(s, axis=0, return_inverse=True)
    indices = inverse.reshape(-1)[np.concatenate(tris)]
    d = unique - np.clip(unique, -a, a)
    normals = d / np.linalg.norm(d, axis=1, keepdims=True)
    rot = GLOSSY_CREASE_ROTATION
    pos = (unique @ rot.T).astype(np.float32).astype(np.float64)
    nrm = normals @ rot.T
    nrm = (nrm / np.linalg.norm(nrm, axis=1, keepdims=True)).astype(np.float32)
    return [_part("crease", pos, indices, None, nrm)]


def concave_ngon() -> list[FixturePart]:
    """One planar L-shaped hexagon in the plane y = 0, facing +Y, area exactly 3 m^2, one part.

    Corners (x, z), counter-clockwise seen from +Y:
    (-1, 1), (1, 1), (1, 0), (0, 0), (0, -1), (-1, -1); vertex 3 (the origin) is the reflex corner.
    ``polygons`` holds the single 6-corner face (OBJ ``f`` with 6 corners, USD
    faceVertexCounts [6]); ``indices`` holds its triangulation for glTF: the fan from the reflex
    corner, 4 triangles with areas 0.5, 1, 1, 0.5. Normals +Y, UVs u = (x + 1) / 2,
    v = (z + 1) / 2 (glTF).

    Returns
    -------
    [FixturePart] with positions (6, 3), indices (4, 3), polygons ([6], 6 corners).
    """
    xz = np.array([[-1, 1], [1, 1], [1, 0], [0, 0], [0, -1], [-1, -1]], np.float64)
    pos = np.stack([xz[:, 0], np.zeros(6), xz[:, 1]], axis=1)
    tris = [[3, 4, 5], [3, 5, 0], [3, 0, 1], [3, 1, 2]]
    uv = (xz + 1.0) / 2.0
    normals = np.tile([0.0, 1.0, 0.0], (6, 1))
    return [_part("lshape", pos, tris, uv, normals, polygons=([6], np.arange(6)))]


def _tetra(name: str = "tetra") -> FixturePart:
    """Asymmetric tetrahedron (0,0,0), (0.25,0,0), (0,0.5,0), (0,0,0.75) m: 12 vertices (flat
    normals), 4 CCW outward triangles, UVs (0,0), (1,0), (0,1) per face. Volume 1/64 m^3."""
    c = np.array([[0, 0, 0], [0.25, 0, 0], [0, 0.5, 0], [0, 0, 0.75]], np.float64)
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    pos = c[faces].reshape(-1, 3)
    a, b, cc = (c[faces[:, k]] for k in range(3))
    n = np.cross(b - a, cc - a)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    uv = np.tile([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], (4, 1))
    return _part(name, pos, np.arange(12).reshape(4, 3), uv, np.repeat(n, 3, axis=0))


def nested_transforms() -> tuple[list[FixturePart], list[dict]]:
    """glTF node hierarchy: one mesh "tetra" under a 3-node chain and instanced by a 4th node.

    Nodes (glTF JSON form; ``"mesh"`` is an index into the returned parts):

    0. ``chain_a`` (root): translation (1, 0.5, -2), rotation 90 deg about +Y
       (quaternion x, y, z, w = 0, sqrt(1/2), 0, sqrt(1/2)); children [1]
    1. ``chain_b``: translation (0, 1, 0), rotation 180 deg about +X (1, 0, 0, 0),
       scale (2, 1, 0.5); children [2]
    2. ``chain_c``: ``matrix`` (column-major) = translate (0.25, 0, 0) * rotate 90 deg about +Z
       * uniform scale 0.5; mesh 0
    3. ``instance`` (root): translation (-3, 0, 1), scale (3, 3, 3); mesh 0

    The tetra is asymmetric (edges 0.25, 0.5, 0.75 m along x, y, z), so swapped axes, a
    row-major matrix or a wrong TRS order all show. See ``nested_transforms_expected``.

    Returns
    -------
    (parts, nodes): [tetra] in its mesh frame, and 4 node dicts for ``write_gltf(nodes=...)``.
    """
    m_c = _trs((0.25, 0.0, 0.0), _ROT_Z90, (0.5, 0.5, 0.5))
    nodes = [
        {"name": "chain_a", "children": [1], "translation": [1.0, 0.5, -2.0],
         "rotation": [0.0, _SQRT_HALF, 0.0, _SQRT_HALF]},
        {"name": "chain_b", "children": [2], "translation": [0.0, 1.0, 0.0],
         "rotation": [1.0, 0.0, 0.0, 0.0], "scale": [2.0, 1.0, 0.5]},
        {"name": "chain_c", "mesh": 0, "matrix": [float(x) + 0.0 for x in m_c.T.ravel()]},
        {"name": "instance", "mesh": 0, "translation": [-3.0, 0.0, 1.0], "scale": [3.0, 3.0, 3.0]},
    ]
    return [_tetra()], nodes


def nested_transforms_expected() -> dict[str, FixturePart]:
    """World-space tetra per mesh-carrying node: ``{"chain_c": ..., "instance": ...}``.

    chain_c: M_a * M_b * M_c with M = T * R * S built from exact 0/±1 rotation matrices;
    instance: T(-3, 0, 1) * S(3). Positions (12, 3) float64 metres, normals transformed by the
    inverse transpose and renormalised (float32), indices and UVs unchanged (all determinants
    positive: 0.125 and 27).
    """
    tetra = _tetra()
    m_a = _trs((1.0, 0.5, -2.0), _ROT_Y90)
    m_b = _trs((0.0, 1.0, 0.0), _ROT_X180, (2.0, 1.0, 0.5))
    m_c = _trs((0.25, 0.0, 0.0), _ROT_Z90, (0.5, 0.5, 0.5))
    m_i = _trs((-3.0, 0.0, 1.0), np.eye(3), (3.0, 3.0, 3.0))
    return {"chain_c": _transform_part(tetra, m_a @ m_b @ m_c, "chain_c"),
            "instance": _transform_part(tetra, m_i, "instance")}


# Z-up centimetres -> Y-up metres: (x, y, z) -> (x, z, -y) * 0.01 (a proper rotation, det +1).
_ZUP_TO_YUP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def zup_cm_expected() -> list[FixturePart]:
    """What ``zup_cm.usda`` is in lopcook's frame: ``seamed_cube(side=0.5)`` (metres, +Y up)."""
    return seamed_cube(side=0.5)


def zup_cm() -> list[FixturePart]:
    """The cube of ``zup_cm_expected()`` in a Z-up, centimetre frame (what ``zup_cm.usda`` stores).

    Positions are (X, -Z, Y) * 100 of the Y-up metre positions (corners at ±25 cm), normals
    (nX, -nZ, nY); indices and UVs unchanged. Converting back with (x, z, -y) * 0.01 gives the
    expected cube exactly (25 * 0.01 rounds to 0.25 in float64).
    """
    part = zup_cm_expected()[0]
    inv = _ZUP_TO_YUP.T  # rotation inverse
    pos = (part.positions @ inv.T) * 100.0
    normals = (part.normals.astype(np.float64) @ inv.T).astype(np.float32)
    return [replace(part, positions=pos + 0.0, normals=normals + np.float32(0.0))]


@dataclass(frozen=True, eq=False)
class PointInstancerFixture:
    """Data of ``point_instancer.usda``.

    Attributes
    ----------
    prototype : list[FixturePart]
        Meshes of the single prototype ``Proto`` in their own mesh frames: "Box", "Pyramid".
    prototype_xforms : list[(4, 4) float64]
        Each mesh's transform inside the prototype (Box: identity, Pyramid: translate (0, 0.5, 0)).
    positions : (k, 3) float64
        Instance positions (instancer frame), metres.
    orientations : (k, 4) float64
        Quaternions (w, x, y, z) as intended; the file stores ``quath`` (half precision).
    rotations : (k, 3, 3) float64
        The exact rotation matrices the orientations stand for.
    scales : (k, 3) float64
    proto_indices : (k,) int32
    instancer_xform : (4, 4) float64
        The PointInstancer prim's own transform (translate (0, 1, 0)).
    """

    prototype: list
    prototype_xforms: list
    positions: np.ndarray
    orientations: np.ndarray
    rotations: np.ndarray
    scales: np.ndarray
    proto_indices: np.ndarray
    instancer_xform: np.ndarray


def _box_and_pyramid() -> list[FixturePart]:
    """Box 0.5 m (x, z in ±0.25, y in [0, 0.5], 8 vertices, 6 quads) and a pyramid (base
    ±0.25 at y = 0, apex (0, 0.25, 0); 5 vertices, 1 quad + 4 triangles). No normals, no UVs."""
    h = 0.25
    box = np.array([[-h, 0, -h], [h, 0, -h], [h, 0, h], [-h, 0, h],
                    [-h, 0.5, -h], [h, 0.5, -h], [h, 0.5, h], [-h, 0.5, h]], np.float64)
    quads = np.array([[0, 1, 2, 3], [4, 7, 6, 5], [0, 4, 5, 1], [1, 5, 6, 2], [2, 6, 7, 3], [3, 7, 4, 0]])
    box_tris = np.stack([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]], axis=1).reshape(-1, 3)
    pyr = np.array([[-h, 0, -h], [h, 0, -h], [h, 0, h], [-h, 0, h], [0, h, 0]], np.float64)
    pyr_faces = [[0, 1, 2, 3], [0, 4, 1], [1, 4, 2], [2, 4, 3], [3, 4, 0]]
    pyr_tris = [[0, 1, 2], [0, 2, 3], [0, 4, 1], [1, 4, 2], [2, 4, 3], [3, 4, 0]]
    return [
        _part("Box", box, box_tris, polygons=([4] * 6, quads.ravel())),
        _part("Pyramid", pyr, pyr_tris, polygons=([4, 3, 3, 3, 3], np.concatenate(pyr_faces))),
    ]


def point_instancer() -> PointInstancerFixture:
    """A UsdGeom.PointInstancer with 4 instances of one prototype made of 2 meshes.

    Instances (instancer frame): 0 at the origin; 1 at (2, 0, 0); 2 at (0, 0, -2) rotated
    90 deg about +Y; 3 at (-2, 0, 0) scaled 2x. The instancer itself is translated (0, 1, 0).
    Prototype meshes: see ``_box_and_pyramid``; the Pyramid sits on the box (translate
    (0, 0.5, 0) inside the prototype). The prototypes live under the instancer
    (``/Root/Instancer/Prototypes/Proto``) and are not drawn on their own: 8 placed parts.
    """
    k = 4
    rot = np.repeat(np.eye(3)[None], k, axis=0)
    rot[2] = _ROT_Y90
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (k, 1))
    quat[2] = [_SQRT_HALF, 0.0, _SQRT_HALF, 0.0]
    return PointInstancerFixture(
        prototype=_box_and_pyramid(),
        prototype_xforms=[np.eye(4), _trs((0.0, 0.5, 0.0))],
        positions=np.array([[0, 0, 0], [2, 0, 0], [0, 0, -2], [-2, 0, 0]], np.float64),
        orientations=quat,
        rotations=rot,
        scales=np.array([[1, 1, 1], [1, 1, 1], [1, 1, 1], [2, 2, 2]], np.float64),
        proto_indices=np.zeros(k, np.int32),
        instancer_xform=_trs((0.0, 1.0, 0.0)),
    )


def point_instancer_expected() -> dict[str, FixturePart]:
    """World-space placed meshes keyed ``"instance{k}/{Box|Pyramid}"`` (8 parts, k = 0..3).

    world = instancer_xform * T(position_k) * R_k * S(scale_k) * prototype_xform * p, with the
    exact rotation matrices (the file's half-precision quaternion is (0.70703125, 0, 0.70703125,
    0): normalised it is exactly 90 deg about Y; unnormalised it shrinks by 0.9998).
    """
    fx = point_instancer()
    out = {}
    for k in range(len(fx.positions)):
        inst = fx.instancer_xform @ _trs(fx.positions[k], fx.rotations[k], fx.scales[k])
        for mesh, local in zip(fx.prototype, fx.prototype_xforms):
            name = f"instance{k}/{mesh.name}"
            out[name] = _transform_part(mesh, inst @ local, name)
    return out


# ---------------------------------------------------------------------------------------------
# Writers
# ---------------------------------------------------------------------------------------------


def _f32_text(values: np.ndarray) -> list[list[str]]:
    """Shortest decimal that reads back (as float64) to the float32 value of each entry."""
    return [[repr(x) for x in row] for row in np.asarray(values, np.float32).astype(np.float64).tolist()]


def _write_bytes(path: Path, data: bytes) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(data)
    return path


def write_obj(parts: list[FixturePart], path, comment: str = "") -> Path:
    """Wavefront OBJ, one ``o`` per part, 1-based ``v/vt/vn`` corners, polygons kept.

    ``v`` and ``vn`` carry the float32 values (positions are rounded to float32 like in glTF and
    USD); ``vt`` stores ``v = 1 - v_gltf``. A part without UVs writes ``v//vn``, without normals
    ``v/vt``, without both ``v``. Parts share one global index space (offsets accumulate). LF
    line endings, no material library.

    Returns the path written.
    """
    lines = [f"# {GENERATOR}: {comment}".rstrip() if comment else f"# {GENERATOR}",
             "# metres, +Y up, counter-clockwise faces; vt v = 1 - v_gltf"]
    offset = 0
    for part in parts:
        n = len(part.positions)
        lines.append(f"o {part.name}")
        lines += ["v " + " ".join(r) for r in _f32_text(part.positions)]
        if part.uvs is not None:
            st = np.stack([part.uvs[:, 0], np.float32(1.0) - part.uvs[:, 1]], axis=1)
            lines += ["vt " + " ".join(r) for r in _f32_text(st)]
        if part.normals is not None:
            lines += ["vn " + " ".join(r) for r in _f32_text(part.normals)]
        idx = (part.faces.corners.astype(np.int64) + offset + 1).astype(str)
        if part.uvs is not None and part.normals is not None:
            corner = np.char.add(np.char.add(np.char.add(np.char.add(idx, "/"), idx), "/"), idx)
        elif part.normals is not None:
            corner = np.char.add(np.char.add(idx, "//"), idx)
        elif part.uvs is not None:
            corner = np.char.add(np.char.add(idx, "/"), idx)
        else:
            corner = idx
        starts = np.concatenate([[0], np.cumsum(part.faces.counts)])
        corner = corner.tolist()
        lines += ["f " + " ".join(corner[s:e]) for s, e in zip(starts[:-1].tolist(), starts[1:].tolist())]
        offset += n
    return _write_bytes(path, ("\n".join(lines) + "\n").encode("ascii"))


def _gltf_document(parts: list[FixturePart], nodes: list[dict] | None, index_dtype) -> tuple[dict, bytes]:
    """Build the glTF JSON dict and the binary buffer (little-endian, 4-byte aligned views).

    Uses the shared ``lopcook.emit.gltf_writer.BufferBuilder``; the JSON keys keep their insertion
    order here (the committed fixtures predate the sorted-key lopcook writer).
    """
    buf = BufferBuilder()
    add = buf.add

    meshes = []
    for part in parts:
        attributes = {"POSITION": add(part.positions.astype("<f4"), "VEC3", FLOAT, ARRAY_BUFFER, True)}
        if part.normals is not None:
            attributes["NORMAL"] = add(part.normals.astype("<f4"), "VEC3", FLOAT, ARRAY_BUFFER)
        if part.uvs is not None:
            attributes["TEXCOORD_0"] = add(part.uvs.astype("<f4"), "VEC2", FLOAT, ARRAY_BUFFER)
        dtype = index_dtype or ("<u2" if len(part.positions) <= 65535 else "<u4")
        dtype = np.dtype(dtype).newbyteorder("<")
        component = {2: UNSIGNED_SHORT, 4: UNSIGNED_INT}[dtype.itemsize]
        ind = add(part.indices.reshape(-1).astype(dtype), "SCALAR", component, ELEMENT_ARRAY_BUFFER)
        meshes.append({"name": part.name,
                       "primitives": [{"attributes": attributes, "indices": ind, "mode": TRIANGLES}]})

    if nodes is None:
        nodes = [{"name": part.name, "mesh": i} for i, part in enumerate(parts)]
    children = {c for node in nodes for c in node.get("children", ())}
    roots = [i for i in range(len(nodes)) if i not in children]
    doc = {
        "asset": {"generator": GENERATOR, "version": "2.0"},
        "scene": 0,
        "scenes": [{"name": "fixture", "nodes": roots}],
        "nodes": [dict(node) for node in nodes],
        "meshes": meshes,
        "accessors": buf.accessors,
        "bufferViews": buf.views,
        "buffers": [{"byteLength": len(buf.blob)}],
    }
    return doc, bytes(buf.blob)


def write_gltf(parts: list[FixturePart], path, binary: bool = False, nodes: list[dict] | None = None,
               index_dtype=None) -> list[Path]:
    """glTF 2.0: ``.gltf`` JSON + external ``<stem>.bin``, or a single ``.glb`` when ``binary``.

    One mesh with one TRIANGLES primitive per part: POSITION (float32 VEC3 with min/max),
    NORMAL and TEXCOORD_0 (float32) when the part has them, indices uint16 when the part has at
    most 65535 vertices else uint32 (``index_dtype`` forces one, e.g. ``"<u4"``). One bufferView
    per accessor, 4-byte aligned, tightly packed. ``nodes`` (glTF node dicts whose ``"mesh"`` is
    a part index) replaces the default one node per part; roots are the nodes nobody lists as
    a child. JSON keys in a fixed order, floats as Python ``repr`` (round-trip exact).

    Returns the paths written (``[gltf, bin]`` or ``[glb]``).
    """
    path = Path(path)
    doc, blob = _gltf_document(parts, nodes, index_dtype)
    if not binary:
        bin_path = path.with_suffix(".bin")
        doc["buffers"][0]["uri"] = bin_path.name
        text = gltf_json_text(doc, sort_keys=False)
        return [_write_bytes(path, text.encode("ascii")), _write_bytes(bin_path, blob)]
    data = pack_glb(json.dumps(doc, separators=(",", ":")).encode("ascii"), blob)
    return [_write_bytes(path, data)]


def _usd_stage(doc: str, up_axis: str = "Y", meters_per_unit: float = 1.0):
    """In-memory stage with /Root (Xform, defaultPrim), upAxis, metersPerUnit and a fixed doc."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.CreateInMemory()
    stage.GetRootLayer().documentation = doc
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y if up_axis == "Y" else UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, meters_per_unit)
    root = UsdGeom.Xform.Define(stage, "/Root")
    stage.SetDefaultPrim(root.GetPrim())
    return stage


def _usd_mesh(stage, prim_path: str, part: FixturePart, interpolation: str = "vertex"):
    """Define a UsdGeom.Mesh from a part: float32 points, polygons kept, subdivisionScheme none.

    ``interpolation="vertex"``: one point per part vertex, ``primvars:normals`` and
    ``primvars:st`` (texCoord2f, v flipped) per point. ``"faceVarying"``: points welded to the
    unique positions (sorted lexicographically), normals per face corner (unindexed), st
    indexed (values = the part's UVs, ``primvars:st:indices`` = face corners).
    """
    from pxr import Sdf, UsdGeom, Vt

    faces = part.faces
    corners = faces.corners.astype(np.int64)
    points = part.positions.astype(np.float32)
    if interpolation == "faceVarying":
        points, remap = np.unique(points, axis=0, return_inverse=True)
        fvi = remap.reshape(-1)[corners]
    elif interpolation == "vertex":
        fvi = corners
    else:
        raise ValueError(f"interpolation must be 'vertex' or 'faceVarying', got {interpolation!r}")
    mesh = UsdGeom.Mesh.Define(stage, prim_path)
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(points)))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(faces.counts.astype(np.int32)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(fvi.astype(np.int32)))
    mesh.CreateExtentAttr(Vt.Vec3fArray.FromNumpy(np.stack([points.min(axis=0), points.max(axis=0)])))
    api = UsdGeom.PrimvarsAPI(mesh)
    fv = interpolation == "faceVarying"
    if part.normals is not None:
        normals = part.normals[corners] if fv else part.normals
        pv = api.CreatePrimvar("normals", Sdf.ValueTypeNames.Normal3fArray, interpolation)
        pv.Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(normals, np.float32)))
    if part.uvs is not None:
        st = np.stack([part.uvs[:, 0], np.float32(1.0) - part.uvs[:, 1]], axis=1).astype(np.float32)
        pv = api.CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, interpolation)
        pv.Set(Vt.Vec2fArray.FromNumpy(st))
        if fv:
            pv.SetIndices(Vt.IntArray.FromNumpy(corners.astype(np.int32)))
    return mesh


def _save_stage(stage, path) -> Path:
    """Write the root layer: ``.usda`` via ExportToString (text, LF), ``.usdc`` via Export."""
    path = Path(path)
    layer = stage.GetRootLayer()
    if path.suffix == ".usda":
        return _write_bytes(path, layer.ExportToString().encode("utf-8"))
    path.parent.mkdir(parents=True, exist_ok=True)
    if not layer.Export(str(path)):
        raise OSError(f"{path}: USD export failed")
    return path


def write_usd(parts: list[FixturePart], path, doc: str = "", interpolation: str = "vertex") -> Path:
    """USD (``.usda`` text or ``.usdc`` crate, by suffix): /Root Xform (defaultPrim) with one
    UsdGeom.Mesh per part (``/Root/<name>``), upAxis Y, metersPerUnit 1.

    Points float32, faceVertexCounts/Indices (n-gons kept), ``primvars:normals`` (normal3f) and
    ``primvars:st`` (texCoord2f, ``v = 1 - v_gltf``) with ``interpolation`` ("vertex" or
    "faceVarying", see ``_usd_mesh``), extent, subdivisionScheme "none". The layer ``doc`` is
    set explicitly (default: the generator), so no path or timestamp reaches the file.

    Returns the path written.
    """
    stage = _usd_stage(doc or f"{GENERATOR}: {Path(path).stem}")
    for part in parts:
        _usd_mesh(stage, f"/Root/{part.name}", part, interpolation)
    return _save_stage(stage, path)


def write_usd_zup_cm(path) -> Path:
    """``zup_cm()`` as USD: upAxis "Z", metersPerUnit 0.01, mesh ``/Root/cube`` in centimetres.

    Returns the path written.
    """
    stage = _usd_stage(f"{GENERATOR}: zup_cm (Z up, centimetres; in metres +Y up it is a 0.5 m cube)",
                       up_axis="Z", meters_per_unit=0.01)
    for part in zup_cm():
        _usd_mesh(stage, f"/Root/{part.name}", part)
    return _save_stage(stage, path)


def write_usd_point_instancer(path) -> Path:
    """``point_instancer()`` as USD.

    Layout: ``/Root`` (Xform) / ``Instancer`` (PointInstancer, xformOp:translate (0, 1, 0);
    positions point3f[], orientations quath[] (w, x, y, z), scales float3[], protoIndices int[],
    prototypes -> ``/Root/Instancer/Prototypes/Proto``) / ``Prototypes`` (Scope) / ``Proto``
    (Xform) / ``Box``, ``Pyramid`` (Meshes; Pyramid has xformOp:translate (0, 0.5, 0)).

    Returns the path written.
    """
    from pxr import Gf, UsdGeom, Vt

    fx = point_instancer()
    stage = _usd_stage(f"{GENERATOR}: point_instancer (4 instances of a 2-mesh prototype)")
    inst = UsdGeom.PointInstancer.Define(stage, "/Root/Instancer")
    inst.AddTranslateOp().Set(Gf.Vec3d(*fx.instancer_xform[:3, 3].tolist()))
    UsdGeom.Scope.Define(stage, "/Root/Instancer/Prototypes")
    proto = UsdGeom.Xform.Define(stage, "/Root/Instancer/Prototypes/Proto")
    for part, local in zip(fx.prototype, fx.prototype_xforms):
        mesh = _usd_mesh(stage, f"{proto.GetPath()}/{part.name}", part)
        if not np.array_equal(local, np.eye(4)):
            mesh.AddTranslateOp().Set(Gf.Vec3d(*local[:3, 3].tolist()))
    inst.CreatePrototypesRel().SetTargets([proto.GetPath()])
    inst.CreateProtoIndicesAttr(Vt.IntArray.FromNumpy(fx.proto_indices))
    inst.CreatePositionsAttr(Vt.Vec3fArray.FromNumpy(fx.positions.astype(np.float32)))
    inst.CreateOrientationsAttr(Vt.QuathArray([Gf.Quath(float(q[0]), Gf.Vec3h(*q[1:].tolist()))
                                               for q in fx.orientations]))
    inst.CreateOrientationsfAttr(Vt.QuatfArray([Gf.Quatf(float(q[0]), Gf.Vec3f(*q[1:].tolist()))
                                                for q in fx.orientations]))
    inst.CreateScalesAttr(Vt.Vec3fArray.FromNumpy(fx.scales.astype(np.float32)))
    return _save_stage(stage, path)


# ---------------------------------------------------------------------------------------------
# All fixtures
# ---------------------------------------------------------------------------------------------


def write_all(outdir="fixtures") -> list[Path]:
    """Write every fixture in every format it exists in (see the module docstring) to ``outdir``.

    Returns the written paths (``.bin`` files included) in writing order.
    """
    out = Path(outdir)
    written: list[Path] = []

    def each(name: str, parts: list[FixturePart], formats: tuple[str, ...], **gltf) -> None:
        for fmt in formats:
            target = out / f"{name}.{fmt}"
            if fmt == "obj":
                written.append(write_obj(parts, target, comment=name))
            elif fmt in ("gltf", "glb"):
                written.extend(write_gltf(parts, target, binary=fmt == "glb", **gltf))
            else:
                written.append(write_usd(parts, target))

    each("seamed_cube", seamed_cube(), ("obj", "gltf", "glb", "usda", "usdc"))
    written.append(write_usd(seamed_cube(), out / "seamed_cube_facevarying.usda",
                             interpolation="faceVarying"))
    each("two_plates", two_plates(), ("obj", "gltf", "glb", "usda"))
    each("unit_sphere", unit_sphere(), ("obj", "glb", "usda"), index_dtype="<u4")
    each("concave_ngon", concave_ngon(), ("obj", "gltf", "usda"))
    parts, nodes = nested_transforms()
    written.extend(write_gltf(parts, out / "nested_transforms.gltf", nodes=nodes))
    written.append(write_usd_zup_cm(out / "zup_cm.usda"))
    written.append(write_usd_point_instancer(out / "point_instancer.usda"))
    each("glossy_crease", glossy_crease(), ("glb",))
    return written


def main(argv: list[str] | None = None) -> int:
    """``python -m tests.support.fixtures [OUTDIR]``: regenerate the fixtures (default ./fixtures)."""
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) > 1 or (argv and argv[0].startswith("-")):
        print("usage: python -m tests.support.fixtures [OUTDIR]   (default: fixtures)", file=sys.stderr)
        return 2
    for p in write_all(argv[0] if argv else "fixtures"):
        print(f"{p}  {p.stat().st_size} bytes")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())


# ---------------------------------------------------------------------------------------------
# Textured fixtures (materials for decoded previews; added for lopcook.emit.preview's tests)
# ---------------------------------------------------------------------------------------------


def png_bytes(rgba: np.ndarray) -> bytes:
    """A PNG (8-bit RGBA, no filter, zlib level 9) of an (h, w, 4) uint8 array; deterministic."""
    import struct
    import zlib

    rgba = np.ascontiguousarray(rgba, np.uint8)
    h, w = rgba.shape[:2]
    raw = np.concatenate([np.zeros((h, 1), np.uint8), rgba.reshape(h, w * 4)], axis=1).tobytes()

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 6, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


def textured_images(size: int = 16) -> dict[str, bytes]:
    """Four small PNGs: ``albedo`` (red/blue checker, alpha 255 or 64 by cell), ``orm`` (R
    occlusion, G roughness, B metallic ramps), ``normal`` (a tilted tangent-space normal) and
    ``emissive`` (a green stripe), each ``size`` x ``size``."""
    y, x = np.mgrid[0:size, 0:size]
    checker = ((x // 4 + y // 4) % 2).astype(bool)
    albedo = np.zeros((size, size, 4), np.uint8)
    albedo[checker] = (220, 40, 30, 255)
    albedo[~checker] = (30, 60, 200, 64)
    ramp = (x * 255 // max(size - 1, 1)).astype(np.uint8)
    orm = np.stack([np.full_like(ramp, 230), ramp, 255 - ramp, np.full_like(ramp, 255)], axis=2)
    normal = np.zeros((size, size, 4), np.uint8)
    normal[...] = (160, 128, 240, 255)
    emissive = np.zeros((size, size, 4), np.uint8)
    emissive[..., 3] = 255
    emissive[size // 2 - 1: size // 2 + 1, :, 1] = 255
    return {k: png_bytes(v) for k, v in
            (("albedo", albedo), ("orm", orm), ("normal", normal), ("emissive", emissive))}


#: The material of ``write_textured_gltf`` (texture indices: 0 albedo, 1 orm, 2 normal, 3 emissive).
TEXTURED_MATERIAL = {
    "name": "painted",
    "pbrMetallicRoughness": {"baseColorFactor": [0.875, 0.5, 0.25, 1.0], "baseColorTexture": {"index": 0},
                             "metallicFactor": 0.25, "roughnessFactor": 0.75,
                             "metallicRoughnessTexture": {"index": 1}},
    "normalTexture": {"index": 2, "scale": 0.5},
    "occlusionTexture": {"index": 1, "strength": 0.75},
    "emissiveTexture": {"index": 3},
    "emissiveFactor": [0.125, 0.25, 0.5],
    "alphaMode": "MASK",
    "alphaCutoff": 0.375,
    "doubleSided": True,
}
#: Its sampler (nearest filtering, clamp / mirrored-repeat wrapping).
TEXTURED_SAMPLER = {"magFilter": 9728, "minFilter": 9728, "wrapS": 33071, "wrapT": 33648}
#: The two nodes placing the one cube mesh (the second turned 90 degrees about +Y).
TEXTURED_NODES = [
    {"name": "cube_left", "mesh": 0, "translation": [-1.0, 0.0, 0.0]},
    {"name": "cube_right", "mesh": 0, "translation": [1.5, 0.25, 0.0],
     "rotation": [0.0, _SQRT_HALF, 0.0, _SQRT_HALF]},
]


def write_textured_gltf(path, binary: bool = True) -> list[Path]:
    """``seamed_cube`` with ``TEXTURED_MATERIAL`` (base colour, metallic-roughness, normal,
    occlusion and emissive textures, MASK alpha, double-sided) placed twice (``TEXTURED_NODES``,
    one mesh shared by two nodes). Images from ``textured_images()``: embedded as bufferViews in
    a ``.glb`` (``binary``), or PNG files ``<stem>_<name>.png`` beside a ``.gltf`` + ``.bin``.

    Returns the paths written (the glTF/GLB first).
    """
    path = Path(path)
    doc, blob = _gltf_document(seamed_cube(name="cube"), [dict(n) for n in TEXTURED_NODES], None)
    blob = bytearray(blob)
    images, written = [], []
    for name, data in textured_images().items():
        if binary:
            doc["bufferViews"].append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data)})
            blob.extend(data)
            blob.extend(b"\0" * (-len(blob) % 4))
            images.append({"name": name, "bufferView": len(doc["bufferViews"]) - 1, "mimeType": "image/png"})
        else:
            img_path = path.with_name(f"{path.stem}_{name}.png")
            written.append(_write_bytes(img_path, data))
            images.append({"name": name, "uri": img_path.name})
    doc["buffers"][0]["byteLength"] = len(blob)
    doc["meshes"][0]["primitives"][0]["material"] = 0
    doc.update(materials=[json.loads(json.dumps(TEXTURED_MATERIAL))], samplers=[dict(TEXTURED_SAMPLER)],
               textures=[{"sampler": 0, "source": i} for i in range(len(images))], images=images)
    if binary:
        return [_write_bytes(path, pack_glb(json.dumps(doc, separators=(",", ":")).encode("ascii"), bytes(blob)))]
    bin_path = path.with_suffix(".bin")
    doc["buffers"][0]["uri"] = bin_path.name
    return [_write_bytes(path, gltf_json_text(doc, sort_keys=False).encode("ascii")),
            _write_bytes(bin_path, bytes(blob))] + written
