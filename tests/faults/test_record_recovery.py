"""Record files survive damage: nothing lost beyond the damaged part, nothing lost silently
(docs/reliability.md "Record files").

Every case checks what a user sees (exit status, one line naming the file and the problem), what
survives (the episodes of intact chunks, equal to the undamaged file's), and that reading leaves the
input file as it was. Small synthetic files written like the trials stage writes them (config with
runs and episodes, runs interleaved batch by batch, a chunk every 8 episodes: many chunks).
"""

from __future__ import annotations

import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from synthetic_records import LAYOUT_5X5, MAZE_5X5, batches, obstacle_assignment, tiny_png

from faults._checks import sha
from pipeline.records import RecordsError, RecordsWarning, RecordWriter, read_records
from pipeline.records import schema as S

ROOT = Path(__file__).resolve().parents[2]
RUNS, EPISODES = 3, 12
CHUNK_MSG = r"chunk (\d+) of (\d+) damaged \((CRC mismatch|bad decompression|bad record lengths|bad chunk header)"


def write(path: Path, *, pictures: bool = True, flush_every: int = 8) -> Path:
    """A record file as the trials stage writes it: batches of 4 episodes, runs interleaved."""
    every = list(batches(LAYOUT_5X5, batch_size=4, runs=RUNS, episodes_per_run=EPISODES, seed=0))
    per_run = [[(b, g) for b, g in every if b["run"] == run] for run in range(RUNS)]
    with RecordWriter(
        path,
        metadata={
            "config": {"experiment": "faults", "runs": RUNS, "episodes": EPISODES, "seed": 0},
            "seeds": list(range(RUNS)),
        },
        maze=MAZE_5X5,
        runs=[obstacle_assignment(LAYOUT_5X5, r) for r in range(RUNS)],
        pictures={p: tiny_png(p) for p in range(40)} if pictures else None,
        flush_every=flush_every,
    ) as w:
        for i in range(len(per_run[0])):
            for run in range(RUNS):
                batch, group = per_run[run][i]
                for s in (s for f in group for s in f["_substitutions"]):
                    w.substitution(**s)
                w.episodes(**batch)
    return path


def chunks(path: Path) -> list[tuple[int, int, set[tuple[int, int]], set[str]]]:
    """(offset, length, episodes, topics) of each chunk, read with the mcap package's own reader."""
    from mcap.reader import make_reader
    from mcap.records import Channel, Message
    from mcap.stream_reader import StreamReader, breakup_chunk

    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    topics = {c.id: c.topic for c in summary.channels.values()}
    out = []
    with open(path, "rb") as f:
        offsets = iter(
            sorted((c.chunk_start_offset, c.chunk_length) for c in summary.chunk_indexes)
        )
        for rec in StreamReader(f, emit_chunks=True).records:
            if type(rec).__name__ != "Chunk":
                continue
            off, length = next(offsets)
            eps, tops = set(), set()
            for r in breakup_chunk(rec, validate_crc=True):
                if isinstance(r, Message):
                    tops.add(topics[r.channel_id])
                    if topics[r.channel_id] == S.TOPIC_EPISODES:
                        m = S.EpisodeBatch.FromString(r.data)
                        eps |= {(m.run, e) for e in m.episode}
                elif isinstance(r, Channel):
                    tops.add(r.topic)
            out.append((off, length, eps, tops))
    return out


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("faults")
    out = {}
    for name, pictures in (("pictures", True), ("plain", False)):
        path = write(d / f"{name}.mcap", pictures=pictures)
        with warnings.catch_warnings():
            warnings.simplefilter(
                "error", RecordsWarning
            )  # the intact file reads without a warning
            full = read_records(path)
        assert full.meta.complete and len(full.episodes) == RUNS * EPISODES
        out[name] = (path, path.read_bytes(), full, chunks(path))
    return out


def read_warned(path: Path):
    before = sha(path)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r = read_records(path)
    msgs = [str(w.message) for w in caught if issubclass(w.category, RecordsWarning)]
    assert sha(path) == before  # reading changes nothing on disk
    return r, msgs


def same_as_full(r, full, keep: set[tuple[int, int]]) -> None:
    """The episodes and steps read are exactly the undamaged file's rows of ``keep``."""

    def rows(df):
        key = list(zip(df.run, df.episode))
        return df[[k in keep for k in key]].drop(columns="file").reset_index(drop=True)

    assert set(zip(r.episodes.run, r.episodes.episode)) == keep
    if not keep:
        assert r.steps.empty and r.recognitions.empty
        return
    assert r.episodes.drop(columns="file").reset_index(drop=True).equals(rows(full.episodes))
    assert r.steps.drop(columns="file").reset_index(drop=True).equals(rows(full.steps))
    assert (
        r.recognitions.drop(columns="file").reset_index(drop=True).equals(rows(full.recognitions))
    )


def said_lost(message: str, word: str = "lost") -> set[tuple[int, int]]:
    """The (run, episode) pairs a warning says were lost (or missing): ``run 1 episodes 4-7``,
    ``runs 0-2 episodes 0-3 each``, ``run 2 episode 5``, ``runs 1-2 (all 12 episodes each)``."""
    import re

    out = set()
    for part in re.findall(rf"{word} ([^;:]*)", message):
        for m in re.finditer(
            r"runs? (\d+)(?:-(\d+))? (?:episodes? (\d+)(?:-(\d+))?|\(all (\d+) episodes)", part
        ):
            r0, r1 = int(m[1]), int(m[2] or m[1])
            e0, e1 = (int(m[3]), int(m[4] or m[3])) if m[3] else (0, int(m[5]) - 1)
            out |= {(r, e) for r in range(r0, r1 + 1) for e in range(e0, e1 + 1)}
    return out


def cli(args: list[str], capsys) -> tuple[int, str, str]:
    from pipeline.cli import main  # safenav records <args>

    try:
        main(["records", *(str(a) for a in args)])
        code = 0
    except SystemExit as e:
        code = e.code
    out = capsys.readouterr()
    return code, out.out, out.err


def flip(data: bytes, offset: int) -> bytes:
    b = bytearray(data)
    b[offset] ^= 0x5A
    return bytes(b)


# ---------------------------------------------------------------------------------- one flipped byte
@pytest.mark.parametrize("which", ["first", "middle", "last"])
@pytest.mark.parametrize("kind", ["pictures", "plain"])
def test_a_flipped_byte_loses_only_its_chunk(files, tmp_path, capsys, which, kind):
    path, data, full, cks = files[kind]
    i = {"first": 0, "middle": len(cks) // 2, "last": len(cks) - 1}[which]
    off, length, lost_eps, topics = cks[i]
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(flip(data, off + length - 40))  # inside the chunk's compressed data
    r, msgs = read_warned(bad)
    assert len(msgs) == 1 and "\n" not in msgs[0] and msgs[0].startswith(f"{bad}: ")
    m = __import__("re").search(CHUNK_MSG, msgs[0])
    assert m and (int(m[1]), int(m[2])) == (i + 1, len(cks)), msgs[0]
    every = set(zip(full.episodes.run, full.episodes.episode))
    same_as_full(r, full, every - lost_eps)
    assert not r.meta.complete and r.meta.damaged and r.meta.status == "DAMAGED"
    if lost_eps:  # says exactly which runs and episodes were lost
        assert said_lost(msgs[0]) == lost_eps, msgs[0]
        assert f"kept {len(every) - len(lost_eps)} of {len(every)} episodes" in msgs[0]
    else:
        assert "no episode lost" in msgs[0]
    if any(t.startswith("/pictures/") for t in topics):
        assert "lost the 40 pictures" in msgs[0] and not r.meta.pictures
    elif kind == "pictures":
        assert len(r.meta.pictures) == 40
    # the channel and schema definitions of a lost first chunk come from the summary
    assert r.meta.config["episodes"] == EPISODES and r.meta.maze["layout"] == LAYOUT_5X5
    code, out, err = cli([bad], capsys)
    assert code == 0 and err == ""
    line = next(x for x in out.splitlines() if x.startswith(f"{bad}: "))
    assert "DAMAGED" in line and "complete" not in line
    assert f"{len(every) - len(lost_eps)} of {len(every)} episodes" in line or not lost_eps


def test_a_damaged_first_chunk_of_a_killed_run_keeps_the_episodes_of_the_other_chunks(
    files, tmp_path
):
    """No summary (killed run) and the only copy of the channel definitions damaged: the writer's
    fixed channel layout still lets the other chunks be read."""
    path, data, full, cks = files["plain"]
    off, length, lost_eps, topics = cks[0]
    assert (
        S.TOPIC_EPISODES in topics and lost_eps
    )  # the first chunk defines the channels and holds episodes
    cut = cks[-1][0] + 5  # a killed run: it ends 5 bytes into its last chunk
    bad = tmp_path / "records.mcap.partial"
    bad.write_bytes(flip(data[:cut], off + length - 40))
    r, msgs = read_warned(bad)
    assert len(msgs) == 1 and str(bad) in msgs[0] and "fixed channel layout" in msgs[0]
    assert "chunk 1 damaged" in msgs[0] and "the file is truncated" in msgs[0]
    every = set(zip(full.episodes.run, full.episodes.episode))
    same_as_full(r, full, every - lost_eps - cks[-1][2])
    assert said_lost(msgs[0]) == lost_eps and said_lost(msgs[0], "missing") == cks[-1][2], msgs[0]
    assert r.meta.status == "PARTIAL, DAMAGED"


def test_a_bad_chunk_length_loses_nothing_with_an_index_and_stops_reading_without(files, tmp_path):
    path, data, full, cks = files["pictures"]
    off, length, lost_eps, _ = cks[2]
    every = set(zip(full.episodes.run, full.episodes.episode))
    bad = (
        tmp_path / "with-summary.mcap"
    )  # the chunk index says where chunk 3 and its data are: nothing lost
    bad.write_bytes(flip(data, off + 2))  # the record length of chunk 3
    r, msgs = read_warned(bad)
    assert len(msgs) == 1 and "the data section's CRC does not match" in msgs[0], msgs
    same_as_full(r, full, every)
    assert r.meta.status == "DAMAGED"
    # a killed run's file has no index: reading stops at the damaged record, keeps what was before
    bad = tmp_path / "killed.mcap.partial"
    bad.write_bytes(flip(data[: cks[-1][0] + 5], off + 2))
    r, msgs = read_warned(bad)
    assert len(msgs) == 1 and f"chunk 3 at byte {off}" in msgs[0] and "lost" in msgs[0], msgs
    same_as_full(r, full, cks[0][2] | cks[1][2])
    assert lost_eps <= said_lost(msgs[0]) | said_lost(msgs[0], "missing"), msgs[0]


# ---------------------------------------------------------------------------------- truncated
@pytest.mark.parametrize("where", [0.1, 0.5, 0.9, "summary"])
def test_a_truncated_file_keeps_its_complete_chunks(files, tmp_path, capsys, where):
    path, data, full, cks = files["pictures"]
    summary_start = cks[-1][0] + cks[-1][1]
    cut = int(len(data) * where) if where != "summary" else (summary_start + len(data)) // 2
    bad = tmp_path / "cut.mcap"
    bad.write_bytes(data[:cut])
    r, msgs = read_warned(bad)
    assert len(msgs) == 1 and msgs[0].startswith(f"{bad}: ") and "truncated" in msgs[0]
    keep = set().union(*(eps for o, n, eps, _ in cks if o + n <= cut))
    same_as_full(r, full, keep)
    every = set(zip(full.episodes.run, full.episodes.episode))
    if keep != every:
        assert said_lost(msgs[0], "missing") == every - keep, msgs[0]
        assert (
            f"kept {len(keep)} of {len(every)} episodes" in msgs[0]
            or "no complete episode could be read (36 expected)" in msgs[0]
        )
    else:
        assert "all recorded data is intact" in msgs[0]
    code, out, err = cli([bad], capsys)
    assert code == 0 and err == "" and f"{bad}: INCOMPLETE; " in out and "complete;" not in out


# ---------------------------------------------------------------------------------- unusable files
def _foreign(path: Path) -> Path:
    from mcap.writer import Writer

    with open(path, "wb") as f:
        w = Writer(f)
        w.start(profile="ros1", library="some-robot-logger 0.1")
        ch = w.register_channel(
            "/chatter", "ros1", w.register_schema("std_msgs/String", "ros1msg", b"string data")
        )
        for i in range(5):
            w.add_message(ch, log_time=i, publish_time=i, data=b"\x05\x00\x00\x00hello")
        w.finish()
    return path


@pytest.mark.parametrize(
    "case,problem",
    [
        ("empty", "empty file (0 bytes)"),
        ("png", "not an MCAP file"),
        (
            "foreign",
            "not a record file of this pipeline: an MCAP file written by 'some-robot-logger 0.1'",
        ),
        ("header", "the file is truncated: it ends 3 bytes into a header record"),
    ],
)
def test_an_unusable_file_is_named_in_one_line(files, tmp_path, capsys, case, problem):
    bad = tmp_path / "records.mcap"
    if case == "empty":
        bad.write_bytes(b"")
    elif case == "png":
        bad.write_bytes(tiny_png(3))
    elif case == "foreign":
        _foreign(bad)
    else:
        bad.write_bytes(files["pictures"][1][:20])
    before = sha(bad)
    code, out, err = cli([bad], capsys)
    assert (
        code == 2
        and out == ""
        and err == f"error: {bad}: {err.split(': ', 2)[2]}"
        and err.count("\n") == 1
    )
    assert problem in err
    if case != "header":
        with pytest.raises(RecordsError, match=problem.replace("(", r"\(").replace(")", r"\)")):
            read_records(bad)
    # replay: the same one line, blaming the file, exit 2
    from pipeline.stages import stage_main
    from pipeline.stages.replay import run as replay_run

    with pytest.raises(SystemExit) as exc:
        stage_main(
            "replay", replay_run, [f"file={bad}", "run=0", "episode=0", f"out={tmp_path / 'x.rrd'}"]
        )
    err = capsys.readouterr().err
    assert (
        exc.value.code == 2
        and err.count("\n") == 1
        and err.startswith(f"error: config key 'file': {bad}: ")
    )
    assert problem in err and not (tmp_path / "x.rrd").exists()
    assert sha(bad) == before


# ---------------------------------------------------------------------------------- folders
def test_a_folder_lists_partial_files_beside_complete_ones(files, tmp_path, capsys):
    path, data, full, cks = files["pictures"]
    out_dir = tmp_path / "runs"
    (out_dir / ".staging-4242").mkdir(parents=True)
    (out_dir / "records.mcap").write_bytes(data)  # an older complete file
    killed = out_dir / ".staging-4242" / "records.mcap.partial"  # a rerun of the trials, killed
    killed.write_bytes(data[: cks[3][0] + 5])
    beside = (
        out_dir / "records.mcap.partial"
    )  # a RecordWriter killed beside its older finished file
    beside.write_bytes(data[: cks[2][0] + 5])
    (out_dir / "picture.mcap").write_bytes(tiny_png(1))
    _foreign(out_dir / "other.mcap")
    before = {p: sha(p) for p in out_dir.rglob("*") if p.is_file()}
    code, out, err = cli([out_dir], capsys)
    assert code == 1  # some files could not be read: named on stderr, the others listed
    lines = [x for x in out.splitlines() if not x.startswith(("warning:", "replay one:"))]
    assert lines[0].startswith(f"{killed}: PARTIAL, INCOMPLETE; ")
    assert lines[1].startswith(f"{out_dir / 'records.mcap'}: complete; 3 runs, 36 episodes")
    assert lines[2].startswith(f"{beside}: PARTIAL, INCOMPLETE; ")
    assert len(lines) == 3 and "missing run" in lines[0]
    assert sorted(err.splitlines()) == sorted(
        [
            f"error: {out_dir / 'other.mcap'}: not a record file of this pipeline: an MCAP file written by "
            "'some-robot-logger 0.1' (channels /chatter), without the 'recording' metadata or an /episodes channel",
            f"error: {out_dir / 'picture.mcap'}: not an MCAP file: it does not start with the MCAP magic bytes",
        ]
    )
    # the library reads the finished file and says which unfinished ones it left out
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r = read_records(out_dir)
    said = " ".join(str(w.message) for w in caught)
    assert set(r.files) == {str(out_dir / "records.mcap")}
    assert f"{killed}: not read" in said and f"{beside}: not read" in said
    assert "picture.mcap: not an MCAP file" in said and "other.mcap: not a record file" in said
    assert before == {p: sha(p) for p in out_dir.rglob("*") if p.is_file()}
    # a folder of nothing readable: one line, exit 2
    for p in (killed, beside, out_dir / "records.mcap"):
        p.unlink()
    code, out, err = cli([out_dir], capsys)
    assert (
        code == 2
        and err.splitlines()[-1] == f"error: {out_dir}: none of its 2 record files could be read"
    )


def test_runs_piped_into_a_closed_pipe_stop_quietly(files, tmp_path):
    path = files["pictures"][0]
    proc = subprocess.Popen(
        [sys.executable, "-m", "pipeline.records", str(path), "--runs"],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    proc.stdout.close()  # like `| head -0`: the reader is gone before anything is written
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 141 and err == ""
    res = subprocess.run(
        f"{sys.executable} -m pipeline.records {path} --runs | head -1",
        shell=True,
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert res.returncode == 0 and res.stderr == "" and res.stdout.count("\n") == 1


@pytest.mark.parametrize("unbuffered", ["1", ""])
def test_a_folder_listing_into_a_reader_that_stops_early_ends_quietly(files, tmp_path, unbuffered):
    """``python -m pipeline.records DIR --runs | head``: the reader goes away mid-listing (an unreadable file named
    on stderr, a warning, more files to list), stdout unbuffered or not: exit 141, no traceback, nothing on stderr
    but the error line."""
    data = files["pictures"][1]
    folder = tmp_path / "runs"
    folder.mkdir()
    (folder / "a-picture.mcap").write_bytes(tiny_png(1))
    (folder / "b-cut.mcap").write_bytes(data[: len(data) // 2])
    for i in range(60):  # some 30 kB of listing: still writing when the reader stops
        (folder / f"run{i:02d}.mcap").write_bytes(data)
    proc = subprocess.Popen(
        [sys.executable, "-m", "pipeline.records", str(folder), "--runs"],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env={**os.environ, "PYTHONUNBUFFERED": unbuffered},
    )
    first = proc.stdout.readline().decode()
    proc.stdout.close()  # like `| head -1`
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=300) == 141 and first.startswith(f"warning: {folder / 'b-cut.mcap'}: ")
    assert "Traceback" not in err
    assert err.splitlines() == [
        f"error: {folder / 'a-picture.mcap'}: not an MCAP file: it does not start with the MCAP magic bytes"
    ]


def test_the_writer_layout_the_reader_falls_back_on(files):
    from mcap.reader import make_reader

    from pipeline.records.scan import WRITER_CHANNELS

    with open(files["plain"][0], "rb") as f:
        reader = make_reader(f)
        summary, header = reader.get_summary(), reader.get_header()
    assert header.library == S.LIBRARY
    for cid, (topic, sid, cls) in WRITER_CHANNELS.items():
        ch = summary.channels[cid]
        assert (ch.topic, ch.schema_id, summary.schemas[sid].name) == (
            topic,
            sid,
            cls.DESCRIPTOR.full_name,
        )


def test_ranges_and_their_descriptions():
    from pipeline.records.loss import describe

    rg = [(1, 40, 41), (1, 42, 42), (2, 0, 1), (3, 0, 1)]  # adjacent ranges of a run are joined
    assert describe(rg, 2) == "run 1 episodes 40-42, runs 2-3 (all 2 episodes each) (7 episodes)"
    assert describe([(0, 5, 5)], None) == "run 0 episode 5"
    assert (
        describe([(r, 60, 99) for r in range(100)], 100)
        == "runs 0-99 episodes 60-99 each (4000 episodes)"
    )


def test_a_flipped_byte_outside_the_chunks_is_detected(files, tmp_path):
    """The metadata records have no CRC of their own: the data-end record's CRC of the whole data
    section (the writer enables it) catches a flipped byte there, and nothing is lost."""
    path, data, full, cks = files["pictures"]
    at = (
        data.index(b'"experiment":"faults"') + 15
    )  # inside the config metadata record, before chunk 1
    assert at < cks[0][0]
    bad = tmp_path / "meta.mcap"
    bad.write_bytes(data[:at] + b"F" + data[at + 1 :])
    r, msgs = read_warned(bad)
    assert len(msgs) == 1 and msgs[0].startswith(f"{bad}: the data section's CRC does not match")
    assert r.meta.status == "DAMAGED" and len(r.episodes) == len(full.episodes)


def test_any_single_flipped_byte_is_reported_and_nothing_breaks(files, tmp_path):
    path, data, full, cks = files["pictures"]
    bad = tmp_path / "x.mcap"
    for at in range(3, len(data), 127):
        bad.write_bytes(flip(data, at))
        try:
            r, msgs = read_warned(bad)
        except RecordsError as e:  # the magic bytes: not an MCAP file any more
            assert at < 8 and "not an MCAP file" in str(e)
            continue
        assert not r.meta.complete and len(msgs) == 1 and str(bad) in msgs[0], at


@pytest.mark.parametrize("length", [0, 1, 2, 3, 5])
def test_a_damaged_data_end_length_is_reported(files, tmp_path, length):
    """The data-end record's length (4) has no CRC over it; a changed one is found all the same."""
    path, data, full, cks = files["pictures"]
    foot = (
        len(data) - 8 - 29
    )  # the footer: opcode, length, summary start, summary offset start, CRC
    head = (
        int.from_bytes(data[foot + 9 : foot + 17], "little") - 13
    )  # the data-end record before the summary
    assert data[head] == 0x0F and int.from_bytes(data[head + 1 : head + 9], "little") == 4
    bad = tmp_path / "dataend.mcap"
    bad.write_bytes(data[: head + 1] + length.to_bytes(8, "little") + data[head + 9 :])
    r, msgs = read_warned(bad)
    assert not r.meta.complete and len(msgs) == 1 and str(bad) in msgs[0]
    assert len(r.episodes) == len(full.episodes)


def test_what_a_killed_long_run_lost_is_worked_out_in_ranges():
    """The loss accounting of a killed 100 x 200,000 trial (every run stopped at episode 1,300) and
    of a damaged file with a gap, a window and an unknown shape: ranges per run, not episodes."""
    from pipeline.records.loss import account

    runs, eps = np.repeat(np.arange(100), 1300), np.tile(np.arange(1300), 100)
    expected, lost, absent = account(runs, eps, runs=100, per_run=200_000, finished=False)
    assert (expected, lost) == (20_000_000, [])
    assert absent == [(r, 1300, 199_999) for r in range(100)]
    keep = ~((runs == 3) & (eps >= 40) & (eps < 60)) & (eps < 100)  # run 3 lost 40-59
    span = [(S.log_time_ns(3, 40), S.log_time_ns(3, 59))]
    assert account(runs[keep], eps[keep], runs=100, per_run=100, finished=True, spans=span) == (
        10_000,
        [(3, 40, 59)],
        [],
    )
    window, inside = (S.log_time_ns(3, 0), S.log_time_ns(4, 0)), keep & (runs == 3)
    got = account(runs[inside], eps[inside], runs=100, per_run=100, finished=True, window=window)
    assert got == (100, [(3, 40, 59)], [])
    got = account(runs[keep], eps[keep], runs=None, per_run=None, finished=False)
    assert got == (None, [(3, 40, 59)], [])  # a gap is lost even in an unfinished file
    tail = keep & ~((runs == 5) & (eps >= 90))  # run 5 cut at 90 inside a damaged chunk's span
    span = [(S.log_time_ns(5, 88), S.log_time_ns(5, 95))]
    got = account(runs[tail], eps[tail], runs=100, per_run=100, finished=False, spans=span)
    assert got == (10_000, [(3, 40, 59), (5, 90, 99)], [])
