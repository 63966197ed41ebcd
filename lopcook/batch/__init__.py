"""``lopcook batch``: cook a whole asset tree, incrementally, locally in parallel or on a Dask cluster.

Every asset is cooked by exactly what ``lopcook cook SOURCE -o OUT [options]`` does (the worker
calls ``lopcook.cli.main`` in a fresh process), so a batch output has the same bytes as one
``lopcook cook`` per asset with the same options. The modules, in the order a batch uses them:

``discover``  SOURCES (files, directories searched recursively, manifests) -> ``Asset`` list
``config``    ``lopcook.toml``: per-glob cook options and excludes -> resolved options per asset
``keys``      depfile parsing, the incremental key, the state file ``OUTDIR/.lopcook-batch.json``
``worker``    one cook in a fresh process under a memory cap (``python -m lopcook.batch.worker``)
``local``     ``--jobs N`` worker processes on this machine
``cluster``   ``--scheduler tcp://HOST:PORT``: the same tasks on a Dask distributed cluster
``ninja``     ``--emit-ninja build.ninja``: the batch as a Ninja file of ``lopcook cook`` edges
``progress``  a bar on a terminal, one line per asset otherwise
``run``       plan (up-to-date check), execute, record, summarise
``cli``       the ``batch`` subcommand's flags and ``cmd_batch``

The user documentation, with the config format and measurements, is docs/batch.md.
"""

from __future__ import annotations

STATE_FILE = ".lopcook-batch.json"
#: per-cook scratch folders live here (under OUTDIR) and are removed after each cook
SCRATCH_DIR = ".lopcook-batch-tmp"

__all__ = ["STATE_FILE", "SCRATCH_DIR"]
