"""``lopcook bench``: lopcook against gltfpack, glTF-Transform and Draco on the same meshes, and how
the cook's cost grows with the mesh. Not collected by pytest; see docs/bench.md.

Modules, from the entry down: ``run`` (``run(opts)``: what the flags ask for), ``summary`` (checks,
tables, output files), ``compare`` (lopcook and the peers on one asset), ``scaling`` (cook cost
against triangles), ``attributes`` (``--attributes``: GPU bytes per vertex against PSNR),
``connectivity`` (``--connectivity``: hierarchy coding), ``streaming`` (``--streaming``: PSNR
against bytes received in the three.js viewer; ``browser`` runs its page in headless Chromium),
``render`` (peer outputs rendered against the source), ``charts``, ``peers`` (finding and running
the peer tools), ``draco_run`` (the Draco child process), ``metrics`` (pure measurements),
``common`` (what they share).
"""
