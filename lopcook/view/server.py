"""A loopback HTTP server of a fixed set of URLs (``lopcook view``'s, and ``lopcook bench --streaming``'s).

What it answers, and nothing else:

* **Only the URLs of its ``Site``.** A site maps each URL path (``/js/lop.js``) to bytes in
  memory or to a regular file, listed when the site is built; a request is served only when its
  percent-decoded path is one of those keys, exactly. There is no path joining at request time,
  so ``..``, absolute or encoded paths, and anything reached through a symbolic link that the
  site did not list, get 404.
* **Only on 127.0.0.1**, and only for a ``Host`` header naming that address or ``localhost`` with
  the server's port (403 otherwise: a page on another site that renamed itself to 127.0.0.1
  through DNS cannot read the files).
* **GET and HEAD**, and POST only where the site has a ``post`` sink (the bench's page posts its
  images); 405 otherwise.
* **Range requests** (RFC 9110 section 14): one range ``bytes=a-b``, ``bytes=a-`` or
  ``bytes=-n`` gets 206 with ``Content-Range``; a range that starts at or past the end of the
  file, an empty suffix, a malformed or a multi-range header gets 416 with
  ``Content-Range: bytes */size``.
* **Pacing.** A route marked ``paced`` sends its body at ``?rate=B`` bytes per second (in chunks
  of ``rate / 20`` bytes, at least 512, each at its time since the first): the bandwidth
  throttle of the viewer. Without ``rate`` (or 0) it is sent at once.

Responses carry ``Cache-Control: no-store`` (a replay fetches again) and
``X-Content-Type-Options: nosniff``.
"""

from __future__ import annotations

import http.server
import re
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable
from urllib.parse import parse_qs, unquote, urlsplit

from ..errors import LopcookError

#: MIME type of each file extension the sites serve (anything else: application/octet-stream)
MIME = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8", ".mjs": "text/javascript",
        ".json": "application/json", ".css": "text/css", ".glsl": "text/plain; charset=utf-8",
        ".md": "text/plain; charset=utf-8", ".gltf": "model/gltf+json", ".glb": "model/gltf-binary",
        ".bin": "application/octet-stream", ".lop": "application/octet-stream", ".png": "image/png",
        ".jpg": "image/jpeg", ".jpeg": "image/jpeg", ".svg": "image/svg+xml", "": "text/plain"}
#: chunks per second of a paced response, and its smallest chunk in bytes
PACE_HZ = 20
PACE_MIN_CHUNK = 512
_RANGE = re.compile(r"bytes=(\d*)-(\d*)")


@dataclass(frozen=True)
class Route:
    """One URL's content: ``data`` (bytes in memory) or ``path`` (a regular file, read per request),
    its MIME type, and whether ``?rate=`` paces it."""

    data: bytes | None = None
    path: Path | None = None
    mime: str = "application/octet-stream"
    paced: bool = False

    def body(self) -> bytes:
        return self.data if self.data is not None else Path(self.path).read_bytes()


@dataclass
class Site:
    """URL path -> Route, and an optional sink for POSTs ``post(path, body)`` (None: 405)."""

    routes: dict[str, Route] = field(default_factory=dict)
    post: Callable[[str, bytes], None] | None = None

    def add_bytes(self, url: str, data: bytes, mime: str | None = None, paced: bool = False) -> None:
        self.routes[url] = Route(data=bytes(data), mime=mime or mime_of(url), paced=paced)

    def add_file(self, url: str, path, paced: bool = False) -> None:
        """Serve the regular file ``path`` at ``url`` (LopcookError when it is not one)."""
        p = Path(path)
        if not p.is_file():
            raise LopcookError("usage", str(path), "not a regular file")
        self.routes[url] = Route(path=p.resolve(), mime=mime_of(url), paced=paced)

    def add_tree(self, prefix: str, root) -> int:
        """Serve every regular file under ``root`` at ``prefix + relative/path``; symbolic links
        (to files or folders) and files whose real path leaves ``root`` are left out. Returns the
        number of files added."""
        base = Path(root).resolve()
        n = 0
        for p in sorted(base.rglob("*")):
            rel = p.relative_to(base)
            if any((base / Path(*rel.parts[:k + 1])).is_symlink() for k in range(len(rel.parts))):
                continue
            if p.is_file() and base in p.resolve().parents:
                self.add_file(prefix + rel.as_posix(), p)
                n += 1
        return n


def mime_of(url: str) -> str:
    suffix = Path(urlsplit(url).path).suffix.lower()
    return MIME.get(suffix, "application/octet-stream")


def parse_range(header: str, size: int) -> tuple[int, int] | None:
    """``[start, end)`` of a ``Range`` header over a body of ``size`` bytes; None when it cannot be
    satisfied (module doc: past the end, empty suffix, malformed, several ranges)."""
    m = _RANGE.fullmatch(header.strip())
    if m is None or (not m.group(1) and not m.group(2)):
        return None
    if not m.group(1):  # suffix: the last n bytes
        n = int(m.group(2))
        return (max(0, size - n), size) if n > 0 and size > 0 else None
    start = int(m.group(1))
    end = size if not m.group(2) else min(size, int(m.group(2)) + 1)
    if start >= size or end <= start:
        return None
    return start, end


def _rate(query: str) -> int | None:
    """``rate`` of a query string in bytes per second (0 when absent), None when malformed."""
    values = parse_qs(query, keep_blank_values=True).get("rate")
    if not values:
        return 0
    text = values[-1]
    return int(text) if text.isdigit() and len(text) <= 12 else None


class _Handler(http.server.BaseHTTPRequestHandler):
    """The request handler of a ViewerServer; ``site`` and ``port_ref`` (``[port]``) are set on a
    subclass per server (``_handler``)."""

    site: Site
    port_ref: list
    server_version = "lopcook"
    sys_version = ""
    protocol_version = "HTTP/1.1"

    def _host_ok(self) -> bool:
        host = (self.headers.get("Host") or "").strip().lower()
        return host in (f"127.0.0.1:{self.port_ref[0]}", f"localhost:{self.port_ref[0]}")

    def _status(self, code: int, extra: dict | None = None) -> None:
        self.send_response(code)
        for k, v in (extra or {}).items():
            self.send_header(k, v)
        self.send_header("Content-Length", "0")
        self.send_header("Cache-Control", "no-store")
        self.end_headers()

    def _route(self) -> tuple[Route | None, str]:
        parts = urlsplit(self.path)
        return self.site.routes.get(unquote(parts.path, errors="strict")), parts.query

    def _get(self, head: bool) -> None:
        if not self._host_ok():
            return self._status(403)
        try:
            route, query = self._route()
        except UnicodeDecodeError:
            route, query = None, ""
        if route is None:
            return self._status(404)
        rate = _rate(query) if route.paced else 0
        if rate is None:
            return self._status(400)
        data = route.body()
        start, end, code = 0, len(data), 200
        if self.headers.get("Range") is not None:
            rng = parse_range(self.headers["Range"], len(data))
            if rng is None:
                return self._status(416, {"Content-Range": f"bytes */{len(data)}"})
            (start, end), code = rng, 206
        self.send_response(code)
        self.send_header("Content-Type", route.mime)
        self.send_header("Content-Length", str(end - start))
        self.send_header("Accept-Ranges", "bytes")
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        if code == 206:
            self.send_header("Content-Range", f"bytes {start}-{end - 1}/{len(data)}")
        self.end_headers()
        if not head:
            self._send(memoryview(data)[start:end], rate)

    def _send(self, body: memoryview, rate: int) -> None:
        """Write ``body``, at ``rate`` bytes per second when > 0; a client that hangs up (a
        replay aborts its fetch) ends it quietly."""
        try:
            if rate <= 0:
                self.wfile.write(body)
                return
            chunk = max(PACE_MIN_CHUNK, rate // PACE_HZ)
            t0 = time.monotonic()
            for at in range(0, len(body), chunk):
                wait = t0 + at / rate - time.monotonic()
                if wait > 0:
                    time.sleep(wait)
                self.wfile.write(body[at:at + chunk])
                self.wfile.flush()
        except (BrokenPipeError, ConnectionResetError):
            self.close_connection = True

    def do_GET(self):  # noqa: N802 - http.server's naming
        self._get(head=False)

    def do_HEAD(self):  # noqa: N802
        self._get(head=True)

    def do_POST(self):  # noqa: N802
        if not self._host_ok():
            return self._status(403)
        if self.site.post is None:
            return self._status(405, {"Allow": "GET, HEAD"})
        n = int(self.headers.get("Content-Length") or 0)
        body = self.rfile.read(n)
        self.site.post(unquote(urlsplit(self.path).path), body)
        self._status(204)

    def log_message(self, *args):  # quiet: the command prints its URL and nothing per request
        pass


def _handler(site: Site, port_ref: list) -> type:
    return type("Handler", (_Handler,), {"site": site, "port_ref": port_ref})


class ViewerServer:
    """``site`` served on ``http://127.0.0.1:PORT/`` (``port`` 0: any free port) by a threaded
    ``http.server``. ``start()`` serves from a daemon thread, ``serve_forever()`` in the caller's;
    ``close()`` stops it. LopcookError when the port cannot be bound."""

    def __init__(self, site: Site, port: int = 0):
        if not 0 <= int(port) <= 65535:
            raise LopcookError("usage", None, f"--port {port} is outside [0, 65535]")
        port_ref = [int(port)]
        try:
            self._httpd = http.server.ThreadingHTTPServer(("127.0.0.1", int(port)), _handler(site, port_ref))
        except OSError as exc:
            raise LopcookError("usage", None, f"cannot listen on 127.0.0.1:{port}: {exc.strerror or exc}",
                               hint="choose another --port, or 0 for any free one") from None
        self._httpd.daemon_threads = True
        port_ref[0] = self.port
        self._thread: threading.Thread | None = None

    @property
    def port(self) -> int:
        return int(self._httpd.server_address[1])

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}/"

    def start(self) -> "ViewerServer":
        self._thread = threading.Thread(target=self._httpd.serve_forever, daemon=True)
        self._thread.start()
        return self

    def serve_forever(self) -> None:
        self._httpd.serve_forever()

    def close(self) -> None:
        if self._thread is not None:
            self._httpd.shutdown()
            self._thread.join()
        self._httpd.server_close()

    def __enter__(self) -> "ViewerServer":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.close()


__all__ = ["MIME", "PACE_HZ", "PACE_MIN_CHUNK", "Route", "Site", "ViewerServer", "mime_of", "parse_range"]
