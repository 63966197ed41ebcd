"""Text formatting shared by the report's HTML and SVG: numbers as the page shows them, escaping."""

from __future__ import annotations

import html


def fmt_pct(x) -> str:
    """A percentage as the page shows it: one decimal, ``-`` for None."""
    return "-" if x is None else f"{x:.1f}"


def fmt_psnr(x) -> str:
    """A PSNR in dB as the page shows it: one decimal, ``inf`` for None (identical images)."""
    return "inf" if x is None else f"{x:.1f}"


def escape(s) -> str:
    """``str(s)`` escaped for HTML text and attribute values (quotes included)."""
    return html.escape(str(s), quote=True)


__all__ = ["fmt_pct", "fmt_psnr", "escape"]
