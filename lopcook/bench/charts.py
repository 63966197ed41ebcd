"""PNG charts of ``lopcook bench`` (matplotlib, Agg backend; pip install 'lopcook[bench]').

(a) ``pareto.png``: GPU position bytes per vertex against masked PSNR (min over views), one panel
    per asset, every (configuration, camera level) point of every tool and each tool's Pareto
    front (``metrics.pareto_front``); identical images (PSNR infinite) are drawn at ``INF_DB``.
(b) ``scaling.png``: cook wall time against triangles, log-log, with the fitted slope, and
    gltfpack ``-si 0.5 -vp 14`` in the same chart.
(c) ``stages.png``: stacked bars of lopcook's time per stage for every cook.
(d) ``streaming.png``: PSNR against bytes received of a streamed container, one panel per asset,
    a step line per camera, the peers' whole files (gzip -9) as vertical lines.
"""

from __future__ import annotations

import math

import numpy as np

from .metrics import loglog_slope, pareto_front

INF_DB = 100.0
COLOURS = {"lopcook CAP": "tab:red", "lopcook AP": "tab:orange", "gltfpack": "tab:blue",
           "gltf-transform": "tab:green", "draco": "tab:purple", "lopcook CAP (calibrated)": "tab:brown"}


def pyplot():
    """``matplotlib.pyplot`` on the Agg backend (an optional dependency, ``pip install 'lopcook[bench]'``,
    imported on first use: ImportError when it is missing)."""
    import matplotlib  # optional (lopcook[bench])

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # after use("Agg"): pyplot takes its backend when first imported

    return plt


def _num(v) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return float("nan")


def series_name(row: dict) -> str:
    if row["tool"] == "lopcook":
        return f"lopcook {row['config']}"
    return row["tool"]


def pareto_chart(rows: list[dict], path) -> None:
    """rows: accuracy rows (``bench.ROW_COLUMNS``); rows from -cc outputs are left out (same GPU
    data as the matching non-cc output)."""
    plt = pyplot()
    assets = list(dict.fromkeys(r["asset"] for r in rows))
    n = max(1, len(assets))
    cols = min(2, n)
    nrows = math.ceil(n / cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(6.5 * cols, 4.6 * nrows), squeeze=False)
    for ax, asset in zip(axes.ravel(), assets):
        sub = [r for r in rows if r["asset"] == asset and not r.get("accuracy_from") and not r.get("error")]
        for name in dict.fromkeys(series_name(r) for r in sub):
            pts = [r for r in sub if series_name(r) == name]
            x = np.array([_num(r["gpu_bytes_per_vertex"]) for r in pts])
            y = np.array([_num(r["psnr_min_db"]) for r in pts])
            y = np.where(np.isinf(y), INF_DB, y)
            if not np.isfinite(y).any():
                continue
            colour = COLOURS.get(name)
            ax.scatter(x, y, s=12, alpha=0.45, color=colour)
            front = pareto_front(x, y)
            ax.plot(x[front], y[front], "-o", ms=4, color=colour, label=name)
        ax.axhline(40.0, color="grey", lw=0.8, ls="--")
        ax.set_title(asset)
        ax.set_xlabel("GPU position bytes / vertex")
        ax.set_ylabel("masked PSNR, min over views (dB)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    for ax in axes.ravel()[len(assets):]:
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def scaling_chart(rows: list[dict], path) -> float:
    """rows: scaling rows (``bench.SCALING_COLUMNS``). Returns lopcook's fitted log-log slope."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 5))
    slope = float("nan")
    for tool, colour in (("lopcook", "tab:red"), ("gltfpack", "tab:blue")):
        pts = [r for r in rows if r["tool"] == tool and not r.get("error")]
        if not pts:
            continue
        x = np.array([_num(r["triangles"]) for r in pts])
        y = np.array([_num(r["wall_s"]) for r in pts])
        s, b = loglog_slope(x, y)
        label = pts[0]["config"]
        if tool == "lopcook":
            slope = s
        ax.scatter(x, y, color=colour)
        for r, xi, yi in zip(pts, x, y):
            ax.annotate(r["input"], (xi, yi), fontsize=6, xytext=(3, 3), textcoords="offset points")
        if math.isfinite(s):
            xs = np.geomspace(x.min(), x.max(), 20)
            ax.plot(xs, 10 ** (s * np.log10(xs) + b), color=colour, label=f"{tool} {label}: slope {s:.2f}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("triangles (LOD 0)")
    ax.set_ylabel("wall time of the whole process (s)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return slope


def stages_chart(rows: list[dict], path) -> None:
    """rows: stage rows (``bench.STAGE_COLUMNS``), one per (cook, stage)."""
    plt = pyplot()
    cooks = list(dict.fromkeys(r["cook"] for r in rows))
    stages = list(dict.fromkeys(r["stage"] for r in rows))
    fig, ax = plt.subplots(figsize=(max(6, 1.1 * len(cooks) + 2), 5))
    bottom = np.zeros(len(cooks))
    for st in stages:
        vals = np.array([sum(_num(r["seconds"]) for r in rows if r["cook"] == c and r["stage"] == st) for c in cooks])
        ax.bar(range(len(cooks)), vals, bottom=bottom, label=st)
        bottom += vals
    ax.set_xticks(range(len(cooks)))
    ax.set_xticklabels(cooks, rotation=30, ha="right", fontsize=7)
    ax.set_ylabel("seconds")
    ax.set_title("lopcook cook: time per stage")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


CAMERA_COLOURS = {"near": "tab:red", "middle": "tab:orange", "far": "tab:olive"}
PEER_LINES = (("gltfpack_cc_gzip_bytes", "gltfpack -cc, gzip -9", "tab:blue"),
              ("draco_gzip_bytes", "Draco, gzip -9", "tab:purple"))


def streaming_chart(curves: dict, peers: dict, path) -> None:
    """curves: ``{(asset, camera): streaming.Curve}``; peers: ``{asset: {"gltfpack_cc_gzip_bytes",
    "draco_gzip_bytes"}}`` (None: not run). x: bytes received (log, 1 % to 110 % of the .lop), y:
    PSNR against the float render; identical images are drawn at ``INF_DB``."""
    plt = pyplot()
    assets = list(dict.fromkeys(a for a, _ in curves))
    fig, axes = plt.subplots(1, max(1, len(assets)), figsize=(5.2 * max(1, len(assets)), 4.4), squeeze=False)
    for ax, asset in zip(axes.ravel(), assets):
        top = 0.0
        size = next(cv.file_bytes for (a, _), cv in curves.items() if a == asset)
        for (a, camera), cv in curves.items():
            pts = [(b, INF_DB if p is None else p) for (b, p), n in zip(cv.points, cv.covered) if a == asset and n > 0]
            if not pts:
                continue
            x, y = np.array(pts, dtype=np.float64).T
            x, y = np.append(x, cv.file_bytes), np.append(y, y[-1])
            top = max(top, float(y.max()))
            ax.step(x, y, where="post", color=CAMERA_COLOURS.get(camera), label=f"lopcook, {camera} camera")
            ax.plot(x[:1], y[:1], "o", ms=4, color=CAMERA_COLOURS.get(camera))
        ax.axvline(size, color="grey", lw=0.8, ls=":", label="whole .lop")
        ax.axvspan(0.01 * size, 0.05 * size, color="tab:green", alpha=0.08, lw=0, label="first 5 % of the .lop")
        for key, label, colour in PEER_LINES:
            if peers.get(asset, {}).get(key):
                ax.axvline(peers[asset][key], color=colour, lw=1.2, ls="--", label=f"{label} (whole file)")
        ax.axhline(40.0, color="grey", lw=0.8, ls="--")
        ax.set_xscale("log")
        ax.set_xlim(0.01 * size, 1.1 * size)
        ax.set_ylim(0, min(INF_DB, top + 5) if top else INF_DB)
        ax.set_title(asset)
        ax.set_xlabel("bytes received")
        ax.set_ylabel("PSNR against the float render (dB)")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


__all__ = ["INF_DB", "pareto_chart", "scaling_chart", "stages_chart", "series_name", "streaming_chart"]
