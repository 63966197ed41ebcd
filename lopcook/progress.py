"""Progress of long steps: a bar with counts and an ETA on a terminal, one line per stage for CI
logs, or nothing.

``progress.stage(name, total)`` is a context manager whose ``advance(n)`` counts the stage's
items (LOD chains, analysed LOD levels, renders, calibration probes); calling ``progress(msg)``
reports a one-off line (a calibration probe's result arrives as a dict). Modes (``--progress``):

* ``auto`` (default): a bar (tqdm) when stderr is a terminal and neither ``--quiet`` nor
  ``--json`` is given, else nothing: build logs stay clean;
* ``bar``: the bar even off a terminal; ``plain``: one line per finished stage with its time
  (``lopcook: analyse: 12 of 12 in 3.4 s``) and one per message; ``none``: nothing.

Progress goes to stderr only; stdout keeps the summary and ``--json``.
"""

from __future__ import annotations

import contextlib
import sys
import time

MODES = ("auto", "bar", "plain", "none")


class _Stage:
    def __init__(self, owner: "Progress", name: str, total: int | None) -> None:
        self.owner, self.name, self.total, self.done = owner, name, total, 0
        self.t0 = time.perf_counter()

    def advance(self, n: int = 1) -> None:
        self.done += n


class Progress:
    """Reports nothing (``none``); the base of the other modes."""

    def __init__(self, stream=None) -> None:
        self.stream = stream if stream is not None else sys.stderr

    @contextlib.contextmanager
    def stage(self, name: str, total: int | None = None):
        st = _Stage(self, name, total)
        self._start(st)
        try:
            yield st
        finally:
            self._end(st)

    def __call__(self, message) -> None:
        self.note(format_message(message))

    def _start(self, st: _Stage) -> None:
        pass

    def _end(self, st: _Stage) -> None:
        pass

    def note(self, text: str) -> None:
        pass


class PlainProgress(Progress):
    """One line per finished stage with its count and time, one per message."""

    def _end(self, st: _Stage) -> None:
        count = "" if st.total is None and not st.done else (
            f"{st.done} of {st.total} " if st.total is not None else f"{st.done} ")
        print(f"lopcook: {st.name}: {count}in {time.perf_counter() - st.t0:.1f} s", file=self.stream, flush=True)

    def note(self, text: str) -> None:
        print(f"lopcook: {text}", file=self.stream, flush=True)


class BarProgress(Progress):
    """A tqdm bar per stage (counts, rate, ETA) on stderr."""

    def _start(self, st: _Stage) -> None:
        from tqdm import tqdm  # imported only when a bar is drawn (a terminal, or --progress bar)

        st.bar = tqdm(total=st.total, desc=f"lopcook: {st.name}", file=self.stream, leave=False,
                      dynamic_ncols=True, unit="")
        real = st.advance

        def advance(n: int = 1) -> None:
            real(n)
            st.bar.update(n)

        st.advance = advance

    def _end(self, st: _Stage) -> None:
        st.bar.close()
        print(f"lopcook: {st.name}: {time.perf_counter() - st.t0:.1f} s", file=self.stream, flush=True)

    def note(self, text: str) -> None:
        from tqdm import tqdm  # imported only when a bar is drawn (a terminal, or --progress bar)

        tqdm.write(f"lopcook: {text}", file=self.stream)


def format_message(message) -> str:
    """A progress message: text, or a calibration probe (dict) as one line."""
    if not isinstance(message, dict):
        return str(message)
    p = message
    ps = "inf" if p.get("psnr_min") is None else f"{p['psnr_min']:.1f} dB"
    what = "confirm" if p.get("confirm") else "calibrate"
    return (f"{what}: k_f scale 2^{p['log2_sigma']:.3g}, edge eps {p['edge_eps']:.3g}: CAP {ps}, "
            f"{max(p['cap_percent']):.1f}% of float32 ({p['seconds']:.1f} s)")


def make(mode: str = "auto", *, quiet: bool = False, json: bool = False, stream=None) -> Progress:
    """The Progress of a ``--progress`` mode (module doc)."""
    stream = stream if stream is not None else sys.stderr
    if mode == "auto":
        tty = hasattr(stream, "isatty") and stream.isatty()
        mode = "bar" if tty and not quiet and not json else "none"
    return {"bar": BarProgress, "plain": PlainProgress}.get(mode, Progress)(stream)


NONE = Progress()

__all__ = ["MODES", "Progress", "PlainProgress", "BarProgress", "NONE", "make", "format_message"]
