"""The lopcook version, recorded in every container's ``generator`` and in reports."""

__version__ = "0.1.0"
