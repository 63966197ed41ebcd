"""Run the reference shaders of ``shaders/`` headlessly: moderngl through EGL, GLSL and HLSL.

This work is based on: Meyer et al., "Adaptive Level-of-Precision for GPU-Rendering", VMV 2011,
section 6 (vertex-shader decoding, data-parallel precision adaption). The harness follows
moderngl's own tests: one standalone context per process (``tests/conftest.py`` there, EGL
backend), transform feedback to read what a vertex shader computed (``tests/test_transform.py``),
shader storage buffers to read what a compute shader wrote.

* GLSL runs as written (``#version 450`` and the defines below are prepended).
* HLSL is compiled by glslang's HLSL front end to SPIR-V (``glslangValidator -D -V``) and
  cross-compiled by spirv-cross to GLSL 4.50, which then runs on the same context. The HLSL
  registers map to the same binding numbers as the GLSL files, so one set of buffers serves both.

Context: Mesa llvmpipe on machines without a GPU, the vendor's EGL driver where there is one
(``context_info()`` names it). System packages: ``libegl1 libegl-mesa0 libgl1-mesa-dri`` (EGL and
Mesa), ``glslang-tools`` and ``spirv-cross`` (HLSL only). Missing ones raise LopcookError naming them.

Buffers are numpy arrays in and out: packed words ``(w,) uint32``, tables ``(25,) int`` (VertexId,
BitId), grid integers ``(n, 3) uint32``, positions ``(n, 3) float32`` metres.

The attribute record's decoders run the same way in ``lopcook.verify.attribute_gpu``.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..lop.binning import LEVELS, buffer_bytes, table_bit_id
from ..errors import EXIT_BAD_INPUT, EXIT_VERIFY_FAILED, LopcookError

LANGUAGES = ("glsl", "hlsl")
SYSTEM_PACKAGES_EGL = ("libegl1", "libegl-mesa0", "libgl1-mesa-dri")
SYSTEM_PACKAGES_HLSL = {"glslangValidator": "glslang-tools", "spirv-cross": "spirv-cross"}
GL_VERSION_REQUIRED = 430  # SSBOs and compute shaders
LOCAL_SIZE = 64  # threads per work group of the compute kernels
MAX_GROUPS = 65535  # per dispatch (GL_MAX_COMPUTE_WORK_GROUP_COUNT minimum)
KERNELS = ("unpack", "add_plane", "remove_plane", "tables", "pack")

# Transform feedback record of the verification vertex shader: 28 bytes per vertex.
FEEDBACK = np.dtype([("grid", "<u4", 3), ("position", "<f4", 3), ("level", "<u4")])
VARYINGS = ("lop_out_grid", "lop_out_position", "lop_out_level")


def shader_dir() -> Path:
    """The ``shaders/`` folder: ``$LOPCOOK_SHADERS``, the repository's ``shaders/`` (editable
    install / checkout), or ``<prefix>/share/lopcook/shaders`` (where a wheel installs them)."""
    env = os.environ.get("LOPCOOK_SHADERS")
    candidates = [Path(env)] if env else [Path(__file__).resolve().parents[2] / "shaders",
                                          Path(sys.prefix) / "share" / "lopcook" / "shaders"]
    path = next((c for c in candidates if (c / "decode_bitplanes.glsl").is_file()), candidates[0])
    if not (path / "decode_bitplanes.glsl").is_file():
        raise LopcookError("verify", str(path), "the reference shaders are missing (decode_bitplanes.glsl)",
                           hint="run from a lopcook checkout or set LOPCOOK_SHADERS to its shaders/ folder")
    return path


def shader_source(name: str) -> str:
    """The text of ``shaders/<name>`` from ``shader_dir()``."""
    return (shader_dir() / name).read_text()


# ---- the context ------------------------------------------------------------------------------

_CONTEXT = None
_FRAMEBUFFER = None


def context():
    """The process's headless moderngl context (OpenGL 4.3+ core through EGL), created once."""
    global _CONTEXT, _FRAMEBUFFER
    if _CONTEXT is not None:
        return _CONTEXT
    try:
        import moderngl  # optional native GL binding, imported where a context is made
    except ImportError as exc:  # pragma: no cover - moderngl is a dependency
        raise LopcookError("verify", None, f"moderngl is not importable ({exc})",
                           hint="pip install moderngl") from None
    try:
        ctx = moderngl.create_standalone_context(backend="egl", require=GL_VERSION_REQUIRED)
    except Exception as exc:
        pkgs = " ".join(SYSTEM_PACKAGES_EGL)
        raise LopcookError(
            "verify", None, f"cannot create a headless OpenGL {GL_VERSION_REQUIRED // 100}.{GL_VERSION_REQUIRED % 100 // 10}"
            f"+ context through EGL ({type(exc).__name__}: {exc})",
            hint=f"install the system packages {pkgs} (Debian/Ubuntu: sudo apt-get install {pkgs}); "
                 "with a GPU, its vendor's EGL driver works as well", exit_code=EXIT_BAD_INPUT) from None
    # EGL without a surface has no default framebuffer: draws (even with the rasterizer off, as
    # transform feedback runs) need a complete one bound.
    _FRAMEBUFFER = ctx.simple_framebuffer((1, 1))
    _FRAMEBUFFER.use()
    _CONTEXT = ctx
    return ctx


def use_default_framebuffer() -> None:
    """Bind the context's 1x1 framebuffer again (what ``context`` leaves bound and the transform
    feedback kernels draw into); a no-op before ``context()`` has run."""
    if _FRAMEBUFFER is not None:
        _FRAMEBUFFER.use()


_FLUSH = None


def flush() -> None:
    """``glFlush`` on the current context: the commands issued so far start executing, without
    waiting for them (llvmpipe hands its binned scene to its rasteriser threads and returns, so the
    caller's own work overlaps the rasterisation). The results are those without the call (GL
    keeps the order of commands). Resolved once through ``eglGetProcAddress`` (moderngl has no
    flush); a no-op where that is not available. ctypes releases the GIL during the call."""
    global _FLUSH
    if _FLUSH is None:
        _FLUSH = _resolve_flush()
    if _FLUSH is not False:
        _FLUSH()


def _resolve_flush():
    """``glFlush`` through ``eglGetProcAddress`` as a ctypes function, or False where EGL or the
    entry point is missing."""
    try:
        egl = ctypes.CDLL(ctypes.util.find_library("EGL") or "libEGL.so.1")
        egl.eglGetProcAddress.restype = ctypes.c_void_p
        egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
        addr = egl.eglGetProcAddress(b"glFlush")
    except (OSError, AttributeError):
        return False
    return ctypes.CFUNCTYPE(None)(addr) if addr else False


def context_info() -> dict:
    """Renderer, vendor and version strings of the context (llvmpipe or the GPU's driver)."""
    info = context().info
    return {"renderer": info["GL_RENDERER"], "vendor": info["GL_VENDOR"], "version": info["GL_VERSION"]}


def gl_available() -> str | None:
    """None when a context can be created, else the reason (for pytest skips)."""
    try:
        context()
    except LopcookError as exc:
        return str(exc)
    return None


# ---- HLSL -> SPIR-V -> GLSL 4.50 --------------------------------------------------------------

def _tool(name: str) -> str:
    path = shutil.which(name)
    if path is None:
        pkg = SYSTEM_PACKAGES_HLSL[name]
        raise LopcookError("verify", None, f"{name} is not installed: it is needed to run the HLSL shaders",
                           hint=f"install the Debian package {pkg}: sudo apt-get install glslang-tools spirv-cross",
                           exit_code=EXIT_BAD_INPUT)
    return path


def require_hlsl_tools() -> None:
    """Raise LopcookError (exit 2, naming the Debian packages) unless both HLSL tools are on PATH."""
    for name in SYSTEM_PACKAGES_HLSL:
        _tool(name)


def hlsl_tools_available() -> str | None:
    """None when glslangValidator and spirv-cross are on PATH, else the reason."""
    try:
        require_hlsl_tools()
    except LopcookError as exc:
        return str(exc)
    return None


def tool_versions() -> dict:
    """First line of each HLSL tool's version output (None when missing)."""
    out = {}
    for name, args in (("glslangValidator", ["--version"]), ("spirv-cross", ["--revision"])):
        path = shutil.which(name)
        if path is None:
            out[name] = None
            continue
        try:
            res = subprocess.run([path, *args], capture_output=True, text=True, timeout=30)
            text = (res.stdout or res.stderr).strip().splitlines()
            out[name] = text[0] if text else ""
        except (OSError, subprocess.SubprocessError):
            out[name] = ""
    return out


_HLSL_CACHE: dict = {}


def hlsl_to_glsl(source: str, stage: str, entry: str, *, defines: tuple = (),
                 rename_outputs: tuple = (), name: str = "shader.hlsl") -> str:
    """Compile HLSL ``source`` (stage ``vert`` or ``comp``, entry point ``entry``) with glslang's HLSL
    front end to SPIR-V, then with spirv-cross to GLSL 4.50 (entry renamed ``main``; output
    ``rename_outputs[i]`` gets location i). Results are cached per process."""
    key = hashlib.sha256(repr((source, stage, entry, defines, rename_outputs)).encode()).hexdigest()
    if key in _HLSL_CACHE:
        return _HLSL_CACHE[key]
    glslang, cross = _tool("glslangValidator"), _tool("spirv-cross")
    with tempfile.TemporaryDirectory(prefix="lopcook-hlsl-") as tmp:
        src = Path(tmp) / name
        spv = Path(tmp) / "out.spv"
        src.write_text(source)
        cmd = [glslang, "-D", "-V", "-S", stage, "-e", entry, *[f"-D{d}" for d in defines], "-o", str(spv), str(src)]
        res = subprocess.run(cmd, capture_output=True, text=True)
        if res.returncode != 0:
            raise LopcookError("verify", name, f"glslang could not compile entry {entry}: "
                               f"{(res.stdout + res.stderr).strip()}", exit_code=EXIT_VERIFY_FAILED)
        cmd = [cross, str(spv), "--version", "450", "--no-es", "--rename-entry-point", entry, "main", stage]
        for loc, out in enumerate(rename_outputs):
            cmd += ["--rename-interface-variable", "out", str(loc), out]
        res = subprocess.run(cmd, capture_output=True, text=True)
        if res.returncode != 0:
            raise LopcookError("verify", name, f"spirv-cross could not translate entry {entry}: "
                               f"{res.stderr.strip()}", exit_code=EXIT_VERIFY_FAILED)
    _HLSL_CACHE[key] = res.stdout
    return res.stdout


# ---- vertex-shader decoding (transform feedback) ----------------------------------------------

_GLSL_VS_MAIN = """
out uvec3 lop_out_grid;
out vec3 lop_out_position;
out uint lop_out_level;

void main()
{
    uvec3 grid;
    vec3 position;
    uint level;
#ifdef LOP_CRACK_FREE
    lop_decode_crack_free(uint(gl_VertexID), grid, position, level);
#else
    lop_decode(uint(gl_VertexID), grid, position, level);
#endif
    lop_out_grid = grid;
    lop_out_position = position;
    lop_out_level = level;
}
"""

_HLSL_VS_MAIN = """
struct LopVerifyOut
{
    nointerpolation uint3 grid : LOP_GRID;
    float3 position : LOP_POSITION;
    nointerpolation uint level : LOP_LEVEL;
};

LopVerifyOut lop_verify_vs(uint j : SV_VertexID)
{
    LopVerifyOut o;
#ifdef LOP_CRACK_FREE
    lop_decode_crack_free(j, o.grid, o.position, o.level);
#else
    lop_decode(j, o.grid, o.position, o.level);
#endif
    return o;
}
"""

_PASSTHROUGH_VS = """#version 450
in vec3 in_position;
out vec3 lop_out_position;
void main() { lop_out_position = in_position; }
"""


def vertex_shader_source(language: str, crack_free: bool = False, clustered: bool = False) -> str:
    """GLSL 4.50 source of the verification vertex shader: the library of ``shaders/`` plus a main
    that writes grid integers, float position and level to transform feedback. ``clustered``
    defines ``LOP_CLUSTERED`` (the clustered layout, docs/format.md 6.9)."""
    if language == "glsl":
        head = "#version 450\n" + ("#define LOP_CRACK_FREE\n" if crack_free else "#define LOP_NO_VIEW\n")
        head += "#define LOP_CLUSTERED\n" if clustered else ""
        return head + "#line 1\n" + shader_source("decode_bitplanes.glsl") + _GLSL_VS_MAIN
    if language == "hlsl":
        defines = ("LOP_CRACK_FREE",) if crack_free else ("LOP_NO_VIEW",)
        defines += ("LOP_CLUSTERED",) if clustered else ()
        return hlsl_to_glsl(shader_source("decode_bitplanes.hlsl") + _HLSL_VS_MAIN, "vert", "lop_verify_vs",
                            defines=defines, rename_outputs=VARYINGS, name="decode_bitplanes.hlsl")
    raise ValueError(f"language must be one of {LANGUAGES}, got {language!r}")


def _table32(table) -> np.ndarray:
    """(25,) table -> (32,) uint32 padded with 0xFFFFFFFF (the shaders' binary search needs it)."""
    t = np.asarray(table, dtype=np.int64)
    if t.shape != (LEVELS + 1,):
        raise ValueError(f"tables have {LEVELS + 1} entries, got shape {t.shape}")
    if t.min() < 0 or t.max() >= 2**32:
        raise ValueError("table entries must fit in uint32 (at most 59 652 323 vertices per buffer)")
    out = np.full(32, 0xFFFFFFFF, dtype="<u4")
    out[: LEVELS + 1] = t
    return out


def decode_block(vertex_id, bit_id, level: int, origin, half_cell, words: int) -> bytes:
    """The 288 bytes of the LopDecode uniform block / cbuffer (std140 layout, see the shader header)."""
    origin = np.asarray(origin, dtype=np.float32)
    return b"".join([
        _table32(vertex_id).tobytes(), _table32(bit_id).tobytes(),
        np.array([origin[0], origin[1], origin[2], np.float32(half_cell)], dtype="<f4").tobytes(),
        np.array([int(level), max(int(words), 1), 0, 0], dtype="<u4").tobytes(),
    ])


def view_block(camera, level_dist, block_radius) -> bytes:
    """The 272 bytes of the LopView uniform block / cbuffer: camera, then the two (25,) float32 tables
    (``lopcook.verify.decoders.view_tables``), each padded to 32 entries with zeros."""
    cam = np.zeros(4, dtype="<f4")
    cam[:3] = np.asarray(camera, dtype=np.float32)
    out = [cam.tobytes()]
    for t in (level_dist, block_radius):
        pad = np.zeros(32, dtype="<f4")
        pad[: LEVELS + 1] = np.asarray(t, dtype=np.float32)
        out.append(pad.tobytes())
    return b"".join(out)


@dataclass
class Decoded:
    """GPU decode of a buffer: grid (n, 3) uint32, position (n, 3) float32 metres, level (n,) uint32
    (bits per component used: max(bin, B), or the per-vertex level on the crack-free path)."""

    grid: np.ndarray
    position: np.ndarray
    level: np.ndarray


class VertexDecoder:
    """The vertex-shader decoder of one language, run through transform feedback (rasterizer off).

    ``decode(words, vertex_id, bit_id, level, origin, half_cell)`` decodes every vertex
    ``j = gl_VertexID`` in ``[0, VertexId[24])``; with ``crack_free=True`` pass ``view=(camera,
    level_dist, block_radius)`` too.
    """

    def __init__(self, language: str, crack_free: bool = False, source: str | None = None):
        self.ctx = context()
        self.language = language
        self.crack_free = crack_free
        self.source = vertex_shader_source(language, crack_free) if source is None else source
        self.program = self.ctx.program(vertex_shader=self.source, varyings=VARYINGS)
        self.vao = self.ctx.vertex_array(self.program, [])

    def decode_clustered(self, words, records, cluster_id, vertex_id, cluster_size: int, level: int, origin,
                         half_cell, view=None) -> Decoded:
        """The clustered decode (for a decoder from ``clustered_vertex_decoder``, whose shader has
        ``LOP_CLUSTERED``): as ``decode_clustered`` of this module, without its validation."""
        n = int(vertex_id[LEVELS])
        if n == 0:
            return Decoded(np.zeros((0, 3), np.uint32), np.zeros((0, 3), np.float32), np.zeros(0, np.uint32))
        words = np.ascontiguousarray(words, dtype="<u4")
        rec = np.ascontiguousarray(records, dtype="<u4")
        clusters = self.ctx.buffer(rec.tobytes() if rec.size else b"\0" * 16)
        clusters.bind_to_storage_buffer(3)
        try:
            block = cluster_decode_block(vertex_id, cluster_id, level, origin, half_cell, words.size, cluster_size)
            return self._transform(n, words, block, view)
        finally:
            clusters.release()

    def decode(self, words, vertex_id, bit_id, level: int, origin, half_cell, view=None) -> Decoded:
        n = int(vertex_id[LEVELS])
        if n == 0:
            return Decoded(np.zeros((0, 3), np.uint32), np.zeros((0, 3), np.float32), np.zeros(0, np.uint32))
        words = np.ascontiguousarray(words, dtype="<u4")
        return self._transform(n, words, decode_block(vertex_id, bit_id, level, origin, half_cell, words.size), view)

    def _transform(self, n: int, words, block: bytes, view) -> Decoded:
        ctx = self.ctx
        resources = [ctx.buffer(words.tobytes() if words.size else b"\0\0\0\0"), ctx.buffer(block)]
        resources[0].bind_to_storage_buffer(0)
        resources[1].bind_to_uniform_block(0)
        if self.crack_free:
            if view is None:
                raise ValueError("the crack-free decoder needs view=(camera, level_dist, block_radius)")
            resources.append(ctx.buffer(view_block(*view)))
            resources[2].bind_to_uniform_block(1)
        out = ctx.buffer(reserve=n * FEEDBACK.itemsize)
        try:
            import moderngl  # optional native GL binding, imported where GL runs (its POINTS constant)

            self.vao.transform(out, mode=moderngl.POINTS, vertices=n)
            rec = np.frombuffer(out.read(), dtype=FEEDBACK)
        finally:
            out.release()
            for r in resources:
                r.release()
        return Decoded(grid=rec["grid"].copy(), position=rec["position"].copy(), level=rec["level"].copy())

    def release(self) -> None:
        self.vao.release()
        self.program.release()


_DECODERS: dict = {}


def vertex_decoder(language: str, crack_free: bool = False) -> VertexDecoder:
    """Cached VertexDecoder per (language, crack_free, shader source) for this process's context."""
    source = vertex_shader_source(language, crack_free)
    key = (language, bool(crack_free), source)
    if key not in _DECODERS:
        _DECODERS[key] = VertexDecoder(language, crack_free, source)
    return _DECODERS[key]


# ---- clustered buffers (docs/format.md 6.9): vertex decoding --------------------------------------
#
# Layout (the contract between the CPU reference and these shaders; docs/format.md): vertices in
# (minimum level, Morton code) order, each bin cut into clusters of at most N vertices;
# ClusterId[k] = clusters in bins <= k; per cluster and component the shared prefix length k_t and
# anchor a_t, stored as 4 uint32 records (a_t | k_t << 24 for x, y, z, then ClusterBit[c] at the
# current level); P holds w_t = max(0, b - k_t) bits per component, clusters back to back.

#: uint32 words per cluster record (LopClusters)
CLUSTER_RECORD_WORDS = 4
#: bytes of the clustered LopDecode block
CLUSTER_DECODE_BLOCK_BYTES = 416
#: cluster sizes N the decoders accept (the contract's range; lop_div is exact there)
CLUSTER_SIZES = (16, 1024)


def check_cluster_tables(records, cluster_id, vertex_id, cluster_size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Validate a clustered buffer's tables and return them as ``(records (n_c, 4) uint32,
    cluster_id (25,) int64, vertex_id (25,) int64)``. Raises ValueError when the shapes disagree,
    ``cluster_size`` is outside ``CLUSTER_SIZES``, the buffer has 2^26 vertices or more, ClusterId[24] is not the number of records, a bin's
    cluster count is not ceil(bin vertices / N), or a k_t exceeds 24 / an anchor has more than
    k_t bits."""
    rec = np.ascontiguousarray(records, dtype=np.uint32).reshape(-1, CLUSTER_RECORD_WORDS)
    cid = np.asarray(cluster_id, dtype=np.int64)
    vid = np.asarray(vertex_id, dtype=np.int64)
    n = int(cluster_size)
    if cid.shape != (LEVELS + 1,) or vid.shape != (LEVELS + 1,):
        raise ValueError(f"ClusterId and VertexId have {LEVELS + 1} entries, got {cid.shape} and {vid.shape}")
    if not CLUSTER_SIZES[0] <= n <= CLUSTER_SIZES[1]:
        raise ValueError(f"cluster size {n} is outside [{CLUSTER_SIZES[0]}, {CLUSTER_SIZES[1]}]")
    if vid[LEVELS] >= 1 << 26:
        raise ValueError(f"{int(vid[LEVELS])} vertices exceed the clustered decoder's 2^26 per buffer")
    if int(cid[LEVELS]) != len(rec) or cid[0] != 0:
        raise ValueError(f"ClusterId[24] = {int(cid[LEVELS])} but {len(rec)} cluster records (ClusterId[0] must be 0)")
    per_bin = -(-np.diff(vid) // n)
    if np.any(np.diff(cid) != per_bin):
        raise ValueError("ClusterId does not cut each bin of VertexId into runs of the cluster size")
    k = rec[:, :3] >> np.uint32(24)
    a = rec[:, :3] & np.uint32(0xFFFFFF)
    if np.any(k > LEVELS) or np.any(a >> np.minimum(k, 31).astype(np.uint32) != 0):
        raise ValueError("a cluster record has k_t > 24 or an anchor wider than k_t bits")
    return rec, cid, vid


def cluster_decode_block(vertex_id, cluster_id, level: int, origin, half_cell, words: int,
                         cluster_size: int) -> bytes:
    """The 416 bytes of the clustered LopDecode uniform block / cbuffer (``LOP_CLUSTERED``): the
    288 bytes of ``decode_block`` with BitId zero and ``lop_params.z = cluster_size``, then
    ClusterId[0..24] padded to 32 entries with 0xFFFFFFFF."""
    base = bytearray(decode_block(vertex_id, np.zeros(LEVELS + 1, np.int64), level, origin, half_cell, words))
    base[272 + 8:272 + 12] = np.array([int(cluster_size)], dtype="<u4").tobytes()
    return bytes(base) + _table32(cluster_id).tobytes()


def clustered_vertex_decoder(language: str, crack_free: bool = False) -> "VertexDecoder":
    """Cached clustered VertexDecoder (``LOP_CLUSTERED``) per (language, crack_free, source)."""
    source = vertex_shader_source(language, crack_free, clustered=True)
    key = (language, bool(crack_free), source)
    if key not in _DECODERS:
        _DECODERS[key] = VertexDecoder(language, crack_free, source)
    return _DECODERS[key]


def decode_clustered(language: str, words, records, cluster_id, vertex_id, cluster_size: int, level: int,
                     origin, half_cell, view=None) -> Decoded:
    """Decode every vertex ``j`` in ``[0, VertexId[24])`` of a clustered buffer with the vertex
    shader of ``language`` (``shaders/decode_bitplanes.*`` with ``LOP_CLUSTERED``).

    ``words``: P at ``level`` (uint32); ``records``: (n_c, 4) uint32 cluster records whose word 3 is
    ClusterBit at ``level`` (the CPU reference's ``records(clusters, level)``); ``cluster_id``,
    ``vertex_id``: (25,) tables; ``cluster_size``: N; ``origin`` / ``half_cell``: the grid, rounded
    to float32 here. With ``view=(camera, level_dist, block_radius)`` the crack-free decode runs
    instead. Returns ``Decoded`` (grid, float32 position, bits per component), which must equal
    the unclustered decode at max(B, m_v) bits."""
    rec, cid, vid = check_cluster_tables(records, cluster_id, vertex_id, cluster_size)
    dec = clustered_vertex_decoder(language, crack_free=view is not None)
    return dec.decode_clustered(words, rec, cid, vid, cluster_size, level, origin, half_cell, view=view)


class Passthrough:
    """Float passthrough for the benchmark: a vertex shader that copies a float32 vec3 attribute
    (a standard vertex buffer, the paper's "UC" column) to transform feedback."""

    def __init__(self, positions):
        import moderngl  # optional native GL binding, imported where GL runs (its POINTS constant)

        self.ctx = context()
        self.program = self.ctx.program(vertex_shader=_PASSTHROUGH_VS, varyings=("lop_out_position",))
        self.vbo = self.ctx.buffer(np.ascontiguousarray(positions, dtype="<f4").tobytes())
        self.vao = self.ctx.vertex_array(self.program, [(self.vbo, "3f", "in_position")])
        self.n = len(positions)
        self.out = self.ctx.buffer(reserve=max(self.n, 1) * 12)
        self._mode = moderngl.POINTS

    def run(self) -> None:
        self.vao.transform(self.out, mode=self._mode, vertices=self.n)

    def read(self) -> np.ndarray:
        return np.frombuffer(self.out.read(), dtype="<f4").reshape(-1, 3)


# ---- compute shaders: precision adaption --------------------------------------------------------

_GLSL_KERNEL_DEFINE = {"unpack": "LOP_KERNEL_UNPACK", "add_plane": "LOP_KERNEL_ADD_PLANE",
                       "remove_plane": "LOP_KERNEL_REMOVE_PLANE", "tables": "LOP_KERNEL_TABLES",
                       "pack": "LOP_KERNEL_PACK"}
_HLSL_KERNEL_ENTRY = {"unpack": "lop_unpack_cs", "add_plane": "lop_add_plane_cs",
                      "remove_plane": "lop_remove_plane_cs", "tables": "lop_tables_cs", "pack": "lop_pack_cs"}


def compute_shader_source(language: str, kernel: str, clustered: bool = False) -> str:
    """GLSL 4.50 source of one adaption kernel (``KERNELS``); ``clustered`` defines ``LOP_CLUSTERED``."""
    if kernel not in KERNELS:
        raise ValueError(f"kernel must be one of {KERNELS}, got {kernel!r}")
    if language == "glsl":
        return (f"#version 450\n{'#define LOP_CLUSTERED' + chr(10) if clustered else ''}"
                f"#define {_GLSL_KERNEL_DEFINE[kernel]}\n#line 1\n" + shader_source("adapt_bitplanes.comp.glsl"))
    if language == "hlsl":
        return hlsl_to_glsl(shader_source("adapt_bitplanes.comp.hlsl"), "comp", _HLSL_KERNEL_ENTRY[kernel],
                            defines=("LOP_CLUSTERED",) if clustered else (), name="adapt_bitplanes.comp.hlsl")
    raise ValueError(f"language must be one of {LANGUAGES}, got {language!r}")


class AdaptBuffer:
    """One binned buffer resident on the GPU for adaption: P (``packed``), the tables SSBO, U.

    ``level`` is the level of ``packed`` (and of the tables); ``u_level`` the level U currently
    holds (None when U is stale). Use ``Adapter`` to change it."""

    def __init__(self, ctx, words, vertex_id, level: int):
        self.ctx = ctx
        self.vertex_id = np.asarray(vertex_id, dtype=np.int64)
        self.n = int(self.vertex_id[LEVELS])
        self.level = int(level)
        self.u_level = None
        words = np.ascontiguousarray(words, dtype="<u4")
        self.packed = ctx.buffer(words.tobytes() if words.size else b"\0\0\0\0")
        self.words = int(words.size)
        self.tables = ctx.buffer(_table32(self.vertex_id).tobytes()
                                 + _table32(table_bit_id(self.vertex_id, level)).tobytes())
        self.unpacked = ctx.buffer(reserve=max(12 * self.n, 4))

    def read_words(self) -> np.ndarray:
        """(w,) uint32 packed words at ``level``."""
        return np.frombuffer(self.packed.read(), dtype="<u4")[: self.words].copy()

    def read_tables(self) -> tuple[np.ndarray, np.ndarray]:
        """(32,) uint32 VertexId and BitId as the GPU holds them (entries 25..31: padding)."""
        t = np.frombuffer(self.tables.read(), dtype="<u4")
        return t[:32].copy(), t[32:64].copy()

    def read_unpacked(self) -> np.ndarray:
        return np.frombuffer(self.unpacked.read(), dtype="<u4")[: 3 * self.n].reshape(-1, 3).copy()

    def release(self) -> None:
        for b in (self.packed, self.tables, self.unpacked):
            b.release()


class Adapter:
    """The five adaption kernels of one language (section 6.1 of the paper), as compute shaders.

    Protocol (one plane at a time, as the shaders' header describes): ``unpack`` P -> U at the
    buffer's level; ``add_plane`` / ``remove_plane`` change U's level by one; ``repack`` rewrites
    BitId on the GPU (``tables`` kernel) and packs U into a new P. ``adapt(buf, target, plane)``
    does a whole change, plane by plane, each plane a full unpack / merge / tables / pack cycle.
    """

    def __init__(self, language: str, sources: dict | None = None):
        self.ctx = context()
        self.language = language
        self.sources = sources or {k: compute_shader_source(language, k) for k in KERNELS}
        self.kernels = {k: self.ctx.compute_shader(self.sources[k]) for k in KERNELS}

    def upload(self, words, vertex_id, level: int) -> AdaptBuffer:
        return AdaptBuffer(self.ctx, words, vertex_id, level)

    def _bind(self, buf) -> tuple:
        """Bind ``buf``'s SSBOs; returns the three uniform words after ``first``."""
        buf.packed.bind_to_storage_buffer(0)
        buf.unpacked.bind_to_storage_buffer(1)
        buf.tables.bind_to_storage_buffer(3)
        return (0, 0, 0)

    def _run(self, kernel: str, buf, params, threads: int, extra=()) -> None:
        ctx = self.ctx
        tail = self._bind(buf)
        for binding, b in extra:
            b.bind_to_storage_buffer(binding)
        shader = self.kernels[kernel]
        first = 0
        while True:
            groups = min(max((threads - first + LOCAL_SIZE - 1) // LOCAL_SIZE, 1), MAX_GROUPS)
            ubo = ctx.buffer(np.array([*params, first, *tail], dtype="<u4").tobytes())
            ubo.bind_to_uniform_block(0)
            shader.run(groups)
            ctx.memory_barrier()
            ubo.release()
            first += groups * LOCAL_SIZE
            if first >= threads:
                break

    def unpack(self, buf: AdaptBuffer) -> None:
        """U <- P at ``buf.level`` (one thread per vertex)."""
        self._run("unpack", buf, (buf.level, buf.n, 0, max(buf.words, 1)), buf.n)
        buf.u_level = buf.level

    def add_plane(self, buf: AdaptBuffer, plane_words, bit_offset: int = 0) -> None:
        """U's level L -> L + 1: merge plane L + 1 (uint32 words; bit ``bit_offset + 3 j + c`` is the
        new bit of component c of vertex j < VertexId[L])."""
        p = buf.u_level + 1
        if not 2 <= p <= LEVELS:
            raise ValueError(f"cannot add plane {p}")
        self._before_plane(buf, p)
        count = int(buf.vertex_id[p - 1])
        data = np.ascontiguousarray(plane_words, dtype="<u4").tobytes() or b"\0\0\0\0"
        plane = self.ctx.buffer(data)
        try:
            if count:
                self._run("add_plane", buf, (p, count, int(bit_offset), 0), count, extra=[(2, plane)])
        finally:
            plane.release()
        buf.u_level = p

    def _before_plane(self, buf, p: int) -> None:
        """Hook run before plane ``p`` is merged (the clustered adapter's tables kernel)."""

    def remove_plane(self, buf: AdaptBuffer) -> None:
        """U's level L -> L - 1: zero bit 24 - L of the vertices of bins below L."""
        b = buf.u_level
        if not 2 <= b <= LEVELS:
            raise ValueError(f"cannot remove a plane below level {b}")
        count = int(buf.vertex_id[b - 1])
        if count:
            self._run("remove_plane", buf, (b, count, 0, 0), count)
        buf.u_level = b - 1

    def repack(self, buf: AdaptBuffer) -> None:
        """P <- U at U's level: BitId rewritten on the GPU, then one thread per word of the new P
        (sized on the CPU from VertexId: ``buffer_bytes``)."""
        level = buf.u_level
        self._run("tables", buf, (level, 1, 0, 0), 1)
        nwords = buffer_bytes(buf.vertex_id, level) // 4
        out = self.ctx.buffer(reserve=max(nwords, 1) * 4)
        self._run("pack", buf, (level, nwords, 0, 0), nwords, extra=[(4, out)])
        buf.packed.release()
        buf.packed = out
        buf.words = nwords
        buf.level = level

    def adapt(self, buf: AdaptBuffer, target: int, plane) -> None:
        """Change ``buf`` to level ``target`` one plane at a time (unpack, add or remove one plane,
        tables, pack for each). ``plane(p)`` returns (words, bit_offset) of refinement plane p."""
        if not 1 <= target <= LEVELS:
            raise ValueError(f"target level {target} is outside [1, {LEVELS}]")
        while buf.level != target:
            self.unpack(buf)
            if buf.level < target:
                self.add_plane(buf, *plane(buf.level + 1))
            else:
                self.remove_plane(buf)
            self.repack(buf)

    def release(self) -> None:
        for k in self.kernels.values():
            k.release()


# ---- clustered buffers (docs/format.md 6.9): adaption ----------------------------------------------

def clustered_bits(records, cluster_id, vertex_id, cluster_size: int, level: int) -> tuple[int, int]:
    """(bits of P, bits of plane ``level`` in this buffer's slice) of a clustered buffer at
    ``level``, from the tables the CPU holds (what it needs to size buffers; no read-back):
    sum over clusters of count_c * sum_t max(0, max(m_c, B) - k_t), and of count_c * #{t : k_t < p}
    over clusters with m_c < p."""
    rec, cid, vid = check_cluster_tables(records, cluster_id, vertex_id, cluster_size)
    k = (rec[:, :3] >> np.uint32(24)).astype(np.int64)
    c = np.arange(len(rec), dtype=np.int64)
    i = np.searchsorted(cid, c, side="right") - 1  # bin i + 1
    count = np.minimum(int(cluster_size), vid[i + 1] - vid[i] - (c - cid[i]) * int(cluster_size))
    b = np.maximum(i + 1, int(level))[:, None]
    bits = int((count * np.maximum(b - k, 0).sum(axis=1)).sum())
    plane = int((count * (k < level).sum(axis=1) * (i + 1 < level)).sum())
    return bits, plane


class ClusteredAdaptBuffer:
    """One clustered buffer resident on the GPU for adaption: P (``packed``), the tables SSBO
    (VertexId, BitId, ClusterId: 384 bytes), the cluster records (``clusters``, word 3 = ClusterBit
    at ``level``), PlaneBit (``plane_bit``) and U. Use ``ClusteredAdapter`` to change its level."""

    def __init__(self, ctx, words, records, cluster_id, vertex_id, cluster_size: int, level: int):
        rec, cid, vid = check_cluster_tables(records, cluster_id, vertex_id, cluster_size)
        self.ctx = ctx
        self.vertex_id, self.cluster_id, self.cluster_size = vid, cid, int(cluster_size)
        self.records = rec.copy()  # words 0-2 (the CPU's copy; word 3 lives on the GPU)
        self.n = int(vid[LEVELS])
        self.n_clusters = len(rec)
        self.level = int(level)
        self.u_level = None
        words = np.ascontiguousarray(words, dtype="<u4")
        self.packed = ctx.buffer(words.tobytes() if words.size else b"\0\0\0\0")
        self.words = int(words.size)
        self.tables = ctx.buffer(_table32(vid).tobytes() + np.zeros(32, "<u4").tobytes() + _table32(cid).tobytes())
        self.clusters = ctx.buffer(rec.astype("<u4").tobytes() if rec.size else b"\0" * 16)
        self.plane_bit = ctx.buffer(reserve=4 * (self.n_clusters + 1))
        self.unpacked = ctx.buffer(reserve=max(12 * self.n, 4))

    def bits(self, level: int) -> tuple[int, int]:
        return clustered_bits(self.records, self.cluster_id, self.vertex_id, self.cluster_size, level)

    def read_words(self) -> np.ndarray:
        return np.frombuffer(self.packed.read(), dtype="<u4")[: self.words].copy()

    def read_tables(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(32,) uint32 VertexId, BitId (= ClusterBit[ClusterId[k]] after the tables kernel), ClusterId."""
        t = np.frombuffer(self.tables.read(), dtype="<u4")
        return t[:32].copy(), t[32:64].copy(), t[64:96].copy()

    def read_records(self) -> np.ndarray:
        """(n_c, 4) uint32 cluster records as the GPU holds them."""
        return np.frombuffer(self.clusters.read(), dtype="<u4")[: 4 * self.n_clusters].reshape(-1, 4).copy()

    def read_plane_bit(self) -> np.ndarray:
        """(n_c + 1,) uint32 PlaneBit of the last tables kernel's level."""
        return np.frombuffer(self.plane_bit.read(), dtype="<u4")[: self.n_clusters + 1].copy()

    def read_unpacked(self) -> np.ndarray:
        return np.frombuffer(self.unpacked.read(), dtype="<u4")[: 3 * self.n].reshape(-1, 3).copy()

    def release(self) -> None:
        for b in (self.packed, self.tables, self.clusters, self.plane_bit, self.unpacked):
            b.release()


class ClusteredAdapter(Adapter):
    """The adaption kernels compiled with ``LOP_CLUSTERED`` (protocol in adapt_bitplanes.comp.glsl):
    ``unpack`` at the buffer's level; ``add_plane`` runs the tables kernel at the new level first
    (PlaneBit of the plane, word 3) and merges the plane; ``remove_plane`` zeroes the lowest bit;
    ``repack`` runs the tables kernel (unless ``add_plane`` already did for that level) and packs."""

    def __init__(self, language: str, sources: dict | None = None):
        sources = sources or {k: compute_shader_source(language, k, clustered=True) for k in KERNELS}
        super().__init__(language, sources)

    def upload(self, words, records, cluster_id, vertex_id, cluster_size: int, level: int) -> ClusteredAdaptBuffer:
        return ClusteredAdaptBuffer(self.ctx, words, records, cluster_id, vertex_id, cluster_size, level)

    def _bind(self, buf) -> tuple:
        super()._bind(buf)
        buf.clusters.bind_to_storage_buffer(5)
        buf.plane_bit.bind_to_storage_buffer(6)
        return (buf.cluster_size, buf.n_clusters, 0)

    def unpack(self, buf) -> None:
        self._run("unpack", buf, (buf.level, buf.n, 0, max(buf.words, 1)), buf.n)
        buf.u_level = buf.level
        buf.tables_level = buf.level

    def tables(self, buf, level: int) -> None:
        """Word 3 of every record = ClusterBit at ``level``, PlaneBit of plane ``level``, BitId."""
        self._run("tables", buf, (level, 1, 0, 0), 1)
        buf.tables_level = level

    def _before_plane(self, buf, p: int) -> None:
        """The tables kernel at p: PlaneBit of plane p, which ``add_plane``'s merge reads (the
        plane's words hold this buffer's slice laid out as the spec's refinement plane: per cluster
        with m_c < p, per vertex, the components with k_t < p)."""
        self.tables(buf, p)

    def repack(self, buf) -> None:
        level = buf.u_level
        if getattr(buf, "tables_level", None) != level:
            self.tables(buf, level)
        nwords = max((buf.bits(level)[0] + 31) // 32, 1)
        out = self.ctx.buffer(reserve=nwords * 4)
        self._run("pack", buf, (level, nwords, 0, 0), nwords, extra=[(4, out)])
        buf.packed.release()
        buf.packed = out
        buf.words = nwords
        buf.level = level


_CLUSTERED_ADAPTERS: dict = {}


def clustered_adapter(language: str) -> ClusteredAdapter:
    """Cached ClusteredAdapter per (language, shader sources) for this process's context."""
    sources = {k: compute_shader_source(language, k, clustered=True) for k in KERNELS}
    key = (language, tuple(sources[k] for k in KERNELS))
    if key not in _CLUSTERED_ADAPTERS:
        _CLUSTERED_ADAPTERS[key] = ClusteredAdapter(language, sources)
    return _CLUSTERED_ADAPTERS[key]


_ADAPTERS: dict = {}


def adapter(language: str) -> Adapter:
    """Cached Adapter per (language, shader sources) for this process's context."""
    sources = {k: compute_shader_source(language, k) for k in KERNELS}
    key = (language, tuple(sources[k] for k in KERNELS))
    if key not in _ADAPTERS:
        _ADAPTERS[key] = Adapter(language, sources)
    return _ADAPTERS[key]


__all__ = ["LANGUAGES", "KERNELS", "context", "use_default_framebuffer", "context_info", "gl_available", "hlsl_tools_available",
           "require_hlsl_tools", "tool_versions", "hlsl_to_glsl", "vertex_shader_source", "compute_shader_source", "decode_block",
           "view_block", "Decoded", "VertexDecoder", "vertex_decoder",
           "Passthrough", "AdaptBuffer", "Adapter",
           "adapter", "CLUSTER_RECORD_WORDS", "CLUSTER_DECODE_BLOCK_BYTES", "CLUSTER_SIZES", "check_cluster_tables", "cluster_decode_block",
           "clustered_vertex_decoder", "decode_clustered", "clustered_bits", "ClusteredAdaptBuffer", "ClusteredAdapter",
           "clustered_adapter"]
