"""``lopcook verify OUT.lop --source SOURCE`` (render check as a build gate), ``lopcook cook
--target-psnr`` and ``lopcook calibrate``: exit codes 0 pass, 1 threshold failed, 2 usage / bad input.

Small resolutions and few views. Skips without EGL, except under CI=true, where it fails.
"""

from __future__ import annotations

import json

import pytest

from conftest import FIXTURES
from lopcook.cli import main
from lopcook.lop.container import read

CREASE = str(FIXTURES / "glossy_crease.glb")
PLATES = str(FIXTURES / "two_plates.glb")
FAST = ["--views", "4", "--resolution", "320x180"]


@pytest.fixture(scope="module", autouse=True)
def _needs_gl(gl):
    """Every test here renders."""


@pytest.fixture(scope="module")
def crease_lop(tmp_path_factory):
    out = tmp_path_factory.mktemp("cook") / "crease.lop"
    assert main(["-q", "cook", CREASE, "-o", str(out)]) == 0
    return str(out)


def test_verify_source_passes(crease_lop, capsys):
    rc = main(["verify", crease_lop, "--source", CREASE, "--levels", "6-8", *FAST])
    out = capsys.readouterr().out
    assert rc == 0, out
    assert "AP mem" in out and "CAP PSNR" in out and "ok" in out
    assert len([ln for ln in out.splitlines() if ln.strip()[:2] in ("6 ", "7 ", "8 ")]) == 3


def test_verify_source_json(crease_lop, capsys):
    rc = main(["verify", crease_lop, "--source", CREASE, "--levels", "6,9", "--json", *FAST])
    report = json.loads(capsys.readouterr().out)
    assert rc == 0 and report["ok"] is True
    render = report["render"]
    assert [r["level"] for r in render["levels"]] == [6, 9]
    assert render["thresholds"]["min_psnr"] == 40.0 and render["failures"] == []
    for r in render["levels"]:
        for v in ("ap", "cap"):
            assert set(r[v]) >= {"bytes", "percent_of_float32", "psnr_min", "psnr_mean", "max_error", "share_off",
                                 "depth_order_errors"}
    assert "images" not in render


def test_verify_source_impossible_threshold_fails(crease_lop, capsys):
    rc = main(["verify", crease_lop, "--source", CREASE, "--levels", "6", "--min-psnr", "200", *FAST])
    out = capsys.readouterr().out
    assert rc == 1
    assert "FAILED" in out and "< 200 dB" in out


def test_verify_mean_statistic(crease_lop, capsys):
    rc = main(["verify", crease_lop, "--source", CREASE, "--levels", "6", "--psnr-stat", "mean", "--min-psnr", "45",
               "--json", *FAST])
    render = json.loads(capsys.readouterr().out)["render"]
    assert rc == 0 and render["thresholds"]["psnr_stat"] == "mean"
    assert render["levels"][0]["cap"]["psnr_mean"] >= render["levels"][0]["cap"]["psnr_min"]
    assert main(["verify", crease_lop, "--source", CREASE, "--levels", "6", "--psnr-stat", "mean", "--min-psnr",
                 "150", *FAST]) == 1


def test_verify_depth_threshold(tmp_path, capsys):
    out = tmp_path / "plates.lop"
    assert main(["-q", "cook", PLATES, "-o", str(out)]) == 0
    rc = main(["verify", str(out), "--source", PLATES, "--levels", "6-9", "--min-psnr", "0",
               "--max-depth-errors", "0", "--json", *FAST])
    report = json.loads(capsys.readouterr().out)
    assert rc == 0, report["render"]["failures"]
    assert all(r["cap"]["depth_order_errors"] == 0 for r in report["render"]["levels"])


@pytest.mark.parametrize("extra", [
    ["--resolution", "big"], ["--resolution", "0x10"], ["--views", "0"], ["--views", "21"], ["--levels", "30"],
    ["--levels", "x"], ["--max-depth-errors", "-1"],
])
def test_verify_source_usage_errors(crease_lop, extra, capsys):
    rc = main(["verify", crease_lop, "--source", CREASE, *FAST, *extra])
    assert rc == 2
    assert "error" in capsys.readouterr().err


def test_verify_needs_a_check(crease_lop, capsys):
    assert main(["verify", crease_lop]) == 2
    assert "--source" in capsys.readouterr().err


def test_verify_with_the_wrong_source_is_bad_input(crease_lop, capsys):
    assert main(["verify", crease_lop, "--source", str(FIXTURES / "unit_sphere.glb"), *FAST]) == 2
    assert "source" in capsys.readouterr().err


def test_argparse_usage_is_exit_2(crease_lop):
    with pytest.raises(SystemExit) as exc:
        main(["verify", crease_lop, "--source", CREASE, "--min-psnr", "lots"])
    assert exc.value.code == 2


def test_cook_target_psnr_records_the_calibration(tmp_path, capsys):
    out = tmp_path / "cal.lop"
    rc = main(["cook", CREASE, "-o", str(out), "--target-psnr", "45", "--calibration-views", "2",
               "--calibration-resolution", "160x90", "--calibration-levels", "6-8", "--json",
               "--no-calibration-confirm"])
    desc = json.loads(capsys.readouterr().out)
    assert rc == 0
    assert desc["calibration"]["reached"] is True
    cal = read(str(out)).manifest["options"]["calibration"]
    assert cal["target_psnr"] == 45.0 and cal["kf"] > 0 and cal["levels"] == [6, 7, 8]
    assert len(cal["curve"]) >= 3
    sigmas = [p["sigma"] for p in cal["curve"]]
    assert sigmas == sorted(sigmas)
    chosen = [p for p in cal["curve"] if p["sigma"] == cal["kf_scale"]][0]
    assert chosen["psnr_min"] is None or chosen["psnr_min"] >= 45.0
    # the container was cooked with the calibrated eps (every k_f scaled by the chosen sigma), then
    # scaled by the attribute search's positions knob (lopcook.tune.attributes)
    search = read(str(out)).manifest["options"]["attribute_search"]
    assert read(str(out)).manifest["options"]["analyse"]["eps"] == pytest.approx(
        cal["eps"] / 2.0 ** search["choice"]["log2_kf_scale"])
    assert cal["eps"] == pytest.approx(cal["base_eps"] / cal["kf_scale"])


def test_cook_unreachable_target_fails_without_output(tmp_path, capsys):
    out = tmp_path / "never.lop"
    # --no-edges: with the edge constraint searched, 24-bit rims render the plates exactly (PSNR inf);
    # 89 dB is under the 90.0 dB one colour code off in one pixel of 96x54 shows, so it is searched
    rc = main(["cook", PLATES, "-o", str(out), "--target-psnr", "89", "--calibration-views", "1",
               "--calibration-resolution", "96x54", "--calibration-levels", "6", "--no-edges",
               "--no-calibration-confirm"])
    assert rc == 1
    assert not out.exists()
    err = capsys.readouterr().err
    assert "89 dB" in err and "turn on --edges" in err  # off here: the hint says so


def test_a_missed_target_does_not_suggest_the_edges_when_they_were_searched(tmp_path, capsys):
    out = tmp_path / "never.lop"
    rc = main(["cook", str(FIXTURES / "unit_sphere.glb"), "-o", str(out), "--target-psnr", "89",
               "--calibration-views", "1", "--calibration-resolution", "96x54", "--calibration-levels", "6",
               "--no-calibration-confirm"])
    assert rc == 1 and not out.exists()
    err = capsys.readouterr().err
    assert "no k_f and edge_eps reaches 89 dB" in err and "--edges" not in err


def test_calibrate_command(capsys):
    rc = main(["calibrate", CREASE, "--target-psnr", "40", "--views", "2", "--resolution", "160x90",
               "--levels", "6-7", "--json", "--no-calibration-confirm"])
    cal = json.loads(capsys.readouterr().out)
    assert rc == 0 and cal["reached"] is True
    assert all(len(p["cap_percent"]) == 2 for p in cal["curve"])
    # memory never shrinks as k_f grows
    for a, b in zip(cal["curve"], cal["curve"][1:]):
        assert all(x <= y + 1e-9 for x, y in zip(a["cap_percent"], b["cap_percent"]))
    assert main(["calibrate", CREASE, "--target-psnr", "-3", "--views", "1"]) == 2


def test_calibration_is_confirmed_on_the_gate_harness(gl):
    """The k_f (and edge_eps) chosen on the reduced harness is checked on the gate's (here 4 views at
    320x180); while it fails there, one step stricter on the edges and on k_f are tried, never
    looser; the passing probe with the least memory is kept and recorded."""
    from lopcook.ingest import load
    from lopcook.tune.calibrate import TOLERANCE, calibrate, format_calibration

    scene = load(CREASE)
    cal = calibrate(scene, target_psnr=45.0, levels=[6, 7], views=1, resolution=(96, 54), confirm=(4, (320, 180)))
    conf = cal["confirmation"]
    assert conf["views"] == 4 and conf["resolution"] == [320, 180] and conf["passed"] is cal["reached"] is True
    first = conf["probes"][0]
    searched = {(p["log2_sigma"], p["edge_scale"]) for p in cal["curve"]}
    assert (first["log2_sigma"], first["edge_scale"]) in searched  # starts at the search's choice
    for p in conf["probes"]:
        assert p["confirm"] and p["log2_sigma"] >= first["log2_sigma"] and p["edge_scale"] >= first["edge_scale"]
        steps = (p["log2_sigma"] - first["log2_sigma"]) / TOLERANCE
        assert steps == pytest.approx(round(steps)) and p["edge_scale"] == round(p["edge_scale"])
    chosen = cal["chosen"]
    assert chosen in conf["probes"] and (chosen["psnr_min"] is None or chosen["psnr_min"] >= 45.0)
    assert cal["sigma"] == chosen["sigma"] and cal["edge_eps"] == chosen["edge_eps"]
    for p in conf["probes"]:  # a probe with less memory than the choice did not pass
        if sum(p["cap_percent"]) < sum(chosen["cap_percent"]):
            assert p["psnr_min"] is not None and p["psnr_min"] < 45.0
    assert "confirmed on 4 views" in format_calibration(cal)
    # the same harness as the search: nothing to confirm
    assert calibrate(scene, target_psnr=45.0, levels=[6], views=4, resolution=(320, 180),
                     confirm=(4, (320, 180)))["confirmation"] is None


def test_failed_confirmation_is_one_clear_error():
    from lopcook.errors import LopcookError
    from lopcook.tune.calibrate import require_reached

    probe = {"psnr_min": 38.5, "log2_sigma": 0.0}
    result = {"reached": False, "statistic": "min", "target_psnr": 40.0, "views": 8, "resolution": [640, 360],
              "curve": [dict(probe, psnr_min=41.0)], "search": "kf+edge", "edges": True,
              "confirmation": {"views": 20, "resolution": [1280, 720], "passed": False,
                               "probes": [probe, dict(probe, psnr_min=39.2)]}}
    with pytest.raises(LopcookError, match=r"reached 40 dB there, but on the gate's 20 views at 1280x720 the best of "
                                           r"2 stricter probes was 39.2 dB") as exc:
        require_reached(result, "x.obj")
    assert exc.value.exit_code == 1
