"""The bench's outputs: the acceptance checks (``checks``, docs/bench.md), the results table, and
``write_outputs``: results.csv, scaling.csv, stages.csv, the charts (when matplotlib is installed),
summary.json and summary.md.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from ..atomic import write_atomic
from . import charts as C
from . import metrics as BM
from .common import asset_name, log, write_csv
from .compare import DEFAULT_ASSETS, PEER_BYTES_16BIT, ROW_COLUMNS, STAGE_COLUMNS, TARGET_PSNR_DB
from .scaling import SCALING_COLUMNS, SCALING_LODS


def _f(v) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return float("nan")


def checks(rows: list[dict], scaling: list[dict], assets: list[str], charts: dict, levels) -> list[dict]:
    """The bench's acceptance checks (docs/bench.md), computed from the rows: each {"check", "status"
    (pass / miss / not measured), "detail", numbers}."""
    out = []
    # (1) Pareto chart for each asset
    have = {r["asset"] for r in rows if r.get("psnr_min_db") not in ("", None)}
    missing = [a for a in dict.fromkeys([asset_name(d) for d in DEFAULT_ASSETS] + list(assets)) if a not in have]
    out.append({"check": "Pareto chart for bunny, fandisk, DamagedHelmet and the chess set",
                "status": "pass" if charts.get("pareto") and not missing else "miss",
                "detail": f"{charts.get('pareto') or 'no chart'}; assets with PSNR data: {sorted(have)}"
                          + (f"; missing: {missing}" if missing else "")})
    # (2) CAP bytes/vertex at >= 40 dB vs 8: per asset the CAP configuration (default k_f, or
    # calibrated with --calibrated) with the least bytes among those reaching 40 dB at every level
    per = {}
    for a in assets:
        options = {}
        for config in ("CAP", "CAP (calibrated)"):
            cap = [r for r in rows if r["asset"] == a and r["tool"] == "lopcook" and r["config"] == config
                   and r.get("psnr_min_db") not in ("", None) and int(r["level"]) in levels]
            if not cap:
                continue
            options[config] = {
                "config": config, "cap_psnr_min_db": min(_f(r["psnr_min_db"]) for r in cap),
                "cap_bytes_per_vertex_max": max(_f(r["gpu_bytes_per_vertex"]) for r in cap),
                "per_level": {int(r["level"]): [_f(r["gpu_bytes_per_vertex"]), _f(r["psnr_min_db"])] for r in cap}}
        if not options:
            continue
        reaching = [o for o in options.values() if o["cap_psnr_min_db"] >= TARGET_PSNR_DB]
        best = min(reaching or options.values(), key=lambda o: o["cap_bytes_per_vertex_max"])
        per[a] = dict(best, alternatives=sorted(options))
    limit = 0.5 * PEER_BYTES_16BIT
    ok = bool(per) and all(v["cap_psnr_min_db"] >= TARGET_PSNR_DB and v["cap_bytes_per_vertex_max"] <= limit
                           for v in per.values())
    out.append({"check": f"CAP GPU bytes/vertex <= {limit:g} (0.5 x the 16-bit peers' 8) at >= {TARGET_PSNR_DB:g} dB, "
                         f"levels {levels[0]}-{levels[-1]}",
                "status": ("pass" if ok else "miss") if per else "not measured",
                "detail": "; ".join(f"{a}: {v['config']} max {v['cap_bytes_per_vertex_max']:.2f} B/vertex "
                                    f"({v['cap_bytes_per_vertex_max'] / PEER_BYTES_16BIT:.2f}x), worst PSNR "
                                    f"{v['cap_psnr_min_db']:.1f} dB" for a, v in per.items()) or "no CAP renders",
                "assets": per})
    # (3) the cooks of the 1.1M and 4.4M GLBs with 3 LODs vs gltfpack -si 0.5 -vp 14
    for name, label, rss_limit in (("bunny s2", "1.1M", 500.0), ("bunny s3", "4.4M", 1500.0)):
        out.extend(_speed_checks(scaling, name, label, rss_limit))
    # (4) log-log slope
    lp = [r for r in scaling if r["tool"] == "lopcook" and not r.get("error")]
    slope, _ = BM.loglog_slope([_f(r["triangles"]) for r in lp], [_f(r["wall_s"]) for r in lp])
    out.append({"check": "log-log slope of cook wall time vs triangles <= 1.1",
                "status": "not measured" if not math.isfinite(slope) else ("pass" if slope <= 1.1 else "miss"),
                "slope": slope, "detail": f"slope {slope:.3f} over {len(lp)} inputs "
                                          f"({', '.join(r['input'] for r in lp)})"})
    return out


#: largest cook / gltfpack wall-time ratio of the scaling checks (docs/bench.md)
MAX_SPEED_RATIO = 3.0


def _speed_checks(scaling: list[dict], name: str, label: str, rss_limit_mb: float) -> list[dict]:
    """Two checks on scaling input ``name``: lopcook's cook within ``MAX_SPEED_RATIO`` x gltfpack's
    wall time in the same run, and its peak RSS within ``rss_limit_mb`` MB (10^6 bytes)."""
    rows = [r for r in scaling if r["input"] == name and not r.get("error")]
    lc = next((r for r in rows if r["tool"] == "lopcook"), None)
    gp = next((r for r in rows if r["tool"] == "gltfpack"), None)
    speed = f"cook of the {label}-triangle GLB (3 LODs, full analysis) within {MAX_SPEED_RATIO:g}x gltfpack -si 0.5 -vp 14"
    memory = f"peak RSS <= {rss_limit_mb:g} MB at {label} triangles"
    out = []
    if lc and gp:
        ratio = _f(lc["wall_s"]) / _f(gp["wall_s"])
        out.append({"check": speed, "status": "pass" if ratio <= MAX_SPEED_RATIO else "miss", "ratio": ratio,
                    "detail": f"lopcook {_f(lc['wall_s']):.2f} s vs gltfpack {_f(gp['wall_s']):.2f} s "
                              f"({lc['triangles']:,} triangles): {ratio:.2f}x"})
    else:
        out.append({"check": speed, "status": "not measured", "detail": f"needs the scaling run with {name} and gltfpack"})
    if lc:
        rss = _f(lc["peak_rss_mb"]) * 2**20 / 1e6
        out.append({"check": memory, "status": "pass" if rss <= rss_limit_mb else "miss", "peak_rss_MB": rss,
                    "detail": f"{rss:.0f} MB (10^6 bytes; {_f(lc['peak_rss_mb']):.0f} MiB) for lopcook cook "
                              f"--lods {SCALING_LODS}"})
    else:
        out.append({"check": memory, "status": "not measured", "detail": f"needs the scaling run with {name}"})
    return out


def results_table(rows: list[dict], levels) -> list[str]:
    """Markdown lines: one row per asset and configuration (peers: position bits; lopcook: AP/CAP
    over the levels) with GPU position bytes per vertex (range over camera levels), PSNR (min over
    views) at the farthest and nearest camera level, file bytes, wall time and peak RSS of the tool's
    process, and cracks between parts. ``-cc`` rows show their own file bytes (accuracy is that of
    the file without ``-cc``)."""
    lo, hi = min(levels), max(levels)
    out = ["| asset | tool | config | GPU B/vertex | PSNR dB at level "
           f"{lo} / {hi} | file KB | wall s | peak RSS MiB | cracks between parts |",
           "|---|---|---|---|---|---|---|---|---|"]
    groups: dict = {}
    for r in rows:
        if r.get("error"):
            continue
        groups.setdefault((r["asset"], r["tool"], r["config"]), []).append(r)

    def db(v):
        f_ = _f(v)
        return "-" if not math.isfinite(f_) and str(v) in ("", "nan") else ("inf" if math.isinf(f_) else f"{f_:.1f}")

    for (asset, tool, config), rs in groups.items():
        by_level = {int(r["level"]): r for r in rs if str(r.get("level", "")).strip()}
        bpv = [_f(r["gpu_bytes_per_vertex"]) for r in rs]
        bpv_text = f"{min(bpv):.2f}" if max(bpv) - min(bpv) < 0.005 else f"{min(bpv):.2f}-{max(bpv):.2f}"
        far, near = by_level.get(lo, {}), by_level.get(hi, {})
        first = rs[0]
        rss = _f(first.get("peak_rss_mb"))
        out.append(f"| {asset} | {tool} | {config} | {bpv_text} | {db(far.get('psnr_min_db', ''))} / "
                   f"{db(near.get('psnr_min_db', ''))} | {_f(first['file_bytes']) / 1024:,.0f} | "
                   f"{_f(first['wall_s']):.2f} | {rss:.0f} | {first.get('cracks_between_parts', '')} |")
    return out


def write_outputs(out_dir: Path, rows, scaling, stage_rows, assets, opts, meta: dict) -> dict:
    """Write results.csv, scaling.csv, stages.csv, the charts (when matplotlib is installed), summary.json
    and summary.md into ``out_dir``; returns the summary dict (``meta`` plus charts and checks)."""
    write_csv(out_dir / "results.csv", rows, ROW_COLUMNS)
    write_csv(out_dir / "scaling.csv", scaling, SCALING_COLUMNS)
    write_csv(out_dir / "stages.csv", stage_rows, STAGE_COLUMNS)
    made = {}
    try:
        if rows:
            C.pareto_chart(rows, out_dir / "pareto.png")
            made["pareto"] = "pareto.png"
        if scaling:
            C.scaling_chart(scaling, out_dir / "scaling.png")
            made["scaling"] = "scaling.png"
        if stage_rows:
            C.stages_chart(stage_rows, out_dir / "stages.png")
            made["stages"] = "stages.png"
    except ImportError as exc:
        log(opts, f"no charts: {exc} (pip install 'lopcook[bench]')")
    results = checks(rows, scaling, assets, made, list(opts.levels))
    summary = dict(meta, charts=made, checks=results)
    write_atomic(out_dir / "summary.json", (json.dumps(summary, indent=1, sort_keys=True, default=str) + "\n").encode())
    lines = ["# lopcook bench summary", "", f"Command: `{meta['command']}`", "",
             f"Machine: {meta['machine'].get('cpu', '?')}, {meta['machine'].get('cpus')} CPUs, "
             f"{meta['machine'].get('memory_gb', '?')} GB; renderer at {opts.resolution[0]}x{opts.resolution[1]}, "
             f"{opts.views} views, levels {opts.levels[0]}-{opts.levels[-1]}; total {meta['seconds']:.0f} s", "",
             "Peers: " + ", ".join(f"{k}: {v}" for k, v in meta["peers"].items()), "",
             "| check | status | numbers |", "|---|---|---|"]
    lines += [f"| {c['check']} | {c['status']} | {c['detail']} |" for c in results]
    if rows:
        lines += ["", "## Results", "", *results_table(rows, list(opts.levels))]
    if scaling:
        lines += ["", "## Scaling", "", "| input | triangles | tool | config | wall s | peak RSS MiB |",
                  "|---|---|---|---|---|---|"]
        lines += [f"| {r['input']} | {int(_f(r['triangles'])):,} | {r['tool']} | {r['config']} | {_f(r['wall_s']):.2f} | "
                  f"{_f(r['peak_rss_mb']):.0f} |" for r in scaling if not r.get("error")]
    lines += ["", "Charts: " + ", ".join(made.values()), ""]
    write_atomic(out_dir / "summary.md", "\n".join(lines).encode())
    return summary


__all__ = ["checks", "MAX_SPEED_RATIO", "results_table", "write_outputs"]
