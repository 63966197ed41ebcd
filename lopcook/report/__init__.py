"""``lopcook report``: one self-contained HTML page plus ``report.json`` for a cooked container.

* ``render``: every render of the page in one GL harness (``render_for_report``).
* ``model``: the numbers of ``report.json`` (``build_report``, ``analysis_warnings``).
* ``images``, ``svg``, ``text``: crops and PNGs, inline SVG charts, number formatting.
* ``html``: the page (``write_html`` writes the page and its JSON atomically).
"""

from __future__ import annotations

from .html import write_html
from .model import analysis_warnings, build_report
from .render import render_for_report

__all__ = ["analysis_warnings", "build_report", "render_for_report", "write_html"]
