"""The repetition section (pipeline/report/repetition.py): the DSS gain per recogniser and r from
the cells, and repetition's share of Table 3's growth, pinned on small exact cases; the section
with its figure (no overlapping texts) from records made up here."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from pipeline.report import repetition as R
from pipeline.report.experiments import Cell
from pipeline.report.spec import Group, ReportSpec

#: The fixed-accuracy recogniser's ``_target_`` (``conf/recogniser/fixed_accuracy.yaml``).
FIXED = "pipeline.rl.fixed_accuracy.FixedAccuracyRecogniser"


def cell(name, method, maze, per_run, recogniser=None, p=None, experiment="repetition", rows=()):
    episodes = pd.DataFrame(
        {"run": np.arange(len(per_run)), "episode": 0, "collisions": np.asarray(per_run)}
    )
    return Cell(
        experiment=experiment,
        name=name,
        info={
            "method": {
                "name": method,
                "safety": "fewshot",
                "dynamic_support": method.endswith("dss"),
            },
            "maze": maze,
            "substitution": 1,
            "recogniser": {"kind": recogniser} if recogniser else None,
        },
        layout=list(rows),
        obstacles={},
        episodes=episodes,
        recognitions=pd.DataFrame(),
        substitutions=pd.DataFrame(),
        config={
            "seed": 0,
            "recogniser": {"_target_": FIXED, "p": p} if p is not None else {},
        },
    )


class Exp:
    def __init__(self, cells, name="repetition", spec=None):
        self.cells = {c.name: c for c in cells}
        self.folder = self.name = name
        self.spec = spec or ReportSpec()


#: The paper's Table 3 few-shot rows, as table3's report block records them.
TABLE3_PAPER = ReportSpec(
    groups=[
        Group("fewshot", paper={"5x5": "8.77", "7x7": "18.39", "11x11": "48.44"}),
        Group("fewshot_dss", paper={"5x5": "7.145", "7x7": "9.75", "11x11": "15.9"}),
    ]
)


def repetition_cells(rel_by_r: dict[int, float], recogniser="relation_net", p=None):
    """Two layouts per r, 10 collisions without the DSS, 10 * (1 - rel) with it, every run."""
    out = []
    for r, rel in rel_by_r.items():
        for k in range(2):
            maze = f"random:11x11:{10 * r}:{1000 * r + k}"
            tag = recogniser or f"p{p}"
            out.append(cell(f"a_{tag}_{r}_{k}", "fewshot", maze, [10.0] * 4, recogniser, p))
            out.append(
                cell(f"b_{tag}_{r}_{k}", "fewshot_dss", maze, [10 * (1 - rel)] * 4, recogniser, p)
            )
    return out


def test_layout_rows_pair_the_methods_per_layout_and_recogniser():
    cells = repetition_cells({1: 0.2, 4: 0.5}) + repetition_cells({1: 0.0, 4: 0.4}, None, 0.55)
    df = R.layout_rows(Exp(cells))
    assert sorted(df["recogniser"].unique()) == ["Relation Network", "fixed accuracy p = 0.55"]
    assert sorted(df["r"].unique()) == [1.0, 4.0]
    rn = df[df["recogniser"] == "Relation Network"].sort_values("r")
    assert rn["gain"].tolist() == pytest.approx([2.0, 2.0, 5.0, 5.0])
    rows, curves = R.curve_table(df)
    c = curves["Relation Network"]
    assert c["relative"][0] == pytest.approx([0.2, 0.5])  # no spread: the intervals collapse
    assert c["relative"][1] == pytest.approx([0.2, 0.5]) and c["gain"][2] == pytest.approx([2, 5])
    assert rows[0]["relative gain [95% CI]"] == "20.0% [20.0, 20.0]"


def test_read_at_interpolates_and_holds_the_ends():
    rs, v = np.array([1.0, 2.0, 5.0]), np.array([0.1, 0.3, 0.6])
    assert R.at(rs, v, 0.9) == 0.1 and R.at(rs, v, 1.5) == pytest.approx(0.2)
    assert R.at(rs, v, 4.9) == pytest.approx(0.59) and R.at(rs, v, 6) == 0.6


def table3(rel5, rel11):
    rows5 = ["SX" + "X" * 7]  # 9 obstacles: r = 0.9
    rows11 = ["X" * 49]  # r = 4.9
    runs = np.arange(4)
    return {
        "5x5": (0.9, pd.Series(10.0, index=runs), pd.Series(10 * (1 - rel5), index=runs)),
        "11x11": (4.9, pd.Series(10.0, index=runs), pd.Series(10 * (1 - rel11), index=runs)),
        "_rows": (rows5, rows11),
    }


def test_the_verdict_is_repetitions_share_of_table_3s_growth():
    # at one size the relative gain goes 0.2 (r <= 1) -> 0.6 (r = 4.9, between 4 and 5): +0.4;
    # Table 3's goes 0.0 -> 0.8: +0.8, so repetition accounts for half of it
    df = R.layout_rows(Exp(repetition_cells({1: 0.2, 4: 0.6, 5: 0.6})))
    t3 = table3(0.0, 0.8)
    rows, n = R.verdict(df, {k: v for k, v in t3.items() if k != "_rows"}, "Relation Network")
    est, lo, hi, rep_pts, t3_pts = n["relative gain"]
    assert est == pytest.approx(0.5) and lo == pytest.approx(0.5) and hi == pytest.approx(0.5)
    assert rep_pts == pytest.approx(40) and t3_pts == pytest.approx(80)
    assert rows[0]["repetition's share [95% CI]"] == "50% [50, 50]"
    assert R.words(0.7, 0.5, 0.9) == "most of it" and R.words(0.1, 0.05, 0.15) == "little of it"
    assert R.words(0.95, 0.85, 1.1) == "nearly all of it" and R.words(0.3, 0.1, 0.5) == "part of it"


def test_the_section_builds_with_table_3_beside(tmp_path):
    from pipeline.report.build import Report

    rep = Report(tmp_path)
    rng = np.random.default_rng(0)
    cells = []
    for r in (1, 2, 3, 4):
        for k in range(3):
            maze = f"random:11x11:{10 * r}:{1000 * r + k}"
            for rec, p in (("relation_net", None), (None, 0.55)):
                tag = rec or "fixed"
                w = 10 + 5 * r + rng.normal(0, 1, 5)
                cells.append(cell(f"w_{tag}_{r}_{k}", "fewshot", maze, w, rec, p))
                cells.append(
                    cell(f"d_{tag}_{r}_{k}", "fewshot_dss", maze, w * (1 - 0.15 * r), rec, p)
                )
    t3 = []
    for maze, n, rel in (("5x5", 9, 0.01), ("7x7", 16, 0.3), ("11x11", 49, 0.65)):
        rows = ["X" * n]
        w = 10 + rng.normal(0, 1, 6)
        t3.append(
            cell(
                f"fewshot_{maze}",
                "fewshot",
                maze,
                w,
                "relation_net",
                experiment="table3",
                rows=rows,
            )
        )
        for way in (1, 2, 3, 4):
            t3.append(
                cell(
                    f"dss{way}_{maze}",
                    "fewshot_dss",
                    maze,
                    w * (1 - rel),
                    "relation_net",
                    experiment="table3",
                    rows=rows,
                )
            )
    table = Exp(t3, "table3", TABLE3_PAPER)
    R.repetition_section(rep, Exp(cells), [table])
    text = "\n".join(rep.sections)
    assert "**Verdict.**" in text and "repetition accounts for" in text
    assert (tmp_path / "figures" / "repetition.png").stat().st_size > 1000
    verdict = pd.read_csv(tmp_path / "tables" / "repetition_verdict.csv")
    assert verdict["scale"].tolist() == ["relative gain", "absolute gain (collisions per run)"]


def source_cells(per_setting: list[float], r: int = 1, layouts: int = 2) -> list[Cell]:
    """The five settings of the split (repetition_sources.SETTINGS) on ``layouts`` layouts, the
    Relation Network's cells, collisions per run ``per_setting`` in SETTINGS order (every run)."""
    from pipeline.report.repetition_sources import SETTINGS

    out = []
    for k in range(layouts):
        maze = f"random:11x11:{10 * r}:{1000 * r + k}"
        for (method, learn_from), per_run in zip(SETTINGS, per_setting):
            c = cell(f"{method}_{learn_from}_{k}", method, maze, [per_run] * 4, "relation_net")
            if learn_from != "all":
                c.config["recogniser"] = {"learn_from": learn_from}
            out.append(c)
    return out


def test_the_gain_splits_by_source_in_steps_that_sum_to_it():
    """Without the DSS 10 collisions; seeing the same picture 8; its obstacle 7; its category 5.5;
    everything 5: the whole gain 5 splits 2 + 1 + 1.5 + 0.5. The learn_from cells stay out of the
    section's other rows."""
    from pipeline.report.repetition_sources import source_rows, split_table

    exp = Exp(source_cells([10, 8, 7, 5.5, 5]))
    df = source_rows(exp, R.recogniser_label)
    assert len(df) == 2 and set(df["r"]) == {1.0}
    assert df[["same face", "other faces of the obstacle"]].iloc[0].tolist() == [2, 1]
    assert df["the category's other obstacle"].iloc[0] == 1.5
    assert df["other categories"].iloc[0] == 0.5 and df["whole gain"].iloc[0] == 5
    rows, numbers = split_table(df, resamples=50, seed=0)
    assert rows[0]["whole DSS gain [95% CI]"] == "5.00 [5.00, 5.00]"
    assert rows[0]["same face [95% CI]"] == "2.00 [2.00, 2.00] (40%)"
    assert numbers[("Relation Network", 1.0, "the category's other obstacle")] == (1.5, 1.5, 1.5)
    plain = R.layout_rows(exp)
    assert plain["gain"].tolist() == [5, 5]  # without vs the full DSS only


def test_a_layout_missing_a_setting_gives_no_split_row():
    from pipeline.report.repetition_sources import source_rows

    cells = [c for c in source_cells([10, 8, 7, 5.5, 5]) if not c.name.endswith("same_object_1")]
    assert len(source_rows(Exp(cells), R.recogniser_label)) == 1
