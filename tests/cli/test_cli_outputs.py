"""What a user meets on the command line: outputs checked before any work, inputs never
overwritten, warnings visible (and fatal with --strict), option values checked at parse time,
one-line messages in the user's terms, progress lines for CI logs."""

from __future__ import annotations

import shutil
import subprocess
import sys

import pytest

from conftest import FIXTURES, REPO
from lopcook.cli import main

SRC = FIXTURES / "two_plates.glb"


@pytest.fixture()
def work(tmp_path, monkeypatch):
    shutil.copy(SRC, tmp_path / "two_plates.glb")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _err(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err, err
    return err


@pytest.mark.parametrize("out, words", [
    ("two_plates.glb", "ends in '.glb'"),            # the source itself
    ("missing_dir/x.lop", "does not exist"),
    ("newdir/", "is a directory"),
    ("x.gltf", "ends in '.gltf'"),
    ("x.json", "ends in '.json'"),
])
def test_cook_output_refused_before_any_work(work, capsys, out, words):
    before = (work / "two_plates.glb").read_bytes()
    assert main(["cook", "two_plates.glb", "-o", out]) == 2
    assert words in _err(capsys)
    assert (work / "two_plates.glb").read_bytes() == before
    assert sorted(p.name for p in work.iterdir()) == ["two_plates.glb"]


def test_a_name_too_long_is_refused_first_and_the_longest_allowed_one_is_written(work, capsys):
    from lopcook.atomic import name_max

    limit = name_max(work)
    too_long = "a" * (limit - 3) + ".lop"
    assert main(["cook", "two_plates.glb", "-o", too_long]) == 2
    assert "allows" in _err(capsys)
    longest = "b" * (limit - 4) + ".lop"  # its temporary file's name would be too long: a short one is used
    assert main(["cook", "two_plates.glb", "-o", longest, "-q"]) == 0
    assert sorted(p.name for p in work.iterdir()) == sorted(["two_plates.glb", longest])


def test_output_under_a_file_is_refused(work, capsys):
    (work / "afile").write_text("x")
    assert main(["cook", "two_plates.glb", "-o", "afile/x.lop"]) == 2
    assert "does not exist" in _err(capsys)


def test_an_input_is_never_overwritten(work, capsys):
    """A source named .lop, or a dependency of the source (a glTF's .bin), is never an output."""
    shutil.copy(SRC, work / "weird.lop")
    assert main(["cook", "weird.lop", "-o", "weird.lop"]) == 2
    assert "input of this run" in _err(capsys)
    for name in ("two_plates.gltf", "two_plates.bin"):
        shutil.copy(FIXTURES / name, work / name)
    before = (work / "two_plates.bin").read_bytes()
    assert main(["cook", "two_plates.gltf", "-o", "x.lop", "--depfile", "two_plates.bin"]) == 2
    assert "--depfile ends in '.bin'" in _err(capsys)
    assert (work / "two_plates.bin").read_bytes() == before and not (work / "x.lop").exists()


def test_depfile_naming_the_container_is_refused(work, capsys):
    assert main(["-q", "cook", "two_plates.glb", "-o", "x.lop"]) == 0
    old = (work / "x.lop").read_bytes()
    assert main(["cook", "two_plates.glb", "-o", "x.lop", "--depfile", "x.lop"]) == 2
    assert "--depfile" in _err(capsys) and (work / "x.lop").read_bytes() == old


def test_decode_output_checks(work, capsys):
    assert main(["-q", "cook", "two_plates.glb", "-o", "x.lop"]) == 0
    old = (work / "x.lop").read_bytes()
    for out in ("x.lop", "x.txt", "x"):
        assert main(["decode", "x.lop", "--level", "10", "-o", out]) == 2
        assert "must name a .glb/.gltf file" in _err(capsys)
    assert (work / "x.lop").read_bytes() == old
    assert main(["-q", "decode", "x.lop", "--level", "10", "-o", "x.glb"]) == 0


def test_warnings_are_printed_quiet_hides_them_strict_refuses(work, capsys):
    obj = work / "tri.obj"
    obj.write_text("mtllib missing.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    assert main(["cook", str(obj), "-o", "tri.lop"]) == 0
    err = capsys.readouterr().err
    assert "lopcook: warning:" in err and "missing.mtl" in err
    assert main(["-q", "cook", str(obj), "-o", "tri2.lop"]) == 0
    assert capsys.readouterr().err == ""
    assert main(["cook", str(obj), "-o", "tri3.lop", "--strict"]) == 2
    err = _err(capsys)
    assert "--strict" in err and not (work / "tri3.lop").exists()
    # labelled by the stage that warned, not as a usage error
    assert err.startswith(f"lopcook: error: ingest: {obj}: ") and "usage" not in err


@pytest.mark.parametrize("flag, value", [("--eps", "2"), ("--eps", "inf"), ("--texture-kf", "-1"),
                                         ("--texture-kf", "nan"), ("--depth-threshold", "-1"), ("--nearest", "inf"),
                                         ("--kf", "inf"), ("--pixel-error", "inf"), ("--target-psnr", "nan"),
                                         ("--edge-eps", "nan"), ("--crease-angle", "nan")])
def test_option_values_are_checked_at_parse_time(work, capsys, flag, value):
    assert main(["cook", "two_plates.glb", "-o", "x.lop", flag, value]) == 2
    err = _err(capsys)
    assert flag in err and "error: usage" in err
    assert not (work / "x.lop").exists()


def test_wording(work, capsys):
    assert main(["-q", "cook", "two_plates.glb", "-o", "x.lop"]) == 0
    assert main(["verify", "x.lop", "--decoders", "--levels", "12-6"]) == 2
    assert "reversed" in _err(capsys)
    with pytest.raises(SystemExit) as exc:
        main(["cook", "two_plates.glb", "-o", "y.lop", "--bogus"])
    assert exc.value.code == 2
    err = _err(capsys)  # one line, naming the command and where its usage is
    assert err.startswith("lopcook cook: error:") and "--bogus" in err and "lopcook cook --help" in err
    sphere = FIXTURES / "unit_sphere.glb"
    assert main(["cook", str(sphere), "-o", "s.lop", "--nearest", "50"]) == 0
    out = capsys.readouterr().out
    assert "1 part," in out and "1 parts" not in out and "planes none" not in out
    assert "by what no view needs: planes 14-24 not written" in out


def test_progress_plain_prints_one_line_per_stage(work):
    r = subprocess.run([sys.executable, "-m", "lopcook", "--progress", "plain", "cook", "two_plates.glb", "-o", "p.lop"],
                       capture_output=True, text=True, cwd=work, env={"PYTHONPATH": str(REPO), "PATH": ""})
    assert r.returncode == 0, r.stderr
    lines = r.stderr.splitlines()
    assert any(line.startswith("lopcook: ingest two_plates.glb:") and line.endswith(" s") for line in lines)
    assert any(line.startswith("lopcook: analyse: 1 of 1 in ") for line in lines)
    silent = subprocess.run([sys.executable, "-m", "lopcook", "cook", "two_plates.glb", "-o", "q.lop"],
                            capture_output=True, text=True, cwd=work, env={"PYTHONPATH": str(REPO), "PATH": ""})
    assert silent.returncode == 0 and silent.stderr == ""  # off a terminal: no progress by default


@pytest.mark.parametrize("src", ["two_plates.glb", "point_instancer.usda", "unit_sphere.obj"])
def test_max_triangles_is_a_flag(work, capsys, src):
    """``--max-triangles`` bounds a source in every format, counted before it is expanded."""
    path = FIXTURES / src
    assert main(["cook", str(path), "-o", "m.lop", "--max-triangles", "10"]) == 2
    err = _err(capsys)
    assert "--max-triangles" in err and not (work / "m.lop").exists()
    assert main(["-q", "cook", str(path), "-o", "m.lop"]) == 0
    assert main(["cook", str(path), "-o", "n.lop", "--max-triangles", "0"]) == 2
    assert "--max-triangles must be in [1, " in _err(capsys)


def test_container_read_errors_are_not_emit_errors(work, capsys):
    (work / "junk.lop").write_bytes(b"LOPC" + b"\0" * 40)
    assert main(["inspect", "junk.lop"]) == 2
    err = _err(capsys)
    assert "emit:" not in err and err.startswith("lopcook: error: container: junk.lop: ")


@pytest.mark.parametrize("args", [["cook", "two_plates.glb"], ["cook", "two_plates.glb", "-o", "x.lop", "--lods"],
                                  ["nosuch"], [], ["verify"]])
def test_argument_errors_are_one_line(work, capsys, args):
    with pytest.raises(SystemExit) as exc:
        main(args)
    assert exc.value.code == 2
    err = _err(capsys)  # one line, no traceback
    assert "error:" in err and "--help" in err
