"""Batch progress on stderr: a bar over the assets on a terminal (tqdm), one line per asset
otherwise (build logs, CI), nothing with ``-q``."""

from __future__ import annotations

import os
import sys


class Progress:
    """``advance(relpath, result)`` once per finished cook; ``close()`` at the end.

    ``mode``: "bar" (tqdm on stderr), "lines" or "quiet"; ``None`` picks "bar" when stderr is a
    terminal, else "lines".
    """

    def __init__(self, total: int, mode: str | None = None, stream=None) -> None:
        self.stream = stream or sys.stderr
        if mode is None:
            mode = "bar" if getattr(self.stream, "isatty", lambda: False)() else "lines"
        self.mode, self.total, self.done = mode, total, 0
        self.bar = None
        if mode == "bar" and total:
            from tqdm import tqdm  # imported only when a bar is drawn (a terminal)

            try:
                width, height = os.get_terminal_size(self.stream.fileno())
            except (OSError, ValueError, AttributeError):
                width = height = 0
            # a pty may report a 0 x 0 window: tqdm would then draw nothing
            size = {"dynamic_ncols": True} if width > 0 else {"ncols": 80}
            if height <= 0:
                size["nrows"] = 24
            self.bar = tqdm(total=total, unit="asset", file=self.stream, leave=False, desc="lopcook batch", **size)

    def advance(self, relpath: str, result: dict) -> None:
        self.done += 1
        ok = result.get("status") == "cooked"
        if self.bar is not None:
            self.bar.set_postfix_str(("" if ok else "FAILED ") + relpath, refresh=False)
            self.bar.update(1)
            if not ok:
                self.bar.write(f"lopcook: FAILED {relpath}: {result.get('error')}", file=self.stream)
        elif self.mode == "lines":
            width = len(str(self.total))
            head = f"lopcook: [{self.done:{width}d}/{self.total}]"
            if ok:
                line = (f"{head} cooked {relpath} ({result.get('wall_s', result.get('time_s', 0.0)):.1f} s, "
                        f"{result.get('bytes', 0):,} B)")
            else:
                line = f"{head} FAILED {relpath}: {result.get('error')}"
            print(line, file=self.stream, flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None


__all__ = ["Progress"]
