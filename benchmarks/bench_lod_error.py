"""LOD 0 -> LOD distance: the sampled measurement (``error.sampled_ref_to_lod``, what chains record)
against querying every LOD 0 vertex and the centroids that can matter (``error.measure_ref_to_lod``,
the former measurement), on meshoptimizer LODs of each mesh at 1/2 ... 1/16 from LOD 0. Not a test.

    PYTHONPATH=. .venv/bin/python benchmarks/bench_lod_error.py MESH [MESH ...]

Prints per LOD: both values, their CPU seconds, the sampled upper bound and the vertices queried.
"""
import sys, time
import numpy as np
from lopcook.ingest import load
from lopcook.simplify import backends as B, error as E
from lopcook.simplify.reference import Reference
from lopcook.types import MeshPart
for name in sys.argv[1:]:
    part = load(name).parts[0]
    ref = Reference(part)
    t0 = time.process_time(); ref.sample_order; to = time.process_time() - t0
    work, _ = B.prepare(part, "ignore")
    for ratio in (0.5, 0.25, 0.125, 0.0625):
        r = B.run_backend("meshopt", work, int(ratio * part.n_triangles), True, True)
        lod = MeshPart(name="l", positions=r.positions, indices=r.faces.astype(np.uint32))
        t0 = time.process_time(); full = E.measure_ref_to_lod(ref, lod); tf = time.process_time() - t0
        t0 = time.process_time(); m, b, n = E.sampled_ref_to_lod(ref, lod); ts = time.process_time() - t0
        print(f"{name.split('/')[-1]:<22} 1/{round(1/ratio):<3} full {full:.4g} ({tf:.2f}s) sampled {m:.4g} bound {b:.4g} n={n} of {ref.sample_order.n} ({ts:.2f}s, order {to:.2f}s) ratio {m/full:.3f}", flush=True)
