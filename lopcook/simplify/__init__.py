"""Simplify: every part's LOD chain (Garland-Heckbert quadric collapse through pymeshlab or
fast-simplification), with attributes carried over, the geometric error measured, and copies of
one mesh simplified once.

Modules: ``backends`` (the simplifiers behind one signature), ``transfer`` (attribute transfer
from LOD 0), ``error`` (measured Hausdorff error), ``topology`` (defects, UV seams),
``instances`` (copies of one mesh), ``chain`` (the chain driver, ``lod_chain``).
"""

from .backends import BACKENDS
from .chain import (MIN_SIMPLIFY_TRIANGLES, SEAM_MODES, Lod, LodReport, chain_notes, chain_warnings, lod_chain,
                    parametrise, simplify)
from .error import hausdorff
from .topology import SeamStats, mesh_defects, seam_stats

__all__ = ["BACKENDS", "SEAM_MODES", "MIN_SIMPLIFY_TRIANGLES", "Lod", "LodReport", "chain_notes", "chain_warnings",
           "lod_chain", "parametrise", "simplify", "hausdorff", "SeamStats", "mesh_defects", "seam_stats"]
