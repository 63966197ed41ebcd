"""Materials, textures and instancing for decoded previews (``lopcook decode``, docs/format.md 9.2).

A ``.lop`` container stores geometry only. To make a decoded preview look like the source in any
glTF viewer, ``decode`` reads the materials again from the *source* asset, without changing the
container:

* ``find_source(container_path, manifest, given)``: the source file to read. ``given`` (``decode
  --source``) or, by default, where the cook recorded it (the manifest's ``source.path``,
  relative to the container's folder), then the manifest's ``source.file`` beside the container.
  It is used only when its sha256 equals the manifest's ``source.sha256``; otherwise the preview
  is geometry only and the reason is one line (``None, reason``). ``recorded_source_path`` is
  the rule ``source.path`` is written by.
* ``source_materials(path, fmt, parts, ...)``: one glTF 2.0 core material per manifest part (or
  None: the default material), with the textures, samplers and images it uses, as
  ``lopcook.emit.gltf_writer.write_gltf(materials=...)`` takes them. The source format's own
  material reader (``Format.materials`` of ``lopcook.ingest.FORMATS``, found by the manifest's
  ``source.format``) reads them; what each format carries is documented there.
* ``instance_nodes(c, lods, meshes, keys)``: parts that are copies of one mesh (the same
  ``mesh_key`` and material, identical indices, UVs and colours at the decoded LOD) become
  nodes sharing the lead's mesh, each with a TRS transform. The transform is fitted (least
  squares, then projected on rotation x per-axis scale) between the lead's and the copy's
  positions decoded at level 24, and used only when it reproduces the copy's level-24 positions
  within ``INSTANCE_TOL_STEPS`` cells of the 24-bit grid; otherwise the copy keeps its own mesh.
  A copy then shows the *lead's* quantization at level B moved by the transform, not its own:
  ``max_instancing_offset_m`` reports the largest distance between the two (docs/format.md).

Everything is deterministic: the same container, source and options give the same bytes.
"""

from __future__ import annotations

import hashlib
import os
import struct

import numpy as np

from ..ingest import format_of
from ..ingest.materials import MaterialSet, resolve_vertex_colour_base, untextured
from ..lop.manifest import recorded_source_path
from ..lop.reader import decode_positions

#: A copy becomes an instance only if the fitted transform reproduces its level-24 positions within
#: this many cells of the 24-bit grid (the decode itself is exact to half a cell).
INSTANCE_TOL_STEPS = 8


def _sha256(path: str) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


# ---------------------------------------------------------------------------------------------
# Which source
# ---------------------------------------------------------------------------------------------


def _recorded(container_path: str, manifest: dict) -> str | None:
    """Where the manifest's ``source.path`` points, joined to the container's folder (an absolute
    record as it is); None when absent or not a usable path."""
    src = manifest.get("source") if isinstance(manifest.get("source"), dict) else {}
    rec = src.get("path")
    if not isinstance(rec, str) or not rec or "\0" in rec:
        return None
    return os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(container_path)), rec))


def _beside(container_path: str, manifest: dict) -> str | None:
    """The manifest's ``source.file`` beside the container; None when it names none."""
    src = manifest.get("source") if isinstance(manifest.get("source"), dict) else {}
    name = src.get("file")
    if not isinstance(name, str) or not name or "\0" in name:
        return None
    return os.path.join(os.path.dirname(os.path.abspath(container_path)), os.path.basename(name))


def source_candidates(container_path: str, manifest: dict, given: str | None) -> list[str]:
    """The paths ``find_source`` looks at, in its order (whether or not they exist): ``given``
    alone; else where the cook recorded the source (``source.path``), then ``source.file``
    beside the container. ``decode`` refuses an output at any of them (it never overwrites what
    it may read)."""
    if given is not None:
        return [given]
    found = [p for p in (_recorded(container_path, manifest), _beside(container_path, manifest)) if p is not None]
    return list(dict.fromkeys(found))


def _check(path: str, want, flag: str) -> str | None:
    """None when ``path`` is a regular file whose sha256 is ``want``; else why not (one line)."""
    if not os.path.exists(path):
        return f"{flag} {path}: not found"
    if not os.path.isfile(path):
        return f"{flag} {path}: not a regular file"
    if not isinstance(want, str):
        return f"the container records no source sha256, so {path} cannot be checked"
    try:
        have = _sha256(path)
    except OSError as exc:
        return f"{flag} {path}: unreadable ({exc.strerror})"
    if have != want:
        return f"{flag} {path} is not the source this container was cooked from (sha256 differs)"
    return None


def find_source(container_path: str, manifest: dict, given: str | None) -> tuple[str | None, str | None]:
    """``(path, None)`` when the source can give the preview its materials, else ``(None, reason)``.

    ``given`` (``decode --source``) alone when given: an explicit source is never replaced by
    another. Otherwise the first of ``source_candidates`` that is a regular file whose sha256
    equals ``manifest["source"]["sha256"]``: where the cook recorded it (``source.path``,
    relative to the container's folder), then ``source.file`` beside the container. ``reason``
    is one line naming what was looked at.
    """
    src = manifest.get("source") if isinstance(manifest.get("source"), dict) else {}
    want = src.get("sha256")
    if given is not None:
        reason = _check(given, want, "--source")
        return (given, None) if reason is None else (None, reason)
    recorded, beside = _recorded(container_path, manifest), _beside(container_path, manifest)
    if recorded is None and beside is None:
        return None, "the container names no source file (pass --source SRC)"
    looked = []
    for path, flag in ((recorded, "source (where the cook recorded it)"), (beside, "source")):
        if path is None or path in (p for p, _ in looked):
            continue
        reason = _check(path, want, flag)
        if reason is None:
            return path, None
        looked.append((path, reason))
    if all(not os.path.exists(p) for p, _ in looked):
        name = os.path.basename(beside or recorded)
        also = "" if recorded in (None, beside) else f", nor at {src['path']!r} where the cook recorded it"
        return None, f"source {name!r} not found beside {container_path}{also} (pass --source SRC)"
    return None, "; ".join(r for p, r in looked if os.path.exists(p)) + " (pass --source SRC)"


# ---------------------------------------------------------------------------------------------
# Materials
# ---------------------------------------------------------------------------------------------


def source_materials(path: str, fmt: str, parts: list[dict], has_uvs: list[bool],
                     has_colors: list[bool] | None = None) -> tuple[dict, list, list[str]]:
    """``(materials for write_gltf, material index or None per part, warnings)``.

    ``fmt`` is the source's kind (the manifest's ``source.format``); ``parts`` are manifest part
    entries (``mesh_key``, ``source``); ``has_uvs[i]`` says whether part i is decoded with UVs (a
    part without gets the material's untextured variant), and ``has_colors[i]`` (default: none
    have) whether with vertex colours (a material that asks for them as base colour,
    ``BASE_FROM_VERTEX_COLOURS``, gets white, else its grey). Unreadable sources raise nothing:
    they give no materials and a warning.
    """
    col = MaterialSet()
    source_format = format_of(fmt)
    if source_format is None or source_format.materials is None:
        return {}, [None] * len(parts), [f"no materials for source format {(fmt or '').lower()!r}"]
    try:
        per_part = source_format.materials(path, parts, col)
    except (OSError, ValueError, KeyError, TypeError, IndexError, RuntimeError, struct.error) as exc:
        return {}, [None] * len(parts), [f"materials of {os.path.basename(path)} unreadable ({exc}); "
                                         "decoded geometry only"]
    out = []
    has_colors = [False] * len(parts) if has_colors is None else has_colors
    for mat, uv, colored in zip(per_part, has_uvs, has_colors):
        if mat is None:
            out.append(None)
            continue
        mat = resolve_vertex_colour_base(mat, colored)
        out.append(col.material(mat if uv else untextured(mat)))
    return col.as_writer_arg(), out, col.warnings


# ---------------------------------------------------------------------------------------------
# Instancing
# ---------------------------------------------------------------------------------------------


def _quaternion(r: np.ndarray) -> list[float]:
    """Unit quaternion (x, y, z, w) of a proper rotation matrix (Shepperd's method), w >= 0."""
    t = np.trace(r)
    if t > 0:
        s = 2.0 * np.sqrt(1.0 + t)
        q = [(r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s, 0.25 * s]
    else:
        i = int(np.argmax(np.diag(r)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + r[i, i] - r[j, j] - r[k, k])
        q = [0.0] * 4
        q[i] = 0.25 * s
        q[j] = (r[j, i] + r[i, j]) / s
        q[k] = (r[k, i] + r[i, k]) / s
        q[3] = (r[k, j] - r[j, k]) / s
    q = np.asarray(q, np.float64)
    q /= np.linalg.norm(q)
    return [float(x) for x in (q if q[3] >= 0 else -q)]


def _rotation(q: list[float]) -> np.ndarray:
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def fit_trs(p: np.ndarray, q: np.ndarray, snap_tol: float = 0.0) -> tuple[list, list, list, float] | None:
    """``(translation, rotation xyzw, scale, max residual)`` of the TRS map nearest the least-
    squares affine map taking ``p`` (n, 3) to ``q``; None when the points do not determine it.
    A scale within 1e-5 of +-1 is written as exactly +-1 when the residual then stays within
    ``snap_tol`` (metres) or within twice the fitted one."""
    p, q = np.asarray(p, np.float64), np.asarray(q, np.float64)
    if p.shape[0] < 4:
        return None
    c = p.mean(axis=0)
    h = np.concatenate([p - c, np.ones((p.shape[0], 1))], axis=1)
    x, _, rank, sv = np.linalg.lstsq(h, q, rcond=None)
    if rank < 4 or sv[-1] <= 1e-9 * sv[0]:
        return None
    a = x[:3].T
    scale = np.linalg.norm(a, axis=0)
    if not np.isfinite(a).all() or (scale <= 0).any():
        return None
    u, _, vt = np.linalg.svd(a / scale)
    r = u @ vt
    if np.linalg.det(r) < 0:  # a mirror: a negative scale on the last axis
        r[:, 2] *= -1.0
        scale[2] *= -1.0
    quat = _quaternion(r)
    rot = _rotation(quat)

    def residual(s):
        m = rot * s
        t = (q - p @ m.T).mean(axis=0)
        return t, float(np.abs(p @ m.T + t - q).max())

    t, resid = residual(scale)
    unit = np.sign(scale)  # a scale within fitting noise of +-1 is written as exactly +-1
    if np.abs(np.abs(scale) - 1.0).max() < 1e-5:
        t1, r1 = residual(unit)
        if r1 <= max(2.0 * resid, snap_tol):
            t, resid, scale = t1, r1, unit
    return [float(v) for v in t], quat, [float(v) for v in scale], resid


def tangents(positions, normals, uvs, indices) -> np.ndarray:
    """(n, 4) float32 per-vertex tangents for normal mapping (glTF 2.0 3.7.2.1: xyz unit, along
    increasing u, orthogonal to the normal; w = +-1 with bitangent = cross(normal, xyz) * w).

    Per-triangle dP/du and dP/dv accumulated on the corners (larger triangles weigh more), then
    Gram-Schmidt against the normal; w is chosen so that the bitangent points along decreasing
    glTF v (increasing v with the origin bottom-left, the convention of tangent-space normal
    maps). A vertex without a usable UV gradient gets any unit vector orthogonal to its normal.
    """
    p = np.asarray(positions, np.float64)
    n = np.asarray(normals, np.float64)
    uv = np.asarray(uvs, np.float64)
    t = np.asarray(indices, np.int64).reshape(-1, 3)
    e1, e2 = p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]
    d1, d2 = uv[t[:, 1]] - uv[t[:, 0]], uv[t[:, 2]] - uv[t[:, 0]]
    r = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    ok = np.abs(r) > 1e-20
    inv = np.where(ok, 1.0 / np.where(ok, r, 1.0), 0.0)[:, None]
    du = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) * inv
    dv = (e2 * d1[:, 0:1] - e1 * d2[:, 0:1]) * inv
    tu, tv = np.zeros_like(p), np.zeros_like(p)
    for k in range(3):
        np.add.at(tu, t[:, k], du)
        np.add.at(tv, t[:, k], dv)
    tu -= n * np.sum(n * tu, axis=1, keepdims=True)
    length = np.linalg.norm(tu, axis=1)
    bad = ~(length > 1e-12)
    if bad.any():  # any unit vector orthogonal to n: n x (the axis least aligned with n)
        axis = np.eye(3)[np.argmin(np.abs(n[bad]), axis=1)]
        tu[bad] = np.cross(n[bad], axis)
        length[bad] = np.linalg.norm(tu[bad], axis=1)
    tu /= length[:, None]
    w = np.where(np.sum(np.cross(n, tu) * -tv, axis=1) < 0, -1.0, 1.0)
    return np.concatenate([tu, w[:, None]], axis=1).astype(np.float32)


def _same(a, b) -> bool:
    if a is None or b is None:
        return a is None and b is None
    return np.array_equal(a, b)


def instance_nodes(c, lods: list[int], meshes: list[dict], keys: list) -> tuple[list, list, dict]:
    """``(meshes to write, nodes, stats)``: copies of one mesh share it (module doc).

    ``meshes[i]`` is part i decoded at its LOD ``lods[i]`` (dict as ``write_gltf`` takes, with
    ``material``); ``keys[i]`` its grouping key (``mesh_key``, material) or None (never shared).
    ``stats``: ``instances`` (nodes placed on another part's mesh) and ``max_instancing_offset_m``
    (largest distance between a copy's own decoded vertex and the lead's moved by the node).
    """
    cell = float(c.manifest["grid"]["extent"]) / float(1 << 24)
    tol = INSTANCE_TOL_STEPS * cell
    groups: dict = {}
    for i, k in enumerate(keys):
        if k is not None:
            groups.setdefault(k, []).append(i)
    place: dict[int, tuple[int, list, list, list]] = {}
    worst = 0.0
    for members in groups.values():
        lead = members[0]
        lm = meshes[lead]
        fine_lead = None
        for i in members[1:]:
            m = meshes[i]
            if lods[i] != lods[lead] or not all(_same(lm[f], m[f]) for f in ("indices", "uvs", "colors")):
                continue
            # the finest level both hold (24 in a complete file; a prefix holds less: format.md 8)
            fine = min(24, c.level_of(lead, lods[lead]), c.level_of(i, lods[i]))
            if fine_lead is None or fine_lead[0] != fine:
                fine_lead = (fine, decode_positions(c, lead, lods[lead], fine)[2].astype(np.float64))
            fit = fit_trs(fine_lead[1], decode_positions(c, i, lods[i], fine)[2].astype(np.float64), tol)
            if fit is None or fit[3] > tol:
                continue
            t, quat, s, _ = fit
            mat = _rotation(quat) * np.asarray(s)
            moved = np.asarray(lm["positions"], np.float64) @ mat.T + np.asarray(t)
            worst = max(worst, float(np.linalg.norm(moved - np.asarray(m["positions"], np.float64), axis=1).max()))
            place[i] = (lead, t, quat, s)
    out_meshes, index_of, nodes = [], {}, []
    for i, m in enumerate(meshes):
        if i in place:
            continue
        index_of[i] = len(out_meshes)
        shared = any(v[0] == i for v in place.values())
        out_meshes.append(dict(m, name=str(keys[i][0]) if shared else m["name"]))
    for i, m in enumerate(meshes):
        if i in place:
            lead, t, quat, s = place[i]
            node = {"name": m["name"], "mesh": index_of[lead], "translation": t, "rotation": quat}
            if not np.allclose(s, 1.0, rtol=0, atol=1e-12):
                node["scale"] = s
            nodes.append(node)
        else:
            nodes.append({"name": m["name"], "mesh": index_of[i]})
    return out_meshes, nodes, {"instances": len(place), "max_instancing_offset_m": worst}


# ---------------------------------------------------------------------------------------------
# decode's one call
# ---------------------------------------------------------------------------------------------


def preview(c, container_path: str, meshes: list[dict], lods: list[int], source: str | None) -> dict:
    """Everything ``decode`` adds to the decoded ``meshes`` (one per manifest part, in order).

    Returns ``{"meshes", "nodes", "materials" (None: geometry only), "warnings" (one-line
    strings), "source" (path used or None), "instances", "max_instancing_offset_m"}``; the first
    three are ``write_gltf``'s arguments.
    """
    parts = c.manifest["parts"]
    path, reason = find_source(container_path, c.manifest, source)
    warnings = [] if reason is None else [f"{reason}; decoded geometry only (no materials)"]
    materials, per_part = None, [None] * len(parts)
    if path is not None:
        materials, per_part, more = source_materials(path, c.manifest["source"].get("format", ""), parts,
                                                     [m["uvs"] is not None for m in meshes],
                                                     [m["colors"] is not None for m in meshes])
        warnings += more
        if not materials:
            materials, per_part = None, [None] * len(parts)
    meshes = [dict(m, material=mi) for m, mi in zip(meshes, per_part)]
    for m in meshes:  # a normal map needs a tangent space: written, not left to each viewer
        mat = None if m["material"] is None else materials["materials"][m["material"]]
        if mat and "normalTexture" in mat and m["normals"] is not None and m["uvs"] is not None \
                and m.get("tangents") is None:  # a container that stores tangents keeps its own
            m["tangents"] = tangents(m["positions"], m["normals"], m["uvs"], m["indices"])
    keys = [(p.get("mesh_key"), mi) if p.get("mesh_key") else None for p, mi in zip(parts, per_part)]
    out_meshes, nodes, stats = instance_nodes(c, lods, meshes, keys)
    return {"meshes": out_meshes, "nodes": nodes, "materials": materials, "warnings": warnings,
            "source": path, **stats}


__all__ = ["recorded_source_path", "source_candidates", "find_source", "source_materials", "instance_nodes", "fit_trs", "tangents", "preview",
           "INSTANCE_TOL_STEPS"]
