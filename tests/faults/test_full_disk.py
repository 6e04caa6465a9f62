"""A full or read-only disk (docs/reliability.md "DVC experiments and full disks"): trials, an experiment
with workers and replay end in one line naming the folder and the space needed, exit 2; a failed
run removes its own staging folder and keeps what ``out`` held; replay writes its ``.rrd`` whole or
not at all. The disks are small tmpfs mounts: where this machine does not allow mounting (not
root, or no mount permission), every case is skipped and says why."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest
from entry import cli

from faults._checks import digest, one_line_error

#: 1 MB holds a few hundred kB of records, far from a 100-run x 500-episode cell.
BIG = ["method=ssrl", "maze=11x11", "runs=100", "episodes=500", "progress=false"]


@pytest.fixture
def mount_small(tmp_path):
    """``mount_small(size, read_only=False)``: a folder on a tmpfs of ``size``, unmounted after."""
    mounted = []

    def mount(size: str, read_only: bool = False) -> Path:
        where = tmp_path / f"disk{len(mounted)}"
        where.mkdir()
        if os.geteuid() != 0:
            pytest.skip("mounting a small tmpfs needs root: the full-disk cases are not run here")
        options = f"size={size}" + (",ro" if read_only else "")
        done = subprocess.run(
            ["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(where)],
            capture_output=True,
            text=True,
        )
        if done.returncode != 0:
            pytest.skip(f"cannot mount a tmpfs here ({done.stderr.strip()}): cases not run")
        mounted.append(where)
        return where

    yield mount
    for where in mounted:
        subprocess.run(["umount", str(where)], check=False)


def test_a_full_disk_stops_a_trial_in_one_line_and_removes_its_staging(mount_small):
    out = mount_small("1m") / "out"
    line = one_line_error(
        cli("trials", *BIG, f"out={out}"),
        f"config key 'out': no space left on the device of {out}",
        "the run needs about",
        "of 50,000 episodes",
    )
    assert "MB free" in line or "kB free" in line  # measured once the staging folder is gone
    assert [p.name for p in out.iterdir()] == []


def test_a_full_disk_keeps_the_previous_results_and_names_a_stale_staging_folder(mount_small):
    out = mount_small("1m") / "out"
    assert (
        cli("trials", "method=ssrl", "maze=5x5", "runs=2", "episodes=5", f"out={out}").returncode
        == 0
    )
    before = digest(out)
    ended = subprocess.Popen(["true"])  # a process that has ended: its staging folder is stale
    ended.wait()
    stale = out / f".staging-{ended.pid}"  # the partial records of a killed run
    stale.mkdir()
    (stale / "records.mcap.partial").write_bytes(b"\0" * 200_000)
    line = one_line_error(
        cli("trials", *BIG, f"out={out}", "overwrite=true"), "no space left", str(out)
    )
    assert f"{stale} (an interrupted run's partial records) holds 200.0 kB" in line
    assert sorted(p.name for p in out.iterdir()) == [
        stale.name,
        "records.mcap",
        "summary.json",
    ]
    assert {k: v for k, v in digest(out).items() if not k.startswith(".")} == before


def test_a_full_disk_stops_an_experiment_with_workers_in_one_line(mount_small):
    out = mount_small("1m") / "out"
    one_line_error(
        cli(
            "trials",
            "+experiment=fig9",
            "recogniser=oracle",
            "workers=2",
            "progress=false",
            f"out={out}",
        ),
        f"config key 'out': no space left on the device of {out}",
        "; cell 'way",  # the cell that met the full disk: what it needs, or that it could not start
        "(one of 8 cells)",
    )
    assert [p.name for p in out.iterdir()] == []


@pytest.fixture(scope="module")
def records(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("records")
    assert (
        cli("trials", "method=ssrl", "maze=5x5", "runs=2", "episodes=5", f"out={out}").returncode
        == 0
    )
    return out / "records.mcap"


@pytest.mark.parametrize(
    "read_only,words",
    [
        (False, ["no space left on the device of", "the replay needs"]),
        (True, ["Read-only file system"]),
    ],
)
def test_replay_to_a_full_or_read_only_disk_is_one_line_and_no_file(
    mount_small, records, read_only, words
):
    disk = mount_small("16k", read_only)
    rrd = disk / "replay.rrd"
    one_line_error(
        cli("replay", f"file={records}", "run=1", "episode=2", f"out={rrd}"),
        "config key 'out': ",
        str(disk),
        *words,
    )
    assert list(disk.iterdir()) == []  # no .rrd, no temporary file


def test_replay_writes_its_rrd_whole(tmp_path, records):
    """The .rrd appears complete or not at all: written from memory through one atomic rename."""
    rrd = tmp_path / "r.rrd"
    assert cli("replay", f"file={records}", "run=1", "episode=2", f"out={rrd}").returncode == 0
    assert rrd.stat().st_size > 0 and [p.name for p in tmp_path.iterdir()] == ["r.rrd"]
