"""The suite's one cache of cooked containers (``tests/conftest.py`` fixture ``cooks``, session
scope): each (source, option set) is cooked once per session, whichever test asks first, and every
later test gets the same file or objects. A cook is deterministic (the same source and options
give the same bytes), so sharing it changes no result.

Three ways to ask, one per kind of test:

* ``cli(source, *flags)`` -> ``Path``: ``lopcook cook SOURCE -o X.lop -q FLAGS``, the CLI's bytes
  (what a user's cook writes); ``cli_many([(source, flags), ...])`` cooks the missing ones two at
  a time in child processes (the runtime tests' corpus sweep).
* ``analysed(source)`` -> ``(scene, analysis, bytes, container)``: ``ingest.load``, ``analyse``
  and ``emit.build`` with the defaults, for tests that compare the container with the analysis.
* ``api(source, settings)`` -> ``(scene, container)``: ``lopcook.load`` and ``lopcook.cook``.

``source`` is a path (str or Path); the key is its absolute path and the options as given.
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path


class CookCache:
    """Containers cooked once per session, written under ``folder``."""

    def __init__(self, folder: Path):
        self.folder = Path(folder)
        self._paths: dict = {}
        self._objects: dict = {}
        self._lock = threading.RLock()
        self._count = 0

    def _out(self, source) -> Path:
        """A new file name under ``folder`` (call with the lock held)."""
        self._count += 1
        return self.folder / f"{Path(source).stem}-{self._count}.lop"

    def cli(self, source, *flags) -> Path:
        """The path of ``source`` cooked by the CLI with ``flags`` (in this process)."""
        from lopcook.cli import main

        key = (os.path.abspath(source), tuple(str(f) for f in flags))
        with self._lock:
            if key not in self._paths:
                out = self._out(source)
                rc = main(["-q", "cook", str(source), "-o", str(out), *key[1]])
                assert rc == 0, f"cook {source} {' '.join(key[1])}: exit {rc}"
                self._paths[key] = out
            return self._paths[key]

    def cli_many(self, jobs) -> list[Path]:
        """``[cli(source, *flags) for source, flags in jobs]``, the missing cooks two at a time in
        child processes (``python -m lopcook cook``: the same bytes as ``cli``)."""
        keys = [(os.path.abspath(s), tuple(str(f) for f in flags)) for s, flags in jobs]
        with self._lock:
            todo = {}
            for k, (s, _) in zip(keys, jobs):
                if k not in self._paths and k not in todo:
                    todo[k] = (s, self._out(s))

        def run(item):
            key, (source, out) = item
            subprocess.run([sys.executable, "-m", "lopcook", "cook", str(source), "-o", str(out), "-q", *key[1]],
                           check=True, timeout=1800, env=dict(os.environ))

        with ThreadPoolExecutor(2) as pool:
            list(pool.map(run, todo.items()))
        with self._lock:
            self._paths.update({k: out for k, (_, out) in todo.items()})
            return [self._paths[k] for k in keys]

    def analysed(self, source):
        """``(scene, analysis, bytes, container)`` of ``source`` with the default analysis and
        ``emit.build``."""
        from lopcook.analyse import analyse
        from lopcook.emit import build
        from lopcook.ingest import load
        from lopcook.lop.container import from_bytes

        key = ("analysed", os.path.abspath(source))
        with self._lock:
            if key not in self._objects:
                scene = load(str(source))
                an = analyse(scene)
                data = build(scene, an)
                self._objects[key] = (scene, an, data, from_bytes(data, str(source)))
            return self._objects[key]

    def api(self, source, settings=None):
        """``(scene, container)``: ``lopcook.load(source)`` cooked by ``lopcook.cook`` with
        ``settings`` (the defaults when None)."""
        from lopcook import api

        key = ("api", os.path.abspath(source), repr(settings))
        with self._lock:
            if key not in self._objects:
                scene = api.load(source)
                self._objects[key] = (scene, api.cook(scene, settings) if settings is not None else api.cook(scene))
            return self._objects[key]
