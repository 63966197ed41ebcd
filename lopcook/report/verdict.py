"""The report's verdict: does the container pass? CAP against the float source at every rendered
level and view, the same criterion as ``lopcook verify --source`` with its defaults.

PASS when the CAP PSNR of every rendered (level, view) is at least ``min_psnr`` dB (a view whose
CAP render equals the float render, PSNR None, passes); FAIL otherwise. The banner names the
worst (level, view): the lowest CAP PSNR (``worst_view``), and the part holding the largest share
of that view's squared error (``worst_part``). ``lopcook report`` exits 1 on FAIL.
"""

from __future__ import annotations

import numpy as np

from .images import squared_error

#: the default threshold of ``lopcook report --min-psnr`` and ``lopcook verify --min-psnr``, dB
DEFAULT_MIN_PSNR = 40.0


def worst_view(rows: list[dict], view_ids: list[int]) -> dict | None:
    """The rendered (level, view) with the lowest CAP PSNR: ``{"level", "view", "psnr"}`` (``view``
    the icosahedron view index; the first of equal values, levels in ``rows`` order, views in
    render order), or None when every CAP render equals its float render. ``rows``: the
    evaluation's ``levels`` (each with ``cap.psnr_views`` per view of ``view_ids``)."""
    best = None
    for r in rows:
        cap = r.get("cap")
        if not cap:
            continue
        for i, p in enumerate(cap["psnr_views"]):
            if p is not None and (best is None or p < best["psnr"]):
                best = {"level": int(r["level"]), "view": int(view_ids[i]), "psnr": float(p)}
    return best


#: pixels of an outline that the part-ID images (one sample per pixel) show as background while
#: the multisampled colour covers them count for a part up to this many pixels away (``worst_part``)
OUTLINE_PX = 2


def _spread(ids: np.ndarray, steps: int) -> np.ndarray:
    """``ids`` ((h, w) part IDs, 0 = background) with each background pixel given the largest ID of
    its 3x3 neighbourhood, ``steps`` times: the outline pixels the ID images miss get a part."""
    out = ids
    for _ in range(steps):
        p = np.pad(out, 1)
        h, w = out.shape
        near = np.max([p[y:y + h, x:x + w] for y in range(3) for x in range(3)], axis=0)
        out = np.where(out > 0, out, near)
    return out


def worst_part(images: dict | None, names: list[str]) -> dict | None:
    """The part holding the largest share of CAP's squared error against float in one view's
    images (``float``, ``cap``, ``float_ids``, ``cap_ids``: ``evaluate``'s ``keep_images``): each
    pixel counts for the part the float render shows there, or CAP's where float shows background,
    or, on an outline both ID images miss, the part within ``OUTLINE_PX`` pixels (``_spread``).
    Returns ``{"index", "name", "share"}`` (``share`` in (0, 1]: its error over the view's), or None
    when the images are missing or equal."""
    if not images or any(images.get(k) is None for k in ("float", "cap", "float_ids", "cap_ids")):
        return None
    err = squared_error(images["float"], images["cap"])
    total = float(err.sum())
    if not total > 0.0:
        return None
    f_ids, c_ids = np.asarray(images["float_ids"]), np.asarray(images["cap_ids"])
    ids = _spread(np.where(f_ids > 0, f_ids, c_ids).astype(np.int64), OUTLINE_PX).ravel()
    sums = np.bincount(ids, weights=err.ravel(), minlength=len(names) + 1)
    sums[0] = 0.0  # far from every part: counted for none
    i = int(np.argmax(sums))
    if not sums[i] > 0.0 or i > len(names):
        return None
    return {"index": i - 1, "name": str(names[i - 1]), "share": min(1.0, float(sums[i] / total))}


def verdict(rows: list[dict], view_ids: list[int], min_psnr: float, worst: dict | None = None) -> dict:
    """The verdict record of ``report.json``: ``result`` "PASS" or "FAIL", ``min_psnr`` (dB),
    ``statistic`` ("CAP PSNR per view"), ``worst`` (``worst_view`` with ``part``: the ``worst``
    record's part when it is that view, else None; None when every render is identical),
    ``failing_levels`` (levels with a view under the threshold) and ``failing_views`` (the number of
    (level, view) pairs under it)."""
    w = worst_view(rows, view_ids)
    if w is not None:
        same = worst is not None and (worst.get("level"), worst.get("view")) == (w["level"], w["view"])
        w["part"] = worst.get("part") if same else None
    failing, count = [], 0
    for r in rows:
        below = [p for p in (r.get("cap") or {}).get("psnr_views") or [] if p is not None and p < min_psnr]
        if below:
            failing.append(int(r["level"]))
            count += len(below)
    return {"result": "FAIL" if count else "PASS", "min_psnr": float(min_psnr), "statistic": "CAP PSNR per view",
            "worst": w, "failing_levels": failing, "failing_views": count}


def verdict_line(v: dict, source: str | None = None) -> str:
    """One line for the terminal: ``PASS: ...`` or ``FAIL: ...`` naming the worst level, view and part."""
    w = v["worst"]
    if w is None:
        return f"{v['result']}: every CAP render equals the float render (threshold {v['min_psnr']:g} dB)"
    part = f", part {w['part']['name']}" if w.get("part") else ""
    cmp = ">=" if w["psnr"] >= v["min_psnr"] else "<"
    head = (f"{v['result']}: worst CAP PSNR {w['psnr']:.1f} dB {cmp} {v['min_psnr']:g} dB at level {w['level']}, "
            f"view {w['view']}{part}")
    if v["result"] == "FAIL":
        lv = ", ".join(str(b) for b in v["failing_levels"])
        plural = "s" if len(v["failing_levels"]) > 1 else ""
        head += f" ({v['failing_views']} views under the threshold at level{plural} {lv})"
    return head + (f" [{source}]" if source else "")


__all__ = ["DEFAULT_MIN_PSNR", "worst_view", "worst_part", "verdict", "verdict_line"]
