"""LOD stage of the chess set (pipeline.chains, --lods auto defaults) with LOPCOOK_LOD_WORKERS=1 and 2:
wall, CPU of the parent and its children, LODs. Usage: PYTHONPATH=. .venv/bin/python benchmarks/bench_lod_parallel.py 1 2
"""
import os, time, resource, sys
from lopcook.ingest import load
from lopcook import pipeline
from lopcook.settings import LodSpec, Settings, SimplifySettings
scene = load("/work/shared/corpus/chess_set_flat.usdc")
s = Settings(simplify=SimplifySettings(lods=LodSpec(auto=True)))
for w in sys.argv[1:]:
    os.environ["LOPCOOK_LOD_WORKERS"] = w
    t0 = time.perf_counter(); c0 = time.process_time(); ch0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    out, rep = pipeline.chains(scene, s, None)
    ch = resource.getrusage(resource.RUSAGE_CHILDREN)
    print(f"workers {w}: wall {time.perf_counter()-t0:.1f} s, cpu self {time.process_time()-c0:.1f} + children {ch.ru_utime+ch.ru_stime-ch0.ru_utime-ch0.ru_stime:.1f} s, LODs {sum(len(c) for c in out)}", os.getloadavg(), flush=True)
