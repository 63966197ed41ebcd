"""Headless Chromium for ``lopcook bench --streaming``: open one page of a local site and wait until
it posts ``/result``.

Chromium is ``$LOPCOOK_CHROMIUM`` or the first of ``chromium``, ``chromium-browser``,
``google-chrome`` on ``PATH``; WebGL2 runs on SwiftShader (``--use-angle=swiftshader``), the same
software rasteriser on every machine, and nothing is fetched from the network.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
import threading

from ..errors import LopcookError

FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
         "--no-first-run", "--disable-extensions", "--disable-background-networking", "--disable-component-update",
         "--disable-sync", "--disable-quic", "--disable-background-timer-throttling",
         "--disable-renderer-backgrounding"]


def find_chromium() -> str | None:
    env = os.environ.get("LOPCOOK_CHROMIUM")
    if env:
        return env if os.path.isfile(env) else shutil.which(env)
    return next((p for p in map(shutil.which, ("chromium", "chromium-browser", "google-chrome")) if p), None)


def chromium_version(exe: str) -> str:
    try:
        r = subprocess.run([exe, "--version"], capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        return "unknown"
    return (r.stdout.strip().splitlines() or ["unknown"])[0]


def run_page(url: str, done: threading.Event, *, timeout: float, size=(512, 512)) -> None:
    """Open ``url`` in headless Chromium and wait until ``done`` is set (the site's POST sink sets
    it on ``/result``); LopcookError when Chromium is missing, exits first, or ``timeout`` s pass."""
    exe = find_chromium()
    if exe is None:
        raise LopcookError("usage", None, "chromium not found (the streaming bench renders in headless Chromium)",
                           hint="apt-get install chromium, or set LOPCOOK_CHROMIUM")
    with tempfile.TemporaryDirectory() as profile:
        cmd = [exe, *FLAGS, f"--user-data-dir={profile}", f"--window-size={size[0]},{size[1]}", url]
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        drain = threading.Thread(target=lambda: proc.stderr.read(), daemon=True)  # never block on a full pipe
        drain.start()
        try:
            step = 0.5
            waited = 0.0
            while not done.wait(step):
                waited += step
                if proc.poll() is not None:
                    raise LopcookError("bench", url, f"chromium exited ({proc.returncode}) before the page finished")
                if waited > timeout:
                    raise LopcookError("bench", url, f"the page did not finish within {timeout:.0f} s")
        finally:
            proc.terminate()
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


__all__ = ["FLAGS", "chromium_version", "find_chromium", "run_page"]
