"""The ``accuracy_curve`` experiment and its report section: collisions against the accuracy p of
the fixed-accuracy recogniser, SSRL and the shield as references, the Relation Network's measured
accuracy marked, break-even accuracies with bootstrap intervals. Smoke scale (3 runs x 20 episodes)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from pipeline.records import read_records
from pipeline.report.accuracy_curve import split
from pipeline.report.experiments import load_experiment
from pipeline.report.spec import Group, ReportSpec
from pipeline.stages import run_stage
from pipeline.stats import break_even

LEVELS = [0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0]
MAZES = ["5x5", "7x7", "11x11"]


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    d = tmp_path_factory.mktemp("accuracy_curve")
    run_stage(
        "trials",
        [
            "+experiment=accuracy_curve",
            "profile=smoke",
            "progress=false",
            f"out={d}/runs/accuracy_curve",
        ],
    )
    # an accuracy study of its own (a recogniser of known accuracy stands in for the model)
    run_stage(
        "accuracy",
        [
            "recogniser=fixed_accuracy",
            "recogniser.p=0.7",
            "study.repeats=3",
            f"out_dir={d}/accuracy",
            "profile=smoke",
            "progress=false",
        ],
    )
    run_stage(
        "report",
        [
            f"runs_dir={d}/runs",
            f"accuracy_dir={d}/accuracy",
            f"out={d}/reports",
            "allow_missing=true",
        ],
    )
    return d, (d / "reports" / "index.md").read_text()


def summary_means(d) -> dict[str, float]:
    """Mean collisions per run of every cell, from the trials' own summaries (not the records)."""
    cells = json.loads((d / "runs" / "accuracy_curve" / "summary.json").read_text())["cells"]
    return {name: cell["collisions"]["mean"] for name, cell in cells.items()}


def expected_break_even(means: dict[str, float], method: str, maze: str, reference: str) -> str:
    ref = means[f"{reference}_{maze}"]
    below = [p for p in LEVELS if means[f"{method}_{maze}_p{round(p * 100)}"] <= ref]
    if not below:
        return "not reached"
    return f"≤ {below[0]:g}" if below[0] == LEVELS[0] else f"{below[0]:g}"


def level(text: str) -> float:
    """A printed break-even level as a number (``≤ 0.2`` -> 0.2, ``not reached`` -> inf)."""
    return np.inf if text == "not reached" else float(text.removeprefix("≤ "))


def test_each_cell_ran_and_recorded_its_accuracy(built):
    d, _ = built
    for name, p in (
        ("fewshot_5x5_p20", 0.2),
        ("fewshot_dss_11x11_p70", 0.7),
        ("fewshot_7x7_p100", 1.0),
    ):
        meta = read_records(
            d / "runs" / "accuracy_curve" / name / "records.mcap", pictures=False
        ).meta
        assert meta.config["recogniser"]["p"] == p
        assert meta.config["recogniser"]["_target_"].endswith("FixedAccuracyRecogniser")
    means = summary_means(d)
    assert all(
        means[f"{m}_{z}_p100"] == 0 for m in ("fewshot", "fewshot_dss") for z in MAZES
    )  # always right


def test_the_section_plots_the_curves_and_marks_the_relation_network(built):
    d, index = built
    assert "## Beyond the paper: collisions against recognition accuracy (three mazes)" in index
    baseline = json.loads((d / "accuracy" / "summary.json").read_text())["baseline"]
    correct, total = sum(baseline["correct"]), sum(baseline["total"])
    assert (
        f"({correct}/{total} = {100 * correct / total:.1f}%;" in index
    )  # read from the study, not a constant
    assert correct != 22  # not the committed study's 22/40
    assert (d / "reports" / "figures" / "accuracy_curve.png").stat().st_size > 10_000
    data = pd.read_csv(d / "reports" / "tables" / "accuracy_curve_data.csv")
    curves = data[data["p"].notna()]
    assert sorted(curves["p"].unique().round(2).tolist()) == LEVELS
    assert curves.groupby(["maze", "method"]).size().to_dict() == {
        (z, m): 9 for z in MAZES for m in ("Few-shot (static support set)", "Few-shot + DSS")
    }
    refs = data[data["p"].isna()]
    assert sorted(zip(refs["maze"], refs["method"])) == sorted(
        (z, m) for z in MAZES for m in ("SSRL", "Shield")
    )
    means = summary_means(d)
    assert dict(zip(data["cell"], data["mean"].round(4))) == {
        k: round(v, 4) for k, v in means.items()
    }
    assert (data["ci_low"] <= data["mean"]).all() and (data["mean"] <= data["ci_high"]).all()


def test_break_even_table_matches_the_cells_means(built):
    d, _ = built
    table = pd.read_csv(d / "reports" / "tables" / "accuracy_curve.csv", keep_default_na=False)
    assert table["maze"].tolist() == [
        z for z in MAZES for _ in range(4)
    ]  # mazes by size, not by name
    means = summary_means(d)
    methods = {"Few-shot (static support set)": "fewshot", "Few-shot + DSS": "fewshot_dss"}
    references = {"SSRL": "ssrl", "Shield": "shield"}
    for row in table.to_dict("records"):
        expected = expected_break_even(
            means, methods[row["method"]], row["maze"], references[row["against"]]
        )
        assert row["break-even p"] == expected, row
        low, high = row["95% CI"].strip("[]").split(", ")
        assert level(low) <= level(row["break-even p"]) <= level(high), (
            row
        )  # the point lies in its interval


def test_break_even_finds_the_first_level_at_or_below_the_reference():
    levels = [0.2, 0.4, 0.6, 0.8]
    curve = np.array([[10.0] * 5, [8.0] * 5, [5.0] * 5, [1.0] * 5])
    assert break_even(levels, curve, np.full(5, 5.0)) == (
        0.6,
        0.6,
        0.6,
    )  # "at or below": equal counts
    assert break_even(levels, curve, np.full(5, 12.0)) == (0.2, 0.2, 0.2)
    assert break_even(levels, curve, np.full(5, 0.5)) == (np.inf, np.inf, np.inf)


def test_break_even_interval_resamples_run_seeds_together():
    rng = np.random.default_rng(1)
    seeds = rng.normal(0, 5, 200)  # a run seed's difficulty, shared by every cell (paired)
    levels = np.array([0.2, 0.4, 0.6, 0.8])
    curve = 20 - 10 * levels[:, None] + seeds + rng.normal(0, 1, (4, 200))
    reference = 14 + seeds + rng.normal(0, 1, 200)
    point, low, high = break_even(levels, curve, reference)
    assert point == 0.6 and low <= point <= high and high - low <= 0.2 + 1e-9
    # unpaired (the reference's seeds shuffled) the noise of the seeds widens the interval
    _, low_u, high_u = break_even(levels, curve, rng.permutation(reference))
    assert high_u - low_u >= high - low
    assert break_even(levels, curve, reference) == (point, low, high)  # seeded: the same interval


def test_the_block_chooses_cells_and_takes_no_groups(built):
    d, _ = built
    exp = load_experiment(d / "runs" / "accuracy_curve")
    exp.spec.cells = ["ssrl_7x7", "fewshot_7x7_p50", "fewshot_7x7_p20"]
    parts = split(exp)
    assert parts.mazes == ["7x7"] and list(parts.references) == [("7x7", "SSRL")]
    assert [(c.label, c.levels.tolist()) for c in parts.curves] == [
        ("Few-shot (static support set)", [0.2, 0.5])
    ]
    spec = ReportSpec(kind="accuracy_curve", groups=[Group(key="a", cells=["ssrl_7x7"])])
    assert [key for key, _ in spec.problems(exp.declared)] == ["groups"]
    for key in (
        "curves",
        "support_accuracy",
    ):  # given, even as true, they would be ignored: refused
        for value in (True, False):
            spec = ReportSpec(kind="accuracy_curve", **{key: value})
            assert [k for k, _ in spec.problems(exp.declared)] == [key]
    assert (
        ReportSpec(kind="default", curves=False, support_accuracy=True).problems(exp.declared) == []
    )
