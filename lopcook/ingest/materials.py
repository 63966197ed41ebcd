"""``MaterialSet``: glTF 2.0 materials, textures, samplers and images gathered from a source.

Each format's material reader (``Format.materials``: ``gltf.materials``, ``obj.materials``,
``usd.materials``) turns its source's shading into glTF 2.0 core material dicts and adds the
textures they use here; ``lopcook.emit.preview`` hands the result to
``lopcook.emit.gltf_writer.write_gltf(materials=...)``. Indices are given in first-use order and
equal entries are stored once, so the same source and parts give the same lists (deterministic
bytes). Images are carried only when they are PNG or JPEG, decode completely and have no side over
``MAX_IMAGE_SIDE`` pixels; anything left out is one line in ``warnings``.
"""

from __future__ import annotations

import io
import json

from PIL import Image

#: Largest image side carried (px); a larger or undecodable image is left out with a warning.
MAX_IMAGE_SIDE = 8192

#: A material key (removed before writing) asking for the part's vertex colours as its base colour
#: (base colour factor white) when the part has them, else for this grey (linear, in [0, 1]).
BASE_FROM_VERTEX_COLOURS = "lopcook:vertex-colours-or-grey"

_MIME = {b"\x89PNG\r\n\x1a\n": "image/png", b"\xff\xd8\xff": "image/jpeg"}


def image_mime(data: bytes) -> str | None:
    """``"image/png"`` or ``"image/jpeg"`` from the magic bytes of ``data``, else None."""
    for magic, mime in _MIME.items():
        if data.startswith(magic):
            return mime
    return None


def image_readable(data: bytes) -> bool:
    """The image decodes completely and no side exceeds ``MAX_IMAGE_SIDE`` (checked on the
    header, before decoding)."""
    try:
        with Image.open(io.BytesIO(data)) as im:
            w, h = im.size
            if not (0 < w <= MAX_IMAGE_SIDE and 0 < h <= MAX_IMAGE_SIDE):
                return False
            im.load()
            return True
    except Exception:  # noqa: BLE001 - any decoder failure means: not usable
        return False


class MaterialSet:
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
        """Record one warning line (once)."""
        if msg not in self.warnings:
            self.warnings.append(msg)

    def image(self, key, loader) -> int | None:
        """Index of the image ``key``; ``loader() -> (bytes, name) | None`` runs once per key.
        None when the image is missing, not PNG/JPEG or does not decode (a warning says which)."""
        if key not in self._img:
            got = loader()
            idx = None
            if got is not None:
                data, name = got
                mime = image_mime(data)
                if mime is None:
                    self.warn(f"image {name!r} is not PNG or JPEG; left out of the preview")
                elif not image_readable(data):
                    self.warn(f"image {name!r} cannot be decoded; left out of the preview")
                else:
                    self.images.append({"name": name, "mimeType": mime, "data": data})
                    idx = len(self.images) - 1
            self._img[key] = idx
        return self._img[key]

    def sampler(self, sampler: dict | None) -> int | None:
        """Index of the glTF sampler ``sampler`` (None for none: the viewer's default)."""
        if not sampler:
            return None
        key = json.dumps(sampler, sort_keys=True)
        if key not in self._smp:
            self.samplers.append(sampler)
            self._smp[key] = len(self.samplers) - 1
        return self._smp[key]

    def texture(self, image: int | None, sampler: dict | None) -> int | None:
        """Index of the texture of image index ``image`` with ``sampler``; None without an image."""
        if image is None:
            return None
        s = self.sampler(sampler)
        key = (image, s)
        if key not in self._tex:
            self.textures.append({"source": image} if s is None else {"sampler": s, "source": image})
            self._tex[key] = len(self.textures) - 1
        return self._tex[key]

    def material(self, mat: dict) -> int:
        """Index of the material ``mat`` (equal dicts share one index)."""
        key = json.dumps(mat, sort_keys=True)
        if key not in self._mat:
            self.materials.append(mat)
            self._mat[key] = len(self.materials) - 1
        return self._mat[key]

    def as_writer_arg(self) -> dict:
        """``write_gltf``'s ``materials`` argument."""
        return {"materials": self.materials, "textures": self.textures, "samplers": self.samplers,
                "images": self.images}


def untextured(mat: dict) -> dict:
    """``mat`` without texture references (for a part decoded without UVs)."""
    out = {k: v for k, v in mat.items() if k not in ("normalTexture", "occlusionTexture", "emissiveTexture")}
    if "pbrMetallicRoughness" in out:
        out["pbrMetallicRoughness"] = {k: v for k, v in out["pbrMetallicRoughness"].items()
                                       if k not in ("baseColorTexture", "metallicRoughnessTexture")}
    return out


def resolve_vertex_colour_base(mat: dict, coloured: bool) -> dict:
    """``mat`` with its ``BASE_FROM_VERTEX_COLOURS`` request settled: base colour factor white for a
    part with vertex colours, else the requested grey (alpha 1). Other materials pass unchanged."""
    if BASE_FROM_VERTEX_COLOURS not in mat:
        return mat
    grey = 1.0 if coloured else mat[BASE_FROM_VERTEX_COLOURS]
    out = {k: v for k, v in mat.items() if k != BASE_FROM_VERTEX_COLOURS}
    out["pbrMetallicRoughness"] = dict(out["pbrMetallicRoughness"], baseColorFactor=[grey] * 3 + [1.0])
    return out


__all__ = ["MaterialSet", "MAX_IMAGE_SIDE", "BASE_FROM_VERTEX_COLOURS", "image_mime", "image_readable",
           "untextured", "resolve_vertex_colour_base"]
