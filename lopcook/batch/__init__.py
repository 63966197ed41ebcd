"""``lopcook batch``: cook a whole asset tree, incrementally, locally in parallel or on a Dask cluster.

Every asset is cooked by exactly what ``lopcook cook SOURCE -o OUT [options]`` does (a fresh
process parses the options with ``lopcook.cli.parser`` and cooks with ``lopcook.cookjob``, as the
CLI does), so a batch output has the same bytes as one ``lopcook cook`` per asset with the same
options. The modules, in the order a batch uses them:

``discover``  SOURCES (files, directories searched recursively, manifests) -> ``Asset`` list
``config``    ``lopcook.toml``: per-glob cook options and excludes -> resolved options per asset,
              validated with the CLI's own parser (``lopcook.cli.parser``)
``keys``      depfile parsing, the incremental key, the state file ``OUTDIR/.lopcook-batch.json``
``worker``    one cook in a fresh process under a memory cap, waited for (``run_isolated``)
``child``     that process (``python -m lopcook.batch.child``): the cap, the cook, the key
``local``     ``--jobs N`` worker processes on this machine
``cluster``   ``--scheduler tcp://HOST:PORT``: the same tasks on a Dask distributed cluster
``ninja``     ``--emit-ninja build.ninja``: the batch as a Ninja file of ``lopcook cook`` edges
``progress``  a bar on a terminal, one line per asset otherwise
``run``       plan (up-to-date check), execute, record, summarise
``command``   ``cmd_batch``: the ``batch`` command run from its parsed flags, and its summary printed

The user documentation, with the config format and measurements, is docs/batch.md.
"""

from __future__ import annotations

STATE_FILE = ".lopcook-batch.json"
#: per-cook scratch folders live here (under OUTDIR) and are removed after each cook
SCRATCH_DIR = ".lopcook-batch-tmp"

__all__ = ["STATE_FILE", "SCRATCH_DIR"]
