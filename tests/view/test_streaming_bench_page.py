"""``lopcook bench --streaming``'s page (runtime/js/viewer/bench.js) in headless Chromium on a small
container: it draws the float reference and the container after every cut that changed the
state, the first image comes exactly at the shortest prefix lopcook's reader decodes, and the
whole file renders like the float reference (>= 40 dB) from every camera."""

from __future__ import annotations

import os
from pathlib import Path
from types import SimpleNamespace

import pytest

from cdp import chromium_missing
from lopcook.bench import streaming as S
from lopcook.errors import LopcookError
from lopcook.lop.container import from_bytes
from lopcook.view import runtime_site

REPO = Path(__file__).resolve().parents[2]
IN_CI = os.environ.get("CI", "").lower() == "true"


def _first_renderable(data: bytes) -> int:
    def level(k):
        try:
            return from_bytes(data[:k], "prefix", allow_prefix=True).available_level
        except LopcookError:
            return 0

    return next(k for k in range(1, len(data) + 1) if level(k) >= 1)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    reason = chromium_missing()
    if reason:
        if IN_CI:
            pytest.fail(f"CI=true but {reason}")
        pytest.skip(reason)
    out = tmp_path_factory.mktemp("streamingbench")
    site = runtime_site()
    job = S.prepare_asset(str(REPO / "fixtures" / "unit_sphere.obj"), out, site, [],
                          SimpleNamespace(quiet=True))
    curves, drawn = S.run_jobs([job], out, site, timeout_s=900)
    return job, curves, out, drawn


def test_every_camera_is_drawn_from_the_first_renderable_prefix_to_the_end(run):
    job, curves, out, drawn = run
    data = bytes(job["_container"].data)
    first = _first_renderable(data)
    assert first in job["cuts"]
    for name, _ in S.CAMERAS:
        cv = curves[(job["name"], name)]
        got = [b for b, _ in cv.points]
        assert got == sorted(got) and set(got) <= set(job["cuts"]) and got[-1] == len(data)
        assert cv.first_image_bytes() == got[0] == first
        assert all(n > 500 for n in cv.covered)
        assert (out / "images" / f"{job['name']}-{name}-reference.png").is_file()
    data_levels = [from_bytes(data[:b], "prefix", allow_prefix=True).available_level for b, _ in drawn[job["name"]]]
    assert [lv for _, lv in drawn[job["name"]]] == data_levels  # the page drew what lopcook's reader reads
    assert data_levels[-1] == job["_container"].available_level


def test_the_whole_file_renders_like_the_float_reference(run):
    job, curves, _, _ = run
    for name, _ in S.CAMERAS:
        final = curves[(job["name"], name)].final_db()
        assert final is None or final >= 40.0, (name, final)


def test_the_near_camera_fills_more_of_the_canvas_than_the_far_one(run):
    job, curves, _, _ = run
    near, mid, far = (curves[(job["name"], n)].covered[-1] for n, _ in S.CAMERAS)
    # the sphere spans 100 %, 40 % and 15 % of the height: covered areas scale about as the squares
    assert near > mid > far
    assert mid / far == pytest.approx((0.40 / 0.15) ** 2, rel=0.15)
