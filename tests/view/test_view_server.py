"""``lopcook view``'s server (lopcook/view/): only the site's URLs are answered (404 for ``..``,
absolute, percent-encoded and symlinked paths), ranges are exact and a range outside the file gets
416, a foreign ``Host`` gets 403, the throttle paces the body, and the command prints its URL,
serves, stops on Ctrl-C with exit 0, and refuses a bad container or port with one line and exit 2.
"""

from __future__ import annotations

import hashlib
import http.client
import json
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from lopcook.view import ViewerServer, parse_range, runtime_site, viewer_site

REPO = Path(__file__).resolve().parents[2]
JS = REPO / "runtime" / "js"
CONTAINER = REPO / "fixtures" / "golden" / "unit_sphere.lop"
VENDOR = JS / "viewer" / "vendor" / "three"


def get(server: ViewerServer, path: str, headers: dict | None = None, method: str = "GET"):
    """(status, headers, body) of one request with ``path`` sent exactly as given."""
    conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=30)
    conn.putrequest(method, path, skip_host=True, skip_accept_encoding=True)
    hdrs = {"Host": f"127.0.0.1:{server.port}", **(headers or {})}
    for k, v in hdrs.items():
        conn.putheader(k, v)
    conn.endheaders()
    res = conn.getresponse()
    body = res.read()
    conn.close()
    return res.status, dict(res.getheaders()), body


@pytest.fixture(scope="module")
def tree(tmp_path_factory):
    """A copy of runtime/js with a symlink to a file outside it and one to a folder outside it, and a
    container folder holding a secret file and a symlink beside the container."""
    root = tmp_path_factory.mktemp("view")
    outside = root / "outside"
    outside.mkdir()
    (outside / "secret.txt").write_text("secret")
    js = root / "js"
    shutil.copytree(JS, js, symlinks=True)
    (js / "viewer" / "leak.txt").symlink_to(outside / "secret.txt")
    (js / "viewer" / "linked").symlink_to(outside, target_is_directory=True)
    assets = root / "assets"
    assets.mkdir()
    shutil.copy(CONTAINER, assets / "sphere.lop")
    (assets / "secret.txt").write_text("secret")
    (assets / "link.txt").symlink_to(outside / "secret.txt")
    return {"js": js, "container": assets / "sphere.lop", "outside": outside}


@pytest.fixture(scope="module")
def server(tree):
    site, _ = viewer_site(str(tree["container"]), js_dir=tree["js"])
    with ViewerServer(site) as s:
        yield s


def test_serves_the_page_runtime_and_container(server, tree):
    status, hdrs, body = get(server, "/")
    assert status == 200 and b"/js/viewer/main.js" in body and hdrs["Content-Type"].startswith("text/html")
    for url, path in (("/js/lop.js", tree["js"] / "lop.js"), ("/js/three-lop.js", tree["js"] / "three-lop.js"),
                      ("/js/viewer/viewer.js", tree["js"] / "viewer" / "viewer.js"),
                      ("/asset/scene.lop", tree["container"])):
        status, hdrs, body = get(server, url)
        assert status == 200 and body == path.read_bytes(), url
        assert hdrs["Cache-Control"] == "no-store" and hdrs["Accept-Ranges"] == "bytes"
    status, _, body = get(server, "/asset/scene.gltf")
    doc = json.loads(body)
    assert status == 200 and doc["extensions"]["LOPCOOK_lop_geometry"]["uri"] == "scene.lop"
    assert doc["extensions"]["LOPCOOK_lop_geometry"]["byteLength"] == tree["container"].stat().st_size
    info = json.loads(get(server, "/asset/info.json")[2])
    assert info["name"] == "sphere.lop" and info["bytes"] == tree["container"].stat().st_size
    assert get(server, "/js/lop.js", method="HEAD")[:2][0] == 200


@pytest.mark.parametrize("path", [
    "/../README.md", "/js/../../lopcook/__init__.py", "/js/viewer/../../../pyproject.toml", "/asset/../js/lop.js",
    "/js/%2e%2e/%2e%2e/pyproject.toml", "/%2e%2e/%2e%2e/etc/passwd", "/js%2f..%2f..%2fpyproject.toml",
    "/js/viewer/%2E%2E%2Fmain.js", "/js/lop.js%00", "/js/lop.js/", "/js/%ff", "/etc/passwd", "//etc/passwd",
    "///etc/passwd", "http://127.0.0.1/etc/passwd", "/js//lop.js", "/js/./lop.js", "/asset/secret.txt",
    "/asset/link.txt", "/asset/sphere.lop", "/js/viewer/leak.txt", "/js/viewer/linked/secret.txt",
    "/js/viewer/linked/", "/JS/LOP.JS", "/js/", "/asset/",
])
def test_any_other_path_is_404(server, path):
    status, _, body = get(server, path)
    assert status == 404, (path, status)
    assert b"secret" not in body


def test_absolute_paths_of_real_files_are_404(server, tree):
    for path in (str(tree["outside"] / "secret.txt"), str(tree["container"]), str(JS / "lop.js")):
        assert get(server, path)[0] == 404, path
        assert get(server, path.replace("/", "%2F"))[0] == 404, path


def test_ranges(server, tree):
    data = tree["container"].read_bytes()
    n = len(data)
    for header, (start, end) in (("bytes=0-9", (0, 10)), ("bytes=100-", (100, n)), ("bytes=-10", (n - 10, n)),
                                 (f"bytes=5-{n + 50}", (5, n)), (f"bytes={n - 1}-{n - 1}", (n - 1, n)),
                                 (f"bytes=-{n + 7}", (0, n))):
        status, hdrs, body = get(server, "/asset/scene.lop", {"Range": header})
        assert status == 206 and body == data[start:end], header
        assert hdrs["Content-Range"] == f"bytes {start}-{end - 1}/{n}" and int(hdrs["Content-Length"]) == end - start


@pytest.mark.parametrize("header", ["bytes={n}-", "bytes={n}-{n}", "bytes={big}-", "bytes=-0", "bytes=9-3",
                                    "bytes=0-1,4-5", "bytes=abc", "bytes=-", "items=0-3", "bytes=1e3-"])
def test_a_range_outside_the_file_or_malformed_is_416(server, tree, header):
    n = tree["container"].stat().st_size
    status, hdrs, body = get(server, "/asset/scene.lop", {"Range": header.format(n=n, big=10 * n)})
    assert status == 416 and body == b""
    assert hdrs["Content-Range"] == f"bytes */{n}"


def test_parse_range_against_rfc_examples():
    # RFC 9110 section 14.1.2 examples, on a 10000-byte representation
    assert parse_range("bytes=0-499", 10000) == (0, 500)
    assert parse_range("bytes=500-999", 10000) == (500, 1000)
    assert parse_range("bytes=-500", 10000) == (9500, 10000)
    assert parse_range("bytes=9500-", 10000) == (9500, 10000)
    assert parse_range("bytes=0-0", 10000) == (0, 1)
    assert parse_range("bytes=0-", 0) is None and parse_range("bytes=-1", 0) is None


def test_foreign_host_and_post_are_refused(server):
    assert get(server, "/", {"Host": f"evil.example:{server.port}"})[0] == 403
    assert get(server, "/", {"Host": "127.0.0.1:1"})[0] == 403
    assert get(server, "/", {"Host": f"localhost:{server.port}"})[0] == 200
    assert get(server, "/js/lop.js", {"Content-Length": "0"}, method="POST")[0] == 405
    assert get(server, "/asset/scene.lop?rate=fast")[0] == 400


def test_throttle_paces_the_container(server, tree):
    data = tree["container"].read_bytes()
    rate = max(2048, len(data) * 2)  # about half a second
    t0 = time.monotonic()
    status, _, body = get(server, f"/asset/scene.lop?rate={rate}")
    elapsed = time.monotonic() - t0
    chunk = max(512, rate // 20)
    assert status == 200 and body == data
    # the last chunk is not written before its time: a lower bound, whatever the machine's load
    assert elapsed >= ((len(data) - 1) // chunk) * chunk / rate - 0.01


def test_the_server_binds_loopback_only(server):
    with socket.socket() as s:
        s.settimeout(2)
        assert s.connect_ex(("127.0.0.1", server.port)) == 0
    addr = server._httpd.server_address
    assert addr[0] == "127.0.0.1"


def test_runtime_site_lists_no_symlink(tree):
    site = runtime_site(tree["js"])
    assert "/js/viewer/leak.txt" not in site.routes
    assert not [u for u in site.routes if "linked" in u]
    files = {p.relative_to(tree["js"]).as_posix() for p in tree["js"].rglob("*") if p.is_file() and not p.is_symlink()
             and not any(q.is_symlink() for q in p.relative_to(tree["js"]).parents if str(q) != ".")}
    assert {u[len("/js/"):] for u in site.routes if u.startswith("/js/")} == files


def test_vendored_three_files_are_the_release_files():
    sums = {}
    for line in (VENDOR / "SHA256SUMS").read_text().splitlines():
        digest, name = line.split(maxsplit=1)
        sums[name] = digest
    listed = {p.relative_to(VENDOR).as_posix() for p in VENDOR.rglob("*") if p.is_file()} - {"SHA256SUMS", "README.md"}
    assert set(sums) == listed
    for name, digest in sums.items():
        assert hashlib.sha256((VENDOR / name).read_bytes()).hexdigest() == digest, name
    tracked = subprocess.run(["git", "-C", str(REPO), "ls-files", str(VENDOR.relative_to(REPO))], capture_output=True,
                             text=True, check=True).stdout.split()
    assert {Path(t).relative_to(VENDOR.relative_to(REPO)).as_posix() for t in tracked} == set(sums) | {"SHA256SUMS",
                                                                                                    "README.md"}
    npm = REPO / ".ci" / "node" / "node_modules" / "three"
    if (npm / "package.json").is_file():
        assert json.loads((npm / "package.json").read_text())["version"] == "0.170.0"
        for name in sums:
            assert (npm / name).read_bytes() == (VENDOR / name).read_bytes(), name


def _lopcook(*args, **kw):
    return subprocess.Popen([sys.executable, "-m", "lopcook", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, **kw)


def test_cli_prints_the_url_serves_and_stops_on_ctrl_c(tmp_path):
    shutil.copy(CONTAINER, tmp_path / "sphere.lop")
    shutil.copy(REPO / "fixtures" / "unit_sphere.obj", tmp_path)  # its source: no warning
    proc = _lopcook("view", str(tmp_path / "sphere.lop"), "--json")
    try:
        line = proc.stdout.readline()
        out = json.loads(line)
        assert out["url"].startswith("http://127.0.0.1:") and out["bytes"] == CONTAINER.stat().st_size
        port = int(out["url"].rsplit(":", 1)[1].strip("/"))
        conn = http.client.HTTPConnection("127.0.0.1", port, timeout=30)
        conn.request("GET", "/asset/scene.lop")
        assert conn.getresponse().read() == CONTAINER.read_bytes()
        conn.close()
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=30)
        assert proc.returncode == 0, err
        assert err == ""
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


@pytest.mark.parametrize("args, words", [
    (["missing.lop"], "file not found"),
    (["{bad}"], "container"),
    (["{good}", "--port", "70000"], "outside [0, 65535]"),
    (["{good}", "--port", "{busy}"], "cannot listen"),
])
def test_cli_refuses_bad_input_with_one_line(tmp_path, args, words):
    shutil.copy(CONTAINER, tmp_path / "sphere.lop")
    (tmp_path / "bad.lop").write_bytes(CONTAINER.read_bytes()[:40])
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen(1)
        fill = {"bad": tmp_path / "bad.lop", "good": tmp_path / "sphere.lop", "busy": busy.getsockname()[1]}
        proc = _lopcook("view", *[a.format(**fill) for a in args], cwd=tmp_path)
        out, err = proc.communicate(timeout=60)
    assert proc.returncode == 2, (out, err)
    assert out == "" and len(err.strip().splitlines()) == 1 and words in err and "Traceback" not in err


def test_a_wheel_ships_every_runtime_file_the_viewer_serves():
    import fnmatch
    import tomllib

    files = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["data-files"]
    tracked = subprocess.run(["git", "-C", str(REPO), "ls-files", "runtime/js"], capture_output=True, text=True,
                             check=True).stdout.split()
    for path in tracked:
        dest = [d for d, globs in files.items() if any(fnmatch.fnmatch(path, g) and Path(g).parent == Path(path).parent
                                                       for g in globs)]
        assert dest == ["share/lopcook/" + str(Path(path).parent)], path
