"""Wavefront OBJ -> ``Scene``; the OBJ ``FORMAT`` of the registry (OBJ has no signature: a
``.obj`` file is read as OBJ unless its first bytes show another format).

``load(path, fmt="obj", settings) -> Scene`` (not yet validated) reads:

* ``v x y z [w]`` (``w`` ignored) or ``v x y z r g b [a]`` (a vertex colour), ``vt u [v [w]]``,
  ``vn x y z``; ``f``/``fo`` corners ``v``, ``v/vt``, ``v//vn``, ``v/vt/vn`` (empty fields allowed),
  positive and negative (relative) indices; ``\\`` continuations, ``#`` comments, any line end, a
  UTF-8 BOM; non-UTF-8 text falls back to Latin-1 (a warning). ``l``/``p`` and free-form
  statements are skipped and counted in a warning; ``s`` is ignored.
* parts: one per (``o``, ``g``) pair in effect (a new ``o`` resets the group; a pair seen again
  continues its part), named ``group``, ``object``, ``object/group`` or the file stem, made
  unique with ``#k``. ``mesh_key`` is ``obj:<file name>:<part name>``.
* vertices: one per distinct ``(v, vt, vn)`` triple the part's corners use, ordered by that triple
  (``v`` records no face uses are dropped). All corners without ``vt``: ``uvs=None``; some
  without: (0, 0) and a warning. Any corner without ``vn``: the part's normals are computed
  (``build.make_part``, split at ``settings.crease_angle_deg``). UVs become ``(u, 1 - v)``
  (origin top-left). Positions are metres as written (OBJ has no units), +Y up, CCW.
* polygons: triangulated by ``polygons.triangulate`` (concave quads and n-gons right, winding
  kept).
* materials: ``usemtl`` (a part's first material is kept in ``MeshPart.source``; several: a
  warning) and ``mtllib``; the material's ``map_Kd`` is the part's ``texture``. A missing .mtl
  or image is a warning. ``Scene.dependencies``: the .obj, each .mtl looked for (found or not),
  then each used ``map_Kd`` file (the path given and, when missing, the fallback beside the .obj).

Refused, each as one ``LopcookError("ingest", path, "line N: ...")``: a malformed number or a
wrong count of values, NaN/Inf, a corner that is not an index, index 0 or out of range (with the
record count), a face of fewer than three corners, a polygon ``polygons`` refuses (concave over
``MAX_CONCAVE_CORNERS``, or over ``REPEAT_CHECK_CORNERS`` corners naming fewer distinct ``v``
records than half its corners: checked before any corner position exists), a line continuation
inside a number, NUL bytes (binary or UTF-16 content), more than ``build.MAX_PARTS`` parts. A
file without faces gives ``parts=()`` (``Scene.validate`` reports it).

Cost: vectorised over the file's bytes (implementation notes and why not trimesh:
docs/ingest.md, "OBJ"); only name statements and n-gons of 5+ corners take a Python loop; the
peak is about 11x the file size. ``materials(path, parts, out)`` reads the .mtl materials again
for ``lopcook decode`` (docs/format.md 9.2).
"""

from __future__ import annotations

import os
import re
import warnings
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..depfile import DependencyList
from ..errors import LopcookError
from ..settings import IngestSettings
from ..types import Scene, Texture
from .build import MAX_PARTS, checked_texture, make_part, unique_names
from .format import Format
from .materials import MaterialSet
from .polygons import PolygonTooComplex, check_distinct_corners, triangulate

# byte classes -------------------------------------------------------------------------------
_WS = np.zeros(256, dtype=bool)           # token separators (newline included)
_WS[[9, 10, 11, 12, 13, 32]] = True
_BLANK = np.zeros(256, dtype=bool)        # indentation (no newline)
_BLANK[[9, 11, 12, 13, 32]] = True
_FACE_OK = _WS.copy()                     # bytes allowed in the corner list of an f line
_FACE_OK[[ord(c) for c in "0123456789+-/"]] = True

_NUMBER_BYTE = np.zeros(256, dtype=bool)  # bytes a number token is made of
_NUMBER_BYTE[[ord(c) for c in "0123456789.eE+-"]] = True

_V, _VT, _VN, _F = 1, 2, 3, 4

#: map_Kd options and how many arguments they take (None: 1 to 3 numbers)
_MAP_OPTIONS = {"-blendu": 1, "-blendv": 1, "-bm": 1, "-boost": 1, "-cc": 1, "-clamp": 1,
                "-imfchan": 1, "-texres": 1, "-type": 1, "-mm": 2, "-o": None, "-s": None, "-t": None}


class _Ctx:
    """Per-file state shared by the helpers: path, line bookkeeping, warnings."""

    def __init__(self, path: str):
        self.path = path
        self.warnings: list[str] = []
        self.deps = DependencyList(path)  # Scene.dependencies: files opened or looked for
        self.starts: np.ndarray = np.zeros(0, np.int64)   # byte offset of each logical line
        self.cont_pos: np.ndarray | None = None          # byte offsets of "\\\n" continuations

    def lineno(self, logical) -> np.ndarray | int:
        """Physical (1-based) line number of logical line(s) ``logical``."""
        logical = np.asarray(logical, dtype=np.int64)
        out = logical + 1
        if self.cont_pos is not None:
            out = out + np.searchsorted(self.cont_pos, self.starts[logical])
        return int(out) if out.ndim == 0 else out

    def fail(self, message: str, hint: str | None = None, line=None):
        where = f"line {self.lineno(line)}: " if line is not None else ""
        raise LopcookError("ingest", self.path, where + message,
                           hint=hint or "fix or re-export the OBJ file")


# --------------------------------------------------------------------------------------------
def load(path: str, *, fmt: str = "obj", settings: IngestSettings) -> Scene:
    """Read one OBJ file into an unvalidated Scene (metres as written, +Y up, CCW).

    Parameters
    ----------
    path : str
        The .obj file, as the user gave it (used verbatim in messages and ``Scene.source``).
    fmt : str
        Always ``"obj"``.
    settings : IngestSettings
        ``crease_angle_deg`` is used for parts whose normals are computed.

    Returns
    -------
    Scene with one MeshPart per (object, group) that has faces: positions (n, 3) float64,
    indices (m, 3) uint32, uvs (n, 2) float32 or None, normals (n, 3) float32, colors (n, 4)
    float32 or None.
    """
    ctx = _Ctx(path)
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError as exc:
        raise LopcookError("ingest", path, f"cannot read file: {exc.strerror or exc}",
                           hint="check the path and permissions") from None
    try:
        return _load_bytes(ctx, data, fmt, settings)
    except LopcookError:
        raise
    except (ValueError, IndexError, OverflowError, TypeError) as exc:  # safety net: no tracebacks
        detail = " ".join(str(exc).split())[:160] or "unreadable data"
        raise LopcookError("ingest", path, f"malformed OBJ ({detail})", hint="fix or re-export the OBJ file") from None


def _load_bytes(ctx: _Ctx, data: bytes, fmt: str, settings: IngestSettings) -> Scene:
    """The steps of ``load`` on the file's bytes."""
    path = ctx.path
    # (1) one byte string: BOM, NUL, encoding, line ends and continuations settled
    data, encoding = _normalise(ctx, data)
    # (2) classify lines by their first bytes; read the few name statements
    arr, lines = _classify(ctx, data)
    names = _name_statements(ctx, data, lines, encoding)
    # (3) the bytes of every v / vt / vn / f line, keywords and trailing comments blanked
    work, btype = _record_bytes(data, arr, lines)
    del arr
    rows = {k: np.flatnonzero(lines.code == k) for k in (_V, _VT, _VN, _F)}
    V, colors, has_color = _read_v(ctx, work[btype == _V], rows[_V])
    UV = _read_vt(ctx, work[btype == _VT], rows[_VT])
    N = _read_vn(ctx, work[btype == _VN], rows[_VN])
    nv, nvt, nvn = V.shape[0], UV.shape[0], N.shape[0]
    f_lines = rows[_F]
    if f_lines.size == 0:
        ctx.warnings.append(f"no faces (f statements): {nv} v records, nothing to mesh")
        return Scene(parts=(), source=path, format="obj", unit_scale=1.0, up_axis="Y",
                     warnings=tuple(ctx.warnings), dependencies=ctx.deps.paths())
    # (4) faces: corners resolved to record indices, polygons triangulated
    fblob = work[btype == _F]
    del work, btype
    counts, cv, cvt, cvn, has_vt, has_vn = _read_faces(ctx, fblob, f_lines)
    del fblob
    corner_line = np.repeat(f_lines, counts)
    cv = _resolve(ctx, "v", cv, None, rows[_V], corner_line, nv)
    try:
        check_distinct_corners(counts, cv)  # before any per-corner position or triangle is made
    except PolygonTooComplex as exc:
        ctx.fail(str(exc), hint=exc.hint, line=f_lines[exc.face])
    cvt = _resolve(ctx, "vt", cvt, has_vt, rows[_VT], corner_line, nvt)
    cvn = _resolve(ctx, "vn", cvn, has_vn, rows[_VN], corner_line, nvn)
    del corner_line
    if np.all(counts == 3):
        tri = np.arange(cv.size, dtype=np.int64).reshape(-1, 3)
        tri_face = np.arange(counts.size, dtype=np.int64)
    else:
        try:
            tri, tri_face = triangulate(counts, V[cv])
        except PolygonTooComplex as exc:
            ctx.fail(str(exc), hint=exc.hint, line=f_lines[exc.face])
    # (5) parts: one per (object, group), each split per corner into its vertices
    face_part, keys = _part_of_faces(ctx, names, f_lines)
    stem = os.path.splitext(os.path.basename(path))[0] or "obj"
    part_names = unique_names([_part_name(k, stem) for k in keys])
    mtl_lines = np.array([e[0] for e in names.usemtl], dtype=np.int64)
    mtl_names = [e[1] for e in names.usemtl]
    face_mtl = np.searchsorted(mtl_lines, f_lines) - 1   # -1: no usemtl in effect
    materials = _read_mtllibs(ctx, names.mtllibs, encoding) if names.mtllibs else {}
    tex_cache: dict[str, Texture | None] = {}
    tri_part = face_part[tri_face]
    n_parts = len(keys)
    if n_parts == 1:
        order = None
        bounds = np.array([0, tri.shape[0]])
    else:
        order = np.argsort(tri_part, kind="stable")
        bounds = np.searchsorted(tri_part[order], np.arange(n_parts + 1))
    out = []
    for p, (key, name) in enumerate(zip(keys, part_names)):
        sel = slice(bounds[p], bounds[p + 1])
        tc = tri[sel] if order is None else tri[order[sel]]
        faces_p = tri_face[sel] if order is None else tri_face[order[sel]]
        mat = _first_material(ctx, name, face_mtl[faces_p], mtl_names)
        texture = _texture_for(ctx, mat, materials, tex_cache, bool(names.mtllibs))
        out.append(_build_part(ctx, name, key, mat, tc, cv, cvt, cvn, V, UV, N, colors, has_color,
                               texture, settings))
    return Scene(parts=tuple(out), source=path, format="obj", unit_scale=1.0, up_axis="Y",
                 warnings=tuple(ctx.warnings), dependencies=ctx.deps.paths())


def _normalise(ctx: _Ctx, data: bytes) -> tuple[bytes, str]:
    """``(bytes, encoding of names)``: a BOM blanked (offsets kept), ``\\r\\n`` and ``\\r`` made
    ``\\n``, backslash continuations joined (their positions kept in ``ctx.cont_pos`` for line
    numbers), a final ``\\n``. Refuses NUL bytes and a continuation inside a number."""
    if data.startswith(b"\xef\xbb\xbf"):
        data = b"   " + data[3:]  # keep byte offsets
    if b"\x00" in data:
        at = data.index(b"\x00")
        ctx.fail(f"contains NUL bytes (first at byte offset {at}): binary data, not a text OBJ",
                 hint="UTF-16 files must be saved as UTF-8; otherwise the file is not an OBJ")
    encoding = "utf-8"
    if not data.isascii():
        try:
            data.decode("utf-8")
        except UnicodeDecodeError as exc:
            encoding = "latin-1"
            ctx.warnings.append(f"not valid UTF-8 (byte 0x{data[exc.start]:02x} at offset {exc.start}); "
                                "names decoded as Latin-1")
    if b"\r" in data:
        data = data.replace(b"\r\n", b"\n").replace(b"\r", b"\n")
    if b"\\\n" in data:
        raw = np.frombuffer(data, dtype=np.uint8)
        ctx.cont_pos = np.flatnonzero((raw[:-1] == 92) & (raw[1:] == 10))
        # "1\\<newline>.5" would silently read as two numbers "1 .5": refuse a continuation
        # between two characters of a number
        cp = ctx.cont_pos
        inside = cp[(cp > 0) & (cp + 2 < raw.size)]
        inside = inside[_NUMBER_BYTE[raw[inside - 1]] & _NUMBER_BYTE[raw[inside + 2]]]
        if inside.size:
            at = int(inside[0])
            line = int(np.count_nonzero(raw[:at] == 10)) + 1
            raise LopcookError("ingest", ctx.path, f"line {line}: a line continuation (backslash at the end of "
                               "the line) splits a number", hint="join the number on one line")
        data = data.replace(b"\\\n", b"  ")
    if not data.endswith(b"\n"):
        data = data + b"\n"
    return data, encoding


@dataclass
class _Lines:
    """Per logical line: ``starts`` its first byte's offset, ``nl`` its newline's, ``s`` its first
    non-blank byte's, ``code`` (``_V``, ``_VT``, ``_VN``, ``_F`` or 0), ``one``/``two`` the lines whose
    keyword is one / two bytes long, ``other`` the lines to read as name statements; ``n`` the
    bytes of the text."""

    n: int
    starts: np.ndarray
    nl: np.ndarray
    s: np.ndarray
    code: np.ndarray
    one: np.ndarray
    two: np.ndarray
    other: np.ndarray


def _classify(ctx: _Ctx, data: bytes) -> tuple[np.ndarray, _Lines]:
    """``(the bytes as uint8, padded by 3 newlines; the lines classified)``; ``l``/``p`` lines are
    counted in a warning."""
    n = len(data)
    arr = np.frombuffer(data + b"\n\n\n", dtype=np.uint8)  # padded so first bytes can be peeked
    nl = np.flatnonzero(arr[:n] == 10)
    starts = np.empty(nl.size, dtype=np.int64)
    starts[0] = 0
    starts[1:] = nl[:-1] + 1
    ctx.starts = starts
    s = starts.copy()                      # first non-blank byte of each line
    idx = np.flatnonzero(_BLANK[arr[s]])
    for _ in range(16):                    # usual indentation: a few vectorised steps
        if not idx.size:
            break
        s[idx] += 1
        idx = idx[_BLANK[arr[s[idx]]]]
    for i in idx.tolist():                 # deeper indentation (rare): per line
        line = data[s[i]:nl[i]]
        s[i] += len(line) - len(line.lstrip(b" \t\v\f\r"))
    b0, b1, b2 = arr[s], arr[s + 1], arr[s + 2]
    ws1, ws2 = _WS[b1], _WS[b2]
    code = np.zeros(nl.size, dtype=np.uint8)
    is_v = (b0 == ord("v")) & ws1
    is_vt = (b0 == ord("v")) & (b1 == ord("t")) & ws2
    is_vn = (b0 == ord("v")) & (b1 == ord("n")) & ws2
    is_f = (b0 == ord("f")) & ws1
    is_fo = (b0 == ord("f")) & (b1 == ord("o")) & ws2
    code[is_v] = _V
    code[is_vt] = _VT
    code[is_vn] = _VN
    code[is_f | is_fo] = _F
    quiet = (b0 == ord("#")) | (b0 == 10) | ((b0 == ord("s")) & ws1)
    n_l = int(np.count_nonzero((b0 == ord("l")) & ws1))
    n_p = int(np.count_nonzero((b0 == ord("p")) & ws1))
    quiet |= ((b0 == ord("l")) | (b0 == ord("p"))) & ws1
    if n_l or n_p:
        ctx.warnings.append(f"skipped {n_l} line (l) and {n_p} point (p) statements: only faces are ingested")
    return arr, _Lines(n=n, starts=starts, nl=nl, s=s, code=code, one=np.flatnonzero(is_v | is_f),
                       two=np.flatnonzero(is_vt | is_vn | is_fo), other=np.flatnonzero((code == 0) & ~quiet))


@dataclass
class _Names:
    """The name statements: ``(line, name)`` of each ``o``, ``g`` and ``usemtl``; ``mtllib`` values."""

    objects: list[tuple[int, str]]
    groups: list[tuple[int, str]]
    usemtl: list[tuple[int, str]]
    mtllibs: list[str]


def _name_statements(ctx: _Ctx, data: bytes, lines: _Lines, encoding: str) -> _Names:
    """The ``o``, ``g``, ``usemtl`` and ``mtllib`` statements (trailing comments cut); any other
    keyword is counted in one warning."""
    names = _Names([], [], [], [])
    unknown: Counter = Counter()
    for li in lines.other.tolist():
        text = data[lines.s[li]:lines.nl[li]].decode(encoding, errors="replace")
        parts = text.split(None, 1)
        if not parts:
            continue
        kw = parts[0]
        rest = parts[1] if len(parts) > 1 else ""
        if " #" in rest or "\t#" in rest or rest.startswith("#"):  # trailing comment
            rest = rest[:min(i for i in (rest.find(" #"), rest.find("\t#"), 0 if rest.startswith("#") else -1)
                             if i >= 0)]
        rest = rest.strip()
        if kw == "o":
            names.objects.append((li, rest))
        elif kw == "g":
            names.groups.append((li, rest))
        elif kw == "usemtl":
            names.usemtl.append((li, rest))
        elif kw == "mtllib":
            if rest:
                names.mtllibs.append(rest)
        elif kw.startswith("#"):
            continue
        else:
            unknown[kw] += 1
    if unknown:
        what = ", ".join(f"{k!r} x{c}" for k, c in unknown.most_common(8))
        ctx.warnings.append(f"ignored {sum(unknown.values())} unsupported statements ({what})")
    return names


def _record_bytes(data: bytes, arr: np.ndarray, lines: _Lines) -> tuple[np.ndarray, np.ndarray]:
    """``(work, btype)``: a copy of the text's bytes with the ``v``/``vt``/``vn``/``f``/``fo``
    keywords and every trailing ``#`` comment of such lines blanked, and each byte's line code."""
    n, nl = lines.n, lines.nl
    lengths = np.diff(np.r_[lines.starts, n])  # each includes its "\n"
    btype = np.repeat(lines.code, lengths)
    work = arr[:n].copy()
    work[lines.s[lines.one]] = 32
    work[lines.s[lines.two]] = 32
    work[lines.s[lines.two] + 1] = 32
    if b"#" in data:
        hp = np.flatnonzero(work == 35)
        hp = hp[btype[hp] != 0]
        if hp.size:
            line_of = np.searchsorted(nl, hp)
            _, first = np.unique(line_of, return_index=True)
            h = hp[first]
            e = nl[line_of[first]]
            d = np.zeros(n + 1, dtype=np.int8)
            d[h] = 1
            d[e] -= 1
            blank = np.cumsum(d[:n], dtype=np.int8).astype(bool)
            work[blank] = 32
    return work, btype


def _part_of_faces(ctx: _Ctx, names: _Names, f_lines: np.ndarray) -> tuple[np.ndarray, list[tuple]]:
    """``(part index of each face, the (object, group) key of each part)``, parts in first-use
    order; refuses more than ``MAX_PARTS`` parts before any is built."""
    og = sorted([(li, "o", name) for li, name in names.objects] + [(li, "g", name) for li, name in names.groups])
    og_lines = np.array([e[0] for e in og], dtype=np.int64)
    states: list[tuple[str | None, str | None]] = [(None, None)]
    cur_o: str | None = None
    cur_g: str | None = None
    for _, kind, name in og:
        if kind == "o":
            cur_o, cur_g = (name or None), None
        else:
            cur_g = name or None
        states.append((cur_o, cur_g))
    seg = np.searchsorted(og_lines, f_lines)          # state index per face (monotone)
    key_to_part: dict[tuple, int] = {}
    seg_to_part = np.full(len(states), -1, dtype=np.int64)
    for sg in np.unique(seg).tolist():
        key = states[sg]
        if key not in key_to_part:
            key_to_part[key] = len(key_to_part)
        seg_to_part[sg] = key_to_part[key]
    keys = list(key_to_part)
    if len(keys) > MAX_PARTS:  # counted before any part is built
        ctx.fail(f"the file has {len(keys):,} objects/groups with faces, more than the {MAX_PARTS:,} parts "
                 "lopcook accepts", hint="merge groups or split the file")
    return seg_to_part[seg], keys


def _first_material(ctx: _Ctx, name: str, fm: np.ndarray, mtl_names: list[str]) -> str | None:
    """The first material (``usemtl``, index ``fm`` per face, -1 none) a part's faces use; a part
    using several gets a warning."""
    fm = fm[fm >= 0]
    if not fm.size:
        return None
    used_ids, first = np.unique(fm, return_index=True)
    used_names = list(dict.fromkeys(mtl_names[i] for i in used_ids[np.argsort(first)].tolist()))
    used_names = [m for m in used_names if m and m != "(null)"]
    if not used_names:
        return None
    if len(used_names) > 1:
        ctx.warnings.append(f"part {name!r} uses {len(used_names)} materials "
                            f"({', '.join(used_names[:5])}); its texture is {used_names[0]!r}'s")
    return used_names[0]


# numbers --------------------------------------------------------------------------------------
def _tokens(blob: np.ndarray):
    """blob: uint8 bytes of lines, each ending in "\\n" -> (token start offsets, token end offsets
    (exclusive), tokens per line (L,))."""
    ws = _WS[blob]
    nonws = ~ws
    st = nonws.copy()
    st[1:] &= ws[:-1]
    tok_start = np.flatnonzero(st)
    tok_end = np.flatnonzero(nonws[:-1] & ws[1:]) + 1
    nlpos = np.flatnonzero(blob == 10)
    per_line = np.diff(np.r_[0, np.searchsorted(tok_start, nlpos)])
    return tok_start, tok_end, per_line


def _fromstring(blob: np.ndarray, n_tokens: int, dtype) -> np.ndarray | None:
    """Parse whitespace-separated numbers; None when the text does not parse to n_tokens values."""
    if n_tokens == 0:
        return np.zeros(0, dtype=dtype)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            vals = np.fromstring(blob.tobytes(), dtype=dtype, sep=" ")
        except (ValueError, DeprecationWarning):
            return None
    return vals if vals.size == n_tokens else None


def _bad_number(ctx: _Ctx, blob: np.ndarray, line_ids: np.ndarray, kind: str):
    """Error path: find the first token on a ``kind`` line that is not a number and raise."""
    for j, line in enumerate(blob.tobytes().split(b"\n")):
        for tok in line.split():
            with warnings.catch_warnings():
                warnings.simplefilter("error")
                try:
                    ok = np.fromstring(tok, dtype=np.float64, sep=" ").size == 1
                except (ValueError, DeprecationWarning):
                    ok = False
            if not ok:
                txt = tok.decode("latin-1")[:40]
                ctx.fail(f"malformed number {txt!r} on a {kind} line", line=line_ids[min(j, line_ids.size - 1)])
    ctx.fail(f"malformed numbers on {kind} lines", line=None)


def _numbers(ctx: _Ctx, blob: np.ndarray, line_ids: np.ndarray, kind: str):
    """Parse all values of the ``kind`` lines -> (values (T,) float64, offsets (L,), counts (L,))."""
    tok_start, _, per_line = _tokens(blob)
    vals = _fromstring(blob, tok_start.size, np.float64)
    if vals is None:
        _bad_number(ctx, blob, line_ids, kind)
    offsets = np.cumsum(per_line) - per_line
    return vals, offsets, per_line


def _check_finite(ctx: _Ctx, arr: np.ndarray, line_ids: np.ndarray, kind: str):
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        i = int(np.argmax(bad))
        ctx.fail(f"{kind} has a NaN or Inf value ({' '.join(repr(float(x)) for x in arr[i])})",
                 line=line_ids[i])


def _gather(vals, offsets, width, counts=None, fill=0.0):
    """(L, width) values: column k is vals[offsets + k] where k < counts (else ``fill``)."""
    idx = offsets[:, None] + np.arange(width)
    if counts is None:
        return vals[idx]
    ok = np.arange(width) < counts[:, None]
    out = np.full(idx.shape, fill, dtype=np.float64)
    out[ok] = vals[idx[ok]]
    return out


def _read_v(ctx, blob, line_ids):
    """-> positions (nv, 3) float64, colors (nv, 4) float64 or None, has_color (nv,) bool or None."""
    if line_ids.size == 0:
        return np.zeros((0, 3)), None, None
    vals, offsets, cnt = _numbers(ctx, blob, line_ids, "v")
    if np.all(cnt == 3):
        V = vals.reshape(-1, 3)
        _check_finite(ctx, V, line_ids, "v")
        return V, None, None
    bad = ~np.isin(cnt, (3, 4, 6, 7))
    if bad.any():
        i = int(np.argmax(bad))
        ctx.fail(f"v needs 3 coordinates (x y z [w], or x y z r g b [a]), got {int(cnt[i])} values",
                 line=line_ids[i])
    V = _gather(vals, offsets, 3)
    _check_finite(ctx, V, line_ids, "v")
    has_color = cnt >= 6
    if not has_color.any():
        return V, None, None
    colors = np.ones((V.shape[0], 4))
    colors[has_color, :3] = _gather(vals, offsets[has_color] + 3, 3)
    four = cnt == 7
    colors[four, 3] = vals[offsets[four] + 6]
    _check_finite(ctx, colors, line_ids, "v colour")
    return V, colors, has_color


def _read_vt(ctx, blob, line_ids):
    """-> uv (nvt, 2) float64 as written (OBJ origin bottom-left; flipped later)."""
    if line_ids.size == 0:
        return np.zeros((0, 2))
    vals, offsets, cnt = _numbers(ctx, blob, line_ids, "vt")
    if np.all(cnt == 2):
        UV = vals.reshape(-1, 2)
    else:
        bad = (cnt < 1) | (cnt > 3)
        if bad.any():
            i = int(np.argmax(bad))
            ctx.fail(f"vt needs 1 to 3 values (u [v [w]]), got {int(cnt[i])}", line=line_ids[i])
        UV = _gather(vals, offsets, 2, cnt)
    _check_finite(ctx, UV, line_ids, "vt")
    return UV


def _read_vn(ctx, blob, line_ids):
    """-> normals (nvn, 3) float64 as written."""
    if line_ids.size == 0:
        return np.zeros((0, 3))
    vals, offsets, cnt = _numbers(ctx, blob, line_ids, "vn")
    bad = cnt != 3
    if bad.any():
        i = int(np.argmax(bad))
        ctx.fail(f"vn needs 3 values (x y z), got {int(cnt[i])}", line=line_ids[i])
    N = vals.reshape(-1, 3)
    _check_finite(ctx, N, line_ids, "vn")
    zero = ~(np.linalg.norm(N, axis=1) > 1e-20)
    if zero.any():  # as the glTF reader: said, not silently replaced
        ctx.warnings.append(f"{int(zero.sum())} vn records have zero length (first on line "
                            f"{int(line_ids[np.argmax(zero)]) + 1}); the vertices using them get +Y")
    return N


# faces ------------------------------------------------------------------------------------------
def _read_faces(ctx: _Ctx, blob: np.ndarray, f_lines: np.ndarray):
    """Parse every f line.

    Returns counts (F,) corners per face, per corner (C = counts.sum()) int64 arrays of the raw
    OBJ indices v, vt, vn as written (0 where the field is absent; read-only broadcasts when no
    corner has a ``/``), and (C,) bool has_vt, has_vn.
    """
    bad = ~_FACE_OK[blob]
    if bad.any():
        pos = int(np.argmax(bad))
        j = int(np.count_nonzero(blob[:pos] == 10))
        line = blob[:].tobytes().split(b"\n")[j]
        toks = [t for t in line.split() if not all(_FACE_OK[c] for c in t)]
        what = toks[0].decode("latin-1")[:40] if toks else chr(blob[pos])
        ctx.fail(f"malformed face corner {what!r} (expected v, v/vt, v//vn or v/vt/vn indices)",
                 line=f_lines[j])
    tok_start, tok_end, counts = _tokens(blob)
    few = counts < 3
    if few.any():
        i = int(np.argmax(few))
        ctx.fail(f"face has {int(counts[i])} corners, needs at least 3", line=f_lines[i])
    ntok = tok_start.size
    slash = np.flatnonzero(blob == 47)
    if slash.size == 0:
        has_vt = has_vn = np.zeros(ntok, dtype=bool)
        n_values = ntok
    else:
        k0 = np.searchsorted(slash, tok_start)
        ns = np.searchsorted(slash, tok_end) - k0
        face_of_tok = np.repeat(np.arange(counts.size), counts)
        if (ns > 2).any() or (blob[tok_start] == 47).any():
            i = int(np.argmax((ns > 2) | (blob[tok_start] == 47)))
            txt = blob[tok_start[i]:tok_end[i]].tobytes().decode("latin-1")[:40]
            ctx.fail(f"malformed face corner {txt!r} (expected v, v/vt, v//vn or v/vt/vn)",
                     line=f_lines[face_of_tok[i]])
        first = slash[np.minimum(k0, slash.size - 1)]
        vt_empty = (blob[first + 1] == 47) | (first + 1 == tok_end)
        has_vt = (ns >= 1) & ~vt_empty
        has_vn = (ns == 2) & (blob[tok_end - 1] != 47)
        nfield = 1 + has_vt.astype(np.int64) + has_vn
        blob[slash] = 32  # blob is the caller's own copy (boolean-mask gather)
        n_values = int(nfield.sum())
    vals = _fromstring(blob, n_values, np.int64)
    if vals is None:
        # a sign in the middle of a number ("1-2") or a lone sign: find the corner
        for i in range(ntok):
            txt = blob[tok_start[i]:tok_end[i]].tobytes()
            if any(not t.lstrip(b"+-").isdigit() for t in txt.split()):
                face_of_tok = np.repeat(np.arange(counts.size), counts)
                ctx.fail(f"malformed face corner {txt.decode('latin-1')[:40]!r}", line=f_lines[face_of_tok[i]])
        ctx.fail("malformed face indices")
    if slash.size == 0:
        absent = np.broadcast_to(np.int64(0), (ntok,))  # no vt or vn field: one read-only value
        return counts, vals, absent, absent, has_vt, has_vn
    off = np.cumsum(nfield) - nfield
    last = vals.size - 1
    cv = vals[off]
    cvt = np.where(has_vt, vals[np.minimum(off + 1, last)], 0)
    cvn = np.where(has_vn, vals[np.minimum(off + 1 + has_vt, last)], 0)
    return counts, cv, cvt, cvn, has_vt, has_vn


def _resolve(ctx: _Ctx, kind: str, idx: np.ndarray, present: np.ndarray | None, rec_lines: np.ndarray,
             corner_line: np.ndarray, total: int) -> np.ndarray:
    """OBJ 1-based / negative-relative indices -> 0-based int64 (-1 where ``present`` is False; a
    read-only broadcast of -1 when no corner has the field).

    A positive index must be <= the number of ``kind`` records in the file; a negative one counts
    back from the records defined before its line.
    """
    if present is not None and not present.any():
        return np.broadcast_to(np.int64(-1), (idx.size,))  # read-only, no memory per corner
    zero = idx == 0 if present is None else (idx == 0) & present
    if zero.any():
        i = int(np.argmax(zero))
        ctx.fail(f"face {kind} index 0 is invalid (OBJ indices start at 1; {total} {kind} records)",
                 line=corner_line[i])
    out = idx - 1
    neg = idx < 0
    if neg.any():
        before = np.searchsorted(rec_lines, corner_line[neg])
        out[neg] = before + idx[neg]
        badn = out[neg] < 0
        if badn.any():
            i = int(np.argmax(badn))
            ctx.fail(f"face {kind} index {int(idx[neg][i])} out of range: only {int(before[i])} {kind} "
                     f"records before this line", line=corner_line[neg][i])
    badp = (idx > 0) & (out >= total)
    if badp.any():
        i = int(np.argmax(badp))
        ctx.fail(f"face {kind} index {int(idx[i])} out of range: the file has {total} {kind} records",
                 line=corner_line[i])
    if present is not None:
        out[~present] = -1
    return out


# parts ------------------------------------------------------------------------------------------
def _part_name(key: tuple, stem: str) -> str:
    o, g = key
    if o and g:
        return f"{o}/{g}"
    return g or o or stem


def _unique_corners(keys: np.ndarray, size: int):
    """Dense or sorted de-duplication of non-negative int64 keys < size -> (unique, inverse)."""
    if size <= 4 * keys.size + 1024:
        used = np.zeros(size, dtype=bool)
        used[keys] = True
        uniq = np.flatnonzero(used)
        remap = np.empty(size, dtype=np.int64)
        remap[uniq] = np.arange(uniq.size)
        return uniq, remap[keys]
    uniq, inv = np.unique(keys, return_inverse=True)
    return uniq, inv.reshape(-1)


def _refine(inv: np.ndarray, n: int, attr: np.ndarray, n_attr: int):
    """Split vertices by one more per-corner attribute.

    inv : (C,) vertex id in [0, n) of every corner; attr : (C,) attribute index in [-1, n_attr).
    Returns (new inv (C,), old vertex of each new vertex (n',), attribute of each new vertex (n',)).
    New vertices are ordered by (old vertex, attribute). When every vertex already has a single
    attribute value (no seam), the split is the identity and costs O(C) instead of a sort.
    """
    rep = np.empty(n, dtype=np.int64)
    rep[inv] = attr
    if np.array_equal(rep[inv], attr):
        return inv, np.arange(n, dtype=np.int64), rep
    uniq, inv2 = _unique_corners(inv * (n_attr + 1) + (attr + 1), n * (n_attr + 1))
    return inv2, uniq // (n_attr + 1), uniq % (n_attr + 1) - 1


def _build_part(ctx, name, key, mat, tc, cv, cvt, cvn, V, UV, N, colors, has_color, texture, settings):
    """Per-corner split of one part's triangles tc (T, 3) corner ids -> MeshPart."""
    kv, kvt, kvn = cv[tc].ravel(), cvt[tc].ravel(), cvn[tc].ravel()
    nvt, nvn = UV.shape[0], N.shape[0]
    vt_have = kvt >= 0
    vn_have = kvn >= 0
    use_vt = bool(vt_have.any())
    use_vn = bool(vn_have.all()) and kvn.size > 0
    if use_vt and not vt_have.all():
        ctx.warnings.append(f"part {name!r}: {int(np.count_nonzero(~vt_have))} of {kvt.size} triangle "
                            "corners have no vt; their uvs are set to (0, 0)")
    if vn_have.any() and not use_vn:
        ctx.warnings.append(f"part {name!r}: {int(np.count_nonzero(~vn_have))} of {kvn.size} triangle "
                            "corners have no vn; the file's normals are ignored and normals are computed")
    vert_v, inv = _unique_corners(kv, V.shape[0])
    vert_vt = vert_vn = None
    if use_vt:
        inv, old, vert_vt = _refine(inv, vert_v.size, kvt, nvt)
        vert_v = vert_v[old]
    if use_vn:
        inv, old, vert_vn = _refine(inv, vert_v.size, kvn, nvn)
        vert_v = vert_v[old]
        vert_vt = None if vert_vt is None else vert_vt[old]
    indices = inv.reshape(-1, 3)
    positions = V[vert_v]
    uvs = None
    if vert_vt is not None:
        uvs = np.zeros((vert_vt.size, 2))
        ok = vert_vt >= 0
        uvs[ok, 0] = UV[vert_vt[ok], 0]
        uvs[ok, 1] = 1.0 - UV[vert_vt[ok], 1]
    normals = None if vert_vn is None else N[vert_vn]
    col = None
    if colors is not None:
        hc = has_color[vert_v]
        if hc.any():
            col = colors[vert_v]
            if not hc.all():
                ctx.warnings.append(f"part {name!r}: {int(np.count_nonzero(~hc))} of {hc.size} vertices have "
                                    "no colour; they are white")
            if (col < 0).any() or (col > 1).any():
                ctx.warnings.append(f"part {name!r}: vertex colours outside [0, 1] were clipped")
                col = np.clip(col, 0.0, 1.0)
    o, g = key
    src = " ".join(x for x in (f"o {o}" if o else "", f"g {g}" if g else "") if x) or "(no o/g)"
    if mat:
        src += f" usemtl {mat}"
    return make_part(name, positions, indices, settings=settings, normals=normals, uvs=uvs, colors=col,
                     source=src, texture=texture, mesh_key=f"obj:{os.path.basename(ctx.path)}:{name}")


# materials --------------------------------------------------------------------------------------
def _read_mtllibs(ctx: _Ctx, mtllibs: list[str], encoding: str) -> dict[str, str | None]:
    """Parse the .mtl files -> {material name: absolute map_Kd path or None}."""
    base = os.path.dirname(ctx.path)
    out: dict[str, str | None] = {}
    for spec in mtllibs:
        cands = [spec] if os.path.isfile(os.path.join(base, spec.replace("\\", "/"))) else spec.split()
        for name in cands:
            mpath = os.path.join(base, name.replace("\\", "/"))
            ctx.deps.add_path(mpath)  # listed even when missing: a build must rerun when it appears
            if not os.path.isfile(mpath):
                ctx.warnings.append(f"material library {name!r} not found; parts have no texture")
                continue
            try:
                with open(mpath, "rb") as fh:
                    raw = fh.read()
            except OSError as exc:
                ctx.warnings.append(f"material library {name!r} unreadable ({exc.strerror}); parts have no texture")
                continue
            try:
                text = raw.decode("utf-8-sig")
            except UnicodeDecodeError:
                text = raw.decode("latin-1")
            cur = None
            mdir = os.path.dirname(mpath)
            for kw, rest in _mtl_statements(text):
                if kw == "newmtl":
                    cur = rest
                    out.setdefault(cur, None)
                elif kw == "map_kd" and cur is not None:
                    fname = _map_filename(rest)
                    out[cur] = os.path.join(mdir, fname.replace("\\", "/")) if fname else None
    return out


def _map_filename(rest: str) -> str:
    """The file name of a ``map_Kd [options] file`` statement (options skipped)."""
    toks = rest.split()
    i = 0
    while i < len(toks) and toks[i].lower() in _MAP_OPTIONS:
        nargs = _MAP_OPTIONS[toks[i].lower()]
        i += 1
        if nargs is None:
            taken = 0
            while i < len(toks) - 1 and taken < 3:
                try:
                    float(toks[i])
                except ValueError:
                    break
                i += 1
                taken += 1
        else:
            i += nargs
    return " ".join(toks[i:])


def _texture_for(ctx, mat, materials, cache, have_lib) -> Texture | None:
    if mat is None:
        return None
    if mat not in materials:
        if have_lib and mat not in cache:
            ctx.warnings.append(f"material {mat!r} is not defined in the material libraries")
            cache[mat] = None
        return None
    fpath = materials[mat]
    if fpath is None:
        return None
    if fpath in cache:
        return cache[fpath]
    tex = None
    target = fpath
    ctx.deps.add_path(fpath)  # listed even when missing (as is the fallback looked for below)
    if not os.path.isfile(target):
        alt = os.path.join(os.path.dirname(ctx.path), os.path.basename(fpath))
        ctx.deps.add_path(alt)
        target = alt if os.path.isfile(alt) else None
    if target is None:
        ctx.warnings.append(f"texture {os.path.basename(fpath)!r} of material {mat!r} not found; no texture")
    else:
        try:
            with open(target, "rb") as fh:
                tex = checked_texture(os.path.basename(target), fh.read(), ctx.warnings.append,
                                      f"texture {os.path.basename(target)!r} of material {mat!r}")
        except OSError as exc:
            ctx.warnings.append(f"texture {os.path.basename(fpath)!r} unreadable ({exc.strerror}); no texture")
    cache[fpath] = tex
    return tex


def _mtl_statements(text: str):
    """``(keyword lower-cased, rest stripped)`` of each statement of a .mtl file's text (backslash
    line continuations joined; blank lines and ``#`` comment lines skipped)."""
    for line in text.replace("\\\r\n", " ").replace("\\\n", " ").splitlines():
        bits = line.strip().split(None, 1)
        if not bits or bits[0].startswith("#"):
            continue
        yield bits[0].lower(), (bits[1].strip() if len(bits) > 1 else "")


# ---------------------------------------------------------------------------------------------
# Materials for decoded previews (docs/format.md 9.2)
# ---------------------------------------------------------------------------------------------

#: sampler of every OBJ texture: repeat (MTL maps tile)
_REPEAT = {"wrapS": 10497, "wrapT": 10497}


def materials(path: str, parts: list[dict], out: MaterialSet) -> list[dict | None]:
    """The ``.mtl`` material of each manifest part's ``usemtl`` (recorded in its ``source``) as
    glTF 2.0 core, or None (no ``usemtl``, or a material no library defines: a warning).

    ``Kd`` -> base colour factor, ``map_Kd`` -> base colour texture, ``d`` (or ``1 - Tr``) ->
    alpha (BLEND when < 1), ``norm`` / ``map_Bump`` / ``bump`` -> normal texture (``-bm`` ->
    scale), ``Ke`` / ``map_Ke`` -> emissive, ``Pm`` -> metallic (default 0), ``Pr`` ->
    roughness, else ``sqrt(2 / (Ns + 2))`` from the Phong exponent ``Ns``, else 1. Textures are
    looked for where the .mtl names them, then beside the .obj; a missing one is a warning.
    Raises ``OSError`` when the .obj cannot be read.
    """
    reader = _MtlMaterials(path, out)
    per_part, cache = [], {}
    for p in parts:
        mk = re.search(r" usemtl (.+)$", str(p.get("source", "")))
        name = mk.group(1) if mk else None
        if name is not None and name not in cache:
            cache[name] = reader.material(name)
            if cache[name] is None and reader.mtl:
                out.warn(f"material {name!r} is not in the material libraries; default material")
        per_part.append(None if name is None else cache[name])
    return per_part


def _mtl_numbers(s: str, n: int) -> list[float] | None:
    """The first ``n`` numbers of ``s`` when there are ``n`` finite ones, else None."""
    try:
        v = [float(x) for x in s.split()[:n]]
    except ValueError:
        return None
    return v if len(v) == n and all(np.isfinite(v)) else None


class _MtlMaterials:
    """The statements of every material of an OBJ's ``mtllib`` files, made into glTF materials."""

    def __init__(self, path: str, out: MaterialSet) -> None:
        self.base = os.path.dirname(os.path.abspath(path))
        self.out = out
        self.mtl: dict[str, dict] = {}  # name -> {keyword: first value, "dir": the .mtl's folder}
        libs = re.findall(rb"^[ \t]*mtllib[ \t]+([^\r\n]+?)[ \t]*$", Path(path).read_bytes(), re.M)
        for lib in libs:
            name = lib.decode("utf-8", "replace")
            mpath = os.path.join(self.base, name.replace("\\", "/"))
            if not os.path.isfile(mpath):
                out.warn(f"material library {name!r} not found; its materials are left out of the preview")
                continue
            cur = None
            for kw, rest in _mtl_statements(Path(mpath).read_bytes().decode("utf-8", "replace")):
                if kw == "newmtl":
                    cur = self.mtl.setdefault(rest, {"dir": os.path.dirname(mpath)})
                elif cur is not None:
                    cur.setdefault(kw, rest)

    def texmap(self, m: dict, key: str, what: str) -> tuple[dict | None, dict]:
        """``(texture reference or None, options)`` of the map statement ``key`` of material ``m``."""
        if key not in m:
            return None, {}
        toks, opts, fname = m[key].split(), {}, []
        i = 0
        while i < len(toks):
            if toks[i].lower() == "-bm" and i + 1 < len(toks):
                opts["bm"] = toks[i + 1]
                i += 2
            elif toks[i].startswith("-") and i + 1 < len(toks):
                i += 2  # other options (one argument taken; -o/-s with three numbers skip below)
                while i < len(toks) - 1 and re.fullmatch(r"[-+0-9.eE]+", toks[i]):
                    i += 1
            else:
                fname.append(toks[i])
                i += 1
        name = " ".join(fname).replace("\\", "/")
        if not name:
            return None, opts
        cands = [os.path.join(m["dir"], name), os.path.join(self.base, os.path.basename(name))]
        found = next((c for c in cands if os.path.isfile(c)), None)
        if found is None:
            self.out.warn(f"{what} {os.path.basename(name)!r} not found; left out of the preview")
            return None, opts
        t = self.out.texture(self.out.image(("file", os.path.realpath(found)),
                                            lambda: (Path(found).read_bytes(), os.path.basename(found))), _REPEAT)
        return (None if t is None else {"index": t}), opts

    def material(self, name: str) -> dict | None:
        """Material ``name`` as glTF 2.0 core (see ``materials``), None when no library defines it."""
        m = self.mtl.get(name)
        if m is None:
            return None
        kd = _mtl_numbers(m.get("kd", ""), 3) or [1.0, 1.0, 1.0]
        alpha = 1.0
        if _mtl_numbers(m.get("d", ""), 1):
            alpha = _mtl_numbers(m["d"], 1)[0]
        elif _mtl_numbers(m.get("tr", ""), 1):
            alpha = 1.0 - _mtl_numbers(m["tr"], 1)[0]
        alpha = float(np.clip(alpha, 0.0, 1.0))
        rough = 1.0
        if _mtl_numbers(m.get("pr", ""), 1):
            rough = _mtl_numbers(m["pr"], 1)[0]
        elif _mtl_numbers(m.get("ns", ""), 1):
            rough = float(np.sqrt(2.0 / (max(_mtl_numbers(m["ns"], 1)[0], 0.0) + 2.0)))
        metal = _mtl_numbers(m.get("pm", ""), 1)[0] if _mtl_numbers(m.get("pm", ""), 1) else 0.0
        pbr = {"baseColorFactor": [float(np.clip(c, 0, 1)) for c in kd] + [alpha],
               "metallicFactor": float(np.clip(metal, 0, 1)), "roughnessFactor": float(np.clip(rough, 0, 1))}
        what = f"material {name!r}"
        ref, _ = self.texmap(m, "map_kd", f"{what} map_Kd")
        if ref:
            pbr["baseColorTexture"] = ref
        res = {"name": name, "pbrMetallicRoughness": pbr}
        for key in ("norm", "map_bump", "bump"):
            if key in m:
                ref, opts = self.texmap(m, key, f"{what} {key}")
                if ref:
                    bm = _mtl_numbers(opts.get("bm", ""), 1)
                    if bm:
                        ref["scale"] = bm[0]
                    res["normalTexture"] = ref
                break
        ke = _mtl_numbers(m.get("ke", ""), 3)
        ref, _ = self.texmap(m, "map_ke", f"{what} map_Ke")
        if ref:
            res["emissiveTexture"] = ref
            ke = ke or [1.0, 1.0, 1.0]
        if ke and any(ke):
            res["emissiveFactor"] = [float(np.clip(c, 0, 1)) for c in ke]
        if alpha < 1.0:
            res["alphaMode"] = "BLEND"
        return res


# ---------------------------------------------------------------------------------------------
# The format
# ---------------------------------------------------------------------------------------------

#: OBJ has no signature: an .obj file is read as OBJ unless its first bytes show another format
EXTENSIONS = {".obj": ("obj",)}

FORMAT = Format(name="obj", title="OBJ", extensions=EXTENSIONS, load=load, sniff=None, materials=materials,
                sidecars=(".mtl",))

__all__ = ["load", "materials", "EXTENSIONS", "FORMAT"]
