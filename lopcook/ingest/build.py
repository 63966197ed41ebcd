"""One way for every loader to turn arrays into a ``MeshPart``: dtypes, unit normals, computed
normals where the source has none, and per-vertex attributes kept in step with vertex splits."""

from __future__ import annotations

import io
import os
import stat
import warnings

import numpy as np
from PIL import Image, UnidentifiedImageError

from ..settings import IngestSettings
from ..types import MeshPart, Texture
from .normals import compute_normals


def make_part(name: str, positions: np.ndarray, indices: np.ndarray, *, settings: IngestSettings,
              normals: np.ndarray | None = None, uvs: np.ndarray | None = None,
              colors: np.ndarray | None = None, extra: dict | None = None, source: str = "",
              texture: Texture | None = None, mesh_key: str = "", double_sided: bool = False) -> MeshPart:
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
    extra : ``{codec name: (n, k) float}`` of any other attribute (``lopcook.lop.codecs``), world space
    """
    positions = np.ascontiguousarray(positions, dtype=np.float64)
    indices = np.ascontiguousarray(indices).astype(np.uint32, copy=False).reshape(-1, 3)
    computed = False
    if colors is not None and colors.shape[1] == 3:
        colors = np.concatenate([colors, np.ones((colors.shape[0], 1), colors.dtype)], axis=1)
    # (positions beyond MAX_COORDINATE, or not finite, are refused by Scene.validate with their own
    # message: their cross products would overflow into NaN normals first)
    others = {"uvs": uvs, "colors": colors, **(extra or {})}
    if normals is None and indices.size and positions.size and np.isfinite(positions).all() \
            and float(np.abs(positions).max()) <= MAX_COORDINATE and int(indices.max()) < positions.shape[0]:
        res = compute_normals(positions, indices, settings.crease_angle_deg)
        sv = res.source_vertex
        if sv.size != positions.shape[0] or not np.array_equal(sv, np.arange(sv.size)):
            positions = np.take(positions, sv, axis=0)  # row gathers: np.take is 2-3x faster than [sv]
            others = {k: None if v is None else np.take(v, sv, axis=0) for k, v in others.items()}
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
        attributes={k: np.ascontiguousarray(v, dtype=np.float32)
                    for k, v in {"normals": normals, **others}.items() if v is not None},
        source=source,
        normals_computed=computed,
        texture=texture,
        mesh_key=mesh_key,
        double_sided=bool(double_sided),
    )



def usable_tangents(tangents: np.ndarray | None, normals: np.ndarray | None, warn, what: str) -> np.ndarray | None:
    """Source tangents (n, 4) (xyz, handedness w) made usable, the one rule of every loader:
    dropped with a warning without normals (a tangent frame needs both); xyz of zero length or not
    finite replaced by a unit vector perpendicular to the normal, and w not +-1 snapped to its sign
    (0 to +1), each with one warning through ``warn``."""
    if tangents is None:
        return None
    if normals is None:
        warn(f"{what}: tangents without normals (a tangent frame needs both); tangents dropped")
        return None
    xyz, w = tangents[:, :3].astype(np.float64), tangents[:, 3].astype(np.float64)
    length = np.linalg.norm(xyz, axis=1)
    bad = ~(length > 1e-20) | ~np.isfinite(length)
    if bad.any():
        warn(f"{what}: {int(bad.sum())} tangents are zero or not finite (replaced by a direction "
             "perpendicular to the normal)")
        n = np.asarray(normals, np.float64)[bad]
        axis = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
        xyz[bad] = np.cross(n, axis)
    odd = ~np.isin(w, (-1.0, 1.0))
    if odd.any():
        warn(f"{what}: {int(odd.sum())} tangents have a handedness w other than +1 or -1 (read as its "
             "sign, 0 as +1)")
        w = np.where(w < 0.0, -1.0, 1.0)
    return np.concatenate([xyz, w[:, None]], axis=1)


def placed_tangents(tangents: np.ndarray, lin: np.ndarray, det: float) -> np.ndarray:
    """(n, 4) tangents under a placement whose linear part maps a row vector as ``v @ lin``
    ((3, 3); a glTF node's column-vector matrix passes its transpose): xyz mapped by ``lin``
    (tangents lie in the surface: not the inverse transpose) and made unit, w flipped where the
    placement mirrors (``det < 0``, where the winding is flipped too)."""
    xyz = tangents[:, :3] @ lin
    length = np.linalg.norm(xyz, axis=1, keepdims=True)
    xyz = xyz / np.where(length > 0, length, 1.0)
    return np.concatenate([xyz, tangents[:, 3:] * (-1.0 if det < 0 else 1.0)], axis=1)

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


# ---------------------------------------------------------------------------- hostile-input limits

from ..types import FLOAT32_RESOLUTION, MAX_COORDINATE, MAX_PARTS, MAX_TRIANGLES  # noqa: E402,F401 (re-exported)

#: Largest base-colour texture decoded, in pixels (8192 x 8192). Pillow's ``MAX_IMAGE_PIXELS`` is
#: set to this value, so a decompression bomb fails in every later decode too; ingest checks the
#: declared size before decoding and treats a larger image as unreadable (a warning; the parts
#: cook untextured).
MAX_TEXTURE_PIXELS = 8192 * 8192


def _set_pillow_limit() -> None:
    Image.MAX_IMAGE_PIXELS = MAX_TEXTURE_PIXELS


_set_pillow_limit()


def texture_problem(data: bytes) -> str | None:
    """Why the encoded image ``data`` cannot be used as a base-colour texture, or None when it
    decodes (fully: truncated files, bad chunk CRCs and corrupt compressed data are found) to an
    image of at most ``MAX_TEXTURE_PIXELS`` pixels that converts to RGBA. The reason is worded in
    the image's own terms (no Python exception names)."""
    if not data:
        return "the image is empty (0 bytes)"
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            img = Image.open(io.BytesIO(data))
            w, h = img.size
            if w < 1 or h < 1:
                return f"the image declares {w} x {h} pixels"
            if w * h > MAX_TEXTURE_PIXELS:
                return (f"the image declares {w} x {h} pixels, more than the {MAX_TEXTURE_PIXELS:,} "
                        "lopcook decodes")
            img.load()
            img.crop((0, 0, 1, 1)).convert("RGBA")
    except UnidentifiedImageError:
        return "the image cannot be identified (a corrupt header, or not a PNG, JPEG or other format Pillow reads)"
    except Image.DecompressionBombError:
        return f"the image is larger than the {MAX_TEXTURE_PIXELS:,} pixels lopcook decodes"
    except MemoryError:
        return "the image is too large to decode"
    except Exception as exc:  # noqa: BLE001 - Pillow raises many kinds for corrupt data
        text = " ".join(str(exc).split()) or "corrupt data"
        return f"the image is truncated or corrupt ({text[:120]})"
    return None


def checked_texture(name: str, data: bytes | None, warn, what: str) -> Texture | None:
    """``Texture(name, data)`` when ``data`` decodes (see ``texture_problem``); otherwise call
    ``warn`` with one line naming ``what`` and the reason, and return None (the parts using it
    cook untextured)."""
    if data is None:
        return None
    problem = texture_problem(data)
    if problem is not None:
        warn(f"{what}: {problem}; the parts using it have no texture")
        return None
    return Texture(name=name, data=data)


def regular_file_problem(path: str) -> str | None:
    """Why ``path`` must not be read as a sidecar file (missing, a directory, a device, a FIFO or a
    socket; symlinks are followed), or None for a regular file."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return "not found"
    except OSError as exc:
        return f"cannot be read ({exc.strerror or 'error'})"
    if stat.S_ISDIR(st.st_mode):
        return "is a directory"
    if not stat.S_ISREG(st.st_mode):
        return "is not a regular file (a device, FIFO or socket)"
    return None


def bad_path_characters(path: str) -> bool:
    """True when ``path`` holds a line break or a NUL: such a name cannot be written in a depfile
    (``lopcook.depfile.escape``), so ingest refuses it before anything is written."""
    return any(c in path for c in "\n\r\x00")
