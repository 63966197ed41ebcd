"""GLSL ES 3.00 (WebGL2) versions of the vertex decoders in ``shaders/``, generated from their GLSL
twins: ``runtime/js/glsl/*.es.glsl`` and the same text as JavaScript strings in
``runtime/js/lop-glsl.js`` (what ``runtime/js/three-lop.js`` and a web page import).

This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
section 6.2 (decoding in the vertex shader, the packed buffer bound as a texture).

WebGL2 has no storage buffers, no ``binding`` layout qualifier and no ``precise``. The generator
(``generate``, deterministic: the same twins give the same bytes) keeps every function of
``decode_bitplanes.glsl`` and ``decode_attributes.glsl`` token for token, and rewrites only:

* each storage buffer (``TEXTURES``) as a ``highp usampler2D`` read with ``texelFetch``: word i
  is texel ``(i & 2047, i >> 11)`` (rows of 2048 texels, a width every WebGL2 implementation
  supports; ``lop.js`` ``textureLayout`` lays the words out), through the override macros the twins
  already offer (``LOP_WORD``, ``LOP_CLUSTER``, ``LOP_ATTR_WORD``);
* each std140 uniform block as plain uniforms of the same names and types (three.js and WebGL set
  them one by one; the values are those of ``lopcook.verify.gpu.decode_block`` and friends, as
  ``lop.js`` ``decodeInputs`` / ``attributeInputs`` give them);
* each ``precise`` declaration as a plain one in which every product that feeds a sum or a
  difference is wrapped in ``lop_rounded``: ``uintBitsToFloat(floatBitsToUint(x) ^ lop_fma_guard)``
  with ``lop_fma_guard`` a uniform left at 0 (GL sets uniforms to 0 at link). No compiler can see
  through it, so the product is rounded to float32 before the sum: no fused multiply-add, which is
  all ``precise`` guarantees here (the other operations are correctly rounded in GLSL ES 3.00
  highp);

and adds ``lop_place`` (a placement's rows, ``lopcook.lop.placement.to_world``, with the same
guard). ``check`` reports any difference between the files and a fresh generation, and function
bodies that differ from the twins' after these rewrites. ``python -m lopcook.verify.webgl
[--update]`` checks (exit 1 on a difference) or writes the files.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

from ..errors import EXIT_VERIFY_FAILED, LopcookError
from .gpu import shader_dir
from .twins import code_digest, functions

#: the twins generated, in output order, and the name of each one's JavaScript string
SOURCES = (("decode_bitplanes.glsl", "DECODE_BITPLANES"), ("decode_attributes.glsl", "DECODE_ATTRIBUTES"))
#: storage buffer -> (override macro, sampler, what a texel holds, component read)
TEXTURES = {
    "LopPositions": ("LOP_WORD", "lop_positions", "R32UI, word i of the packed buffer P", ".r"),
    "LopClusters": ("LOP_CLUSTER", "lop_clusters", "RGBA32UI, cluster c's record (3 header words, ClusterBit)", ""),
    "LopAttributes": ("LOP_ATTR_WORD", "lop_attributes", "R32UI, word i of the attribute section", ".r"),
}
TEXTURE_WIDTH_LOG2 = 11
JS_MODULE = "lop-glsl.js"

_TOKEN = re.compile(r"\d+\.\d*(?:[eE][-+]?\d+)?[fF]?|\d+[eE][-+]?\d+[fF]?|0[xX][0-9a-fA-F]+[uU]?|\d+[uU]?"
                    r"|[A-Za-z_]\w*|<<|>>|<=|>=|==|!=|&&|\|\||\S")
#: binary operators and their precedence (GLSL, high binds tighter)
_PRECEDENCE = {"*": 10, "/": 10, "%": 10, "+": 9, "-": 9, "<<": 8, ">>": 8, "<": 7, ">": 7, "<=": 7, ">=": 7,
               "==": 6, "!=": 6, "&": 5, "^": 4, "|": 3, "&&": 2, "||": 1}

PRELUDE = f"""#ifndef LOP_ES_PRELUDE
#define LOP_ES_PRELUDE
// Texel of word (or record) i of an integer texture of rows of 2^{TEXTURE_WIDTH_LOG2} texels.
#define LOP_TEXTURE_WIDTH_LOG2 {TEXTURE_WIDTH_LOG2}u
#define LOP_TEXEL(s, i) texelFetch(s, ivec2(int((i) & ((1u << LOP_TEXTURE_WIDTH_LOG2) - 1u)), int((i) >> LOP_TEXTURE_WIDTH_LOG2)), 0)
// Stands in for GLSL 4.x `precise`: x rounded to float32 as it is, never fused into a following
// add (lop_fma_guard is a uniform no compiler can know; leave it at its initial 0).
uniform uint lop_fma_guard;
float lop_rounded(float x) {{ return uintBitsToFloat(floatBitsToUint(x) ^ lop_fma_guard); }}
vec2 lop_rounded(vec2 x) {{ return uintBitsToFloat(floatBitsToUint(x) ^ uvec2(lop_fma_guard)); }}
vec3 lop_rounded(vec3 x) {{ return uintBitsToFloat(floatBitsToUint(x) ^ uvec3(lop_fma_guard)); }}
vec4 lop_rounded(vec4 x) {{ return uintBitsToFloat(floatBitsToUint(x) ^ uvec4(lop_fma_guard)); }}
#endif
"""

PLACE = """
// World position of a placement (container 3.0, cook --instances; lopcook.lop.placement.to_world):
// w_i = ((a_i0 p.x + a_i1 p.y) + a_i2 p.z) + t_i per row r_i = (a_i0, a_i1, a_i2, t_i), every product
// and sum rounded to float32 (no fused multiply-add); rows (1,0,0,0), (0,1,0,0), (0,0,1,0) on the
// scene grid give p back exactly.
vec3 lop_place(vec3 p, vec4 r0, vec4 r1, vec4 r2)
{
    vec3 w;
    w.x = ((lop_rounded(r0.x * p.x) + lop_rounded(r0.y * p.y)) + lop_rounded(r0.z * p.z)) + r0.w;
    w.y = ((lop_rounded(r1.x * p.x) + lop_rounded(r1.y * p.y)) + lop_rounded(r1.z * p.z)) + r1.w;
    w.z = ((lop_rounded(r2.x * p.x) + lop_rounded(r2.y * p.y)) + lop_rounded(r2.z * p.z)) + r2.w;
    return w;
}
"""


def _fail(path, message: str) -> None:
    raise LopcookError("verify", str(path), message, hint="update lopcook/verify/webgl.py with the twins")


# ---- expressions: wrap every product that feeds a sum --------------------------------------------

def _parse(expr: str) -> tuple[dict, list]:
    """``(tree, tokens)`` of one GLSL expression: nodes ``{"kind", "op", "first", "last", "kids"}``
    (token indices), kinds atom, paren, unary, postfix (member, index, call), binary. ValueError
    for what this small parser does not read (assignments, the ternary operator)."""
    toks = [(m.group(), m.start(), m.end()) for m in _TOKEN.finditer(expr)]
    pos = 0

    def peek():
        return toks[pos][0] if pos < len(toks) else None

    def take(want=None):
        nonlocal pos
        if pos >= len(toks) or (want is not None and toks[pos][0] != want):
            raise ValueError(f"cannot read {expr!r} at token {pos}")
        pos += 1

    def node(kind, first, last, op=None, kids=()):
        return {"kind": kind, "op": op, "first": first, "last": last, "kids": list(kids)}

    def primary():
        first, t = pos, peek()
        if t == "(":
            take()
            inner = binary(0)
            take(")")
            n = node("paren", first, pos - 1, kids=[inner])
        elif t in ("-", "+", "!", "~"):
            take()
            kid = primary()
            return node("unary", first, pos - 1, op=t, kids=[kid])
        elif t is not None and (t[0].isalnum() or t[0] == "_"):
            take()
            n = node("atom", first, pos - 1)
        else:
            raise ValueError(f"cannot read {expr!r} at token {pos}")
        while peek() in (".", "[", "("):
            t = peek()
            take()
            kids = [n]
            if t == ".":
                take()
            elif t == "[":
                kids.append(binary(0))
                take("]")
            else:
                while peek() != ")":
                    kids.append(binary(0))
                    if peek() == ",":
                        take()
                take(")")
            n = node("postfix", first, pos - 1, kids=kids)
        return n

    def binary(min_prec):
        left = primary()
        while peek() in _PRECEDENCE and _PRECEDENCE[peek()] >= min_prec:
            op = peek()
            take()
            right = binary(_PRECEDENCE[op] + 1)
            left = node("binary", left["first"], right["last"], op=op, kids=[left, right])
        return left

    tree = binary(0)
    if pos != len(toks):
        raise ValueError(f"cannot read {expr!r} at token {pos}")
    return tree, toks


def wrap_products(expr: str) -> str:
    """``expr`` (one GLSL expression) with every ``a * b`` whose value feeds ``+`` or ``-`` (through
    parentheses and unary signs) written ``lop_rounded(a * b)``; the text otherwise unchanged.
    ValueError for what ``_parse`` does not read."""
    tree, toks = _parse(expr)
    wraps: list[tuple[int, int]] = []

    def visit(n, feeds_sum):
        through = n["kind"] == "paren" or (n["kind"] == "unary" and n["op"] in "+-")
        if n["kind"] == "binary" and n["op"] == "*" and feeds_sum:
            wraps.append((toks[n["first"]][1], toks[n["last"]][2]))
        sums = n["kind"] == "binary" and n["op"] in "+-"
        for k in n["kids"]:
            visit(k, sums or (through and feeds_sum))

    visit(tree, False)
    out = expr
    for start, end in sorted(wraps, reverse=True):
        out = out[:start] + "lop_rounded(" + out[start:end] + ")" + out[end:]
    return out


_PRECISE = re.compile(r"^(\s*)precise (\w+) (\w+) = (.*);(.*)$")


def _precise(line: str, path) -> str:
    """A ``precise T x = e;`` line without ``precise``, the products feeding sums guarded."""
    m = _PRECISE.match(line)
    if not m:
        _fail(path, f"a `precise` line the generator does not read: {line.strip()!r}")
    indent, typ, name, expr, rest = m.groups()
    try:
        expr = wrap_products(expr)
    except ValueError as exc:
        _fail(path, str(exc))
    return f"{indent}{typ} {name} = {expr};{rest}"


# ---- declarations --------------------------------------------------------------------------------

_BINDING_DEFAULT = re.compile(r"#ifndef (LOP_\w+_BINDING)\n#define \1 \w+\n#endif\n\n?")
_SSBO = re.compile(r"#ifndef (LOP_\w+)\nlayout\(std430, binding = \w+\) readonly buffer (\w+) \{\n.*?\n\};\n"
                   r"#define \1\((\w+)\) [^\n]*\n#endif", re.S)
_UBO = re.compile(r"layout\(std140, binding = \w+\) uniform (\w+) \{\n(.*?)\n\};", re.S)
_MEMBER = re.compile(r"^(\s*)(\w+) (\w+(?:\[\d+\])?);(.*)$")


def _texture(m: re.Match, path) -> str:
    macro, block, arg = m.group(1), m.group(2), m.group(3)
    if block not in TEXTURES or TEXTURES[block][0] != macro:
        _fail(path, f"storage buffer {block} ({macro}) has no WebGL2 texture in TEXTURES")
    _, sampler, what, comp = TEXTURES[block]
    return (f"#ifndef {macro}\nuniform highp usampler2D {sampler};  // {what}\n"
            f"#define {macro}({arg}) LOP_TEXEL({sampler}, ({arg})){comp}\n#endif")


def _uniforms(m: re.Match, path) -> str:
    out = [f"// uniform block {m.group(1)} of the GLSL twin (std140 there), as plain uniforms"]
    for line in m.group(2).split("\n"):
        if line.lstrip().startswith("#"):
            out.append(line.strip())
            continue
        mm = _MEMBER.match(line)
        if not mm:
            _fail(path, f"uniform block member the generator does not read: {line.strip()!r}")
        _, typ, name, rest = mm.groups()
        out.append(f"uniform highp {typ} {name};{rest}")
    return "\n".join(out)


def _header(source: str, name: str) -> str:
    """The ES file's opening comment: what it is, where it comes from, how to bind it."""
    first = source.split("\n", 1)[0].replace(name, name.replace(".glsl", ".es.glsl"), 1)
    first = first.replace("(GLSL 4.30+)", "(GLSL ES 3.00, WebGL2)")
    return (f"{first}\n//\n"
            f"// GENERATED from shaders/{name} (code sha256 {code_digest(source)[:16]}) by\n"
            "// `python -m lopcook.verify.webgl --update`; do not edit (lopcook/verify/webgl.py says what\n"
            "// changes: storage buffers read as integer textures, uniform blocks as plain uniforms, `precise`\n"
            "// replaced by lop_rounded on every product that feeds a sum). Every function is the twin's, so\n"
            "// the twin's comments and tests/test_webgl_decoders.py's transform-feedback check hold: the\n"
            "// decode is bit-exact with lopcook's CPU reference and runtime/js/lop.js.\n"
            "//\n"
            "// Include it after `#version 300 es` and any #define (LOP_CLUSTERED, LOP_NO_VIEW, ...) in a\n"
            "// vertex shader; word i of a texture is texel (i & 2047, i >> 11) (lop.js textureLayout);\n"
            "// set the uniforms from lop.js decodeInputs / attributeInputs.\n")


def generate_one(source: str, name: str, path=None) -> str:
    """The GLSL ES 3.00 text of one twin (``name``: its file name)."""
    body = source.split("\n\n", 1)[1]  # after the opening comment
    body = _BINDING_DEFAULT.sub("", body)
    body = _SSBO.sub(lambda m: _texture(m, path), body)
    body = _UBO.sub(lambda m: _uniforms(m, path), body)
    lines = [(_precise(ln, path) if re.match(r"^\s*precise ", ln) else ln) for ln in body.split("\n")]
    body = "\n".join(lines)
    if re.search(r"\bprecise\b|\bbinding\b|\bbuffer\b|std430", re.sub(r"//[^\n]*", "", body)):
        _fail(path, "GLSL 4.x left in the ES text (precise, binding, buffer or std430)")
    extra = PLACE if name == "decode_bitplanes.glsl" else ""
    return _header(source, name) + "\n" + PRELUDE + "\n" + body.rstrip("\n") + "\n" + extra


def _repo() -> Path:
    return Path(__file__).resolve().parents[2]


def generate(shaders: Path | None = None) -> dict[str, str]:
    """``{relative output path: text}``: each twin's ``runtime/js/glsl/NAME.es.glsl`` and the
    JavaScript module ``runtime/js/lop-glsl.js`` that exports the same texts."""
    folder = Path(shaders) if shaders is not None else shader_dir()
    out, js = {}, []
    for name, const in SOURCES:
        path = folder / name
        text = generate_one(path.read_text(encoding="utf-8"), name, path)
        out[f"runtime/js/glsl/{name.replace('.glsl', '.es.glsl')}"] = text
        quoted = text.replace("\\", "\\\\").replace("`", "\\`").replace("${", "\\${")
        js.append(f"/** GLSL ES 3.00 text of runtime/js/glsl/{name.replace('.glsl', '.es.glsl')}. */\n"
                  f"export const {const} = `{quoted}`;\n")
    out[f"runtime/js/{JS_MODULE}"] = (
        "// lop-glsl.js: the WebGL2 decoders of runtime/js/glsl/ as strings (ES module, no dependency).\n"
        "// GENERATED by `python -m lopcook.verify.webgl --update` from shaders/; do not edit.\n\n"
        + "\n".join(js))
    return out


def function_differences(ours: str, twin: str) -> list[str]:
    """Functions of the twin missing from the ES text, or whose tokens differ after the rewrites
    (``precise`` dropped, ``lop_rounded(...)`` unwrapped)."""
    def norm(text):
        t = re.sub(r"\bprecise\s+", "", text)
        return t

    def unwrap(toks):
        out, skip = [], []
        for i, t in enumerate(toks):
            if t == "lop_rounded" and i + 1 < len(toks) and toks[i + 1] == "(":
                depth, j = 0, i + 1
                while True:
                    depth += {"(": 1, ")": -1}.get(toks[j], 0)
                    if depth == 0:
                        break
                    j += 1
                skip += [i, i + 1, j]
        return [t for i, t in enumerate(toks) if i not in set(skip)]

    mine = {k: unwrap(v) for k, v in functions(ours).items()}
    theirs = functions(norm(twin))
    out = [f"{k}: missing from the ES text" for k in sorted(set(theirs) - set(mine))]
    out += [f"{k}: differs from the twin" for k in sorted(set(theirs) & set(mine)) if mine[k] != theirs[k]]
    return out


def check(shaders: Path | None = None, repo: Path | None = None) -> list[str]:
    """Problems: a generated file missing or different from a fresh generation, or an ES function
    that is not its twin's. Empty when all is in order."""
    repo = Path(repo) if repo is not None else _repo()
    folder = Path(shaders) if shaders is not None else shader_dir()
    problems = []
    for rel, text in generate(folder).items():
        path = repo / rel
        if not path.is_file():
            problems.append(f"{rel}: missing (python -m lopcook.verify.webgl --update)")
        elif path.read_text(encoding="utf-8") != text:
            problems.append(f"{rel}: differs from a fresh generation (python -m lopcook.verify.webgl --update)")
    for name, _ in SOURCES:
        es = repo / f"runtime/js/glsl/{name.replace('.glsl', '.es.glsl')}"
        if es.is_file():
            problems += [f"{es.name}: {d}" for d in function_differences(es.read_text(encoding="utf-8"),
                                                                       (folder / name).read_text(encoding="utf-8"))]
    return problems


def update(shaders: Path | None = None, repo: Path | None = None) -> list[str]:
    """Write every generated file; returns their relative paths."""
    repo = Path(repo) if repo is not None else _repo()
    files = generate(shaders)
    for rel, text in files.items():
        (repo / rel).parent.mkdir(parents=True, exist_ok=True)
        (repo / rel).write_text(text, encoding="utf-8")
    return list(files)


def main(argv=None) -> int:
    """``python -m lopcook.verify.webgl [--update]``: check (exit 0 / 1) or write the WebGL2 decoders."""
    p = argparse.ArgumentParser(prog="python -m lopcook.verify.webgl", description=__doc__.split("\n")[0])
    p.add_argument("--update", action="store_true", help="write runtime/js/glsl/*.es.glsl and runtime/js/lop-glsl.js")
    args = p.parse_args(argv)
    try:
        if args.update:
            for rel in update():
                print(f"wrote {rel}")
            return 0
        problems = check()
    except LopcookError as exc:
        print(f"lopcook: error: {exc}", file=sys.stderr)
        return exc.exit_code
    for line in problems:
        print(line)
    return EXIT_VERIFY_FAILED if problems else 0


__all__ = ["SOURCES", "TEXTURES", "PRELUDE", "PLACE", "wrap_products", "generate_one", "generate",
           "function_differences", "check", "update", "main"]

if __name__ == "__main__":
    sys.exit(main())
