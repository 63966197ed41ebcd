"""``lopcook bench --streaming``: how good a streamed ``.lop`` looks in three.js after each byte count.

For each asset (default: the bunny, DamagedHelmet, the chess set) the source is cooked
(``COOK_FLAGS``), served with the viewer's files (``lopcook.view``) and drawn in headless Chromium
by ``runtime/js/viewer/bench.js`` with the viewer's own scene (viewer.js: RoomEnvironment light,
tone mapping, the glTF materials ``lopcook web`` finds), at ``SIZE`` pixels, from three cameras:

* the camera looks at the centre of the source's bounding sphere from ``VIEW_DIRECTION`` (viewer.js),
  at the distance where the sphere spans 100 % (``near``), 40 % (``middle``) or 15 % (``far``) of
  the viewport height (vertical field of view 45 degrees): ``CAMERAS``;
* the reference is the **float render**: the source's own float32 geometry (every part, its
  normals and UVs) with the same materials, as a plain glTF (``reference.glb``), same viewer and camera;
* the container is fed to the viewer's loader up to every section end (the only byte counts at
  which the renderable state can change) and drawn after each cut that changed it; PSNR is
  ``lopcook.verify.metrics.image_metrics`` (pixels covered in either image, 8-bit RGB), so each
  curve is a step function of the bytes received.

Per asset and camera: ``first_image_bytes`` (the first cut drawn with the model on screen),
``bytes_to_30db`` / ``bytes_to_40db`` (the first cut at or above; None when never), and the peers
as points at their whole file gzip -9'd (``gzip -9 -n``): gltfpack ``-cc -kv`` at its defaults
(positions 14 bits, normals 8, UVs 12; input: the bench's material-less ``input.glb``, so ``-kv``
keeps its UVs) and Draco (DracoPy, positions 14 bits, normals 10, UVs 12, level 7: the parts'
buffers back to back, without the glTF JSON around them). A peer that cannot run is None and the
output says why. Outputs: ``streaming.csv``, ``streaming.json``, ``streaming.png``, ``images/``.
"""

from __future__ import annotations

import gzip
import json
import shutil
import struct
import subprocess
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..emit import preview
from ..emit.gltf_writer import write_gltf
from ..errors import LopcookError
from ..ingest import load
from ..lop.container import HEADER_SIZE, read
from ..verify.metrics import image_metrics
from ..view import Site, ViewerServer, add_container, runtime_site
from . import peers as P
from .charts import streaming_chart
from .browser import chromium_version, find_chromium, run_page
from .common import asset_name, corpus_dir, log, machine, run_cook, write_csv
from .draco_run import write_parts

DEFAULT_ASSETS = ("stanford-bunny.obj", "DamagedHelmet/DamagedHelmet.gltf", "chess_set_flat.usdc")
#: (name, share of the viewport height the bounding sphere spans)
CAMERAS = (("near", 1.0), ("middle", 0.4), ("far", 0.15))
#: canvas size in pixels (width, height)
SIZE = (512, 512)
#: extra ``lopcook cook`` flags of the streamed containers (``--cook-args`` adds to them)
COOK_FLAGS: tuple[str, ...] = ()
#: position bits of the peers (gltfpack's default -vp, glTF-Transform's draco default)
PEER_POSITION_BITS = 14
CSV_COLUMNS = ("asset", "camera", "bytes", "psnr_db")
#: the issue's streaming goals, checked on this camera
CHECK_CAMERA = "middle"
FIRST_IMAGE_SHARE = 0.05
PAGE = """<!doctype html><html><head><meta charset="utf-8"><style>body{margin:0;background:#000}</style>
<script type="importmap">{"imports": {"three": "/js/viewer/vendor/three/build/three.module.min.js",
"three/addons/": "/js/viewer/vendor/three/examples/jsm/"}}</script></head><body>
<script type="module" src="/js/viewer/bench.js"></script></body></html>"""


@dataclass
class Curve:
    """PSNR against bytes received for one asset and camera: ``points`` (bytes, dB; None for identical
    images) at every cut drawn, ``covered`` the model's pixels at each."""

    asset: str
    camera: str
    file_bytes: int
    points: list = field(default_factory=list)
    covered: list = field(default_factory=list)

    def first_image_bytes(self) -> int | None:
        return next((b for (b, _), n in zip(self.points, self.covered) if n > 0), None)

    def bytes_to(self, db: float) -> int | None:
        """The first byte count whose image is at ``db`` or above (None: never)."""
        return next((b for (b, p), n in zip(self.points, self.covered) if n > 0 and (p is None or p >= db)), None)

    def final_db(self):
        return self.points[-1][1] if self.points else None


def cut_points(c) -> list[int]:
    """Every section end of container ``c`` (absolute byte offsets, ascending, distinct), the end of
    the manifest first: the byte counts at which a reader's renderable state can change."""
    manifest_size = struct.unpack_from("<I", c.data, 12)[0]
    base = HEADER_SIZE + manifest_size
    ends = {base + int(s["offset"]) + int(s["length"]) for s in c.manifest["sections"]}
    return sorted(ends | {base, len(c.data)})


def gzip9(data: bytes) -> int:
    """Bytes of ``data`` after ``gzip -9 -n`` (Python's gzip at level 9 where there is no gzip)."""
    exe = shutil.which("gzip")
    if exe:
        return len(subprocess.run([exe, "-9", "-n", "-c"], input=data, capture_output=True, check=True).stdout)
    return len(gzip.compress(data, 9, mtime=0))


def write_reference(scene, c, source: str, out: Path) -> None:
    """The float render's glTF: every part of ``scene`` with its float32 geometry and the material
    ``lopcook web`` gives the container's part of the same index."""
    parts = c.manifest["parts"]
    if len(parts) != len(scene.parts):
        raise LopcookError("bench", source, f"the container has {len(parts)} parts, the source {len(scene.parts)}")
    has = lambda key: [p["attribute_bits"].get(key) is not None for p in parts]  # noqa: E731
    mats, per_part, _ = preview.source_materials(source, c.manifest["source"].get("format", ""), parts, has("uvs"),
                                                 has("colors"))
    meshes = [{"name": p.name, "positions": p.positions, "indices": p.indices, "normals": p.normals,
               "uvs": p.uvs if has("uvs")[i] else None, "colors": p.colors if has("colors")[i] else None,
               "material": per_part[i] if mats else None} for i, p in enumerate(scene.parts)]
    write_gltf(out, meshes, generator="lopcook bench --streaming (float reference)", materials=mats or None)


def peer_sizes(scene, adir: Path, avail: dict) -> dict:
    """``{"gltfpack_cc_gzip_bytes", "draco_gzip_bytes"}`` of the source (module doc), None where the
    peer is missing or fails, and ``notes``: one line per such peer."""
    out, notes = {"gltfpack_cc_gzip_bytes": None, "draco_gzip_bytes": None}, []
    glb = adir / "input.glb"
    write_gltf(glb, scene.parts, generator="lopcook bench")
    if avail.get("gltfpack"):
        dst = adir / "gltfpack_cc.glb"
        m = P.run_measured([avail["gltfpack"], "-i", glb, "-o", dst, "-cc", "-kv"], timeout_s=3600)
        if m.returncode == 0 and dst.is_file():
            out["gltfpack_cc_gzip_bytes"] = gzip9(dst.read_bytes())
        else:
            notes.append(f"gltfpack failed (exit {m.returncode}): {(m.stderr.strip().splitlines() or [''])[-1]}")
    else:
        notes.append(P.missing_line("gltfpack"))
    if avail.get("draco"):
        npz, dst = adir / "parts.npz", adir / "draco.npz"
        write_parts(npz, scene.parts)
        m = P.run_measured(P.draco_argv(avail["draco"], npz, dst, PEER_POSITION_BITS), timeout_s=3600)
        if m.returncode == 0 and dst.is_file():
            with np.load(dst) as z:
                out["draco_gzip_bytes"] = gzip9(b"".join(z[f"buffer_{k}"].tobytes() for k in range(len(z.files))))
        else:
            notes.append(f"draco failed (exit {m.returncode}): {(m.stderr.strip().splitlines() or [''])[-1]}")
    else:
        notes.append(P.missing_line("draco"))
    return {**out, "notes": notes}


class Collector:
    """The bench page's POST sink: reference images kept per (asset, camera), every other image scored
    against its reference on arrival (``Curve``), the first and last drawn kept as PNG in ``images``."""

    def __init__(self, curves: dict, images: Path):
        self.curves, self.images = curves, images
        self.refs, self.result, self.error = {}, None, None
        self.done = threading.Event()
        self._lock = threading.Lock()

    def post(self, path: str, body: bytes) -> None:
        try:
            with self._lock:
                self._post(path, body)
        except Exception as exc:  # noqa: BLE001 -- ends the run with the reason
            self.error = f"{path}: {type(exc).__name__}: {exc}"
            self.done.set()

    def _post(self, path: str, body: bytes) -> None:
        if path == "/result":
            self.result = json.loads(body)
            self.done.set()
            return
        _, kind, asset, camera, tag = path.split("/")
        if kind != "image":
            raise ValueError("unexpected POST")
        img = np.frombuffer(body, np.uint8).reshape(SIZE[1], SIZE[0], 4)[::-1]
        if tag == "reference":
            self.refs[(asset, camera)] = img
            self._save(img, f"{asset}-{camera}-reference")
            return
        curve = self.curves[(asset, camera)]
        m = image_metrics(self.refs[(asset, camera)], img)
        covered = int(np.count_nonzero(img[..., 3]))
        if covered and not any(curve.covered) or int(tag) == curve.file_bytes:
            self._save(img, f"{asset}-{camera}-{int(tag)}")
        curve.points.append((int(tag), m["psnr"]))
        curve.covered.append(covered)

    def _save(self, img: np.ndarray, name: str) -> None:
        from PIL import Image  # optional: only the saved frames need it

        self.images.mkdir(parents=True, exist_ok=True)
        Image.fromarray(np.ascontiguousarray(img)).save(self.images / f"{name}.png")


def prepare_asset(source: str, out_dir: Path, site: Site, cook_flags, opts) -> dict:
    """Cook ``source``, add its container, web glTF and float reference to ``site``; the page's job."""
    name = asset_name(source)
    adir = out_dir / "assets" / name
    adir.mkdir(parents=True, exist_ok=True)
    lop = adir / "scene.lop"
    log(opts, f"{name}: cook {' '.join(cook_flags)}".rstrip())
    m, desc = run_cook(source, lop, list(cook_flags))
    if desc is None:
        tail = (m.stderr.strip().splitlines() or [f"exit {m.returncode}"])[-1]
        raise LopcookError("bench", source, f"lopcook cook failed: {tail}")
    c = read(str(lop))
    scene = load(source)
    add_container(site, str(lop), source, prefix=f"/asset/{name}/")
    write_reference(scene, c, source, adir / "reference.glb")
    site.add_file(f"/asset/{name}/reference.glb", adir / "reference.glb")
    lo, hi = (np.asarray(v, np.float64) for v in scene.bounds())
    return {"name": name, "gltf": f"/asset/{name}/scene.gltf", "lop": f"/asset/{name}/scene.lop",
            "reference": f"/asset/{name}/reference.glb", "cuts": cut_points(c),
            "centre": [float(v) for v in (lo + hi) / 2], "radius": float(np.linalg.norm(hi - lo) / 2),
            "cameras": [{"name": n, "fraction": f} for n, f in CAMERAS], "_scene": scene, "_container": c}


def run_jobs(jobs: list[dict], out_dir: Path, site: Site, timeout_s: float) -> tuple[dict, dict]:
    """Serve ``site`` with the bench page and ``jobs``, run the page; returns ``{(asset, camera): Curve}``
    and ``{asset: [[bytes, level drawn], ...]}`` (every cut drawn)."""
    curves = {(j["name"], n): Curve(j["name"], n, len(j["_container"].data)) for j in jobs for n, _ in CAMERAS}
    sink = Collector(curves, out_dir / "images")
    site.post = sink.post
    site.add_bytes("/bench/index.html", PAGE.encode())
    public = [{k: v for k, v in j.items() if not k.startswith("_")} for j in jobs]
    site.add_bytes("/bench/jobs.json", json.dumps({"size": list(SIZE), "assets": public}).encode())
    with ViewerServer(site) as server:
        run_page(server.url + "bench/index.html", sink.done, timeout=timeout_s, size=SIZE)
    if sink.error or (sink.result or {}).get("error"):
        raise LopcookError("bench", None, f"the streaming page failed: {sink.error or sink.result['error']}")
    return curves, {a["name"]: [[d["bytes"], d["level"]] for d in a["drawn"]] for a in sink.result["assets"]}


def summarise(curves: dict, peers: dict, jobs: list[dict]) -> tuple[list[dict], dict, list[dict]]:
    """(CSV rows, ``{asset: {camera: numbers}}``, checks of the issue's goals on ``CHECK_CAMERA``)."""
    rows, results, checks = [], {}, []
    for (asset, camera), cv in curves.items():
        rows += [{"asset": asset, "camera": camera, "bytes": b, "psnr_db": float("inf") if p is None else round(p, 3)}
                 for (b, p), n in zip(cv.points, cv.covered) if n > 0]
        final = cv.final_db()
        results.setdefault(asset, {})[camera] = {
            "file_bytes": cv.file_bytes, "first_image_bytes": cv.first_image_bytes(),
            "bytes_to_30db": cv.bytes_to(30.0), "bytes_to_40db": cv.bytes_to(40.0),
            "final_psnr_db": None if final is None else round(final, 3),
            "gltfpack_cc_gzip_bytes": peers[asset]["gltfpack_cc_gzip_bytes"],
            "draco_gzip_bytes": peers[asset]["draco_gzip_bytes"]}
    for j in jobs:
        r = results[j["name"]][CHECK_CAMERA]
        first, to40, gp = r["first_image_bytes"], r["bytes_to_40db"], r["gltfpack_cc_gzip_bytes"]
        checks.append(_check(f"{j['name']}: first image within {FIRST_IMAGE_SHARE:.0%} of the file",
                             first is not None and first <= FIRST_IMAGE_SHARE * r["file_bytes"],
                             f"{first} of {r['file_bytes']} bytes" if first else "no image"))
        checks.append(_check(f"{j['name']}: 40 dB within gltfpack -cc gzip -9's bytes",
                             None if gp is None else (to40 is not None and to40 <= gp),
                             f"40 dB at {to40} bytes, gltfpack -cc gzip -9 {gp} bytes"))
    return rows, results, checks


def _check(name: str, ok, detail: str) -> dict:
    return {"check": name, "status": "unknown" if ok is None else ("pass" if ok else "fail"), "detail": detail}


def default_assets() -> list[str]:
    corpus = corpus_dir()
    if corpus is None:
        raise LopcookError("usage", None, "no --assets given and no corpus found",
                           hint="give --assets files, or set LOPCOOK_CORPUS to the shared corpus folder")
    return [str(corpus / a) for a in DEFAULT_ASSETS if (corpus / a).is_file()]


def run_streaming(opts) -> dict:
    """``lopcook bench --streaming``: every output into ``opts.output`` (module doc); returns the summary."""
    t0 = time.perf_counter()
    assets = [str(a) for a in opts.assets] or default_assets()
    for a in assets:
        if not Path(a).is_file():
            raise LopcookError("usage", a, "not found or not a regular file", hint="give source assets with --assets")
    cook_flags = list(COOK_FLAGS) + list(getattr(opts, "cook_args", []) or [])
    chromium = find_chromium()
    if chromium is None:
        raise LopcookError("usage", None, "chromium not found (the streaming bench renders in headless Chromium)",
                           hint="apt-get install chromium, or set LOPCOOK_CHROMIUM")
    out_dir = Path(opts.output)
    out_dir.mkdir(parents=True, exist_ok=True)
    avail = P.availability([p for p in ("gltfpack", "draco")])
    site = runtime_site()
    jobs = [prepare_asset(a, out_dir, site, cook_flags, opts) for a in assets]
    peers = {}
    for j in jobs:
        log(opts, f"{j['name']}: peers (gltfpack -cc, Draco; gzip -9)")
        peers[j["name"]] = peer_sizes(j["_scene"], out_dir / "assets" / j["name"], avail)
        for note in peers[j["name"]]["notes"]:
            log(opts, f"{j['name']}: {note}")
    log(opts, f"render {len(jobs)} assets x {len(CAMERAS)} cameras in headless Chromium ({SIZE[0]}x{SIZE[1]})")
    curves, drawn = run_jobs(jobs, out_dir, site, timeout_s=3600.0 * len(jobs))
    rows, results, checks = summarise(curves, peers, jobs)
    write_csv(out_dir / "streaming.csv", rows, CSV_COLUMNS)
    summary = {"generator": "lopcook bench --streaming", "command": "lopcook bench " + " ".join(getattr(opts, "argv", [])),
               "machine": machine(), "chromium": chromium_version(chromium), "three": "0.170.0", "size": list(SIZE),
               "cameras": dict(CAMERAS), "cook_flags": cook_flags, "peer_position_bits": PEER_POSITION_BITS,
               "peer_notes": {a: p["notes"] for a, p in peers.items()},
               "lop_gzip_bytes": {j["name"]: gzip9(bytes(j["_container"].data)) for j in jobs},
               "results": results, "levels_drawn": drawn, "checks": checks, "seconds": round(time.perf_counter() - t0, 1)}
    (out_dir / "streaming.json").write_text(json.dumps(summary, indent=1, sort_keys=True) + "\n")
    streaming_chart(curves, peers, out_dir / "streaming.png")
    for c in checks:
        log(opts, f"{c['status']:>8}: {c['check']}: {c['detail']}")
    log(opts, f"wrote {out_dir}/streaming.csv, streaming.json, streaming.png in {summary['seconds']:.0f} s")
    return summary


__all__ = ["CAMERAS", "COOK_FLAGS", "CSV_COLUMNS", "Collector", "Curve", "DEFAULT_ASSETS", "SIZE", "cut_points",
           "gzip9", "peer_sizes", "prepare_asset", "run_jobs", "run_streaming", "summarise", "write_reference"]
