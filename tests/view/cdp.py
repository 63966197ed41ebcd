"""Headless Chromium driven through the DevTools protocol over a pipe (``--remote-debugging-pipe``):
open a page, evaluate JavaScript in it and read the value back. No network port, no dependency.

Chromium reads commands from its file descriptor 3 and writes replies and events to 4, each a
JSON object ended by a NUL byte (the protocol: chromedevtools.github.io/devtools-protocol).
``Page(url)`` starts Chromium on ``url``, attaches to the page's target (flat sessions) and
``evaluate(expr)`` runs ``Runtime.evaluate`` with ``awaitPromise`` and ``returnByValue``.
Flags: those of tests/runtime/browser.py (SwiftShader WebGL2, nothing reached off the machine).
"""

from __future__ import annotations

import fcntl
import json
import os
import shutil
import subprocess
import tempfile
import time

CHROMIUM = os.environ.get("LOPCOOK_CHROMIUM", "/usr/bin/chromium")
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
         "--no-first-run", "--disable-extensions", "--disable-background-networking", "--disable-component-update",
         "--disable-sync", "--disable-quic", "--disable-background-timer-throttling",
         "--disable-renderer-backgrounding", "--disable-backgrounding-occluded-windows"]


def chromium_missing() -> str | None:
    """Why Chromium cannot run here, or None."""
    if shutil.which(CHROMIUM) or os.path.isfile(CHROMIUM):
        return None
    return f"chromium not found at {CHROMIUM} (apt-get install chromium)"


def _above_4(fd: int) -> int:
    """``fd`` moved to a descriptor >= 10 (the old one closed)."""
    new = fcntl.fcntl(fd, fcntl.F_DUPFD, 10)
    os.close(fd)
    return new


class Page:
    """One headless Chromium showing ``url`` (``size`` = window width, height in pixels)."""

    def __init__(self, url: str, size=(800, 600), timeout: float = 60.0):
        self._tmp = tempfile.TemporaryDirectory()
        cmd_r, self._cmd_w = os.pipe()    # we write commands, Chromium reads them on fd 3
        self._out_r, out_w = os.pipe()    # Chromium writes on fd 4, we read
        cmd_r, out_w = (_above_4(fd) for fd in (cmd_r, out_w))  # so that moving one to 3 or 4 moves no other
        # bash, not sh: dash's redirections take one-digit descriptors only
        args = [CHROMIUM, *FLAGS, "--remote-debugging-pipe", f"--user-data-dir={self._tmp.name}",
                f"--window-size={size[0]},{size[1]}", url]
        self.proc = subprocess.Popen(["bash", "-c", f'exec "$@" 3<&{cmd_r} 4>&{out_w}', "bash", *args],
                                     pass_fds=(cmd_r, out_w), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        os.close(cmd_r)
        os.close(out_w)
        self._buf = b""
        self._id = 0
        deadline = time.monotonic() + timeout
        target = None
        while target is None:
            targets = self._call("Target.getTargets", timeout=timeout)["targetInfos"]
            target = next((t for t in targets if t["type"] == "page"), None)
            if target is None:
                if time.monotonic() > deadline:
                    raise RuntimeError("chromium opened no page")
                time.sleep(0.1)
        self._session = self._call("Target.attachToTarget", {"targetId": target["targetId"], "flatten": True},
                                   timeout=timeout)["sessionId"]

    def _send(self, method: str, params: dict | None, session: str | None) -> int:
        self._id += 1
        msg = {"id": self._id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        os.write(self._cmd_w, json.dumps(msg).encode() + b"\0")
        return self._id

    def _read(self, deadline: float) -> dict:
        while b"\0" not in self._buf:
            if time.monotonic() > deadline:
                raise TimeoutError("no reply from chromium")
            chunk = os.read(self._out_r, 1 << 20)
            if not chunk:
                raise RuntimeError("chromium closed its DevTools pipe")
            self._buf += chunk
        msg, _, self._buf = self._buf.partition(b"\0")
        return json.loads(msg)

    def _call(self, method: str, params: dict | None = None, session: str | None = None, timeout: float = 60.0):
        want = self._send(method, params, session)
        deadline = time.monotonic() + timeout
        while True:
            msg = self._read(deadline)
            if msg.get("id") == want:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg["result"]

    def evaluate(self, expression: str, timeout: float = 60.0):
        """The JSON value of ``expression`` in the page (a promise is awaited); RuntimeError when it throws."""
        res = self._call("Runtime.evaluate", {"expression": expression, "awaitPromise": True, "returnByValue": True},
                         self._session, timeout)
        if "exceptionDetails" in res:
            d = res["exceptionDetails"]
            raise RuntimeError(f"page: {d.get('exception', {}).get('description') or d.get('text')}")
        return res["result"].get("value")

    def wait_for(self, expression: str, timeout: float, interval: float = 0.05):
        """Evaluate ``expression`` until it gives a truthy value (returned); TimeoutError after ``timeout`` s."""
        deadline = time.monotonic() + timeout
        while True:
            try:
                value = self.evaluate(expression)
            except RuntimeError as exc:  # the page is still loading (no execution context yet)
                if "context" not in str(exc):
                    raise
                value = None
            if value:
                return value
            if time.monotonic() > deadline:
                raise TimeoutError(f"{expression!r} stayed falsy for {timeout} s")
            time.sleep(interval)

    def close(self) -> None:
        for fd in (self._cmd_w, self._out_r):
            try:
                os.close(fd)
            except OSError:
                pass
        self.proc.terminate()
        try:
            self.proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self._tmp.cleanup()

    def __enter__(self) -> "Page":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
