"""The pieces of ``lopcook bench --streaming`` (lopcook/bench/streaming.py) that need no browser:
the cuts are exactly the byte counts where a reader's state can change, the curve's first image and
thresholds, the page's POST sink scoring images, the checks of the issue's goals, the float
reference glTF, gzip -9 sizes, and the command's flags. tests/view/test_streaming_bench_page.py
runs the page itself."""

from __future__ import annotations

import gzip
import json
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

from lopcook.bench import streaming as S
from lopcook.cli.parser import build_parser
from lopcook.errors import LopcookError
from lopcook.ingest import load
from lopcook.lop.container import from_bytes, read
from lopcook.verify.metrics import image_metrics

REPO = Path(__file__).resolve().parents[2]
GOLDEN = REPO / "fixtures" / "golden"


def _level(data: bytes, k: int) -> int:
    try:
        return from_bytes(data[:k], "prefix", allow_prefix=True).available_level
    except LopcookError:
        return 0


@pytest.mark.parametrize("name", ["unit_sphere", "unit_sphere_lods", "two_plates", "seamed_cube"])
def test_cuts_are_every_byte_count_where_the_readable_state_changes(name):
    c = read(str(GOLDEN / f"{name}.lop"))
    data = bytes(c.data)
    cuts = S.cut_points(c)
    assert cuts == sorted(set(cuts)) and cuts[-1] == len(data)
    assert cuts[0] == 32 + int.from_bytes(data[12:16], "little")  # header and manifest
    # the readable level only grows with the prefix, so it is constant between two cuts when it is
    # the same at both ends: the state never changes between two cuts
    for a, b in zip(cuts, cuts[1:]):
        assert _level(data, a) == _level(data, b - 1), (a, b)
    assert _level(data, cuts[0] - 1) == 0
    assert _level(data, len(data)) == c.available_level >= 1


def _curve(points, covered=None):
    cv = S.Curve("a", "middle", 1000)
    cv.points = list(points)
    cv.covered = list(covered or [100] * len(points))
    return cv


def test_curve_first_image_and_thresholds():
    cv = _curve([(100, 12.0), (200, 31.0), (300, 39.9), (400, 40.0), (1000, None)], [0, 50, 50, 50, 50])
    assert cv.first_image_bytes() == 200  # the first cut with the model on the canvas
    assert cv.bytes_to(30.0) == 200 and cv.bytes_to(40.0) == 400 and cv.bytes_to(60.0) == 1000  # None: identical
    assert cv.final_db() is None
    never = _curve([(500, 20.0), (1000, 25.0)])
    assert never.bytes_to(30.0) is None and never.first_image_bytes() == 500
    assert _curve([]).first_image_bytes() is None and _curve([]).final_db() is None


def _rgba(rng, covered: bool) -> np.ndarray:
    img = np.zeros((S.SIZE[1], S.SIZE[0], 4), np.uint8)
    if covered:
        img[100:300, 150:350, :3] = rng.integers(0, 256, (200, 200, 3), dtype=np.uint8)
        img[100:300, 150:350, 3] = 255
    return img


def test_collector_scores_each_image_against_its_reference(tmp_path, rng):
    curves = {("a", "near"): S.Curve("a", "near", 5000)}
    sink = S.Collector(curves, tmp_path / "images")
    ref = _rgba(rng, True)
    noisy = ref.copy()
    noisy[150:200, 200:250, :3] //= 2
    rows_first = lambda img: img[::-1].tobytes()  # noqa: E731 - the page posts gl.readPixels rows, bottom first
    sink.post("/image/a/near/reference", rows_first(ref))
    sink.post("/image/a/near/1200", rows_first(_rgba(rng, False)))
    sink.post("/image/a/near/3000", rows_first(noisy))
    sink.post("/image/a/near/5000", rows_first(ref))
    cv = curves[("a", "near")]
    assert [b for b, _ in cv.points] == [1200, 3000, 5000]
    assert cv.covered[0] == 0 and cv.covered[1] == cv.covered[2] == 200 * 200
    assert cv.points[1][1] == pytest.approx(image_metrics(ref, noisy)["psnr"], abs=1e-12)
    assert cv.points[2][1] is None  # identical to the reference
    assert cv.first_image_bytes() == 3000
    assert sorted(p.name for p in (tmp_path / "images").iterdir()) == ["a-near-3000.png", "a-near-5000.png",
                                                                     "a-near-reference.png"]
    assert not sink.done.is_set() and sink.error is None
    sink.post("/result", json.dumps({"assets": []}).encode())
    assert sink.done.is_set() and sink.result == {"assets": []}


def test_collector_stops_on_a_post_it_cannot_place(tmp_path):
    sink = S.Collector({}, tmp_path)
    sink.post("/image/a/near/100", b"\0" * 16)  # no such curve, wrong size
    assert sink.done.is_set() and "/image/a/near/100" in sink.error


def test_summary_rows_numbers_and_checks():
    curves = {("good", "middle"): _curve([(30, 35.0), (50, 41.0), (1000, 55.0)]),
              ("good", "near"): _curve([(30, 20.0), (1000, 45.0)]),
              ("late", "middle"): _curve([(900, 45.0), (1000, 46.0)]),
              ("nopeer", "middle"): _curve([(10, 50.0), (1000, None)])}
    peers = {"good": {"gltfpack_cc_gzip_bytes": 60, "draco_gzip_bytes": 40},
             "late": {"gltfpack_cc_gzip_bytes": 300, "draco_gzip_bytes": None},
             "nopeer": {"gltfpack_cc_gzip_bytes": None, "draco_gzip_bytes": None}}
    jobs = [{"name": n} for n in ("good", "late", "nopeer")]
    rows, results, checks = S.summarise(curves, peers, jobs)
    assert {"asset": "nopeer", "camera": "middle", "bytes": 1000, "psnr_db": float("inf")} in rows
    assert len(rows) == 9 and set(rows[0]) == set(S.CSV_COLUMNS)
    g = results["good"]["middle"]
    assert (g["file_bytes"], g["first_image_bytes"], g["bytes_to_30db"], g["bytes_to_40db"]) == (1000, 30, 30, 50)
    assert (g["gltfpack_cc_gzip_bytes"], g["draco_gzip_bytes"], g["final_psnr_db"]) == (60, 40, 55.0)
    status = {c["check"].split(":")[0] + ("/first" if "first" in c["check"] else "/40"): c["status"] for c in checks}
    assert status == {"good/first": "pass", "good/40": "pass", "late/first": "fail", "late/40": "fail",
                      "nopeer/first": "pass", "nopeer/40": "unknown"}


def test_reference_gltf_holds_the_sources_float_geometry(tmp_path):
    src = REPO / "fixtures" / "seamed_cube.glb"
    c = read(str(GOLDEN / "seamed_cube.lop"))
    scene = load(src)
    S.write_reference(scene, c, str(src), tmp_path / "reference.glb")
    back = load(tmp_path / "reference.glb")
    assert len(back.parts) == len(scene.parts)
    for a, b in zip(scene.parts, back.parts):
        assert np.array_equal(a.positions.astype(np.float32), b.positions.astype(np.float32))
        assert np.array_equal(a.indices, b.indices)
        assert np.array_equal(a.uvs, b.uvs) and np.allclose(a.normals, b.normals, atol=1e-7)


def test_reference_refuses_a_source_with_other_parts(tmp_path):
    c = read(str(GOLDEN / "two_plates.lop"))
    with pytest.raises(LopcookError, match="2 parts, the source 1"):
        S.write_reference(load(REPO / "fixtures" / "seamed_cube.glb"), c, "x.glb", tmp_path / "r.glb")


def test_gzip9_is_the_size_of_a_stream_that_decompresses_to_the_data(rng):
    data = bytes(rng.integers(0, 4, 200_000, dtype=np.uint8))
    n = S.gzip9(data)
    out = subprocess.run(["gzip", "-9", "-n", "-c"], input=data, capture_output=True, check=True).stdout
    assert n == len(out) and gzip.decompress(out) == data
    assert n < len(data) / 3  # two bits of entropy per byte
    assert S.gzip9(data) == n


def test_bench_flags_parse():
    args = build_parser().parse_args(["bench", "--streaming", "x.obj", "--assets", "a.glb", "b.usd", "-o", "out",
                                      "--cook-args", "--lods 1/2"])
    assert args.streaming and args.assets == ["x.obj"] and args.more_assets == ["a.glb", "b.usd"]
    assert args.cook_args == "--lods 1/2"


def test_bench_streaming_refuses_a_missing_asset_with_one_line(tmp_path):
    r = subprocess.run([sys.executable, "-m", "lopcook", "bench", "--streaming", "--assets", str(tmp_path / "no.obj"),
                        "-o", str(tmp_path / "out")], capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "no.obj" in r.stderr, r.stderr
    assert not (tmp_path / "out").exists()


def test_collector_is_safe_from_several_server_threads(tmp_path, rng):
    curves = {("a", c): S.Curve("a", c, 10) for c in ("near", "far")}
    sink = S.Collector(curves, tmp_path)
    ref = _rgba(rng, True)
    for c in ("near", "far"):
        sink.post(f"/image/a/{c}/reference", ref[::-1].tobytes())
    threads = [threading.Thread(target=sink.post, args=(f"/image/a/{c}/{k}", ref[::-1].tobytes()))
               for c in ("near", "far") for k in range(1, 9)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert sink.error is None and all(len(cv.points) == 8 for cv in curves.values())
