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

from importlib import import_module

from .version import __version__

#: the API's names, each resolved from its module when first used (PEP 562), so that importing any
#: lopcook module (a batch worker parsing flags, ``lopcook --help``) loads no pipeline stage
_API = {"load": "api", "cook": "api", "read": "api", "Container": "lop.container", "Settings": "settings",
        "DEFAULTS": "settings"}


def __getattr__(name: str):
    if name not in _API:
        raise AttributeError(f"module 'lopcook' has no attribute {name!r}")
    value = getattr(import_module(f".{_API[name]}", __name__), name)
    globals()[name] = value
    return value


__all__ = ["__version__", "load", "cook", "read", "Container", "Settings", "DEFAULTS"]
