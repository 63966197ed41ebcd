"""lopcook: an offline asset cooker for level-of-precision (LOP) vertex containers.

Pipeline: ingest -> simplify -> analyse -> emit -> verify, with tune above the stages
(docs/architecture.md). The Python API::

    import lopcook
    scene = lopcook.load("fixtures/two_plates.glb")
    container = lopcook.cook(scene, lopcook.Settings())
    container.write("two_plates.lop")

Method: Q. Meyer, G. Sussner, G. Greiner, M. Stamminger, "Adaptive Level-of-Precision for
GPU-Rendering", VMV 2011.
"""

from .version import __version__  # noqa: E402

from .api import cook, load, read  # noqa: E402
from .lop.container import Container  # noqa: E402
from .settings import DEFAULTS, Settings  # noqa: E402

__all__ = ["__version__", "load", "cook", "read", "Container", "Settings", "DEFAULTS"]
