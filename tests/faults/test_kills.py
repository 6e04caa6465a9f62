"""Processes killed mid-run. SIGTERM and SIGINT during a trial, during an experiment's re-run and
while workers run: one line saying what was kept, the workers ended, and nothing the user had lost
(docs/reliability.md "Trials")."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from entry import cli

from faults._checks import FAST, digest, trials_process

ROOT = Path(__file__).resolve().parents[2]


LONG = [
    "method=ssrl",
    "maze=11x11",
    "runs=100",
    "episodes=200000",
    "progress=false",
    "flush_every=1000",
]


def _wait_for_partial(out: Path, timeout=60.0):
    t0 = time.time()
    while time.time() - t0 < timeout:
        if list(out.glob(".staging-*/records.mcap.partial")):
            time.sleep(1.0)
            return
        time.sleep(0.1)
    raise AssertionError("the trial did not start writing")


@pytest.mark.parametrize("sig,code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_killed_trial_says_what_it_kept_and_loses_nothing(tmp_path, sig, code):
    assert cli("trials", "method=ssrl", f"out={tmp_path}", *FAST).returncode == 0
    before = digest(tmp_path)
    proc = trials_process(*LONG, f"out={tmp_path}", "overwrite=true")
    _wait_for_partial(tmp_path)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == code, err
    lines = err.strip().splitlines()
    assert (
        len(lines) == 1
        and lines[0].startswith("interrupted; partial records at ")
        and " episodes" in lines[0]
    ), err
    partial = Path(lines[0].split(" at ")[1].split(":")[0])
    from pipeline.records import read_records

    n = int(lines[0].rsplit(": ", 1)[1].split()[0])
    assert (
        0 < len(read_records(partial, pictures=False).episodes) <= n
    )  # the reader keeps whole runs' prefixes
    after = digest(tmp_path)
    assert {
        k: v for k, v in after.items() if not k.startswith(".staging-")
    } == before  # old results whole


def _children(pid: int) -> list[int]:
    """The processes whose parent is ``pid`` (Linux ``/proc``)."""
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        with contextlib.suppress(OSError):
            fields = stat.read_text().rsplit(")", 1)[1].split()
            if int(fields[1]) == pid:
                out.append(int(stat.parent.name))
    return out


def _alive(pid: int) -> bool:
    with contextlib.suppress(OSError):
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    return False


def _wait_for_cells(stage: subprocess.Popen, out: Path, timeout=120.0) -> None:
    """Until the workers of ``stage`` run cells: a cell's partial records in its staging folder
    (an event, not a guess at how long start-up takes on a loaded machine)."""
    t0 = time.time()
    while not list(out.glob(".staging-*/*/records.mcap.partial")):
        if stage.poll() is not None:
            raise AssertionError(f"the stage ended before running a cell: {stage.stderr.read()}")
        assert time.time() - t0 < timeout, f"no cell started within {timeout:.0f} s"
        time.sleep(0.1)


def two_worker_stage(out: Path, episodes: int):
    """A ``workers=2`` trials stage of Figure 9's cells, long enough to be stopped mid-run."""
    args = ["+experiment=fig9", "recogniser=oracle", "workers=2", "runs=100", "progress=false"]
    return trials_process(*args, f"episodes={episodes}", f"out={out}")


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_workers_end_when_their_stage_is_killed(tmp_path):
    """``kill -9`` of a ``workers=2`` stage: its worker processes (and the resource tracker they
    kept alive) end within seconds instead of running on as orphans."""
    stage = two_worker_stage(tmp_path, episodes=4000)
    children: list[int] = []
    try:
        t0 = time.time()
        while time.time() - t0 < 60 and len(children) < 3:  # two workers and the resource tracker
            children = _children(stage.pid)
            time.sleep(0.2)
        assert len(children) >= 2, children
        _wait_for_cells(stage, tmp_path)
        stage.kill()
        stage.wait(timeout=10)
        t0 = time.time()
        while time.time() - t0 < 20 and any(map(_alive, children)):
            time.sleep(0.2)
        assert not [p for p in children if _alive(p)], "workers outlived their stage"
    finally:  # whatever happened, nothing of this test runs on
        for pid in [stage.pid, *children]:
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGKILL)


def test_a_terminated_multi_worker_stage_says_one_line(tmp_path):
    """SIGTERM of a ``workers=2`` stage: the one line saying where the finished cells are, and no
    warning after it (the workers make no semaphore the resource tracker would report)."""
    stage = two_worker_stage(tmp_path, episodes=20000)
    try:
        _wait_for_cells(stage, tmp_path)
        stage.send_signal(signal.SIGTERM)
        _, err = stage.communicate(timeout=60)
    finally:
        stage.kill()
    assert stage.returncode == 143, err
    assert err.strip().splitlines() == [
        f"interrupted; the finished cells' records are under {tmp_path}/.staging-{stage.pid}"
    ], err


def test_a_killed_experiment_rerun_keeps_the_previous_experiment(tmp_path):
    assert (
        cli("trials", "+experiment=fig9", "recogniser=oracle", f"out={tmp_path}", *FAST).returncode
        == 0
    )
    before = digest(tmp_path)
    proc = trials_process(
        "+experiment=fig9",
        "recogniser=oracle",
        "runs=100",
        "episodes=100000",
        "seed=3",
        "progress=false",
        f"out={tmp_path}",
        "overwrite=true",
    )
    t0 = time.time()
    while (
        not list(tmp_path.glob(".staging-*/way1/records.mcap.partial")) and time.time() - t0 < 120
    ):
        time.sleep(0.2)
    time.sleep(1.0)
    proc.send_signal(signal.SIGTERM)
    proc.communicate(timeout=60)
    assert proc.returncode == 143
    assert {k: v for k, v in digest(tmp_path).items() if not k.startswith(".staging-")} == before
    # the next complete run replaces it and clears the partial one
    assert (
        cli(
            "trials",
            "+experiment=fig9",
            "recogniser=oracle",
            "seed=3",
            f"out={tmp_path}",
            "overwrite=true",
            *FAST,
        ).returncode
        == 0
    )
    assert not list(tmp_path.glob(".staging-*"))
    assert json.loads((tmp_path / "way1" / "summary.json").read_text())["seed"] == 3


def test_sigterm_while_numba_compiles_stops_at_once_in_one_line(tmp_path):
    """A child process (the signal is the point) compiles a fresh numba function (no cache) under
    the stages' signal handling and sends itself SIGTERM in the middle of it."""
    script = """
import os, signal, threading, numba, numpy as np
from pipeline.stages import user_facing
def kernel(a):
    s = 0.0
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            s += np.sin(a[i, j]) * np.cos(a[j, i]) + np.sqrt(abs(a[i, j]))
    return s
threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGTERM)).start()
with user_facing():
    for n in range(40):  # distinct signatures: compile after compile until the signal comes
        numba.njit(kernel)(np.ones((2, 2), dtype=np.float64)[:, : 1 + n % 2] + n)
print("not stopped")
"""
    start = time.perf_counter()
    child = subprocess.run(
        [sys.executable, "-c", script],
        cwd=ROOT,
        env={**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)},
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert time.perf_counter() - start < 30
    assert child.returncode == 143, child.stderr[-2000:]
    assert child.stderr.strip() == "interrupted while numba compiled a kernel"


@pytest.mark.slow
@pytest.mark.parametrize("delay", [3.0, 4.5, 6.0])
def test_sigterm_during_the_trials_first_compile_exits_within_5_s_in_one_line(tmp_path, delay):
    """The real stage with an empty numba cache: SIGTERM somewhere in its first compile (issue 31:
    two tracebacks and no exit within 5 s; the signal used to land in LLVM's ctypes callbacks)."""
    child = subprocess.Popen(
        [sys.executable, "-m", "pipeline", "trials", "method=ssrl", "maze=5x5", "runs=2"]
        + ["episodes=5", "progress=false", f"out={tmp_path / 'out'}"],
        cwd=ROOT,
        env={**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")},
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    time.sleep(delay)
    start = time.perf_counter()
    child.send_signal(15)
    try:
        _, err = child.communicate(timeout=5)
    except subprocess.TimeoutExpired:
        child.kill()
        raise AssertionError("still running 5 s after SIGTERM") from None
    if child.returncode == 0:
        pytest.skip(f"the stage finished within {delay} s: no compile left to interrupt")
    assert child.returncode == 143 and time.perf_counter() - start < 5, err[-2000:]
    assert len(err.strip().splitlines()) == 1 and err.startswith("interrupted"), err[-2000:]
