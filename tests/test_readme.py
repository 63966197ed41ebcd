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
