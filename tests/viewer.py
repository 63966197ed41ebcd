"""Headless-Chromium screenshots of glTF files in three.js (for tests/emit/test_preview.py).

``shoot(files, out_dir)`` serves the files and ``.ci/node/node_modules`` (three, installed by
``.ci/run``) from a local ``http.server`` on 127.0.0.1, opens one page per file in
``/usr/bin/chromium --headless`` (WebGL through SwiftShader, no GPU) and returns the rendered
canvases as RGBA arrays. The page loads the file with three's ``GLTFLoader``, lights it with
``RoomEnvironment`` (image-based lighting, so metallic-roughness and normal maps show), frames
the union of all files' bounding boxes from a fixed direction (so the same camera sees the
source and the preview), renders once on a transparent background and POSTs the canvas as PNG
back to the server. Object pixels are those with alpha > 0.
"""

from __future__ import annotations

import functools
import http.server
import io
import os
import shutil
import subprocess
import tempfile
import threading
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
#: where .ci/run installs npm packages; else beside the validator GLTF_VALIDATOR_DIR names
NODE_MODULES = REPO / ".ci" / "node" / "node_modules"
if not (NODE_MODULES / "three").is_dir() and os.environ.get("GLTF_VALIDATOR_DIR"):
    NODE_MODULES = Path(os.environ["GLTF_VALIDATOR_DIR"]).parent
CHROMIUM = os.environ.get("LOPCOOK_CHROMIUM", "/usr/bin/chromium")
#: what .ci/run installs (keep the two in step)
THREE_VERSION = "0.170.0"

PAGE = """<!doctype html><html><head><meta charset="utf-8"><style>body{margin:0;background:#000}</style>
<script type="importmap">{"imports":{"three":"/node_modules/three/build/three.module.js",
"three/addons/":"/node_modules/three/examples/jsm/"}}</script></head><body>
<script type="module">
import * as THREE from 'three';
import {GLTFLoader} from 'three/addons/loaders/GLTFLoader.js';
import {RoomEnvironment} from 'three/addons/environments/RoomEnvironment.js';
const q = new URLSearchParams(location.search);
const W = +q.get('w'), H = +q.get('h');
const box = new THREE.Box3(new THREE.Vector3(...q.get('min').split(',').map(Number)),
                           new THREE.Vector3(...q.get('max').split(',').map(Number)));
const dir = new THREE.Vector3(...q.get('dir').split(',').map(Number)).normalize();
async function post(body, kind) {
  await fetch('/result?name=' + encodeURIComponent(q.get('name')) + '&kind=' + kind, {method: 'POST', body});
}
try {
  const renderer = new THREE.WebGLRenderer({antialias: false, alpha: true, preserveDrawingBuffer: true,
                                            premultipliedAlpha: false});
  renderer.setPixelRatio(1); renderer.setSize(W, H); renderer.setClearColor(0x000000, 0);
  renderer.toneMapping = THREE.NeutralToneMapping;
  document.body.appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  scene.environment = new THREE.PMREMGenerator(renderer).fromScene(new RoomEnvironment(), 0.04).texture;
  const gltf = await new GLTFLoader().loadAsync(q.get('file'));
  scene.add(gltf.scene);
  const c = box.getCenter(new THREE.Vector3()), r = box.getSize(new THREE.Vector3()).length() / 2;
  const cam = new THREE.PerspectiveCamera(35, W / H, r / 100, r * 10);
  cam.position.copy(c).addScaledVector(dir, r / Math.sin(THREE.MathUtils.degToRad(17.5)));
  cam.lookAt(c);
  renderer.render(scene, cam);
  const blob = await new Promise(res => renderer.domElement.toBlob(res, 'image/png'));
  await post(blob, 'png');
} catch (e) { await post(String(e && e.stack || e), 'error'); }
</script></body></html>
"""


class ViewerUnavailable(RuntimeError):
    pass


def locate() -> None:
    """Raise ViewerUnavailable naming what is missing (chromium, three)."""
    if not (shutil.which(CHROMIUM) or os.path.isfile(CHROMIUM)):
        raise ViewerUnavailable(f"chromium not found at {CHROMIUM}")
    if not (NODE_MODULES / "three" / "package.json").is_file():
        raise ViewerUnavailable(f"three.js not found in {NODE_MODULES}: npm install --prefix .ci/node "
                                f"three@{THREE_VERSION} --no-audit --no-fund")


def bounds_of(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """World-space bounding box of a glTF/GLB file (pygltflib-free: lopcook's own importer)."""
    from lopcook.ingest import load

    s = load(str(path))
    lo = np.min([p.positions.min(axis=0) for p in s.parts], axis=0)
    hi = np.max([p.positions.max(axis=0) for p in s.parts], axis=0)
    return lo, hi


def shoot(files: dict[str, Path], *, size=(512, 512), direction=(0.35, 0.3, 1.0), timeout=240) -> dict:
    """``{name: (H, W, 4) uint8 RGBA}``: each file rendered by three.js in headless Chromium,
    all with the one camera framing the union of their bounding boxes."""
    from PIL import Image

    locate()
    boxes = [bounds_of(p) for p in files.values()]
    lo = np.min([b[0] for b in boxes], axis=0)
    hi = np.max([b[1] for b in boxes], axis=0)
    results: dict = {}
    done = threading.Condition()
    with tempfile.TemporaryDirectory() as root:
        root = Path(root)
        (root / "node_modules").symlink_to(NODE_MODULES)
        (root / "view.html").write_text(PAGE)
        for name, p in files.items():
            d = root / name
            d.mkdir()
            for f in p.parent.iterdir():  # a .gltf's .bin and images travel with it
                if f.is_file():
                    (d / f.name).symlink_to(f.resolve())

        class Handler(http.server.SimpleHTTPRequestHandler):
            def do_POST(self):  # noqa: N802 - http.server's naming
                from urllib.parse import parse_qs, urlparse

                qs = parse_qs(urlparse(self.path).query)
                body = self.rfile.read(int(self.headers.get("Content-Length", 0)))
                with done:
                    results[qs["name"][0]] = (qs["kind"][0], body)
                    done.notify_all()
                self.send_response(204)
                self.end_headers()

            def log_message(self, *args):
                pass

        server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(Handler, directory=str(root)))
        threading.Thread(target=server.serve_forever, daemon=True).start()
        port = server.server_address[1]
        procs = []
        try:
            for name, p in files.items():
                from urllib.parse import urlencode

                query = urlencode({"file": f"/{name}/{p.name}", "name": name, "w": size[0], "h": size[1],
                                   "min": ",".join(map(repr, map(float, lo))),
                                   "max": ",".join(map(repr, map(float, hi))),
                                   "dir": ",".join(map(str, direction))})
                profile = root / f"profile-{name}"
                cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
                       "--enable-unsafe-swiftshader", "--no-first-run", "--disable-extensions",
                       f"--user-data-dir={profile}", f"--window-size={size[0]},{size[1]}",
                       f"http://127.0.0.1:{port}/view.html?{query}"]
                procs.append(subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE))
                with done:
                    ok = done.wait_for(lambda: name in results, timeout=timeout)
                procs[-1].terminate()
                try:
                    procs[-1].wait(timeout=20)
                except subprocess.TimeoutExpired:
                    procs[-1].kill()
                if not ok:
                    err = procs[-1].stderr.read().decode("utf-8", "replace")[-2000:]
                    raise RuntimeError(f"{name}: no render from chromium within {timeout} s; stderr: {err}")
        finally:
            for pr in procs:
                if pr.poll() is None:
                    pr.kill()
                    pr.wait()
            server.shutdown()
            server.server_close()
    out = {}
    for name, (kind, body) in results.items():
        if kind != "png":
            raise RuntimeError(f"{name}: the viewer failed: {body.decode('utf-8', 'replace')}")
        with Image.open(io.BytesIO(body)) as im:
            out[name] = np.asarray(im.convert("RGBA"))
    return out
