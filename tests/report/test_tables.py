"""Text tables of render results (lopcook.verify.tables): exact lines for a known result. No GL."""

from __future__ import annotations

from lopcook.verify.tables import format_table


def _variant(mem, pmin, pmean, depth):
    return {"percent_of_float32": mem, "psnr_min": pmin, "psnr_mean": pmean, "depth_order_errors": depth}


RESULT = {
    "source": "a.glb", "container": "a.lop", "resolution": [320, 180], "views": [0, 10], "samples": 4,
    "shading": {"ks": 0.5, "shininess": 32.0}, "float32_bytes": 123456,
    "levels": [
        {"level": 6, "camera_level": 6, "camera_distance_m": 12.3456,
         "ap": _variant(25.0, 30.04, 31.25, 17), "cap": _variant(40.55, None, None, 0)},
        {"level": 24, "camera_level": 9, "camera_distance_m": 0.5, "cap": _variant(100.0, 88.0, 90.0, 2)},
    ],
    "seconds": {"total": 1.26, "render": 1.0, "metrics": 0.2}, "device": {"renderer": "llvmpipe"},
}


def test_format_table_lines():
    lines = format_table(RESULT).split("\n")
    assert lines[0] == "render check: a.glb vs a.lop"
    assert lines[1] == ("  2 views, 320x180, 4x MSAA, Phong ks 0.5 n 32; PSNR in dB over object pixels "
                        "(min / mean over views); memory vs float32 (123,456 bytes)")
    assert lines[2].split() == ["level", "AP", "mem", "AP", "PSNR", "min/mean", "CAP", "mem", "CAP", "PSNR",
                                "min/mean", "depth-order", "px", "AP/CAP", "distance", "m"]
    assert lines[3].split() == ["6", "25.0%", "30.0", "/", "31.2", "40.5%", "inf", "/", "inf", "17", "/", "0",
                                "12.35"]
    assert lines[4].split() == ["24@9", "-", "-", "100.0%", "88.0", "/", "90.0", "-", "/", "2", "0.5"]
    assert lines[5] == "  1.3 s (render 1.0 s, metrics 0.2 s) on llvmpipe"
    assert len(lines) == 6


def test_columns_line_up():
    """Every level line has the width of the column line up to the distance column."""
    lines = format_table(RESULT).split("\n")
    head = lines[2].index("distance")
    for ln in lines[3:5]:
        assert ln[head - 2:head] == "  " and ln[head] != " "


def test_the_header_says_when_back_faces_are_culled():
    culled = dict(RESULT, shading=dict(RESULT["shading"], back_faces="culled unless the part is double-sided"))
    line = format_table(culled).split("\n")[1]
    assert line.startswith("  2 views, 320x180, 4x MSAA, Phong ks 0.5 n 32, single-sided back faces culled; PSNR")
