"""lopcook batch: config globs, discovery, depfile parsing, content keys, and real batches of the
fixtures (outputs == one ``lopcook cook`` each, incremental re-cooks, local failures, a worker
crash under the memory cap, progress lines, usage errors)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import FIXTURES
from lopcook import cli
from lopcook.batch.config import BatchConfig, glob_match, load_config, resolve
from lopcook.batch.discover import SOURCE_EXTENSIONS, discover
from lopcook.batch.keys import asset_key, parse_depfile
from lopcook.depfile import format_depfile
from lopcook.errors import LopcookError


def batch(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "lopcook", "batch", *map(str, args)], capture_output=True,
                          text=True, cwd=cwd)


def cook_reference(src: Path, out: Path, *options) -> bytes:
    """What one `lopcook cook SRC -o OUT [options]` writes. The manifest records the source's path
    relative to OUT's folder, so OUT lies as the batch's output does: in a folder beside the
    batch's OUTDIR, at the same relative path."""
    out.parent.mkdir(parents=True, exist_ok=True)
    assert cli.main(["cook", str(src), "-o", str(out), "-q", *options]) == 0
    return out.read_bytes()


def statuses(proc) -> dict:
    doc = json.loads(proc.stdout)
    return {a["relpath"]: a for a in doc["assets"]}


# -- config ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("pattern, path, expected", [
    ("props/**", "props/chair.glb", True),
    ("props/**", "props/a/b/chair.glb", True),
    ("props/**", "hero/props/chair.glb", False),
    ("props/*", "props/a/chair.glb", False),
    ("**/x.obj", "x.obj", True),
    ("**/x.obj", "a/b/x.obj", True),
    ("*.obj", "a/b/x.obj", True),          # no '/': the file name at any depth
    ("*.obj", "a/b/x.glb", False),
    ("a/?.glb", "a/b.glb", True),
    ("a/?.glb", "a/bc.glb", False),
    ("a/[bc].glb", "a/c.glb", True),
    ("a/[!bc].glb", "a/c.glb", False),
    ("a/[!bc].glb", "a/d.glb", True),
    ("hero/**/*.usd", "hero/ship.usd", True),
    ("hero/**/*.usd", "hero/x/y/ship.usd", True),
    ("a+b/(c).glb", "a+b/(c).glb", True),  # regex characters are literal
])
def test_glob_semantics(pattern, path, expected):
    assert glob_match(pattern, path) is expected


def test_config_rules_in_order_later_wins(tmp_path):
    cfg = tmp_path / "lopcook.toml"
    cfg.write_text('options = ["--crease-angle", "45"]\nexclude = ["**/_wip/**"]\n'
                   '[[rules]]\nglob = "props/**"\noptions = ["--lods", "auto"]\n'
                   '[[rules]]\nglob = "props/big/**"\noptions = "--lods 1/2,1/4 --pixel-error 1"\n')
    c = load_config(cfg)
    assert c.options_for("hero/a.glb") == ("--crease-angle", "45")
    assert c.options_for("props/big/a.glb") == ("--crease-angle", "45", "--lods", "auto", "--lods", "1/2,1/4",
                                                "--pixel-error", "1")
    r = resolve(c.options_for("props/big/a.glb"))
    assert r["lods"] == "1/2,1/4" and r["pixel_error"] == 1.0 and r["crease_angle"] == 45.0
    assert c.excluded("x/_wip/a.glb") and not c.excluded("x/wip/a.glb")


def test_resolved_options_are_canonical():
    assert resolve(["--lods=auto"]) == resolve(["--lods", "auto"])
    assert resolve([]) == resolve(["--pixel-error", "0.5"])  # the default spelt out
    assert resolve([]) != resolve(["--pixel-error", "1"])
    assert "output" not in resolve([]) and "source" not in resolve([])


@pytest.mark.parametrize("text, needle", [
    ('[[rules]]\nglob = "a/**"\noptions = ["--no-such-flag"]\n', "--no-such-flag"),
    ('[[rules]]\nglob = "a/**"\noptions = ["--fov", "wide"]\n', "--fov"),
    ('options = ["-o", "x.lop"]\n', "-o"),
    ('options = ["--depfile", "x.d"]\n', "--depfile"),
    ('options = ["--json"]\n', "--json"),
    ('options = ["--help"]\n', "--help"),
    ('options = ["other.glb"]\n', "other.glb"),
    ('[[rules]]\noptions = ["--lods", "auto"]\n', "glob"),
    ('colour = "red"\n', "colour"),
    ('options = [\n', "TOML"),
])
def test_bad_config_is_one_error_naming_the_file(tmp_path, text, needle):
    cfg = tmp_path / "lopcook.toml"
    cfg.write_text(text)
    with pytest.raises(LopcookError) as exc:
        load_config(cfg)
    assert str(cfg) in str(exc.value) and needle in str(exc.value)
    assert exc.value.exit_code == 2


# -- discovery ------------------------------------------------------------------------------------

def test_extensions_are_the_importers():
    from lopcook.ingest import EXTENSIONS

    assert set(SOURCE_EXTENSIONS) == set(EXTENSIONS)


def test_discover_directory_manifest_excludes_and_collisions(tmp_path):
    (tmp_path / "src/props/.hidden").mkdir(parents=True)
    (tmp_path / "src/props/_wip").mkdir()
    for rel in ("props/chair.glb", "props/Table.OBJ", "props/.hidden/x.glb", "props/_wip/y.glb", "props/notes.txt",
                "props/chair.bin", "hero.usda"):
        (tmp_path / "src" / rel).write_bytes(b"x")
    out = tmp_path / "src/out"   # an OUTDIR inside the tree is not searched
    out.mkdir()
    (out / "stale.glb").write_bytes(b"x")
    cfg = BatchConfig(exclude=("**/_wip/**",))
    assets = discover([tmp_path / "src"], out, cfg)
    assert [a.relpath for a in assets] == ["hero.usda", "props/Table.OBJ", "props/chair.glb"]
    assert [os.path.relpath(a.output, out) for a in assets] == ["hero.lop", os.path.join("props", "Table.lop"),
                                                                 os.path.join("props", "chair.lop")]
    assert all(os.path.isabs(a.source) and os.path.isabs(a.output) for a in assets)
    # a manifest: paths relative to it, its directory is the root
    (tmp_path / "src/list.txt").write_text("# assets\nprops/chair.glb\n\nhero.usda\n")
    m = discover([tmp_path / "src/list.txt"], out)
    assert [a.relpath for a in m] == ["hero.usda", "props/chair.glb"]
    # two sources, one output
    (tmp_path / "src/props/chair.obj").write_bytes(b"x")
    with pytest.raises(LopcookError, match="same output"):
        discover([tmp_path / "src"], out, cfg)
    with pytest.raises(LopcookError, match="no such file"):
        discover([tmp_path / "nope"], out)
    (tmp_path / "up.txt").write_text("../elsewhere.glb\n")
    (tmp_path / "src/up.txt").write_text("../elsewhere.glb\n")
    with pytest.raises(LopcookError, match="outside the manifest"):
        discover([tmp_path / "src/up.txt"], out)


# -- depfile parsing and keys -------------------------------------------------------------------------

_path_chars = st.characters(blacklist_characters="\n\r\0", blacklist_categories=("Cs",))


@settings(max_examples=300, deadline=None)
@given(st.lists(st.text(_path_chars, min_size=1, max_size=12).filter(lambda p: not p.endswith("\\") and p.strip()),
                min_size=1, max_size=6, unique=True))
def test_parse_depfile_inverts_format_depfile(deps):
    # words are split on blanks: a dependency that is only blanks, or has leading/trailing ones
    # the escaping keeps, still round-trips because escape() protects every blank
    text = format_depfile("out dir/a.lop", deps, phony=True)
    assert parse_depfile(text) == ("out dir/a.lop", deps)


def test_parse_depfile_examples():
    assert parse_depfile("a.lop: x.glb \\\n  y\\ z.bin\n\nx.glb:\n") == ("a.lop", ["x.glb", "y z.bin"])
    assert parse_depfile("t: a\\\\\\ b c$$d e\\#f") == ("t", ["a\\ b", "c$d", "e#f"])
    with pytest.raises(ValueError):
        parse_depfile("no colon here\n")


def test_key_tracks_content_options_version_and_dependency_set(tmp_path):
    src, tex = tmp_path / "a.obj", tmp_path / "t.png"
    src.write_bytes(b"v 0 0 0\n")
    tex.write_bytes(b"one")
    deps = [str(src), str(tex)]
    k = asset_key(str(src), deps, resolve([]))
    assert asset_key(str(src), list(reversed(deps)), resolve([])) == k  # order does not matter
    os.utime(tex, (1, 1))
    assert asset_key(str(src), deps, resolve([])) == k                  # a time change is not a change
    tex.write_bytes(b"two")
    k2 = asset_key(str(src), deps, resolve([]))
    assert k2 != k
    assert asset_key(str(src), deps, resolve(["--lods", "auto"])) != k2
    assert asset_key(str(src), deps, resolve([]), version="0.0.0") != k2
    tex.unlink()                                                        # a listed file that went away
    assert asset_key(str(src), deps, resolve([])) != k2
    # a tree moved as a whole keeps its keys
    moved = tmp_path / "moved"
    moved.mkdir()
    tex.write_bytes(b"two")
    shutil.copy(src, moved / "a.obj")
    shutil.copy(tex, moved / "t.png")
    assert asset_key(str(moved / "a.obj"), [str(moved / "a.obj"), str(moved / "t.png")], resolve([])) == k2


# -- real batches ---------------------------------------------------------------------------------

def _textured_cube(folder: Path) -> Path:
    """seamed_cube.obj with a material whose map_Kd is tex.png (a 4x4 gradient)."""
    from PIL import Image

    folder.mkdir(parents=True, exist_ok=True)
    obj = (FIXTURES / "seamed_cube.obj").read_text()
    (folder / "cube.obj").write_text("mtllib cube.mtl\nusemtl painted\n" + obj)
    (folder / "cube.mtl").write_text("newmtl painted\nmap_Kd tex.png\n")
    Image.frombytes("L", (4, 4), bytes(range(0, 256, 16))).save(folder / "tex.png")
    return folder / "cube.obj"


@pytest.fixture
def tree(tmp_path):
    """assets/ with a textured OBJ, a glTF (+ .bin), a GLB and a USD text file, and a config."""
    root = tmp_path / "assets"
    _textured_cube(root / "props")
    (root / "hero").mkdir(parents=True)
    shutil.copy(FIXTURES / "two_plates.gltf", root / "hero/plates.gltf")
    shutil.copy(FIXTURES / "two_plates.bin", root / "hero/two_plates.bin")
    shutil.copy(FIXTURES / "glossy_crease.glb", root / "glossy.glb")
    shutil.copy(FIXTURES / "unit_sphere.usda", root / "hero/sphere.usda")
    cfg = tmp_path / "lopcook.toml"
    cfg.write_text('[[rules]]\nglob = "hero/**"\noptions = ["--lods", "1/2", "--pixel-error", "1"]\n')
    return root, cfg


def test_batch_equals_cook_and_is_incremental(tree, tmp_path):
    root, cfg = tree
    out = tmp_path / "out"
    proc = batch(root, "-o", out, "--jobs", "2", "--config", cfg, "--json")
    assert proc.returncode == 0, proc.stderr
    s = statuses(proc)
    assert set(s) == {"props/cube.obj", "hero/plates.gltf", "hero/sphere.usda", "glossy.glb"}
    assert all(a["status"] == "cooked" for a in s.values())
    for a in s.values():
        assert a["bytes"] == os.path.getsize(a["output"]) and a["time_s"] > 0 and a["cpu_s"] > 0
        assert a["peak_rss_bytes"] > 10 * 2 ** 20 and a["warnings"] == []
    # byte for byte what one lopcook cook per asset writes, with the config's options
    ref = tmp_path / "ref"
    ref.mkdir()
    for rel, opts in (("props/cube.obj", ()), ("glossy.glb", ()), ("hero/plates.gltf", ("--lods", "1/2",
                      "--pixel-error", "1")), ("hero/sphere.usda", ("--lods", "1/2", "--pixel-error", "1"))):
        want = cook_reference(root / rel, ref / Path(rel).with_suffix(".lop"), *opts)
        assert Path(s[rel]["output"]).read_bytes() == want, rel
    assert s["hero/plates.gltf"]["output"] == str(out / "hero/plates.lop")
    assert not (out / ".lopcook-batch-tmp").exists()

    # nothing changed: nothing cooked, and it says so
    proc = batch(root, "-o", out, "--jobs", "2", "--config", cfg)
    assert proc.returncode == 0 and "nothing to cook" in proc.stdout and "4 assets up to date" in proc.stdout
    assert proc.stderr == ""
    # a time-only touch of the texture is not a change
    os.utime(root / "props/tex.png")
    assert "nothing to cook" in batch(root, "-o", out, "--config", cfg).stdout

    # new texture content: only the asset whose depfile lists it re-cooks
    from PIL import Image

    Image.frombytes("L", (4, 4), bytes(range(255, 0, -16))).save(root / "props/tex.png")
    s = statuses(batch(root, "-o", out, "--jobs", "2", "--config", cfg, "--json"))
    assert {k: a["status"] for k, a in s.items()} == {"props/cube.obj": "cooked", "hero/plates.gltf": "up-to-date",
                                                    "hero/sphere.usda": "up-to-date", "glossy.glb": "up-to-date"}
    assert Path(s["props/cube.obj"]["output"]).read_bytes() == cook_reference(root / "props/cube.obj",
                                                                              ref / "props/cube.lop")
    # output missing -> re-cook; output altered -> re-cook; the config's options changed -> re-cook
    (out / "glossy.lop").unlink()
    with open(out / "hero/sphere.lop", "r+b") as fh:
        fh.seek(100)
        fh.write(b"\xff")
    cfg.write_text('[[rules]]\nglob = "hero/plates.gltf"\noptions = ["--lods", "1/2", "--pixel-error", "2"]\n'
                   '[[rules]]\nglob = "hero/sphere.usda"\noptions = ["--lods", "1/2", "--pixel-error", "1"]\n')
    s = statuses(batch(root, "-o", out, "--config", cfg, "--json", "--jobs", "2"))
    assert {k: a["status"] for k, a in s.items()} == {"props/cube.obj": "up-to-date", "hero/plates.gltf": "cooked",
                                                    "hero/sphere.usda": "cooked", "glossy.glb": "cooked"}
    assert (out / "glossy.lop").read_bytes() == cook_reference(root / "glossy.glb", ref / "glossy.lop")
    assert (out / "hero/plates.lop").read_bytes() == cook_reference(root / "hero/plates.gltf", ref / "hero/plates.lop",
                                                                    "--lods", "1/2", "--pixel-error", "2")
    # --force cooks everything again, to the same bytes
    before = {p: p.read_bytes() for p in out.rglob("*.lop")}
    s = statuses(batch(root, "-o", out, "--config", cfg, "--json", "--force"))
    assert all(a["status"] == "cooked" for a in s.values())
    assert {p: p.read_bytes() for p in out.rglob("*.lop")} == before


def test_a_bad_asset_fails_alone(tree, tmp_path):
    root, cfg = tree
    out = tmp_path / "out"
    assert batch(root, "-o", out, "--config", cfg, "-q").returncode == 0
    assert (out / "glossy.lop").is_file()
    (root / "glossy.glb").write_bytes(b"glTF\x02\x00\x00\x00 this is not a GLB")   # corrupt the asset
    (root / "broken.obj").write_text("v 0 0 0\nv 1 0 0\nf 1 2 7\n")               # an index out of range
    proc = batch(root, "-o", out, "--config", cfg, "--json", "--jobs", "2")
    assert proc.returncode == 2
    s = statuses(proc)
    assert s["glossy.glb"]["status"] == "failed" and s["broken.obj"]["status"] == "failed"
    assert {k: a["status"] for k, a in s.items() if k not in ("glossy.glb", "broken.obj")} == {
        "props/cube.obj": "up-to-date", "hero/plates.gltf": "up-to-date", "hero/sphere.usda": "up-to-date"}
    for rel in ("glossy.glb", "broken.obj"):
        err = s[rel]["error"]
        assert err.startswith("ingest: ") and str(root / rel) in err and "\n" not in err
    # no partial output, and the old output of the now-corrupt asset is gone (it no longer matches)
    assert not (out / "glossy.lop").exists() and not (out / "broken.lop").exists()
    # a killed batch's scratch folder is removed by the next batch on that OUTDIR
    stale = out / ".lopcook-batch-tmp" / "cook-stale"
    stale.mkdir(parents=True)
    (stale / "task.json").write_text("{}")
    assert batch(root, "-o", out, "--config", cfg, "-q").returncode == 2
    assert not (out / ".lopcook-batch-tmp").exists()
    assert sorted(p.name for p in out.rglob("*") if p.is_file()) == [".lopcook-batch.json", ".lopcook-batch.lock", "cube.lop",
                                                                       "plates.lop", "sphere.lop"]
    # the text summary names each failure with its error; -q keeps only those lines, on stderr
    proc = batch(root, "-o", out, "--config", cfg)
    assert proc.returncode == 2
    assert "2 failed" in proc.stdout and "FAILED glossy.glb: ingest: " in proc.stdout
    assert "FAILED broken.obj: ingest: " in proc.stdout
    proc = batch(root, "-o", out, "--config", cfg, "-q")
    assert proc.returncode == 2 and proc.stdout == ""
    assert [ln.split(":")[2].strip() for ln in proc.stderr.splitlines()] == ["broken.obj", "glossy.glb"]


def _grid_usdc(path: Path, n: int = 100) -> None:
    """An n x n quad grid as a USD crate file (a real, valid asset)."""
    import numpy as np
    from pxr import Usd, UsdGeom, Vt

    stage = Usd.Stage.CreateNew(str(path))
    mesh = UsdGeom.Mesh.Define(stage, "/grid")
    x, y = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1))
    pts = np.stack([x.ravel(), y.ravel(), 0.1 * np.sin(7 * x.ravel())], 1).astype(np.float32)
    i = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
    quads = np.stack([i, i + 1, i + n + 2, i + n + 1], -1).reshape(-1).astype(np.int32)
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(pts))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(n * n, 4, np.int32)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(quads))
    stage.GetRootLayer().Save()


def test_a_worker_crash_fails_only_its_asset(tmp_path):
    """A real failure: under a 1 GB address-space cap usd-core (0.26) dies opening this crate file,
    while the small GLB beside it cooks."""
    root = tmp_path / "a"
    root.mkdir()
    _grid_usdc(root / "grid.usdc")
    shutil.copy(FIXTURES / "seamed_cube.glb", root / "cube.glb")
    out = tmp_path / "out"
    proc = batch(root, "-o", out, "--worker-memory", "1GB", "--jobs", "2", "--json")
    assert proc.returncode == 2, proc.stderr
    s = statuses(proc)
    assert s["cube.glb"]["status"] == "cooked"
    assert (out / "cube.lop").read_bytes() == cook_reference(root / "cube.glb", tmp_path / "ref" / "cube.lop")
    crash = s["grid.usdc"]
    assert crash["status"] == "failed" and not (out / "grid.lop").exists()
    # usd-core dies under the cap: in lopcook's forked USD reader (a clean ingest error) or, where
    # that child is not used, in the worker itself (the worker's crash, by signal)
    if crash.get("signal") is not None:
        assert crash["signal"] in ("SIGSEGV", "SIGBUS", "SIGABRT", "SIGKILL"), crash
        assert crash["error"].startswith("worker crashed: killed by SIG") and "--worker-memory" in crash["error"]
    else:
        assert crash["error"].startswith("ingest: ") and "\n" not in crash["error"], crash
    # with room to work the same asset cooks, to what lopcook cook writes
    proc = batch(root, "-o", out, "--worker-memory", "4GB", "--json")
    assert proc.returncode == 0 and statuses(proc)["grid.usdc"]["status"] == "cooked"
    assert (out / "grid.lop").read_bytes() == cook_reference(root / "grid.usdc", tmp_path / "ref" / "grid.lop")
    assert not (out / ".lopcook-batch-tmp").exists()


def test_progress_lines_and_quiet(tmp_path):
    root = tmp_path / "a"
    root.mkdir()
    for name in ("seamed_cube.glb", "unit_sphere.obj"):
        shutil.copy(FIXTURES / name, root / name)
    proc = batch(root, "-o", tmp_path / "out", "--jobs", "1")
    lines = proc.stderr.splitlines()
    assert proc.returncode == 0 and len(lines) == 2
    assert lines[0].startswith("lopcook: [1/2] cooked ") and lines[1].startswith("lopcook: [2/2] cooked ")
    assert proc.stdout.startswith("lopcook batch: 2 assets: 2 cooked, 0 up to date, 0 failed")
    proc = batch(root, "-o", tmp_path / "out2", "-q")
    assert proc.returncode == 0 and proc.stdout == "" and proc.stderr == ""


def test_one_batch_per_outdir_at_a_time(tmp_path):
    import fcntl

    (tmp_path / "SRC").mkdir()
    shutil.copy(FIXTURES / "seamed_cube.glb", tmp_path / "SRC/cube.glb")
    (tmp_path / "out").mkdir()
    with open(tmp_path / "out/.lopcook-batch.lock", "a+b") as held:
        fcntl.flock(held.fileno(), fcntl.LOCK_EX)   # what a running batch holds
        proc = batch("SRC", "-o", "out", cwd=tmp_path)
        assert proc.returncode == 2 and "another lopcook batch is writing this OUTDIR" in proc.stderr
        assert not (tmp_path / "out/cube.lop").exists()
    assert batch("SRC", "-o", "out", "-q", cwd=tmp_path).returncode == 0
    assert (tmp_path / "out/cube.lop").is_file()


@pytest.mark.parametrize("args, needle", [
    (["NOPE", "-o", "out"], "NOPE"),
    (["SRC", "-o", "out", "--jobs", "0"], "--jobs"),
    (["SRC", "-o", "out", "--worker-memory", "lots"], "--worker-memory"),
    (["SRC", "-o", "out", "--scheduler", "localhost"], "--scheduler"),
    (["SRC", "-o", "out", "--config", "missing.toml"], "missing.toml"),
])
def test_usage_errors_are_one_line(tmp_path, args, needle):
    (tmp_path / "SRC").mkdir()
    proc = batch(*args, cwd=tmp_path)
    assert proc.returncode == 2 and proc.stdout == ""
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("lopcook: error: ") and needle in lines[0], proc.stderr


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="pty.fork: Linux")
def test_progress_bar_on_a_terminal(tmp_path):
    import pty

    root = tmp_path / "a"
    root.mkdir()
    shutil.copy(FIXTURES / "seamed_cube.glb", root / "cube.glb")
    pid, fd = pty.fork()        # stdout and stderr are a terminal (a 0 x 0 window, as in CI)
    if pid == 0:  # pragma: no cover - the child
        os.execv(sys.executable, [sys.executable, "-m", "lopcook", "batch", str(root), "-o", str(tmp_path / "o")])
    out = b""
    while True:
        try:
            chunk = os.read(fd, 4096)
        except OSError:
            break
        if not chunk:
            break
        out += chunk
    _, status = os.waitpid(pid, 0)
    text = out.decode("utf-8", "replace")
    assert os.waitstatus_to_exitcode(status) == 0, text
    assert "\rlopcook batch: 100%|" in text and "1/1" in text     # the tqdm bar, redrawn in place
    assert "[1/1] cooked" not in text                            # not the log lines
    assert "lopcook batch: 1 asset: 1 cooked" in text


def test_an_output_folder_that_cannot_be_made_fails_before_any_cook(tmp_path):
    (tmp_path / "afile").write_text("x")
    src = tmp_path / "cube.glb"
    shutil.copy(FIXTURES / "seamed_cube.glb", src)
    proc = batch(src, "-o", tmp_path / "afile" / "out")
    assert proc.returncode == 2 and "cannot create the output folder" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and "Traceback" not in proc.stderr


def test_emit_ninja_never_overwrites_an_input(tmp_path):
    src = tmp_path / "cube.glb"
    shutil.copy(FIXTURES / "seamed_cube.glb", src)
    before = src.read_bytes()
    for target, words in ((src, "ends in '.glb'"), (tmp_path / "missing" / "b.ninja", "does not exist")):
        proc = batch(src, "-o", tmp_path / "out", "--emit-ninja", target)
        assert proc.returncode == 2 and words in proc.stderr and "Traceback" not in proc.stderr, proc.stderr
    assert src.read_bytes() == before
