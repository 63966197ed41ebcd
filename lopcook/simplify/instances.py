"""Parts that are one mesh placed several times: found by content, so that a LOD chain is
simplified once per distinct mesh and placed on every copy.

Scenes place one mesh many times (USD instances and references, glTF nodes sharing a mesh, a
chess set's pawns). lopcook's scene model is in world space, so
the copies differ in positions only. Two parts are **copies** when they have the same vertex count,
the same triangles (index arrays equal), the same attributes a placement does not change (UVs,
colours: bit for bit), and one affine map ``x -> A x + t`` takes every position of the first to the
second's within ``rtol`` of the part's extent (least squares over all vertices, then the largest
residual is checked), with ``A`` invertible, and the attributes a placement maps agree with their
codec's ``to_world`` (normals: ``A^-T n`` normalised) within ``NORMAL_TOL``.

A copy's LOD is the representative's LOD mapped by the same ``(A, t)`` (attributes by their
codec's ``to_world``; triangles, UVs and colours unchanged). Its error: when ``A`` is a similarity
(``A^T A = s^2 I``, rotation or reflection times a uniform scale s) distances scale by ``s``
exactly, so error_m = s * the representative's; otherwise the error is measured again
(``lod.hausdorff``). Mirrored placements whose importer reversed the winding have different index
arrays and are simplified on their own; so is anything the checks reject.
"""

from __future__ import annotations

import hashlib
import time
import weakref
from dataclasses import replace

import numpy as np

from ..lop.codecs import CODECS
from ..lop.codecs.normals_oct import NORMALS
from ..types import MeshPart
from .error import hausdorff
from .stop import StopRule, breach_text, limit, part_extent

#: largest position residual of the affine fit, relative to the part's bounding-box diagonal
RTOL = 1e-9
#: largest normal difference (unit vectors) between a copy and the mapped representative
NORMAL_TOL = 1e-4


def _digest(a: np.ndarray | None) -> str:
    return "-" if a is None else hashlib.sha1(np.ascontiguousarray(a).tobytes()).hexdigest()


def signature(part: MeshPart) -> tuple:
    """What copies must share exactly: vertex count, triangles, every attribute a placement does
    not map (UVs, colours: digests) and which mapped ones (normals) are present."""
    return (part.n_vertices, part.n_triangles, _digest(part.indices),
            *(_digest(part.attributes.get(c.name)) for c in CODECS if not c.placed),
            *(c.name in part.attributes for c in CODECS if c.placed))


def affine_map(rep: MeshPart, other: MeshPart, rtol: float = RTOL) -> tuple[np.ndarray, np.ndarray] | None:
    """``(A (3, 3), t (3,))`` with ``other.positions ~ rep.positions @ A.T + t`` (module doc), or None
    when ``other`` is not a copy of ``rep``."""
    if signature(rep) != signature(other) or rep.n_vertices < 4:
        return None
    p, q = np.asarray(rep.positions, np.float64), np.asarray(other.positions, np.float64)
    c = p.mean(axis=0)
    h = np.concatenate([p - c, np.ones((p.shape[0], 1))], axis=1)  # centred: a well-conditioned fit
    x, _, rank, sv = np.linalg.lstsq(h, q, rcond=None)
    if rank < 4 or sv[-1] <= 1e-9 * sv[0]:
        return None  # flat or degenerate: the map is not determined by the vertices
    a = x[:3].T
    t = x[3] - a @ c
    diag = float(np.linalg.norm(q.max(axis=0) - q.min(axis=0)))
    if not np.isfinite(a).all() or abs(np.linalg.det(a)) <= 1e-300:
        return None
    if float(np.abs(p @ a.T + t - q).max()) > rtol * max(diag, 1e-300):
        return None
    for c in CODECS:
        if c.placed and c.name in rep.attributes:
            if float(np.abs(c.to_world(rep.attributes[c.name], a) - other.attributes[c.name]).max()) > NORMAL_TOL:
                return None
    return a, t


def map_normals(normals: np.ndarray, a: np.ndarray) -> np.ndarray:
    """(n, 3) float32 unit normals mapped by the inverse transpose of ``a`` (``NORMALS.to_world``)."""
    return NORMALS.to_world(normals, a)


def similarity_scale(a: np.ndarray, rtol: float = 1e-9) -> float | None:
    """``s`` when ``a`` is s times an orthogonal matrix (distances scale by s), else None."""
    s2 = float(abs(np.linalg.det(a))) ** (2.0 / 3.0)
    if s2 <= 0 or float(np.abs(a.T @ a - s2 * np.eye(3)).max()) > rtol * s2:
        return None
    return float(np.sqrt(s2))


def place(part: MeshPart, a: np.ndarray, t: np.ndarray, like: MeshPart) -> MeshPart:
    """``part`` (a LOD of the representative) mapped by ``(a, t)``, named and sourced as ``like``
    (the copy it is placed on)."""
    return MeshPart(name=like.name, positions=np.ascontiguousarray(part.positions @ a.T + t, dtype=np.float64),
                    indices=part.indices,
                    attributes={c.name: c.to_world(part.attributes[c.name], a) for c in CODECS
                                if c.name in part.attributes},
                    source=like.source, normals_computed=like.normals_computed,
                    texture=like.texture, mesh_key=like.mesh_key, double_sided=like.double_sided)


#: a part is compared with at most this many groups of its signature (the affine fit is O(n) per
#: comparison; many same-topology parts that are not copies, e.g. deformed variants, stay linear)
MAX_CANDIDATES = 16


#: the last ``copies`` answer: (weak references to its parts, the answer). One cook asks for the
#: same parts several times (the default's decision, the LOD chains, the grouping, and every probe
#: of a search); the parts are not kept alive by it
_LAST: list = []


def copies(parts) -> list[tuple[int, list[tuple[int, np.ndarray, np.ndarray]]]]:
    """``parts`` grouped into copies: ``[(lead, [(i, A, t), ...]), ...]`` in part order, each lead
    the first part of its group and every member ``i`` a copy of it by ``x -> A x + t``
    (``affine_map``). A part that copies no earlier part leads a group of its own. Each part is
    tried against the first ``MAX_CANDIDATES`` groups with its signature. Asked again for the very
    same part objects (MeshParts are frozen), the last answer is returned (a fresh list; the
    arrays are shared, read-only)."""
    parts = list(parts)
    if _LAST and len(_LAST[0]) == len(parts) and all(r() is p for r, p in zip(_LAST[0], parts)):
        return [(lead, list(members)) for lead, members in _LAST[1]]
    out = _copies(parts)
    for _, members in out:
        for _, a, t in members:
            a.setflags(write=False)
            t.setflags(write=False)
    _LAST[:] = [[weakref.ref(p) for p in parts], [(lead, list(members)) for lead, members in out]]
    return out


def _copies(parts) -> list:
    """``copies`` without the memory of the last answer."""
    by_sig: dict = {}
    out: list = []
    for i, p in enumerate(parts):
        cands = by_sig.setdefault(signature(p), [])
        for lead, members in cands[:MAX_CANDIDATES]:
            m = affine_map(parts[lead], p)
            if m is not None:
                members.append((i, *m))
                break
        else:
            g = (i, [])
            cands.append(g)
            out.append(g)
    return out


def groups(parts) -> list[list[int]]:
    """``copies`` as index lists: ``[[lead, member, ...], ...]``."""
    return [[lead] + [i for i, _, _ in members] for lead, members in copies(parts)]


def placed_chain(lods: list, report, copy: MeshPart, a: np.ndarray, t: np.ndarray,
                 max_error_m: float | None = None, stop_rule: StopRule | None = None) -> tuple[list, object]:
    """The representative's chain ``(lods, report)`` (``lod.lod_chain``) placed on ``copy``:
    LOD 0 is ``copy`` itself, every other LOD ``place``d, errors scaled by the similarity scale or
    measured (module doc), the chain cut where an error exceeds the tighter of ``max_error_m`` and
    ``stop_rule``'s limit for the copy's extent (``lopcook.simplify.stop.limit``). Returns
    ``(lods, report)`` for the copy; where the copy keeps every LOD, the report's stop is the
    representative's (its dropped LOD's error scaled, or None when the map is not a similarity)."""
    t0 = time.perf_counter()
    s = similarity_scale(a)
    out = [replace(lods[0], part=copy, notes=list(lods[0].notes))]
    note = (f"copy of part {report.part!r}: its LODs placed by the affine map (scale {s:.6g}: errors scaled)"
            if s is not None else f"copy of part {report.part!r}: its LODs placed by the affine map (not a "
                                  "similarity: errors measured)")
    extent = part_extent(copy.positions)
    cap, breach = limit(extent, max_error_m, stop_rule)
    dropped = None if report.dropped is None else dict(
        report.dropped, error_m=None if s is None or report.dropped.get("error_m") is None
        else report.dropped["error_m"] * s)
    stop = (report.stop, report.stop_reason, dropped)
    for k, lod in enumerate(lods[1:], start=1):
        part = place(lod.part, a, t, copy)
        if s is not None:
            h, one = lod.hausdorff_m * s, (lod.one_sided_m[0] * s, lod.one_sided_m[1] * s)
            bound = lod.error_bound_m * s
        else:
            h, ab, ba = hausdorff(part, copy)
            one, bound = (ab, ba), h
        err = max(h, out[-1].error_m)
        if cap is not None and err > cap:
            stop = (breach, breach_text(breach, f"LOD {k}", lod.triangles, err, cap, extent, stop_rule),
                    {"triangles": int(lod.triangles), "error_m": float(err), "target_ratio": float(lod.target_ratio)})
            break
        out.append(replace(lod, part=part, hausdorff_m=h, error_m=err, one_sided_m=one, error_bound_m=bound,
                           seconds=0.0, notes=list(lod.notes)))
    rep = replace(report, part=copy.name, max_error_m=cap, notes=[note] + list(report.notes),
                  stop=stop[0], stop_reason=stop[1], dropped=stop[2], extent_m=extent,
                  lods=[lod.summary() for lod in out], seconds=time.perf_counter() - t0)
    return out, rep


__all__ = ["RTOL", "NORMAL_TOL", "MAX_CANDIDATES", "signature", "affine_map", "map_normals", "similarity_scale", "place", "copies", "groups", "placed_chain"]
