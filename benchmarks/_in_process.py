"""An experiment's trials run in this process, for benchmarks that compare two settings of the
same code (``pipeline.stages.run_stage``, its printing silenced)."""

from __future__ import annotations

import contextlib
import filecmp
import os
import shutil
import time
from pathlib import Path

from pipeline.stages import run_stage


@contextlib.contextmanager
def _quiet():
    with open(os.devnull, "w") as sink, contextlib.redirect_stdout(sink):
        yield


def warm_up(experiment: str, out: Path) -> None:
    """``experiment`` at the smoke scale into ``out / 'warm-up'`` (numba's cache, the imports)."""
    with _quiet():
        run_stage(
            "trials",
            [f"+experiment={experiment}", "profile=smoke", "progress=false", "overwrite=true"]
            + [f"out={out / 'warm-up'}"],
        )


def timed_run(
    experiment: str, out: Path, kept: Path, setting: contextlib.AbstractContextManager
) -> float:
    """Wall seconds of ``experiment`` at its own scale inside ``setting``, run into ``out`` (the same
    folder every time: the records embed it) and then moved to ``kept``."""
    shutil.rmtree(out, ignore_errors=True)
    shutil.rmtree(kept, ignore_errors=True)
    t0 = time.perf_counter()
    with setting, _quiet():
        run_stage("trials", [f"+experiment={experiment}", "progress=false", f"out={out}"])
    seconds = time.perf_counter() - t0
    out.rename(kept)
    return seconds


def differing(a: Path, b: Path, names: tuple[str, ...]) -> tuple[int, list[str]]:
    """How many files called one of ``names`` lie under ``a``, and those whose bytes differ in ``b``."""
    found = sorted(p.relative_to(a).as_posix() for p in a.rglob("*") if p.name in names)
    return len(found), [n for n in found if not filecmp.cmp(a / n, b / n, shallow=False)]
