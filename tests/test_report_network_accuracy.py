"""Accuracy across networks (pipeline/report/network_accuracy.py): each network's test and
validation accuracy, query pictures and Tables 1-2, the spread across networks and the intervals
over these networks and over networks then theirs, pinned on copies of the committed study."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pipeline.report import network_accuracy as NA
from pipeline.report.build import Report
from pipeline.report.study import read_summary

ACCURACY = Path(__file__).resolve().parents[1] / "datasets" / "accuracy"
FILES = ("summary.json", "table1.csv", "table2.csv", "draws.csv", "families.csv")

pytestmark = pytest.mark.skipif(
    not all((ACCURACY / f).exists() for f in FILES), reason="needs the committed accuracy study"
)


def study_copy(folder: Path, correct_scale: float = 1.0) -> Path:
    """A copy of the committed study, its families' correct answers scaled (0: none right)."""
    folder.mkdir(parents=True)
    for name in FILES:
        shutil.copy(ACCURACY / name, folder / name)
    if correct_scale != 1.0:
        rows = pd.read_csv(folder / "families.csv")
        rows["correct"] = (rows["correct"] * correct_scale).round().astype(int)
        rows.to_csv(folder / "families.csv", index=False)
    return folder


def row(rows, quantity):
    (found,) = [r for r in rows if r["quantity"] == quantity]
    return found


def test_the_folders_of_each_kind_are_found_by_name(tmp_path):
    seed0 = study_copy(tmp_path / "accuracy")
    nets = tmp_path / "networks"
    study_copy(nets / "relation_net_seed2")
    study_copy(nets / "relation_net_seed1")
    study_copy(nets / "unknown_seed1")  # a kind without a seed-0 study: not shown
    (nets / "relation_net_seed3").mkdir()  # no study in it: not shown
    found = NA.network_folders({"relation_net": seed0}, nets)
    assert found == {
        "relation_net": {0: seed0, 1: nets / "relation_net_seed1", 2: nets / "relation_net_seed2"}
    }
    assert NA.network_folders({"relation_net": seed0}, tmp_path / "none") == {
        "relation_net": {0: seed0}
    }


def test_identical_networks_have_no_spread_and_the_studys_own_family_interval(tmp_path):
    """Two copies of one study: s.d. 0, and both intervals of the test accuracy are the study's
    own family interval (the same families resampled with the same seed)."""
    seed0 = study_copy(tmp_path / "accuracy")
    study_copy(tmp_path / "networks" / "relation_net_seed1")
    rows = NA.spread_rows(NA.network_folders({"relation_net": seed0}, tmp_path / "networks"))
    test = row(rows, NA.SPLITS["test"])
    family = read_summary(ACCURACY)["families"]["test"]
    lo, hi = (100 * v for v in family["family_ci"])
    assert (
        test["mean"] == f"{100 * family['accuracy']:.2f}%"
        and test["s.d. across networks"] == "0.00"
    )
    assert test["95% CI, these networks"] == f"[{lo:.2f}, {hi:.2f}]"
    assert test["95% CI, networks then theirs"] == test["95% CI, these networks"]
    pictures = [r for r in rows if r["quantity"].startswith("query pictures right")]
    assert pictures[0]["95% CI, these networks"] == ""  # no random draw
    assert [r["quantity"] for r in rows] == [
        NA.SPLITS["test"],
        NA.SPLITS["val"],
        pictures[0]["quantity"],
        "Table 1: mean after one substitution",
        "Table 2: after five substitutions",
    ]


def test_a_network_that_names_nothing_right_halves_the_mean_and_widens_the_interval(tmp_path):
    seed0 = study_copy(tmp_path / "accuracy")
    study_copy(tmp_path / "networks" / "relation_net_seed1", correct_scale=0.0)
    rows = NA.spread_rows(NA.network_folders({"relation_net": seed0}, tmp_path / "networks"))
    test = row(rows, NA.SPLITS["test"])
    accuracy = 100 * read_summary(ACCURACY)["families"]["test"]["accuracy"]
    assert test["each network"] == f"{accuracy:.1f} / 0.0"
    assert test["mean"] == f"{accuracy / 2:.2f}%"
    assert test["s.d. across networks"] == f"{accuracy / np.sqrt(2):.2f}"
    # resampling two networks draws the bad one twice in a quarter of the resamples
    assert test["95% CI, networks then theirs"].startswith("[0.00, ")


def test_networks_then_theirs_resamples_networks_before_their_draws():
    values = np.array([0.2, 0.8])
    no_draws = NA.networks_then_draws(values, None)
    assert set(np.unique(no_draws)) == {0.2, 0.5, 0.8}
    draws = np.vstack([np.full(NA.RESAMPLES, 0.2), np.full(NA.RESAMPLES, 0.8)])
    assert np.array_equal(NA.networks_then_draws(values, draws), no_draws)


def test_the_section_writes_its_table_and_figure_only_with_a_second_network(tmp_path):
    seed0 = study_copy(tmp_path / "accuracy")
    rep = Report(tmp_path / "out")
    NA.network_accuracy_section(rep, {"relation_net": seed0}, tmp_path / "networks")
    assert rep.sections == []  # one network: no spread to show
    study_copy(tmp_path / "networks" / "relation_net_seed1")
    NA.network_accuracy_section(rep, {"relation_net": seed0}, tmp_path / "networks")
    assert (tmp_path / "out" / "figures" / "network_accuracy.png").is_file()
    table = pd.read_csv(tmp_path / "out" / "tables" / "network_accuracy.csv")
    assert table["networks"].tolist() == [2] * 5 and table["seeds"].tolist() == ["0 1"] * 5
