"""``lopcook web`` (lopcook.emit.web): the glTF that carries a container's materials for
runtime/js/three-lop.js: one mesh per part naming it through LOPCOOK_lop_geometry, the container
by a relative URI, the source's materials and images, the extension required; deterministic;
bad output names refused with exit 2."""

from __future__ import annotations

import json
import shutil
import struct

import pytest

from lopcook.cli import main
from lopcook.lop.container import read
from lopcook.emit.web import EXTENSION, write_web_gltf


@pytest.fixture
def helmet(corpus_containers, corpus, tmp_path):
    shutil.copy(corpus_containers["DamagedHelmet"], tmp_path / "helmet.lop")
    return tmp_path / "helmet.lop", corpus / "DamagedHelmet" / "DamagedHelmet.gltf"


def test_web_gltf_names_every_part_with_the_sources_materials(helmet, tmp_path):
    lop, src = helmet
    (tmp_path / "web").mkdir()
    out = write_web_gltf(str(lop), str(tmp_path / "web" / "h.gltf"), str(src))
    assert out["written"] == [str(tmp_path / "web" / "h.gltf"), str(tmp_path / "web" / "h.bin")] and not out["warnings"]
    doc = json.loads((tmp_path / "web" / "h.gltf").read_text())
    c = read(str(lop))
    ext = doc["extensions"][EXTENSION]
    assert ext == {"uri": "../helmet.lop", "byteLength": lop.stat().st_size, "version": [3, 0]}
    assert doc["extensionsRequired"] == doc["extensionsUsed"] == [EXTENSION]
    assert len(doc["meshes"]) == len(c.manifest["parts"]) == len(doc["nodes"]) - 1
    prim = doc["meshes"][0]["primitives"][0]
    assert prim["extensions"][EXTENSION] == {"part": 0} and prim["mode"] == 4
    pos = doc["accessors"][prim["attributes"]["POSITION"]]
    assert pos["count"] == c.manifest["parts"][0]["lods"][0]["vertices"] and "bufferView" not in pos
    assert set(prim["attributes"]) == {"POSITION", "NORMAL", "TEXCOORD_0"}
    mat = doc["materials"][prim["material"]]
    assert {"baseColorTexture", "metallicRoughnessTexture"} <= set(mat["pbrMetallicRoughness"]) and "normalTexture" in mat
    assert len(doc["images"]) == 5 and doc["buffers"][0]["byteLength"] == (tmp_path / "web" / "h.bin").stat().st_size
    first = (tmp_path / "web" / "h.gltf").read_bytes()
    write_web_gltf(str(lop), str(tmp_path / "web" / "h.gltf"), str(src))
    assert (tmp_path / "web" / "h.gltf").read_bytes() == first  # deterministic


def test_web_glb_and_placements(corpus_containers, corpus, tmp_path):
    shutil.copy(corpus_containers["chess_set_flat"], tmp_path / "chess.lop")
    write_web_gltf(str(tmp_path / "chess.lop"), str(tmp_path / "chess.glb"), str(corpus / "chess_set_flat.usdc"))
    data = (tmp_path / "chess.glb").read_bytes()
    n = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20:20 + n])
    parts = read(str(tmp_path / "chess.lop")).manifest["parts"]
    assert [m["primitives"][0]["extensions"][EXTENSION]["part"] for m in doc["meshes"]] == list(range(len(parts)))
    assert any("placement" in p for p in parts) and doc["extensions"][EXTENSION]["uri"] == "chess.lop"


def test_cli_web(helmet, tmp_path, capsys):
    lop, src = helmet
    assert main(["web", str(lop), "-o", str(tmp_path / "x.gltf"), "--source", str(src), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["parts"] == 1 and out["materials"] == 1
    assert main(["web", str(lop), "-o", str(tmp_path / "x.obj")]) == 2
    assert main(["web", str(lop), "-o", str(lop)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 2 and "Traceback" not in err
    assert main(["web", str(tmp_path / "missing.lop"), "-o", str(tmp_path / "y.gltf")]) == 2
    assert not (tmp_path / "y.gltf").exists()


def test_web_without_source_warns_and_has_no_materials(helmet, tmp_path, capsys):
    """Moved where neither its recorded source path nor its folder leads to the source."""
    lop = tmp_path / "moved" / "deeper" / "helmet.lop"
    lop.parent.mkdir(parents=True)
    shutil.move(helmet[0], lop)
    assert main(["web", str(lop), "-o", str(tmp_path / "g.gltf")]) == 0
    assert "no materials" in capsys.readouterr().err
    doc = json.loads((tmp_path / "g.gltf").read_text())
    assert "materials" not in doc and "buffers" not in doc and not (tmp_path / "g.bin").exists()
