"""Regenerate the golden containers in ``fixtures/golden/`` on purpose.

``fixtures/golden/SHA256SUMS`` is both the record and the recipe: a line
``# NAME.lop: lopcook cook ARGS... -o NAME.lop`` names each golden file and the exact command
that cooks it (run from the repository root; ``-o`` names the file inside ``fixtures/golden/``),
and a line ``SHA256  NAME.lop`` (``sha256sum`` format) pins its bytes. ``tests/lop/test_golden.py``
checks both. To change a golden file -- a deliberate format or algorithm change -- run::

    python tests/golden_update.py            # re-cook every golden file, rewrite the sha256 lines
    python tests/golden_update.py --check    # re-cook into a temporary folder, report differences

The cook is ``lopcook.cli.main`` of whichever ``lopcook`` is imported (``PYTHONPATH`` chooses the
tree). To add a golden file, add its ``# NAME.lop: lopcook cook ...`` line and run the update.
"""

from __future__ import annotations

import contextlib
import hashlib
import re
import shlex
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
GOLDEN = REPO / "fixtures" / "golden"
SUMS = GOLDEN / "SHA256SUMS"

_COMMAND = re.compile(r"^# (?P<name>[\w.-]+\.lop): lopcook (?P<args>cook .*)$")
_HASH = re.compile(r"^(?P<sha>[0-9a-f]{64})  (?P<name>[\w.-]+\.lop)$")


@dataclass(frozen=True)
class Golden:
    """One golden container: file name in ``fixtures/golden/``, the ``lopcook`` argv that cooks it
    (``-o`` value = ``name``), and its pinned sha256 (None before the first update)."""

    name: str
    argv: tuple[str, ...]
    sha256: str | None

    @property
    def source(self) -> Path:
        """The source file the command cooks (the first argument after ``cook``)."""
        return REPO / self.argv[1]


def sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def entries(text: str | None = None) -> list[Golden]:
    """The golden files listed in SHA256SUMS, in file order. Raises ValueError on a line that is
    neither a comment nor a hash line, a hash without a command, or a command whose ``-o`` is not
    the file's own name."""
    text = SUMS.read_text() if text is None else text
    commands: dict[str, tuple[str, ...]] = {}
    hashes: dict[str, str] = {}
    for n, line in enumerate(text.splitlines(), start=1):
        if m := _COMMAND.match(line):
            argv = tuple(shlex.split(m["args"]))
            if "-o" not in argv or argv.index("-o") + 1 >= len(argv) or argv[argv.index("-o") + 1] != m["name"]:
                raise ValueError(f"SHA256SUMS line {n}: the command must write -o {m['name']}")
            commands[m["name"]] = argv
        elif m := _HASH.match(line):
            hashes[m["name"]] = m["sha"]
        elif line.strip() and not line.startswith("#"):
            raise ValueError(f"SHA256SUMS line {n} is neither a comment nor 'SHA256  NAME.lop': {line!r}")
    unknown = sorted(set(hashes) - set(commands))
    if unknown:
        raise ValueError(f"SHA256SUMS pins {unknown} without a '# NAME.lop: lopcook cook ...' line")
    return [Golden(name, argv, hashes.get(name)) for name, argv in commands.items()]


def cook(golden: Golden, folder: Path) -> Path:
    """Run the recorded command writing into ``folder``; the path. The cook runs in a mirror of
    the repository's ``fixtures/`` (a symlink per file) under ``folder``, writing
    ``fixtures/golden/NAME.lop`` there: the manifest records the source's path relative to the
    container's folder (``../two_plates.glb``), so the pinned bytes are those of a cook into
    ``fixtures/golden/`` itself, wherever ``folder`` is."""
    from lopcook.cli import main

    tree = Path(folder) / "tree"
    (tree / "fixtures" / "golden").mkdir(parents=True, exist_ok=True)
    for f in sorted((REPO / "fixtures").iterdir()):
        if f.is_file() and not (tree / "fixtures" / f.name).exists():
            (tree / "fixtures" / f.name).symlink_to(f)
    argv = list(golden.argv)
    argv[argv.index("-o") + 1] = f"fixtures/golden/{golden.name}"
    with contextlib.chdir(tree):
        rc = main(argv + ["-q"])
    if rc != 0:
        raise RuntimeError(f"lopcook {shlex.join(golden.argv)} exited {rc}")
    return tree / "fixtures" / "golden" / golden.name


def render_sums(text: str, goldens: list[Golden]) -> str:
    """SHA256SUMS text with the hash lines replaced by ``goldens``' (comments kept, hashes last)."""
    keep = [line for line in text.splitlines() if not _HASH.match(line)]
    while keep and not keep[-1].strip():
        keep.pop()
    return "\n".join(keep + [""] + [f"{g.sha256}  {g.name}" for g in goldens]) + "\n"


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    check = "--check" in args
    text = SUMS.read_text()
    goldens = entries(text)
    with tempfile.TemporaryDirectory() as tmp:
        fresh = [Golden(g.name, g.argv, sha256(cook(g, Path(tmp)))) for g in goldens]
        changed = [f.name for g, f in zip(goldens, fresh) if g.sha256 != f.sha256]
        if check:
            for name in changed:
                print(f"{name}: differs from its pinned sha256")
            return 1 if changed else 0
        for g in fresh:
            (GOLDEN / g.name).write_bytes((Path(tmp) / "tree" / "fixtures" / "golden" / g.name).read_bytes())
    SUMS.write_text(render_sums(text, fresh))
    listed = {g.name for g in fresh}
    for stale in sorted(p.name for p in GOLDEN.glob("*.lop") if p.name not in listed):
        print(f"{stale}: not listed in SHA256SUMS (remove it or add its command)")
    print(f"{len(fresh)} golden files, {len(changed)} changed: {', '.join(changed) or 'none'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
