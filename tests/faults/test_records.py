"""Record files damaged at derived offsets. A small record file of the trials stage
(docs/reliability.md "Record files", docs/records.md "Damaged and truncated files"): cut at N
evenly spaced offsets, a byte flipped at N offsets, a range zeroed, a range cut out, bytes appended.

The one reader (:func:`pipeline.records.read_records`) gives, for each, exactly one of: one
:class:`~pipeline.records.RecordsError` line naming the file (only when the file no longer starts
with the MCAP magic bytes), or what survives with one :class:`~pipeline.records.RecordsWarning`
line naming the file and saying how many episodes it kept. What survives is the undamaged file's
rows, at least the episodes of every chunk the damage did not touch (exactly the complete chunks
before a cut; everything when bytes were appended); a damaged file is never ``complete``; reading
leaves the file as it was. ``python -m pipeline.records FILE`` says the same (in this process), and
the replay and report stages refuse or warn in one line (one replay through a child process: the
line a user sees, with Python's own warning output).
"""

from __future__ import annotations

import re
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from entry import ROOT, cli

from faults._checks import sha
from faults.test_record_recovery import chunks
from pipeline.records import RecordsError, RecordsWarning, read_records
from pipeline.records.scan import MAGIC
from pipeline.stages import run_stage

N = 16


@pytest.fixture(scope="module")
def original(tmp_path_factory):
    """The trials stage's records of 2 runs x 5 episodes of SSRL, a chunk a run (``flush_every=1``:
    a chunk a batch the runner hands over): (path, bytes, records, chunks)."""
    out = tmp_path_factory.mktemp("records") / "trial"
    args = ["method=ssrl", "runs=2", "episodes=5", f"out={out}", "progress=false", "flush_every=1"]
    run_stage("trials", args)
    path = out / "records.mcap"
    with warnings.catch_warnings():
        warnings.simplefilter("error", RecordsWarning)  # the intact file reads without a warning
        full = read_records(path)
    assert full.meta.complete and len(full.episodes) == 10
    assert len(chunks(path)) == 2
    return path, path.read_bytes(), full, chunks(path)


#: Damage -> (how many, where the first lies, in steps of the file's size over how many).
SPACED = {"cut": (N, 0.0), "flip": (N, 0.5), "zero": (N // 2, 0.25), "drop": (N // 4, 0.5)}
APPENDED = {
    "text": b"garbage after the end\n",
    "bytes": bytes((i * 151 + 7) % 256 for i in range(1000)),
    "zeros": bytes(4096),
    "its magic": MAGIC,
    "a newline": b"\n",
    "the file again": None,
}
CASES = [
    pytest.param(kind, k, id=f"{kind}-{k}") for kind, (n, _) in SPACED.items() for k in range(n)
]
CASES += [pytest.param(f"append {what}", 0, id=f"append {what}") for what in APPENDED]


def offset(kind: str, k: int, size: int) -> int:
    n, first = SPACED[kind]
    return min(size - 1, round((k + first) * size / n))


def damaged(data: bytes, kind: str, k: int) -> tuple[bytes, int]:
    """The damaged bytes and the offset where the damage starts."""
    if kind.startswith("append"):
        extra = APPENDED[kind.removeprefix("append ")]
        return data + (data if extra is None else extra), len(data)
    at = offset(kind, k, len(data))
    if kind == "cut":
        return data[:at], at
    if kind == "flip":
        return data[:at] + bytes([data[at] ^ 0xFF]) + data[at + 1 :], at
    if kind == "zero":
        return data[:at] + bytes(len(data[at : at + 64])) + data[at + 64 :], at
    return data[:at] + data[at + 100 :], at  # drop: 100 bytes cut out


def same_rows(r, full, keep: set[tuple[int, int]]) -> None:
    """Every frame read is the undamaged file's rows of the episodes ``keep``."""
    for name in ("episodes", "steps", "recognitions", "unsafe", "substitutions"):
        got, want = getattr(r, name), getattr(full, name)
        mask = np.fromiter((k in keep for k in zip(want.run, want.episode)), bool, len(want))
        want = want[mask].drop(columns="file").reset_index(drop=True)
        assert got.drop(columns="file").reset_index(drop=True).equals(want), name


def read(path: Path):
    """(records or None, the warnings' messages, the error's message or None), the file unchanged."""
    before = sha(path)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            r, error = read_records(path), None
        except RecordsError as exc:
            r, error = None, str(exc)
    assert sha(path) == before  # reading never changes a file
    return r, [str(w.message) for w in caught if issubclass(w.category, RecordsWarning)], error


def untouched(cks, kind: str, at: int) -> set[tuple[int, int]]:
    """The episodes the damage cannot have taken: every chunk's but the one a flipped byte is in;
    the chunks before a cut, a zeroed or a removed range; all of them when bytes were appended."""
    if kind.startswith("append"):
        return set().union(*(eps for *_, eps, _ in cks))
    if kind == "flip":
        return set().union(*(eps for o, n, eps, _ in cks if not o <= at < o + n))
    return set().union(*(eps for o, n, eps, _ in cks if o + n <= at))


@pytest.mark.parametrize("kind,k", CASES)
def test_a_damaged_file_reads_whole_or_as_a_prefix_with_one_line_or_is_one_error(
    original, tmp_path, capsys, kind, k
):
    path, data, full, cks = original
    bytes_, at = damaged(data, kind, k)
    assert bytes_ != data
    bad = tmp_path / "records.mcap"
    bad.write_bytes(bytes_)
    r, msgs, error = read(bad)
    every = set(zip(full.episodes.run, full.episodes.episode))
    if error is not None:  # only a file that no longer starts as an MCAP file is unreadable
        assert bytes_[:8] != MAGIC and msgs == [], (error, msgs)
        assert "\n" not in error and error.startswith(f"{bad}: "), error
    else:
        assert len(msgs) == 1 and "\n" not in msgs[0] and msgs[0].startswith(f"{bad}: "), msgs
        assert not r.meta.complete and r.meta.status in ("DAMAGED", "INCOMPLETE")
        kept = set(zip(r.episodes.run, r.episodes.episode))
        same_rows(r, full, kept)  # what is read is what was written
        assert untouched(cks, kind, at) <= kept <= every, (kept, msgs[0])
        if kind.startswith("append") and not bytes_.endswith(MAGIC):  # named, not "truncated"
            assert f"{len(bytes_) - len(data)} bytes follow the file's closing magic" in msgs[0]
        if kind == "cut":  # exactly the complete chunks before the cut
            assert kept == untouched(cks, kind, at) and "truncated" in msgs[0]
        n = len(kept)
        said = re.search(rf"kept {n}( of {len(every)})? episodes", msgs[0])
        assert said or (n == 0 and "no complete episode could be read" in msgs[0]), msgs[0]
    # safenav records FILE (python -m pipeline.records FILE): the same, in one line
    from pipeline.cli import main

    try:
        main(["records", str(bad)])
        code = 0
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    if error is not None:
        assert code == 2 and out == "" and err == f"error: {error}\n", (code, out, err)
    else:
        line = next(x for x in out.splitlines() if x.startswith(f"{bad}: "))
        assert (
            code == 0
            and err == ""
            and re.match(rf"{re.escape(str(bad))}: (DAMAGED|INCOMPLETE);", line)
        )


def test_the_derived_damages_reach_every_part_of_the_file(original):
    """Cuts and flips land in the header and metadata, in every chunk and in the summary section."""
    path, data, full, cks = original
    first, end = cks[0][0], cks[-1][0] + cks[-1][1]
    for kind in ("cut", "flip"):
        offsets = [offset(kind, k, len(data)) for k in range(SPACED[kind][0])]
        assert any(8 <= at < first for at in offsets) and any(at > end for at in offsets)
        for o, n, *_ in cks:
            assert any(o <= at < o + n for at in offsets) or n < len(data) / N, (kind, o, n)


# ------------------------------------------------------------------ replay and report
def _write(tmp_path: Path, data: bytes, name: str = "records.mcap") -> Path:
    bad = tmp_path / name
    bad.write_bytes(data)
    return bad


def _chunk_of_run(cks, run: int):
    return next((o, n) for o, n, eps, _ in cks if any(r == run for r, _ in eps))


@pytest.mark.parametrize(
    "case", ["summary cut", "metadata cut", "run 0's chunk flipped", "appended"]
)
def test_replay_of_a_damaged_file_is_one_line(original, tmp_path, case):
    path, data, full, cks = original
    o, n = _chunk_of_run(cks, 0)
    body = {
        "summary cut": data[: (cks[-1][0] + cks[-1][1] + len(data)) // 2],
        "metadata cut": data[: (8 + cks[0][0]) // 2],
        "run 0's chunk flipped": data[: o + n - 40]
        + bytes([data[o + n - 40] ^ 0xFF])
        + data[o + n - 39 :],
        "appended": data + b"garbage",
    }[case]
    bad = _write(tmp_path, body)
    for run in (0, 1):
        rrd = tmp_path / f"run{run}.rrd"
        out = cli("replay", f"file={bad}", f"run={run}", "episode=0", f"out={rrd}")
        lines = out.stderr.splitlines()
        assert len(lines) == 1 and str(bad) in lines[0], out.stderr
        readable = case in ("summary cut", "appended") or (case.startswith("run 0") and run != 0)
        if readable:
            assert out.returncode == 0 and lines[0].startswith(f"warning: {bad}: ") and rrd.exists()
        else:
            assert (
                out.returncode == 2
                and lines[0].startswith("error: config key")
                and not rrd.exists()
            )
            assert "damaged or cut" in lines[0], lines[0]


def test_replay_in_a_child_process_prints_one_line(original, tmp_path):
    """Python prints a warning nobody caught with its source line: none may escape the stage."""
    path, data, full, cks = original
    bad = _write(tmp_path, data[: (8 + cks[0][0]) // 2])
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "pipeline",
            "replay",
            f"file={bad}",
            "run=0",
            f"out={tmp_path}/x.rrd",
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 2 and out.stderr.count("\n") == 1, out.stderr
    assert out.stderr.startswith(f"error: config key 'run': {bad}: no recorded episode of run 0")
    assert not (tmp_path / "x.rrd").exists()


@pytest.mark.parametrize("case", ["cut in a chunk", "a chunk flipped", "appended", "empty"])
def test_the_report_refuses_a_damaged_record_file_and_keeps_the_old_report(
    original, tmp_path, case
):
    path, data, full, cks = original
    o, n = cks[-1][0], cks[-1][1]
    body = {
        "cut in a chunk": data[: o + n // 2],
        "a chunk flipped": data[: o + n - 40]
        + bytes([data[o + n - 40] ^ 0xFF])
        + data[o + n - 39 :],
        "appended": data + bytes(100),
        "empty": b"",
    }[case]
    cell = tmp_path / "runs" / "fig8" / "ssrl"
    cell.mkdir(parents=True)
    bad = _write(cell, body)
    reports = tmp_path / "reports"
    reports.mkdir()
    (reports / "index.md").write_text("the previous report\n")
    out = cli(
        "report",
        f"runs_dir={tmp_path / 'runs'}",
        f"accuracy_dir={tmp_path / 'none'}",
        f"out={reports}",
        "allow_missing=true",
    )
    assert out.returncode == 2 and out.stderr.count("\n") == 1, out.stderr
    assert out.stderr.startswith(f"error: {bad}: "), out.stderr
    assert sorted(p.name for p in reports.iterdir()) == ["index.md"]
    assert (reports / "index.md").read_text() == "the previous report\n"
    assert bad.read_bytes() == body
