"""Where the cook recorded its source (the manifest's ``source.path``, relative to the
container's folder) and how ``decode`` finds it there: ``lopcook cook assets/x.gltf -o
build/x.lop`` then ``decode`` in ``build/`` gives a textured preview (docs/format.md 9.2)."""

from __future__ import annotations

import json
import os
import shutil
import struct
from pathlib import Path

import pytest

from conftest import FIXTURES
from lopcook import api
from lopcook.cli import main
from lopcook.emit import preview as P
from lopcook.lop.container import read
from tests.support import fixtures as F


def _glb_json(path: Path) -> dict:
    data = path.read_bytes()
    assert data[:4] == b"glTF"
    (length,) = struct.unpack_from("<I", data, 12)
    return json.loads(data[20:20 + length])


@pytest.fixture()
def layout(tmp_path, monkeypatch):
    """``root/assets/tex.gltf`` (+ .bin and PNG textures beside it) and an empty ``root/build``;
    the working directory is ``root``."""
    root = tmp_path / "root"
    F.write_textured_gltf(root / "assets" / "tex.gltf", binary=False)
    (root / "build").mkdir()
    monkeypatch.chdir(root)
    return root


def test_decode_in_a_build_folder_finds_the_source_cooked_from_assets(layout, monkeypatch, capsys):
    assert main(["-q", "cook", "assets/tex.gltf", "-o", "build/tex.lop"]) == 0
    assert read("build/tex.lop").manifest["source"]["path"] == "../assets/tex.gltf"
    monkeypatch.chdir(layout / "build")
    assert main(["decode", "tex.lop", "--level", "16", "-o", "preview.glb"]) == 0
    err = capsys.readouterr().err
    assert "warning" not in err, err  # no "not found beside": the recorded path was used
    doc = _glb_json(layout / "build" / "preview.glb")
    assert len(doc["materials"]) == 1 and {i["name"] for i in doc["images"]} == {"albedo", "orm", "normal", "emissive"}
    assert all("material" in prim for mesh in doc["meshes"] for prim in mesh["primitives"])


def test_the_recorded_path_depends_only_on_the_relative_layout(layout, tmp_path, monkeypatch):
    assert main(["-q", "cook", "assets/tex.gltf", "-o", "build/a.lop"]) == 0
    monkeypatch.chdir(layout / "build")  # another working directory, the same layout
    assert main(["-q", "cook", "../assets/tex.gltf", "-o", "b.lop"]) == 0
    other = tmp_path / "elsewhere" / "deeper"  # the same layout under another root
    shutil.copytree(layout / "assets", other / "assets")
    (other / "build").mkdir()
    monkeypatch.chdir(other)
    assert main(["-q", "cook", str(other / "assets" / "tex.gltf"), "-o", str(other / "build" / "c.lop")]) == 0
    a, b, c = ((d / n).read_bytes() for d, n in ((layout / "build", "a.lop"), (layout / "build", "b.lop"),
                                                  (other / "build", "c.lop")))
    assert a == b == c  # the recorded path is relative, even for absolute arguments
    assert read(str(layout / "build" / "a.lop")).manifest["source"]["path"] == "../assets/tex.gltf"


def test_a_source_beside_the_container_is_recorded_by_its_name(layout):
    assert main(["-q", "cook", "assets/tex.gltf", "-o", "assets/tex.lop"]) == 0
    assert read("assets/tex.lop").manifest["source"]["path"] == "tex.gltf"


def test_the_api_cook_without_a_path_records_none():
    src = str(FIXTURES / "two_plates.glb")
    m = api.cook(api.load(src)).manifest
    assert set(m["source"]) == {"file", "format", "sha256", "unit_scale_m", "up_axis"}


def test_where_no_relative_path_exists_the_absolute_one_is_recorded(monkeypatch):
    def other_drive(path, start=os.curdir):
        raise ValueError("path is on mount 'D:', start on mount 'C:'")

    monkeypatch.setattr(os.path, "relpath", other_drive)
    assert P.recorded_source_path("assets/x.gltf", "build/x.lop") == os.path.abspath("assets/x.gltf")


def test_a_moved_container_falls_back_to_the_source_beside_it(layout, monkeypatch, capsys):
    assert main(["-q", "cook", "assets/tex.gltf", "-o", "build/tex.lop"]) == 0
    moved = layout / "moved" / "deeper"  # '../assets' from here does not exist
    moved.mkdir(parents=True)
    shutil.copy(layout / "build" / "tex.lop", moved / "tex.lop")
    monkeypatch.chdir(moved)
    assert main(["decode", "tex.lop", "--level", "16", "-o", "geometry.glb"]) == 0
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "not found beside tex.lop, nor at '../assets/tex.gltf' where the cook " \
                                     "recorded it" in err and "geometry only" in err
    for name in os.listdir(layout / "assets"):
        shutil.copy(layout / "assets" / name, moved / name)
    assert main(["decode", "tex.lop", "--level", "16", "-o", "beside.glb"]) == 0
    assert capsys.readouterr().err == ""
    assert len(_glb_json(moved / "beside.glb")["materials"]) == 1


def test_a_recorded_path_to_another_file_is_checked_by_sha256(layout, monkeypatch, capsys):
    assert main(["-q", "cook", "assets/tex.gltf", "-o", "build/tex.lop"]) == 0
    gltf = layout / "assets" / "tex.gltf"
    gltf.write_bytes(gltf.read_bytes().replace(b'"version"', b'"version" ', 1))  # another file, same scene
    monkeypatch.chdir(layout / "build")
    assert main(["decode", "tex.lop", "--level", "16", "-o", "x.glb"]) == 0
    err = capsys.readouterr().err
    assert "where the cook recorded it" in err and "sha256 differs" in err and "geometry only" in err


def test_an_explicit_source_is_never_replaced(layout, monkeypatch, capsys):
    assert main(["-q", "cook", "assets/tex.gltf", "-o", "build/tex.lop"]) == 0
    monkeypatch.chdir(layout / "build")
    wrong = layout / "other.glb"
    shutil.copy(FIXTURES / "two_plates.glb", wrong)
    assert main(["decode", "tex.lop", "--level", "16", "-o", "x.glb", "--source", str(wrong)]) == 0
    assert "--source" in capsys.readouterr().err  # the recorded source was not used instead
    assert "materials" not in _glb_json(layout / "build" / "x.glb")


def test_decode_never_writes_over_the_recorded_source(layout, monkeypatch, capsys):
    assert main(["-q", "cook", "assets/tex.gltf", "-o", "build/tex.lop"]) == 0
    before = (layout / "assets" / "tex.gltf").read_bytes()
    monkeypatch.chdir(layout / "build")
    assert main(["decode", "tex.lop", "--level", "16", "-o", "../assets/tex.gltf"]) == 2
    assert "input of this run" in capsys.readouterr().err
    assert (layout / "assets" / "tex.gltf").read_bytes() == before


def test_batch_records_the_path_from_the_final_output_folder(layout):
    assert main(["-q", "batch", "assets", "-o", "out"]) == 0
    batch = read("out/tex.lop")
    assert batch.manifest["source"]["path"] == "../assets/tex.gltf"
    assert main(["-q", "cook", "assets/tex.gltf", "-o", "build/tex.lop"]) == 0
    assert Path("build/tex.lop").read_bytes() == Path("out/tex.lop").read_bytes()  # the same layout
