"""The simplifier binding runs on any x86-64 CPU (``lopcook.simplify.meshopt.library_path``).

docs/lod.md, "The simplifier binding": the one PyPI binding of meshoptimizer >= 0.25 (almeshopt
0.1.12) ships wheels built for AVX2 and FMA alone; under ``qemu-x86_64 -cpu Westmere`` or
``SandyBridge`` importing it dies of SIGILL, a crash no ``except`` catches. lopcook keeps the pinned
binding, whose library has no VEX or EVEX instruction. The check is shown to catch such code on a
library compiled here with ``-mavx2 -mfma``, and to pass the same source compiled for baseline
x86-64. (A library that picks AVX2 code at run time after a CPUID check would need the check to
learn that guard.)"""

from __future__ import annotations

import platform
import re
import shutil
import subprocess

import pytest

from conftest import require
from lopcook.simplify.meshopt import library_path

#: instructions baseline x86-64 lacks: anything on the 256/512-bit registers or with a VEX/EVEX
#: encoding (AVX, AVX2, FMA, AVX-512): their mnemonics start with "v" and they name xmm/ymm/zmm
#: registers, or they are FMA
_WIDE = re.compile(r"\t(v[a-z0-9]+)\s+[^\n]*%[xyz]mm|%[yz]mm\d|\tvfn?m(add|sub)")


def wide_instructions(path: str) -> int:
    """How many instructions of the shared library ``path`` need AVX or later (objdump -d)."""
    out = subprocess.run(["objdump", "-d", "--no-show-raw-insn", path], capture_output=True, text=True,
                         check=True).stdout
    return sum(1 for line in out.splitlines() if _WIDE.search(line))


pytestmark = pytest.mark.skipif(platform.machine() not in ("x86_64", "AMD64"), reason="x86-64 instruction check")


def _tools():
    require(None if shutil.which("objdump") else "objdump (binutils) not found")
    require(None if shutil.which("cc") else "a C compiler (cc) not found")


def test_the_simplifier_library_needs_no_avx(tmp_path):
    _tools()
    assert wide_instructions(library_path()) == 0


def test_the_check_finds_avx2_code(tmp_path):
    """The same source compiled for AVX2 and FMA, and for baseline x86-64."""
    _tools()
    src = tmp_path / "dot.c"
    src.write_text("float dot(const float *a, const float *b, int n) {\n"
                   "    float s = 0.0f;\n"
                   "    for (int i = 0; i < n; ++i) s += a[i] * b[i];\n"
                   "    return s;\n}\n"
                   "void axpy(float *y, const float *x, float k, int n) {\n"
                   "    for (int i = 0; i < n; ++i) y[i] = k * x[i] + y[i];\n}\n")
    libs = {}
    for name, flags in (("wide", ["-mavx2", "-mfma"]), ("base", [])):
        libs[name] = tmp_path / f"lib{name}.so"
        subprocess.run(["cc", "-O3", "-ffast-math", "-shared", "-fPIC", *flags, str(src), "-o", str(libs[name])],
                       check=True)
    assert wide_instructions(str(libs["wide"])) > 0
    assert wide_instructions(str(libs["base"])) == 0
