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


def package_copy(folder: Path) -> Path:
    """A copy of ``pipeline/`` and its config folder in ``folder`` (what a test that adds a
    method, a recogniser or an experiment edits); returns the copy's config folder."""
    import shutil

    from pipeline.config.compose import CONF_DIR

    ignore = shutil.ignore_patterns("__pycache__", "*.nbi", "*.nbc")
    shutil.copytree(ROOT / "pipeline", folder / "pipeline", ignore=ignore)
    conf = Path(CONF_DIR)
    if not conf.is_relative_to(ROOT / "pipeline"):  # configs beside the package, not inside it
        shutil.copytree(conf, folder / conf.relative_to(ROOT), ignore=ignore)
    return folder / conf.relative_to(ROOT)
