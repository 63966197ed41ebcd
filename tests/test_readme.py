"""The README quick start is exactly two commands, and CI runs the second one verbatim."""

import re

from conftest import REPO


def quick_start_commands():
    text = (REPO / "README.md").read_text()
    section = text.split("## Quick start", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```sh\n(.*?)\n```", section, flags=re.S)


def test_two_commands_and_ci_runs_the_test_command():
    cmds = quick_start_commands()
    assert len(cmds) == 2 and all("\n" not in c for c in cmds)
    assert "lopcook" in cmds[0] and "fixtures/" in cmds[0]
    assert "pytest" in cmds[1] and "[test]" in cmds[1]
    ci = (REPO / ".ci" / "run").read_text()
    assert cmds[1] in ci.splitlines()
    assert "CI=true" in ci


def test_quick_start_fixture_exists():
    cmd = quick_start_commands()[0]
    fixture = re.search(r"(fixtures/\S+)", cmd).group(1)
    assert (REPO / fixture).is_file()


def api_snippet() -> str:
    text = (REPO / "README.md").read_text()
    section = text.split("## Python API", 1)[1].split("\n## ", 1)[0]
    (code,) = re.findall(r"```python\n(.*?)\n```", section, flags=re.S)
    return code


def test_api_snippet_writes_the_cli_bytes(tmp_path, monkeypatch):
    """The README's Python snippet runs as written and gives exactly `lopcook cook`'s bytes."""
    import shutil

    from lopcook.cli import main

    (tmp_path / "fixtures").mkdir()
    shutil.copy(REPO / "fixtures" / "two_plates.glb", tmp_path / "fixtures")
    monkeypatch.chdir(tmp_path)
    exec(compile(api_snippet(), "README.md", "exec"), {})
    assert main(["-q", "cook", "fixtures/two_plates.glb", "-o", "cli.lop"]) == 0
    assert (tmp_path / "two_plates.lop").read_bytes() == (tmp_path / "cli.lop").read_bytes()
