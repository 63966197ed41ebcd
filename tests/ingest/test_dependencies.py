"""Scene.dependencies (every file an importer read) and lopcook.depfile (Make/ninja depfiles).

Files are built in tmp_path; "relative" cases chdir into tmp_path and load a relative path, so
the expected dependencies are spelt relative to the working directory, as in a Makefile.
"""

from __future__ import annotations

import io
import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest

from lopcook.depfile import DependencyList, escape, format_depfile, write_depfile
from tests.support.fixtures import seamed_cube, write_gltf, write_obj
from lopcook.ingest import load
from lopcook.types import Scene


def png_bytes(color=(200, 10, 10)) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (4, 4), color).save(buf, format="PNG")
    return buf.getvalue()


def spell(tmp_path: Path, mode: str):
    """(path-as-given maker, dependency-as-expected maker) for a relative or absolute source."""
    if mode == "relative":
        os.chdir(tmp_path)
        return (lambda rel: rel), (lambda rel: os.path.normpath(rel))
    return (lambda rel: str(tmp_path / rel)), (lambda rel: os.path.normpath(str(tmp_path / rel)))


@pytest.fixture
def in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # restored after the test (spell() may chdir again)
    return tmp_path


def test_scene_default_is_empty():
    assert Scene(parts=(), source="x.obj", format="obj").dependencies == ()


# ----------------------------------------------------------------------------- glTF
def _gltf_with_images(tmp_path: Path, images: list[dict], used: list[int]) -> Path:
    """seamed_cube as assets/cube.gltf + cube.bin, with ``images``; materials use ``used``."""
    gltf = tmp_path / "assets" / "cube.gltf"
    write_gltf(seamed_cube(), gltf)
    doc = json.loads(gltf.read_text())
    doc["images"] = images
    doc["textures"] = [{"source": i} for i in range(len(images))]
    doc["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": i}}} for i in used]
    if used:
        doc["meshes"][0]["primitives"][0]["material"] = 0
    gltf.write_text(json.dumps(doc))
    return gltf


@pytest.mark.parametrize("mode", ["relative", "absolute"])
def test_gltf_bin_and_texture(in_tmp, mode):
    given, dep = spell(in_tmp, mode)
    (in_tmp / "assets" / "tex").mkdir(parents=True)
    (in_tmp / "assets" / "tex" / "albedo map.png").write_bytes(png_bytes())
    (in_tmp / "assets" / "tex" / "unused.png").write_bytes(png_bytes())
    _gltf_with_images(in_tmp, [{"uri": "tex/albedo%20map.png"}, {"uri": "tex/unused.png"}], used=[0])
    scene = load(given("assets/cube.gltf"))
    assert scene.parts[0].texture is not None
    # the unused image is never opened, so it is not a dependency
    assert scene.dependencies == (dep("assets/cube.gltf"), dep("assets/cube.bin"),
                                  dep("assets/tex/albedo map.png"))
    assert os.path.isabs(scene.dependencies[0]) == (mode == "absolute")


def test_gltf_missing_texture_is_listed_data_uri_is_not(in_tmp):
    import base64

    uri = "data:image/png;base64," + base64.b64encode(png_bytes()).decode()
    _gltf_with_images(in_tmp, [{"uri": "../shared/missing.png"}], used=[0])
    scene = load("assets/cube.gltf")
    assert scene.parts[0].texture is None and any("missing.png" in w for w in scene.warnings)
    assert scene.dependencies == ("assets/cube.gltf", "assets/cube.bin", "shared/missing.png")

    _gltf_with_images(in_tmp, [{"uri": uri}], used=[0])
    scene = load("./assets//cube.gltf")  # spelt normalised
    assert scene.parts[0].texture is not None
    assert scene.dependencies == ("assets/cube.gltf", "assets/cube.bin")


def test_glb_without_sidecars_lists_only_itself(in_tmp):
    write_gltf(seamed_cube(), in_tmp / "cube.glb", binary=True)
    assert load("cube.glb").dependencies == ("cube.glb",)


def test_damaged_helmet_lists_what_the_loader_reads(corpus, monkeypatch):
    # DamagedHelmet has five images, but lopcook reads only the base colour texture
    doc = json.loads((corpus / "DamagedHelmet" / "DamagedHelmet.gltf").read_text())
    assert len(doc["images"]) == 5
    scene = load(corpus / "DamagedHelmet" / "DamagedHelmet.gltf")
    base = str(corpus / "DamagedHelmet")
    assert scene.dependencies == (os.path.join(base, "DamagedHelmet.gltf"),
                                  os.path.join(base, "DamagedHelmet.bin"),
                                  os.path.join(base, "Default_albedo.jpg"))
    monkeypatch.chdir(corpus)
    scene = load("DamagedHelmet/DamagedHelmet.gltf")
    assert scene.dependencies == ("DamagedHelmet/DamagedHelmet.gltf", "DamagedHelmet/DamagedHelmet.bin",
                                  "DamagedHelmet/Default_albedo.jpg")


@pytest.mark.parametrize("name", ["Duck.glb", "CesiumMilkTruck.glb", "spot.obj", "UtahTeapot.usd"])
def test_corpus_sources_come_first_and_every_dependency_exists(corpus, name):
    scene = load(str(corpus / name))
    assert scene.dependencies[0] == str(corpus / name)
    assert all(os.path.isfile(d) for d in scene.dependencies)
    assert len(set(scene.dependencies)) == len(scene.dependencies)


# ----------------------------------------------------------------------------- OBJ
def _obj(tmp_path: Path, mtl_text: str | None, mtllib: str = "mats/cube.mtl") -> Path:
    obj = tmp_path / "models" / "cube.obj"
    write_obj(seamed_cube(), obj)
    obj.write_text(f"mtllib {mtllib}\nusemtl paint\n" + obj.read_text())
    if mtl_text is not None:
        (tmp_path / "models" / "mats").mkdir(parents=True, exist_ok=True)
        (tmp_path / "models" / "mats" / "cube.mtl").write_text(mtl_text)
    return obj


@pytest.mark.parametrize("mode", ["relative", "absolute"])
def test_obj_mtl_and_texture(in_tmp, mode):
    given, dep = spell(in_tmp, mode)
    _obj(in_tmp, "newmtl paint\nmap_Kd -s 1 1 1 ../tex/paint.png\n")
    (in_tmp / "models" / "tex").mkdir()
    (in_tmp / "models" / "tex" / "paint.png").write_bytes(png_bytes())
    scene = load(given("models/cube.obj"))
    assert scene.parts[0].texture is not None
    assert scene.dependencies == (dep("models/cube.obj"), dep("models/mats/cube.mtl"),
                                  dep("models/tex/paint.png"))


def test_obj_missing_texture_is_listed_with_its_fallback(in_tmp):
    _obj(in_tmp, "newmtl paint\nmap_Kd ../tex/gone.png\n")
    scene = load("models/cube.obj")
    assert scene.parts[0].texture is None and any("gone.png" in w for w in scene.warnings)
    # the loader looks for the texture where the .mtl says, then next to the .obj
    assert scene.dependencies == ("models/cube.obj", "models/mats/cube.mtl", "models/tex/gone.png",
                                  "models/gone.png")
    (in_tmp / "models" / "gone.png").write_bytes(png_bytes())  # the fallback appears
    scene = load("models/cube.obj")
    assert scene.parts[0].texture is not None
    assert scene.dependencies[2:] == ("models/tex/gone.png", "models/gone.png")


def test_obj_missing_mtl_is_listed(in_tmp):
    _obj(in_tmp, None)
    scene = load("models/cube.obj")
    assert any("cube.mtl" in w for w in scene.warnings)
    assert scene.dependencies == ("models/cube.obj", "models/mats/cube.mtl")


def test_obj_without_mtllib_lists_only_itself(in_tmp):
    write_obj(seamed_cube(), in_tmp / "plain.obj")
    assert load("plain.obj").dependencies == ("plain.obj",)


# ----------------------------------------------------------------------------- USD
from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade, UsdUtils, Vt  # noqa: E402  (usd-core is a dependency)


def _stage(path: Path, default: str | None = None):
    path.parent.mkdir(parents=True, exist_ok=True)
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, "Y")
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    if default:
        stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, f"/{default}").GetPrim())
    return stage


def _tri(stage, path: str):
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(0, 0, 0), Gf.Vec3f(1, 0, 0), Gf.Vec3f(0, 1, 0)]))
    mesh.CreateFaceVertexCountsAttr([3])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2])
    return mesh


def _textured(stage, mesh, mat_path: str, file: str) -> None:
    mat = UsdShade.Material.Define(stage, mat_path)
    ps = UsdShade.Shader.Define(stage, f"{mat_path}/PS")
    ps.CreateIdAttr("UsdPreviewSurface")
    tx = UsdShade.Shader.Define(stage, f"{mat_path}/Tex")
    tx.CreateIdAttr("UsdUVTexture")
    tx.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(file)
    tx.CreateOutput("rgb", Sdf.ValueTypeNames.Float3)
    ps.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).ConnectToSource(tx.ConnectableAPI(), "rgb")
    mat.CreateSurfaceOutput().ConnectToSource(ps.ConnectableAPI(), "surface")
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(mat)


def _leaf_layer(path: Path, texture: str | None = None, root: str = "X") -> None:
    stage = _stage(path, default=root)
    mesh = _tri(stage, f"/{root}/M")
    if texture:
        _textured(stage, mesh, f"/{root}/Mat", texture)
    stage.GetRootLayer().Save()


def _usd_scene(tmp_path: Path) -> Path:
    """scene/root.usda: sublayer layers/sub.usda, /A references parts/ref.usda, /B payload
    parts/pay.usda (whose mesh uses ../tex/pay.png), /T textured ./tex/root.png, /L ./tex/lost.png
    (missing). Also an unselected variant referencing parts/never.usda (not used, not listed)."""
    scene = tmp_path / "scene"
    (scene / "tex").mkdir(parents=True)
    (scene / "tex" / "root.png").write_bytes(png_bytes())
    (scene / "tex" / "pay.png").write_bytes(png_bytes((0, 0, 255)))
    _leaf_layer(scene / "layers" / "sub.usda", root="S")
    _leaf_layer(scene / "parts" / "ref.usda")
    _leaf_layer(scene / "parts" / "pay.usda", texture="../tex/pay.png")
    _leaf_layer(scene / "parts" / "never.usda")

    stage = _stage(scene / "root.usda")
    stage.GetRootLayer().subLayerPaths.append("layers/sub.usda")
    a = stage.DefinePrim("/A")
    a.GetReferences().AddReference("parts/ref.usda")
    b = stage.DefinePrim("/B")
    b.GetPayloads().AddPayload("parts/pay.usda")
    _textured(stage, _tri(stage, "/T"), "/MatT", "./tex/root.png")
    _textured(stage, _tri(stage, "/L"), "/MatL", "./tex/lost.png")
    v = stage.DefinePrim("/V")
    vset = v.GetVariantSets().AddVariantSet("look")
    for name in ("plain", "other"):
        vset.AddVariant(name)
    vset.SetVariantSelection("other")
    with vset.GetVariantEditContext():
        stage.DefinePrim("/V/Other").GetReferences().AddReference("parts/never.usda")
    vset.SetVariantSelection("plain")
    stage.GetRootLayer().Save()
    return scene / "root.usda"


@pytest.mark.parametrize("mode", ["relative", "absolute"])
def test_usd_sublayer_reference_payload_and_textures(in_tmp, mode):
    given, dep = spell(in_tmp, mode)
    _usd_scene(in_tmp)
    scene = load(given("scene/root.usda"))
    assert sorted(p.name for p in scene.parts) == ["/A/M", "/B/M", "/L", "/S/M", "/T"]
    assert any("lost.png" in w for w in scene.warnings)
    assert scene.dependencies == (
        dep("scene/root.usda"),
        dep("scene/layers/sub.usda"),      # root layer stack first
        dep("scene/parts/ref.usda"),       # then in prim order: /A references,
        dep("scene/parts/pay.usda"),       # /B payload
        dep("scene/tex/pay.png"),          # textures in the order the meshes use them
        dep("scene/tex/root.png"),
        dep("scene/tex/lost.png"),         # missing, still listed
    )


def test_usd_dependencies_are_deterministic(in_tmp):
    _usd_scene(in_tmp)
    first = load("scene/root.usda").dependencies
    for _ in range(3):
        assert load("scene/root.usda").dependencies == first


def test_usd_absolute_reference_stays_absolute(in_tmp):
    _leaf_layer(in_tmp / "lib" / "prop.usda")
    stage = _stage(in_tmp / "shot" / "shot.usda")
    stage.DefinePrim("/P").GetReferences().AddReference(str(in_tmp / "lib" / "prop.usda"))
    stage.DefinePrim("/Q").GetReferences().AddReference("../lib/prop.usda")  # same file, one spelling
    stage.GetRootLayer().Save()
    scene = load("shot/shot.usda")
    assert scene.dependencies == ("shot/shot.usda", os.path.normpath(str(in_tmp / "lib" / "prop.usda")))


def _usdz(tmp_path: Path) -> Path:
    src = tmp_path / "pkgsrc"
    src.mkdir()
    (src / "tex.png").write_bytes(png_bytes())
    _leaf_layer(src / "inner.usda", texture="./tex.png")
    stage = _stage(src / "main.usda", default="Root")
    stage.GetPrimAtPath("/Root").GetReferences().AddReference("./inner.usda")
    stage.GetRootLayer().subLayerPaths.append("./inner.usda")
    stage.GetRootLayer().Save()
    out = tmp_path / "out" / "pkg.usdz"
    out.parent.mkdir()
    assert UsdUtils.CreateNewUsdzPackage(Sdf.AssetPath(str(src / "main.usda")), str(out))
    shutil.rmtree(src)  # only the copies inside the package remain
    return out


@pytest.mark.parametrize("mode", ["relative", "absolute"])
def test_usdz_lists_only_the_package(in_tmp, mode):
    given, dep = spell(in_tmp, mode)
    _usdz(in_tmp)
    scene = load(given("out/pkg.usdz"))
    assert scene.format == "usdz"
    assert all(p.texture is not None for p in scene.parts)  # textures were read from inside
    assert scene.dependencies == (dep("out/pkg.usdz"),)


def test_usda_referencing_a_usdz(in_tmp):
    _usdz(in_tmp)
    stage = _stage(in_tmp / "shot.usda")
    stage.DefinePrim("/P").GetReferences().AddReference("out/pkg.usdz")
    stage.GetRootLayer().Save()
    scene = load("shot.usda")
    assert scene.parts and all(p.texture is not None for p in scene.parts)
    assert scene.dependencies == ("shot.usda", "out/pkg.usdz")


# ----------------------------------------------------------------------------- DependencyList
def test_dependency_list_spelling(in_tmp):
    d = DependencyList("a/b/x.gltf")
    assert d.add("../t.png") == "a/t.png"
    assert d.add("/abs/t.png") == "/abs/t.png"
    assert d.add_path("a/b/./y.bin") == "a/b/y.bin"
    assert d.add_resolved(str(in_tmp / "a" / "b" / "sub" / "l.usda")) == "a/b/sub/l.usda"
    assert d.add_resolved("/elsewhere/l.usda", keep_absolute=True) == "/elsewhere/l.usda"
    d.add("t.png/../../t.png")  # duplicate after normalisation
    assert d.paths() == ("a/b/x.gltf", "a/t.png", "/abs/t.png", "a/b/y.bin", "a/b/sub/l.usda",
                         "/elsewhere/l.usda")
    up = DependencyList("../up/x.obj")
    assert up.add("m.mtl") == "../up/m.mtl"
    assert up.add_resolved(os.path.abspath("../up/t/c.png")) == "../up/t/c.png"
    a = DependencyList(str(in_tmp / "x.obj"))
    assert a.add("m.mtl") == str(in_tmp / "m.mtl")
    assert a.add_resolved(str(in_tmp / "q" / ".." / "l.usda")) == str(in_tmp / "l.usda")


# ----------------------------------------------------------------------------- depfile
def test_escape():
    assert escape("plain/file-1.2_x.png") == "plain/file-1.2_x.png"
    assert escape("my textures/a b.png") == "my\\ textures/a\\ b.png"
    assert escape("price$1.png") == "price$$1.png"
    assert escape("#1.png") == "\\#1.png"
    assert escape("C:/x.png") == "C\\:/x.png"
    assert escape("tab\there") == "tab\\\there"
    assert escape("back\\ slash") == "back\\\\\\ slash"  # 2N+1 backslashes before the space
    with pytest.raises(ValueError):
        escape("new\nline.png")


def test_format_depfile():
    text = format_depfile("out/a b.lop", ["src/a b.gltf", "src/$x.bin", "src/a b.gltf", "t/#1.png"])
    assert text == "out/a\\ b.lop: src/a\\ b.gltf \\\n  src/$$x.bin \\\n  t/\\#1.png\n"
    assert format_depfile("o.lop", []) == "o.lop:\n"
    assert format_depfile("o.lop", ["a.obj", "m.mtl"], phony=True) == "o.lop: a.obj \\\n  m.mtl\n\na.obj:\n\nm.mtl:\n"


def test_write_depfile_atomic_and_deterministic(tmp_path):
    out = tmp_path / "out.d"
    out.write_text("stale content that is much longer than the new one\n" * 10)
    write_depfile(out, "out.lop", ["a.gltf", "my dir/a.bin"])
    first = out.read_bytes()
    assert first == b"out.lop: a.gltf \\\n  my\\ dir/a.bin\n"
    write_depfile(str(out), "out.lop", ("a.gltf", "my dir/a.bin"))
    assert out.read_bytes() == first
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.d"]  # no temporary left behind
    with pytest.raises(ValueError):
        write_depfile(out, "out.lop", ["bad\nname"])
    assert out.read_bytes() == first and sorted(p.name for p in tmp_path.iterdir()) == ["out.d"]


WEIRD = ["src/plain.gltf", "src/with space.bin", "src/dollar$sign.png", "src/hash#1.png", "src/co:lon.png"]


@pytest.mark.skipif(shutil.which("make") is None, reason="GNU make not installed")
def test_gnu_make_reads_the_depfile(tmp_path):
    for name in WEIRD:
        (tmp_path / name).parent.mkdir(exist_ok=True)
        (tmp_path / name).write_text("x")
    (tmp_path / "out.lop").write_text("cooked")
    os.utime(tmp_path / "out.lop", (2e9, 2e9))  # newer than every dependency
    write_depfile(tmp_path / "out.d", "out.lop", WEIRD)
    (tmp_path / "Makefile").write_text("out.lop:\n\ttouch out.lop\n-include out.d\n")

    def up_to_date() -> int:
        return subprocess.run(["make", "-q", "out.lop"], cwd=tmp_path, capture_output=True).returncode

    assert up_to_date() == 0
    for name in WEIRD:  # each escaped name reaches make as the real file
        os.utime(tmp_path / name, (3e9, 3e9))
        assert up_to_date() == 1, name
        os.utime(tmp_path / name, (1e9, 1e9))
        assert up_to_date() == 0, name


@pytest.mark.skipif(shutil.which("make") is None, reason="GNU make not installed")
def test_gnu_make_with_a_missing_dependency_needs_phony_rules(tmp_path):
    (tmp_path / "a.obj").write_text("x")
    (tmp_path / "out.lop").write_text("cooked")
    os.utime(tmp_path / "out.lop", (2e9, 2e9))
    (tmp_path / "Makefile").write_text("out.lop:\n\ttouch out.lop\n-include out.d\n")
    write_depfile(tmp_path / "out.d", "out.lop", ["a.obj", "missing tex.png"])
    run = subprocess.run(["make", "-q", "out.lop"], cwd=tmp_path, capture_output=True, text=True)
    assert run.returncode == 2 and "No rule to make target" in run.stderr
    write_depfile(tmp_path / "out.d", "out.lop", ["a.obj", "missing tex.png"], phony=True)
    run = subprocess.run(["make", "-q", "out.lop"], cwd=tmp_path, capture_output=True, text=True)
    assert run.returncode == 1  # out of date (rebuilds until the file appears), no error


@pytest.mark.skipif(shutil.which("ninja") is None, reason="ninja not installed")
@pytest.mark.parametrize("phony", [False, True])
def test_ninja_reads_the_depfile(tmp_path, phony):
    write_depfile(tmp_path / "prepared.d", "out.lop", WEIRD, phony=phony)
    (tmp_path / "build.ninja").write_text(
        "rule cook\n  command = cp prepared.d out.d && touch out.lop\n  depfile = out.d\n  deps = gcc\n"
        "build out.lop: cook\n")
    subprocess.run(["ninja"], cwd=tmp_path, check=True, capture_output=True)
    listed = subprocess.run(["ninja", "-t", "deps", "out.lop"], cwd=tmp_path, check=True,
                            capture_output=True, text=True).stdout
    deps = [ln.strip() for ln in listed.splitlines()[1:] if ln.strip()]
    assert deps == WEIRD
