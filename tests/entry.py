"""The command line run in this process: ``python -m pipeline <args>`` through its entry function
(``pipeline.__main__.main``), for tests where the child process is not what is tested."""

from __future__ import annotations

import contextlib
import io
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def cli(*args, cwd=ROOT) -> subprocess.CompletedProcess:
    """``python -m pipeline <args>`` from ``cwd``, in this process: the exit status, stdout and
    stderr, as a finished child process would give them."""
    from pipeline.__main__ import main

    out, err, argv, here, code = io.StringIO(), io.StringIO(), sys.argv, os.getcwd(), 0
    try:
        os.chdir(cwd)
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            main([str(a) for a in args])
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else int(exc.code is not None)
    finally:
        os.chdir(here)
        sys.argv = argv
    return subprocess.CompletedProcess(list(args), code, out.getvalue(), err.getvalue())
