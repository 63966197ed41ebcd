"""Pure measurements of ``lopcook bench``: vertex matching, position error, cracks, GPU bytes,
Pareto fronts and log-log slopes. numpy/scipy only; no files, no GL, no subprocesses.

Units: positions in metres (world space); errors are reported relative to the source scene's
bounding-box diagonal (dimensionless); bytes are bytes.
"""

from __future__ import annotations

import math

import numpy as np

#: Source neighbours examined per output vertex when several source vertices share its nearest
#: position (seams: co-located vertices with different normals / UVs).
MATCH_CANDIDATES = 8

# glTF componentType -> bytes
_COMPONENT_BYTES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}


def colocation_classes(positions: np.ndarray) -> np.ndarray:
    """(n,) int64 class id per vertex: vertices with bit-identical float positions share a class.

    positions : (n, 3) float, any dtype (compared after conversion to float64)."""
    p = np.ascontiguousarray(np.asarray(positions, np.float64))
    _, inverse = np.unique(p, axis=0, return_inverse=True)
    return inverse.reshape(-1).astype(np.int64)


def match_vertices(source_pos: np.ndarray, output_pos: np.ndarray, source_attr: np.ndarray | None = None,
                   output_attr: np.ndarray | None = None) -> np.ndarray:
    """For every output vertex the source vertex it came from: (m,) int64 indices into source_pos.

    The nearest source vertex by position (scipy ``cKDTree``); where several source vertices sit
    at exactly that position (a seam: co-located vertices that differ in normal or UV), the one
    whose attributes (``source_attr`` (n, k) / ``output_attr`` (m, k) float, e.g. normal and UV
    concatenated; NaN where absent, and absent columns are not compared) are closest. Exact while the output's position error is less than half the
    distance between distinct source positions; otherwise the error measured with this match is
    a lower bound of the true one."""
    from scipy.spatial import cKDTree  # heavy: imported by the one function that needs it

    src = np.asarray(source_pos, np.float64)
    out = np.asarray(output_pos, np.float64)
    k = int(min(MATCH_CANDIDATES, src.shape[0]))
    tree = cKDTree(src)
    _, idx = tree.query(out, k=k)
    idx = np.asarray(idx, np.int64).reshape(out.shape[0], k)
    if k == 1 or source_attr is None or output_attr is None:
        return idx[:, 0]
    first = src[idx[:, 0]]
    same = np.all(src[idx] == first[:, None, :], axis=2)  # (m, k): co-located with the nearest
    sa = np.asarray(source_attr, np.float64)
    oa = np.asarray(output_attr, np.float64)
    d = np.nansum((sa[idx] - oa[:, None, :]) ** 2, axis=2)  # NaN: attribute absent, not compared
    d = np.where(same, d, np.inf)
    return idx[np.arange(out.shape[0]), np.argmin(d, axis=1)]


def position_errors(source_pos: np.ndarray, output_pos: np.ndarray, match: np.ndarray, diagonal: float) -> dict:
    """Max and RMS of ``|output - source[match]|`` over output vertices, divided by ``diagonal``
    (metres, the source bounding-box diagonal). Returns {"max_rel", "rms_rel", "vertices"}."""
    d = np.linalg.norm(np.asarray(output_pos, np.float64) - np.asarray(source_pos, np.float64)[match], axis=1)
    if d.size == 0:
        return {"max_rel": float("nan"), "rms_rel": float("nan"), "vertices": 0}
    diag = float(diagonal) if diagonal > 0 else 1.0
    return {"max_rel": float(d.max() / diag), "rms_rel": float(math.sqrt(float(np.mean(d * d))) / diag),
            "vertices": int(d.size)}


def count_cracks(source_class: np.ndarray, source_part: np.ndarray, output_pos: np.ndarray,
                 match: np.ndarray) -> dict:
    """Cracks: co-located source positions whose output vertices decode to different points.

    source_class : (n,) int64 co-location class per source vertex (``colocation_classes`` of all
    parts' positions concatenated); source_part : (n,) int part index per source vertex;
    output_pos : (m, 3) decoded output positions; match : (m,) source vertex per output vertex.

    Returns {"cracks": classes whose output vertices take more than one position,
    "cracks_between_parts": those of them whose source vertices lie in two or more parts,
    "shared_between_parts": classes spanning two or more parts (the places a crack can open)}."""
    source_class = np.asarray(source_class, np.int64)
    source_part = np.asarray(source_part, np.int64)
    n_cls = int(source_class.max()) + 1 if source_class.size else 0
    # classes spanning parts: distinct (class, part) pairs per class
    cp = np.unique(np.stack([source_class, source_part], axis=1), axis=0)
    parts_per_class = np.bincount(cp[:, 0], minlength=n_cls)
    multi_part = parts_per_class > 1
    cls = source_class[np.asarray(match, np.int64)]
    pos = np.ascontiguousarray(np.asarray(output_pos, np.float64))
    rows = np.concatenate([cls[:, None].astype(np.float64), pos], axis=1)
    uniq = np.unique(rows, axis=0)
    distinct = np.bincount(uniq[:, 0].astype(np.int64), minlength=n_cls)
    cracked = distinct > 1
    return {"cracks": int(cracked.sum()), "cracks_between_parts": int((cracked & multi_part).sum()),
            "shared_between_parts": int(multi_part.sum())}


def gltf_position_bytes(gltf: dict) -> tuple[int, int]:
    """GPU-resident bytes of every mesh primitive's POSITION stream and its vertex count, from a
    glTF JSON dict: per accessor, count x (element size rounded up to 4 bytes), the vertex
    attribute alignment of glTF 2.0 (float32: 12, 16-bit: 8, 8-bit: 4 bytes per vertex). The same
    holds in an interleaved view (the position's share of the stride) and after
    EXT_meshopt_compression decoding. Accessors used by several primitives count once.
    Returns (bytes, vertices)."""
    accessors = gltf.get("accessors", [])
    seen = set()
    total = verts = 0
    for mesh in gltf.get("meshes", []):
        for prim in mesh.get("primitives", []):
            a = prim.get("attributes", {}).get("POSITION")
            if a is None or a in seen:
                continue
            seen.add(a)
            acc = accessors[a]
            elem = 3 * _COMPONENT_BYTES[int(acc["componentType"])]
            total += int(acc["count"]) * (4 * ((elem + 3) // 4))
            verts += int(acc["count"])
    return total, verts


def pareto_front(cost, quality) -> np.ndarray:
    """Indices of the points not dominated by another (lower or equal cost and higher or equal
    quality, one of them strict), sorted by increasing cost. cost, quality : (n,) float; points
    with a NaN are never on the front; +inf quality (identical images) is the best quality."""
    c = np.asarray(cost, np.float64)
    q = np.asarray(quality, np.float64)
    ok = np.flatnonzero(~(np.isnan(c) | np.isnan(q)))
    if ok.size == 0:
        return np.zeros(0, np.int64)
    order = ok[np.lexsort((-q[ok], c[ok]))]  # by cost, then best quality first
    front, best = [], -np.inf
    for i in order:  # one pass over the (few) configurations, not over vertices
        if q[i] > best:
            front.append(int(i))
            best = q[i]
    return np.asarray(front, np.int64)


def loglog_slope(x, y) -> tuple[float, float]:
    """Least-squares fit of log10(y) = slope * log10(x) + intercept over the positive pairs.
    Returns (slope, intercept); NaNs when fewer than two usable points."""
    x = np.asarray(x, np.float64)
    y = np.asarray(y, np.float64)
    ok = (x > 0) & (y > 0) & np.isfinite(x) & np.isfinite(y)
    if int(ok.sum()) < 2 or np.unique(x[ok]).size < 2:
        return float("nan"), float("nan")
    slope, intercept = np.polyfit(np.log10(x[ok]), np.log10(y[ok]), 1)
    return float(slope), float(intercept)


__all__ = ["MATCH_CANDIDATES", "colocation_classes", "match_vertices", "position_errors", "count_cracks",
           "gltf_position_bytes", "pareto_front", "loglog_slope"]


def attribute_features(normals, uvs, n: int) -> np.ndarray:
    """(n, 5) float64 per-vertex features compared between a peer's output and the source: normal
    (3) and UV (2), NaN where absent (not compared)."""
    a = np.full((n, 5), np.nan)
    if normals is not None:
        a[:, :3] = normals
    if uvs is not None:
        a[:, 3:] = uvs
    return a

