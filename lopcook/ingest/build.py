"""One way for every loader to turn arrays into a ``MeshPart``: dtypes, unit normals, computed
normals where the source has none, and per-vertex attributes kept in step with vertex splits."""

from __future__ import annotations

import numpy as np

from ..settings import IngestSettings
from ..types import MeshPart, Texture
from .normals import compute_normals


def make_part(name: str, positions: np.ndarray, indices: np.ndarray, *, settings: IngestSettings,
              normals: np.ndarray | None = None, uvs: np.ndarray | None = None,
              colors: np.ndarray | None = None, source: str = "", texture: Texture | None = None,
              mesh_key: str = "") -> MeshPart:
    """Build a MeshPart from loader arrays.

    Parameters
    ----------
    positions : (n, 3) float, world metres +Y up (already transformed)
    indices : (m, 3) int, counter-clockwise (already flipped for mirrored transforms / leftHanded)
    normals : (n, 3) float or None; world space; renormalised here. None -> computed
        (area-weighted, split at creases sharper than ``settings.crease_angle_deg``), which may add
        vertices; uvs/colors follow the split.
    uvs : (n, 2) float or None, origin top-left
    colors : (n, 3|4) float or None, linear, alpha 1 added when missing
    """
    positions = np.ascontiguousarray(positions, dtype=np.float64)
    indices = np.ascontiguousarray(indices).astype(np.uint32, copy=False).reshape(-1, 3)
    computed = False
    if colors is not None and colors.shape[1] == 3:
        colors = np.concatenate([colors, np.ones((colors.shape[0], 1), colors.dtype)], axis=1)
    if normals is None and indices.size and positions.size and np.isfinite(positions).all() \
            and int(indices.max()) < positions.shape[0]:
        res = compute_normals(positions, indices, settings.crease_angle_deg)
        sv = res.source_vertex
        if sv.size != positions.shape[0] or not np.array_equal(sv, np.arange(sv.size)):
            positions = np.take(positions, sv, axis=0)  # row gathers: np.take is 2-3x faster than [sv]
            uvs = None if uvs is None else np.take(uvs, sv, axis=0)
            colors = None if colors is None else np.take(colors, sv, axis=0)
        indices = res.indices
        normals = res.normals
        computed = True
    elif normals is not None:
        normals = np.asarray(normals, dtype=np.float64)
        length = np.linalg.norm(normals, axis=1)
        bad = ~(length > 1e-20) | ~np.isfinite(length)
        normals = np.where(bad[:, None], np.array([0.0, 1.0, 0.0]), normals / np.where(bad, 1.0, length)[:, None])
    return MeshPart(
        name=name,
        positions=positions,
        indices=indices,
        normals=None if normals is None else np.ascontiguousarray(normals, dtype=np.float32),
        uvs=None if uvs is None else np.ascontiguousarray(uvs, dtype=np.float32),
        colors=None if colors is None else np.ascontiguousarray(colors, dtype=np.float32),
        source=source,
        normals_computed=computed,
        texture=texture,
        mesh_key=mesh_key,
    )


def unique_names(names: list[str]) -> list[str]:
    """Make names unique, deterministically: repeats get ``#2``, ``#3``, ... suffixes."""
    seen: dict[str, int] = {}
    out = []
    for n in names:
        n = n or "part"
        if n in seen:
            seen[n] += 1
            cand = f"{n}#{seen[n]}"
            while cand in seen:
                seen[n] += 1
                cand = f"{n}#{seen[n]}"
            seen[cand] = 1
            out.append(cand)
        else:
            seen[n] = 1
            out.append(n)
    return out
