"""The ``lopcook`` commands: each ``cmd_NAME(args)`` runs one command on its parsed flags
(``lopcook.cli.parser``) and prints its result (text, or JSON with ``--json``; nothing with
``--quiet`` but errors), returning the exit code (``lopcook.errors``: 0 ok, 1 verification
failed). Bad input raises ``LopcookError``, which ``lopcook.cli.main`` turns into one line and
exit 2. ``COMMANDS`` maps each command's name to its function (``batch``: ``lopcook.batch.command``).
"""

from __future__ import annotations

import json
import math
import os
import shlex
import sys
import time
from pathlib import Path

from .. import api
from ..analyse import analyse
from ..analyse.summary import describe_analysis, format_analysis
from ..bench.compare import DEFAULT_LEVELS
from ..bench.peers import PEERS
from ..bench.run import run as run_bench
from ..cookjob import CookOutputs, cook_file
from ..lop.container import read
from ..emit.gltf_writer import write_gltf
from ..emit.preview import preview, source_candidates
from ..emit.web import write_web_gltf
from ..atomic import write_atomic
from ..lop.reader import decode_positions, lod_attributes, positions_f32, world_attributes
from ..lop.codecs import CODECS
from ..lop.summary import describe_container, format_container
from ..errors import EXIT_OK, EXIT_VERIFY_FAILED, LopcookError
from ..hierarchy.container import refine
from ..ingest import load, sniff
from ..ingest.build import regular_file_problem
from ..ingest.summary import describe_scene, format_scene
from ..memory import release_free_memory
from ..outputs import check_not_input, check_output
from ..progress import make
from ..report import analysis_warnings, build_report, render_for_report, write_html
from ..report.verdict import verdict_line
from ..settings import DEFAULTS as D
from ..settings import parse_resolution
from ..tune.attributes import format_search
from ..tune.budget import format_budget
from ..tune.calibrate import format_calibration
from ..tune.recook import recook
from ..verify.decoders import format_report, parse_levels, verify_decoders
from ..verify.evaluate import evaluate, levels_in_file
from ..verify.tables import format_table
from ..version import __version__
from ..wording import plural
from ..view import ViewerServer, viewer_site
from .parser import (analyse_settings, check_views, ingest_settings, parse_xyz, settings_from_args,
                     source_ingest_settings)


def cmd_analyse(args) -> int:
    settings = analyse_settings(args)
    scene = load(args.source, ingest_settings(args))
    desc = describe_analysis(analyse(scene, settings), args.source)
    if args.json:
        print(json.dumps(desc, indent=1, sort_keys=True))
    elif not args.quiet:
        print(format_analysis(desc))
    return EXIT_OK


def _progress(args):
    """The run's Progress (``--progress``; lopcook.progress): a bar on a terminal unless --quiet or
    --json, nothing off a terminal, plain lines for CI logs."""
    if getattr(args, "_progress", None) is None:
        args._progress = make(getattr(args, "progress", "auto"), quiet=args.quiet, json=getattr(args, "json", False))
    return args._progress


def _print_warnings(args, lines: list[str], kind: str = "warning") -> None:
    """Warnings on stderr (``lopcook: warning: ...``) unless --quiet (``--strict`` made them errors
    before they reach here: ``lopcook.cookjob``); ``kind="note"`` for information."""
    if not args.quiet:
        for line in lines:
            print(f"lopcook: {kind}: {line}", file=sys.stderr)
        sys.stderr.flush()


#: ``cook`` prints up to this many LOD notes one by one, more as one line (``_fallback_summary``)
NOTE_LINES = 3


def _fallback_summary(lines: list[str]) -> list[str]:
    """``cook``'s notes on backend fallbacks that still reached their targets
    (``lopcook.simplify.chain_notes``): each line when there are at most ``NOTE_LINES``, else one
    line with the count and the first (``cook --json`` lists all of them in ``lod_notes``)."""
    if len(lines) <= NOTE_LINES:
        return lines
    return [f"{len(lines):,} LOD backend fallbacks reached their targets anyway (first: {lines[0]}; all: "
            f"cook --json, lod_notes)"]


def _is_container(path: str) -> bool:
    """Whether ``path`` names a container: a ``.lop`` name, or a regular file that starts with the
    container's magic (a FIFO or device is not opened here: reading it could block; the loaders
    reject it with their own message)."""
    if path.lower().endswith(".lop"):
        return True
    if regular_file_problem(path) is not None:
        return False
    try:
        with open(path, "rb") as fh:
            return fh.read(4) == b"LOPC"
    except OSError:
        return False


def cmd_cook(args) -> int:
    settings = settings_from_args(args)
    outputs = CookOutputs(args.output, args.depfile, strict=bool(args.strict))
    desc, result = cook_file(args.source, settings, outputs, progress=_progress(args),
                             warn=lambda lines: _print_warnings(args, lines),
                             note=lambda lines: _print_warnings(args, _fallback_summary(lines), "note"))
    _print_cook(args, desc, result)
    return EXIT_OK


def _print_cook(args, desc: dict, result) -> None:
    if args.json:
        print(json.dumps(desc, indent=1, sort_keys=True))
        return
    if args.quiet:
        return
    if result.calibration is not None:
        print(format_calibration(result.calibration))
    if result.budget is not None:
        print(format_budget(result.budget))
    if result.attribute_search is not None:
        print(format_search(result.attribute_search))
    print(format_container(dict(desc, lod_warnings=[]), timings=desc["timings_s"]))  # warnings went to stderr
    an = result.analysis
    if an.touching or an.intersecting:
        print(f"  note: {len(an.touching):,} touching and {plural(len(an.intersecting), 'intersecting part pair')} "
              f"(depth levels capped at {an.settings.depth_ceiling}; see lopcook analyse)")


def cmd_calibrate(args) -> int:
    settings = settings_from_args(args)
    scene = api.load(args.source, settings)
    cal = api.calibration(scene, settings, _progress(args))
    if args.json:
        print(json.dumps(cal, indent=1, sort_keys=True))
    elif not args.quiet or not cal["reached"]:
        print(format_calibration(cal))
        if cal["reached"]:
            print(f"  apply it: lopcook cook {args.source} -o OUT.lop --eps {cal['eps']:.6g} "
                  f"--edge-eps {cal['edge_eps']:.6g} (or cook --target-psnr {cal['target_psnr']:g} to search again)")
    return EXIT_OK if cal["reached"] else EXIT_VERIFY_FAILED


def _check_gltf_output(args) -> None:
    """``decode``/``refine -o``: a .glb, or a .gltf and its .bin, never the container read."""
    check_output(args.output, "-o", extensions=(".glb", ".gltf"), what="a glTF 2.0 file", inputs=(args.container,))
    if args.output.lower().endswith(".gltf"):
        check_output(str(Path(args.output).with_suffix(".bin")), "-o's .bin", extensions=(".bin",),
                     what="the glTF buffer", inputs=(args.container,))


def cmd_decode(args) -> int:
    if args.output is None and args.positions is None:
        raise LopcookError("usage", args.container, "nothing to write", hint="give -o OUT.glb and/or --positions OUT.f32")
    if not 1 <= args.level <= 24:
        raise LopcookError("usage", None, f"--level {args.level} is outside [1, 24]")
    if args.output is not None:
        _check_gltf_output(args)
    if args.positions is not None:
        check_output(args.positions, "--positions", extensions=(".f32",), what="float32 positions",
                     inputs=(args.container,), required=False)
    c = read(args.container, allow_prefix=True)  # a prefix decodes at the levels it holds (format.md 8)
    if args.output is None:
        return _decode_positions(args, c)
    source_in = tuple(source_candidates(args.container, c.manifest, args.source))  # materials are read from them
    check_not_input(args.output, "-o", source_in)
    if args.output.lower().endswith(".gltf"):
        check_not_input(str(Path(args.output).with_suffix(".bin")), "-o's .bin", source_in)
    parts = c.manifest["parts"]
    deepest = max(len(p["lods"]) for p in parts)
    if not 0 <= args.lod < deepest:
        raise LopcookError("usage", args.container, f"--lod {args.lod}: no part has LOD {args.lod} (the container has "
                           f"LODs 0..{deepest - 1})")
    _check_prefix_level(c, args)
    meshes, coarsest, lods = [], [], []
    for i, part in enumerate(parts):
        # a part whose chain stopped early (too few triangles, or a LOD no distance selects) is
        # drawn with its coarsest LOD at every farther distance: decode that, as a renderer would
        lod = min(args.lod, len(part["lods"]) - 1)
        lods.append(lod)
        if lod != args.lod:
            coarsest.append(part["name"])
        _, _, pos = decode_positions(c, i, lod, args.level)
        a = lod_attributes(c, i, lod, unit_directions=True)
        meshes.append({"name": part["name"], "positions": pos, "indices": a["indices"],
                       **world_attributes(c, i, {x.name: a[x.name] for x in CODECS})})
    if coarsest and not args.quiet and not args.json:
        one = len(coarsest) == 1
        print(f"lopcook: note: {len(coarsest):,} of {plural(len(parts), 'part')} {'has' if one else 'have'} "
              f"no LOD {args.lod}; {'its' if one else 'their'} coarsest LOD is used "
              f"({', '.join(coarsest[:3])}{', ...' if len(coarsest) > 3 else ''})", file=sys.stderr)
    pv = preview(c, args.container, meshes, lods, args.source)
    if not args.quiet:
        for w in pv["warnings"]:
            print(f"lopcook: warning: {w}", file=sys.stderr)
    written = write_gltf(args.output, pv["meshes"], generator=f"lopcook {__version__}", materials=pv["materials"],
                         nodes=pv["nodes"], extras={"lopcook": {"level": args.level, "lod": args.lod,
                                                               "source": c.manifest["source"]["file"]}})
    if args.json:
        print(json.dumps({"written": [str(w) for w in written], "level": args.level, "lod": args.lod,
                          "parts": len(meshes), "parts_at_coarsest_lod": coarsest,
                          "materials": len((pv["materials"] or {}).get("materials", [])),
                          "instances": pv["instances"], "max_instancing_offset_m": pv["max_instancing_offset_m"],
                          "warnings": pv["warnings"]}, sort_keys=True))
    elif not args.quiet:
        print(f"{args.output}: {plural(len(meshes), 'mesh', 'meshes')} decoded at level {args.level}, LOD {args.lod}")
    if args.positions is not None:
        _decode_positions(args, c, quiet=True)
    return EXIT_OK


def _decode_positions(args, c, quiet: bool = False) -> int:
    """``decode --positions``: ``lop.reader.positions_f32`` written atomically (the checks of
    ``decode``: a LOD no part has, or a level the file does not hold, exit 2)."""
    deepest = max(len(p["lods"]) for p in c.manifest["parts"])
    if not 0 <= args.lod < deepest:
        raise LopcookError("usage", args.container, f"--lod {args.lod}: no part has LOD {args.lod} (the container has "
                           f"LODs 0..{deepest - 1})")
    data = positions_f32(c, args.level, args.lod)
    write_atomic(args.positions, data)
    if args.json and not quiet:
        print(json.dumps({"positions": args.positions, "level": args.level, "lod": args.lod, "bytes": len(data),
                          "vertices": len(data) // 12, "parts": len(c.manifest["parts"])}, sort_keys=True))
    elif not args.quiet and not quiet:
        print(f"{args.positions}: {plural(len(data) // 12, 'vertex', 'vertices')} decoded at level {args.level}, "
              f"LOD {args.lod}")
    return EXIT_OK


def _check_prefix_level(c, args) -> None:
    """``decode --level B`` of a file that holds less (a prefix, format.md 8 and 14.4): one usage
    error naming the first buffer below B and the levels the file holds."""
    for i, part in enumerate(c.manifest["parts"]):
        lod = min(args.lod, len(part["lods"]) - 1)
        have = c.level_of(i, lod)
        if args.level > have:
            held = f"holds levels up to {have}" if have else "has not arrived"
            raise LopcookError("usage", args.container, f"--level {args.level}: part {part['name']!r} LOD {lod} "
                               f"{held} in this file ({len(c.data):,} of {c.file_size:,} bytes)",
                               hint=f"use --level {have} or lower" if have else "use a coarser --lod or more of the file")


def cmd_web(args) -> int:
    _check_gltf_output(args)
    out = write_web_gltf(args.container, args.output, args.source)
    if not args.quiet:
        for w in out["warnings"]:
            print(f"lopcook: warning: {w}", file=sys.stderr)
    if args.json:
        print(json.dumps(out, sort_keys=True))
    elif not args.quiet:
        print(f"{args.output}: {plural(out['parts'], 'part')} of {args.container}, "
              f"{plural(out['materials'], 'material')}")
    return EXIT_OK


def cmd_view(args) -> int:
    site, info = viewer_site(args.container, args.source)
    server = ViewerServer(site, args.port)
    if not args.quiet:
        for w in info["warnings"]:
            print(f"lopcook: warning: {w}", file=sys.stderr)
    if args.json:
        print(json.dumps({"url": server.url, "container": args.container, "bytes": info["bytes"],
                          "materials": info["materials"]}, sort_keys=True), flush=True)
    elif not args.quiet:
        print(f"lopcook view: {args.container} ({plural(info['bytes'], 'byte')}, "
              f"{plural(info['materials'], 'material')}) at {server.url}  (Ctrl-C stops)", flush=True)
    try:
        server.serve_forever()
    except KeyboardInterrupt:  # the way to stop it: not an interruption of work
        pass
    finally:
        server.close()
    return EXIT_OK


def cmd_refine(args) -> int:
    camera, target = parse_xyz(args.camera, "--camera"), parse_xyz(args.target, "--target")
    viewport = parse_resolution(args.viewport, "--viewport")
    for flag, v, ok in (("--fov", args.fov, 0 < args.fov < 180), ("--pixel-error", args.pixel_error, args.pixel_error > 0)):
        if not (math.isfinite(v) and ok):
            raise LopcookError("usage", None, f"{flag} {v}: out of range (fov in (0, 180) degrees, pixel error > 0)")
    _check_gltf_output(args)
    c = read(args.container)
    meshes = refine(c, camera, target, fov=args.fov, viewport=viewport, pixel_error=args.pixel_error,
                    backface=args.backface)
    stats = [dict(m.pop("stats"), part=m["name"]) for m in meshes]
    written = write_gltf(args.output, meshes, generator=f"lopcook {__version__}",
                         extras={"lopcook": {"refine": {"camera": camera, "target": target, "fov": args.fov,
                                                        "viewport": list(viewport), "pixel_error": args.pixel_error,
                                                        "backface": args.backface},
                                             "source": c.manifest["source"]["file"]}})
    tri, full = sum(s["triangles"] for s in stats), sum(s["lod0_triangles"] for s in stats)
    if args.json:
        print(json.dumps({"written": [str(w) for w in written], "triangles": tri, "lod0_triangles": full,
                          "parts": stats}, sort_keys=True))
    elif not args.quiet:
        print(f"{args.output}: {plural(len(meshes), 'mesh', 'meshes')}, {tri:,} of {plural(full, 'LOD 0 triangle')} "
              f"(levels {min(s['level'] for s in stats)}-{max(s['level'] for s in stats)})")
    return EXIT_OK


def cmd_inspect(args) -> int:
    if _is_container(args.source):
        c = read(args.source, allow_prefix=True)  # a prefix: each buffer's available level (format.md 8)
        desc = describe_container(c, file_bytes=os.path.getsize(args.source))
        if args.json:
            print(json.dumps(desc, indent=1, sort_keys=True))
        elif not args.quiet:
            print(format_container(desc))
        return EXIT_OK
    scene = load(args.source, ingest_settings(args))
    desc = describe_scene(scene)
    if args.json:
        print(json.dumps(desc, indent=1, sort_keys=True))
    elif not args.quiet:
        print(format_scene(desc))
    return EXIT_OK


def _render_check(args, c, levels) -> dict:
    """``verify --source``: evaluate() + the thresholds; JSON-ready (images dropped)."""
    if args.min_psnr is None or not args.min_psnr == args.min_psnr:
        raise LopcookError("usage", None, "--min-psnr must be a number of dB")
    if args.max_depth_errors is not None and args.max_depth_errors < 0:
        raise LopcookError("usage", None, f"--max-depth-errors {args.max_depth_errors}: expected >= 0 pixels")
    views = check_views(args.views, "--views")
    resolution = parse_resolution(args.resolution, "--resolution")
    ingest = source_ingest_settings(args, c.manifest)
    scene = load(args.source, ingest)
    result = evaluate(c, scene, levels=levels, views=views, resolution=resolution)
    failures = []
    for row in result["levels"]:
        cap = row["cap"]
        value = cap[f"psnr_{args.psnr_stat}"]
        if value is not None and value < args.min_psnr:
            failures.append(f"level {row['level']}: CAP PSNR ({args.psnr_stat} over views) {value:.1f} dB < "
                            f"{args.min_psnr:g} dB")
        if args.max_depth_errors is not None and cap["depth_order_errors"] > args.max_depth_errors:
            failures.append(f"level {row['level']}: {cap['depth_order_errors']} CAP depth-order error pixels > "
                            f"{args.max_depth_errors}")
    result["thresholds"] = {"min_psnr": args.min_psnr, "psnr_stat": args.psnr_stat,
                            "max_depth_errors": args.max_depth_errors}
    result["failures"] = failures
    result["ok"] = not failures
    return result


def cmd_verify(args) -> int:
    if not args.decoders and args.source is None:
        raise LopcookError("usage", args.container, "nothing to verify: give --decoders and/or --source SOURCE",
                           hint="lopcook verify OUT.lop --decoders checks the GLSL/HLSL decoders bit for bit; "
                                "--source SOURCE renders AP and CAP against the float source")
    levels = parse_levels(args.levels, args.container) if args.levels is not None else None
    languages = tuple(v.strip().lower() for v in args.languages.split(",") if v.strip())
    if not languages or any(v not in ("glsl", "hlsl") for v in languages):
        raise LopcookError("usage", None, f"--languages {args.languages!r}: expected glsl, hlsl or glsl,hlsl")
    if args.source is not None:  # usage errors before any work
        check_views(args.views, "--views")
        parse_resolution(args.resolution, "--resolution")
    c = read(args.container, allow_prefix=True)
    report = {"container": args.container}
    ok = True
    if args.decoders:
        dec_levels = levels if levels is not None else list(range(1, c.available_level + 1))
        report["decoders"] = verify_decoders(c, dec_levels, languages, adapt=not args.no_adapt)
        ok = ok and report["decoders"]["ok"]
    if args.source is not None:
        render = _render_check(args, c, levels if levels is not None else levels_in_file(D.render.levels,
                                                                                          c.available_level))
        report["render"] = render
        ok = ok and render["ok"]
    report["ok"] = bool(ok)
    if args.json:
        print(json.dumps(report, indent=1, sort_keys=True))
    elif not args.quiet or not report["ok"]:
        if "decoders" in report:
            print(format_report(report["decoders"]))
        if "render" in report:
            r = report["render"]
            print(format_table(r))
            verdict = "ok" if r["ok"] else "FAILED: " + "; ".join(r["failures"])
            print(f"  thresholds: CAP PSNR ({args.psnr_stat} over views) >= {args.min_psnr:g} dB"
                  + ("" if args.max_depth_errors is None else f", depth-order errors <= {args.max_depth_errors}")
                  + f": {verdict}")
    return EXIT_OK if report["ok"] else EXIT_VERIFY_FAILED


def cmd_report(args) -> int:
    out = args.output
    inputs = (args.container, args.source)
    check_output(out, "-o", extensions=(".html", ".htm"), what="the HTML report (its JSON beside it)", inputs=inputs)
    check_output(str(Path(out).with_suffix(".json")), "-o's .json", extensions=(".json",), what="the report JSON",
                 inputs=inputs)
    views = check_views(args.views, "--views")
    resolution = parse_resolution(args.resolution, "--resolution")
    levels = parse_levels(args.levels, args.container) if args.levels is not None else None
    if not math.isfinite(args.min_psnr):
        raise LopcookError("usage", None, f"--min-psnr {args.min_psnr}: expected a number of dB")

    sniff(args.source)  # a missing file, a directory, a FIFO or device: its own one-line reason
    c = read(args.container, allow_prefix=True)
    if levels is None:
        levels = levels_in_file(D.render.levels, c.available_level)
    ingest = source_ingest_settings(args, c.manifest)
    progress = _progress(args)
    with progress.stage(f"ingest {os.path.basename(args.source)}"):
        t0 = time.perf_counter()
        scene = load(args.source, ingest)
        ingest_s = time.perf_counter() - t0
    warnings = cook = None
    if not args.no_analyse:
        # before the renders, and only its record kept: the re-cook's arrays are freed before the
        # renders' images accumulate, so the two peaks do not add up
        with progress.stage("re-cook (stage timings, warnings, determinism)"):
            cook = recook(c, scene, ingest_s=ingest_s, progress=progress)
            warnings = analysis_warnings(scene, cook.pop("analysis"))
        release_free_memory()
    ev, ev16, level_range = render_for_report(c, scene, levels=levels, views=views, resolution=resolution,
                                              progress=progress)
    desc = describe_container(c, file_bytes=os.path.getsize(args.container))
    with progress.stage("page"):
        rep = build_report(c, scene, ev, desc, warnings=warnings, uniform16=ev16, cook=cook, level_range=level_range,
                           min_psnr=args.min_psnr)
        html_path, json_path = write_html(rep, ev.get("images"), out)
    passed = rep["verdict"]["result"] == "PASS"
    if args.json:
        print(json.dumps(rep, indent=1, sort_keys=True))
    elif not args.quiet or not passed:
        if not args.quiet:
            print(format_table(ev))
        print(f"  {verdict_line(rep['verdict'])}")
        print(f"  wrote {html_path} and {json_path}")
    return EXIT_OK if passed else EXIT_VERIFY_FAILED


def cmd_bench(args) -> int:
    args.assets = list(args.assets) + list(args.more_assets)
    try:
        args.cook_args = shlex.split(args.cook_args)
    except ValueError as exc:
        raise LopcookError("usage", None, f"--cook-args {args.cook_args!r}: {exc}") from None
    args.levels = parse_levels(args.levels) if args.levels else list(DEFAULT_LEVELS)
    args.views = check_views(args.views, "--views")
    args.resolution = parse_resolution(args.resolution, "--resolution")
    try:
        args.bits = [int(b) for b in args.bits.split(",") if b.strip()]
    except ValueError:
        raise LopcookError("usage", None, f"--bits {args.bits!r}: expected integers such as 10,12,14,16") from None
    if not args.bits or any(not 1 <= b <= 16 for b in args.bits):
        raise LopcookError("usage", None, f"--bits {args.bits}: each must be in [1, 16]")
    peers = [v.strip().lower() for v in args.peers.split(",") if v.strip() and v.strip().lower() != "none"]
    if any(v not in PEERS for v in peers):
        raise LopcookError("usage", None, f"--peers {args.peers!r}: expected a subset of {','.join(PEERS)}")
    args.peers = peers
    if args.repeat < 1 or args.scaling_max_triangles < 1:
        raise LopcookError("usage", None, "--repeat and --scaling-max-triangles must be positive")
    args.argv = sys.argv[sys.argv.index("bench") + 1:] if "bench" in sys.argv else []
    summary = run_bench(args)
    if args.json:
        print(json.dumps(summary, indent=1, sort_keys=True, default=str))
    return EXIT_OK


COMMANDS = {"inspect": cmd_inspect, "analyse": cmd_analyse, "cook": cmd_cook, "decode": cmd_decode, "web": cmd_web,
            "view": cmd_view, "refine": cmd_refine,
            "verify": cmd_verify, "calibrate": cmd_calibrate, "report": cmd_report, "bench": cmd_bench}

__all__ = ["COMMANDS", "cmd_analyse", "cmd_bench", "cmd_calibrate", "cmd_cook", "cmd_decode", "cmd_inspect", "cmd_refine",
           "cmd_report", "cmd_verify", "cmd_view"]
