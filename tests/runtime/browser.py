"""Run a test page in headless Chromium (WebGL2 through SwiftShader) and collect what it posts.

``run_page(html, mounts, timeout)`` serves ``html`` as ``/index.html`` and each mount
(``{"/url/prefix/": directory or file}``) from a local HTTP server on 127.0.0.1 (HTTP range
requests answered with 206, so pages can stream and seek), opens the page in
``/usr/bin/chromium --headless`` and returns the JSON object the page POSTs to ``/result`` (a page
reports a failure by posting ``{"error": ...}``). ``locate()`` raises ``BrowserUnavailable`` naming
what is missing. Flags: those of tests/viewer.py plus the ones that keep Chromium off the network
(/work/.library/env/machines/python.md, "Known to work").
"""

from __future__ import annotations

import functools
import http.server
import json
import os
import shutil
import subprocess
import tempfile
import threading
from pathlib import Path
from urllib.parse import unquote, urlparse

REPO = Path(__file__).resolve().parents[2]
NODE_MODULES = REPO / ".ci" / "node" / "node_modules"
if not (NODE_MODULES / "three").is_dir() and os.environ.get("GLTF_VALIDATOR_DIR"):
    NODE_MODULES = Path(os.environ["GLTF_VALIDATOR_DIR"]).parent
CHROMIUM = os.environ.get("LOPCOOK_CHROMIUM", "/usr/bin/chromium")
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
         "--no-first-run", "--disable-extensions", "--disable-background-networking", "--disable-component-update",
         "--disable-sync", "--disable-quic"]
#: the three.js release .ci/run installs
THREE_VERSION = "0.170.0"
MIME = {".js": "text/javascript", ".mjs": "text/javascript", ".html": "text/html", ".json": "application/json",
        ".lop": "application/octet-stream", ".glsl": "text/plain", ".gltf": "model/gltf+json", ".bin": "application/octet-stream",
        ".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg"}


class BrowserUnavailable(RuntimeError):
    pass


def locate(three: bool = False) -> None:
    """Raise BrowserUnavailable naming what is missing (chromium; three.js when ``three``)."""
    if not (shutil.which(CHROMIUM) or os.path.isfile(CHROMIUM)):
        raise BrowserUnavailable(f"chromium not found at {CHROMIUM}")
    if three and not (NODE_MODULES / "three" / "package.json").is_file():
        raise BrowserUnavailable(f"three.js not found in {NODE_MODULES}: npm install --prefix .ci/node "
                                 f"three@{THREE_VERSION} --no-audit --no-fund")


def _handler(mounts: dict, results: dict, done: threading.Condition):
    class Handler(http.server.BaseHTTPRequestHandler):
        def resolve(self) -> Path | None:
            path = unquote(urlparse(self.path).path)
            for prefix, target in sorted(mounts.items(), key=lambda kv: -len(kv[0])):
                if path == prefix or (prefix.endswith("/") and path.startswith(prefix)):
                    target = Path(target)
                    if target.is_file():
                        return target
                    rel = path[len(prefix):]
                    full = (target / rel).resolve()
                    if target.resolve() in full.parents and full.is_file():
                        return full
            return None

        def do_GET(self):  # noqa: N802 - http.server's naming
            f = self.resolve()
            if f is None:
                self.send_error(404)
                return
            data = f.read_bytes()
            start, end, status = 0, len(data), 200
            rng = self.headers.get("Range")
            if rng and rng.startswith("bytes="):
                a, _, b = rng[6:].partition("-")
                start, end, status = int(a), min(len(data), int(b) + 1 if b else len(data)), 206
            self.send_response(status)
            self.send_header("Content-Type", MIME.get(f.suffix, "application/octet-stream"))
            self.send_header("Content-Length", str(end - start))
            self.send_header("Cache-Control", "no-store")
            if status == 206:
                self.send_header("Content-Range", f"bytes {start}-{end - 1}/{len(data)}")
            self.end_headers()
            self.wfile.write(data[start:end])

        def do_POST(self):  # noqa: N802
            body = self.rfile.read(int(self.headers.get("Content-Length", 0)))
            name = urlparse(self.path).path
            with done:
                results[name] = body
                done.notify_all()
            self.send_response(204)
            self.end_headers()

        def log_message(self, *args):
            pass

    return Handler


def run_page(html: str, mounts: dict, *, timeout: float = 300, size=(512, 512)) -> dict:
    """Serve ``html`` with ``mounts``, open it in headless Chromium, return the JSON posted to
    ``/result`` (RuntimeError when the page posts ``error`` or nothing arrives in ``timeout`` s).
    Whatever else the page POSTs is returned under ``"_posts"`` (URL path -> bytes)."""
    locate()
    results: dict = {}
    done = threading.Condition()
    with tempfile.TemporaryDirectory() as tmp:
        page = Path(tmp) / "index.html"
        page.write_text(html)
        all_mounts = {"/index.html": page, **mounts}
        server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _handler(all_mounts, results, done))
        threading.Thread(target=server.serve_forever, daemon=True).start()
        url = f"http://127.0.0.1:{server.server_address[1]}/index.html"
        cmd = [CHROMIUM, *FLAGS, f"--user-data-dir={Path(tmp) / 'profile'}", f"--window-size={size[0]},{size[1]}", url]
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        try:
            with done:
                ok = done.wait_for(lambda: "/result" in results, timeout=timeout)
        finally:
            proc.terminate()
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
            server.shutdown()
            server.server_close()
        if not ok:
            err = proc.stderr.read().decode("utf-8", "replace")[-3000:]
            raise RuntimeError(f"no result from chromium within {timeout} s; stderr: {err}")
    out = json.loads(results["/result"])
    if isinstance(out, dict) and out.get("error"):
        raise RuntimeError(f"the page failed: {out['error']}")
    out["_posts"] = {k: v for k, v in results.items() if k != "/result"}
    return out
