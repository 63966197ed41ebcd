"""README.md: the quick start is exactly two commands and CI runs the second one verbatim; the
Python snippet writes the CLI's bytes; the page stays short, dateless and self-explaining (every
glossary term defined, short command-table cells, links that resolve, a picture its script makes)."""

import importlib.util
import re

import numpy as np
import pytest
from PIL import Image

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


# ---- a README a newcomer reads ------------------------------------------------------------------

#: terms the glossary must define (first cell of a row of its table)
GLOSSARY_TERMS = ("level", "per-buffer level", "minimum level", "AP", "CAP", "E_v", "k_f", "eps", "LOD",
                  "cluster", "placement", "prefix", "buffer", "plane", "mandatory bits", "bin", "grid", "part",
                  "PSNR")
#: a date, written as digits or with a month's name, or a time of day a run log would give
DATE = re.compile(r"\b\d{4}-\d{2}-\d{2}\b|\b\d{1,2}/\d{1,2}/\d{4}\b"
                  r"|\b(jan|feb|mar|apr|may|jun|jul|aug|sep|oct|nov|dec)[a-z]*\.? \d{1,2}(st|nd|rd|th)?,? \d{4}\b"
                  r"|\b\d{1,2} (jan|feb|mar|apr|may|jun|jul|aug|sep|oct|nov|dec)[a-z]* \d{4}\b"
                  r"|\b(this|last|yesterday) (morning|afternoon|evening|night|session|week)\b|\b(yesterday|tonight)\b",
                  flags=re.I)
#: files the runtimes of this round add; their links are checked once runtime/ exists
RUNTIME_LINKS = {"runtime/c/lop.h", "runtime/js/lop.js", "runtime/js/three-lop.js", "docs/runtime-c.md",
                 "docs/runtime-js.md"}


def readme() -> str:
    return (REPO / "README.md").read_text()


def section(title: str) -> str:
    return readme().split(f"\n## {title}\n", 1)[1].split("\n## ", 1)[0]


def table_rows(text: str) -> list[list[str]]:
    """The rows of the first markdown table in ``text`` (header included, separator row left out),
    each as its cells, stripped; ``\\|`` inside a cell is a literal bar."""
    rows = []
    for line in text.splitlines():
        if not line.startswith("|"):
            if rows:
                break
            continue
        cells = [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", line.strip())[1:-1]]
        if not all(re.fullmatch(r":?-+:?", c) for c in cells):
            rows.append(cells)
    return rows


def test_table_rows_parse_escaped_bars():
    text = "x\n| a | b |\n|---|---:|\n| `p\\|q` | c |\n\nafter\n| z |\n"
    assert table_rows(text) == [["a", "b"], ["`p|q`", "c"]]


def test_readme_is_short():
    assert len(readme().splitlines()) <= 150


def test_readme_carries_no_date():
    hits = [m.group(0) for m in DATE.finditer(readme())]
    assert not hits, f"README.md names dates or run times: {hits}"


def test_date_pattern_catches_a_run_log():
    for text in ("measured on 2026-12-05", "Dec 5, 2026", "5 December 2026", "this morning's run", "12/05/2026"):
        assert DATE.search(text), text
    assert not DATE.search("--lods 1/2,1/4 at levels 6..11, commit 46c796a, 1,112 s")


def test_commands_table_cells_are_short():
    rows = table_rows(section("Commands"))
    assert len(rows) > 10 and rows[0] == ["command", "what it does"]
    long = [c for row in rows for c in row if len(c) > 200]
    assert not long, f"commands-table cells over 200 characters: {long}"


def test_every_command_is_in_the_table(capsys):
    """Every command ``lopcook --help`` lists has a row."""
    from lopcook.cli import main

    with pytest.raises(SystemExit):
        main(["--help"])
    listing = capsys.readouterr().out.split("positional arguments:", 1)[1].split("options:", 1)[0]
    commands = re.findall(r"^ {4}([a-z]+)\b", listing, flags=re.M)
    table = " ".join(row[0] for row in table_rows(section("Commands")))
    assert len(commands) >= 10
    missing = [c for c in commands if f"lopcook {c} " not in table]
    assert not missing, f"commands without a row in README.md: {missing}"


def test_glossary_defines_every_term():
    rows = table_rows(section("Glossary"))
    assert rows[0] == ["term", "meaning"]
    defined = {row[0]: row[1] for row in rows[1:]}
    missing = [t for t in GLOSSARY_TERMS if not defined.get(t)]
    assert not missing, f"glossary terms without a definition: {missing}"


def markdown_links(path) -> list[str]:
    """Relative link targets of a markdown file (no URL, no pure #anchor), anchors cut off."""
    text = path.read_text()
    out = []
    for target in re.findall(r"\]\(([^)\s]+)\)", text):
        if re.match(r"[a-z]+:", target) or target.startswith("#"):
            continue
        out.append(target.split("#", 1)[0])
    return out


def test_links_resolve():
    """Every relative link of README.md and docs/ (history included) names a file or folder that
    exists; the runtimes' files are held to it once runtime/ exists."""
    pending = set() if (REPO / "runtime").is_dir() else RUNTIME_LINKS
    bad = []
    for md in [REPO / "README.md", *sorted((REPO / "docs").rglob("*.md"))]:
        for target in markdown_links(md):
            resolved = (md.parent / target).resolve()
            if not resolved.exists() and resolved.relative_to(REPO).as_posix() not in pending:
                bad.append(f"{md.relative_to(REPO)}: {target}")
    assert not bad, f"links to nothing: {bad}"


def make_images():
    """docs/make_images.py as a module (docs/ is no package)."""
    spec = importlib.util.spec_from_file_location("make_images", REPO / "docs" / "make_images.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_readme_picture_is_made_by_the_script():
    """The first picture is the level picture docs/make_images.py draws; the others (the streaming
    bench's chart) exist."""
    target, *others = re.findall(r"!\[[^]]*\]\((docs/img/[^)]+\.png)\)", readme())
    mod = make_images()
    assert mod.DEFAULT_OUT == REPO / target and (REPO / target).is_file()
    assert all((REPO / t).is_file() for t in others)


def test_level_picture_is_deterministic(gl, tmp_path):
    """docs/make_images.py on a fixture, twice: the same PNG bytes, and a legend with one swatch per
    level from the lowest minimum level to the highest."""
    mod = make_images()
    outs = []
    for i in range(2):
        out = tmp_path / f"levels{i}.png"
        assert mod.main([str(REPO / "fixtures" / "glossy_crease.glb"), "-o", str(out), "--resolution", "320x240"]) == 0
        outs.append(out.read_bytes())
    assert outs[0] == outs[1]
    rgba, hist = mod.level_render(REPO / "fixtures" / "glossy_crease.glb", mod.DEFAULT_VIEW, (320, 240))
    assert rgba.shape[2] == 4 and (rgba[..., 3] > 0).any()
    page = np.asarray(Image.open(tmp_path / "levels0.png").convert("RGB"))
    present = [b for b, c in enumerate(hist) if c and b > 0]
    y = rgba.shape[0] + mod.GAP_PX + mod.SWATCH_PX // 2
    swatches = {tuple(int(v) for v in page[y, x]) for x in range(page.shape[1])}
    assert len(present) > 2 and len(swatches) == present[-1] - present[0] + 1
