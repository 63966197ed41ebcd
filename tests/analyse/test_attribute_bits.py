"""Attribute bits end to end: the worst-case bound (lopcook.analyse.attribute_bits.worst_case_bits) on
analytic cases (the average-case default is tests/analyse/test_attribute_bound.py), ``cook --normal-bits/--uv-bits/--color-bits`` (range errors exit 2), the manifest
and ``inspect --json`` fields ``attribute_bits`` / ``vertex_bits``, and determinism."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from lopcook.cli import main
from lopcook.analyse.attribute_bits import ImageModel
from lopcook.analyse.attribute_bits import worst_case_bits as _worst_case_bits
from lopcook.lop.codecs import AttributeBits
from lopcook.lop.codecs.colors_unorm import color_error_bound
from lopcook.lop.codecs.normals_oct import normal_error_deg
from lopcook.lop.codecs.uvs_range import uv_error_bound
from lopcook.lop.container import from_bytes
from lopcook.errors import LopcookError

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures"


def worst_case_bits(*, normals=False, uvs=None, colors=False, eps, normal_kf=0.0, uv_kf=0.0, color_kf=0.0):
    """``worst_case_bits`` of a part that has normals / these UVs / colours (their values do not
    matter to the bound, only the UVs' range)."""
    one = np.ones((1, 3))
    attrs = {"normals": one if normals else None, "uvs": uvs, "colors": np.ones((1, 4)) if colors else None}
    return _worst_case_bits(attrs, ImageModel(eps=eps, direction_kf=normal_kf, texcoord_kf=uv_kf, color_kf=color_kf))


def smallest(pred, lo, hi):
    return next((b for b in range(lo, hi + 1) if pred(b)), hi)


@pytest.mark.parametrize("kf,eps", [(16.0, 1 / 255), (1.0, 1 / 255), (16.0, 0.05), (0.0, 1 / 255), (1e6, 1e-6)])
def test_worst_case_normal_bits_are_the_smallest_meeting_the_bound(kf, eps):
    b = worst_case_bits(normals=True, uvs=None, colors=False, eps=eps, normal_kf=kf).normals
    assert kf * math.radians(normal_error_deg(b)) <= eps or b == 16
    if b > 4:
        assert kf * math.radians(normal_error_deg(b - 1)) > eps
    assert b == smallest(lambda x: kf * math.radians(normal_error_deg(x)) <= eps, 4, 16)


def test_worst_case_bits_with_the_default_shading():
    # ks * n = 16, eps = 1/255: theta <= 0.014 degrees: 14 bits (0.0105), not 13 (0.021)
    assert worst_case_bits(normals=True, uvs=None, colors=True, eps=1 / 255, normal_kf=16.0, color_kf=1.0) == \
        AttributeBits(normals=14, uvs=None, colors=8)
    # colours: 1/(2 (2^b - 1)) <= eps
    assert worst_case_bits(normals=False, uvs=None, colors=True, eps=1 / 29, color_kf=1.0).colors == 4
    assert worst_case_bits(normals=False, uvs=None, colors=True, eps=1 / 100, color_kf=1.0).colors == 6
    assert color_error_bound(6) <= 1 / 100 < color_error_bound(5)


def test_worst_case_uv_bits_follow_the_texture_slope_and_range():
    uv = np.array([[0.0, 0.0], [1.0, 1.0], [0.3, 0.7]])
    eps = 1 / 255
    for slope in (0.0, 1.0, 50.0, 548.0, 3000.0):
        b = worst_case_bits(normals=False, uvs=uv, colors=False, eps=eps, uv_kf=slope).uvs
        ok = lambda x: slope * np.linalg.norm(uv_error_bound([0, 0], [1, 1], x)) <= eps  # noqa: E731
        assert b == smallest(ok, 6, 16)
    assert worst_case_bits(normals=False, uvs=uv, colors=False, eps=eps, uv_kf=0.0).uvs == 6  # untextured
    assert worst_case_bits(normals=False, uvs=uv, colors=False, eps=eps, uv_kf=3000.0).uvs == 16  # capped
    # a smaller range needs fewer bits for the same slope
    assert worst_case_bits(normals=False, uvs=uv * 0.01, colors=False, eps=eps, uv_kf=50.0).uvs < \
        worst_case_bits(normals=False, uvs=uv, colors=False, eps=eps, uv_kf=50.0).uvs
    with pytest.raises(LopcookError):
        worst_case_bits(normals=True, uvs=None, colors=False, eps=0.0, normal_kf=1.0)


def _cook(tmp_path, name, *flags):
    out = tmp_path / name
    rc = main(["-q", "cook", str(FIXTURES / "two_plates.glb"), "-o", str(out), *flags])
    return rc, out


def _inspect(capsys, path):
    capsys.readouterr()
    assert main(["inspect", str(path), "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_cook_flags_set_the_bits_and_inspect_reports_them(tmp_path, capsys):
    rc, out = _cook(tmp_path, "a.lop", "--normal-bits", "9", "--uv-bits", "11", "--color-bits", "5")
    assert rc == 0
    c = from_bytes(out.read_bytes())
    assert c.manifest["options"]["attributes"] == {"normal_bits": 9, "uv_bits": 11, "color_bits": 5, "parts": []}
    d = _inspect(capsys, out)
    for p, mp in zip(d["parts"], c.manifest["parts"]):
        assert p["attribute_bits"] == mp["attribute_bits"] == {"normals": 9, "uvs": 11, "colors": None}
        vb = p["vertex_bits"]
        assert (vb["normals"], vb["uvs"], vb["colors"]) == (18, 22, 0)
        lod = c.entries.parts[0].lods[0]
        for level in ("6", "11", "12"):
            assert vb["positions"][level] == 8 * lod.cap_bytes(int(level)) / lod.vertices
            assert vb["total"][level] == vb["positions"][level] + 40
    assert d["vertex_bits"]["normals"] == 18 and d["vertex_bits"]["total"]["11"] == \
        sum(p["vertex_bits"]["total"]["11"] for p in d["parts"]) / 2  # two equal plates
    # 81 vertices x 40 bits = 3240 bits = 102 words: 24 bits of the last word hold no field;
    # word-aligned records of 9, 9, 11, 11 bits: 11+11+9 = 31 and 9 in two words, 24 bits wasted
    assert d["parts"][0]["attribute_waste"] == {"buffer_bits": [32 * 102 - 81 * 40], "aligned_bits_per_vertex": 24}
    # the same flags give the same bytes
    rc2, out2 = _cook(tmp_path, "b.lop", "--normal-bits", "9", "--uv-bits", "11", "--color-bits", "5")
    assert rc2 == 0 and out2.read_bytes() == out.read_bytes()


def test_default_cook_records_the_bound_based_bits(tmp_path, capsys):
    rc, out = _cook(tmp_path, "d.lop")
    assert rc == 0
    c = from_bytes(out.read_bytes())
    assert "attributes" not in c.manifest["options"]
    for p in c.manifest["parts"]:  # average-case bound: 8-bit normals; untextured UVs cannot change a colour
        assert p["attribute_bits"] == {"normals": 8, "uvs": 6, "colors": None}
        assert all(e["attribute_bits"] == p["attribute_bits"] and e["record_bits"] == 28 for e in p["lods"])


@pytest.mark.parametrize("flag,value", [("--normal-bits", "3"), ("--normal-bits", "17"), ("--uv-bits", "5"),
                                        ("--uv-bits", "17"), ("--color-bits", "3"), ("--color-bits", "9")])
def test_out_of_range_flags_are_usage_errors(tmp_path, capsys, flag, value):
    rc, out = _cook(tmp_path, "x.lop", flag, value)
    err = capsys.readouterr().err
    assert rc == 2 and not out.exists()
    assert flag in err and "usage" in err and "Traceback" not in err
