"""docs/extending.md "Adding a safety method", walked in a copy of the package: a rule member and
its declaration in ``pipeline/rl/rules.py`` and its yaml in ``conf/method/`` are all it takes for
the trials to run it and for the report, the generalisation section included, to show its display
name (never another method's)."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pandas as pd
import pytest
from entry import package_copy

from pipeline.rl.methods import METHOD_DIR

ROOT = Path(__file__).resolve().parents[1]
DISPLAY = "Mine (test rule)"


def add_safety_member(rules: Path, line: str) -> None:
    """Append ``line`` to the body of ``class Safety`` (step 1 of the docs)."""
    text = rules.read_text().splitlines(keepends=True)
    start = next(i for i, t in enumerate(text) if t.startswith("class Safety("))
    end = next(
        i for i in range(start + 1, len(text)) if text[i].strip() and not text[i][0].isspace()
    )
    while not text[end - 1].strip():
        end -= 1
    text.insert(end, f"    {line}\n")
    rules.write_text("".join(text))


def declare(rules: Path, entry: str) -> None:
    """Append ``entry`` to the ``METHODS`` tuple (step 2)."""
    text = rules.read_text()
    head = re.search(r"^METHODS = \(\n(?:    .*\n)+?\)", text, flags=re.M)
    assert head, "METHODS = (...) not found in rules.py"
    block = head.group(0)
    rules.write_text(text.replace(block, block[:-1] + f"    {entry}\n)"))


SCRIPT = """
import json, sys
from pipeline.stages import run_stage

common = ["profile=smoke", "progress=false", "runs=2", "episodes=4", "record=episodes"]
run_stage("trials", ["+experiment=mine", *common])
run_stage("trials", ["+experiment=mine_layouts", *common])
run_stage("report", ["runs_dir=runs", "out=report", "allow_missing=true", "accuracy_dir=none"])
"""


@pytest.mark.slow  # a copy of the package run in a child process; fast: tests/test_declarations.py
def test_a_new_safety_method_needs_its_rule_its_declaration_and_its_yaml(tmp_path):
    copy = tmp_path / "repo"
    conf = package_copy(copy)
    rules = copy / "pipeline" / "rl" / "rules.py"
    # 1. the rule: a member of Safety (a collision adds (s, a), as every rule but none's)
    add_safety_member(rules, "mine = 9  #: a test rule: a collision adds (s, a)")
    # 2. its declaration beside it, and its yaml
    declare(rules, f'Method("mine", "{DISPLAY}", "#17becf"),')
    (copy / METHOD_DIR.relative_to(ROOT) / "mine.yaml").write_text(
        "name: mine\nsafety: mine\nrecovery: true\n"
    )
    # experiments that run it beside Q-learning: listed cells, and cells over generated layouts
    experiments = conf / "experiment"
    (experiments / "mine.yaml").write_text(
        textwrap.dedent(
            """\
            # @package _global_
            out: runs/mine
            experiment:
              name: mine
              cells: {mine: {method: mine}, qlearning: {method: qlearning}}
            """
        )
    )
    (experiments / "mine_layouts.yaml").write_text(
        textwrap.dedent(
            """\
            # @package _global_
            out: runs/mine_layouts
            experiment:
              name: mine_layouts
              layouts:
                sizes: [{size: 5x5, obstacles: 9, count: 2, seed: 0, unique: true}]
                cells: {mine: {method: mine}, qlearning: {method: qlearning}}
              report: {kind: generalisation}
            """
        )
    )
    env = {**os.environ, "PYTHONPATH": str(copy), "NUMBA_DISABLE_JIT": "1"}
    done = subprocess.run(
        [sys.executable, "-c", SCRIPT], cwd=copy, env=env, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr[-3000:]
    summary = json.loads((copy / "runs" / "mine" / "mine" / "summary.json").read_text())
    assert summary["method_spec"]["safety"] == "mine"
    tables = copy / "report" / "tables"
    rows = pd.read_csv(tables / "mine.csv")
    assert sorted(rows["cell"]) == sorted([DISPLAY, "Q-learning"])
    data = pd.read_csv(tables / "mine_layouts_data.csv")
    labels = dict(zip(data["method"], data["label"]))
    assert labels == {"mine": DISPLAY, "qlearning": "Q-learning"}
    features = pd.read_csv(tables / "mine_layouts_features.csv")
    assert set(features["method"]) == {DISPLAY, "Q-learning"}
    index = (copy / "report" / "index.md").read_text()
    assert DISPLAY in index
