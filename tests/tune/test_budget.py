"""Byte-budget fit (lopcook.tune.budget, ``cook --target-bytes``): sizes by scope, the Purnomo ordering on a
small bumpy sphere (the chosen LOD and level beat quantize-only and simplify-only), the written
container holds only the chosen LOD and planes, and the "nothing fits" error.

GL tests skip when EGL is missing, except under CI=true. They render 4 views at 160x90 (seconds).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from lopcook.settings import Settings, SimplifySettings
from lopcook.tune import budget as BG

FAST = Settings(simplify=SimplifySettings(backend="fast"))
from tests.support import fixtures as F
from lopcook.settings import budget_target as _budget_target
from lopcook.cli import main
from lopcook.lop.container import from_bytes, read
from lopcook.lop.summary import memory_rows
from lopcook.errors import LopcookError
from lopcook.ingest.normals import compute_normals
from lopcook.types import MeshPart, Scene

SMALL = (160, 90)
VIEWS = 4


def _bumpy_sphere(subdivisions: int = 4) -> Scene:
    """Icosphere (radius ~1 m) with seeded bumps of +-4 %: detail that simplification loses and a
    coarse grid blocks out; smooth normals (crease 180)."""
    sph = F.unit_sphere(subdivisions)[0]
    p = np.asarray(sph.positions, np.float64)
    r = 1.0 + 0.04 * np.sin(7.0 * p[:, 0]) * np.sin(6.0 * p[:, 1] + 1.0) * np.sin(5.0 * p[:, 2] + 2.0)
    pos = p * r[:, None]
    nr = compute_normals(pos, sph.indices, 180.0)
    pos = pos[nr.source_vertex]
    part = MeshPart("bumpy", pos, nr.indices, normals=nr.normals)
    return Scene((part,), "bumpy_sphere", "glb").validate()


@pytest.fixture(scope="module")
def bumpy():
    return _bumpy_sphere()


@pytest.fixture(scope="module")
def fitted(gl, bumpy):
    target = BG.float_bytes(bumpy) // 6
    data, info = BG.fit(bumpy, target, FAST, views=VIEWS, resolution=SMALL)
    return target, data, info


# ---- sizes (no GL) -----------------------------------------------------------------------------------

def test_float_bytes_by_scope(bumpy):
    n, m = bumpy.parts[0].n_vertices, bumpy.parts[0].n_triangles
    assert BG.float_bytes(bumpy, "positions") == 12 * n
    assert BG.float_bytes(bumpy, "vertices") == 24 * n  # + float32 normals
    assert BG.float_bytes(bumpy, "all") == 24 * n + 12 * m  # + 32-bit indices
    with pytest.raises(LopcookError, match="scope"):
        BG.float_bytes(bumpy, "everything")


def test_default_ratios_stop_at_four_triangles(bumpy):
    r = BG.default_ratios(bumpy)
    m = bumpy.parts[0].n_triangles
    assert r[0] == 0.5 and all(b == a / 2 for a, b in zip(r, r[1:]))
    assert round(r[-1] * m) >= 4 > round(r[-1] / 2 * m)


def test_target_bytes_syntax():
    assert _budget_target("150000") == 150000
    assert _budget_target("150_000") == 150000
    assert _budget_target("1/6") is None
    assert _budget_target("1/6", 600) == 100
    for bad in ("0", "-5", "1.5", "x", "1/0", "-1/6"):
        with pytest.raises(LopcookError):
            _budget_target(bad, 600)


# ---- the fit (GL) --------------------------------------------------------------------------------------

def test_combined_beats_quantize_only_and_simplify_only(fitted):
    """Purnomo et al. 2005, section 5.2 on a small mesh: at 1/6 of the float size the chosen
    (LOD, level) has a higher PSNR than LOD 0 at its largest fitting level and than the finest LOD
    whose float32 buffer fits."""
    target, _, info = fitted
    b = info["budget"]
    ch, q, s = b["chosen"], b["baselines"]["quantize_only"], b["baselines"]["simplify_only"]
    assert q is not None and s is not None
    assert ch["bytes"] <= target and q["bytes"] <= target and s["bytes"] <= target
    assert q["lod"] == 0 and s["lod"] > 0
    assert ch["psnr_mean"] is not None
    assert ch["psnr_mean"] > q["psnr_mean"] + 1.0, (ch, q)
    assert ch["psnr_mean"] > s["psnr_mean"] + 1.0, (ch, s)
    # the choice is the best rendered candidate, and every rendered candidate fits
    assert all(c["bytes"] <= target for c in b["candidates"])
    assert ch["psnr_mean"] == max(c["psnr_mean"] for c in b["candidates"] if c["psnr_mean"] is not None)
    # each rendered LOD's level_fit is the largest that fits: its buffer written one level higher,
    # in the default cook's cluster layout, takes more than the target
    from lopcook.emit import PositionSizer

    cooked = info["cook"]
    for row in b["lods"]:
        if row["status"] == "rendered" and row["level_fit"] < cooked.container.available_level:
            sizer = PositionSizer(cooked.buffers[0][row["lod"]], FAST.emit.clusters)
            assert sizer.bytes_at(row["level_fit"]) <= target < sizer.bytes_at(row["level_fit"] + 1)


def test_written_container_holds_only_the_chosen_lod_and_planes(fitted):
    target, data, info = fitted
    ch = info["budget"]["chosen"]
    c = from_bytes(data)
    m = c.manifest
    assert [len(p["lods"]) for p in m["parts"]] == [1]
    e = m["parts"][0]["lods"][0]
    assert (e["vertices"], e["triangles"]) == (ch["vertices"], ch["triangles"])
    assert m["positions"]["max_level"] == ch["level"] == c.available_level
    assert sorted(int(p) for p in m["positions"]["planes"]) == list(range(2, ch["level"] + 1))
    assert m["stats"]["vertices_clamped_to_max_level"] == ch["clamped_vertices"]
    # the GPU buffer at the chosen level is the budgeted one: every vertex ch["level"] bits, in the
    # layout the default cook's encoding chooses for it (clustered where that is smaller)
    row = memory_rows(c, levels=[ch["level"]])[0]
    assert row["cap_bytes"] == ch["position_bytes"] <= target
    # candidates are sized clustered: on this sphere LOD 0's take fewer bytes than AP at their level
    ap = {(x["lod"], x["level"]): 4 * ((3 * x["level"] * x["vertices"] + 31) // 32) for x in info["budget"]["candidates"]}
    assert any(x["position_bytes"] < ap[x["lod"], x["level"]] for x in info["budget"]["candidates"] if x["lod"] == 0)
    assert m["options"]["budget"]["chosen"] == ch
    assert m["parts"][0]["lods"][0]["min_distance_m"] == 0.0


def test_fit_is_deterministic(gl, bumpy, fitted):
    target, data, _ = fitted
    again, _ = BG.fit(bumpy, target, FAST, views=VIEWS, resolution=SMALL)
    assert again == data


def test_nothing_fits_is_one_clear_error(gl, bumpy):
    with pytest.raises(LopcookError, match=r"nothing fits in 3 bytes.*smallest candidate.*takes \d"):
        BG.fit(bumpy, 3, FAST, views=1, resolution=(32, 18))


def test_cli_target_bytes(gl, bumpy, tmp_path, capsys):
    from tests.support.fixtures import write_gltf

    src = tmp_path / "bumpy.glb"
    p = bumpy.parts[0]
    write_gltf([F._part("bumpy", p.positions, p.indices, None, p.normals)], src, binary=True)
    out = tmp_path / "out.lop"
    rc = main(["cook", str(src), "-o", str(out), "--target-bytes", "1/6", "--lod-backend", "fast",
               "--budget-views", "2", "--budget-resolution", "96x54", "--budget-levels", "1", "--json"])
    assert rc == 0
    desc = json.loads(capsys.readouterr().out)
    b = desc["budget"]
    c = read(str(out))
    assert c.manifest["options"]["budget"] == b
    assert b["target_bytes"] == b["float_bytes"] // 6 and b["chosen"]["bytes"] <= b["target_bytes"]
    assert all(r["status"] != "rendered" or r["level_fit"] is not None for r in b["lods"])
    assert len({c["lod"] for c in b["candidates"]}) == len(b["candidates"])  # --budget-levels 1
    # the report of a budget container: its simplified LOD 0 rendered and coloured by level; not re-cooked
    level = b["chosen"]["level"]
    html_path = tmp_path / "out.html"
    rc = main(["-q", "report", str(out), "--source", str(src), "-o", str(html_path), "--views", "1",
               "--resolution", "96x54", "--levels", f"{max(1, level - 1)}-{level}"])
    rep = json.loads(html_path.with_suffix(".json").read_text())
    assert rc == (1 if rep["verdict"]["result"] == "FAIL" else 0)  # a sixth of the bytes may miss 40 dB
    assert rep["cook"]["status"] == "not re-cooked" and "levels" in rep["images"]["kinds"]
    assert rep["budget"]["chosen"] == b["chosen"]
    # nothing fits: exit 2, one line, no output file
    bad = tmp_path / "bad.lop"
    rc = main(["cook", str(src), "-o", str(bad), "--target-bytes", "3", "--lod-backend", "fast",
               "--budget-views", "1", "--budget-resolution", "32x18"])
    err = capsys.readouterr().err
    assert rc == 2 and not bad.exists()
    assert err.count("\n") == 1 and "nothing fits in 3 bytes" in err and "--target-bytes" in err
    # usage errors before any work
    assert main(["cook", str(src), "-o", str(bad), "--target-bytes", "lots"]) == 2
    assert main(["cook", str(src), "-o", str(bad), "--target-bytes", "1/6", "--budget-views", "0"]) == 2
    assert not bad.exists()
