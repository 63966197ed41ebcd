"""Text tables of render evaluations (``lopcook verify --source``, ``lopcook report``): the rows of
the paper's Table 1 (Meyer et al. 2011, section 7) with PSNR and depth-order errors.

Input: the dict ``lopcook.verify.evaluate.evaluate`` returns. PSNR in dB, ``inf`` when every
object pixel is identical (None in the data); memory in percent of float32 positions.
"""

from __future__ import annotations


def _fmt_psnr(v) -> str:
    return "inf" if v is None else f"{v:.1f}"


def format_table(result: dict) -> str:
    """Table-1-like text of an ``evaluate`` result: a two-line header (paths; views, resolution,
    MSAA, Phong parameters, whether back faces are culled (``shading.back_faces``), float32 bytes), a column line, then one line per level row: level
    (``B@C`` when the camera level C differs), AP memory % of float32, AP PSNR min / mean over views
    (dB, one decimal, ``inf`` = identical), the same for CAP, depth-order error pixels AP / CAP
    (``-`` for a variant not rendered) and the camera distance in metres (4 significant digits); a
    last line with the run's seconds and GL renderer. Lines are joined by ``\\n``, no final newline."""
    w, hgt = result["resolution"]
    lines = [f"render check: {result['source']} vs {result['container']}",
             f"  {len(result['views'])} views, {w}x{hgt}, {result['samples']}x MSAA, "
             f"Phong ks {result['shading']['ks']:g} n {result['shading']['shininess']:g}"
             f"{', single-sided back faces culled' if result['shading'].get('back_faces') else ''}; "
             f"PSNR in dB over object pixels (min / mean over views); memory vs float32 "
             f"({result['float32_bytes']:,} bytes)",
             "  level  AP mem  AP PSNR min/mean  CAP mem  CAP PSNR min/mean  depth-order px AP/CAP  distance m"]
    for r in result["levels"]:
        ap, cap = r.get("ap"), r.get("cap")
        apm = f"{ap['percent_of_float32']:5.1f}%" if ap else "     -"
        app = f"{_fmt_psnr(ap['psnr_min']):>6} / {_fmt_psnr(ap['psnr_mean']):<6}" if ap else f"{'-':>15}"
        capm = f"{cap['percent_of_float32']:5.1f}%" if cap else "     -"
        capp = f"{_fmt_psnr(cap['psnr_min']):>6} / {_fmt_psnr(cap['psnr_mean']):<6}" if cap else f"{'-':>15}"
        dep = f"{ap['depth_order_errors'] if ap else '-'} / {cap['depth_order_errors'] if cap else '-'}"
        lv = f"{r['level']}" if r["camera_level"] == r["level"] else f"{r['level']}@{r['camera_level']}"
        lines.append(f"  {lv:>5}  {apm:>6}  {app:>16}  {capm:>7}  {capp:>17}  {dep:>21}  {r['camera_distance_m']:.4g}")
    s = result["seconds"]
    lines.append(f"  {s['total']:.1f} s (render {s['render']:.1f} s, metrics {s['metrics']:.1f} s) on "
                 f"{result['device']['renderer']}")
    return "\n".join(lines)


__all__ = ["format_table"]
