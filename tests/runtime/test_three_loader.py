"""runtime/js/three-lop.js in headless Chromium with three.js r170: DamagedHelmet and the chess set
load through GLTFLoader + LOPGLTFPlugin from the glTF ``lopcook web`` writes (the source's
materials and textures, geometry streamed from the container) and, drawn with the render
harness's shading, camera and base-colour textures, match the moderngl harness's CAP render of
the same container at >= 40 dB (``lopcook.verify.metrics.image_metrics``); their PBR render covers
the same pixels; and a container streamed in 20 timed chunks shows the model before its last byte
and ends exactly as a whole-file parse draws it.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

import runtime_support as rs
from browser import NODE_MODULES, REPO, BrowserUnavailable, locate, run_page
from lopcook import api
from lopcook.lop.container import read
from lopcook.emit.stages import streamed
from lopcook.emit.web import write_web_gltf
from lopcook.verify import metrics
from lopcook.verify.cameras import camera_distance, look_at, make_camera, perspective, render_viewing
from lopcook.verify.evaluate import evaluate
from lopcook.verify.renderer import Shading

HERE = Path(__file__).resolve().parent
SIZE = 512
#: (name, corpus source, level, view): the harness's camera for that level and icosahedron view
RENDERS = (("DamagedHelmet", "DamagedHelmet/DamagedHelmet.gltf", 10, 3),
           ("DamagedHelmet", "DamagedHelmet/DamagedHelmet.gltf", 12, 12),
           ("chess_set_flat", "chess_set_flat.usdc", 10, 3),
           ("chess_set_flat", "chess_set_flat.usdc", 12, 12))
PAGE = """<!doctype html><html><head><meta charset="utf-8"><style>body{margin:0;background:#000}</style>
<script type="importmap">{"imports":{"three":"/node_modules/three/build/three.module.js",
"three/addons/":"/node_modules/three/examples/jsm/"}}</script></head><body>
<script type="module" src="/tests/three_render.js"></script></body></html>"""


def _image(posts: dict, key: str) -> np.ndarray:
    """An (h, w, 4) uint8 image, top row first, from the page's readPixels bytes."""
    return np.frombuffer(posts[key], np.uint8).reshape(SIZE, SIZE, 4)[::-1]


def _camera_job(c, scene, level: int, view: int) -> tuple[dict, object]:
    """The harness's camera and shading for (level, view) as the page's uniforms, and the camera."""
    viewing = render_viewing(c.manifest, (SIZE, SIZE))
    lo, hi = scene.bounds()
    cam = make_camera(view, lo, hi, camera_distance(level, c.manifest["grid"]["extent"], viewing), viewing)
    sh = Shading.from_manifest(c.manifest)
    light = (cam.eye - cam.centre) / np.linalg.norm(cam.eye - cam.centre)
    view_m = look_at(cam.eye, cam.centre)
    proj = perspective(viewing.fov_y_deg, 1.0, cam.near, cam.far)
    assert np.allclose(proj @ view_m, cam.mvp)
    col = lambda m: [float(v) for v in np.asarray(m, np.float64).T.ravel()]  # noqa: E731 - column-major
    return {"level": level, "mvp": col(cam.mvp), "view": col(view_m), "projection": col(proj),
            "eye": [float(v) for v in cam.eye], "light": [float(v) for v in light],
            "phong": [sh.ambient, sh.diffuse, sh.ks, sh.shininess], "base": sh.base}, cam


#: streamed jobs: (container name, source); "-stream" names the default cook rewritten in the
#: streaming layout (docs/format.md 14: its LODs arrive coarse to fine)
STREAMS = (("stanford-bunny", "stanford-bunny.obj"), ("DamagedHelmet", "DamagedHelmet/DamagedHelmet.gltf"),
           ("duck-lods-stream", "Duck.glb"))


def render(cooked: dict, corpus: Path, root: Path, renders=RENDERS, streams=STREAMS):
    """Run the page (three_render.js) for ``renders`` (name, source, level, view) and ``streams``
    (container names) with everything under ``root``; returns (the page's result, {job: the
    harness's CAP image}, {job: the harness's image metrics dict})."""
    root.mkdir(parents=True, exist_ok=True)
    jobs, cap, scenes = {"size": SIZE, "renders": [], "streams": []}, {}, {}
    for name, src, level, view in renders:
        lop = root / f"{name}.lop"
        if name not in scenes:
            shutil.copy(cooked[name], lop)
            write_web_gltf(str(lop), str(root / f"{name}.gltf"), str(corpus / src))
            scenes[name] = api.load(corpus / src)
        c = read(str(lop))
        job, cam = _camera_job(c, scenes[name], level, view)
        key = f"{name}-{level}-{view}"
        jobs["renders"].append({"name": key, "gltf": f"/web/{name}.gltf", **job})
        res = evaluate(c, scenes[name], levels=[level], views=[view], resolution=(SIZE, SIZE), keep_images=True,
                       variants=("cap",), image_view=view)
        assert res["levels"][0]["camera_distance_m"] == pytest.approx(cam.box_distance, rel=1e-9)
        cap[key] = res["images"]["cap"]
    served = root / "lop"  # the streamed containers under their names (the cook cache names its files its own way)
    served.mkdir(exist_ok=True)
    for name, src in streams:
        lop = served / f"{name}.lop"
        if name.endswith("-stream"):
            lop.write_bytes(streamed(read(str(cooked[name[:-len("-stream")]]))).data)
        else:
            shutil.copy(cooked[name], lop)
        job, _ = _camera_job(read(str(lop)), api.load(corpus / src), 9, 3)
        jobs["streams"].append({"name": name, "lop": f"/lop/{name}.lop", "chunks": 20, **job})
    (root / "jobs.json").write_text(json.dumps(jobs))
    got = run_page(PAGE, {"/runtime/js/": REPO / "runtime/js", "/tests/": HERE, "/web/": root,
                          "/lop/": served, "/jobs.json": root / "jobs.json",
                          "/node_modules/": NODE_MODULES}, timeout=900, size=(SIZE, SIZE))
    _save(root / "images", got["_posts"], cap)
    assert not [m for m in got["console"] if m.startswith("error")], got["console"]
    scores = {k: metrics.image_metrics(img, _image(got["_posts"], f"/image/{k}/harness")) for k, img in cap.items()}
    return got, cap, scores


@pytest.fixture(scope="module")
def renders(corpus_containers, corpus, tmp_path_factory):
    """The page's results and images, the harness's CAP image and the metrics of each render job."""
    try:
        locate(three=True)
    except BrowserUnavailable as exc:
        rs.require(str(exc))
    from lopcook.verify import gpu

    rs.require(gpu.gl_available())
    return render(corpus_containers, corpus, tmp_path_factory.mktemp("web"))


def _save(folder: Path, posts: dict, cap: dict) -> None:
    """Every image as PNG under ``folder`` (the test's temporary directory), to look at."""
    from PIL import Image

    folder.mkdir(exist_ok=True)
    for key in posts:
        if key.startswith("/image/"):
            Image.fromarray(_image(posts, key)).save(folder / (key[7:].replace("/", "-") + ".png"))
    for key, img in cap.items():
        Image.fromarray(np.ascontiguousarray(img)).save(folder / f"{key}-cap.png")
    print(f"images: {folder}")


@pytest.mark.parametrize("name, src, level, view", RENDERS)
def test_three_matches_the_harness_cap_render(renders, name, src, level, view):
    got, cap, scores = renders
    key = f"{name}-{level}-{view}"
    info = next(r for r in got["renders"] if r["name"] == key)
    assert info["level"] == level and info["bytes"] == info["fileSize"]
    if name == "DamagedHelmet":
        assert info["textured"] == info["meshes"] == 1  # the glTF material's base colour texture
    m = scores[key]
    print(f"{key}: PSNR {m['psnr']:.2f} dB over {m['object_pixels']} object pixels, "
          f"max error {m['max_error']:.3f}, {100 * m['share_off']:.2f}% off")
    assert m["object_pixels"] > 5000
    assert m["psnr"] is None or m["psnr"] >= 40.0


@pytest.mark.parametrize("name, src, level, view", RENDERS[::2])
def test_three_materials_cover_the_same_pixels(renders, name, src, level, view):
    got, cap, _ = renders
    key = f"{name}-{level}-{view}"
    pbr = _image(got["_posts"], f"/image/{key}/pbr")
    a, b = metrics.object_mask(pbr), metrics.object_mask(cap[key])
    iou = (a & b).sum() / max((a | b).sum(), 1)
    assert iou >= 0.97, iou
    assert pbr[a][:, :3].astype(np.float64).mean(axis=1).std() > 5.0  # lit and shaded, not flat


@pytest.mark.parametrize("name", ["stanford-bunny", "DamagedHelmet"])
def test_streamed_container_draws_before_its_last_byte(renders, name):
    got, _, _ = renders
    s = next(x for x in got["streams"] if x["name"] == name)
    posts = got["_posts"]
    first, last, whole = (_image(posts, f"/image/{name}/{k}") for k in ("first", "last", "whole"))
    assert s["first"]["bytes"] < s["fileSize"] and s["first"]["level"] >= 1
    assert metrics.object_mask(first).sum() > 1000  # the model is on the canvas before the last byte
    assert s["refines"] and s["refines"][-1][0] == s["level"] == s["wholeLevel"] == 24
    assert [lv for lv, *_ in s["refines"]] == sorted({lv for lv, *_ in s["refines"]})
    assert np.array_equal(last, whole)  # refined in place to exactly what the whole file draws


def test_streaming_layout_draws_its_coarsest_lods_first(renders):
    """A file in the streaming layout: on the canvas from stage 0 (every part's coarsest LOD) on,
    refined stage by stage ('refine' per stage that improves, each stage's level rising), and
    at the end exactly what a whole-file parse draws."""
    got, _, _ = renders
    s = next(x for x in got["streams"] if x["name"] == "duck-lods-stream")
    posts = got["_posts"]
    first, last, whole = (_image(posts, f"/image/duck-lods-stream/{k}") for k in ("first", "last", "whole"))
    assert s["first"]["bytes"] < s["fileSize"] // 2 and metrics.object_mask(first).sum() > 1000
    stages = {st for _, _, st in s["refines"]}
    assert set(range(1, len(s["stageLevels"]))) <= stages and s["stageLevels"] == [24] * len(s["stageLevels"])
    for st in stages:
        levels = [lv for lv, _, x in s["refines"] if x == st]
        assert levels == sorted(set(levels))
    assert np.array_equal(last, whole)
