"""The report's headline (reports/headline.json): the few numbers DVC declares as metrics."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import yaml

from pipeline.report.headline import headline
from pipeline.report.spec import ReportSpec

ROOT = Path(__file__).resolve().parents[1]


def _cell(collisions: list[int]):
    return SimpleNamespace(collisions_per_run=lambda: np.array(collisions))


def _experiment(folder: str, headline_cells: list[str], cells: dict):
    return SimpleNamespace(folder=folder, spec=ReportSpec(headline=headline_cells), cells=cells)


def _claims(*verdicts: str):
    return [SimpleNamespace(verdict=v) for v in verdicts]


def test_headline_holds_accuracies_claims_held_and_the_named_cells_in_order(tmp_path):
    (tmp_path / "rn.json").write_text(json.dumps({"accuracy": 0.7035555, "ci_lower": 0.69}))
    experiments = [
        _experiment("fig8", ["ssrl", "shield"], {"shield": _cell([13, 13]), "ssrl": _cell([6, 9])}),
        _experiment("table3", [], {"sarsa_5x5": _cell([200])}),
    ]
    claims = {
        "relation_net": _claims("holds", "does not hold", "holds"),
        "paper_tables": _claims("not checked"),
    }
    models = {"relation_net": tmp_path / "rn.json", "protonet": tmp_path / "missing.json"}
    got = headline(claims, models, experiments)
    assert got == {
        "accuracy": {"relation_net": 0.70356},
        "claims_held": 2,  # with the main recogniser, the first
        "fig8": {"ssrl": 7.5, "shield": 13.0},
    }
    assert list(got["fig8"]) == ["ssrl", "shield"]  # the declared order: DVC's columns


def test_a_named_cell_without_records_is_left_out_and_an_experiment_cannot_hide_a_headline_key():
    experiments = [_experiment("accuracy", ["a", "b"], {"a": _cell([1, 2])})]
    assert headline({}, {}, experiments) == {"experiment_accuracy": {"a": 1.5}}


def test_a_headline_cell_the_experiment_lacks_is_refused_by_name():
    spec = ReportSpec(headline=["shield", "nope"])
    assert spec.problems(["shield", "ssrl"]) == [
        ("headline", "no cell 'nope' in the experiment (cells: shield, ssrl)")
    ]


def test_the_declared_metrics_are_the_headline_alone():
    """`dvc exp show` prints a column per declared metric key: one small file keeps it to a
    screen; per-cell and per-model files are outs that `dvc metrics show <path>` still reads."""
    stages = yaml.safe_load((ROOT / "dvc.yaml").read_text())["stages"]
    declared = [
        next(iter(m)) if isinstance(m, dict) else m
        for s in stages.values()
        for m in s.get("do", s).get("metrics", [])
    ]
    assert declared == ["reports/headline.json"]
    assert "report" in [n for n, s in stages.items() if s.get("metrics")]


@pytest.mark.parametrize(
    "path", ["datasets/models/metrics.json", "datasets/metrics/fig8/ssrl.json"]
)
def test_committed_intervals_read_lower_then_upper_in_dvc_order(path):
    """DVC sorts a file's keys: ``ci_lower`` before ``ci_upper`` (``ci_low``/``ci_high`` did not)."""
    keys = sorted(json.loads((ROOT / path).read_text()))
    assert keys.index("ci_lower") + 1 == keys.index("ci_upper")
