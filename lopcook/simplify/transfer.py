"""Attribute transfer from LOD 0 to a simplified mesh: closest-point barycentric interpolation of
normals, UVs and colours, with corners re-split where LOD 0 has a crease or seam
(see ``lopcook.simplify.chain`` for the contract)."""

from __future__ import annotations

import numpy as np

from ..lop.codecs import BY_NAME, CODECS
from ..mesh import face_normals, stable_argsort, unique_rows, weld_labels
from ..types import MeshPart
from .backends import Work
from .reference import Reference, point_mesh
from .types import BackendFailure, BackendResult
from .topology import signed_volume


#: a face whose normal is more than 120 degrees from LOD 0's nearby faces is flipped
FLIP_COS = -0.5

#: corners look for their side of a seam this fraction of the way towards the face centroid
NUDGE = 0.25


#: corners per step of the transfer's side test (bounds its (k, 3, 3) temporaries)
TRANSFER_CHUNK = 1 << 17


def barycentric(points: np.ndarray, tri: np.ndarray, clamp: bool) -> np.ndarray:
    """(q, 3) barycentric coordinates of ``points`` projected on triangles ``tri`` (q, 3, 3);
    clamped to the triangle (negative weights set to 0, renormalised) when ``clamp``. Degenerate
    triangles get (1/3, 1/3, 1/3)."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    v0, v1, v2 = b - a, c - a, points - a
    d00 = (v0 * v0).sum(1)
    d01 = (v0 * v1).sum(1)
    d11 = (v1 * v1).sum(1)
    d20 = (v2 * v0).sum(1)
    d21 = (v2 * v1).sum(1)
    den = d00 * d11 - d01 * d01
    ok = den > 1e-30 * np.maximum(d00 * d11, 1e-300)
    safe = np.where(ok, den, 1.0)
    v = (d11 * d20 - d01 * d21) / safe
    w = (d00 * d21 - d01 * d20) / safe
    bary = np.stack([1.0 - v - w, v, w], axis=1)
    bary = np.where(ok[:, None], bary, 1.0 / 3.0)
    if clamp:
        bary = np.clip(bary, 0.0, None)
        s = bary.sum(1, keepdims=True)
        bary = np.where(s > 0, bary / np.where(s > 0, s, 1.0), 1.0 / 3.0)
    return bary


def interpolate(values: np.ndarray, ref: Reference, face: np.ndarray, bary: np.ndarray) -> np.ndarray:
    corners = ref.faces[face]  # (q, 3) vertex ids
    return np.einsum("qk,qkd->qd", bary, values[corners].astype(np.float64))


#: corner values farther than this from their vertex's value belong to another side of a seam or
#: crease: (normal angle in degrees, UV distance, colour distance)
SPLIT_NORMAL_DEG = 30.0


SPLIT_UV = 5e-3


SPLIT_COLOR = 0.02


def _direction_fix(val: np.ndarray, fallback_normal: np.ndarray) -> np.ndarray:
    """A blended direction made unit again (``fallback_normal``, LOD 0's face normal, where the
    blend vanishes); components after the third (a handedness) snapped to +-1."""
    xyz = val[:, :3]
    ln = np.linalg.norm(xyz, axis=1)
    xyz = np.where((ln > 1e-6)[:, None], xyz / np.where(ln > 1e-6, ln, 1.0)[:, None], fallback_normal)
    if val.shape[1] == 3:
        return xyz
    return np.concatenate([xyz, np.where(val[:, 3:] >= 0.0, 1.0, -1.0)], axis=1)


def attributes_at(ref: Reference, names: list, face: np.ndarray, bary: np.ndarray,
                   fallback_normal: np.ndarray) -> dict:
    """LOD 0's attributes ``names`` interpolated at (face, bary), made valid by their codec's
    error model: directions unit (LOD 0's face normal where the interpolation vanishes), colours
    clipped."""
    out = {}
    src = ref.part
    for name in names:
        val = interpolate(src.attributes[name], ref, face, bary)
        model = BY_NAME[name].error_model
        if model == "direction":
            val = _direction_fix(val, fallback_normal)
        elif model == "color":
            val = np.clip(val, 0.0, 1.0)
        out[name] = val
    return out


def _extra_differs(va: np.ndarray, vb: np.ndarray) -> np.ndarray:
    """Rows whose components after the third (a direction's handedness) differ."""
    return (va[:, 3:] != vb[:, 3:]).any(axis=1) if va.shape[1] > 3 else np.zeros(va.shape[0], dtype=bool)


def differs(a: dict, b: dict) -> np.ndarray:
    """Rows where any attribute of ``a`` and ``b`` is beyond its split tolerance: directions more
    than ``SPLIT_NORMAL_DEG`` apart (or of another handedness), texture coordinates ``SPLIT_UV``,
    colours ``SPLIT_COLOR`` (largest component difference)."""
    bad = None
    for name, va in a.items():
        vb = b[name]
        model = BY_NAME[name].error_model
        if model == "direction":
            d = np.einsum("ij,ij->i", va[:, :3], vb[:, :3]) < np.cos(np.radians(SPLIT_NORMAL_DEG))
            d |= _extra_differs(va, vb)
        elif model == "texcoord":
            d = np.abs(va - vb).max(axis=1) > SPLIT_UV
        else:
            d = np.abs(va - vb).max(axis=1) > SPLIT_COLOR
        bad = d if bad is None else bad | d
    return bad


def key_order(names) -> list:
    """Attribute names in the order their bits key vertices: texture coordinates first, then the
    others in record order (``CODECS``)."""
    return sorted(names, key=lambda n: (BY_NAME[n].error_model != "texcoord", CODECS.index(BY_NAME[n])))


def exact_sources(ref: Reference, points: np.ndarray):
    """LOD 0 vertices at exactly the positions ``points`` (k, 3), or None when some point is not
    exactly a vertex of LOD 0.

    Only vertices that LOD 0's (non-degenerate) faces reference count. Returns ``(count, start,
    order)``: point i is bit for bit the position of the ``count[i] >= 1`` LOD 0 vertices
    ``order[start[i]:start[i] + count[i]]`` (more than one where LOD 0 has a seam or crease there:
    co-located vertices with different attributes). meshoptimizer's output vertices are input
    vertices, so along a chain of meshoptimizer LODs every LOD vertex is a LOD 0 vertex; positions
    moved by pymeshlab or fast-simplification are not, and those results take the closest-point
    transfer."""
    used = ref.sample_vertices
    k = points.shape[0]
    lab, n_lab = weld_labels(np.concatenate([ref.positions[used], points]), np.int64)
    lab_ref, lab_q = lab[:used.size], lab[used.size:]
    count_of = np.bincount(lab_ref, minlength=n_lab)
    count = count_of[lab_q]
    if k and int(count.min()) == 0:
        return None
    order = used[stable_argsort(lab_ref)[0]]
    first_of = np.zeros(n_lab, dtype=np.int64)
    np.cumsum(count_of[:-1], out=first_of[1:])
    return count, first_of[lab_q], order


#: candidate scores of a co-located LOD 0 vertex: attribute distances in units of the split
#: tolerances (a normal 30 degrees off, a UV 5e-3 off, a colour 0.02 off each score 1)
def _attribute_distance(names: list, cand: dict, ext: dict) -> np.ndarray:
    score = None
    for name in names:
        a, b = cand[name].astype(np.float64), ext[name]
        model = BY_NAME[name].error_model
        if model == "direction":
            d = (1.0 - np.einsum("ij,ij->i", a[:, :3], b[:, :3])) / (1.0 - np.cos(np.radians(SPLIT_NORMAL_DEG)))
            if a.shape[1] > 3:
                d = d + _extra_differs(a, b)
        else:
            d = np.abs(a - b).max(axis=1) / (SPLIT_UV if model == "texcoord" else SPLIT_COLOR)
        score = d if score is None else score + d
    return score


def exact_corner_sources(ref: Reference, names: list, P: np.ndarray, F: np.ndarray, centroid: np.ndarray,
                         found, corner_uvs: np.ndarray | None = None) -> np.ndarray:
    """(3m,) the LOD 0 vertex whose attributes each face corner of (P, F) copies, for a result
    whose every vertex is a LOD 0 vertex (``found = exact_sources(ref, P)``).

    A vertex with one LOD 0 vertex at its position: that one, for all its corners. Where several
    LOD 0 vertices share the position (a seam or crease of LOD 0), the corner's side is LOD 0's
    face nearest to the point ``NUDGE`` of the way from the vertex towards the LOD face's centroid
    (one closest-point query per such corner): a candidate that is a corner of that face, else the
    candidate whose attributes are nearest to that face's attribute field extrapolated to the
    vertex (ties: the lowest LOD 0 index). ``corner_uvs`` (3m, 2): the UVs the corners already
    have (the backend's, copied from the input vertex they are): only a candidate with the same
    UV bits is then chosen where one exists, so all of a corner's attributes come from one LOD 0
    vertex."""
    count, start, order = found
    vid = F.ravel()
    src = order[start[vid]]  # the only candidate, or the first of several
    amb = np.flatnonzero(count[vid] > 1)
    if amb.size == 0 or not names:
        return src
    face_of_corner = amb // 3
    pv = P[vid[amb]]
    g2 = ref.query_near(pv + NUDGE * (centroid[face_of_corner] - pv),
                           (NUDGE ** 2) * np.einsum("ij,ij->i", centroid[face_of_corner] - pv,
                                                    centroid[face_of_corner] - pv))[1]
    ext = attributes_at(ref, names, g2, barycentric(pv, ref.positions[ref.faces[g2]], clamp=False),
                        ref.face_unit[g2])
    c = count[vid[amb]]
    pair = np.repeat(np.arange(amb.size), c)  # (corner, candidate) pairs
    offs = np.arange(pair.size) - np.repeat(np.cumsum(c) - c, c)
    cand = order[start[vid[amb]][pair] + offs]
    score = _attribute_distance(names, {n: ref.part.attributes[n][cand] for n in names},
                                {n: v[pair] for n, v in ext.items()})
    incident = (ref.faces[g2[pair]] == cand[:, None]).any(axis=1)
    score = np.where(incident, -1.0, score)
    if corner_uvs is not None and ref.part.uvs is not None:
        same_uv = (_bits(ref.part.uvs[cand]) == _bits(corner_uvs[amb][pair])).all(axis=1)
        score = score + np.where(same_uv, 0.0, 1e6)
    best = np.lexsort((cand, score, pair))  # per corner: lowest score, then lowest id
    head = np.r_[True, pair[best][1:] != pair[best][:-1]]
    src[amb] = cand[best[head]]
    return src


def _bits(values: np.ndarray) -> np.ndarray:
    """int64 columns of float32 bit patterns (``-0.0`` as ``0.0``), the vertex keys' form."""
    return (np.ascontiguousarray(values, dtype=np.float32) + np.float32(0.0)).view(np.int32).astype(np.int64)


def _exact_vertex_key(vid: np.ndarray, srcv, found, corner_attr: dict, names: list):
    """``unique_rows`` of the corners' (vertex, attribute bits) rows for an exact copy, through a
    two-column integer key: ``(first, inverse)`` equal to the generic key's, or None when it does
    not apply (per-corner UVs that are not a function of the vertex).

    Corners of a vertex with one LOD 0 vertex at its position copy the same values; at co-located
    vertices the copied LOD 0 vertex is replaced by the first one of the same vertex with the same
    attribute bits, so equal rows get equal keys."""
    if "uvs" in corner_attr and "uvs" not in names:  # the backend's per-corner UVs
        uvb = _bits(corner_attr["uvs"])
        per_vertex = np.zeros((int(vid.max()) + 1, 2), dtype=np.int64)
        per_vertex[vid] = uvb
        if not (per_vertex[vid] == uvb).all():
            return None
    if srcv is None:
        return unique_rows(vid.reshape(-1, 1).astype(np.int64))
    count = found[0]
    canon = srcv.copy()
    amb = np.flatnonzero(count[vid] > 1)
    if amb.size:
        first, inv = unique_rows(np.concatenate([vid[amb].reshape(-1, 1).astype(np.int64)]
                                                + [_bits(corner_attr[n][amb]) for n in names], axis=1))
        canon[amb] = srcv[amb][first][inv]
    key = vid.astype(np.int64)
    key *= int(canon.max()) + 1
    key += canon
    del canon
    return unique_rows(key.reshape(-1, 1))


def transfer_attributes(res: BackendResult, ref: Reference, input_part: MeshPart, work: Work, mode: str,
              max_flipped_fraction: float, exact: bool = True) -> tuple[MeshPart, dict]:
    """Attributes for the cleaned backend result; flip check; LOD -> LOD 0 distance.

    **Exact copy** (``exact`` and every result vertex bit for bit a LOD 0 vertex, as with
    meshoptimizer: ``exact_sources``): each face corner copies the normals, colours and
    (transferred) UVs of one LOD 0 vertex at its position, bit for bit (``exact_corner_sources``
    picks among co-located LOD 0 vertices); the LOD -> LOD 0 distance is exactly 0 at the vertices,
    so only the face centroids are queried and ``lod_to_ref`` is their largest distance.
    ``info["on_ref"]``: (LOD 0 vertices,) bool, True at LOD 0 vertices known to be vertices of the
    LOD (those the exact copy read; ``error.sampled_ref_to_lod`` needs no query for them), None
    for the closest-point transfer.

    **Closest-point transfer** (otherwise; ``exact=False`` forces it, for comparisons): every LOD
    vertex takes LOD 0's attributes at its closest point. A face corner whose own side
    (LOD 0's face nearest to the face centroid, refined by a query pulled ``NUDGE`` of the way from
    the corner towards the centroid) gives clearly different values at the vertex (beyond the
    ``_SPLIT_*`` tolerances: another side of a seam or crease) gets those values instead; corners
    of one vertex that land in the same LOD 0 region share one value."""
    P, F = res.positions, res.faces
    m = F.shape[0]
    found, centroid, fc, near, lod_to_ref = _distances(ref, P, F, exact)
    flipped = _flipped_faces(ref, P, F, centroid, fc, found is not None)
    if flipped > max_flipped_fraction * m and flipped > 0:
        raise BackendFailure(f"{flipped} of {m} faces are flipped against the source surface")
    if ref.defects["closed"] and abs(ref.volume) > 0:
        vol = signed_volume(P, F)
        if np.sign(vol) != np.sign(ref.volume):
            raise BackendFailure("the closed mesh's signed volume changed sign (inside out)")

    src = ref.part
    names = [c.name for c in CODECS if c.error_model != "texcoord" and c.name in src.attributes]
    uv_from_ref = src.uvs is not None and mode != "xatlas" and res.wedge_uvs is None and not (
        mode == "lock" and res.vertex_source is not None and work.region is not None)
    if uv_from_ref:
        names.append("uvs")
    vid = F.ravel()
    corner_attr, srcv, first, group = {}, None, None, None
    if found is not None:
        if names:
            wedge = (res.wedge_uvs.reshape(-1, 2).astype(np.float32) if res.wedge_uvs is not None
                     and src.uvs is not None and not uv_from_ref and mode != "xatlas" else None)
            srcv = exact_corner_sources(ref, names, P, F, centroid, found, wedge)
            corner_attr = {n: np.ascontiguousarray(src.attributes[n][srcv], dtype=np.float32) for n in names}
    elif names:
        corner_attr, first, group = _closest_point_corners(ref, names, P, F, centroid, fc, near)
    per_group = bool(names) and found is None  # every attribute so far is a function of the corner's group
    if src.uvs is not None and mode != "xatlas" and not uv_from_ref:
        if per_group:
            corner_attr = {n: v[group] for n, v in corner_attr.items()}
            per_group = False
        if res.wedge_uvs is not None:
            corner_attr["uvs"] = res.wedge_uvs.reshape(-1, 2).astype(np.float32)
        else:
            corner_attr["uvs"] = lock_uvs(res, input_part, work)[vid]
    vfirst, vinv, pick = _lod_vertices(vid, corner_attr, srcv, found, names, first, group, per_group)
    out = MeshPart(
        name=input_part.name,
        positions=np.ascontiguousarray(P[vid[vfirst]], dtype=np.float64),
        indices=vinv.reshape(m, 3).astype(np.uint32),
        attributes={n: v[pick] for n, v in corner_attr.items()},
        source=input_part.source,
        normals_computed=input_part.normals_computed,
        texture=input_part.texture,
        mesh_key=input_part.mesh_key,
        double_sided=input_part.double_sided,
    )
    on_ref = None
    if found is not None:  # the LOD 0 vertices the corners copy lie on the LOD: at distance 0
        on_ref = np.zeros(ref.positions.shape[0], dtype=bool)
        on_ref[srcv if srcv is not None else found[2][found[1][vid]]] = True
    return out, {"lod_to_ref": lod_to_ref, "flipped": flipped, "on_ref": on_ref}


def _distances(ref: Reference, P: np.ndarray, F: np.ndarray, exact: bool) -> tuple:
    """``transfer_attributes``' queries of LOD 0: ``(found, centroids (m, 3), LOD 0 face nearest
    each centroid (m,), near, LOD -> LOD 0 distance in metres)``. ``found``: ``exact_sources``
    (every vertex a LOD 0 vertex) or None; ``near``: None for an exact copy, else (LOD 0 face
    nearest each vertex (k,), the closest points of the vertices and centroids (k + m, 3))."""
    m, k = F.shape[0], P.shape[0]
    found = exact_sources(ref, P) if exact else None
    if found is not None:
        # every vertex is a LOD 0 vertex (meshoptimizer): at distance 0, attributes copied; only
        # the face interiors (centroids) are queried. Row-wise temporaries only ((m, 3), no (m, 3, 3)).
        centroid = P[F[:, 0]] + P[F[:, 1]]
        centroid += P[F[:, 2]]
        centroid /= 3.0
        # a vertex of the face lies on LOD 0: its distance bounds the centroid's
        bound = np.full(m, np.inf)
        for j in range(3):
            gap = centroid - P[F[:, j]]
            np.minimum(bound, np.einsum("ij,ij->i", gap, gap), out=bound)
        del gap
        d2, fc, _ = ref.query_bounded(centroid, bound, closest=False)
        del bound, _
        near = None
    else:
        tri = P[F]
        centroid = tri.mean(axis=1)
        del tri
        d2, fid, closest = ref.query_any(np.concatenate([P, centroid]))
        fc = fid[k:]
        near = (fid[:k], closest)
    return found, centroid, fc, near, float(np.sqrt(d2.max()))


def _flipped_faces(ref: Reference, P: np.ndarray, F: np.ndarray, centroid: np.ndarray, fc: np.ndarray,
                   on_ref: bool) -> int:
    """Faces facing away (more than 120 degrees) from LOD 0's nearest face at the centroid and at 2
    of the 3 points half-way to the corners (one sample alone is fooled where a coarse face cuts a
    sharp edge or lies between two sheets). ``on_ref``: every vertex lies on LOD 0."""
    unit = face_normals(P, F)
    fl = np.linalg.norm(unit, axis=1)
    unit /= np.where(fl > 0, fl, 1.0)[:, None]
    del fl
    cand = np.flatnonzero(np.einsum("ij,ij->i", unit, ref.face_unit[fc]) < FLIP_COS)
    if not cand.size:
        return 0
    tri_c = P[F[cand]]
    half = 0.5 * (tri_c + centroid[cand][:, None, :])  # (c, 3, 3)
    if on_ref:  # half-way to a corner that lies on LOD 0
        hb = 0.25 * ((tri_c - centroid[cand][:, None, :]) ** 2).sum(axis=2)
        fh = ref.query_near(half.reshape(-1, 3), hb.reshape(-1))[1].reshape(-1, 3)
    else:
        fh = ref.query_any(half.reshape(-1, 3))[1].reshape(-1, 3)
    votes = (np.einsum("ij,ikj->ik", unit[cand], ref.face_unit[fh]) < FLIP_COS).sum(axis=1)
    return int((votes >= 2).sum())


def _closest_point_corners(ref: Reference, names: list, P: np.ndarray, F: np.ndarray, centroid: np.ndarray,
                           fc: np.ndarray, near: tuple) -> tuple[dict, np.ndarray, np.ndarray]:
    """The closest-point transfer's corner values (``transfer_attributes`` doc): ``({name: value per
    group}, first corner of each group, group of each corner)``; a group is a vertex and, for a
    corner on another side of a seam or crease, the LOD 0 region of that side."""
    m, k = F.shape[0], P.shape[0]
    fv, closest = near
    vid = F.ravel()
    face_of_corner = np.repeat(np.arange(m), 3)
    bary_v = barycentric(closest[:k], ref.positions[ref.faces[fv]], clamp=True)
    at_v = attributes_at(ref, names, fv, bary_v, ref.face_unit[fv])
    # phase 1: the corner's side = LOD 0's face nearest to the LOD face's centroid. That face's
    # attribute field, extrapolated linearly to the vertex, matches the vertex's own value on a
    # smooth field and differs across a seam or crease.
    g = fc[face_of_corner]
    split = np.empty(vid.size, dtype=bool)
    for s0 in range(0, vid.size, TRANSFER_CHUNK):  # row-wise: (chunk, 3, 3) temporaries only
        sl = slice(s0, s0 + TRANSFER_CHUNK)
        gs, vs = g[sl], vid[sl]
        ext = attributes_at(ref, names, gs, barycentric(P[vs], ref.positions[ref.faces[gs]], clamp=False),
                             ref.face_unit[gs])
        split[sl] = differs({n: at_v[n][vs] for n in names}, ext)
        del ext
    cs = np.flatnonzero(split)
    at2 = {}
    if cs.size:
        # phase 2: only for corners that look split, find their side near the corner itself
        q = P[vid[cs]]
        q = q + NUDGE * (centroid[face_of_corner[cs]] - q)
        g2 = ref.query_any(q)[1]
        g[cs] = g2
        pv_cs = P[vid[cs]]
        tri2 = ref.positions[ref.faces[g2]]
        ext2 = attributes_at(ref, names, g2, barycentric(pv_cs, tri2, clamp=False), ref.face_unit[g2])
        split[cs] = differs({n: at_v[n][vid[cs]] for n in names}, ext2)
        # the value of a split corner: its side's field at the vertex, kept inside that face
        at2 = attributes_at(ref, names, g2, barycentric(pv_cs, tri2, clamp=True), ref.face_unit[g2])
    # corners that agree with their vertex share its value; the others group by LOD 0 region
    region = np.where(split, ref.region[g], -1)
    first, group = unique_rows(np.stack([vid, region], axis=1))
    own = ~split[first]
    not_own = np.flatnonzero(~own)
    at_split = np.searchsorted(cs, first[not_own])  # a corner still split after phase 2 is in cs
    corner_attr = {}
    for n in names:
        val = at_v[n][vid[first]]
        if not_own.size:
            val[not_own] = at2[n][at_split]
        if BY_NAME[n].error_model == "direction":
            val = val.copy()
            val[:, :3] = val[:, :3] / np.linalg.norm(val[:, :3], axis=1, keepdims=True)
        corner_attr[n] = val.astype(np.float32)  # per group; per corner: [group]
    return corner_attr, first, group


def _lod_vertices(vid: np.ndarray, corner_attr: dict, srcv, found, names: list, first, group,
                  per_group: bool) -> tuple:
    """The LOD's vertices: corners with equal (vertex, attribute bits) rows are one vertex.
    ``(first corner of each vertex, vertex of each corner, row of each vertex in corner_attr)``."""
    def unique_vertices(row_vid: np.ndarray):
        keys = [row_vid.reshape(-1, 1).astype(np.int64)]
        for name in key_order(corner_attr):
            if name in corner_attr:
                keys.append((np.ascontiguousarray(corner_attr[name]) + np.float32(0.0)).view(np.int32)
                            .astype(np.int64))
        return unique_rows(np.concatenate(keys, axis=1))

    exact_key = _exact_vertex_key(vid, srcv, found, corner_attr, names) if found is not None else None
    if exact_key is not None:
        vfirst, vinv = exact_key
        return vfirst, vinv, vfirst
    if per_group:
        # corners of one group share their row, and groups are numbered by first appearance, so
        # the unique rows of the groups, numbered by first appearance, are those of the corners
        gfirst, ginv = unique_vertices(vid[first])
        return first[gfirst], ginv[group], gfirst
    vfirst, vinv = unique_vertices(vid)
    return vfirst, vinv, vfirst


def lock_uvs(res: BackendResult, input_part: MeshPart, work: Work) -> np.ndarray:
    """Per output vertex UVs for ``fast`` with locked seams: interpolate the input's UVs at the
    closest point when that point lies in the vertex's own UV island (known from the collapse map),
    else copy the UV of the input vertex it came from."""
    src = res.vertex_source
    P = res.positions
    d2, fid, closest = point_mesh(P, work.positions, work.faces)
    island_of_face = work.region[work.faces[:, 0]]
    own = work.region[src]
    ok = island_of_face[fid] == own
    bary = barycentric(closest, work.positions[work.faces[fid]], clamp=True)
    interp = np.einsum("qk,qkd->qd", bary, work.uvs[work.faces[fid]])
    # a vertex that did not move (seam and border vertices are locked) keeps its UV bit for bit
    unmoved = (P == work.positions[src]).all(axis=1)
    return np.where((ok & ~unmoved)[:, None], interp, work.uvs[src]).astype(np.float32)
