"""Concurrent writers of one ``out`` folder (docs/reliability.md, "Trials"): the lock that only its
owner removes (:func:`pipeline.files.exclusive_folder`) and the work folders that no process
removes while their own process lives (:func:`pipeline.files.abandoned`). The lock's cases run in
this process against stand-in owners; the stage's run as real processes on one ``out``: a run A,
a second run B and an ``overwrite=true`` run C, in the grid and in the robot world (the
robot's under ``make test-slow``)."""

from __future__ import annotations

import hashlib
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from entry import ROOT, cli

from faults._checks import trials_process
from pipeline.errors import UserError
from pipeline.files import (
    OWNER_FILE,
    Owner,
    abandoned,
    claim_folder,
    exclusive_folder,
    folder_owner,
    process_start,
    remove_abandoned,
    swap_in,
    work_folder,
)

needs_proc = pytest.mark.skipif(
    not Path("/proc/self/stat").exists(), reason="start times need Linux /proc"
)


def held_by(folder: Path, pid: int) -> str:
    return (
        f"config key 'out': {folder} is being written by another process (pid {pid}); "
        "wait for it, or choose another folder"
    )


@pytest.fixture
def live():
    """A process that runs while the test does, as a lock or work folder names it."""
    proc = subprocess.Popen(["sleep", "60"])
    try:
        yield Owner(proc.pid, process_start(proc.pid), socket.gethostname())
    finally:
        proc.kill()
        proc.wait()


def ended() -> Owner:
    """A process that has ended (and been reaped: its pid is free)."""
    proc = subprocess.Popen(["true"])
    proc.wait()
    return Owner(proc.pid, 4242, socket.gethostname())


def lock_state(folder: Path) -> tuple[int, bytes]:
    lock = folder / ".lock"
    return lock.stat().st_ino, lock.read_bytes()


# ------------------------------------------------------------------ the lock
def test_a_lock_left_by_an_ended_process_is_taken_over(tmp_path):
    (tmp_path / ".lock").write_text(ended().text())
    with exclusive_folder(tmp_path) as out:
        assert Owner.parse((out / ".lock").read_text()) == Owner.me()
    assert not (tmp_path / ".lock").exists()


@needs_proc
def test_a_lock_whose_pid_runs_with_another_start_time_is_stale(tmp_path, live):
    reused = Owner(live.pid, live.start - 1, live.host)  # its pid given to a new process since
    assert live.alive() and not reused.alive()
    (tmp_path / ".lock").write_text(reused.text())
    with exclusive_folder(tmp_path):
        assert Owner.parse((tmp_path / ".lock").read_text()) == Owner.me()
    assert not (tmp_path / ".lock").exists()


def test_a_lock_naming_a_live_process_is_refused_and_left_intact(tmp_path, live):
    """The owner's name alone refuses (a file system where ``flock`` does nothing)."""
    (tmp_path / ".lock").write_text(live.text())
    before = lock_state(tmp_path)
    with pytest.raises(UserError) as refused, exclusive_folder(tmp_path):
        pass
    assert str(refused.value) == held_by(tmp_path, live.pid)
    assert lock_state(tmp_path) == before


def test_a_lock_of_another_host_is_refused_saying_how_to_free_it(tmp_path):
    (tmp_path / ".lock").write_text(Owner(1, 1, "elsewhere").text())
    with pytest.raises(UserError, match=r"\(pid 1 on elsewhere\).*delete .*\.lock if"):
        with exclusive_folder(tmp_path):
            pass
    assert (tmp_path / ".lock").exists()


def test_a_holder_killed_with_sigkill_refuses_while_it_lives_then_is_taken_over(tmp_path):
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys, time\nfrom pipeline.files import exclusive_folder\n"
            "with exclusive_folder(sys.argv[1]):\n    print('held', flush=True)\n"
            "    time.sleep(60)\n",
            str(tmp_path),
        ],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout.readline() == "held\n"
        before = lock_state(tmp_path)
        for _ in range(2):  # a refused process leaves the lock as it was: refused again
            with pytest.raises(UserError) as refused, exclusive_folder(tmp_path):
                pass
            assert str(refused.value) == held_by(tmp_path, holder.pid)
            assert lock_state(tmp_path) == before
    finally:
        holder.kill()
        holder.wait()
    assert (tmp_path / ".lock").exists()  # no finally ran in the killed holder
    with exclusive_folder(tmp_path):
        assert Owner.parse((tmp_path / ".lock").read_text()) == Owner.me()
    assert not (tmp_path / ".lock").exists()


def race(folder: Path, n: int) -> tuple[int, list[str]]:
    """``n`` threads take ``folder`` at once; how many won, and the refusals. A winner holds on
    until every other taker has been refused (or 10 s)."""
    start, won, refused = threading.Barrier(n), [], []

    def take():
        start.wait()
        try:
            with exclusive_folder(folder):
                won.append(1)
                t0 = time.time()
                while len(refused) < n - 1 and time.time() - t0 < 10:
                    time.sleep(0.01)
        except UserError as exc:
            refused.append(str(exc))

    takers = [threading.Thread(target=take) for _ in range(n)]
    for t in takers:
        t.start()
    for t in takers:
        t.join(30)
    return len(won), refused


def test_takers_of_one_stale_lock_never_both_win(tmp_path):
    """Eight takers at once (threads: ``flock`` excludes another open of the file in the same
    process as in another), three times: one wins, seven are refused naming the winner."""
    dead = ended().text()
    for _ in range(3):
        (tmp_path / ".lock").write_text(dead)
        assert race(tmp_path, 8) == (1, [held_by(tmp_path, os.getpid())] * 7)
        assert not (tmp_path / ".lock").exists()


# ------------------------------------------------------------------ work folders
def test_work_folders_of_live_processes_stay_and_those_of_ended_ones_go(tmp_path, live):
    dead, dead_too = ended(), ended()
    keep = {
        tmp_path / f".staging-{live.pid}": live,
        tmp_path / f".staging-{os.getpid()}": None,  # no owner file: by its name's pid
    }
    go = {
        tmp_path / f".staging-{dead.pid}": dead,
        tmp_path / f".staging-{dead_too.pid}": None,
        tmp_path / ".staging-x": None,  # no pid at all
    }
    reused = {tmp_path / f".building-{live.pid}": Owner(live.pid, live.start + 1, live.host)}
    for folder, owner in {**keep, **go, **reused}.items():
        folder.mkdir()
        (folder / "records.mcap.partial").write_bytes(b"partial")
        if owner is not None:
            (folder / OWNER_FILE).write_text(owner.text())
    assert set(abandoned(tmp_path, ".staging")) == set(go)
    assert set(remove_abandoned(tmp_path, ".staging")) == set(go)
    if Path("/proc/self/stat").exists():  # the start time tells a reused pid
        assert remove_abandoned(tmp_path, ".building") == list(reused)
    assert {p for p in tmp_path.iterdir() if p.name.startswith(".staging")} == set(keep)


def test_a_claimed_work_folder_is_this_process_and_its_owner_file_stays_behind(tmp_path):
    mine = claim_folder(work_folder(tmp_path, ".staging"))
    assert mine.name == f".staging-{os.getpid()}" and folder_owner(mine) == Owner.me()
    assert abandoned(tmp_path, ".staging") == []
    (mine / "summary.json").write_text("{}")
    swap_in(mine, tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["summary.json"]


def test_swap_in_syncs_the_staging_folder_before_it_renames_anything(tmp_path, monkeypatch):
    """Files written into a staging folder without their own fsync (the trials stage's records
    and summaries) are on the disk before they are renamed into place: no empty result after a
    crash of the machine."""
    staging = claim_folder(work_folder(tmp_path, ".staging"))
    (staging / "summary.json").write_text("{}")
    seen = []
    monkeypatch.setattr(os, "sync", lambda: seen.append(sorted(p.name for p in tmp_path.iterdir())))
    swap_in(staging, tmp_path)
    assert seen == [[staging.name]]  # synced once, while everything was still in staging
    assert sorted(p.name for p in tmp_path.iterdir()) == ["summary.json"]


def digest(folder: Path) -> dict:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def test_an_overwrite_run_removes_ended_runs_staging_folders_only(tmp_path, live):
    """A live process's staging folder (one that writes without the lock: an older pipeline)
    survives an ``overwrite=true`` run; an ended run's partial records are removed, and said."""
    tiny = ["method=ssrl", "maze=5x5", "runs=2", "episodes=4", "progress=false"]
    dead = ended()
    for owner in (live, dead):
        folder = tmp_path / f".staging-{owner.pid}"
        folder.mkdir()
        (folder / OWNER_FILE).write_text(owner.text())
        (folder / "records.mcap.partial").write_bytes(b"partial")
    theirs = digest(tmp_path / f".staging-{live.pid}")
    done = cli("trials", *tiny, f"out={tmp_path}", "overwrite=true")
    assert done.returncode == 0, done.stderr
    assert (
        f"removed the partial records of an interrupted run: {tmp_path}/.staging-{dead.pid}\n"
        in (done.stdout)
    )
    assert str(live.pid) not in done.stdout
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        f".staging-{live.pid}",
        "records.mcap",
        "summary.json",
    ]
    assert digest(tmp_path / f".staging-{live.pid}") == theirs


# ------------------------------------------------------------------ three processes, one out
WORLDS = {  # runs, episodes and the rest: each run lasts a few seconds
    "grid": ["method=ssrl", "maze=7x7", "runs=20", "episodes=2000"],
    "robot": [
        "method=fewshot_dss",
        "world=robot3d",
        "recogniser=oracle",
        "maze=5x5",
        "runs=2",
        "episodes=5",
    ],
}


@pytest.mark.parametrize(
    "world",
    [  # the lock is taken by the trials stage whatever the world: the robot's run is end to end
        "grid",
        pytest.param("robot", marks=pytest.mark.slow),
    ],
)
def test_a_run_keeps_its_out_from_a_second_run_and_an_overwrite_run(tmp_path, world):
    """A writes; B (same ``out``) and C (``overwrite=true``) are refused in one line naming A's
    pid, and touch neither A's lock nor its staging folder; A's records read back complete, and
    neither its lock nor its staging folder is left. A is stopped (SIGSTOP) while B and C try:
    alive and mid-run, however fast the machine."""
    from pipeline.records import read_records

    args = [*WORLDS[world], "progress=false", f"out={tmp_path}"]
    a = trials_process(*args)
    try:
        t0 = time.time()
        while not list(tmp_path.glob(".staging-*/records.mcap.partial")):
            assert a.poll() is None and time.time() - t0 < 60, a.stderr.read()
            time.sleep(0.01)
        a.send_signal(signal.SIGSTOP)
        held = lock_state(tmp_path)
        assert Owner.parse(held[1].decode()).pid == a.pid
        b, c = trials_process(*args, "seed=1"), trials_process(*args, "seed=2", "overwrite=true")
        for proc in (b, c):
            _, err = proc.communicate(timeout=60)
            assert proc.returncode == 2, err
            assert err.strip().splitlines() == [f"error: {held_by(tmp_path, a.pid)}"]
        assert lock_state(tmp_path) == held
        assert [p.name for p in tmp_path.glob(".staging-*")] == [f".staging-{a.pid}"]
        a.send_signal(signal.SIGCONT)
        _, err = a.communicate(timeout=120)
    finally:
        a.kill()
        a.wait()
    assert a.returncode == 0, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["records.mcap", "summary.json"]
    records = read_records(tmp_path / "records.mcap", pictures=False)
    given = dict(arg.split("=") for arg in WORLDS[world])
    assert records.meta.complete and records.meta.config["seed"] == 0
    assert records.meta.config["world"] == given.get("world", "grid")
    whole = int(given["runs"]) * int(given["episodes"])
    assert len(records.episodes) == records.meta.expected_episodes == whole
