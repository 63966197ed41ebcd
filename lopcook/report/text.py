"""Text formatting shared by the report's HTML and SVG: numbers as the page shows them, escaping."""

from __future__ import annotations

import html


def fmt_pct(x) -> str:
    return "-" if x is None else f"{x:.1f}"


def fmt_psnr(x) -> str:
    return "inf" if x is None else f"{x:.1f}"


def escape(s) -> str:
    return html.escape(str(s), quote=True)


__all__ = ["fmt_pct", "fmt_psnr", "escape"]
