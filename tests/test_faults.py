"""Fault suite: bad input and faults through the command line's entry (``pipeline.__main__.main``,
in this process; in a child process where a signal or a second process is the point). Every case
asserts the exit code, one line on stderr naming the thing and the problem, and that nothing
already on disk was lost (docs/reliability.md lists the guarantees)."""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from entry import cli
from fakes import FIG8_WITHOUT_MODELS

ROOT = Path(__file__).resolve().parents[1]
FAST = ["runs=2", "episodes=4", "progress=false"]


def one_line_error(out, *words, code=2):
    assert out.returncode == code, (out.returncode, out.stderr[-2000:])
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, out.stderr
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


def digest(folder: Path) -> dict:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


# ------------------------------------------------------------------ layouts
@pytest.mark.parametrize(
    "text,words",
    [
        ("", ["empty layout"]),
        ("S..\n..\n..G\n", ["ragged row"]),
        ("S.a\n...\n..G\n", ["unknown character 'a'"]),
        ("...\n...\n..G\n", ["no start"]),
        ("S.G\n...\n..G\n", ["2 goal cells"]),
        ("S.X\n.X.\nX.G\n", ["unreachable"]),
        ("S..\n\n..G\n", ["blank line"]),
    ],
)
def test_bad_layouts(tmp_path, text, words):
    layout = tmp_path / "maze.txt"
    layout.write_text(text)
    one_line_error(
        cli("trials", f"maze={layout}", f"out={tmp_path / 'o'}", *FAST),
        "config key 'maze'",
        str(layout),
        *words,
    )
    assert not (tmp_path / "o").exists()


def test_layout_folder_binary_and_oversized(tmp_path):
    one_line_error(
        cli("trials", f"maze={tmp_path}", f"out={tmp_path / 'o'}"), "a folder, not a layout file"
    )
    binary = tmp_path / "b.txt"
    binary.write_bytes(b"\x89PNG\r\n\x1a\n\xff\xfe")
    one_line_error(cli("trials", f"maze={binary}", f"out={tmp_path / 'o'}"), "not a text file")
    huge = tmp_path / "huge.txt"
    huge.write_text(("." * 2999 + "\n") * 1500)
    one_line_error(cli("trials", f"maze={huge}", f"out={tmp_path / 'o'}"), "layouts up to")


@pytest.mark.parametrize("text", ["SG\n", "S..\n...\n..G\n", "S\nG\n"])
@pytest.mark.parametrize("method", ["ssrl", "fewshot_dss", "sarsa", "constrained"])
def test_unusual_valid_layouts_run(tmp_path, text, method):
    layout = tmp_path / "tiny.txt"
    layout.write_text(text)
    out = cli(
        "trials",
        f"maze={layout}",
        f"method={method}",
        f"out={tmp_path / 'o'}",
        *FAST,
        *(["recogniser=oracle"] if method == "fewshot_dss" else []),
    )
    assert out.returncode == 0, out.stderr
    assert json.loads((tmp_path / "o" / "summary.json").read_text())["n_runs"] == 2


def test_a_1000x1000_layout_is_parsed_and_checked_in_seconds(tmp_path):
    import numpy as np

    from pipeline.world.geometry import build_geometry
    from pipeline.world.maze import load_layout

    grid = np.full((1000, 1000), ".")
    rng = np.random.default_rng(0)
    grid[rng.integers(1000, size=40000), rng.integers(1000, size=40000)] = "X"
    grid[0, 0], grid[-1, -1] = "S", "G"
    grid[0, 1:] = grid[:, -1] = "."
    grid[-1, -1] = "G"
    path = tmp_path / "big.txt"
    path.write_text("\n".join("".join(r) for r in grid) + "\n")
    load_layout(path)  # numba's first compile is not what we time
    t0 = time.perf_counter()
    layout = load_layout(path)
    build_geometry(layout)
    assert time.perf_counter() - t0 < 5.0
    assert layout.n_cells == 1_000_000


# ------------------------------------------------------------------ configs and out folders
@pytest.mark.parametrize(
    "args,words",
    [
        (["runs=2.7"], ["config key 'runs'", "Integer"]),
        (["episodes=abc"], ["config key 'episodes'"]),
        (["record=maybe"], ["config key 'record'"]),
        (["threads=-1"], ["config key 'threads'", ">= 0"]),
        (["threads=999"], ["config key 'threads'", "at most"]),
        (["out="], ["config key 'out'", "empty"]),
        (["bogus=1"], ["config key 'bogus'"]),
        (["method=nope"], ["method/nope"]),
        (["runs=100", "episodes=100000000000000"], ["need about", "GiB", "available"]),
        (["out=/proc/version/x"], ["config key 'out'"]),
    ],
)
def test_bad_trial_configs(tmp_path, args, words):
    one_line_error(cli("trials", *args, "progress=false"), *words)


def test_record_none_means_no_records(tmp_path):
    assert cli("trials", "record=none", f"out={tmp_path}", *FAST).returncode == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["summary.json"]


def test_out_that_is_a_file_is_refused_and_kept(tmp_path):
    target = tmp_path / "results"
    target.write_text("mine")
    one_line_error(cli("trials", f"out={target}", *FAST), "config key 'out'", "is a file")
    assert target.read_text() == "mine"


def test_every_stage_turns_a_bad_config_into_one_line(tmp_path):
    one_line_error(cli("render", "size=abc"), "config key 'size'")
    one_line_error(cli("meta_train", "train.lr=-1"), "config key 'train.lr'")
    one_line_error(cli("accuracy", "study.repeats=0"), "config key 'study.repeats'")
    one_line_error(cli("report", "out="), "config key 'out'")
    one_line_error(
        cli("replay", f"file={tmp_path / 'none.mcap'}"), "config key 'file'", "no such record file"
    )


# ------------------------------------------------------------------ checkpoints and image folders
@pytest.fixture(scope="module")
def tiny_model(tmp_path_factory):
    from pipeline.fewshot.synthetic import write_synthetic_dataset
    from pipeline.stages._common import run_stage

    d = tmp_path_factory.mktemp("model")
    write_synthetic_dataset(d / "images", n_train=6, n_val=5, per_class=8, seed=1)
    run_stage(
        "meta_train",
        [
            f"images_dir={d / 'images'}",
            f"checkpoint={d}/rn.pt",
            f"metrics_file={d}/metrics.json",
            f"history_file={d}/h.csv",
            "train.input_size=24",
            "train.relation_padding=1",
            "train.episodes=4",
            "train.val_every=2",
            "train.val_episodes=2",
            "train.eval_episodes=4",
            "train.n_query=2",
            "train.eval_queries=2",
            "progress=false",
        ],
    )
    return d


def _with_model(d, *extra):
    return [
        "method=fewshot",
        f"recogniser.images_dir={d / 'images'}",
        "recogniser.input_size=24",
        "recogniser.relation_padding=1",
        *FAST,
        *extra,
    ]


def test_a_small_model_runs_and_is_named_in_the_records(tiny_model, tmp_path):
    from pipeline.fewshot.checkpoint import file_sha256
    from pipeline.records import read_records

    out = cli(
        "trials",
        *_with_model(tiny_model, f"recogniser.checkpoint={tiny_model}/rn.pt", f"out={tmp_path}"),
    )
    assert out.returncode == 0, out.stderr
    info = read_records(tmp_path / "records.mcap", pictures=False).meta.info["info"]["recogniser"]
    assert info["checkpoint"]["sha256"] == file_sha256(tiny_model / "rn.pt")
    assert info["checkpoint"]["model"] == {"input_size": 24, "relation_padding": 1}


@pytest.mark.parametrize(
    "make,words",
    [
        (lambda p, good: p.write_bytes(b""), ["corrupt or not a torch checkpoint"]),
        (
            lambda p, good: p.write_bytes(good.read_bytes()[: len(good.read_bytes()) // 2]),
            ["corrupt"],
        ),
        (lambda p, good: p.write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 100), ["corrupt"]),
        (lambda p, good: None, ["does not exist"]),
    ],
)
def test_bad_checkpoints(tiny_model, tmp_path, make, words):
    bad = tmp_path / "bad.pt"
    make(bad, tiny_model / "rn.pt")
    one_line_error(
        cli(
            "trials",
            *_with_model(tiny_model, f"recogniser.checkpoint={bad}", f"out={tmp_path / 'o'}"),
        ),
        "config key 'recogniser'",
        str(bad),
        *words,
    )
    assert not (tmp_path / "o").exists()


def test_a_bad_checkpoint_stops_workers_before_any_folder(tiny_model, tmp_path):
    """With workers, each recogniser is built in a worker first: the same one line, no ``out``."""
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"")
    args = [a for a in _with_model(tiny_model, f"recogniser.checkpoint={bad}") if "method" not in a]
    out = tmp_path / "o"
    one_line_error(
        cli("trials", "+experiment=fig9", "workers=2", f"out={out}", *args),
        "config key 'recogniser'",
        str(bad),
        "corrupt or not a torch checkpoint",
    )
    assert not out.exists()


def test_a_checkpoint_of_another_shape_is_refused(tiny_model, tmp_path):
    args = _with_model(tiny_model, f"recogniser.checkpoint={tiny_model}/rn.pt", f"out={tmp_path}")
    args = [a for a in args if not a.startswith("recogniser.input_size")]  # the config expects 48
    one_line_error(
        cli("trials", *args), "config key 'recogniser'", "was trained for", "input_size=24"
    )


def test_an_images_folder_without_a_manifest(tiny_model, tmp_path):
    one_line_error(
        cli(
            "trials",
            "method=fewshot",
            f"recogniser.images_dir={tmp_path}",
            f"recogniser.checkpoint={tiny_model}/rn.pt",
            "recogniser.input_size=24",
            "recogniser.relation_padding=1",
            f"out={tmp_path / 'o'}",
            *FAST,
        ),
        "no picture manifest",
    )


# ------------------------------------------------------------------ concurrent writers and kills
LONG = [
    "method=ssrl",
    "maze=11x11",
    "runs=100",
    "episodes=200000",
    "progress=false",
    "flush_every=1000",
]


def _start(*args):
    return subprocess.Popen(
        [sys.executable, "-m", "pipeline", "trials", *args],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _wait_for_partial(out: Path, timeout=60.0):
    t0 = time.time()
    while time.time() - t0 < timeout:
        if list(out.glob(".staging-*/records.mcap.partial")):
            time.sleep(1.0)
            return
        time.sleep(0.1)
    raise AssertionError("the trial did not start writing")


def test_a_second_writer_fails_at_once_and_the_first_is_untouched(tmp_path):
    from pipeline.records import read_records

    first = _start(*LONG, f"out={tmp_path}")
    _wait_for_partial(tmp_path)
    second = cli("trials", "method=ssrl", "seed=1", f"out={tmp_path}", *FAST)
    one_line_error(second, "config key 'out'", "being written by another process")
    assert first.poll() is None  # still running, not disturbed
    first.send_signal(signal.SIGTERM)
    _, err = first.communicate(timeout=60)
    assert first.returncode == 143
    partial = Path(err.strip().split(" at ")[1].split(":")[0])
    recs = read_records(partial, pictures=False)
    assert recs.meta.config["seed"] == 0 and len(recs.episodes) > 0
    assert not (tmp_path / "summary.json").exists()  # no summary of the second writer beside them


@pytest.mark.parametrize("sig,code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_killed_trial_says_what_it_kept_and_loses_nothing(tmp_path, sig, code):
    assert cli("trials", "method=ssrl", f"out={tmp_path}", *FAST).returncode == 0
    before = digest(tmp_path)
    proc = _start(*LONG, f"out={tmp_path}", "overwrite=true")
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


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_workers_end_when_their_stage_is_killed(tmp_path):
    """``kill -9`` of a ``workers=2`` stage: its worker processes (and the resource tracker they
    kept alive) end within seconds instead of running on as orphans."""
    stage = _start(
        "+experiment=fig9", "recogniser=oracle", "workers=2", "runs=100", "episodes=4000",
        "progress=false", f"out={tmp_path}",
    )  # fmt: skip
    children: list[int] = []
    try:
        t0 = time.time()
        while time.time() - t0 < 60 and len(children) < 3:  # two workers and the resource tracker
            children = _children(stage.pid)
            time.sleep(0.2)
        assert len(children) >= 2, children
        time.sleep(2.0)  # the workers are running cells
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
    stage = _start(
        "+experiment=fig9", "recogniser=oracle", "workers=2", "runs=100", "episodes=20000",
        "progress=false", f"out={tmp_path}",
    )  # fmt: skip
    try:
        t0 = time.time()
        while time.time() - t0 < 60 and len(_children(stage.pid)) < 3:
            time.sleep(0.2)
        time.sleep(2.0)
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
    proc = _start(
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


# ------------------------------------------------------------------ the report
@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """fig8 and fig9 recorded at a tiny scale, and a report built from them."""
    d = tmp_path_factory.mktemp("report")
    for exp in ("fig8", "fig9"):
        out = cli(
            "trials",
            f"+experiment={exp}",
            "recogniser=oracle",
            f"out={d}/runs/{exp}",
            *FAST,
            *(FIG8_WITHOUT_MODELS if exp == "fig8" else []),
        )
        assert out.returncode == 0, out.stderr
    out = cli(
        "report",
        f"runs_dir={d}/runs",
        f"accuracy_dir={d}/none",
        f"out={d}/reports",
        "allow_missing=true",
    )
    assert out.returncode == 0, out.stderr
    return d


def _report(d, runs, *extra):
    return cli("report", f"runs_dir={runs}", f"accuracy_dir={d}/none", f"out={d}/reports", *extra)


def test_report_refuses_missing_experiments_and_keeps_the_old_one(recorded):
    before = digest(recorded / "reports")
    one_line_error(
        _report(recorded, recorded / "runs"),
        "no complete records for experiment",
        "experiment fig10",
        "allow_missing=true",
    )
    assert digest(recorded / "reports") == before


@pytest.mark.parametrize("runs", ["absent", "empty"])
def test_report_with_no_records_changes_nothing(recorded, runs):
    (recorded / "empty").mkdir(exist_ok=True)
    before = digest(recorded / "reports")
    one_line_error(_report(recorded, recorded / runs, "allow_missing=true"), "nothing to report")
    assert digest(recorded / "reports") == before


@pytest.mark.parametrize("damage", ["truncate", "partial_only", "garbage"])
def test_report_refuses_damaged_records_and_keeps_the_old_one(recorded, tmp_path, damage):
    import shutil

    runs = tmp_path / "runs"
    shutil.copytree(recorded / "runs", runs)
    target = runs / "fig8" / "ssrl" / "records.mcap"
    if damage == "truncate":
        target.write_bytes(target.read_bytes()[: target.stat().st_size // 2])
    elif damage == "partial_only":
        target.rename(target.with_name("records.mcap.partial"))
    else:
        target.write_bytes(b"not an mcap file at all")
    before = digest(recorded / "reports")
    out = _report(recorded, runs)
    words = ["ssrl"] if damage == "partial_only" else ["fig8/ssrl/records.mcap"]
    one_line_error(out, *words)
    assert digest(recorded / "reports") == before


def test_report_refuses_cells_of_different_setups(recorded, tmp_path):
    import shutil

    runs = tmp_path / "runs"
    shutil.copytree(recorded / "runs", runs)
    other = tmp_path / "other"
    assert (
        cli(
            "trials",
            "+experiment=fig8",
            "recogniser=oracle",
            "seed=7",
            f"out={other}",
            *FAST,
            *FIG8_WITHOUT_MODELS,
        ).returncode
        == 0
    )
    shutil.rmtree(runs / "fig8" / "shield")
    shutil.copytree(other / "shield", runs / "fig8" / "shield")
    before = digest(recorded / "reports")
    one_line_error(_report(recorded, runs, "allow_missing=true"), "fig8/shield", "seed=7")
    assert digest(recorded / "reports") == before
