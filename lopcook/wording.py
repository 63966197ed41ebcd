"""How lopcook words counts and lengths in the text it prints (``cook``, ``inspect``, ``decode``, ...).

``plural(n, "part")`` -> ``"1 part"``, ``"2 parts"``; ``plural(n, "mesh", "meshes")`` for an
irregular noun. Counts get thousands separators (``"12,946 triangles"``).

``length(m)`` -> a length in metres with three significant digits and the unit that keeps the
number between 1 and 1000 where it can: ``"0.14 mm"``, ``"4.5 mm"``, ``"9.41 m"``, ``"1.2 km"``;
``"0"`` for zero.
"""

from __future__ import annotations

import math


def plural(n: int, one: str, many: str | None = None) -> str:
    """``n`` with thousands separators and the noun in the right number: ``1 vertex``, ``3 vertices``
    (``many`` default: ``one + "s"``)."""
    return f"{int(n):,} {one if int(n) == 1 else (many or one + 's')}"


_UNITS = ((1e3, "km"), (1.0, "m"), (1e-3, "mm"), (1e-6, "µm"), (1e-9, "nm"))


def length(metres: float) -> str:
    """A length in metres, three significant digits, in km, m, mm, µm or nm (see the module doc);
    ``"0"`` for 0, ``"inf"`` for an infinite length."""
    v = float(metres)
    if v == 0.0:
        return "0"
    if not math.isfinite(v):
        return "inf"
    for scale, unit in _UNITS:
        if abs(v) >= scale:
            return f"{v / scale:.3g} {unit}"
    return f"{v / 1e-9:.3g} nm"


__all__ = ["plural", "length"]
