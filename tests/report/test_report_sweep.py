"""Every command that reads a container (inspect, decode, verify, report) over every kind of cook
(default, ``--lods auto``, ``--target-psnr``, ``--target-bytes``, ``--hierarchy``, ``--nearest``),
each with its default options, and the report of the calibrated and byte-budget containers of the
corpus assets.

The sweep uses the smallest corpus asset, the Utah teapot (2,472 triangles): a calibrated cook
renders dozens of probes (about 30 s for the teapot, 20 to 90 s for the others on 2 cores), and the
point is that each command runs on each kind of file and gives a sound verdict: ``verify --source``
and ``report`` render with the same small harness (2 views at 320x180) and must agree, PSNR for
PSNR, and report exit 1 exactly when its verdict is FAIL. Containers are cooked once per session
(``cooked``). The per-asset test reports the calibrated and ``--target-bytes 1/6`` containers of
every corpus asset; all but the three smallest are marked ``slow`` (they run in CI too, and can be
left out locally with ``-m "not slow"``)."""

from __future__ import annotations

import json

import pytest

from conftest import REPO, corpus_path
from lopcook.cli import main

#: the kinds of cook the sweep covers: name -> cook flags
COOKS = {"default": (), "lods-auto": ("--lods", "auto"), "target-psnr": ("--target-psnr", "40"),
         "target-bytes": ("--target-bytes", "1/6"), "hierarchy": ("--hierarchy",), "nearest": ("--nearest", "0.5")}
HARNESS = ["--views", "2", "--resolution", "320x180"]
ASSET = "UtahTeapot.usd"
#: the smallest corpus assets (calibrated cook under a minute on 2 cores): not ``slow``
SMALL = ("UtahTeapot.usd", "spot.obj", "CesiumMilkTruck.glb")


def _schema() -> dict:
    return json.loads((REPO / "schema" / "report.schema.json").read_text())


def _check_report(rep: dict, rc: int, available: int) -> None:
    """A sound report: valid JSON, the default levels the file holds, exit 1 exactly on FAIL."""
    import jsonschema

    from lopcook.settings import DEFAULTS

    jsonschema.validate(rep, _schema(), cls=jsonschema.Draft202012Validator)
    wanted = [b for b in DEFAULTS.render.levels if b <= available] or [available]
    assert [r["level"] for r in rep["levels"]] == wanted
    assert rc == (1 if rep["verdict"]["result"] == "FAIL" else 0)


@pytest.mark.parametrize("kind", list(COOKS))
def test_every_command_on_every_kind_of_cook(corpus, gl, cooked, tmp_path, capsys, kind):
    from lopcook.lop.container import read

    src = corpus / ASSET
    lop = cooked(src, *COOKS[kind])
    available = read(lop).available_level
    # inspect: text and JSON
    assert main(["inspect", str(lop)]) == 0
    capsys.readouterr()
    assert main(["inspect", str(lop), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)
    # decode the finest level the file holds
    glb = tmp_path / "preview.glb"
    assert main(["-q", "decode", str(lop), "--level", str(available), "-o", str(glb)]) == 0
    assert glb.stat().st_size > 0
    # verify: the decoders at every level the file holds, the render check at its default levels
    rc_verify = main(["verify", str(lop), "--decoders", "--source", str(src), *HARNESS, "--json"])
    ver = json.loads(capsys.readouterr().out)
    assert ver["decoders"]["ok"] and rc_verify == (0 if ver["ok"] else 1)
    # report with its default options (and the small harness)
    out = tmp_path / "report.html"
    rc = main(["-q", "report", str(lop), "--source", str(src), "-o", str(out), *HARNESS])
    capsys.readouterr()
    rep = json.loads(out.with_suffix(".json").read_text())
    _check_report(rep, rc, available)
    # the same verdict as verify's render check, PSNR for PSNR
    assert [r["level"] for r in ver["render"]["levels"]] == [r["level"] for r in rep["levels"]]
    for a, b in zip(ver["render"]["levels"], rep["levels"]):
        assert a["cap"]["psnr_views"] == b["cap"]["psnr_views"]
    assert ver["render"]["ok"] is (rep["verdict"]["result"] == "PASS")
    if kind == "target-bytes":
        assert available < max(_default_levels())  # the case that was a usage error
    if kind == "target-psnr":
        assert rep["calibration"] and 'aria-label="k_f calibration: memory vs PSNR"' in out.read_text()


def _default_levels():
    from lopcook.settings import DEFAULTS

    return DEFAULTS.render.levels


def _assets() -> list:
    path = corpus_path()
    if path is None:
        return ["corpus-missing"]
    names = [a["file"] for a in json.loads((path / "corpus.json").read_text())["assets"]]
    return [n if n in SMALL else pytest.param(n, marks=pytest.mark.slow) for n in names]


@pytest.mark.parametrize("asset", _assets())
@pytest.mark.parametrize("kind", ["target-psnr", "target-bytes"])
def test_calibrated_and_budget_containers_of_every_asset(corpus, gl, cooked, tmp_path, asset, kind):
    """``report`` of the calibrated (``--target-psnr 40``) and ``--target-bytes 1/6`` containers
    with its default options: a page and a valid report.json, the levels the file holds, exit 0 on
    PASS and 1 on FAIL (never 2 or 3). A byte budget of 1/6 of float32 is far below 40 dB for most
    assets: FAIL is the sound verdict there."""
    from lopcook.lop.container import read

    src = corpus / asset
    lop = cooked(src, *COOKS[kind])
    out = tmp_path / "report.html"
    rc = main(["-q", "report", str(lop), "--source", str(src), "-o", str(out), *HARNESS])
    rep = json.loads(out.with_suffix(".json").read_text())
    _check_report(rep, rc, read(lop).available_level)
    assert out.stat().st_size > 0 and rep["verdict"]["worst"] is not None
