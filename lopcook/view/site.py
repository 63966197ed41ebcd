"""What ``lopcook view CONTAINER.lop`` serves: the viewer page and one container with its materials.

URLs (``lopcook.view.server.Site``; nothing else is answered):

* ``/`` the viewer page (``runtime/js/viewer/index.html``); ``/js/...`` every regular file under
  ``runtime/js/`` (lop.js, three-lop.js, the WebGL2 decoders, the viewer's modules and the
  three.js r170 files it ships in ``viewer/vendor/three/``), symbolic links left out;
* ``/asset/scene.lop`` the container's bytes as they were when the command started, paced by
  ``?rate=`` (the page's throttle);
* ``/asset/scene.gltf`` and ``/asset/scene.bin`` the glTF ``lopcook web`` would write for it
  (``lopcook.emit.web.web_document``: the source's materials, found as ``decode`` finds them, and
  their images embedded in the ``.bin``; the extension's ``uri`` is ``scene.lop``), built in
  memory, so the source's own files are never served;
* ``/asset/info.json`` ``{"name", "bytes", "source", "warnings"}`` for the page's title and HUD.

The runtime is looked for in ``$LOPCOOK_RUNTIME_JS``, the checkout's ``runtime/js``, then
``<prefix>/share/lopcook/runtime/js`` (where a wheel installs it).
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

from ..emit.gltf_writer import gltf_json_text
from ..emit.web import EXTENSION, web_document
from ..errors import LopcookError
from ..lop.container import read
from .server import Site

def runtime_js_dir() -> Path:
    """The ``runtime/js`` folder holding ``viewer/index.html`` (module doc); LopcookError when none does."""
    env = os.environ.get("LOPCOOK_RUNTIME_JS")
    candidates = [Path(env)] if env else [Path(__file__).resolve().parents[2] / "runtime" / "js",
                                          Path(sys.prefix) / "share" / "lopcook" / "runtime" / "js"]
    for c in candidates:
        if (c / "viewer" / "index.html").is_file() and (c / "three-lop.js").is_file():
            return c
    raise LopcookError("usage", str(candidates[0]), "the browser runtime (runtime/js/viewer/index.html) is missing",
                       hint="run from a lopcook checkout or set LOPCOOK_RUNTIME_JS to its runtime/js folder")


def runtime_site(js_dir=None) -> Site:
    """A site of the runtime alone: ``/js/...`` and the viewer page at ``/``."""
    root = Path(js_dir) if js_dir is not None else runtime_js_dir()
    site = Site()
    site.add_tree("/js/", root)
    if "/js/viewer/index.html" not in site.routes:
        raise LopcookError("usage", str(root), "the viewer page viewer/index.html is missing or a symbolic link")
    site.routes["/"] = site.routes["/js/viewer/index.html"]
    return site


def add_container(site: Site, container_path: str, source: str | None = None, prefix: str = "/asset/") -> dict:
    """Add ``prefix`` + ``scene.lop``, ``scene.gltf`` (+ ``scene.bin``) and ``info.json`` of the
    container at ``container_path`` (materials from ``source`` or the manifest's source beside
    it) to ``site``; returns the info dict. LopcookError for a container that does not read."""
    c = read(str(container_path))
    here = os.path.dirname(os.path.abspath(container_path))
    doc, blob, warnings = web_document(c, str(container_path), os.path.join(here, "scene.gltf"), source)
    doc["extensions"][EXTENSION]["uri"] = "scene.lop"
    if blob:
        doc["buffers"][0]["uri"] = "scene.bin"
        site.add_bytes(prefix + "scene.bin", blob)
    site.add_bytes(prefix + "scene.gltf", gltf_json_text(doc, sort_keys=True).encode("ascii"))
    site.add_bytes(prefix + "scene.lop", bytes(c.data), paced=True)
    info = {"name": os.path.basename(str(container_path)), "bytes": len(c.data), "parts": len(c.manifest["parts"]),
            "materials": len(doc.get("materials", [])), "warnings": warnings}
    site.add_bytes(prefix + "info.json", json.dumps(info, sort_keys=True).encode("utf-8"))
    return info


def viewer_site(container_path: str, source: str | None = None, js_dir=None) -> tuple[Site, dict]:
    """The site ``lopcook view`` serves (module doc) and the container's info dict."""
    site = runtime_site(js_dir)
    info = add_container(site, container_path, source)
    return site, info


__all__ = ["add_container", "runtime_js_dir", "runtime_site", "viewer_site"]
