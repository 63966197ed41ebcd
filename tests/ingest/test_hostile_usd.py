"""Hostile USD (issue 17): deep hierarchies load (walked iteratively, the native parser in a
forked child), PointInstancer bombs are counted and refused before they are expanded, and a
crash of the native library becomes one clear error."""

from __future__ import annotations

import os
import re

import pytest

from tests.support import fuzzcases as fz
from lopcook.errors import LopcookError  # noqa: E402
from lopcook.ingest import load, usd  # noqa: E402
from lopcook.ingest.build import MAX_PARTS  # noqa: E402

EXC_NAME = re.compile(r"\b\w+(Error|Exception)\b")


def _write(tmp_path, text, name="a.usda"):
    p = tmp_path / name
    p.write_text(text)
    return str(p)


def test_a_600_deep_hierarchy_loads(tmp_path):
    scene = load(_write(tmp_path, fz._deep_xform(600)))
    assert len(scene.parts) == 1 and scene.n_triangles == 12
    assert scene.parts[0].source.count("/") == 602  # /R/x0/.../x599/m


def test_a_20000_deep_hierarchy_loads_or_is_refused_cleanly(tmp_path):
    try:
        scene = load(_write(tmp_path, fz._deep_xform(20_000)))
    except LopcookError as exc:
        assert "\n" not in str(exc) and not EXC_NAME.search(str(exc))
    else:
        assert scene.n_triangles == 12


def test_an_instancer_bomb_is_refused_before_expanding(tmp_path):
    path = _write(tmp_path, fz._instancer_bomb(MAX_PARTS + 1))
    with pytest.raises(LopcookError, match=f"at most {MAX_PARTS:,} parts"):
        load(path)


def test_nested_instancers_are_counted_through_every_level(tmp_path):
    with pytest.raises(LopcookError, match="PointInstancer"):
        load(_write(tmp_path, fz._nested_instancers(22)))


def test_small_nested_instancers_still_expand(tmp_path):
    scene = load(_write(tmp_path, fz._nested_instancers(3)))
    assert len(scene.parts) == 8


def test_a_native_crash_becomes_one_clear_error(tmp_path, monkeypatch):
    """The child that runs USD dies by a signal: the parent reports it (exit 2), it does not die."""
    import signal

    def crash(*args):
        os.kill(os.getpid(), signal.SIGSEGV)

    monkeypatch.setattr(usd, "_load_in_child", crash)
    monkeypatch.setattr(usd, "_usd_started_here", lambda: False)  # the forked child sees the patch
    path = _write(tmp_path, fz._deep_xform(2))
    with pytest.raises(LopcookError) as info:
        usd.load(path, fmt="usda", settings=__import__("lopcook.settings").settings.DEFAULT_INGEST)
    text = str(info.value)
    assert "USD crashed" in text and "signal 11" in text and "\n" not in text


def test_errors_raised_in_the_child_keep_their_fields(tmp_path):
    path = _write(tmp_path, fz._instancer_bomb(2).replace("protoIndices = [0, 0]", "protoIndices = [0, 5]"))
    with pytest.raises(LopcookError) as info:
        load(path)
    assert info.value.stage == "ingest" and info.value.exit_code == 2 and info.value.path == path


@pytest.mark.parametrize("label", ["junk_png", "truncated_png", "bomb_png"])
def test_unreadable_usd_texture_is_a_warning(tmp_path, label):
    (tmp_path / "t.png").write_bytes(fz._bad_pngs()[label])
    scene = load(_write(tmp_path, fz.usda_textured("t.png")))
    assert scene.parts[0].texture is None
    assert any("texture" in w for w in scene.warnings), scene.warnings


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_fifo_texture_is_never_opened(tmp_path):
    os.mkfifo(tmp_path / "t.png")
    scene = load(_write(tmp_path, fz.usda_textured("t.png")))
    assert any("not a regular file" in w for w in scene.warnings), scene.warnings


@pytest.mark.parametrize("attr, value, what", [("quatf[] orientationsf", "(nan, 0, 0, 0)", "NaN"),
                                               ("point3f[] positions", "(inf, 0, 0)", "Inf")])
def test_a_non_finite_instance_is_refused_naming_it(tmp_path, attr, value, what):
    """A NaN orientation was reported as a zero scale and the instance skipped: now the file is
    refused, naming the instancer, the array, the instance and NaN or Inf."""
    from conftest import FIXTURES

    text = (FIXTURES / "point_instancer.usda").read_text()
    line = next(ln for ln in text.splitlines() if ln.strip().startswith(attr + " ="))
    head, values = line.split("= [", 1)
    items = re.findall(r"\([^)]*\)", values)
    items[2] = value
    path = tmp_path / "bad.usda"
    path.write_text(text.replace(line, f"{head}= [{', '.join(items)}]"))
    with pytest.raises(LopcookError) as exc:
        load(str(path))
    msg = str(exc.value)
    assert "\n" not in msg and "PointInstancer" in msg and f"[2] is {what}" in msg, msg
    assert "zero scale" not in msg
