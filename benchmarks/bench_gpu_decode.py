"""Time the reference shaders: vertex-shader decoding against a float passthrough, and the adaption
kernels (paper section 6), on whatever the EGL context runs on (llvmpipe without a GPU).

Not a test (pytest does not collect benchmarks/). Usage::

    .venv/bin/python benchmarks/bench_gpu_decode.py [SOURCE_OR_LOP] [--levels 6,8,10,12,16,24]
                                                    [--repeat 20] [--out bench-out/gpu_decode]
                                                    [--clustered N] [--adapt-off]

SOURCE_OR_LOP defaults to the corpus chess set (49 buffers, 774,281 vertices), cooked in-process.

Decode: one "frame" draws every buffer once through transform feedback (rasterizer off) with a
vertex shader that decodes vertex ``gl_VertexID`` and writes its float3 position (12 bytes, the
same output as the passthrough). Passthrough: the same frame from standard float32 vertex buffers
(a vec3 attribute copied to the output: the paper's "UC"). All buffers are resident; each frame
is timed to ``ctx.finish()``; the best of ``--repeat`` frames is reported, after one warm-up.
ratio = decode time / passthrough time (> 1: decoding is slower).

Clustered (``--clustered N``, issue 16): every buffer is also re-ordered and cut into clusters of N
vertices by the cluster layout's CPU reference (lopcook.lop.clusters once merged; until then the
reference in tests/verify/test_gpu_clusters.py), packed at each level and decoded by the ``LOP_CLUSTERED``
vertex shader, frames of both layouts alternating (both see the same machine load);
``{lang}_clustered_ratio`` = best clustered frame / best unclustered frame (the issue's target:
<= 1.3), ``{lang}_clustered_ratio_median`` the median of the per-pair ratios, ``clustered_bytes`` = P + 16 B per cluster.
``--adapt-off`` skips the adaption part.

Adapt: on the largest buffer, and on a synthetic ``--synthetic`` N-vertex buffer (1,000,000 by default;
minimum levels drawn from the container's histogram), each single-plane change B -> B + 1 (unpack, add the uploaded plane,
tables, pack) and B + 1 -> B (unpack, remove, tables, pack), best of ``--repeat``; vertices/s =
buffer vertices / seconds per plane step. Upload of the plane is included in the add step.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from lopcook.lop.binning import LEVELS  # noqa: E402
from lopcook.lop.bitplane import decode, reconstruct_float32  # noqa: E402
from lopcook.lop.reader import gpu_buffer  # noqa: E402
from lopcook.verify import gpu  # noqa: E402
from lopcook.verify.decoders import plane_source  # noqa: E402

LANGUAGES = list(gpu.LANGUAGES)  # --languages

GLSL_MAIN = """
out vec3 lop_out_position;
void main()
{
    uvec3 grid; vec3 position; uint level;
    lop_decode(uint(gl_VertexID), grid, position, level);
    lop_out_position = position;
}
"""

HLSL_MAIN = """
struct LopBenchOut { float3 position : LOP_POSITION; };
LopBenchOut lop_bench_vs(uint j : SV_VertexID)
{
    LopBenchOut o; uint3 grid; uint level;
    lop_decode(j, grid, o.position, level);
    return o;
}
"""


def container(path: str | None):
    from lopcook.analyse import analyse
    from lopcook.emit import build
    from lopcook.lop.container import from_bytes, read
    from lopcook.ingest import load

    if path is None:
        path = str(REPO.parent / "shared" / "corpus" / "chess_set_flat.usdc")
    if path.endswith(".lop"):
        return read(path), path
    scene = load(path)
    return from_bytes(build(scene, analyse(scene)), path), path


def decode_program(ctx, language: str, clustered: bool = False):
    if language == "glsl":
        src = ("#version 450\n#define LOP_NO_VIEW\n" + ("#define LOP_CLUSTERED\n" if clustered else "")
               + gpu.shader_source("decode_bitplanes.glsl") + GLSL_MAIN)
    else:
        src = gpu.hlsl_to_glsl(gpu.shader_source("decode_bitplanes.hlsl") + HLSL_MAIN, "vert", "lop_bench_vs",
                               defines=("LOP_NO_VIEW",) + (("LOP_CLUSTERED",) if clustered else ()),
                               rename_outputs=("lop_out_position",))
    return ctx.program(vertex_shader=src, varyings=("lop_out_position",))


def cluster_reference():
    """The cluster layout's CPU reference: lopcook.lop.clusters once merged, else the copy in
    tests/verify/test_gpu_clusters.py."""
    try:
        from lopcook.lop import clusters as ref  # noqa: F401
    except ImportError:
        sys.path.insert(0, str(REPO / "tests" / "verify"))
        import test_gpu_clusters as ref
    return ref


def clustered_buffers(c, buffers, size: int):
    """Per buffer: (q in clustered order, Clusters) from the container's level-24 grid integers and
    minimum levels (VertexId)."""
    from lopcook.lop.bitplane import to_grid

    ref = cluster_reference()
    out = []
    for i, k in buffers:
        b = gpu_buffer(c, i, k, LEVELS)
        q = to_grid(*decode(b.words, b.vertex_id, b.bit_id, LEVELS))
        levels = np.repeat(np.arange(1, LEVELS + 1), np.diff(np.asarray(b.vertex_id, dtype=np.int64)))
        bins = ref.cluster_order(q, levels)
        qb = q[bins.order]
        out.append((qb, ref.make_clusters(qb, bins.vertex_id, size)))
    return ref, out


def best_frame(ctx, draw, repeat: int) -> float:
    draw()
    ctx.finish()
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        draw()
        ctx.finish()
        best = min(best, time.perf_counter() - t0)
    return best


def interleaved(ctx, draw_a, draw_b, repeat: int) -> tuple[float, float, float]:
    """Frames of ``draw_a`` and ``draw_b`` alternately (so both see the same machine load): best
    time of each and the median of the per-pair ratios b / a."""
    draw_a(), draw_b()
    ctx.finish()
    ta, tb = [], []
    for _ in range(repeat):
        for draw, times in ((draw_a, ta), (draw_b, tb)):
            t0 = time.perf_counter()
            draw()
            ctx.finish()
            times.append(time.perf_counter() - t0)
    return min(ta), min(tb), float(np.median(np.asarray(tb) / np.asarray(ta)))


def bench_decode(c, levels, repeat: int, clustered: int = 0) -> list[dict]:
    import moderngl

    ctx = gpu.context()
    g = c.manifest["grid"]
    cell = g["extent"] / 2**24
    half = np.float32(cell / 2)
    buffers = [(i, k) for i, p in enumerate(c.manifest["parts"]) for k, _ in enumerate(p["lods"])]
    n_total = sum(c.manifest["parts"][i]["lods"][k]["vertices"] for i, k in buffers)
    out = ctx.buffer(reserve=12 * max(c.manifest["parts"][i]["lods"][k]["vertices"] for i, k in buffers))
    # passthrough: float32 positions at level 24 (the source, as a standard vertex buffer)
    floats = []
    for i, k in buffers:
        b = gpu_buffer(c, i, k, LEVELS)
        v, w = decode(b.words, b.vertex_id, b.bit_id, LEVELS)
        floats.append(gpu.Passthrough(reconstruct_float32(v, w, g["origin"], cell)))

    def pass_frame():
        for p in floats:
            p.vao.transform(out, mode=moderngl.POINTS, vertices=p.n)

    t_pass = best_frame(ctx, pass_frame, repeat)
    rows = []
    programs = {}
    for lang in LANGUAGES:
        if lang == "hlsl" and gpu.hlsl_tools_available() is not None:
            continue
        prog = decode_program(ctx, lang)
        programs[lang] = (prog, ctx.vertex_array(prog, []))
    cprograms, cbufs = {}, None
    if clustered:
        ref, cbufs = clustered_buffers(c, buffers, clustered)
        for lang in programs:
            prog = decode_program(ctx, lang, clustered=True)
            cprograms[lang] = (prog, ctx.vertex_array(prog, []))
    for level in levels:
        resident = []
        for i, k in buffers:
            b = gpu_buffer(c, i, k, level)
            words = ctx.buffer(b.words.astype("<u4").tobytes() or b"\0\0\0\0")
            ubo = ctx.buffer(gpu.decode_block(b.vertex_id, b.bit_id, level, g["origin"], half, b.words.size))
            resident.append((words, ubo, int(b.vertex_id[LEVELS]), b.words.size * 4))
        p_bytes = sum(r[3] for r in resident)
        row = {"level": level, "vertices": n_total, "packed_bytes": p_bytes, "float_bytes": 12 * n_total,
               "passthrough_s": t_pass}
        cres = []
        if clustered:
            from lopcook.lop.bitplane import top_bits

            for qb, cl in cbufs:
                widths = np.maximum(np.repeat(np.arange(1, LEVELS + 1), np.diff(cl.vertex_id)), level)
                cw = ref.pack_clustered(top_bits(qb, widths), cl, level)
                rec = ref.records(cl, level)
                cres.append((ctx.buffer(cw.astype("<u4").tobytes()), ctx.buffer(rec.astype("<u4").tobytes() or b"\0" * 16),
                             ctx.buffer(gpu.cluster_decode_block(cl.vertex_id, cl.cluster_id, level, g["origin"], half,
                                                                 cw.size, cl.size)),
                             len(qb), ref.clustered_bytes(cl, level)))
            row["cluster_size"] = clustered
            row["clustered_bytes"] = sum(r[4] for r in cres)
            row["clusters"] = sum(len(cl.count) for _, cl in cbufs)
        for lang, (prog, vao) in programs.items():
            def frame(vao=vao):
                for words, ubo, n, _ in resident:
                    words.bind_to_storage_buffer(0)
                    ubo.bind_to_uniform_block(0)
                    vao.transform(out, mode=moderngl.POINTS, vertices=n)

            if clustered:
                def cframe(vao=cprograms[lang][1]):
                    for words, recs, ubo, n, _ in cres:
                        words.bind_to_storage_buffer(0)
                        recs.bind_to_storage_buffer(3)
                        ubo.bind_to_uniform_block(0)
                        vao.transform(out, mode=moderngl.POINTS, vertices=n)

                t, tc, median = interleaved(ctx, frame, cframe, repeat)
                row[f"{lang}_clustered_s"] = tc
                row[f"{lang}_clustered_ratio"] = tc / t
                row[f"{lang}_clustered_ratio_median"] = median
            else:
                t = best_frame(ctx, frame, repeat)
            row[f"{lang}_s"] = t
            row[f"{lang}_ratio"] = t / t_pass
            row[f"{lang}_mvertices_per_s"] = n_total / t / 1e6
        for words, ubo, _, _ in resident:
            words.release()
            ubo.release()
        for r in cres:
            for b in r[:3]:
                b.release()
        rows.append(row)
        text = ", ".join(f"{lang} {row[f'{lang}_s'] * 1e3:.2f} ms ({row[f'{lang}_mvertices_per_s']:.1f} Mvert/s, "
                         f"ratio {row[f'{lang}_ratio']:.2f})" for lang in programs)
        if clustered:
            text += "; clustered N=%d (%d clusters, %.0f%% of float32 memory): " % (
                clustered, row["clusters"], 100 * row["clustered_bytes"] / (12 * n_total)) + ", ".join(
                f"{lang} {row[f'{lang}_clustered_s'] * 1e3:.2f} ms (x{row[f'{lang}_clustered_ratio']:.2f} of unclustered, "
                f"median of pairs x{row[f'{lang}_clustered_ratio_median']:.2f})"
                for lang in cprograms)
        print(f"decode B={level:2d}: {n_total:,} vertices, {p_bytes / (12 * n_total):.0%} of float32 memory: "
              f"passthrough {t_pass * 1e3:.2f} ms ({n_total / t_pass / 1e6:.1f} Mvert/s); {text}", flush=True)
    return rows


def synthetic(c, n: int, seed: int = 20111011):
    """A buffer of ``n`` vertices whose minimum levels follow the container's histogram, random grid
    integers: (vertex_id, words_at(level), plane(p))."""
    from lopcook.lop.binning import make_bins, vertex_widths
    from lopcook.lop.bitplane import pack, plane_bits, top_bits

    rng = np.random.default_rng(seed)
    hist = np.zeros(LEVELS + 1)
    for p in c.manifest["parts"]:
        for e in p["lods"]:
            hist += np.diff(np.asarray(e["vertex_id"], dtype=np.int64), prepend=0)
    hist[0] = 0
    bins = make_bins(rng.choice(np.arange(LEVELS + 1), size=n, p=hist / hist.sum()))
    q = rng.integers(0, 2**24, (n, 3)).astype(np.uint32)
    vid = bins.vertex_id

    def words_at(level):
        return pack(top_bits(q, vertex_widths(vid, level)), vid, level)

    def plane(p):
        bits = plane_bits(q, vid, p).ravel()
        bits = np.concatenate([bits, np.zeros(-bits.size % 32, np.uint8)])
        return np.packbits(bits, bitorder="little").view("<u4"), 0

    return vid, words_at, plane


def bench_adapt(c, levels, repeat: int, synthetic_n: int) -> list[dict]:
    """Single-plane adaption steps on the container's largest buffer and on a synthetic large one."""
    ctx = gpu.context()
    sizes = [(p["lods"][0]["vertices"], i) for i, p in enumerate(c.manifest["parts"])]
    n, part = max(sizes)
    cases = [(f"part {part}", gpu_buffer(c, part, 0, 1).vertex_id, lambda b: gpu_buffer(c, part, 0, b).words,
              plane_source(c, part, 0))]
    if synthetic_n:
        cases.append(("synthetic", *synthetic(c, synthetic_n)))
    rows = []
    for name, vid, words_at, plane in cases:
        n = int(vid[LEVELS])
        for lang in LANGUAGES:
            if lang == "hlsl" and gpu.hlsl_tools_available() is not None:
                continue
            ad = gpu.adapter(lang)
            for level in levels:
                if level >= LEVELS:
                    continue
                start = words_at(level)
                words, offset = plane(level + 1)
                best_add = best_remove = float("inf")
                kernels = {}
                for _ in range(repeat):
                    buf = ad.upload(start, vid, level)
                    ctx.finish()
                    t0 = time.perf_counter()
                    ad.unpack(buf)
                    ad.add_plane(buf, words, offset)
                    ad.repack(buf)
                    ctx.finish()
                    best_add = min(best_add, time.perf_counter() - t0)
                    t0 = time.perf_counter()
                    ad.unpack(buf)
                    ad.remove_plane(buf)
                    ad.repack(buf)
                    ctx.finish()
                    best_remove = min(best_remove, time.perf_counter() - t0)
                    for kname, fn in (("unpack", lambda: ad.unpack(buf)),
                                      ("add_plane", lambda: ad.add_plane(buf, words, offset)),
                                      ("repack", lambda: ad.repack(buf))):  # one add step, kernel by kernel
                        t0 = time.perf_counter()
                        fn()
                        ctx.finish()
                        kernels[kname] = min(kernels.get(kname, float("inf")), time.perf_counter() - t0)
                    buf.release()
                row = {"language": lang, "buffer": name, "vertices": n, "level": level, "add_s": best_add,
                       "remove_s": best_remove, "add_vertices_per_s": n / best_add,
                       "remove_vertices_per_s": n / best_remove, "kernels_s": kernels}
                rows.append(row)
                print(f"adapt {lang} {name} ({n:,} vertices) {level}->{level + 1}: {best_add * 1e3:.2f} ms "
                      f"({n / best_add / 1e6:.1f} Mvert/s; unpack {kernels['unpack'] * 1e3:.2f}, add "
                      f"{kernels['add_plane'] * 1e3:.2f}, tables+pack {kernels['repack'] * 1e3:.2f} ms), "
                      f"{level + 1}->{level}: {best_remove * 1e3:.2f} ms ({n / best_remove / 1e6:.1f} Mvert/s)",
                      flush=True)
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("source", nargs="?", default=None, help="source scene or .lop (default: corpus chess set)")
    ap.add_argument("--levels", default="6,8,10,12,16,24")
    ap.add_argument("--repeat", type=int, default=20)
    ap.add_argument("--synthetic", type=int, default=1_000_000, metavar="N",
                    help="also adapt a synthetic N-vertex buffer (0: skip)")
    ap.add_argument("--out", default=str(REPO / "bench-out" / "gpu_decode"))
    ap.add_argument("--clustered", type=int, default=0, metavar="N",
                    help="also decode every buffer in clusters of N vertices (issue 16 layout)")
    ap.add_argument("--adapt-off", action="store_true", help="skip the adaption kernels")
    ap.add_argument("--languages", default=",".join(gpu.LANGUAGES), help="glsl,hlsl (default both)")
    args = ap.parse_args(argv)
    levels = [int(v) for v in args.levels.split(",")]
    LANGUAGES[:] = [v for v in args.languages.split(",") if v]
    c, path = container(args.source)
    info = gpu.context_info()
    print(f"{path}: {info['renderer']} ({info['version']})", flush=True)
    result = {"source": Path(path).name, "device": info, "repeat": args.repeat,
              "decode": bench_decode(c, levels, args.repeat, args.clustered),
              "adapt": [] if args.adapt_off else bench_adapt(c, levels, max(3, args.repeat // 4), args.synthetic)}
    if args.clustered:
        result["cluster_size"] = args.clustered
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    name = "".join(ch if ch.isalnum() else "_" for ch in info["renderer"].split("(")[0].strip().lower())
    (out / f"{name}.json").write_text(json.dumps(result, indent=1, sort_keys=True))
    print(f"wrote {out / (name + '.json')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
