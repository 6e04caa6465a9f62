"""The trials command end to end, composed from the real configs (lightning-hydra-template style)."""
import json
import subprocess
import sys
from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir

from pipeline.stages import trials
from pipeline.stages._common import CONF_DIR, ConfigError

ROOT = Path(__file__).resolve().parents[1]


def cfg(*overrides):
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        return compose(config_name="trials", overrides=list(overrides))


def test_trials_writes_summary(tmp_path):
    summary = trials.run(cfg("method=shield", "maze=7x7", "runs=3", "episodes=40", "seed=5", "record=false",
                             f"out={tmp_path}", "progress=false"))
    on_disk = json.loads((tmp_path / "summary.json").read_text())
    assert on_disk["runs"] == summary["runs"] and len(on_disk["runs"]) == 3
    assert on_disk["method"] == "shield" and on_disk["maze"] == "7x7"
    for key in ("collisions", "steps", "converged_episode"):
        assert {"mean", "std"} <= set(on_disk[key])


def test_method_fields_can_be_overridden(tmp_path):
    summary = trials.run(cfg("method=qlearning", "method.epsilon=0.5", "runs=2", "episodes=5",
                             "record=false", f"out={tmp_path}", "progress=false"))
    assert summary["method_spec"]["epsilon"] == 0.5


@pytest.mark.parametrize("override,message", [
    ("episodes=-3", "config key 'episodes'"),
    ("runs=0", "config key 'runs'"),
    ("maze=does/not/exist.txt", "config key 'maze'"),
    ("method.alpha=2", "config key 'method'"),
    ("method=fewshot", "config key 'recogniser.checkpoint'"),
    ("+experiment=fig8", "config key 'recogniser.checkpoint'"),
    ("substitution=7", "config key 'substitution'"),
])
def test_broken_configs_fail_naming_the_key(tmp_path, override, message):
    with pytest.raises(ConfigError, match=message):
        trials.run(cfg(override, f"out={tmp_path}", "progress=false", "recogniser.checkpoint=/nonexistent.pt"))
    assert not (tmp_path / "summary.json").exists()


def test_command_line(tmp_path):
    out = subprocess.run([sys.executable, "-m", "pipeline", "trials", "method=ssrl", "maze=5x5", "runs=2",
                          "episodes=10", f"out={tmp_path}", "progress=false", "record=false"],
                         capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    assert json.loads((tmp_path / "summary.json").read_text())["n_runs"] == 2
    bad = subprocess.run([sys.executable, "-m", "pipeline", "trials", "method=nope"],
                         capture_output=True, text=True, cwd=ROOT)
    assert bad.returncode != 0 and "method/nope" in bad.stderr
    unknown = subprocess.run([sys.executable, "-m", "pipeline", "nostage"], capture_output=True, text=True, cwd=ROOT)
    assert unknown.returncode == 2 and "unknown stage 'nostage'" in unknown.stderr
