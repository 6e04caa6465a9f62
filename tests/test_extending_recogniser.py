"""docs/extending.md "Adding a recogniser" and "Adding an experiment", walked in a copy of the
package: a recogniser is its class and its ``conf/recogniser/<name>.yaml`` (no list, no class tree
to join), an experiment its ``conf/experiment/<name>.yaml``; the trials run them and the report
names each recogniser's rows by its declared ``display_name``, never another recogniser's name."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pandas as pd
import pytest
from entry import package_copy

from pipeline.rl.methods import declaration, get_method

TOY = '''\
from pipeline.rl.fixed_accuracy import FixedAccuracyRecogniser


class ToyRecogniser(FixedAccuracyRecogniser):
    """A fixed-accuracy recogniser under a name of its own."""

    kind = "toy"
    display_name = "Toy Net"
    colour = "#2a9d8f"

    def describe(self) -> dict:
        return {"kind": self.kind}
'''

EXPERIMENT = """\
# @package _global_
defaults:
  - override /recogniser: fixed_accuracy
out: runs/toy
experiment:
  name: toy
  cells:
    fixed: {method: fewshot}
    toy: {method: fewshot, recogniser_group: toy}
    shield: {method: shield}
"""

SCRIPT = """
from pipeline.stages import run_stage

run_stage("trials", ["+experiment=toy", "profile=smoke", "progress=false", "runs=2", "episodes=4"])
run_stage("report", ["runs_dir=runs", "out=report", "allow_missing=true", "accuracy_dir=none"])
"""


@pytest.mark.slow  # a copy of the package run in a child process
def test_a_new_recogniser_is_two_files_and_a_new_experiment_one(tmp_path):
    copy = tmp_path / "repo"
    conf = package_copy(copy)
    # the recogniser: its module and its yaml
    (copy / "pipeline" / "rl" / "toy.py").write_text(TOY)
    (conf / "recogniser" / "toy.yaml").write_text(
        "_target_: pipeline.rl.toy.ToyRecogniser\np: 0.9\n"
    )
    # the experiment: one file
    (conf / "experiment" / "toy.yaml").write_text(textwrap.dedent(EXPERIMENT))
    env = {**os.environ, "PYTHONPATH": str(copy), "NUMBA_DISABLE_JIT": "1"}
    done = subprocess.run(
        [sys.executable, "-c", SCRIPT], cwd=copy, env=env, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr[-3000:]
    rows = pd.read_csv(copy / "report" / "tables" / "toy.csv")
    fewshot = declaration(get_method("fewshot").as_dict()).display
    assert sorted(rows["cell"]) == [
        f"{fewshot}, Toy Net recogniser",
        f"{fewshot}, fixed accuracy recogniser",
        declaration(get_method("shield").as_dict()).display,
    ]
    assert "Toy Net" in (copy / "report" / "index.md").read_text()
