"""The pure parts of ``lopcook bench`` (lopcook/bench/): Pareto front, log-log
slope, vertex matching and position error, crack counting, GPU bytes of a glTF, the "peer not
installed" line and the CSV columns. No peer tool, no GL, no timing."""

from __future__ import annotations

import csv
import subprocess
import sys

import numpy as np
import pytest

from lopcook.bench import common, compare, summary
from lopcook.bench import metrics as BM
from lopcook.bench import peers as P


def test_pareto_front_keeps_exactly_the_non_dominated_points():
    cost = np.array([1.0, 2.0, 2.0, 3.0, 4.0, 5.0, np.nan])
    quality = np.array([30.0, 35.0, 33.0, 34.0, 50.0, 50.0, 99.0])
    # (2, 33) is dominated by (2, 35); (3, 34) by (2, 35); (5, 50) by (4, 50); NaN never counts
    assert BM.pareto_front(cost, quality).tolist() == [0, 1, 4]


def test_pareto_front_treats_infinite_psnr_as_best():
    front = BM.pareto_front([8.0, 4.0, 2.0], [np.inf, 60.0, 60.0])
    assert front.tolist() == [2, 0]


def test_loglog_slope_recovers_a_power_law():
    x = np.geomspace(7e4, 4e6, 5)
    slope, intercept = BM.loglog_slope(x, 3e-6 * x**1.07)
    assert slope == pytest.approx(1.07, abs=1e-12)
    assert intercept == pytest.approx(np.log10(3e-6), abs=1e-9)
    assert all(np.isnan(BM.loglog_slope([1.0], [2.0])))


def test_matching_and_error_on_a_known_offset(rng):
    src = rng.random((500, 3))
    diag = float(np.linalg.norm(src.max(0) - src.min(0)))
    perm = rng.permutation(500)
    offset = np.array([1e-4, 0.0, 0.0])
    out = src[perm] + offset  # a tool that reorders and shifts every vertex by 1e-4 m
    match = BM.match_vertices(src, out)
    assert np.array_equal(match, perm)
    err = BM.position_errors(src, out, match, diag)
    assert err["max_rel"] == pytest.approx(1e-4 / diag, rel=1e-9)
    assert err["rms_rel"] == pytest.approx(1e-4 / diag, rel=1e-9)


def test_matching_picks_the_seam_twin_by_attributes():
    # two co-located vertices (a UV seam) that differ only in UV, and one far away
    src = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [1.0, 1.0, 1.0]])
    nan = np.nan
    src_attr = np.array([[0, 0, 1, 0.1, 0.1], [0, 0, 1, 0.9, 0.9], [0, 1, 0, 0.5, 0.5]], float)
    out = np.array([[1e-6, 0, 0], [0, 1e-6, 0], [1, 1, 1]])
    out_attr = np.array([[nan, nan, nan, 0.9, 0.9], [nan, nan, nan, 0.1, 0.1], [nan, nan, nan, 0.5, 0.5]])
    assert BM.match_vertices(src, out, src_attr, out_attr).tolist() == [1, 0, 2]


def test_cracks_between_two_parts():
    # part 0 and part 1 share the edge (0,0,0)-(1,0,0); part 0 also has a seam twin at (0,1,0)
    p0 = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 1, 0]], float)
    p1 = np.array([[0, 0, 0], [1, 0, 0], [0, -1, 0]], float)
    pos = np.concatenate([p0, p1])
    part = np.array([0, 0, 0, 0, 1, 1, 1])
    classes = BM.colocation_classes(pos)
    match = np.arange(7)
    same = BM.count_cracks(classes, part, pos, match)
    assert same == {"cracks": 0, "cracks_between_parts": 0, "shared_between_parts": 2}
    moved = pos.copy()
    moved[5] += [1e-5, 0, 0]  # part 1's copy of (1,0,0) decodes elsewhere: one crack between parts
    moved[3] += [0, 1e-5, 0]  # the seam twin inside part 0 decodes apart: a crack, not between parts
    got = BM.count_cracks(classes, part, moved, match)
    assert got == {"cracks": 2, "cracks_between_parts": 1, "shared_between_parts": 2}


def test_gltf_position_bytes_rounds_elements_to_four_bytes():
    gltf = {"meshes": [{"primitives": [{"attributes": {"POSITION": 0}}, {"attributes": {"POSITION": 1}}]},
                       {"primitives": [{"attributes": {"POSITION": 0}}]}],  # accessor 0 shared: counted once
            "accessors": [{"componentType": 5123, "count": 10, "type": "VEC3"},   # 16-bit: 6 -> 8 bytes
                          {"componentType": 5126, "count": 5, "type": "VEC3"}]}   # float: 12 bytes
    assert BM.gltf_position_bytes(gltf) == (10 * 8 + 5 * 12, 15)


def test_missing_peer_line_with_empty_path(tmp_path, monkeypatch):
    monkeypatch.setenv("LOPCOOK_PEERS", str(tmp_path))  # no node_modules/.bin here
    empty = tmp_path / "bin"
    empty.mkdir()
    assert P.find_tool("gltfpack", path=str(empty)) is None
    avail = P.availability(("gltfpack", "gltf-transform"), path=str(empty))
    assert avail == {"gltfpack": None, "gltf-transform": None}
    line = P.missing_line("gltfpack")
    assert line.startswith("bench: skip gltfpack: not installed") and "\n" not in line
    assert "npm install" in line and str(tmp_path) in line


def test_cli_bench_prints_one_line_per_missing_peer(tmp_path):
    env = {"PATH": str(tmp_path), "LOPCOOK_PEERS": str(tmp_path), "HOME": str(tmp_path)}
    r = subprocess.run([sys.executable, "-m", "lopcook", "bench", "--no-accuracy", "--peers", "gltfpack,gltf-transform",
                        "-o", str(tmp_path / "out")], capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 0, r.stderr
    skipped = [ln for ln in r.stderr.splitlines() if ln.startswith("bench: skip")]
    assert [ln.split(":")[1].strip() for ln in skipped] == ["skip gltfpack", "skip gltf-transform"]
    assert (tmp_path / "out" / "summary.json").is_file()


def test_csv_columns_and_values(tmp_path):
    rows = [compare.result_row(asset="a", tool="lopcook", config="CAP", level=6, psnr_min_db=float("inf"), max_err_rel=1.5e-7)]
    common.write_csv(tmp_path / "r.csv", rows, compare.ROW_COLUMNS)
    with open(tmp_path / "r.csv", newline="") as fh:
        got = list(csv.DictReader(fh))
    assert tuple(got[0].keys()) == compare.ROW_COLUMNS
    assert got[0]["psnr_min_db"] == "inf" and float(got[0]["max_err_rel"]) == 1.5e-7 and got[0]["error"] == ""
    for col in ("file_bytes", "gpu_bytes_per_vertex", "max_err_rel", "rms_err_rel", "cracks",
                "cracks_between_parts", "psnr_min_db", "wall_s", "peak_rss_mb"):
        assert col in compare.ROW_COLUMNS


def test_cook_stages_split_the_analysis():
    t = {"ingest": 1.0, "lod": 2.0, "analyse": 3.0, "analyse.attribute_error": 1.0, "analyse.depth": 0.5,
         "emit": 0.25, "write": 0.125}
    s = common.cook_stages(t)
    assert s["E_v"] == 1.0 and s["depth"] == 0.5 and s["analyse other"] == 1.5 and s["bins/planes"] == 0.25
    assert sum(s.values()) == pytest.approx(1.0 + 2.0 + 3.0 + 0.25 + 0.125)


def test_checks_report_pass_and_miss_from_rows():
    rows = [compare.result_row(asset="x", tool="lopcook", config="CAP", level=b, gpu_bytes_per_vertex=3.0 + 0.1 * b,
                   psnr_min_db=45.0) for b in (6, 7)]
    scaling = [{"input": "bunny s2", "tool": "lopcook", "triangles": 1_111_216, "wall_s": 6.0, "peak_rss_mb": 500.0},
               {"input": "bunny s2", "tool": "gltfpack", "triangles": 1_111_216, "wall_s": 3.0, "peak_rss_mb": 300.0},
               {"input": "bunny s0", "tool": "lopcook", "triangles": 69_451, "wall_s": 6.0 / 16, "peak_rss_mb": 90.0},
               {"input": "bunny s3", "tool": "lopcook", "triangles": 4_444_864, "wall_s": 24.0, "peak_rss_mb": 1400.0},
               {"input": "bunny s3", "tool": "gltfpack", "triangles": 4_444_864, "wall_s": 6.0, "peak_rss_mb": 600.0}]
    checks = summary.checks(rows, scaling, ["x"], {"pareto": "p.png"}, [6, 7])
    status = [c["status"] for c in checks]
    # the chart lacks the four default assets; 3.7 B/vertex at 45 dB; 1.1M: 2x gltfpack (<= 3x) but
    # 500 MiB = 524 MB (> 500 MB); 4.4M: 4x gltfpack (> 3x), 1,400 MiB = 1,468 MB (<= 1,500); slope 1
    assert status == ["miss", "pass", "pass", "miss", "miss", "pass", "pass"]
    assert checks[2]["ratio"] == pytest.approx(2.0) and checks[4]["ratio"] == pytest.approx(4.0)
    assert checks[3]["peak_rss_MB"] == pytest.approx(500 * 2**20 / 1e6)
    assert [c["status"] for c in summary.checks(rows, scaling[:3], ["x"], {}, [6, 7])[4:6]] == ["not measured"] * 2
    assert summary.checks(rows, scaling, ["x"], {}, [6, 7])[1]["assets"]["x"]["cap_bytes_per_vertex_max"] == pytest.approx(3.7)


def test_cap_check_takes_the_cheapest_config_that_reaches_40_db():
    rows = [compare.result_row(asset="x", tool="lopcook", config="CAP", level=b, gpu_bytes_per_vertex=6.0, psnr_min_db=55.0)
            for b in (6, 7)]
    rows += [compare.result_row(asset="x", tool="lopcook", config="CAP (calibrated)", level=b, gpu_bytes_per_vertex=3.0 + 0.1 * b,
                    psnr_min_db=39.0 + b / 6) for b in (6, 7)]  # 40.0 and 40.17 dB
    c = summary.checks(rows, [], ["x"], {}, [6, 7])[1]
    assert c["status"] == "pass" and c["assets"]["x"]["config"] == "CAP (calibrated)"
    assert c["assets"]["x"]["cap_bytes_per_vertex_max"] == pytest.approx(3.7)
    rows[-1]["psnr_min_db"] = 38.0  # calibrated misses 40 dB at level 7: the default CAP is taken
    c = summary.checks(rows, [], ["x"], {}, [6, 7])[1]
    assert c["assets"]["x"]["config"] == "CAP" and c["status"] == "miss"  # 6 B/vertex > 4


def test_results_table_one_row_per_configuration():
    rows = [compare.result_row(asset="x", tool="lopcook", config=v, bits=b, level=b, gpu_bytes_per_vertex=2.0 + b / 10,
                   psnr_min_db=30.0 + b, file_bytes=2048, wall_s=1.5, peak_rss_mb=100.0, cracks_between_parts=0)
            for v in ("AP", "CAP") for b in (6, 11)]
    rows += [compare.result_row(asset="x", tool="gltfpack", config="-vp 14", bits=14, level=b, gpu_bytes_per_vertex=8.0,
                    psnr_min_db=float("inf") if b == 11 else 50.0, file_bytes=1024, wall_s=0.2, peak_rss_mb=60.0,
                    cracks_between_parts=3) for b in (6, 11)]
    lines = summary.results_table(rows, [6, 11])
    assert len(lines) == 2 + 3
    assert "| x | lopcook | AP | 2.60-3.10 | 36.0 / 41.0 | 2 | 1.50 | 100 | 0 |" in lines
    assert "| x | gltfpack | -vp 14 | 8.00 | 50.0 / inf | 1 | 0.20 | 60 | 3 |" in lines
