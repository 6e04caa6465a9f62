"""The trials command end to end, composed from the real configs (lightning-hydra-template style)."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from pipeline.errors import ConfigError
from pipeline.stages import run_stage

ROOT = Path(__file__).resolve().parents[1]


def trials(*overrides):
    return run_stage("trials", list(overrides))


def test_trials_writes_summary(tmp_path):
    summary = trials(
        "method=shield",
        "maze=7x7",
        "runs=3",
        "episodes=40",
        "seed=5",
        "record=none",
        f"out={tmp_path}",
        "progress=false",
    )
    on_disk = json.loads((tmp_path / "summary.json").read_text())
    assert on_disk["runs"] == summary["runs"] and len(on_disk["runs"]) == 3
    assert on_disk["method"] == "shield" and on_disk["maze"] == "7x7"
    for key in ("collisions", "steps", "converged_episode"):
        assert {"mean", "std"} <= set(on_disk[key])


def test_method_fields_can_be_overridden(tmp_path):
    summary = trials(
        "method=qlearning",
        "method.epsilon=0.5",
        "runs=2",
        "episodes=5",
        "record=none",
        f"out={tmp_path}",
        "progress=false",
    )
    assert summary["method_spec"]["epsilon"] == 0.5


@pytest.mark.parametrize(
    "override,message",
    [
        ("episodes=-3", "config key 'episodes'"),
        ("runs=0", "config key 'runs'"),
        ("maze=does/not/exist.txt", "config key 'maze'"),
        ("method.alpha=2", "config key 'method.alpha'"),
        (
            "method=fewshot recogniser.checkpoint=/nonexistent.pt",
            "config key 'recogniser'.*nonexistent.pt",
        ),
        (
            "+experiment=fig8 recogniser.checkpoint=/nonexistent.pt",
            "config key 'recogniser'.*nonexistent.pt",
        ),
        ("substitution=7", "config key 'substitution'"),
    ],
)
def test_broken_configs_fail_naming_the_key(tmp_path, override, message):
    with pytest.raises(ConfigError, match=message):
        trials(*override.split(), f"out={tmp_path}", "progress=false")
    assert not list(tmp_path.iterdir())  # refused before anything was written


def test_command_line(tmp_path):
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "pipeline",
            "trials",
            "method=ssrl",
            "maze=5x5",
            "runs=2",
            "episodes=10",
            f"out={tmp_path}",
            "progress=false",
            "record=none",
        ],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert out.returncode == 0, out.stderr
    assert json.loads((tmp_path / "summary.json").read_text())["n_runs"] == 2
    bad = subprocess.run(
        [sys.executable, "-m", "pipeline", "trials", "method=nope"],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert (
        bad.returncode == 2
        and "method/nope" in bad.stderr
        and len(bad.stderr.strip().splitlines()) == 1
    )
    unknown = subprocess.run(
        [sys.executable, "-m", "pipeline", "nostage"], capture_output=True, text=True, cwd=ROOT
    )
    assert unknown.returncode == 2 and "unknown stage 'nostage'" in unknown.stderr


@pytest.mark.parametrize("level", ["steps", "episodes", "none"])
def test_record_levels(tmp_path, level):
    """``record=steps|episodes|none``: the same trial, every step, every episode without its steps, or no
    record file; the summary is the same whatever is recorded, and the file names its level."""
    from pipeline.records import read_records

    summary = trials(
        "method=fewshot_dss",
        "recogniser=fixed_accuracy",
        "maze=5x5",
        "runs=2",
        "episodes=30",
        f"record={level}",
        f"out={tmp_path}",
        "progress=false",
    )
    path = tmp_path / "records.mcap"
    assert path.exists() == (level != "none")
    if level != "none":
        recs = read_records(path)
        assert (
            recs.meta.record == level and recs.meta.config["record"] == level and recs.meta.complete
        )
        assert len(recs.episodes) == 60 and int(recs.episodes.collisions.sum()) == sum(
            r["collisions"] for r in summary["runs"]
        )
        assert recs.steps.empty == (level == "episodes") and not recs.substitutions.empty
        assert len(recs.steps) in (0, int(recs.episodes.steps.sum()))


def test_a_stage_without_a_bar_says_how_long_is_left():
    """Under ``dvc repro`` (``progress=false``) a study prints a line every tenth of its cells: how
    far it is, and the time left at the pace so far."""
    from pipeline.cells.progress import progress_line

    assert progress_line(210, 2100, 7.0) == "210/2100 cells (7 s, about 63 s left)"
    assert progress_line(2100, 2100, 70.4) == "2100/2100 cells (70 s)"
