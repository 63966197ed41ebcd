"""Materials, textures and instancing for decoded previews (``lopcook decode``).

A ``.lop`` container stores geometry only (positions, normals, UVs, colours, indices). To make a
decoded preview look like the source in any glTF viewer, ``decode`` reads the materials again
from the *source* asset, here, without changing the container or the importers:

* ``find_source(container_path, manifest, given)``: the source file to read. ``given`` (``decode
  --source``) or, by default, the manifest's ``source.file`` looked up beside the container. It is
  used only when its sha256 equals the manifest's ``source.sha256``; otherwise the preview is
  geometry only and the reason is one line (``None, reason``).
* ``source_materials(path, fmt, parts)``: one glTF 2.0 core material per manifest part (or None:
  the default material), with the textures, samplers and images it uses, as
  ``lopcook.emit.gltf_writer.write_gltf(materials=...)`` takes them.

  - glTF/GLB: the source's own ``materials`` / ``textures`` / ``samplers`` / ``images``, found by
    the part's ``mesh_key`` ``mesh{mi}/prim{k}`` (see ``lopcook.ingest.gltf``): base colour
    (factor and texture), metallic-roughness (factors and texture), normal (with ``scale``),
    occlusion (with ``strength``), emissive (factor and texture), ``alphaMode``, ``alphaCutoff``,
    ``doubleSided``. Images (from a bufferView, a data URI or a relative file) are embedded in
    the output's buffer. Material extensions are not carried (a warning names them). A texture
    read through another UV set than the base colour's (the one set the container keeps), or
    one whose image is not PNG/JPEG or cannot be read, is left out with a warning.
  - OBJ: the ``.mtl`` of the part's ``usemtl`` (recorded in ``parts[].source``): ``Kd`` ->
    base colour factor, ``map_Kd`` -> base colour texture, ``d`` (or ``1 - Tr``) -> alpha (BLEND
    when < 1), ``norm`` / ``map_Bump`` / ``bump`` -> normal texture (``-bm`` -> scale), ``Ke``
    / ``map_Ke`` -> emissive, ``Pm`` / ``Pr`` -> metallic / roughness (default 0 and, from
    ``Ns`` (Phong exponent), ``sqrt(2 / (Ns + 2))``, else 1).
  - USD: the ``UsdPreviewSurface`` bound to the part's prim (``parts[].source``, without the
    ``[instance k]`` suffix): ``diffuseColor`` (value or ``UsdUVTexture``), ``metallic`` and
    ``roughness`` (values; textures packed into one metallic-roughness image, G = roughness,
    B = metallic, from the channel each connection reads), ``opacity`` (< 1: BLEND) and
    ``opacityThreshold`` (> 0: MASK with that cutoff), ``normal``, ``emissiveColor`` and
    ``occlusion`` textures; the mesh's ``doubleSided``. A prim without a bound preview surface
    gets UsdPreviewSurface's defaults (metallic 0, roughness 0.5; diffuse white when the part
    has vertex colours, its ``displayColor``, else the 0.18 default grey) instead of glTF's
    metallic default material.

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

import base64
import hashlib
import io
import json
import os
import re
import struct
from pathlib import Path
from urllib.parse import unquote

import numpy as np

from ..lop.reader import decode_positions

#: A copy becomes an instance only if the fitted transform reproduces its level-24 positions within
#: this many cells of the 24-bit grid (the decode itself is exact to half a cell).
INSTANCE_TOL_STEPS = 8

#: Largest image side carried (px); a larger or undecodable image is left out with a warning.
MAX_IMAGE_SIDE = 8192

_MIME = {b"\x89PNG\r\n\x1a\n": "image/png", b"\xff\xd8\xff": "image/jpeg"}
_WRAP_USD = {"repeat": 10497, "clamp": 33071, "mirror": 33648}


def _mime(data: bytes) -> str | None:
    for magic, mime in _MIME.items():
        if data.startswith(magic):
            return mime
    return None


def _sha256(path: str) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


# ---------------------------------------------------------------------------------------------
# Which source
# ---------------------------------------------------------------------------------------------


def source_candidate(container_path: str, manifest: dict, given: str | None) -> str | None:
    """The path ``find_source`` looks at (whether or not it exists): ``given``, else the
    manifest's ``source.file`` beside the container; None when there is neither. ``decode``
    refuses an output there (it never overwrites what it reads)."""
    if given is not None:
        return given
    src = manifest.get("source") if isinstance(manifest.get("source"), dict) else {}
    name = src.get("file")
    if not isinstance(name, str) or not name:
        return None
    return os.path.join(os.path.dirname(os.path.abspath(container_path)), os.path.basename(name))


def find_source(container_path: str, manifest: dict, given: str | None) -> tuple[str | None, str | None]:
    """``(path, None)`` when the source can give the preview its materials, else ``(None, reason)``.

    ``given`` (``decode --source``) or ``<container dir>/<source.file>``; used only when it is a
    regular file whose sha256 equals ``manifest["source"]["sha256"]``. ``reason`` is one line.
    """
    src = manifest.get("source") if isinstance(manifest.get("source"), dict) else {}
    want = src.get("sha256")
    if given is None:
        name = src.get("file")
        if not isinstance(name, str) or not name:
            return None, "the container names no source file (pass --source SRC)"
        path = os.path.join(os.path.dirname(os.path.abspath(container_path)), os.path.basename(name))
        if not os.path.exists(path):
            return None, f"source {os.path.basename(name)!r} not found beside {container_path} (pass --source SRC)"
        flag = "source"
    else:
        path, flag = given, "--source"
        if not os.path.exists(path):
            return None, f"--source {given}: not found"
    if not os.path.isfile(path):
        return None, f"{flag} {path}: not a regular file"
    if not isinstance(want, str):
        return None, f"the container records no source sha256, so {path} cannot be checked"
    try:
        have = _sha256(path)
    except OSError as exc:
        return None, f"{flag} {path}: unreadable ({exc.strerror})"
    if have != want:
        return None, f"{flag} {path} is not the source this container was cooked from (sha256 differs)"
    return path, None


# ---------------------------------------------------------------------------------------------
# Materials
# ---------------------------------------------------------------------------------------------


class _Collector:
    """Materials, textures, samplers and images in first-use order (deterministic indices)."""

    def __init__(self) -> None:
        self.materials: list[dict] = []
        self.textures: list[dict] = []
        self.samplers: list[dict] = []
        self.images: list[dict] = []
        self.warnings: list[str] = []
        self._mat: dict = {}
        self._tex: dict = {}
        self._smp: dict = {}
        self._img: dict = {}

    def warn(self, msg: str) -> None:
        if msg not in self.warnings:
            self.warnings.append(msg)

    def image(self, key, loader) -> int | None:
        """Index of the image ``key``; ``loader() -> (bytes, name) | None`` runs once per key."""
        if key not in self._img:
            got = loader()
            idx = None
            if got is not None:
                data, name = got
                mime = _mime(data)
                if mime is None:
                    self.warn(f"image {name!r} is not PNG or JPEG; left out of the preview")
                elif not _readable(data):
                    self.warn(f"image {name!r} cannot be decoded; left out of the preview")
                else:
                    self.images.append({"name": name, "mimeType": mime, "data": data})
                    idx = len(self.images) - 1
            self._img[key] = idx
        return self._img[key]

    def sampler(self, sampler: dict | None) -> int | None:
        if not sampler:
            return None
        key = json.dumps(sampler, sort_keys=True)
        if key not in self._smp:
            self.samplers.append(sampler)
            self._smp[key] = len(self.samplers) - 1
        return self._smp[key]

    def texture(self, image: int | None, sampler: dict | None) -> int | None:
        if image is None:
            return None
        s = self.sampler(sampler)
        key = (image, s)
        if key not in self._tex:
            self.textures.append({"source": image} if s is None else {"sampler": s, "source": image})
            self._tex[key] = len(self.textures) - 1
        return self._tex[key]

    def material(self, mat: dict) -> int:
        key = json.dumps(mat, sort_keys=True)
        if key not in self._mat:
            self.materials.append(mat)
            self._mat[key] = len(self.materials) - 1
        return self._mat[key]

    def as_writer_arg(self) -> dict:
        return {"materials": self.materials, "textures": self.textures, "samplers": self.samplers,
                "images": self.images}


def _readable(data: bytes) -> bool:
    """The image decodes completely and no side exceeds ``MAX_IMAGE_SIDE`` (checked on the
    header, before decoding)."""
    try:
        from PIL import Image

        with Image.open(io.BytesIO(data)) as im:
            w, h = im.size
            if not (0 < w <= MAX_IMAGE_SIDE and 0 < h <= MAX_IMAGE_SIDE):
                return False
            im.load()
            return True
    except Exception:  # noqa: BLE001 - any decoder failure means: not usable
        return False


def _untextured(mat: dict) -> dict:
    """``mat`` without texture references (for a part decoded without UVs)."""
    out = {k: v for k, v in mat.items() if k not in ("normalTexture", "occlusionTexture", "emissiveTexture")}
    if "pbrMetallicRoughness" in out:
        out["pbrMetallicRoughness"] = {k: v for k, v in out["pbrMetallicRoughness"].items()
                                       if k not in ("baseColorTexture", "metallicRoughnessTexture")}
    return out


#: marks USD's no-material fallback until the part's vertex colours are known
_FALLBACK = "lopcook:usd-fallback"
#: UsdPreviewSurface's diffuseColor default (linear)
USD_DEFAULT_DIFFUSE = 0.18


def source_materials(path: str, fmt: str, parts: list[dict], has_uvs: list[bool],
                     has_colors: list[bool] | None = None) -> tuple[dict, list, list[str]]:
    """``(materials for write_gltf, material index or None per part, warnings)``.

    ``parts`` are manifest part entries (``mesh_key``, ``source``); ``has_uvs[i]`` says whether
    part i is decoded with UVs (a part without gets the material's untextured variant), and
    ``has_colors[i]`` (default: none have) whether with vertex colours: a USD prim without a
    preview surface is drawn in its ``displayColor`` (the vertex colours, base colour white)
    or, without one, in UsdPreviewSurface's default diffuse ``USD_DEFAULT_DIFFUSE`` grey.
    Unreadable sources raise nothing: they give no materials and a warning.
    """
    col = _Collector()
    fmt = (fmt or "").lower()
    try:
        if fmt in ("gltf", "glb"):
            per_part = _gltf(path, parts, col)
        elif fmt == "obj":
            per_part = _obj(path, parts, col)
        elif fmt.startswith("usd"):
            per_part = _usd(path, parts, col)
        else:
            return {}, [None] * len(parts), [f"no materials for source format {fmt!r}"]
    except (OSError, ValueError, KeyError, TypeError, IndexError, RuntimeError, struct.error) as exc:
        return {}, [None] * len(parts), [f"materials of {os.path.basename(path)} unreadable ({exc}); "
                                         "decoded geometry only"]
    out = []
    has_colors = [False] * len(parts) if has_colors is None else has_colors
    for mat, uv, colored in zip(per_part, has_uvs, has_colors):
        if mat is None:
            out.append(None)
            continue
        if _FALLBACK in mat:
            grey = 1.0 if colored else USD_DEFAULT_DIFFUSE
            mat = {k: v for k, v in mat.items() if k != _FALLBACK}
            mat["pbrMetallicRoughness"] = dict(mat["pbrMetallicRoughness"], baseColorFactor=[grey] * 3 + [1.0])
        out.append(col.material(mat if uv else _untextured(mat)))
    return col.as_writer_arg(), out, col.warnings


# --- glTF ------------------------------------------------------------------------------------


def _gltf(path: str, parts: list[dict], col: _Collector) -> list:
    raw = Path(path).read_bytes()
    bin_chunk = None
    if raw[:4] == b"glTF":
        jlen, jtype = struct.unpack_from("<I4s", raw, 12)
        if jtype != b"JSON":
            raise ValueError("GLB has no JSON chunk first")
        doc = json.loads(raw[20:20 + jlen])
        off = 20 + jlen
        if off + 8 <= len(raw):
            blen, btype = struct.unpack_from("<I4s", raw, off)
            if btype == b"BIN\0":
                bin_chunk = raw[off + 8: off + 8 + blen]
    else:
        doc = json.loads(raw)
    base = os.path.dirname(os.path.abspath(path))
    buffers: dict = {}

    def uri_bytes(uri: str, what: str) -> bytes | None:
        if uri.startswith("data:"):
            head, _, payload = uri.partition(",")
            return base64.b64decode(payload) if head.endswith(";base64") else unquote(payload).encode("latin-1")
        rel = unquote(uri)
        if "://" in rel or os.path.isabs(rel):
            col.warn(f"{what}: URI {uri!r} is not a relative file; left out of the preview")
            return None
        p = os.path.join(base, rel)
        if not os.path.isfile(p):
            col.warn(f"{what}: file {rel!r} not found; left out of the preview")
            return None
        return Path(p).read_bytes()

    def buffer(i: int) -> bytes | None:
        if i not in buffers:
            b = doc["buffers"][i]
            buffers[i] = uri_bytes(b["uri"], f"buffer {i}") if "uri" in b else bin_chunk
        return buffers[i]

    def image(i: int):
        img = doc["images"][i]
        name = img.get("name") or (os.path.basename(unquote(img["uri"])) if "uri" in img and
                                   not img["uri"].startswith("data:") else f"image{i}")
        if "uri" in img:
            data = uri_bytes(img["uri"], f"image {i}")
        else:
            v = doc["bufferViews"][img["bufferView"]]
            b = buffer(v["buffer"])
            data = None if b is None else b[v.get("byteOffset", 0): v.get("byteOffset", 0) + v["byteLength"]]
        return None if not data else (bytes(data), name)

    samplers = doc.get("samplers") or []
    dropped_ext: set = set()

    def tex_ref(ref, uv_set: int, what: str) -> dict | None:
        if not isinstance(ref, dict) or "index" not in ref:
            return None
        if ref.get("texCoord", 0) != uv_set:
            col.warn(f"{what} reads TEXCOORD_{ref.get('texCoord', 0)}, the container keeps TEXCOORD_{uv_set} "
                     "only; left out of the preview")
            return None
        dropped_ext.update((ref.get("extensions") or {}).keys())
        tex = doc["textures"][ref["index"]]
        if "source" not in tex:
            col.warn(f"{what}: texture {ref['index']} has no PNG/JPEG source; left out of the preview")
            return None
        smp = None
        if "sampler" in tex:
            s = samplers[tex["sampler"]]
            smp = {k: s[k] for k in ("magFilter", "minFilter", "wrapS", "wrapT") if k in s}
        t = col.texture(col.image(("gltf", tex["source"]), lambda: image(tex["source"])), smp)
        if t is None:
            return None
        out = {"index": t}
        for k in ("scale", "strength"):
            if k in ref:
                out[k] = ref[k]
        return out

    def material(mi: int) -> dict:
        m = doc["materials"][mi]
        dropped_ext.update((m.get("extensions") or {}).keys())
        pbr_in = m.get("pbrMetallicRoughness") or {}
        uv_set = int((pbr_in.get("baseColorTexture") or {}).get("texCoord", 0))
        what = f"material {mi}" + (f" {m['name']!r}" if m.get("name") else "")
        out: dict = {"name": m["name"]} if isinstance(m.get("name"), str) else {}
        pbr = {k: pbr_in[k] for k in ("baseColorFactor", "metallicFactor", "roughnessFactor") if k in pbr_in}
        for k in ("baseColorTexture", "metallicRoughnessTexture"):
            r = tex_ref(pbr_in.get(k), uv_set, f"{what} {k}")
            if r is not None:
                pbr[k] = r
        out["pbrMetallicRoughness"] = pbr
        for k in ("normalTexture", "occlusionTexture", "emissiveTexture"):
            r = tex_ref(m.get(k), uv_set, f"{what} {k}")
            if r is not None:
                out[k] = r
        for k in ("emissiveFactor", "alphaMode", "alphaCutoff", "doubleSided"):
            if k in m:
                out[k] = m[k]
        if out.get("alphaMode") != "MASK":
            out.pop("alphaCutoff", None)
        return out

    cache: dict = {}
    per_part = []
    for p in parts:
        mk = re.fullmatch(r"mesh(\d+)/prim(\d+)", str(p.get("mesh_key", "")))
        mat = None
        if mk:
            prim = doc["meshes"][int(mk.group(1))]["primitives"][int(mk.group(2))]
            mi = prim.get("material")
            if mi is not None:
                if mi not in cache:
                    cache[mi] = material(mi)
                mat = cache[mi]
        per_part.append(mat)
    if dropped_ext:
        col.warn(f"material extensions not carried into the preview: {', '.join(sorted(dropped_ext))}")
    return per_part


# --- OBJ -------------------------------------------------------------------------------------


def _obj(path: str, parts: list[dict], col: _Collector) -> list:
    base = os.path.dirname(os.path.abspath(path))
    libs = re.findall(rb"^[ \t]*mtllib[ \t]+([^\r\n]+?)[ \t]*$", Path(path).read_bytes(), re.M)
    mtl: dict[str, dict] = {}
    for lib in libs:
        name = lib.decode("utf-8", "replace")
        mpath = os.path.join(base, name.replace("\\", "/"))
        if not os.path.isfile(mpath):
            col.warn(f"material library {name!r} not found; its materials are left out of the preview")
            continue
        text = Path(mpath).read_bytes().decode("utf-8", "replace")
        cur = None
        for line in text.replace("\\\r\n", " ").replace("\\\n", " ").splitlines():
            bits = line.strip().split(None, 1)
            if not bits or bits[0].startswith("#"):
                continue
            kw, rest = bits[0].lower(), (bits[1].strip() if len(bits) > 1 else "")
            if kw == "newmtl":
                cur = mtl.setdefault(rest, {"dir": os.path.dirname(mpath)})
            elif cur is not None:
                cur.setdefault(kw, rest)

    def nums(s: str, n: int) -> list[float] | None:
        try:
            v = [float(x) for x in s.split()[:n]]
        except ValueError:
            return None
        return v if len(v) == n and all(np.isfinite(v)) else None

    def texmap(m: dict, key: str, what: str) -> tuple[dict | None, dict]:
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
        cands = [os.path.join(m["dir"], name), os.path.join(base, os.path.basename(name))]
        found = next((c for c in cands if os.path.isfile(c)), None)
        if found is None:
            col.warn(f"{what} {os.path.basename(name)!r} not found; left out of the preview")
            return None, opts
        t = col.texture(col.image(("file", os.path.realpath(found)),
                                  lambda: (Path(found).read_bytes(), os.path.basename(found))),
                        {"wrapS": 10497, "wrapT": 10497})
        return (None if t is None else {"index": t}), opts

    def material(name: str) -> dict | None:
        m = mtl.get(name)
        if m is None:
            return None
        kd = nums(m.get("kd", ""), 3) or [1.0, 1.0, 1.0]
        alpha = 1.0
        if nums(m.get("d", ""), 1):
            alpha = nums(m["d"], 1)[0]
        elif nums(m.get("tr", ""), 1):
            alpha = 1.0 - nums(m["tr"], 1)[0]
        alpha = float(np.clip(alpha, 0.0, 1.0))
        rough = 1.0
        if nums(m.get("pr", ""), 1):
            rough = nums(m["pr"], 1)[0]
        elif nums(m.get("ns", ""), 1):
            rough = float(np.sqrt(2.0 / (max(nums(m["ns"], 1)[0], 0.0) + 2.0)))
        metal = nums(m.get("pm", ""), 1)[0] if nums(m.get("pm", ""), 1) else 0.0
        pbr = {"baseColorFactor": [float(np.clip(c, 0, 1)) for c in kd] + [alpha],
               "metallicFactor": float(np.clip(metal, 0, 1)), "roughnessFactor": float(np.clip(rough, 0, 1))}
        what = f"material {name!r}"
        ref, _ = texmap(m, "map_kd", f"{what} map_Kd")
        if ref:
            pbr["baseColorTexture"] = ref
        out = {"name": name, "pbrMetallicRoughness": pbr}
        for key in ("norm", "map_bump", "bump"):
            if key in m:
                ref, opts = texmap(m, key, f"{what} {key}")
                if ref:
                    bm = nums(opts.get("bm", ""), 1)
                    if bm:
                        ref["scale"] = bm[0]
                    out["normalTexture"] = ref
                break
        ke = nums(m.get("ke", ""), 3)
        ref, _ = texmap(m, "map_ke", f"{what} map_Ke")
        if ref:
            out["emissiveTexture"] = ref
            ke = ke or [1.0, 1.0, 1.0]
        if ke and any(ke):
            out["emissiveFactor"] = [float(np.clip(c, 0, 1)) for c in ke]
        if alpha < 1.0:
            out["alphaMode"] = "BLEND"
        return out

    per_part, cache = [], {}
    for p in parts:
        mk = re.search(r" usemtl (.+)$", str(p.get("source", "")))
        name = mk.group(1) if mk else None
        if name is not None and name not in cache:
            cache[name] = material(name)
            if cache[name] is None and mtl:
                col.warn(f"material {name!r} is not in the material libraries; default material")
        per_part.append(None if name is None else cache[name])
    return per_part


# --- USD -------------------------------------------------------------------------------------


def _usd(path: str, parts: list[dict], col: _Collector) -> list:
    from pxr import Ar, Usd, UsdGeom, UsdShade

    stage = Usd.Stage.Open(path)
    if stage is None:
        raise ValueError("the stage does not open")

    def read_asset(asset) -> tuple[bytes, str] | None:
        resolved = asset.resolvedPath
        if not resolved:
            col.warn(f"texture @{asset.path}@ not found; left out of the preview")
            return None
        handle = Ar.GetResolver().OpenAsset(Ar.ResolvedPath(resolved))
        data = bytes(handle.GetBuffer()) if handle else b""
        if not data:
            col.warn(f"texture @{asset.path}@ unreadable; left out of the preview")
            return None
        return data, os.path.basename(asset.path)

    def source_of(shader, name: str):
        """(value, None) or (None, (UsdUVTexture shader, output channel name)) for an input."""
        inp = shader.GetInput(name)
        if not inp:
            return None, None
        for attr in inp.GetValueProducingAttributes():
            prim = attr.GetPrim()
            if prim.IsA(UsdShade.Shader) and attr.GetName().startswith("outputs:"):
                src = UsdShade.Shader(prim)
                if src.GetShaderId() == "UsdUVTexture":
                    return None, (src, attr.GetName().split(":", 1)[1])
                continue
            return attr.Get(), None
        return None, None

    def texture(src) -> int | None:
        shader, _ = src
        f = shader.GetInput("file")
        asset = f.Get() if f else None
        if asset is None or not asset.path:
            return None
        smp = {}
        for key, gl in (("wrapS", "wrapS"), ("wrapT", "wrapT")):
            w = shader.GetInput(key)
            v = w.Get() if w else None
            if v in _WRAP_USD:
                smp[gl] = _WRAP_USD[v]
        return col.texture(col.image(("usd", asset.resolvedPath or asset.path), lambda: read_asset(asset)),
                           smp or None)

    def packed_mr(metal_src, rough_src) -> int | None:
        """One metallic-roughness PNG (G roughness, B metallic) from USD's separate textures."""
        from PIL import Image

        chans = {}
        for label, src in (("metallic", metal_src), ("roughness", rough_src)):
            if src is None:
                continue
            f = src[0].GetInput("file")
            asset = f.Get() if f else None
            got = read_asset(asset) if asset is not None and asset.path else None
            if got is None or not _readable(got[0]):
                continue
            with Image.open(io.BytesIO(got[0])) as im:
                band = "rgba".find(src[1]) if src[1] in ("r", "g", "b", "a") else 0
                im = im.convert("RGBA")
                chans[label] = (np.asarray(im)[:, :, band], got[1])
        if not chans:
            return None
        h = max(c[0].shape[0] for c in chans.values())
        w = max(c[0].shape[1] for c in chans.values())
        img = np.full((h, w, 3), 255, np.uint8)
        for label, slot in (("roughness", 1), ("metallic", 2)):
            if label in chans:
                band = Image.fromarray(chans[label][0]).resize((w, h), Image.BILINEAR) \
                    if chans[label][0].shape != (h, w) else Image.fromarray(chans[label][0])
                img[:, :, slot] = np.asarray(band)
        buf = io.BytesIO()
        Image.fromarray(img, "RGB").save(buf, format="PNG", optimize=False)
        key = ("usd-mr",) + tuple(sorted(c[1] for c in chans.values()))
        return col.texture(col.image(key, lambda: (buf.getvalue(), "metallicRoughness.png")), None)

    def material(prim) -> dict:
        mat = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()[0]
        shader = mat.ComputeSurfaceSource()[0] if mat else None
        double = bool(UsdGeom.Mesh(prim).GetDoubleSidedAttr().Get()) if prim.IsA(UsdGeom.Mesh) else False
        if not shader or shader.GetShaderId() != "UsdPreviewSurface":
            out = {_FALLBACK: True, "pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 0.5}}
            if double:
                out["doubleSided"] = True
            return out
        pbr: dict = {}
        out: dict = {"name": mat.GetPrim().GetName(), "pbrMetallicRoughness": pbr}
        value, src = source_of(shader, "diffuseColor")
        rgb = [1.0, 1.0, 1.0] if src is not None else \
            [float(x) for x in (value if value is not None else (0.18, 0.18, 0.18))]
        opacity, osrc = source_of(shader, "opacity")
        alpha = 1.0 if opacity is None else float(np.clip(opacity, 0.0, 1.0))
        pbr["baseColorFactor"] = [float(np.clip(c, 0, 1)) for c in rgb] + [alpha]
        if src is not None:
            t = texture(src)
            if t is not None:
                pbr["baseColorTexture"] = {"index": t}
        mv, msrc = source_of(shader, "metallic")
        rv, rsrc = source_of(shader, "roughness")
        pbr["metallicFactor"] = 1.0 if msrc is not None else float(np.clip(0.0 if mv is None else mv, 0, 1))
        pbr["roughnessFactor"] = 1.0 if rsrc is not None else float(np.clip(0.5 if rv is None else rv, 0, 1))
        if msrc is not None or rsrc is not None:
            t = packed_mr(msrc, rsrc)
            if t is not None:
                pbr["metallicRoughnessTexture"] = {"index": t}
            else:  # textures unreadable: back to the defaults
                pbr["metallicFactor"] = 0.0 if msrc is not None else pbr["metallicFactor"]
                pbr["roughnessFactor"] = 0.5 if rsrc is not None else pbr["roughnessFactor"]
        for usd_name, key in (("normal", "normalTexture"), ("occlusion", "occlusionTexture"),
                              ("emissiveColor", "emissiveTexture")):
            v, s = source_of(shader, usd_name)
            if s is not None:
                t = texture(s)
                if t is not None:
                    out[key] = {"index": t}
                    if key == "emissiveTexture":
                        out["emissiveFactor"] = [1.0, 1.0, 1.0]
            elif usd_name == "emissiveColor" and v is not None and any(float(c) > 0 for c in v):
                out["emissiveFactor"] = [float(np.clip(c, 0, 1)) for c in v]
        threshold, _ = source_of(shader, "opacityThreshold")
        if threshold is not None and float(threshold) > 0 and (alpha < 1.0 or osrc is not None):
            out["alphaMode"], out["alphaCutoff"] = "MASK", float(threshold)
        elif alpha < 1.0:
            out["alphaMode"] = "BLEND"
        if double:
            out["doubleSided"] = True
        return out

    per_part = []
    cache: dict = {}
    for p in parts:
        prim_path = re.sub(r" \[instance \d+\]$", "", str(p.get("source", "")))
        if prim_path not in cache:
            prim = stage.GetPrimAtPath(prim_path) if prim_path.startswith("/") else None
            try:
                cache[prim_path] = material(prim) if prim else None
            except Exception as exc:  # noqa: BLE001 - a broken shading network only loses the material
                why = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
                col.warn(f"{prim_path}: material unreadable ({why}); default material")
                cache[prim_path] = None
        per_part.append(cache[prim_path])
    return per_part


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
            if fine_lead is None:
                fine_lead = decode_positions(c, lead, lods[lead], 24)[2].astype(np.float64)
            fit = fit_trs(fine_lead, decode_positions(c, i, lods[i], 24)[2].astype(np.float64), tol)
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


__all__ = ["source_candidate", "find_source", "source_materials", "instance_nodes", "fit_trs", "tangents", "preview", "INSTANCE_TOL_STEPS"]
