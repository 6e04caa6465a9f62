"""MCAP records: schema, writer, reader, truncated files (docs/records.md)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from synthetic_records import (
    LAYOUT_5X5,
    MAZE_5X5,
    batches,
    make_batch,
    obstacle_assignment,
    tiny_png,
    write_synthetic,
)

from pipeline.records import RecordsWarning, RecordWriter, read_records
from pipeline.records import schema as S


def _episode(run=0, episode=0, n=3, **over):
    f = {
        "run": run,
        "episode": episode,
        "states": np.arange(n, dtype=np.int32),
        "actions": np.ones(n, np.int8),
        "rewards": np.zeros(n, np.float32),
        "flags": np.zeros(n, np.uint8),
        "recognitions": {},
        "unsafe_added": {},
        "summary": {
            "steps": n,
            "collisions": 0,
            "return_": 0.0,
            "reached_goal": False,
            "prevented": 0,
            "epsilon": 0.1,
            "greedy_optimal": False,
        },
    }
    f.update(over)
    return f


def test_flags_and_sources_mirror_the_rl_codes():
    from pipeline.rl.codes import Source, StepFlag

    assert {m.name: int(m) for m in StepFlag} == S.FLAG_NAMES
    assert tuple(m.name for m in sorted(Source)) == S.SOURCE_NAMES


def test_log_time_is_derived_from_run_episode_step():
    assert S.log_time_ns(0, 0, 0) == 0
    assert S.log_time_ns(3, 120, 7) == 3 * 10**15 + 120 * 10**9 + 7 * 10**6
    assert S.split_log_time(S.log_time_ns(99, 499, 199)) == (99, 499, 199)
    with pytest.raises(ValueError, match="step 1000"):
        S.log_time_ns(0, 0, 1000)


def test_write_then_read_back_equals_what_was_written(tmp_path):
    written = write_synthetic(tmp_path / "a.mcap", runs=3, episodes_per_run=7, seed=1)
    recs = read_records(tmp_path / "a.mcap")
    assert not (tmp_path / "a.mcap.partial").exists()
    assert len(recs.episodes) == 21
    steps = recs.steps.groupby(["run", "episode"])
    recg = recs.recognitions.groupby(["run", "episode"])
    unsafe = recs.unsafe.groupby(["run", "episode"])
    for f in written:
        key = (f["run"], f["episode"])
        st = steps.get_group(key)
        np.testing.assert_array_equal(st.state.to_numpy(), f["states"])
        np.testing.assert_array_equal(st.action.to_numpy(), f["actions"])
        np.testing.assert_array_equal(st.reward.to_numpy(), f["rewards"])
        np.testing.assert_array_equal(st["flags"].to_numpy(), f["flags"])
        np.testing.assert_array_equal(st.step.to_numpy(), np.arange(len(f["states"])))
        np.testing.assert_array_equal(st.collided.to_numpy(), (f["flags"] & S.FLAG_COLLIDED) != 0)
        rec = f["recognitions"]
        if len(rec["step"]):
            r = recg.get_group(key)
            for col, k in [
                ("step", "step"),
                ("state", "state"),
                ("action", "action"),
                ("picture", "picture"),
                ("predicted", "predicted"),
                ("true", "true"),
            ]:
                np.testing.assert_array_equal(r[col].to_numpy(), rec[k])
            np.testing.assert_array_equal(
                r[[f"score_{j}" for j in range(5)]].to_numpy(), rec["scores"]
            )
        un = f["unsafe_added"]
        if len(un["step"]):
            u = unsafe.get_group(key)
            for k in ("step", "state", "action", "source"):
                np.testing.assert_array_equal(u[k].to_numpy(), un[k])
        e = recs.episodes.set_index(["run", "episode"]).loc[key]
        for k, v in f["summary"].items():
            assert e[k] == v, k
        assert e["n_recognitions"] == len(rec["step"]) and e["n_unsafe_added"] == len(un["step"])
    assert recs.episodes.greedy_optimal.dtype == bool and recs.episodes.greedy_optimal.any()
    assert recs.episodes.reached_goal.dtype == bool
    subs = [s for f in written for s in f["_substitutions"]]
    assert len(recs.substitutions) == len(subs)
    got = recs.substitutions[["run", "episode", "step", "picture", "category", "position"]].to_dict(
        "records"
    )
    assert got == sorted(subs, key=lambda s: (s["run"], s["episode"], s["step"]))  # stable per step
    m = recs.meta
    assert m.complete and m.closed == {
        "complete": "true",
        "episodes": "21",
        "substitutions": str(len(subs)),
    }
    assert m.config == {"experiment": "synthetic", "seed": 1, "runs": 3}
    assert "experiment: synthetic" in m.config_yaml
    assert m.seeds == [0, 1, 2]
    assert (
        m.maze["layout"] == LAYOUT_5X5
        and m.maze["width"] == 5
        and m.maze["categories"][0] == "chair"
    )
    assert m.obstacles == {r: obstacle_assignment(LAYOUT_5X5, r, 1) for r in range(3)}
    assert m.pictures == {pid: tiny_png(pid) for pid in range(40)}
    assert m.versions["mcap"] and m.versions["python"]


def test_same_data_gives_the_same_bytes(tmp_path):
    write_synthetic(tmp_path / "a.mcap", runs=2, episodes_per_run=5)
    write_synthetic(tmp_path / "b.mcap", runs=2, episodes_per_run=5)
    assert (tmp_path / "a.mcap").read_bytes() == (tmp_path / "b.mcap").read_bytes()


def test_fsync_false_leaves_the_flush_to_the_caller_and_the_same_bytes(tmp_path, monkeypatch):
    """The trials stage writes records into a staging folder that ``swap_in`` syncs once: its
    writers skip the per-file ``fsync``, and the file is the same bytes either way."""
    import os

    synced = []
    real_fsync = os.fsync
    monkeypatch.setattr(os, "fsync", lambda fd: synced.append(fd) or real_fsync(fd))
    write_synthetic(tmp_path / "synced.mcap", runs=2, episodes_per_run=5)
    assert synced
    synced.clear()
    write_synthetic(tmp_path / "unsynced.mcap", runs=2, episodes_per_run=5, fsync=False)
    assert synced == []
    assert (tmp_path / "synced.mcap").read_bytes() == (tmp_path / "unsynced.mcap").read_bytes()


def test_pictures_are_stored_once_per_file(tmp_path):
    from mcap.reader import make_reader

    write_synthetic(tmp_path / "a.mcap", runs=2, episodes_per_run=20)
    with open(tmp_path / "a.mcap", "rb") as f:
        reader = make_reader(f)
        topics = [ch.topic for _, ch, _ in reader.iter_messages()]
    pictures = [t for t in topics if t.startswith("/pictures/")]
    assert len(pictures) == len(set(pictures)) == 40
    assert topics.count("/episodes") == 10  # one message per sink batch (of 4 episodes here)


def test_q_values_and_missing_scores_round_trip(tmp_path):
    q = np.arange(25 * 4, dtype=np.float32).reshape(25, 4) / 7
    rec = {
        "step": np.array([1, 2]),
        "state": np.array([3, 4]),
        "action": np.array([0, 1]),
        "picture": np.array([5, 6]),
        "predicted": np.array([1, 2]),
        "true": np.array([1, 3]),
        "scores": np.zeros((0, 0)),
    }
    with RecordWriter(tmp_path / "q.mcap") as w:
        w.episodes(
            **make_batch(
                [
                    _episode(
                        0,
                        0,
                        q_values=q,
                        recognitions=rec,
                        summary={
                            "steps": 3,
                            "collisions": 1,
                            "return_": -1.0,
                            "reached_goal": False,
                            "prevented": 1,
                            "epsilon": 0.07,
                            "greedy_optimal": True,
                        },
                    )
                ]
            )
        )
        w.episodes(**make_batch([_episode(0, 1)]))
    r = read_records(tmp_path / "q.mcap")
    assert list(r.q_values) == [(str(tmp_path / "q.mcap"), 0, 0)]
    np.testing.assert_array_equal(r.q_values[(str(tmp_path / "q.mcap"), 0, 0)], q)
    assert list(r.episodes.greedy_optimal) == [True, False] and list(r.episodes.epsilon) == [
        0.07,
        0.1,
    ]
    assert "score_0" not in r.recognitions and list(r.recognitions.correct) == [True, False]
    assert list(r.recognitions.episode) == [0, 0] and list(r.episodes.n_recognitions) == [2, 0]


def test_batches_of_the_runner_protocol_round_trip(tmp_path):
    """``episodes(**batch)`` with runs interleaving, as the runner hands them over; equals the frames
    of the same episodes written one at a time."""
    from pipeline.rl.sink import split_batch

    groups = list(batches(LAYOUT_5X5, batch_size=3, runs=2, episodes_per_run=7, seed=5))
    order = [g for pair in zip(groups[:3], groups[3:6]) for g in pair] + groups[
        6:
    ]  # run 0, run 1, ...
    with RecordWriter(tmp_path / "b.mcap", flush_every=4) as w:
        for batch, _ in order:
            w.episodes(**batch)
    with RecordWriter(tmp_path / "e.mcap") as w:
        for batch, _ in groups:
            for ep in split_batch(
                batch
            ):  # the sink protocol's own per-episode view, a batch of one each
                w.episodes(**make_batch([ep]))
    a, b = read_records(tmp_path / "b.mcap"), read_records(tmp_path / "e.mcap")
    for key in ("steps", "episodes", "recognitions", "unsafe"):
        assert getattr(a, key).drop(columns="file").equals(getattr(b, key).drop(columns="file")), (
            key
        )
    assert len(a.episodes) == 14 and a.meta.closed["episodes"] == "14"
    # one run, one episode: the batch stamped before it is read and filtered
    one = read_records(tmp_path / "b.mcap", run=1, episode=5)
    assert list(one.episodes.episode) == [5] and set(one.steps.episode) == {5}
    assert one.steps.drop(columns="file").equals(
        a.steps[(a.steps.run == 1) & (a.steps.episode == 5)]
        .drop(columns="file")
        .reset_index(drop=True)
    )


def _encode_with_the_runtime(b) -> bytes:
    """The reference: a checked batch filled into the real ``EpisodeBatch`` through the runtime's
    ``extend`` (what any Protobuf library writes for these values)."""
    from pipeline.records.codec import SUBS

    msg = S.EpisodeBatch(**{k: v for k, v in b["scalars"]["EpisodeBatch"].items()})
    for name, cols in b["cols"].items():
        sub = msg if name == "EpisodeBatch" else getattr(msg, {m: f for f, m in SUBS.items()}[name])
        for k, a in cols.items():
            if len(a):
                getattr(sub, k).extend(a.tolist())
    if b["scalars"]["Recognitions"]["n_categories"]:
        msg.recognitions.n_categories = b["scalars"]["Recognitions"]["n_categories"]
    return msg.SerializeToString(deterministic=True)


def _odd_batches(seed: int, n: int = 30):
    """Batches of the 11x11 maze with large states, negative predictions, no scores, -0.0 returns,
    Q tables and no unsafe-set additions."""
    from synthetic_records import maze_layout

    layout = maze_layout(11, seed=seed)
    groups = [
        b
        for b, _ in batches(
            layout, batch_size=5, runs=2, episodes_per_run=n, seed=seed, max_steps=300
        )
    ]
    groups[1]["states"] = groups[1]["states"] + 70000
    groups[2]["recognitions"]["predicted"][:] = -1
    groups[3]["recognitions"]["scores"] = np.zeros((0, 0), np.float32)
    groups[4]["summary"]["return_"] = -0.0 * groups[4]["summary"]["return_"]
    groups[5]["q_values"] = np.arange(5 * 121 * 4, dtype=np.float32).reshape(5, 121, 4)
    for k in ("step", "state", "action", "source", "episode"):
        groups[6]["unsafe_added"][k] = groups[6]["unsafe_added"][k][:0]
    return groups


def test_the_batch_encoder_matches_protobuf_byte_for_byte():
    """The raw-view encoding equals the real class filled through the runtime, byte for byte."""
    from pipeline.records.batch_check import check_batch
    from pipeline.records.codec import encode_batch

    for b in _odd_batches(2):
        checked = check_batch(b)
        assert encode_batch(checked) == _encode_with_the_runtime(checked)


def test_bad_input_is_refused_with_a_message_naming_it(tmp_path):
    from pipeline.records.batch_check import check_batch

    with pytest.raises(ValueError, match="end in .mcap"):
        RecordWriter(tmp_path / "x.bin")
    for batch, error, why in (
        (
            {k: v for k, v in make_batch([_episode()]).items() if k != "summary"},
            TypeError,
            "missing fields \\['summary'\\]",
        ),
        (make_batch([_episode(actions=np.zeros(2))]), ValueError, "actions: length 2, expected 3"),
        (make_batch([_episode(actions=np.zeros(3))]), ValueError, "must hold integers"),
        (
            make_batch([_episode(states=np.array([0, -1, 2]))]),
            ValueError,
            "states: values -1..2 outside 0..4294967295",
        ),
        (
            make_batch([_episode(actions=np.array([0, 1, 2**27], np.int64))]),
            ValueError,
            "actions: values 0..134217728 outside 0..134217727",  # action * 32 + flags: a uint32
        ),
        (
            make_batch([_episode(flags=np.array([0, 32, 1], np.uint8))]),
            ValueError,
            "flags: values 0..32 outside 0..31",  # five flag bits
        ),
        (
            make_batch([_episode(summary=dict(_episode()["summary"], violations=1))]),
            ValueError,
            "violations",
        ),
        (make_batch([_episode(1, 0), _episode(1, 2)]), ValueError, "consecutive"),
    ):
        with pytest.raises(error, match=why):
            check_batch(batch)
    check_batch(make_batch([_episode(states=np.array([0, 1, 2], ">i4"))]))  # non-native: kept
    # through the writer: checked on its thread, raised by the next call, naming the file
    w = RecordWriter(tmp_path / "x.mcap")
    w.episodes(**make_batch([_episode()]))
    with pytest.raises(ValueError, match="recorded once and in order"):  # at once, in the caller
        w.episodes(**make_batch([_episode()]))
    with pytest.raises(ValueError, match="episode -3 out of range"):
        w.episodes(**make_batch([_episode(run=2, episode=-3)]))
    w.episodes(**make_batch([_episode(1, 1, states=np.array([0, -1, 2]))]))
    with pytest.raises(ValueError, match=f"{tmp_path / 'x.mcap.partial'}: episode batch of run 1"):
        w.flush()
    with pytest.raises(ValueError, match="states: values -1..2"):  # the file is left .partial
        w.close()
    assert (tmp_path / "x.mcap.partial").exists() and not (tmp_path / "x.mcap").exists()


def test_a_disk_error_on_the_writer_thread_reaches_the_caller_naming_the_file(tmp_path):
    """An OSError on the writer's thread (a full disk) is raised by the next call with its errno and
    the file's name; the file keeps its .partial name."""
    import errno

    w = RecordWriter(tmp_path / "d.mcap")

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    w._mcap.add_message = full
    w.episodes(**make_batch([_episode()]))
    with pytest.raises(OSError) as e:
        w.flush()
    assert e.value.errno == errno.ENOSPC and e.value.filename == str(tmp_path / "d.mcap.partial")
    with pytest.raises(OSError, match="No space left"):
        w.close()
    assert (tmp_path / "d.mcap.partial").exists() and not (tmp_path / "d.mcap").exists()


def test_an_exception_leaves_a_finished_partial_file(tmp_path):
    with pytest.raises(RuntimeError):
        with RecordWriter(tmp_path / "r.mcap", flush_every=1) as w:
            w.episodes(**make_batch([_episode()]))
            raise RuntimeError("trial crashed")
    assert not (tmp_path / "r.mcap").exists()
    with pytest.warns(RecordsWarning, match="closed after an error"):
        r = read_records(tmp_path / "r.mcap.partial")
    assert len(r.episodes) == 1


def _chunks(path: Path) -> list[tuple[int, int, int]]:
    """(end offset, first log time, last log time) of each chunk record of a finished file."""
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    return sorted(
        (ci.chunk_start_offset + ci.chunk_length, ci.message_start_time, ci.message_end_time)
        for ci in summary.chunk_indexes
    )


def _chunk_ends(path: Path) -> list[int]:
    return [c[0] for c in _chunks(path)]


def test_a_file_truncated_at_many_points_reads_up_to_its_last_complete_chunk(tmp_path):
    written = write_synthetic(tmp_path / "full.mcap", runs=2, episodes_per_run=12, flush_every=3)
    data = (tmp_path / "full.mcap").read_bytes()
    full = read_records(tmp_path / "full.mcap")
    chunks = _chunks(tmp_path / "full.mcap")
    ends = [c[0] for c in chunks]
    assert (
        len(chunks) >= 1 + 24 // 4
    )  # the pictures, then a chunk once 3 episodes came in (4 a batch)
    from pipeline.records.scan import scan

    batch_sizes = {
        t: len(S.EpisodeBatch.FromString(d).episode)
        for t, d in scan(tmp_path / "full.mcap").messages["/episodes"]
    }
    assert sum(batch_sizes.values()) == len(written)
    rng = np.random.default_rng(0)
    cuts = set(rng.integers(9, len(data) - 1, 60).tolist())
    cuts |= {e + d for e in ends for d in (-1, 0, 1)}
    for cut in sorted(cuts):
        cut_path = tmp_path / "cut.mcap"
        cut_path.write_bytes(data[:cut])
        with pytest.warns(RecordsWarning) as caught:
            r = read_records(cut_path)
        msg = " ".join(str(w.message) for w in caught)
        assert str(cut_path) in msg and "truncated" in msg, (cut, msg)
        # exactly the episodes of the complete chunks before the cut, equal to the full read
        expected = sum(
            n
            for end, lo, hi in chunks[1:]
            if end <= cut
            for t, n in batch_sizes.items()
            if lo <= t <= hi
        )
        assert len(r.episodes) == expected, (cut, msg)
        assert ("no complete episode" in msg) == (expected == 0)
        assert r.episodes.drop(columns="file").equals(
            full.episodes.drop(columns="file").iloc[:expected]
        )
        n_steps = int(full.episodes.steps.iloc[:expected].sum())
        assert r.steps.drop(columns="file").equals(full.steps.drop(columns="file").iloc[:n_steps])
        if cut >= ends[0]:
            assert len(r.meta.pictures) == 40 and r.meta.maze["layout"] == LAYOUT_5X5


def test_a_corrupt_chunk_is_skipped_with_a_warning(tmp_path):
    write_synthetic(tmp_path / "full.mcap", runs=1, episodes_per_run=12, flush_every=3)
    data = bytearray((tmp_path / "full.mcap").read_bytes())
    ends = _chunk_ends(tmp_path / "full.mcap")
    data[ends[2] - 40] ^= 0xFF  # inside the third chunk's compressed data or its message index
    (tmp_path / "bad.mcap").write_bytes(bytes(data))
    with pytest.warns(RecordsWarning, match="bad.mcap"):
        r = read_records(tmp_path / "bad.mcap")
    assert len(r.episodes) == 8  # the third chunk's batch (episodes 8-11) is lost


def test_a_killed_writer_keeps_what_it_was_handed_flush_seconds_before(tmp_path):
    """Chunks close every ``flush_every`` episodes; what came after the last one is written as a
    provisional chunk once ``flush_seconds`` pass: a kill then loses nothing handed over. The child
    kills itself once the file on disk holds every episode (not after a guess at how long the
    writer's thread takes on a loaded machine); it exits 3 if that never happens."""
    script = f"""
import os, sys, time, warnings
sys.path.insert(0, {str(Path(__file__).resolve().parents[1])!r})
from tests.synthetic_records import LAYOUT_5X5, batches
from pipeline.records import RecordWriter, read_records
w = RecordWriter({str(tmp_path / "k.mcap")!r}, maze={{"layout": LAYOUT_5X5}}, flush_every=5,
                 flush_seconds=0.3)
for batch, _ in batches(LAYOUT_5X5, batch_size=3, runs=1, episodes_per_run=14):
    w.episodes(**batch)
end = time.monotonic() + 60
while time.monotonic() < end:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:  # the writer's thread may be mid-chunk: read again
            held = len(read_records(w.partial_path, pictures=False).episodes)
        except Exception:
            held = 0
    if held == 14:
        os._exit(9)  # killed: no close(), no interpreter clean-up
    time.sleep(0.05)
sys.exit(3)
"""
    res = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert res.returncode == 9, res.stderr
    assert not (tmp_path / "k.mcap").exists()
    with pytest.warns(RecordsWarning, match="k.mcap.partial"):
        r = read_records(tmp_path)  # a folder: the .partial of the killed run is found
    assert list(r.episodes.episode) == list(range(14))  # 0-11 in two chunks, 12-13 provisional


def test_provisional_chunks_leave_the_same_bytes(tmp_path):
    """A provisional chunk is overwritten by the next chunk and cut off at the end: the finished
    file is byte for byte the file written without any."""
    import time

    groups = [b for b, _ in batches(LAYOUT_5X5, batch_size=3, runs=2, episodes_per_run=12, seed=3)]
    for name, seconds in (("slow.mcap", 0.01), ("fast.mcap", 1e9)):
        with RecordWriter(
            tmp_path / name, maze=MAZE_5X5, flush_every=7, flush_seconds=seconds
        ) as w:
            for b in groups:
                w.episodes(**b)
                time.sleep(0.05 if seconds < 1 else 0)
    assert (tmp_path / "slow.mcap").read_bytes() == (tmp_path / "fast.mcap").read_bytes()


def test_reading_a_folder_and_filtering_one_episode(tmp_path):
    write_synthetic(tmp_path / "x" / "a.mcap", runs=2, episodes_per_run=5, seed=0)
    write_synthetic(tmp_path / "x" / "b.mcap", runs=3, episodes_per_run=5, seed=1)
    r = read_records(tmp_path / "x")
    assert len(r.files) == 2 and len(r.episodes) == 25
    assert r.episodes.groupby("file", observed=True).size().tolist() == [10, 15]
    one = read_records(tmp_path / "x" / "b.mcap", run=2, episode=3)
    assert len(one.episodes) == 1 and set(one.steps.episode) == {3} and set(one.steps.run) == {2}
    assert one.steps.equals(
        r.steps[
            (r.steps.file == str(tmp_path / "x" / "b.mcap"))
            & (r.steps.run == 2)
            & (r.steps.episode == 3)
        ]
        .reset_index(drop=True)
        .assign(file=lambda d: d.file.cat.remove_unused_categories())
    )


def test_a_file_that_is_no_mcap_is_refused(tmp_path):
    (tmp_path / "n.mcap").write_bytes(b"hello world, not mcap")
    with pytest.raises(ValueError, match="not an MCAP file"):
        read_records(tmp_path / "n.mcap")
    with pytest.raises(FileNotFoundError):
        read_records(tmp_path / "missing.mcap")


def test_rerun_mcap_convert_yields_the_pictures(tmp_path):
    import rerun.chunk

    write_synthetic(tmp_path / "a.mcap", runs=1, episodes_per_run=3)
    rerun_cli = Path(sys.executable).with_name("rerun")
    res = subprocess.run(
        [
            str(rerun_cli),
            "mcap",
            "convert",
            str(tmp_path / "a.mcap"),
            "-o",
            str(tmp_path / "a.rrd"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert res.returncode == 0, res.stderr
    images = {}
    episodes_seen = 0
    for ch in rerun.chunk.RrdReader(tmp_path / "a.rrd").stream().to_chunks():
        rb = ch.to_record_batch()
        path = str(ch.entity_path)
        if "EncodedImage:blob" in rb.schema.names:
            images[path] = rb.column("EncodedImage:blob").to_pylist()
        if path == "/episodes" and "fsrl.records.EpisodeBatch:message" in rb.schema.names:
            episodes_seen += ch.num_rows
    assert len(images) == 40
    blob = images["/pictures/7"][0]
    flat = blob[0] if isinstance(blob, list) and blob and isinstance(blob[0], list) else blob
    assert bytes(flat) == tiny_png(7)
    assert episodes_seen == 1  # the 3 episodes in one batch message
    # a killed run's file: Rerun needs --recover (without it, it writes an empty recording)
    data = (tmp_path / "a.mcap").read_bytes()
    (tmp_path / "cut.mcap").write_bytes(data[: len(data) - 3000])
    res = subprocess.run(
        [
            str(rerun_cli),
            "mcap",
            "convert",
            "--recover",
            str(tmp_path / "cut.mcap"),
            "-o",
            str(tmp_path / "cut.rrd"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert res.returncode == 0, res.stderr
    paths = {
        str(ch.entity_path)
        for ch in rerun.chunk.RrdReader(tmp_path / "cut.rrd").stream().to_chunks()
    }
    assert "/pictures/39" in paths


def _runtime_flat(data: list[bytes]) -> dict:
    """The reference decoder: every column of ``EpisodeBatch`` messages read through the real classes'
    repeated fields (what any Protobuf library reads), in the codec's ``_flat`` layout."""
    from pipeline.records.codec import COLUMNS, SUBS

    top = [S.EpisodeBatch.FromString(d) for d in data]
    msgs = {"EpisodeBatch": top} | {
        sub: [getattr(v, field) for v in top] for field, sub in SUBS.items()
    }
    out = {
        "run": np.array([m.run for m in top], np.int64),
        "n_actions": np.array([m.n_actions for m in top]),
        "n_categories": np.array([m.recognitions.n_categories for m in top], np.int64),
    }
    for msg, fields in COLUMNS.items():
        for f in fields:
            raw = [list(getattr(m, f.name)) for m in msgs[msg]]
            out[msg, f.name] = (
                np.array(
                    [x for xs in raw for x in xs],
                    {S.F32: np.float32, S.F64: np.float64}.get(f.type, np.int64),
                ),
                np.array([len(x) for x in raw], np.int64),
            )
    pairs, n = out["Steps", "transitions"]  # two values a step
    out["Steps", "transitions"] = pairs.reshape(-1, 2), n // 2
    return out


def test_raw_view_decoding_equals_the_protobuf_runtime(tmp_path):
    from pipeline.records import codec
    from pipeline.records.scan import scan

    def same(data):
        fast, slow = codec._flat(data), _runtime_flat(data)
        assert fast.keys() == slow.keys()
        for k in fast:
            for a, b in zip(fast[k], slow[k]) if isinstance(k, tuple) else [(fast[k], slow[k])]:
                np.testing.assert_array_equal(a, b, err_msg=str(k))
        cols, ref = codec._columns(fast, "v"), codec._columns(slow, "v")
        for key in ("steps", "recognitions", "unsafe", "episodes"):
            assert cols[key].keys() == ref[key].keys()
            for k in cols[key]:
                np.testing.assert_array_equal(cols[key][k], ref[key][k], err_msg=k)
                assert cols[key][k].dtype == ref[key][k].dtype, k
        return cols

    groups = _odd_batches(4, 20)
    with RecordWriter(
        tmp_path / "wide.mcap"
    ) as w:  # states of 128 or more: varints of several bytes
        for b in groups:
            w.episodes(**b)
    wide = [d for _, d in scan(tmp_path / "wide.mcap").messages["/episodes"]]
    assert max(S.EpisodeBatch.FromString(d).steps.transitions[0] for d in wide) >= 70000
    same(wide)
    states = read_records(tmp_path / "wide.mcap").steps.query(
        "run == 0 and episode in [5, 6, 7, 8, 9]"
    )["state"]
    np.testing.assert_array_equal(states, groups[1]["states"])
    groups[1]["states"] = groups[1]["states"] - 70000
    with RecordWriter(tmp_path / "v.mcap") as w:
        for b in groups:
            w.episodes(**b)
    msgs = scan(tmp_path / "v.mcap").messages["/episodes"]
    data = [d for _, d in msgs]
    cols = same(data)
    assert cols["q_values"].keys() == {
        ("v", 1, e) for e in range(5, 10)
    }  # group 5: run 1, episodes 5-9
    np.testing.assert_array_equal(cols["q_values"][("v", 1, 6)], groups[5]["q_values"][1])
    assert np.isnan(cols["recognitions"]["score_0"]).sum() > 0  # group 3: no scores
    # other valid encodings of the same values: re-serialized by the real classes, then read the same
    one = S.EpisodeBatch.FromString(data[0])
    pairs = one.steps.transitions
    tail = S.EpisodeBatch(steps=S.Steps(transitions=pairs[len(pairs) // 2 :]))
    one.steps.ClearField("transitions")
    one.steps.transitions.extend(pairs[: len(pairs) // 2])
    split = (
        one.SerializeToString(deterministic=True) + tail.SerializeToString()
    )  # a packed field in two
    unknown = data[0] + bytes([(15 << 3) | 0, 1])  # an unknown field 15
    long_code = S.EpisodeBatch.FromString(data[0])
    long_code.steps.transitions[1] = 200  # a two-byte varint in a code column
    for odd in (split, unknown, long_code.SerializeToString()):
        same([odd])
    np.testing.assert_array_equal(
        codec.decode_batches([split], "v")["steps"]["state"], np.asarray(pairs[::2], np.int32)
    )


def test_code_columns_of_every_size_read_back_exactly():
    """Code columns with varints of one to five bytes, in several messages, read as the runtime reads them
    (with the count a message); a payload cut inside a value is refused."""
    from pipeline.records import codec

    rng = np.random.default_rng(0)
    values = np.concatenate(
        [
            [0, 127, 128, 16383, 16384, 2**21, 2**28 - 1, 2**28, 2**32 - 1],
            rng.integers(0, 2**32, 500) >> rng.integers(0, 32, 500),
        ]
    )
    parts = [values[:8], values[8:8], values[7:], values[:4] % 128]  # whole pairs
    data = [
        S.EpisodeBatch(
            run=1,
            steps=S.Steps(transitions=v.tolist()),
            recognitions=S.CLASSES["Recognitions"](action=v % 4),
        ).SerializeToString()
        for v in parts
    ]
    got, want = codec._flat(data), _runtime_flat(data)
    for k in (("Steps", "transitions"), ("Recognitions", "action")):
        np.testing.assert_array_equal(got[k][0], want[k][0])
        assert got[k][1].tolist() == [len(v) // (2 if k[1] == "transitions" else 1) for v in parts]
    cut = codec.VIEWS["EpisodeBatch"](
        steps=codec.VIEWS["Steps"](
            transitions=codec._payload("Steps", codec.TRANSITIONS, np.array([300, 1]))[:1]
        )
    )
    with pytest.raises(ValueError, match="whole value"):
        codec._flat([cut.SerializeToString()])


def test_the_info_command_lists_runs_and_warns_about_truncation(tmp_path, capsys):
    from pipeline.cli import main  # safenav records <folder> --runs

    write_synthetic(tmp_path / "a.mcap", runs=2, episodes_per_run=4)
    data = (tmp_path / "a.mcap").read_bytes()
    (tmp_path / "b.mcap").write_bytes(data[: len(data) // 2])
    main(["records", str(tmp_path), "--runs"])
    out = capsys.readouterr().out
    assert "a.mcap: complete; 2 runs, 8 episodes" in out
    assert (
        "warning: " in out
        and "b.mcap: the file is truncated" in out
        and "b.mcap: INCOMPLETE" in out
    )


def test_the_file_is_self_describing_for_generic_protobuf_readers(tmp_path):
    """Decode with the schemas stored in the file (what Foxglove and mcap tools do), not our classes."""
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    written = write_synthetic(tmp_path / "a.mcap", runs=1, episodes_per_run=3)
    with open(tmp_path / "a.mcap", "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        decoded = {}
        for _, channel, _, msg in reader.iter_decoded_messages():
            decoded.setdefault(channel.topic, []).append(msg)
    eps = decoded["/episodes"]
    assert [type(m).DESCRIPTOR.full_name for m in eps[:1]] == ["fsrl.records.EpisodeBatch"]
    assert len(eps) == 1 and list(eps[0].episode) == [0, 1, 2]
    pairs = np.stack(
        [np.concatenate([f[k] for f in written]) for k in ("states", "actions", "flags")]
    )
    assert list(eps[0].steps.transitions[0::2]) == pairs[0].tolist()
    assert list(eps[0].steps.transitions[1::2]) == (pairs[1] * 32 + pairs[2]).tolist()
    assert list(eps[0].summary.return_) == [f["summary"]["return_"] for f in written]
    assert decoded["/pictures/5"][0].format == "png" and decoded["/pictures/5"][0].data == tiny_png(
        5
    )
    subs = [
        s for f in written for s in f["_substitutions"]
    ]  # format 5: in the batch of their episodes
    assert subs and list(eps[0].substitutions.picture) == [s["picture"] for s in subs]
    assert list(eps[0].substitutions.category) == [s["category"] for s in subs]


def test_a_file_of_an_older_record_format_is_refused_in_one_line():
    """tests/data/format4.mcap and format6.mcap were written by the writers of those formats: their
    episode batches have another schema record, so reading them is refused, naming the format, not
    misread; so is a schema record of another kind."""
    from pipeline.records import RecordsError
    from pipeline.records.codec import OUR_SCHEMA, FormatError, check_schema

    with pytest.raises(
        RecordsError,
        match=r"format4\.mcap: its episode batches use record format 4; this reader "
        r"reads format 7: re-run the trials that wrote it",
    ):
        read_records(Path(__file__).parent / "data" / "format4.mcap")
    with pytest.raises(
        RecordsError, match=r"format6\.mcap: .* record format 6; this reader reads format 7"
    ):
        read_records(Path(__file__).parent / "data" / "format6.mcap")  # the format before pairs
    check_schema(None, None)  # lost: this writer's is assumed
    check_schema(OUR_SCHEMA, S.LIBRARY)
    with pytest.raises(FormatError, match="use another record schema; this reader reads format 7"):
        check_schema(b"\x0a\x03abc", "someone else/1")


def test_record_level_episodes_keeps_everything_but_the_steps(tmp_path):
    """``steps=False`` (``record=episodes``): the same episodes, recognitions, unsafe-set additions and
    substitutions as a full recording, no step rows, the level in the metadata, and a smaller file."""
    import pandas as pd

    write_synthetic(tmp_path / "steps.mcap", runs=2, episodes_per_run=6)
    write_synthetic(tmp_path / "episodes.mcap", runs=2, episodes_per_run=6, steps=False)
    full, lean = read_records(tmp_path / "steps.mcap"), read_records(tmp_path / "episodes.mcap")
    assert (full.meta.record, lean.meta.record) == ("steps", "episodes") and lean.meta.complete
    assert (
        len(full.steps) > 0
        and lean.steps.empty
        and list(lean.steps.columns) == list(full.steps.columns)
    )
    for frame in ("episodes", "recognitions", "unsafe", "substitutions"):
        pd.testing.assert_frame_equal(
            getattr(lean, frame).drop(columns="file"), getattr(full, frame).drop(columns="file")
        )
    assert (tmp_path / "episodes.mcap").stat().st_size < (tmp_path / "steps.mcap").stat().st_size


@pytest.mark.parametrize(
    "rewards", [[0, -1, 1], [0, 63, -64], [0.5, -1, 0], [64, 0, 0], [-65, 0, 0], [0, np.nan, 1]]
)
def test_rewards_are_stored_in_one_byte_when_whole_and_small_and_read_back_exactly(
    tmp_path, rewards
):
    """Format 5: a batch whose rewards are whole numbers in -64..63 stores them as one-byte zigzag
    varints (small_rewards), any other batch as floats; both read back to the same float32 values, in a
    file that mixes the two, through the fast path and the Protobuf runtime, and encode byte for byte
    as the runtime does."""
    from pipeline.records import codec
    from pipeline.records.batch_check import check_batch
    from pipeline.records.scan import scan

    groups = [b for b, _ in batches(LAYOUT_5X5, batch_size=3, runs=1, episodes_per_run=6, seed=5)]
    odd = np.resize(np.asarray(rewards, np.float32), len(groups[1]["rewards"]))
    groups[1]["rewards"] = odd
    with RecordWriter(tmp_path / "r.mcap") as w:
        for b in groups:
            w.episodes(**b)
    data = [d for _, d in scan(tmp_path / "r.mcap").messages["/episodes"]]
    small = all(np.isfinite(odd)) and all(float(r).is_integer() and -64 <= r <= 63 for r in odd)
    for d, b in zip(data, groups):
        steps = S.EpisodeBatch.FromString(d).steps
        assert (len(steps.small_rewards), len(steps.rewards)) == (
            (len(b["rewards"]), 0) if b is not groups[1] or small else (0, len(b["rewards"]))
        )
        assert d == _encode_with_the_runtime(check_batch(b))
    want = np.concatenate([b["rewards"] for b in groups])
    np.testing.assert_array_equal(
        read_records(tmp_path / "r.mcap").steps["reward"].to_numpy(), want
    )
    slow = codec._columns(_runtime_flat(data), "r")
    np.testing.assert_array_equal(slow["steps"]["reward"], want)
    assert slow["steps"]["reward"].dtype == np.float32


def test_the_obstacles_metadata_is_the_json_of_each_runs_obstacles():
    """The writer puts the obstacles' JSON together as text: the text ``to_json`` gives of
    ``{run: [{key: int}]}`` (keys sorted as strings), for a list or a dict of runs, numpy ints."""
    from pipeline.records.config_text import to_json
    from pipeline.records.writer import OBSTACLE_KEYS, _obstacles_json

    rng = np.random.default_rng(0)

    def obstacle():
        return {k: np.int64(v) for k, v in zip(OBSTACLE_KEYS, rng.integers(-3, 200, 5))}

    as_list = [[obstacle() for _ in range(n)] for n in (0, 1, 3, 12)]
    as_dict = {np.int32(r): obs for r, obs in zip((12, 2, 0, 101), as_list)}
    for runs in (as_list, as_dict, [], {}):
        items = runs.items() if isinstance(runs, dict) else enumerate(runs)
        expected = {
            str(int(r)): [{k: int(o[k]) for k in OBSTACLE_KEYS} for o in obs] for r, obs in items
        }
        assert _obstacles_json(runs) == to_json(expected)
