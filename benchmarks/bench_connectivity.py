"""Bits per triangle of every hierarchy connectivity variant on the corpus, with references, and
the chart of bits per triangle against the random-access unit size (``lopcook.bench.connectivity``;
also ``lopcook bench --connectivity``). Not a test. Usage::

    PYTHONPATH=. .venv/bin/python benchmarks/bench_connectivity.py [--corpus DIR] [--assets A ...]
        [--json OUT.json] [--out DIR]
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from lopcook.bench.connectivity import main  # noqa: E402

if __name__ == "__main__":
    main()
