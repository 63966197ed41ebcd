"""The attribute codecs of the packed vertex record, and the one registry every stage reads.

``CODECS`` lists every codec in **record order** (docs/format.md section 7.2): a vertex's record
holds the fields of each present attribute in this order. Each codec is one module of this
package (``base.Codec`` says what it declares: bit range, encode, decode, error bound, the shader
function, the uniform-block slots, placements' ``to_world`` and the error model that sizes it).

:class:`AttributeBits` is the bits of one buffer's attributes, keyed by codec name, with None
for an absent attribute; ``record_bits`` is the record size S.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

from ...errors import LopcookError
from .base import Codec, check_bits
from .colors_unorm import COLORS
from .normals_oct import NORMALS
from .tangents_oct import TANGENTS
from .uvs_range import UVS

#: every codec, in record order
CODECS: tuple[Codec, ...] = (NORMALS, UVS, COLORS, TANGENTS)
BY_NAME: dict[str, Codec] = {c.name: c for c in CODECS}

__all__ = ["CODECS", "BY_NAME", "Codec", "AttributeBits", "bits_for", "check_bits", "codec"]


def codec(name: str) -> Codec:
    """The codec called ``name`` (a manifest key such as ``"normals"``)."""
    try:
        return BY_NAME[name]
    except KeyError:
        raise LopcookError("usage", None, f"unknown attribute {name!r} (known: {', '.join(BY_NAME)})") from None


class AttributeBits:
    """Bits per field of one buffer's attributes, by codec name (None: the attribute is absent).

    ``AttributeBits(normals=8, uvs=10)`` or positionally in record order ``AttributeBits(8, 10,
    None)``; each value is checked against its codec's range (a usage error otherwise). Immutable,
    hashable, equal when every codec's bits are equal. Attribute access by codec name
    (``bits.normals``) gives the bits or None."""

    __slots__ = ("_values",)

    def __init__(self, *args, **kwargs) -> None:
        if len(args) > len(CODECS):
            raise TypeError(f"AttributeBits takes at most {len(CODECS)} positional bits, got {len(args)}")
        given = dict(zip((c.name for c in CODECS), args))
        for key, v in kwargs.items():
            if key not in BY_NAME or key in given:
                raise TypeError(f"AttributeBits got an unknown or repeated attribute {key!r}")
            given[key] = v
        object.__setattr__(self, "_values", tuple(
            None if given.get(c.name) is None else c.check(given[c.name]) for c in CODECS))

    def __getattr__(self, name: str):
        if name in BY_NAME:
            return self._values[CODECS.index(BY_NAME[name])]
        raise AttributeError(name)

    def __setattr__(self, name, value):
        raise AttributeError("AttributeBits is immutable")

    def __eq__(self, other) -> bool:
        return isinstance(other, AttributeBits) and other._values == self._values

    def __hash__(self) -> int:
        return hash(self._values)

    def __reduce__(self):
        return (_rebuild, (self.as_map(),))

    def __repr__(self) -> str:
        return "AttributeBits(" + ", ".join(f"{c.name}={b}" for c, b in zip(CODECS, self._values)) + ")"

    def get(self, name: str) -> int | None:
        return self._values[CODECS.index(codec(name))]

    def present(self) -> list[tuple[Codec, int]]:
        """``(codec, bits)`` of every present attribute, in record order."""
        return [(c, b) for c, b in zip(CODECS, self._values) if b is not None]

    def replace(self, **changes) -> "AttributeBits":
        return AttributeBits(**{**self.as_map(), **changes})

    def as_map(self) -> dict:
        """``{name: bits or None}`` for every codec."""
        return {c.name: b for c, b in zip(CODECS, self._values)}

    @property
    def record_bits(self) -> int:
        """S: bits of one vertex's record, the sum of the present codecs' field widths."""
        return sum(sum(c.field_widths(b)) for c, b in self.present())

    @property
    def format_major(self) -> int:
        """The lowest container major version that can hold these attributes."""
        return max([2] + [c.format_major for c, _ in self.present()])

    def as_dict(self) -> dict:
        """The manifest's ``attribute_bits``: every codec of the first format (null where absent),
        and a later codec only where present (so files without it keep their bytes)."""
        return {c.name: b for c, b in zip(CODECS, self._values) if c.format_major == 2 or b is not None}

    @classmethod
    def of(cls, d: Mapping) -> "AttributeBits":
        """From a manifest ``attribute_bits`` record (absent keys: absent attributes)."""
        return cls(**{k: d.get(k) for k in BY_NAME if k in d})


def _rebuild(values: dict) -> AttributeBits:
    return AttributeBits(**values)


def bits_for(present: Iterable[str], requested: Mapping[str, int | None] | None = None) -> AttributeBits:
    """The bits of a buffer whose attributes ``present`` (codec names) are stored: ``requested``
    where it gives a number, else each codec's ``default_bits``; absent attributes get None."""
    requested = requested or {}
    have = set(present)
    return AttributeBits(**{c.name: (c.default_bits if requested.get(c.name) is None else requested[c.name])
                            for c in CODECS if c.name in have})
