"""The GLSL/HLSL twins of ``shaders/`` change together: a record of both sides' code digests, and a
token comparison of the vertex decoders' function bodies.

``shaders/`` ships every decoder twice, once per language (``TWINS``): the GLSL file is the one the
harness runs as written, the HLSL file is checked through glslang and spirv-cross
(``lopcook.verify.gpu``). Both must implement the same algorithm (Meyer et al. 2011, sections 5.3
and 6), so a change to one side without the other is an error:

* ``shaders/twins.json`` records, per pair, the sha256 of each side's **code** (``code_digest``:
  comments removed, runs of white space collapsed to one space, so comment and layout edits do not
  count). ``check`` reports a pair whose recorded digests no longer match the files; ``update``
  (``python -m lopcook.verify.twins --update``) rewrites the record, and refuses when only one side
  of a pair changed, unless ``force`` (``--force``: a language-specific change whose twin really
  needs none, e.g. an HLSL attribute).
* ``function_differences`` compares the bodies of the functions both files of each vertex-decoder
  pair (``TOKEN_TWINS``: positions and attributes) define, token by token, after mapping the few
  spelling differences of the two languages (``HLSL_TO_GLSL``: ``uint3`` -> ``uvec3``, ``float3`` ->
  ``vec3``, ..., float literal suffix ``f`` dropped, loop attributes ``[loop]`` / ``[unroll]``
  dropped). The compute kernels differ in their buffer access (``ByteAddressBuffer.Load`` against
  SSBO arrays), so only the digest record covers them.

Bad input (a missing file, a record that does not parse or lacks a pair, a one-sided update):
``LopcookError`` (exit 2) naming the file and what to do.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import re
import sys
from pathlib import Path

from ..errors import EXIT_VERIFY_FAILED, LopcookError
from .gpu import shader_dir

#: (GLSL file, HLSL file) pairs of ``shaders/`` that implement the same algorithm
TWINS = (("decode_bitplanes.glsl", "decode_bitplanes.hlsl"),
         ("adapt_bitplanes.comp.glsl", "adapt_bitplanes.comp.hlsl"),
         ("decode_attributes.glsl", "decode_attributes.hlsl"))
#: the vertex-decoder pairs whose function bodies are compared token by token
TOKEN_TWINS = (TWINS[0], TWINS[2])
#: the positions' decoder pair (the first of ``TOKEN_TWINS``)
TOKEN_TWIN = TOKEN_TWINS[0]
#: the record's file name inside ``shaders/``
RECORD = "twins.json"
#: HLSL spellings and their GLSL equivalents (types only; everything else must match as written)
HLSL_TO_GLSL = {"uint2": "uvec2", "uint3": "uvec3", "uint4": "uvec4", "int2": "ivec2", "int3": "ivec3",
                "int4": "ivec4", "float2": "vec2", "float3": "vec3", "float4": "vec4", "bool2": "bvec2",
                "bool3": "bvec3", "bool4": "bvec4", "float4x4": "mat4", "float3x3": "mat3"}

_COMMENT = re.compile(r"//[^\n]*|/\*.*?\*/", re.S)
_TOKEN = re.compile(r"\d+\.\d*(?:[eE][-+]?\d+)?[fF]?|\d+[eE][-+]?\d+[fF]?|0[xX][0-9a-fA-F]+[uU]?|\d+[uU]?"
                    r"|[A-Za-z_]\w*|<<=|>>=|<<|>>|<=|>=|==|!=|&&|\|\||\+\+|--|[-+*/%&|^]=|\S")
_ATTRIBUTE = re.compile(r"\[\s*(?:loop|unroll|branch|flatten)\s*\]")


def code_text(source: str) -> str:
    """``source`` without comments, every run of white space one space, stripped at both ends."""
    return " ".join(_COMMENT.sub(" ", source).split())


def code_digest(source: str) -> str:
    """sha256 (hex) of ``code_text(source)`` encoded as UTF-8."""
    return hashlib.sha256(code_text(source).encode("utf-8")).hexdigest()


def tokens(source: str, hlsl: bool = False) -> list[str]:
    """Tokens of ``source`` without comments; for HLSL, types mapped by ``HLSL_TO_GLSL``, the suffix
    of float literals (``2.0f``) and loop attributes dropped, so equal algorithms give equal lists."""
    text = _COMMENT.sub(" ", source)
    if hlsl:
        text = _ATTRIBUTE.sub(" ", text)
    out = []
    for t in _TOKEN.findall(text):
        if hlsl:
            t = HLSL_TO_GLSL.get(t, t)
            if t[0].isdigit() and t[-1] in "fF" and not t.lower().startswith("0x"):
                t = t[:-1]
        out.append(t)
    return out


def functions(source: str, hlsl: bool = False) -> dict[str, list[str]]:
    """Function name -> tokens of its signature and body (from the return type to the closing
    brace), for every top-level function definition of ``source``. A name defined more than once
    (alternatives under ``#ifdef``, e.g. ``LOP_CLUSTERED``) keys its second definition ``name#2``,
    its third ``name#3``, and so on, in source order, so every definition is compared."""
    toks = tokens(source, hlsl)
    out: dict[str, list[str]] = {}
    depth, i = 0, 0
    while i < len(toks):
        t = toks[i]
        if t == "{":
            depth += 1
        elif t == "}":
            depth -= 1
        elif (depth == 0 and i + 2 < len(toks) and re.fullmatch(r"[A-Za-z_]\w*", t)
              and re.fullmatch(r"[A-Za-z_]\w*", toks[i + 1]) and toks[i + 2] == "("):
            j = i + 2
            while j < len(toks) and toks[j] != ")":
                j += 1
            if j + 1 < len(toks) and toks[j + 1] == "{":
                k, d = j + 1, 0
                while k < len(toks):
                    d += {"{": 1, "}": -1}.get(toks[k], 0)
                    if d == 0:
                        break
                    k += 1
                name, n = toks[i + 1], 1
                while (name if n == 1 else f"{name}#{n}") in out:
                    n += 1
                out[name if n == 1 else f"{name}#{n}"] = toks[i:k + 1]
                i = k + 1
                continue
        i += 1
    return out


def function_differences(glsl_source: str, hlsl_source: str) -> list[str]:
    """One line per function that both sources define with different (mapped) tokens, and per
    function that only one of them defines; empty when the twins agree."""
    g, h = functions(glsl_source), functions(hlsl_source, hlsl=True)
    out = [f"{name}: only in the {'GLSL' if name in g else 'HLSL'} file" for name in sorted(set(g) ^ set(h))]
    for name in sorted(set(g) & set(h)):
        if g[name] != h[name]:
            k = next((i for i, (a, b) in enumerate(zip(g[name], h[name])) if a != b), min(len(g[name]), len(h[name])))
            out.append(f"{name}: differs at token {k}: GLSL {' '.join(g[name][k:k + 6])!r} vs HLSL "
                       f"{' '.join(h[name][k:k + 6])!r}")
    return out


def _read(folder: Path, name: str) -> str:
    path = folder / name
    if not path.is_file():
        raise LopcookError("verify", str(path), "shader file missing", hint="restore it from the repository")
    return path.read_text(encoding="utf-8")


def digests(folder: Path) -> dict[str, dict[str, str]]:
    """``{glsl file: {glsl file: digest, hlsl file: digest}}`` of every pair in ``TWINS`` in ``folder``."""
    return {g: {g: code_digest(_read(folder, g)), h: code_digest(_read(folder, h))} for g, h in TWINS}


def read_record(folder: Path) -> dict:
    """The pairs recorded in ``folder / RECORD``; LopcookError when missing or not as written by ``update``."""
    path = folder / RECORD
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        pairs = data["pairs"]
        assert isinstance(pairs, dict)
    except (OSError, ValueError, KeyError, AssertionError) as exc:
        raise LopcookError("verify", str(path), f"the twin record cannot be read ({type(exc).__name__}: {exc})",
                           hint="python -m lopcook.verify.twins --update") from None
    return pairs


def check(folder: Path | None = None) -> list[str]:
    """Problems of the twins in ``folder`` (default ``lopcook.verify.gpu.shader_dir()``): pairs
    changed since the record (naming the side that changed, or both), function bodies of a
    ``TOKEN_TWINS`` pair that differ. Empty when both agree and match the record."""
    folder = Path(folder) if folder is not None else shader_dir()
    record = read_record(folder)
    out = []
    for g, now in digests(folder).items():
        old = record.get(g)
        if not isinstance(old, dict):
            out.append(f"{g}: pair not in {RECORD} (python -m lopcook.verify.twins --update)")
            continue
        changed = [f for f, d in now.items() if old.get(f) != d]
        if len(changed) == 1:
            (f,) = changed
            twin = next(x for x in now if x != f)
            out.append(f"{f} changed without its twin {twin}: change both, then python -m lopcook.verify.twins "
                       "--update")
        elif changed:
            out.append(f"{' and '.join(changed)} changed: record them with python -m lopcook.verify.twins --update")
    for g, h in TOKEN_TWINS:
        out += [f"{g} / {h}: {d}" for d in function_differences(_read(folder, g), _read(folder, h))]
    return out


def update(folder: Path | None = None, force: bool = False) -> dict:
    """Write ``folder / RECORD`` with the current digests and return it. Raises LopcookError (exit
    2) when a pair has only one side changed since the record (unless ``force``) or a decoder
    pair's function bodies differ; nothing is written then."""
    folder = Path(folder) if folder is not None else shader_dir()
    path = folder / RECORD
    old = read_record(folder) if path.exists() else {}
    now = digests(folder)
    if not force:
        for g, d in now.items():
            changed = [f for f, v in d.items() if (old.get(g) or {}).get(f) != v]
            if g in old and len(changed) == 1:
                raise LopcookError("verify", str(folder / changed[0]), "changed without its twin "
                                   f"{next(x for x in d if x != changed[0])}",
                                   hint="change both files (or pass --force for a language-specific change)")
    for g, h in TOKEN_TWINS:
        diffs = function_differences(_read(folder, g), _read(folder, h))
        if diffs:
            raise LopcookError("verify", str(folder / h), f"the decoder twins differ: {diffs[0]}",
                               hint=f"make the function bodies of {g} and {h} agree")
    data = {"note": "sha256 of each shader's code without comments (lopcook.verify.twins); "
                    "update with python -m lopcook.verify.twins --update", "pairs": now}
    path.write_text(json.dumps(data, indent=1, sort_keys=True) + "\n", encoding="utf-8")
    return data


def main(argv=None) -> int:
    """``python -m lopcook.verify.twins [--update [--force]] [DIR]``: check (exit 0 / 1) or record
    (exit 0) the twins of ``DIR`` (default the shaders folder); bad input exits 2."""
    p = argparse.ArgumentParser(prog="python -m lopcook.verify.twins", description=__doc__.split("\n")[0])
    p.add_argument("folder", nargs="?", type=Path, help="shaders folder (default: the one lopcook uses)")
    p.add_argument("--update", action="store_true", help="record the current digests of every pair")
    p.add_argument("--force", action="store_true", help="with --update: accept a pair with one side changed")
    args = p.parse_args(argv)
    try:
        if args.update:
            update(args.folder, force=args.force)
            print(f"recorded {len(TWINS)} pairs")
            return 0
        problems = check(args.folder)
    except LopcookError as exc:
        print(f"lopcook: error: {exc}", file=sys.stderr)
        return exc.exit_code
    for line in problems:
        print(line)
    return EXIT_VERIFY_FAILED if problems else 0


__all__ = ["TWINS", "TOKEN_TWINS", "TOKEN_TWIN", "RECORD", "HLSL_TO_GLSL", "code_text", "code_digest", "tokens", "functions",
           "function_differences", "digests", "read_record", "check", "update", "main"]

if __name__ == "__main__":
    sys.exit(main())
