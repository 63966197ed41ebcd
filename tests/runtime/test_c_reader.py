"""runtime/c/lop.h, the C reference reader: it builds without a warning under gcc and clang
(-std=c99 -Wall -Wextra -Wpedantic -Werror, and as C++11), needs nothing but the C library, passes
the conformance set (every verdict, error class, available level and decoded byte), stays
bit-exact when the compiler may fuse multiply-adds, and under AddressSanitizer and
UndefinedBehaviorSanitizer survives every single-byte flip and every truncation of the conformance
files (the streaming layout, encoded sections and tangents of container 4.0 among them), every
allocation failure and every .lop of the hostile-input corpus, with lopcook's verdict on each;
libFuzzer runs 60 s clean. Tangents (format 4.0) decode as docs/format.md 7.6 defines them."""

from __future__ import annotations

import copy
import json
import struct
import subprocess
import zlib

import numpy as np
import pytest

from c_tools import c_build  # noqa: F401  (the session's build, a pytest fixture)
from c_tools import (CONFORMANCE, RUNTIME, conformance, expected_of, lopcheck, lopdump, make, sha, tool, verdict,
                     want_verdict)

from lopcook.lop.codecs.normals_oct import decode_normals
from tests.support import fuzzcases
from lopcook.lop.container import manifest_bytes, manifest_of
from lopcook.lop.layout import is_stream, layout_of

COMPILERS = ("gcc", "clang")
#: the C library functions lop.h may call (and nothing else: no libm, no I/O)
LIBC = {"free", "malloc", "memcmp", "memcpy", "memset", "snprintf", "strlen", "strncmp", "vsnprintf"}


def _compile(cc: str, src: str, out, *flags) -> subprocess.CompletedProcess:
    return subprocess.run([tool(cc), *flags, "-I", str(RUNTIME), "-x", "c++" if cc.endswith("++") else "c", "-",
                           "-o", str(out)], input=src, capture_output=True, text=True, timeout=300)


# ---- building ---------------------------------------------------------------------------------

def test_the_makefile_builds_strict_and_sanitized_with_both_compilers(c_build):
    for build in ("gcc", "clang", "gcc-san", "clang-san"):
        for program in ("lopdump", "lopcheck"):
            assert (c_build / build / program).is_file(), f"{build}/{program}"


@pytest.mark.parametrize("cc,flags", [("gcc", ("-std=c99", "-O0")), ("gcc", ("-std=c99", "-O3")),
                                      ("clang", ("-std=c99", "-O0")), ("clang", ("-std=c99", "-Os")),
                                      ("gcc", ("-std=c99", "-O2", "-DLOP_STATIC")),
                                      ("clang", ("-std=c11", "-O2", "-DLOP_STATIC")),
                                      ("g++", ("-std=c++11", "-O2")), ("clang++", ("-std=c++11", "-O2"))])
def test_the_header_compiles_without_a_warning(tmp_path, cc, flags):
    src = '#define LOP_IMPLEMENTATION\n#include "lop.h"\n#include "lop.h"\nint main(void) { lop_file *f = 0; ' \
          'return (int)lop_open(0, 0, 0, &f, 0) == 0; }\n'
    run = _compile(cc, src, tmp_path / "a.out", *flags, "-Wall", "-Wextra", "-Wpedantic", "-Werror")
    assert run.returncode == 0, run.stderr


def test_declarations_and_implementation_link_across_files(tmp_path):
    (tmp_path / "impl.c").write_text('#define LOP_IMPLEMENTATION\n#include "lop.h"\n')
    (tmp_path / "use.c").write_text('#include "lop.h"\nint main(void) { return lop_result_name(lop_error_version)[0] '
                                    "!= 'v'; }\n")
    run = subprocess.run([tool("gcc"), "-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Werror", "-I", str(RUNTIME),
                          str(tmp_path / "impl.c"), str(tmp_path / "use.c"), "-o", str(tmp_path / "a.out")],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert subprocess.run([str(tmp_path / "a.out")]).returncode == 0


def test_the_reader_needs_only_the_c_library(tmp_path):
    run = _compile("gcc", '#define LOP_IMPLEMENTATION\n#include "lop.h"\n', tmp_path / "lop.o", "-std=c99", "-O2",
                   "-c")
    assert run.returncode == 0, run.stderr
    nm = subprocess.run([tool("nm"), "-u", str(tmp_path / "lop.o")], capture_output=True, text=True, check=True)
    used = {line.split()[-1] for line in nm.stdout.splitlines() if line.strip()}
    assert used <= LIBC, f"lop.h calls {sorted(used - LIBC)} beyond the C library"


# ---- the conformance set ---------------------------------------------------------------------

def check_conformance(exe, tmp_path, files=None) -> None:
    """Every file of the set through lopdump: whole-file and prefix verdicts (the error class, or the
    available level and each stage's level), and the sha256 of the positions, gpu and attributes
    dumps at every level and LOD the index lists."""
    index = conformance()
    out = {k: tmp_path / f"dump.{k}" for k in ("positions", "gpu", "attributes")}
    for e in index["files"]:
        if files is not None and e["file"] not in files:
            continue
        path = CONFORMANCE / e["file"]
        assert sha(path) == e["sha256"], e["file"]
        for prefix, want in ((False, e), (True, e.get("prefix", e))):
            run = lopdump(exe, path, "--level", "1", "--json", *(["--prefix"] if prefix else []))
            if "error" not in want:
                assert run.returncode == 0, (e["file"], prefix, run.stderr)
                got = json.loads(run.stdout)
                stages = [s["available"] for s in got["stages"]]
                assert want_verdict(want) == f"ok:{got['available_level']}" + (
                    "/" + ",".join(map(str, stages)) if got["stream"] else ""), (e["file"], prefix)
            else:
                assert run.returncode == 2 and f": {want['error']}: " in run.stderr and run.stderr.count("\n") == 1, \
                    (e["file"], prefix, want, run.stderr)
        for lod in expected_of(index, e) or ():
            for level, hashes in lod["levels"].items():
                run = lopdump(exe, path, "--prefix", "--level", level, "--lod", lod["lod"],
                              *[x for k, f in out.items() for x in (f"--{k}", f)])
                assert run.returncode == 0, run.stderr
                assert {k: sha(out[k]) for k in hashes} == hashes, (e["file"], lod["lod"], level)
                assert sha(out["attributes"]) == lod["attributes"], (e["file"], lod["lod"])


@pytest.mark.parametrize("cc", COMPILERS)
def test_the_conformance_set(c_build, tmp_path, cc):
    check_conformance(c_build / cc / "lopdump", tmp_path)


@pytest.mark.parametrize("cc", COMPILERS)
def test_bit_exact_when_the_compiler_may_fuse_multiply_adds(tmp_path, cc):
    """-O3 -march=native -ffp-contract=fast: the float decodes (positions, placements, UVs) keep
    their separate roundings."""
    exe = tmp_path / "lopdump"
    run = subprocess.run([tool(cc), "-std=c99", "-O3", "-march=native", "-ffp-contract=fast",
                          str(RUNTIME / "examples" / "lopdump.c"), "-o", str(exe)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    check_conformance(exe, tmp_path, {"placements.lop", "placements_clustered.lop", "attributes_narrow.lop",
                                      "attributes_wide.lop", "plates_v2.lop", "stream_wedges.lop",
                                      "stream_tangents.lop", "tangents_wide.lop"})


def test_lopdump_refuses_bad_requests_with_one_line_and_no_output(c_build, tmp_path):
    exe = c_build / "gcc" / "lopdump"
    out = tmp_path / "p.f32"
    for args, fragment in ((("--level", "25"), "[1, 24]"), (("--level", "0"), "[1, 24]"),
                           (("--level", "12", "--lod", "3"), "no part has LOD 3"),
                           (("--level", "20", "--prefix"), "not in this file")):
        path = CONFORMANCE / ("prefix_plates_mandatory.lop" if "--prefix" in args else "tetra.lop")
        run = lopdump(exe, path, *args, "--positions", out)
        assert run.returncode == 2 and fragment in run.stderr and run.stderr.count("\n") == 1, run.stderr
        assert not out.exists() and not list(tmp_path.iterdir())
    run = lopdump(exe, tmp_path / "missing.lop", "--level", "3")
    assert run.returncode == 2 and run.stderr.count("\n") == 1


# ---- hostile input under the sanitizers --------------------------------------------------------

def _regions(data: bytes) -> tuple[int, int]:
    return 32, 32 + struct.unpack_from("<I", data, 12)[0]


def _flip_class(data: bytes, at: int) -> str:
    """The class a single-byte flip of a valid complete file gets: the first check that reads it."""
    header, manifest = _regions(data)
    return "bad_magic" if at < 4 else "header_crc" if at < header else "manifest_crc" if at < manifest \
        else "section_crc"


def _prefix_verdict(data: bytes, cut: int) -> str:
    """lopcook's prefix verdict on data[:cut] of a valid file, from its section table (sections 8 and
    14.4: the complete sections, each stage's level from them)."""
    if cut < 32 or cut < _regions(data)[1]:
        return "truncated"
    m = manifest_of(data)
    base, present = _regions(data)[1], set()
    for s in m["sections"]:
        if base + s["offset"] + s["length"] > cut:
            break
        present.add(s["name"])
    levels = layout_of(m).levels(present)
    if levels[0] < 1:
        return "truncated"
    return f"ok:{min(levels)}" + ("/" + ",".join(map(str, levels)) if is_stream(m) else "")


def _sample(n: int) -> list[int]:
    """Positions where lopcook's own reader is asked too: the header, the ends, every 23rd byte."""
    return sorted({*range(min(n, 40)), *range(max(0, n - 16), n), *range(0, n, 23)})


def test_every_flip_of_every_conformance_file(c_build):
    index = conformance()
    exe = c_build / "clang-san" / "lopcheck"
    for e in index["files"]:
        data = (CONFORMANCE / e["file"]).read_bytes()
        lines = lopcheck(exe, "--flips", CONFORMANCE / e["file"])
        assert len(lines) == len(data)
        got = {int(w[0].split(":")[1]): (w[1], w[2]) for w in lines}
        if e["kind"] == "valid":
            for at, (whole, prefix) in got.items():
                assert whole == prefix == _flip_class(data, at), (e["file"], at, whole, prefix)
        for at in _sample(len(data)):
            mutated = data[:at] + bytes([data[at] ^ 0xFF]) + data[at + 1:]
            assert got[at] == (verdict(mutated, False), verdict(mutated, True)), (e["file"], at)


def test_every_truncation_of_every_conformance_file(c_build):
    index = conformance()
    exe = c_build / "gcc-san" / "lopcheck"
    for e in index["files"]:
        data = (CONFORMANCE / e["file"]).read_bytes()
        lines = lopcheck(exe, "--truncations", CONFORMANCE / e["file"])
        assert len(lines) == len(data)
        got = {int(w[0].split(":")[1]): (w[1], w[2]) for w in lines}
        if e["kind"] == "valid":
            for cut, (whole, prefix) in got.items():
                assert whole == "truncated" and prefix == _prefix_verdict(data, cut), (e["file"], cut, prefix)
        for cut in _sample(len(data)):
            assert got[cut] == (verdict(data[:cut], False), verdict(data[:cut], True)), (e["file"], cut)


def test_every_allocation_failure_is_reported_without_a_leak(c_build):
    files = sorted(str(p) for p in CONFORMANCE.glob("*.lop"))
    for cc in COMPILERS:
        lines = lopcheck(c_build / f"{cc}-san" / "lopcheck", "--oom", *files)
        assert len(lines) > 3 * len(files)
        assert {w[1] for w in lines} == {"out_of_memory"}


@pytest.fixture(scope="module")
def hostile_lops(tmp_path_factory) -> list:
    cases = fuzzcases.generate(tmp_path_factory.mktemp("fuzz"))
    paths = sorted({f"{c.directory}/{c.source}" for c in cases if c.source.endswith(".lop")})
    assert len(paths) >= 100
    return paths


@pytest.mark.parametrize("cc", COMPILERS)
def test_the_hostile_corpus_gets_lopcooks_verdicts(c_build, hostile_lops, cc):
    """Every .lop of tests/support/fuzzcases.py (the streaming layout's hostile files included),
    opened whole and as a prefix and decoded at every level when it opens: no sanitizer report, no
    leak, and lopcook's verdict (error class, or the available and stage levels)."""
    lines = lopcheck(c_build / f"{cc}-san" / "lopcheck", *hostile_lops)
    prefixed = lopcheck(c_build / f"{cc}-san" / "lopcheck", "--prefix", *hostile_lops)
    assert len(lines) == len(prefixed) == len(hostile_lops)
    for path, (_, whole), (_, prefix) in zip(hostile_lops, lines, prefixed):
        with open(path, "rb") as fh:
            data = fh.read()
        assert (whole, prefix) == (verdict(data, False), verdict(data, True)), path


def test_libfuzzer_runs_60_seconds_clean(tmp_path):
    tool("clang")
    make(tmp_path, "fuzz")
    corpus = tmp_path / "corpus"
    corpus.mkdir()
    run = subprocess.run(["nice", str(tmp_path / "fuzz" / "fuzz_lop"), "-max_total_time=60", "-print_final_stats=1",
                          f"-artifact_prefix={tmp_path}/", str(corpus), str(CONFORMANCE)],
                         capture_output=True, text=True, timeout=400)
    assert run.returncode == 0, run.stderr[-4000:]
    runs = [line for line in run.stderr.splitlines() if line.startswith("stat::number_of_executed_units")]
    assert runs and int(runs[0].split()[-1]) > 1000, run.stderr[-2000:]
    assert not list(tmp_path.glob("crash-*")) and not list(tmp_path.glob("leak-*"))


# ---- tangents (format 4.0, format.md 7.6) -------------------------------------------------------

def _with_tangents(data: bytes, bt: int, codes: np.ndarray, signs: np.ndarray) -> bytes:
    """tetra.lop relabelled 4.0 with a tangent field per record: (u, v) codes of bt bits and a
    sign bit appended to each vertex's record, the sections re-laid and every checksum recomputed."""
    msize = struct.unpack_from("<I", data, 12)[0]
    m = json.loads(data[32:32 + msize])
    payload = data[32 + msize:]
    lod = m["parts"][0]["lods"][0]
    n, s_old = lod["vertices"], lod["record_bits"]
    old = payload[next(s for s in m["sections"] if s["name"] == lod["attributes"])["offset"]:]
    bits = np.unpackbits(np.frombuffer(old, np.uint8), bitorder="little")
    s_new = s_old + 2 * bt + 1
    out = np.zeros(n * s_new + 32, np.uint8)
    for j in range(n):
        out[j * s_new:j * s_new + s_old] = bits[j * s_old:(j + 1) * s_old]
        field = [(codes[j, 0] >> b) & 1 for b in range(bt)] + [(codes[j, 1] >> b) & 1 for b in range(bt)] + [signs[j]]
        out[j * s_new + s_old:(j + 1) * s_new] = field
    record = np.packbits(out[:32 * ((n * s_new + 31) // 32)], bitorder="little").tobytes()
    for entry in (m["parts"][0], lod):
        entry["attribute_bits"]["tangents"] = bt
    lod["record_bits"] = s_new
    sections, offset = [], 0
    for s in m["sections"]:
        body = record if s["name"] == lod["attributes"] else payload[s["offset"]:s["offset"] + s["length"]]
        s.update(offset=offset, length=len(body), crc32=zlib.crc32(body))
        offset += len(body)
        sections.append(body)
    mb = manifest_bytes(m)
    head = struct.pack("<4sHHIIIQ", b"LOPC", 4, 0, 32, len(mb), zlib.crc32(mb), 32 + len(mb) + offset)
    return head + struct.pack("<I", zlib.crc32(head)) + mb + b"".join(sections)


@pytest.mark.parametrize("bt", [4, 9, 16])
def test_tangents_decode_as_tangents_md_defines(c_build, tmp_path, bt):
    base = (CONFORMANCE / "tetra.lop").read_bytes()
    rng = np.random.default_rng(bt)
    codes = rng.integers(0, 1 << bt, size=(4, 2))
    signs = rng.integers(0, 2, size=4)
    data = _with_tangents(base, bt, codes, signs)
    (tmp_path / "t.lop").write_bytes(data)
    run = lopdump(c_build / "clang-san" / "lopdump", tmp_path / "t.lop", "--level", "3", "--attributes",
                  tmp_path / "a.bin", "--json")
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout)["version"] == "4.0"
    got = np.frombuffer((tmp_path / "a.bin").read_bytes(), "<f4")
    # indices (12 uint32 as bytes), normals 4 x 3, uvs 4 x 2: unchanged; then tangents 4 x 4
    ref = lopdump(c_build / "gcc" / "lopdump", CONFORMANCE / "tetra.lop", "--level", "3", "--attributes",
                  tmp_path / "b.bin")
    assert ref.returncode == 0
    before = (tmp_path / "b.bin").read_bytes()
    assert (tmp_path / "a.bin").read_bytes()[:len(before)] == before
    tangents = got[len(before) // 4:].reshape(4, 4)
    want = np.concatenate([decode_normals(codes, bt), np.where(signs == 1, -1.0, 1.0)[:, None]], axis=1)
    assert tangents.astype(np.float32).tobytes() == want.astype(np.float32).tobytes()
    for major, minor in ((3, 0), (2, 0)):  # a tangents key before 4.x is a version error
        old = bytearray(data)
        old[4:8] = struct.pack("<HH", major, minor)
        old[28:32] = struct.pack("<I", zlib.crc32(bytes(old[:28])))
        (tmp_path / "old.lop").write_bytes(bytes(old))
        run = lopdump(c_build / "gcc" / "lopdump", tmp_path / "old.lop", "--level", "1")
        assert run.returncode == 2 and ": version: " in run.stderr, run.stderr


def test_the_tangent_record_stays_out_of_reach_of_malformed_bits(tmp_path):
    """format.md 7.6: b_t in [4, 16]; a manifest outside it is refused."""
    base = (CONFORMANCE / "tetra.lop").read_bytes()
    data = bytearray(_with_tangents(base, 4, np.zeros((4, 2), np.int64), np.zeros(4, np.int64)))
    msize = struct.unpack_from("<I", data, 12)[0]
    m = json.loads(bytes(data[32:32 + msize]))
    for bad in (3, 17, None):
        mm = copy.deepcopy(m)
        for entry in (mm["parts"][0], mm["parts"][0]["lods"][0]):
            entry["attribute_bits"]["tangents"] = bad
        mb = manifest_bytes(mm)
        payload = bytes(data[32 + msize:])
        head = struct.pack("<4sHHIIIQ", b"LOPC", 4, 0, 32, len(mb), zlib.crc32(mb), 32 + len(mb) + len(payload))
        (tmp_path / "t.lop").write_bytes(head + struct.pack("<I", zlib.crc32(head)) + mb + payload)
        exe = tmp_path / "lopdump"
        if not exe.exists():
            subprocess.run([tool("gcc"), "-std=c99", "-O1", str(RUNTIME / "examples" / "lopdump.c"), "-o", str(exe)],
                           check=True)
        run = lopdump(exe, tmp_path / "t.lop", "--level", "1")
        assert run.returncode == 2 and ": manifest: " in run.stderr, (bad, run.stderr)


# ---- section 9: choosing a LOD and a level -----------------------------------------------------

@pytest.mark.parametrize("name", ["surface_lods.lop", "surface_lods_clustered.lop", "placements.lop", "tetra.lop"])
def test_lod_and_level_selection_is_lopcooks(c_build, name):
    """lop_select and lop_required_level give lopcook.selection.select's (LOD, level) per part at
    distances spread over eight decades (lop.h computes tan without libm: a distance within float
    rounding of a threshold could differ, and none of these is)."""
    from lopcook.lop.container import read
    from lopcook.selection import select

    c = read(str(CONFORMANCE / name))
    for d in np.geomspace(1e-4, 1e4, 41):
        run = lopdump(c_build / "gcc" / "lopdump", CONFORMANCE / name, "--level", "1", "--json", "--distance",
                      repr(float(d)))
        assert run.returncode == 0, run.stderr
        got = [tuple(x) for x in json.loads(run.stdout)["selection"]]
        assert got == [tuple(x) for x in select(c, float(d))], (name, d)


# ---- the JSON number parser ---------------------------------------------------------------------

DECIMAL_DRIVER = r'''
#define LOP_IMPLEMENTATION
#include "lop.h"
#include <stdio.h>
int main(void)
{
    char line[1000];
    while (fgets(line, sizeof line, stdin)) {
        size_t n = strlen(line);
        double d;
        uint64_t u;
        while (n && line[n - 1] == '\n')
            line[--n] = 0;
        d = lop__decimal(line, n);
        memcpy(&u, &d, 8);
        printf("%016llx\n", (unsigned long long)u);
    }
    return 0;
}
'''


def test_numbers_parse_to_the_nearest_double(tmp_path, rng):
    """The manifest's numbers become exactly Python's float() of them (correct rounding, no
    locale): random doubles and float32 values by their repr, decimal halfway points between
    adjacent doubles (25 digits), subnormals, overflow and numbers of up to 800 digits."""
    from fractions import Fraction

    exe = tmp_path / "decimal"
    run = _compile("gcc", DECIMAL_DRIVER, exe, "-std=c99", "-O2")
    assert run.returncode == 0, run.stderr
    words = rng.integers(0, 2**63, size=20000, dtype=np.int64).astype(np.uint64) * np.uint64(2) + \
        rng.integers(0, 2, size=20000).astype(np.uint64)
    doubles = words.view(np.float64)
    values = [repr(float(d)) for d in doubles[np.isfinite(doubles)]]
    singles = rng.integers(0, 2**32, size=10000, dtype=np.int64).astype(np.uint32).view(np.float32)
    values += [repr(float(f)) for f in singles[np.isfinite(singles)]]
    for m, e in zip(rng.integers(2**52, 2**53, size=5000), rng.integers(-1074, 971, size=5000)):
        values.append(f"{float(Fraction(2 * int(m) + 1) * Fraction(2) ** (int(e) - 1)):.25e}")
    values += ["0", "-0", "1e-400", "4.9e-324", "2.4703282292062327e-324", "2.4703282292062328e-324",
               "1.7976931348623157e308", "1.7976931348623158e308", "1e309", "9007199254740993",
               "1" + "0" * 300, "0." + "0" * 320 + "1", "2.2250738585072011e-308", "1." + "0" * 700 + "1", "9" * 799]
    out = subprocess.run([str(exe)], input="\n".join(values) + "\n", capture_output=True, text=True, check=True)
    got = [int(h, 16) for h in out.stdout.split()]
    want = [struct.unpack("<Q", struct.pack("<d", float(v)))[0] for v in values]
    assert len(got) == len(values)
    bad = [v for v, g, w in zip(values, got, want) if g != w]
    assert not bad, bad[:5]


def test_a_recorded_source_path_is_an_informative_field(c_build, tmp_path):
    """``source.path`` (where ``lopcook cook`` found the source, relative to the container's
    folder) is a field lop.h does not need: lopdump decodes the file to lopcook's bytes."""
    from lopcook.cli import main
    from lopcook.lop.container import read

    for folder in ("assets", "build"):
        (tmp_path / folder).mkdir()
    src = tmp_path / "assets" / "two_plates.glb"
    src.write_bytes((CONFORMANCE.parent / "two_plates.glb").read_bytes())
    out = tmp_path / "build" / "plates.lop"
    assert main(["-q", "cook", str(src), "-o", str(out)]) == 0
    assert read(str(out)).manifest["source"]["path"] == "../assets/two_plates.glb"
    for level in (6, 12, 24):
        run = lopdump(c_build / "gcc" / "lopdump", out, "--level", level, "--positions", tmp_path / "c.f32")
        assert run.returncode == 0, run.stderr
        assert main(["-q", "decode", str(out), "--level", str(level), "--positions", str(tmp_path / "py.f32")]) == 0
        assert (tmp_path / "c.f32").read_bytes() == (tmp_path / "py.f32").read_bytes(), level
