"""What every attribute codec declares, and the input checks they share.

An attribute codec stores one per-vertex attribute of ``components`` float values (normals: 3,
UVs: 2, colours: 4) as ``len(field_widths(b))`` unsigned integer fields of the packed attribute
record (docs/format.md section 7.2), at ``b`` bits per field where ``bits[0] <= b <= bits[1]``.
Every encoder is vectorised numpy and deterministic (IEEE-exact operations in a fixed order);
every decoder is defined as float32 operations, each rounded once with no fused multiply-add, so
the shader function ``shader`` (shaders/decode_attributes.glsl and .hlsl) reproduces it bit for
bit.

Adding a codec: one module in this package with a ``Codec`` subclass, and one line in
``CODECS`` (``lopcook.lop.codecs``). The record, the manifest validator, settings, CLI flags,
the simplifier's attribute transfer and the bound-based bit choice (``error_model``), the GPU
decoder check and ``lopcook decode`` read the registry.
"""

from __future__ import annotations

import numpy as np

from ...errors import LopcookError

F4 = np.dtype("<f4")
F32 = np.float32


def check_bits(b, lohi: tuple[int, int], what: str) -> int:
    """``b`` as an int when it is an integer in ``[lohi[0], lohi[1]]``; else a usage error naming
    ``what`` (the codec's singular name)."""
    if isinstance(b, bool) or not isinstance(b, (int, np.integer)) or not lohi[0] <= int(b) <= lohi[1]:
        raise LopcookError("usage", None, f"{what} bits must be an integer in [{lohi[0]}, {lohi[1]}], got {b!r}")
    return int(b)


def float_input(a, width: int, name: str) -> np.ndarray:
    """``(n, width)`` float64 copy of a numeric array; LopcookError("emit") for another shape, a
    non-numeric dtype, NaN or Inf."""
    arr = np.asarray(a)
    if arr.ndim != 2 or arr.shape[1] != width:
        raise LopcookError("emit", None, f"{name} must be (n, {width}), got shape {arr.shape}")
    if arr.dtype.kind not in "fiu":
        raise LopcookError("emit", None, f"{name} must be numeric, got {arr.dtype}")
    arr = arr.astype(np.float64)
    if arr.size and not np.isfinite(arr).all():
        bad = int((~np.isfinite(arr)).any(axis=1).sum())
        raise LopcookError("emit", None, f"{bad} {name} contain NaN or Inf",
                           hint="fix or drop the attribute before emitting")
    return arr


def codes_input(codes, width: int, bits: int, name: str) -> np.ndarray:
    """``(n, width)`` int64 codes from an integer array ((n, width) or flat) of values < 2^bits."""
    c = np.asarray(codes)
    if c.dtype.kind not in "iu":
        raise LopcookError("emit", None, f"{name} codes must be integers, got {c.dtype}")
    if c.ndim not in (1, 2) or (c.ndim == 2 and c.shape[1] != width) or c.size % width:
        raise LopcookError("emit", None, f"{name} codes must be (n, {width}), got {c.shape}")
    c = c.reshape(-1, width).astype(np.int64)
    if c.size and (int(c.min()) < 0 or int(c.max()) >= (1 << bits)):
        raise LopcookError("emit", None, f"{name} codes must be {bits}-bit values")
    return c


class Codec:
    """One attribute codec (subclass it; instances are stateless and live in ``CODECS``).

    Class attributes
    ----------------
    name : manifest key in ``attribute_bits`` and ``encodings`` (``"normals"``).
    singular : ``"normal"``: the CLI flag ``--normal-bits``, settings and messages.
    components : float values per vertex in the scene model and in the decode.
    bits : allowed bits per field, inclusive.
    default_bits : bits used where nothing chooses them.
    format_major : the first container major version that may hold it; a codec newer than the
        first (2) is written to ``attribute_bits`` only where present, so files without it keep
        their bytes, and a file holding it carries at least that major.
    shader : the GLSL/HLSL function of shaders/decode_attributes.* that decodes it.
    ubo : where its values go in the decoder's ``LopAttributeDecode`` block:
        ``{"bits": "bits.x", "scale": "scale.x"}``-style slots (``ubo_values``).
    error_model : the bound-based bit choice that sizes it (``lopcook.analyse.attribute_bits``)
        and how the simplifier blends and splits it (``lopcook.simplify.transfer``):
        ``"direction"`` (a unit vector that shading reads; components after the third are a
        handedness), ``"texcoord"`` (texture lookups), ``"color"`` (a colour in the image).
    lod_keys : LOD-entry fields the codec writes beside ``attribute_bits`` (the UVs' range).
    label : the name people read (``"UVs"``); short : its abbreviation in compact text (``"uv"``);
    description : its CLI flag's help.
    """

    name: str = ""
    singular: str = ""
    components: int = 0
    bits: tuple[int, int] = (1, 16)
    default_bits: int = 16
    format_major: int = 2
    shader: str = ""
    ubo: dict = {}
    error_model: str = ""
    lod_keys: tuple[str, ...] = ()
    label: str = ""
    short: str = ""
    description: str = ""

    def check(self, b) -> int:
        """``b`` validated against ``bits`` (usage error otherwise)."""
        return check_bits(b, self.bits, self.singular)

    def field_widths(self, b: int) -> tuple[int, ...]:
        """Bits of each of the codec's record fields at ``b`` bits, in record order."""
        raise NotImplementedError

    def encode(self, values, b: int) -> tuple[np.ndarray, dict]:
        """``(codes (n, fields) uint16, lod_meta)``: the integer fields of ``(n, components)``
        values and the LOD-entry fields (``lod_keys``) the decode needs."""
        raise NotImplementedError

    def decode(self, codes, b: int, entry: dict) -> np.ndarray:
        """``(n, components)`` float32 decode of ``(n, fields)`` integer codes; ``entry`` holds
        ``lod_keys`` as the manifest writes them."""
        raise NotImplementedError

    def max_error(self, b: int) -> float:
        """Worst-case error at ``b`` bits in ``spec()["unit"]``, where it does not depend on the
        buffer (the UVs' depends on the range: ``error_bound``)."""
        raise NotImplementedError

    def spec(self) -> dict:
        """The manifest's ``encodings`` entry (JSON-ready, informative)."""
        raise NotImplementedError

    def problem(self, values: np.ndarray) -> str | None:
        """What is wrong with finite ``(n, components)`` float32 source values, or None (ingest
        refuses a part whose attribute has a problem)."""
        return None


    def unit(self, values: np.ndarray) -> np.ndarray:
        """A direction codec's decoded values with unit length (float32 of the float64
        normalisation of the first three components); the identity otherwise."""
        return values

    #: whether a placement's matrix maps the values (a direction), or copies share them exactly
    placed: bool = False

    def to_world(self, values: np.ndarray, a: np.ndarray) -> np.ndarray:
        """Values of a part placed by the (3, 3) float64 matrix ``a`` (``x -> a x + t``): the
        identity for values a placement does not change."""
        return values

    def ubo_values(self, b: int, entry: dict) -> dict:
        """``{slot: value}`` for the decoder's uniform block (slots of ``ubo``): bits and the
        float32 constants computed once on the CPU."""
        return {self.ubo["bits"]: b}

    def check_entry(self, entry: dict, b: int, fail, where: str) -> None:
        """Check the codec's ``lod_keys`` in a LOD entry read from a file (``fail(message)``)."""
        for key in self.lod_keys:
            if key in entry:
                fail(f"{where}.{key} is present without {self.name}")
