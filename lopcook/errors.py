"""The one exception lopcook raises, and the exit codes the CLI maps it to.

Every error names the file, what is wrong and what to do, e.g.::

    LopcookError("ingest", "car.glb", "accessor 3: 7 indices, not a multiple of 3",
                 hint="re-export the file with triangulated primitives")

Exit codes (see ``lopcook.cli``): 0 ok, 1 verification failed, 2 bad input or usage, 3 internal
error (a bug: ``internal_error`` words it).
"""

from __future__ import annotations

import re

EXIT_OK = 0
EXIT_VERIFY_FAILED = 1
EXIT_BAD_INPUT = 2
EXIT_INTERNAL = 3


class LopcookError(Exception):
    """A failure lopcook can explain in one line.

    Parameters
    ----------
    stage : str
        Pipeline stage that failed: ``"ingest"``, ``"analyse"``, ``"emit"``, ``"container"`` (reading a
        .lop file), ``"verify"``,
        ``"report"``, ``"usage"``.
    path : str | None
        The file concerned (as the user gave it), or None when no file is involved.
    message : str
        What is wrong, with the offending value and what was expected.
    hint : str | None
        What the user can do about it.
    exit_code : int
        Process exit code the CLI uses: 2 (bad input/usage) by default, 1 for a failed verification.
    reason : str | None
        For a container that cannot be read, its error class (docs/format.md section 12:
        ``bad_magic``, ``header_crc``, ``manifest``, ...; every reader reports the same class for
        the same file, ``fixtures/conformance``), or ``"level"`` for a level the file does not
        hold; None otherwise.

    ``str(error)`` is always one line (``one_line``): line breaks inside a message, a hint or a
    quoted name become spaces.
    """

    def __init__(self, stage: str, path: str | None, message: str, *, hint: str | None = None,
                 exit_code: int = EXIT_BAD_INPUT, reason: str | None = None) -> None:
        self.stage = stage
        self.reason = reason
        self.path = None if path is None else str(path)
        self.message = message
        self.hint = hint
        self.exit_code = exit_code
        super().__init__(self.__str__())

    def __reduce__(self):
        # pickles with its fields (an error raised in a forked child is re-raised in the parent)
        return (_rebuild, (self.stage, self.path, self.message, self.hint, self.exit_code, self.reason))

    def __str__(self) -> str:
        where = f"{self.path}: " if self.path else ""
        text = f"{self.stage}: {where}{self.message}"
        if self.hint:
            text += f" ({self.hint})"
        return one_line(text)


def _rebuild(stage, path, message, hint, exit_code, reason=None) -> LopcookError:
    return LopcookError(stage, path, message, hint=hint, exit_code=exit_code, reason=reason)


def one_line(text: str) -> str:
    """``text`` on one line: every run of whitespace that holds a line break (or any other
    control character) becomes one space, so a message from a parser or a file name quoted in a
    message never spreads over several lines of stderr."""
    return _BREAKS.sub(" ", str(text)).strip()


_BREAKS = re.compile(r"\s*[\x00-\x08\x0a-\x1f\x7f\x85\u2028\u2029]+\s*")


def internal_error(exc: BaseException) -> str:
    """The one line for an exception that is not a ``LopcookError`` (a bug, not bad input): its
    type and message, and what to do."""
    return f"internal error: {type(exc).__name__}: {exc} (run with --debug for the traceback and report it)"
