"""What a simplification backend returns, and how it refuses a result.

Every backend (``lopcook.simplify.backends``: pymeshlab, fast-simplification;
``lopcook.simplify.meshopt``: meshoptimizer) returns a ``BackendResult`` in the input's units
(metres); ``BackendFailure`` marks a result the chain must not use (it falls back to the next backend).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class BackendResult:
    positions: np.ndarray            # (k, 3) float64
    faces: np.ndarray                # (m, 3) int64
    wedge_uvs: np.ndarray | None = None    # (m, 3, 2) per-corner UVs (pymeshlab texture variants)
    vertex_source: np.ndarray | None = None  # (k,) input vertex each output vertex is (fast)


class BackendFailure(Exception):
    """A backend result that must not be used (reason in the message)."""


__all__ = ["BackendResult", "BackendFailure"]
