"""``lopcook view``'s page in headless Chromium (SwiftShader WebGL2), driven through the DevTools
protocol (cdp.py): DamagedHelmet, cooked and served with its materials, streamed with the
throttle on, is on the canvas before the last byte arrives and again once it has (canvas pixels
against the transparent background); the HUD's numbers are the container's; level colours use
the scene's level range; replay streams the file again from its first byte.

The throttle is set from the container's own layout so that the bytes after the first renderable
state take about 3 s to arrive (a lower bound: the server never sends early).
"""

from __future__ import annotations

import base64
import io
import os
import subprocess
import sys

import numpy as np
import pytest

from cdp import Page, chromium_missing
from lopcook.lop.container import from_bytes, read
from lopcook.errors import LopcookError
from lopcook.verify.baselines import container_levels
from lopcook.view import ViewerServer, viewer_site

IN_CI = os.environ.get("CI", "").lower() == "true"
HELMET = "DamagedHelmet/DamagedHelmet.gltf"
#: seconds the bytes after the first renderable state take at the test's throttle
TAIL_S = 3.0
SIZE = (640, 480)


def first_renderable_bytes(data: bytes) -> int:
    """The shortest prefix of the container that lopcook's reader decodes (available level >= 1)."""
    def level(k):
        try:
            return from_bytes(data[:k], "prefix", allow_prefix=True).available_level
        except LopcookError:
            return 0

    lo, hi = 1, len(data)
    while lo < hi:
        mid = (lo + hi) // 2
        lo, hi = (mid + 1, hi) if level(mid) < 1 else (lo, mid)
    return lo


def image(snapshot: dict) -> np.ndarray:
    from PIL import Image

    png = base64.b64decode(snapshot["image"].split(",", 1)[1])
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGBA"))


def model_pixels(img: np.ndarray) -> int:
    """Pixels where the model covers the transparent background (alpha > 0)."""
    return int(np.count_nonzero(img[..., 3] > 0))


@pytest.fixture(scope="module")
def served(corpus, tmp_path_factory):
    reason = chromium_missing()
    if reason:
        if IN_CI:
            pytest.fail(f"CI=true but {reason}")
        pytest.skip(reason)
    out = tmp_path_factory.mktemp("viewpage") / "helmet.lop"
    subprocess.run([sys.executable, "-m", "lopcook", "cook", str(corpus / HELMET), "-o", str(out), "-q"], check=True,
                   timeout=900)
    site, info = viewer_site(str(out), str(corpus / HELMET))
    assert info["materials"] == 1 and not info["warnings"]
    with ViewerServer(site) as server:
        yield server, read(str(out))


@pytest.fixture(scope="module")
def streamed(served):
    """Snapshots of one throttled stream: at the first renderable state, and once complete."""
    server, c = served
    size = len(c.data)
    first = first_renderable_bytes(bytes(c.data))
    rate = max(4096, int((size - first) / TAIL_S))
    with Page(f"{server.url}?rate={rate}", size=SIZE, timeout=120) as page:
        early = page.wait_for("window.lopViewer && window.lopViewer.state().renderable && window.lopViewer.snapshot()",
                              timeout=size / rate + 600)
        late = page.wait_for("window.lopViewer.state().complete && window.lopViewer.snapshot()", timeout=600)
        page.evaluate("window.lopViewer.setLevelColours(true)")
        levels = page.evaluate("window.lopViewer.snapshot()")
        legend = page.evaluate("[document.getElementById('lo').textContent, document.getElementById('hi').textContent]")
        replay = page.evaluate("window.lopViewer.setRate(0), window.lopViewer.state()")
        again = page.wait_for("window.lopViewer.state().complete && window.lopViewer.snapshot()", timeout=600)
    return {"c": c, "first": first, "rate": rate, "early": early, "late": late, "levels": levels, "legend": legend,
            "replay": replay, "again": again}


def test_the_model_is_drawn_before_the_last_byte_arrives(streamed):
    s, c = streamed["early"], streamed["c"]
    assert s["error"] is None
    assert s["rate"] == streamed["rate"] and s["fileSize"] == len(c.data)
    assert streamed["first"] <= s["bytes"] < len(c.data)  # renderable, and the file not all here
    assert s["level"] >= 1 and not s["complete"]
    assert model_pixels(image(s)) > 5000


def test_the_model_is_drawn_again_once_every_byte_arrived(streamed):
    s, c = streamed["late"], streamed["c"]
    assert s["error"] is None and s["complete"]
    assert s["bytes"] == s["fileSize"] == len(c.data) and s["level"] == 24
    assert s["levels"][0][0] == streamed["early"]["level"] and s["levels"][-1][0] == 24
    late, early = image(s), image(streamed["early"])
    assert model_pixels(late) > 5000
    a, b = late[..., 3] > 0, early[..., 3] > 0
    # the same model, refined in place (a streamed layout may show a coarser LOD first: not 1.0)
    assert (a & b).sum() / (a | b).sum() > 0.9
    rgb = late[a][:, :3].astype(np.float64)
    assert rgb.std(axis=0).mean() > 10.0  # textured and lit, not one flat colour


def test_the_hud_reports_the_containers_buffers_lods_and_triangles(streamed):
    s, c = streamed["late"], streamed["c"]
    parts = c.manifest["parts"]
    assert [(b["part"], b["lod"]) for b in s["buffers"]] == [(i, k) for i, p in enumerate(parts)
                                                             if "placement" not in p for k in range(len(p["lods"]))]
    assert all(b["level"] == 24 for b in s["buffers"])
    assert s["triangles"] == sum(parts[d["part"]]["lods"][d["lod"]]["triangles"] for d in s["drawn"])
    assert sum(s["lodCounts"].values()) == len(s["drawn"]) >= 1
    assert s["firstImage"]["bytes"] < len(c.data)


def test_level_colours_span_the_scenes_level_range(streamed):
    c = streamed["c"]
    owners = [i for i, p in enumerate(c.manifest["parts"]) if "placement" not in p]
    lv = np.concatenate([container_levels(c, i, 0) for i in owners])
    assert streamed["legend"] == [str(int(lv.min())), str(int(lv.max()))]
    s = streamed["levels"]
    assert s["levelColours"] and s["error"] is None
    img, own = image(s), image(streamed["late"])
    assert model_pixels(img) > 5000
    assert np.abs(img.astype(np.int16) - own.astype(np.int16))[..., :3].mean() > 5.0  # recoloured


def test_replay_streams_the_file_again(streamed):
    r, s = streamed["replay"], streamed["again"]
    assert r["rate"] == 0 and not r["renderable"] and not r["complete"] and r["bytes"] < r["fileSize"]
    assert s["complete"] and s["bytes"] == s["fileSize"] and s["level"] == 24 and s["error"] is None
    assert model_pixels(image(s)) > 5000
