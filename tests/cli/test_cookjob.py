"""lopcook.cookjob: the one cook that ``lopcook cook`` and every batch worker run writes the CLI's
bytes and depfile, reports warnings through ``warn``, and under ``strict`` refuses on the first
warning without writing anything."""

from __future__ import annotations

import json

import pytest

from conftest import FIXTURES
from lopcook.cli import main
from lopcook.cookjob import CookOutputs, cook_file
from lopcook.errors import LopcookError
from lopcook.settings import DEFAULTS


def test_cook_file_writes_what_lopcook_cook_writes(tmp_path, capsys):
    src = str(FIXTURES / "two_plates.gltf")
    assert main(["cook", src, "-o", str(tmp_path / "cli.lop"), "--depfile", str(tmp_path / "cli.d"), "--json"]) == 0
    cli_summary = json.loads(capsys.readouterr().out)
    warned = []
    summary, result = cook_file(src, DEFAULTS, CookOutputs(str(tmp_path / "job.lop"), str(tmp_path / "job.d")),
                                warn=warned.append)
    assert (tmp_path / "job.lop").read_bytes() == (tmp_path / "cli.lop").read_bytes()
    deps = (tmp_path / "job.d").read_text()
    assert deps.replace("job.lop", "cli.lop") == (tmp_path / "cli.d").read_text() and "two_plates.bin" in deps
    assert set(summary) == set(cli_summary) and summary["file_bytes"] == cli_summary["file_bytes"]
    assert result.analysis is not None and warned == []


def test_a_warning_is_reported_and_strict_refuses_it(tmp_path):
    src = str(FIXTURES / "two_plates.obj")
    warned = []
    cook_file(src, DEFAULTS, CookOutputs(str(tmp_path / "out.x")), warn=warned.append)
    assert warned == [[f"{tmp_path / 'out.x'}: a .lop container is written to a file not named .lop"]]
    with pytest.raises(LopcookError, match="not named .lop .*--strict treats every warning as an error") as exc:
        cook_file(src, DEFAULTS, CookOutputs(str(tmp_path / "strict.x"), str(tmp_path / "strict.d"), strict=True))
    assert exc.value.exit_code == 2
    assert exc.value.stage == "output" and not str(exc.value).startswith("usage")  # a warning, not a usage error
    assert not (tmp_path / "strict.x").exists() and not (tmp_path / "strict.d").exists()
