"""The silence and traceback cases of issue 31, each now one line (exit 2) or a note: a layout count
that would plan millions of cells, an empty ``cells={}`` that Hydra would merge away, a missing
metrics file in the report, a decompression bomb, a symbolic link loop and a class folder linked to
its tree's parent in a ``data=folder`` tree, ``render_mode="human"`` without pygame, and SIGTERM
while numba compiles its first kernel (docs/reliability.md)."""

from __future__ import annotations

import importlib.util
import os
import struct
import subprocess
import sys
import time
import zlib
from pathlib import Path

import gymnasium
import pytest
from entry import cli
from test_faults import one_line_error
from test_fewshot_folder import SHRINK, make_tree, outputs

import pipeline  # noqa: F401  (registers the Gymnasium environments)
from pipeline.fewshot.data import DataError, load_folder
from pipeline.report.accuracy import recogniser_row

ROOT = Path(__file__).resolve().parents[1]


def test_a_layout_count_that_would_plan_millions_of_cells_is_refused_at_once(tmp_path):
    start = time.perf_counter()
    one_line_error(
        cli(
            "trials",
            "+experiment=generalisation",
            "experiment.layouts.sizes.0.count=1000000",
            f"out={tmp_path}",
        ),
        "config key 'experiment.layouts.sizes.0.count': 1,000,000 layouts give 7,001,400 cells",
        "at most 100,000",
        "GB",
    )
    assert time.perf_counter() - start < 5


def test_an_empty_mapping_merged_away_is_refused_not_ignored(tmp_path):
    one_line_error(
        cli(
            "trials", "+experiment=generalisation", "experiment.layouts.cells={}", f"out={tmp_path}"
        ),
        "config key 'experiment.layouts.cells': {} does not empty it",
    )
    assert not any(tmp_path.iterdir())


def test_the_report_names_a_missing_metrics_file_in_its_cell(tmp_path):
    row = recogniser_row("Relation Network", tmp_path / "metrics.json", tmp_path / "study")
    assert row["test [95%]"] == f"no metrics file `{tmp_path / 'metrics.json'}`"
    assert row["query pictures [95%]"] == f"no study `{tmp_path / 'study' / 'summary.json'}`"


def _png_header_only(path: Path, side: int) -> None:
    """A PNG that declares ``side`` x ``side`` pixels (PIL's bomb check reads the header)."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (
            struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
        )

    ihdr = struct.pack(">IIBBBBB", side, side, 8, 2, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IEND", b""))


@pytest.mark.parametrize("side", [20000, 10000])  # over PIL's error and its warning limits
def test_a_decompression_bomb_in_a_folder_tree_is_one_line(tmp_path, side):
    root = make_tree(tmp_path / "tree", ["a", "b"], per_class=2)
    _png_header_only(root / "a" / "huge.png", side)
    with pytest.raises(DataError, match=r"huge.png: too large, Image size \("):
        load_folder(root, 24)


def _meta_train(tmp_path, train, val):
    test = make_tree(tmp_path / "test", ["x0", "x1"], per_class=2)
    return cli(
        "meta_train",
        "data=folder",
        f"data.train_dir={train}",
        f"data.val_dir={val}",
        f"data.test_dir={test}",
        "progress=false",
        *outputs(tmp_path / "m"),
        *SHRINK,
    )


def test_a_symbolic_link_loop_as_the_training_folder_is_one_line(tmp_path):
    loop = tmp_path / "loop"
    loop.symlink_to(loop)
    val = make_tree(tmp_path / "val", ["v0", "v1"], per_class=2)
    one_line_error(
        _meta_train(tmp_path, loop, val), "config key 'data.train_dir'", "symbolic link loop"
    )


@pytest.mark.parametrize("target", ["..", "self"])
def test_a_class_folder_linked_to_its_parent_or_itself_is_one_line(tmp_path, target):
    train = make_tree(tmp_path / "train", ["t0", "t1"], per_class=2)
    (train / "link").symlink_to(target)
    val = make_tree(tmp_path / "val", ["v0", "v1"], per_class=2)
    words = ["which holds this tree"] if target == ".." else ["leads nowhere or to itself"]
    one_line_error(_meta_train(tmp_path, train, val), f"{train / 'link'}:", *words)


@pytest.mark.skipif(
    importlib.util.find_spec("pygame") is not None, reason="pygame is installed: human works"
)
def test_render_mode_human_without_pygame_is_refused_at_make():
    with pytest.raises(ValueError, match="render_mode='human' opens a window through pygame"):
        gymnasium.make("SafeNav-5x5-v0", method="shield", render_mode="human")


def test_sigterm_while_numba_compiles_stops_at_once_in_one_line(tmp_path):
    """A child process (the signal is the point) compiles a fresh numba function (no cache) under
    the stages' signal handling and sends itself SIGTERM in the middle of it."""
    script = """
import os, signal, threading, numba, numpy as np
from pipeline.stages._common import user_facing
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


def test_a_bad_value_in_a_config_file_names_its_key():
    """What Hydra raises when a file holds a value of the wrong type (``dvc exp run -S
    pipeline/conf/profile/paper.yaml:trials.episodes=abc`` writes one): the key is in its text."""
    from hydra.errors import ConfigCompositionException

    from pipeline.stages._common import one_line

    exc = ConfigCompositionException(
        "In 'profile/paper': ValidationError raised while composing config:\n"
        "Value 'abc' of type 'str' could not be converted to Integer\n"
        "    full_key: profile.trials.episodes\n    reference_type=TrialsProfile"
    )
    assert one_line(exc) == (
        "config key 'profile.trials.episodes': In 'profile/paper': ValidationError raised while "
        "composing config: Value 'abc' of type 'str' could not be converted to Integer"
    )
