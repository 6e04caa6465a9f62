"""The report is driven by the experiment files: a cells-only experiment gets the default section
(collisions with 95% intervals, learning curves with bands) with no code change; the paper's
experiments keep their sections through the ``report:`` blocks of their yamls, read back from the
records; the block is typed; rows are named from what their cells ran. Smoke scale with the oracle
recogniser (no model needed)."""

import dataclasses
import shutil

import numpy as np
import pandas as pd
import pytest
from fakes import FIG8_WITHOUT_MODELS

from pipeline.config.compose import load_config
from pipeline.errors import ConfigError
from pipeline.report.spec import ReportSpec
from pipeline.stages import run_stage
from pipeline.stats import mean_band, t_quantile_975

#: A new experiment file that holds only cells (no report block).
CELLS_ONLY = """\
# @package _global_
maze: 5x5
experiment:
  name: mine
  cells:
    a: {method: shield}
    b: {method: ssrl}
"""


def trials(exp, out, *extra):
    run_stage(
        "trials", [f"+experiment={exp}", "profile=smoke", "progress=false", f"out={out}", *extra]
    )


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    d = tmp_path_factory.mktemp("report_experiments")
    conf = d / "conf"
    (conf / "experiment").mkdir(parents=True)
    (conf / "experiment" / "mine.yaml").write_text(CELLS_ONLY)
    runs = d / "runs"
    # a config folder of one's own on Hydra's search path: +experiment=mine finds conf/experiment/mine.yaml
    trials("mine", runs / "mine", f"hydra.searchpath=[file://{conf}]")
    trials("fig8", runs / "fig8", "recogniser=oracle", *FIG8_WITHOUT_MODELS)
    trials("table3", runs / "table3", "recogniser=oracle")
    run_stage(
        "report",
        [
            f"runs_dir={runs}",
            f"accuracy_dir={d}/no_accuracy",
            f"out={d}/reports",
            "allow_missing=true",
        ],
    )
    return d, (d / "reports" / "index.md").read_text()


def test_a_cells_only_experiment_gets_the_default_section(built):
    d, index = built
    assert "## Experiment mine" in index
    table = pd.read_csv(d / "reports" / "tables" / "mine.csv")
    assert table["cell"].tolist() == [
        "Shield",
        "SSRL",
    ]  # named from the recorded methods, not the cell ids
    assert table["runs"].tolist() == [3, 3]
    ci = table["collisions (mean ± s.d. [95% CI])"]
    assert ci.str.fullmatch(r"[\d.]+ ± [\d.]+ \[[\d.]+, [\d.]+\]").all()
    assert (d / "reports" / "figures" / "mine_learning_curves.png").stat().st_size > 1000
    curves = pd.read_csv(d / "reports" / "tables" / "mine_learning_curves.csv")
    assert curves.columns.tolist() == [
        "series",
        "key",
        "colour",
        "maze",
        "episode",
        "mean",
        "ci_low",
        "ci_high",
    ]
    a = curves[curves["key"] == "a"]
    assert set(a["series"]) == {"Shield"} and a["episode"].tolist() == list(
        range(20)
    )  # from episode 0
    assert (a["ci_low"] <= a["mean"]).all() and (a["mean"] <= a["ci_high"]).all()
    # shield: every run collides in the first episode; the mean of the table is the curves' sum
    assert a["mean"].sum() == pytest.approx(
        float(table["collisions (mean ± s.d. [95% CI])"][0].split()[0]), abs=0.01
    )


def test_paper_sections_come_from_their_report_blocks(built):
    d, index = built
    for heading in (
        "## Figure 7: the learned optimal path",
        "## Figure 8: collisions",
        "## Table 3: mean collisions",
    ):
        assert heading in index
    # order: the blocks' order (fig8 1, table3 4), then experiments without a block (100)
    assert (
        index.index("## Figure 7")
        < index.index("## Figure 8")
        < index.index("## Table 3")
        < index.index("## Experiment mine")
    )
    assert "Paper: Methods with a safety guarantee collide far less than Q-learning" in index
    fig8 = pd.read_csv(d / "reports" / "tables" / "fig8.csv")
    # FIG8_WITHOUT_MODELS gives the Prototypical Network's cells the oracle too (no pictures here), so
    # they read as the paper's few-shot rows; the smoke pipeline checks their own names
    # (the paper_tables cells tell them apart by recogniser)
    few = ["Few-shot (static support set)", "Few-shot + DSS"]
    names = ["Q-learning", "Shield", "SSRL", *(f"{n}, oracle recogniser" for n in few)]
    tables = [f"{n}, paper's Tables 1-2 recogniser" for n in few]
    assert fig8["method"].tolist() == names + names[3:] + tables
    # the paper's numbers for Figure 8 are Table 3's for the same setting (recorded in table3's
    # block); the paper_tables rows have no such setting there
    paper = ["", "", "", "8.77 (Table 3)", "7.145 (Table 3, ways 1-4 pooled)"]
    assert fig8["paper"].fillna("").tolist() == paper + paper[3:] + ["", ""]
    for name in (
        "fig8_collisions.png",
        "fig8_learning_curves.png",
        "fig8_path.png",
        "fig8_support_accuracy.png",
        "table3_learning_curves_11x11.png",
        "table3_support_accuracy_7x7.png",
    ):
        assert (d / "reports" / "figures" / name).stat().st_size > 1000, name
    curves = pd.read_csv(
        d / "reports" / "tables" / "fig8_learning_curves.csv"
    )  # dvc.yaml's plots read these columns
    assert curves["series"].unique().tolist() == names + tables and {
        "episode",
        "mean",
        "ci_low",
        "ci_high",
    } <= set(curves)
    table3 = pd.read_csv(d / "reports" / "tables" / "table3.csv")
    assert table3["method"].tolist() == ["Sarsa", "Constrained RL", *names[3:], *tables]
    assert table3.columns.tolist()[1:] == [
        "5x5 ours",
        "5x5 paper",
        "7x7 ours",
        "7x7 paper",
        "11x11 ours",
        "11x11 paper",
    ]
    assert table3.set_index("method").loc[names[4], "5x5 paper"] == 7.145
    assert table3.set_index("method").loc["Sarsa", "7x7 paper"] == "not converged"
    data = pd.read_csv(d / "reports" / "tables" / "table3_data.csv")
    dss = data[(data["row"] == "fewshot_dss") & (data["maze"] == "5x5")]
    assert dss["n"].tolist() == [12]  # the DSS row pools the four ways: 4 cells x 3 runs
    curves = pd.read_csv(d / "reports" / "tables" / "table3_learning_curves.csv")
    assert f"{names[4]} (5x5)" in set(curves["series"])


def test_claims_section_is_generated_from_the_records(built):
    d, index = built
    assert index.index("## Claims of the paper against our data") < index.index("## Figure 8")
    claims = pd.read_csv(d / "reports" / "tables" / "claims.csv")
    assert set(claims["claim verdict"]) <= {"holds", "does not hold", "not resolved", "not checked"}
    # one table per recogniser: the cells ran the oracle (the default config's Prototypical Network
    # study adds its own table); the oracle's first
    assert claims["recogniser"].iloc[0] == "oracle" and "### With the `oracle` recogniser" in index
    claims = claims[claims["recogniser"] == "oracle"]
    by_source = claims.groupby("source")["claim verdict"].apply(set)
    assert by_source["Figure 9"] == {"not checked"} and by_source["Table 2"] == {
        "not checked"
    }  # no records, no study
    order = claims[claims["claim text"].str.startswith("collisions fall in the order")]
    assert (
        len(order) == 9
        and order["check verdict"].isin(["holds", "does not hold", "not resolved"]).all()
    )
    assert (order["ci_low"] <= order["estimate"]).all() and (
        order["estimate"] <= order["ci_high"]
    ).all()
    assert (
        order["interval over"].eq("3 run seeds, paired").all()
    )  # the cells of table3 share run seeds


def test_experiments_and_cells_without_records_are_named(built, tmp_path):
    d, index = built
    line = next(x for x in index.splitlines() if x.startswith("**Missing from this report**"))
    assert (
        "experiment fig9" in line
        and "experiment fig10" in line
        and "fig8" not in line
        and "table3" not in line
    )
    runs = tmp_path / "runs"
    shutil.copytree(d / "runs" / "mine", runs / "mine")
    shutil.rmtree(runs / "mine" / "b")
    run_stage(
        "report",
        [
            f"runs_dir={runs}",
            f"accuracy_dir={tmp_path}/none",
            f"out={tmp_path}/reports",
            "allow_missing=true",
        ],
    )
    index = (tmp_path / "reports" / "index.md").read_text()
    assert "cell mine/b" in next(
        x for x in index.splitlines() if x.startswith("**Missing from this report**")
    )
    assert pd.read_csv(tmp_path / "reports" / "tables" / "mine.csv")["cell"].tolist() == ["Shield"]


@pytest.mark.parametrize(
    "override,message",
    [
        ("+experiment.report.colour=red", "config key 'experiment.report.colour'"),
        ("experiment.report.kind=pie", "config key 'experiment.report.kind': must be one of"),
        (
            "experiment.report.cells=[qlearning,nope]",
            "config key 'experiment.report.cells': no cell 'nope'",
        ),
        ("+experiment.report.path.colour=red", "config key 'experiment.report.path.colour'"),
    ],
)
def test_the_report_block_is_typed(override, message, tmp_path):
    with pytest.raises(ConfigError, match=message):
        run_stage("trials", ["+experiment=fig8", "recogniser=oracle", override, f"out={tmp_path}"])


def test_wrong_group_keys_are_refused(tmp_path):
    with pytest.raises(
        ConfigError, match=r"experiment.report.groups.0.cells': no cell 'sarsa_9x9'"
    ):
        run_stage(
            "trials",
            [
                "+experiment=table3",
                "recogniser=oracle",
                f"out={tmp_path}",
                "experiment.report.groups.0.cells=[sarsa_9x9]",
            ],
        )
    with pytest.raises(ConfigError, match=r"experiment.report.groups.0.paperz"):
        load_config("trials", ["+experiment=table3", "+experiment.report.groups.0.paperz=1"])


def test_spec_round_trips_through_the_recorded_dict():
    spec = load_config("trials", ["+experiment=table3", "recogniser=oracle"]).experiment.report
    assert ReportSpec.from_dict(dataclasses.asdict(spec)) == spec
    assert ReportSpec.from_dict(None) == ReportSpec()
    # blocks recorded before rows were named from their cells still read (their labels unused)
    old = {**dataclasses.asdict(spec), "labels": {"x": "y"}}
    old["groups"] = [{**g, "label": "old"} for g in old["groups"]]
    assert ReportSpec.from_dict(old) == spec
    with pytest.raises(ValueError, match="unknown key"):
        ReportSpec.from_dict({"colour": "red"})
    with pytest.raises(ValueError, match="report.kind"):
        ReportSpec.from_dict({"kind": "pie"})


def test_band_is_a_t_interval():
    assert t_quantile_975(2) == pytest.approx(4.3027, abs=1e-4)
    assert t_quantile_975(30) == pytest.approx(2.0423, abs=1e-4)
    assert t_quantile_975(99) == pytest.approx(1.9842, abs=1e-4)
    values = np.array([[0.0, 1.0, 2.0], [2.0, 1.0, np.nan]])
    mean, lo, hi = mean_band(values)
    np.testing.assert_allclose(mean, [1.0, 1.0, 2.0])
    half = 12.7062 * np.sqrt(2) / np.sqrt(2)  # t(1) * s.d. / sqrt(n)
    np.testing.assert_allclose(lo, [1.0 - half, 1.0, 2.0])
    np.testing.assert_allclose(hi, [1.0 + half, 1.0, 2.0])


def test_start_accuracy_note_names_each_recogniser_when_they_differ():
    from pipeline.report.parts import start_accuracy_note

    same = {"Few-shot": [0.55, 0.55], "Few-shot + DSS": [0.55]}
    assert (
        start_accuracy_note(same)
        == "; at the start of a run the support set recognises 55.0% of the query pictures"
    )
    mixed = {
        "Few-shot, Relation Network": [0.55],
        "Few-shot, Prototypical Network": [0.375],
        "Shield": [],
    }
    assert start_accuracy_note(mixed) == (
        "; at the start of a run the support set recognises 55.0% (Few-shot, "
        "Relation Network), 37.5% (Few-shot, Prototypical Network) of the query pictures"
    )
    assert start_accuracy_note({"Shield": []}) == ""


def test_the_report_says_each_part_without_a_terminal(capsys):
    """Under ``dvc repro`` (no terminal, no bar) the report prints the part it builds, the parts
    done, the time so far and the time left: while it reads the records, at the pace of the bytes;
    after them, at the pace of the parts since (the records are no guide to the rest)."""

    from tqdm import tqdm

    from pipeline.report.build import Parts

    with tqdm(total=4, disable=True) as bar:
        parts = Parts(bar, 3)
        parts.reading("fig8", 0, 300_000_000)
        parts.started -= 5  # five seconds in
        parts.reading("fig9", 100_000_000, 300_000_000)
        parts.started += 5
        parts.more(1)  # the records are read: the pace of the rest starts here
        parts.finished()
        parts.started -= 100  # the records took 100 s
        parts.building("claims")  # no part since: no estimate yet
        parts.finished()
        parts.started -= 10
        parts.paced_from = (parts.paced_from[0] - 10, parts.paced_from[1])  # claims took 10 s
        parts.building("fig8")
    lines = capsys.readouterr().out.splitlines()
    assert lines == [
        "[report] reading the records of fig8: 0 of 300 MB read (0 s)",
        "[report] reading the records of fig9: 100 of 300 MB read (5 s, about 10 s left)",
        "[report] claims: 1/4 parts done (100 s)",
        "[report] fig8: 2/4 parts done (110 s, about 20 s left)",
    ]
