"""Compare two folders of containers file by file (``benchmarks/cook_hashes.sh`` writes them): each
file is ``identical`` (the same bytes), ``same but KEYS`` (every section's payload the same and the
manifests equal once the named informative keys are set aside: a change that only records
something new), or ``differs`` (the sections and manifest keys that differ). Not a test.

    benchmarks/cook_hashes.sh /tmp/hashes-new
    python benchmarks/cook_diff.py /work/hashes-base /tmp/hashes-new [--ignore source.path,options.lods]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from lopcook.lop.container import read  # noqa: E402


def _flat(d, prefix=""):
    """{dotted key: value} of a manifest (lists kept whole)."""
    out = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(_flat(v, key + "."))
        else:
            out[key] = v
    return out


def compare(a: Path, b: Path, ignore: tuple[str, ...]) -> str:
    if a.read_bytes() == b.read_bytes():
        return "identical"
    ca, cb = read(str(a)), read(str(b))
    sections = sorted(n for n in set(ca.sections) | set(cb.sections) if ca.sections.get(n) != cb.sections.get(n))
    fa, fb = _flat(ca.manifest), _flat(cb.manifest)
    keys = sorted(k for k in set(fa) | set(fb) if fa.get(k) != fb.get(k) and k != "sections")
    counted = [k for k in keys if not any(k == i or k.startswith(i + ".") for i in ignore)]
    if not sections and not counted:
        return "same but " + ",".join(sorted({next(i for i in ignore if k == i or k.startswith(i + "."))
                                              for k in keys})) if keys else "same sections and manifest"
    return f"differs: sections {sections or '-'}; manifest {counted or '-'}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("base", type=Path)
    ap.add_argument("new", type=Path)
    ap.add_argument("--ignore", default="source.path", help="informative manifest keys to set aside, comma-separated")
    opts = ap.parse_args(argv)
    ignore = tuple(k for k in opts.ignore.split(",") if k)
    names = sorted(p.name for p in opts.base.glob("*.lop"))
    counts: dict[str, int] = {}
    for name in names:
        other = opts.new / name
        verdict = compare(opts.base / name, other, ignore) if other.exists() else "missing"
        counts[verdict.split(":")[0]] = counts.get(verdict.split(":")[0], 0) + 1
        print(f"{name:45s} {verdict}")
    print("; ".join(f"{v}: {n}" for v, n in sorted(counts.items())))
    return 0


if __name__ == "__main__":
    sys.exit(main())
