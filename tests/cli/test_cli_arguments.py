"""Arguments people type and the messages they get back: negative values in every flag that
takes a list or coordinates, ``--json`` error objects on stdout, a batch config's bad option
quoted once, and a ``--target-psnr`` no render can show refused before any work."""

from __future__ import annotations

import json
import shutil
import struct

import pytest

from conftest import FIXTURES
from lopcook.cli import main
from lopcook.cli.parser import build_parser

SRC = FIXTURES / "two_plates.glb"


@pytest.fixture()
def work(tmp_path, monkeypatch):
    shutil.copy(SRC, tmp_path / "two_plates.glb")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _one_line(capsys) -> tuple[str, str]:
    """(stdout, the one stderr line) of the last run."""
    out, err = capsys.readouterr()
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in err, err
    return out, lines[0]


# ---- negative values ---------------------------------------------------------------------------

COOK = ["cook", "x.obj", "-o", "x.lop"]
LIST_FLAGS = [
    (["refine", "x.lop", "--target", "0,0,0", "-o", "x.glb", "--camera", "-1.2,0.3,4"], "camera", "-1.2,0.3,4"),
    (["refine", "x.lop", "--camera", "1,2,3", "-o", "x.glb", "--target", "-0.5,-1,-2"], "target", "-0.5,-1,-2"),
    (["refine", "x.lop", "--target", "0,0,0", "-o", "x.glb", "--cam", "-1,2,3"], "camera", "-1,2,3"),
    (["refine", "x.lop", "--camera", "1,2,3", "--target", "0,0,0", "-o", "x.glb", "--viewport", "-1x2"],
     "viewport", "-1x2"),
    (COOK + ["--lods", "-1/2,1/4"], "lods", "-1/2,1/4"),
    (COOK + ["--nearest", "-0.5m"], "nearest", "-0.5m"),
    (COOK + ["--viewport", "-1920x1080"], "viewport", "-1920x1080"),
    (COOK + ["--calibration-levels", "-6,7"], "calibration_levels", "-6,7"),
    (COOK + ["--calibration-resolution", "-64x64"], "calibration_resolution", "-64x64"),
    (COOK + ["--budget-resolution", "-64x64"], "budget_resolution", "-64x64"),
    (COOK + ["--target-bytes", "-1/6"], "target_bytes", "-1/6"),
    (COOK + ["--eps", "-1e-3"], "eps", -1e-3),
    (["calibrate", "x.obj", "--target-psnr", "40", "--levels", "-6,7"], "calibration_levels", "-6,7"),
    (["verify", "x.lop", "--decoders", "--levels", "-3,4"], "levels", "-3,4"),
    (["report", "x.lop", "--source", "x.obj", "-o", "r.html", "--levels", "-3,4"], "levels", "-3,4"),
    (["report", "x.lop", "--source", "x.obj", "-o", "r.html", "--resolution", "-64x64"], "resolution", "-64x64"),
    (["bench", "-o", "out", "--bits", "-1,12"], "bits", "-1,12"),
    (["bench", "-o", "out", "--levels", "-6,7"], "levels", "-6,7"),
]


@pytest.mark.parametrize("argv, dest, value", LIST_FLAGS, ids=[f"{a[0]} {a[-2]}" for a, _, _ in LIST_FLAGS])
def test_every_list_flag_takes_a_value_with_a_leading_minus(argv, dest, value):
    """argparse alone reads '-1.2,0.3,4' as an unknown option ("expected one argument")."""
    ns = build_parser().parse_args(argv)
    assert getattr(ns, dest) == value


def test_a_flag_is_still_not_taken_as_a_value(capsys):
    with pytest.raises(SystemExit) as exc:
        build_parser().parse_args(["refine", "x.lop", "--camera", "--target", "0,0,0", "-o", "x.glb"])
    assert exc.value.code == 2
    assert "--camera: expected one argument" in capsys.readouterr().err


def _glb_json(path) -> dict:
    data = path.read_bytes()
    assert data[:4] == b"glTF"
    (length,) = struct.unpack_from("<I", data, 12)
    return json.loads(data[20:20 + length])


def test_refine_with_negative_camera_coordinates_writes_a_gltf(work, capsys):
    assert main(["-q", "cook", "two_plates.glb", "-o", "h.lop", "--hierarchy"]) == 0
    assert main(["refine", "h.lop", "--camera", "-1.2,0.3,4", "--target", "-0.1,-0.2,-0.3", "-o", "r.glb"]) == 0
    refine = _glb_json(work / "r.glb")["asset"]["extras"]["lopcook"]["refine"]
    assert refine["camera"] == [-1.2, 0.3, 4.0] and refine["target"] == [-0.1, -0.2, -0.3]


@pytest.mark.parametrize("argv, flag", [
    (["cook", "two_plates.glb", "-o", "x.lop", "--lods", "-1/2"], "--lods '-1/2'"),
    (["cook", "two_plates.glb", "-o", "x.lop", "--nearest", "-0.5m"], "--nearest"),
    (["cook", "two_plates.glb", "-o", "x.lop", "--viewport", "-1920x1080"], "--viewport"),
    (["bench", "two_plates.glb", "-o", "out", "--bits", "-1,12"], "--bits"),
])
def test_a_negative_value_meets_the_flags_own_check(work, capsys, argv, flag):
    assert main(argv) == 2
    _, line = _one_line(capsys)
    assert line.startswith("lopcook: error: usage: ") and flag in line
    assert not (work / "x.lop").exists() and not (work / "out").exists()


# ---- --json error objects ----------------------------------------------------------------------

#: one failing run per command that takes --json (a missing input: exit 2 after parsing)
FAILING = {
    "inspect": ["inspect", "missing.obj"],
    "cook": ["cook", "missing.obj", "-o", "x.lop"],
    "calibrate": ["calibrate", "missing.obj", "--target-psnr", "40"],
    "decode": ["decode", "missing.lop", "--level", "8", "-o", "x.glb"],
    "web": ["web", "missing.lop", "-o", "x.gltf"],
    "view": ["view", "missing.lop"],
    "refine": ["refine", "missing.lop", "--camera", "-1,2,3", "--target", "0,0,0", "-o", "x.glb"],
    "analyse": ["analyse", "missing.obj"],
    "verify": ["verify", "missing.lop", "--decoders"],
    "report": ["report", "missing.lop", "--source", "missing.obj", "-o", "r.html"],
    "bench": ["bench", "-o", "out", "--bits", "0"],
    "batch": ["batch", "missing.obj", "-o", "out"],
}


def test_the_failing_runs_cover_every_command_with_json():
    sub = build_parser()._subparsers._group_actions[0].choices
    assert set(FAILING) == {name for name, p in sub.items() if "--json" in p._option_string_actions}


def _error_object(out: str) -> dict:
    lines = [ln for ln in out.splitlines() if ln.strip()]
    assert len(lines) == 1, out
    obj = json.loads(lines[0])
    assert set(obj) == {"error"} and set(obj["error"]) == {"exit_code", "message"}
    return obj["error"]


@pytest.mark.parametrize("command", sorted(FAILING))
def test_json_failure_prints_one_error_object_on_stdout(work, capsys, command):
    assert main(FAILING[command] + ["--json"]) == 2
    out, line = _one_line(capsys)
    error = _error_object(out)
    assert error["exit_code"] == 2
    assert line == f"lopcook: error: {error['message']}"  # the same words as stderr
    assert "missing" in error["message"] or "--bits" in error["message"]


@pytest.mark.parametrize("command", sorted(FAILING))
def test_json_usage_error_of_the_parser_prints_one_error_object(work, capsys, command):
    with pytest.raises(SystemExit) as exc:
        main(FAILING[command] + ["--no-such-flag", "--json"])
    assert exc.value.code == 2
    out, line = _one_line(capsys)
    error = _error_object(out)
    assert error["exit_code"] == 2 and "unrecognized arguments: --no-such-flag" in error["message"]
    assert f"lopcook {command}: error: unrecognized arguments: --no-such-flag" in line


def test_without_json_a_failure_prints_nothing_on_stdout(work, capsys):
    assert main(FAILING["inspect"]) == 2
    out, _ = _one_line(capsys)
    assert out == ""


def test_json_internal_error_prints_exit_code_3(work, capsys, monkeypatch):
    from lopcook.cli import commands

    def broken(args):
        raise RuntimeError("a bug")

    monkeypatch.setitem(commands.COMMANDS, "inspect", broken)
    assert main(["inspect", "two_plates.glb", "--json"]) == 3
    out, line = _one_line(capsys)
    error = _error_object(out)
    assert error["exit_code"] == 3 and "internal error: RuntimeError: a bug" in error["message"]


# ---- messages ----------------------------------------------------------------------------------

def test_a_bad_option_in_a_batch_config_is_reported_once(work, capsys):
    (work / "bad.toml").write_text('[[rules]]\nglob = "*.glb"\noptions = ["--lodz", "1/2"]\n')
    assert main(["batch", "two_plates.glb", "-o", "out", "--config", "bad.toml"]) == 2
    _, line = _one_line(capsys)
    assert line.count("error:") == 1 and line.count("--lodz") == 1, line
    assert line.startswith("lopcook: error: usage: bad.toml: rule 1 (*.glb): unrecognized arguments: --lodz 1/2")


@pytest.mark.parametrize("argv, shown", [
    (["cook", "two_plates.glb", "-o", "x.lop", "--target-psnr", "500"], "1280x720 is already 112.5 dB"),
    (["cook", "two_plates.glb", "-o", "x.lop", "--target-psnr", "110", "--calibration-views", "4"],
     "640x360 is already 106.5 dB"),
    (["calibrate", "two_plates.glb", "--target-psnr", "126", "--psnr-stat", "mean"],
     "one of 20 views of 1280x720 is already 125.6 dB"),
])
def test_a_target_psnr_no_render_can_show_is_refused_before_any_work(work, capsys, monkeypatch, argv, shown):
    import lopcook.api

    def no_work(*a, **k):
        raise AssertionError("the source was read")

    monkeypatch.setattr(lopcook.api, "load", no_work)
    assert main(argv) == 2
    _, line = _one_line(capsys)
    assert f"--target-psnr {argv[argv.index('--target-psnr') + 1]}: no render can show it" in line and shown in line
    assert not (work / "x.lop").exists()


def test_a_reachable_target_psnr_passes_the_check():
    from lopcook.cli.parser import settings_from_args

    for argv in (["cook", "x.glb", "-o", "x.lop", "--target-psnr", "112"],
                 ["calibrate", "x.glb", "--target-psnr", "125", "--psnr-stat", "mean"]):
        target = float(argv[argv.index("--target-psnr") + 1])
        assert settings_from_args(build_parser().parse_args(argv)).tune.target_psnr == target
