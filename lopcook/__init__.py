"""lopcook: an offline asset cooker for level-of-precision (LOP) vertex containers.

Pipeline: ``load(path) -> Scene`` (ingest) -> analyse -> emit -> verify/report.
Method: Q. Meyer, G. Sussner, G. Greiner, M. Stamminger, "Adaptive Level-of-Precision for
GPU-Rendering", VMV 2011.
"""

__version__ = "0.1.0"


def load(path, settings=None):
    """Load a glTF/GLB, OBJ or USD file into a validated ``Scene`` (see ``lopcook.ingest.load``)."""
    from .ingest import load as _load
    from .settings import DEFAULT_INGEST

    return _load(path, settings or DEFAULT_INGEST)


__all__ = ["__version__", "load"]
