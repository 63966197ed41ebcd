"""Generators used only by the tests: ``fixtures`` (the procedural scenes of ``fixtures/`` and their
deterministic OBJ, glTF/GLB and USD writers) and ``fuzzcases`` (hostile and malformed inputs, and
the classifier of how the CLI treats them). Imported as ``tests.support`` (the repository root is on
``sys.path``: pytest's ``pythonpath``, or ``python -m`` run from the root); lopcook never imports them."""
