"""The streaming layout against the default layout (docs/format.md 14-15): bytes of the whole file
(as it is, gzip -9, zstd -19), where the first renderable state and every stage lie, the bytes a
streaming reader needs for the view of each harness camera level, what each section kind encodes
to, and the time of the rewrite against the cook it follows (measured in the same process).
Not a test. Usage::

    .venv/bin/python benchmarks/bench_stream.py [--corpus DIR] [--assets a,b] [--flags "--lods auto"]
        [--gltfpack PATH] [--cooked DIR] [-o OUT.json]

``--gltfpack``: also gltfpack -cc's whole file and its gzip -9 (the peer point of the streaming
target; the chess set, which gltfpack cannot read, is written as GLB first). ``--cooked DIR``: take
the default cooks from ``DIR/<source file name>.lods.lop`` (benchmarks/cook_hashes.sh's names)
instead of cooking (no cook time then). Prints a table per
asset; ``-o`` writes every figure as JSON.
"""

from __future__ import annotations

import argparse
import json
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from lopcook import api  # noqa: E402
from lopcook.cli.parser import build_parser, settings_from_args  # noqa: E402
from lopcook.lop.container import from_bytes  # noqa: E402
from lopcook.emit.stages import streamed  # noqa: E402
from lopcook.selection import select, viewing_of  # noqa: E402
from lopcook.verify.cameras import camera_distance  # noqa: E402

ASSETS = {"stanford-bunny": "stanford-bunny.obj", "DamagedHelmet": "DamagedHelmet/DamagedHelmet.gltf",
          "chess_set": "chess_set_flat.usdc"}
CAMERA_LEVELS = range(6, 13)


def squeezed(data: bytes, argv: list) -> int:
    """Bytes of ``data`` through a compressor command (stdin to stdout)."""
    return len(subprocess.run(argv, input=data, capture_output=True, check=True).stdout)


def bytes_for(c, wants: dict) -> int | None:
    """The shortest prefix (file bytes, at a section end) in which every buffer (part, lod) of
    ``wants`` decodes at its level: what a streaming reader must have received."""
    end, present = len(c.data) - sum(t["length"] for t in c.manifest["sections"]), set()
    for t in c.manifest["sections"]:
        end += t["length"]
        present.add(t["name"])
        levels = c.layout.levels(present)
        if all(levels[c.layout.stage_of[(i, k)]] >= b for (i, k), b in wants.items()):
            return end
    return None


def view_rows(default, stream) -> list[dict]:
    """Per harness camera level B (``verify.cameras.camera_distance``): each part's LOD there
    (``lopcook.selection``) and the bytes both layouts need to draw it at B (a placement at its
    converted level, ``Manifest.part_level``)."""
    m = stream.manifest
    rows = []
    for b in CAMERA_LEVELS:
        d = camera_distance(b, float(m["grid"]["extent"]), viewing_of(m))
        sel = select(m, d)
        # each part at its own level: a placement's shared buffer at the level its shift converts to (format.md 6.8)
        wants = {(i, k): min(stream.entries.part_level(i, lv), m["positions"]["max_level"]) for i, (k, lv) in enumerate(sel)}
        rows.append({"level": b, "distance_m": d, "lods": sorted({k for k, _ in sel}),
                     "triangles": sum(m["parts"][i]["lods"][k]["triangles"] for i, (k, _) in enumerate(sel)),
                     "default_bytes": bytes_for(default, wants), "stream_bytes": bytes_for(stream, wants)})
    return rows


def section_kinds(default, stream) -> dict:
    """Per section kind: decoded bytes, stored bytes in the streaming file, and how many are encoded."""
    out: dict = {}
    for t in stream.manifest["sections"]:
        kind = t["name"].rsplit("/", 1)[-1]
        kind = "planes" if kind.startswith("plane") or kind == "deferred" else kind
        r = out.setdefault(kind, {"sections": 0, "encoded": 0, "decoded_bytes": 0, "stored_bytes": 0})
        r["sections"] += 1
        r["encoded"] += "encoding" in t
        r["decoded_bytes"] += t.get("size", t["length"])
        r["stored_bytes"] += t["length"]
    return out


def gltfpack_point(exe: str, src: Path, scene, tmp: Path) -> dict:
    """gltfpack -cc of the geometry (an OBJ as it is; other sources as lopcook's ingest writes them to
    GLB without materials or textures, as ``lopcook bench`` feeds its peers): whole file, gzip -9."""
    from lopcook.emit.gltf_writer import write_gltf  # only with --gltfpack

    inp = src
    if src.suffix.lower() != ".obj":
        inp = tmp / "input.glb"
        write_gltf(inp, scene.parts, generator="bench_stream")
    out = tmp / "gltfpack_cc.glb"
    subprocess.run([exe, "-i", str(inp), "-o", str(out), "-cc"], check=True, capture_output=True)
    data = out.read_bytes()
    return {"bytes": len(data), "gzip9_bytes": squeezed(data, ["gzip", "-9", "-c"])}


def measure(name: str, src: Path, flags: list, gltfpack: str | None, tmp: Path, cooked: Path | None) -> dict:
    args = build_parser().parse_args(["cook", str(src), "-o", "x.lop", *flags])
    settings = settings_from_args(args)
    scene = api.load(src, settings) if gltfpack or cooked is None else None
    t0 = time.perf_counter()
    default = api.cook(scene, settings) if cooked is None else from_bytes((cooked / f"{src.name}.lods.lop").read_bytes())
    cook_s = time.perf_counter() - t0 if cooked is None else None
    t0 = time.perf_counter()
    stream = streamed(default)
    stream_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    from_bytes(stream.data)
    read_s = time.perf_counter() - t0
    files = {}
    for tag, c in (("default", default), ("stream", stream)):
        first = c.section_end(c.layout.stages[0].mandatory)
        files[tag] = {"bytes": len(c.data), "gzip9_bytes": squeezed(c.data, ["gzip", "-9", "-c"]),
                      "zstd19_bytes": squeezed(c.data, ["zstd", "-19", "-q", "-c"]),
                      "manifest_bytes": len(c.data) - 32 - sum(t["length"] for t in c.manifest["sections"]),
                      "first_renderable_bytes": first}
    stages = [{"stage": st.index, "level": st.level, "buffers": len(st.buffers),
               "triangles": sum(e["triangles"] for _, _, e in st.buffers),
               "bytes_renderable": stream.section_end(st.mandatory),
               "bytes_at_level": stream.section_end(st.sections()[-1])} for st in stream.layout.stages]
    out = {"asset": name, "flags": flags, "files": files, "stages": stages, "views": view_rows(default, stream),
           "sections": section_kinds(default, stream),
           "seconds": {"cook": cook_s, "to_stream": stream_s, "read_stream": read_s}}
    if gltfpack:
        out["gltfpack_cc"] = gltfpack_point(gltfpack, src, scene, tmp)
    return out


def report(r: dict) -> str:
    d, s = r["files"]["default"], r["files"]["stream"]
    pct = lambda v, whole: f"{v:,} B ({100.0 * v / whole:.1f} %)"  # noqa: E731
    lines = [f"== {r['asset']} ({' '.join(r['flags'])})",
             f"  file: default {d['bytes']:,} B (gzip -9 {d['gzip9_bytes']:,}, zstd -19 {d['zstd19_bytes']:,}); "
             f"stream {s['bytes']:,} B (gzip -9 {s['gzip9_bytes']:,}, zstd -19 {s['zstd19_bytes']:,}); "
             f"manifest {d['manifest_bytes']:,} / {s['manifest_bytes']:,} B",
             f"  first renderable: default {pct(d['first_renderable_bytes'], d['bytes'])}, "
             f"stream {pct(s['first_renderable_bytes'], s['bytes'])}",
             f"  time: cook {r['seconds']['cook'] or 0:.2f} s, to_stream {r['seconds']['to_stream']:.2f} s "
             f"({100.0 * r['seconds']['to_stream'] / (r['seconds']['cook'] or float('inf')):.1f} % of the cook), "
             f"reading the stream file {r['seconds']['read_stream']:.2f} s"]
    if "gltfpack_cc" in r:
        g = r["gltfpack_cc"]
        lines.append(f"  gltfpack -cc: {g['bytes']:,} B, gzip -9 {g['gzip9_bytes']:,} B")
    lines.append("  stages (level, buffers, triangles, bytes renderable, bytes at its level):")
    lines += [f"    {x['stage']:>3} L={x['level']:>2} {x['buffers']:>4} {x['triangles']:>9,} t "
              f"{pct(x['bytes_renderable'], s['bytes']):>26} {pct(x['bytes_at_level'], s['bytes']):>26}"
              for x in r["stages"]]
    lines.append("  harness cameras (level, distance, LODs, triangles, bytes default, bytes stream):")
    lines += [f"    B={v['level']:>2} d={v['distance_m']:.3g} m LODs {v['lods']} {v['triangles']:,} t: "
              f"{pct(v['default_bytes'], d['bytes'])} / {pct(v['stream_bytes'], s['bytes'])}" for v in r["views"]]
    lines.append("  sections of the stream file (kind: decoded -> stored, encoded/all):")
    lines += [f"    {k:>11}: {v['decoded_bytes']:>10,} -> {v['stored_bytes']:>10,} B "
              f"({100.0 * v['stored_bytes'] / max(v['decoded_bytes'], 1):.1f} %), {v['encoded']}/{v['sections']}"
              for k, v in sorted(r["sections"].items())]
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--corpus", type=Path, default=REPO.parent / "shared" / "corpus")
    p.add_argument("--assets", default=",".join(ASSETS))
    p.add_argument("--flags", default="--lods auto")
    p.add_argument("--gltfpack", default=None, help="a gltfpack executable (npm gltfpack 1.3.0)")
    p.add_argument("--cooked", type=Path, default=None, help="read the default cooks from DIR/<source>.lods.lop")
    p.add_argument("-o", "--output", type=Path, default=None)
    args = p.parse_args(argv)
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.assets.split(","):
            r = measure(name, args.corpus / ASSETS[name], shlex.split(args.flags), args.gltfpack, Path(tmp),
                        args.cooked)
            print(report(r), flush=True)
            results.append(r)
    if args.output:
        args.output.write_text(json.dumps(results, indent=1, sort_keys=True))
    return 0


if __name__ == "__main__":
    sys.exit(main())
