"""The one error type for user errors: a bad config, layout, checkpoint, image folder or record file.

Every stage catches :class:`UserError` once, at its entry (``pipeline.stages.stage_main``),
and prints one line naming the thing and the problem, then exits with status 2. Anything else is a
bug and keeps its traceback.
"""

from __future__ import annotations

import contextlib
import os
import sys


class UserError(ValueError):
    """Input the user can fix; the message names the input (config key, file, line) and the problem."""


class ConfigError(UserError):
    """A configuration value that cannot work; the message names the key."""


class Interrupted(BaseException):
    """Ctrl-C or SIGTERM: the stage stops, says what it kept in one line, and exits 130 or 143."""

    def __init__(self, code: int, message: str = "interrupted"):
        super().__init__(message)
        self.code = code
        self.message = message


@contextlib.contextmanager
def quiet_broken_pipe():
    """``... | head``: a reader that stops early ends the command with status 141 (as a shell's
    SIGPIPE would), without a traceback."""
    try:
        try:
            yield
        finally:
            sys.stdout.flush()  # the last write inside: a reader gone before it is seen here
    except BrokenPipeError:
        os.dup2(
            os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno()
        )  # the interpreter's last flush must not fail
        raise SystemExit(141) from None
