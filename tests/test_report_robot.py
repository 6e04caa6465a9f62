"""The report's robot section (:mod:`pipeline.report.robot`) on the robot3d experiment at a tiny
scale (2 runs x 3 episodes a cell, ``fixed_accuracy``: no model; MuJoCo renders the robot cells'
live pictures): a table per decision rule, robot and grid paired by run, the methods that see no
pictures equal run by run, the range sensor never colliding, and records that do not match their
cell refused, naming the file."""

import dataclasses
import re
import shutil

import pandas as pd
import pytest

from pipeline.report.build import Report
from pipeline.report.experiments import ReportInputError, load_experiment
from pipeline.report.robot import robot_kind
from pipeline.report.robot_cells import check_cell, per_run, read_extra
from pipeline.stages import run_stage

RUNS = 2
FEW_SHOT_ROWS = [
    ("Few-shot (static support set)", "5x5"),
    ("Few-shot (static support set)", "7x7"),
    ("Few-shot + DSS", "5x5"),
    ("Few-shot + DSS", "7x7"),
]


def section(folder, out):
    """The robot section of the experiment recorded in ``folder``, written to ``out``."""
    rep = Report(out)
    robot_kind(rep, load_experiment(folder), [])
    return rep


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    d = tmp_path_factory.mktemp("report_robot")
    folder = d / "runs" / "robot3d"
    run_stage(
        "trials",
        [
            "+experiment=robot3d",
            "recogniser=fixed_accuracy",
            f"runs={RUNS}",
            "episodes=3",
            "workers=1",
            "progress=false",
            f"out={folder}",
        ],
    )
    rep = section(folder, d / "report")
    return folder, d / "report", rep


def table(out, name):
    return pd.read_csv(out / "tables" / f"{name}.csv")


def test_one_table_per_decision_rule(recorded):
    _, out, _ = recorded
    for rule in ("paper", "open_set", "range"):
        t = table(out, f"robot3d_{rule}")
        assert list(zip(t["method"], t["maze"])) == FEW_SHOT_ROWS, rule
        assert t.columns.tolist() == [
            "method",
            "maze",
            "runs",
            "collisions, grid",
            "collisions, robot",
            "collisions, robot - grid (paired)",
            "false stops, grid",
            "false stops, robot",
            "right stops, grid",
            "right stops, robot",
        ]
        assert (t["runs"] == RUNS).all()
    md = (out / "tables" / "robot3d_paper.md").read_text()
    assert md.startswith("Decision rule `paper`:") and "false stop" in md


def test_a_figure_shows_the_robot_against_the_grid_per_rule(recorded, monkeypatch):
    """One row per robot cell: the three rules' few-shot rows and the methods that see no pictures,
    each in its rule's colour, in the tables' order."""
    from pipeline.report import figures_beyond, robot

    folder, out, _ = recorded
    assert (out / "figures" / "robot3d_robot_minus_grid.png").stat().st_size > 0
    drawn = []
    monkeypatch.setattr(robot, "difference_figure", lambda rows, path: drawn.append(rows))
    section(folder, out)
    (rows,) = drawn
    few = [
        (f"{method}, {maze}", rule)
        for rule in figures_beyond.RULES[:3]
        for method, maze in FEW_SHOT_ROWS
    ]
    assert sorted((label, rule) for label, rule, _, _ in rows if rule != "no pictures") == sorted(
        few
    )
    assert any(rule == "no pictures" for _, rule, _, _ in rows)  # shield, SSRL: no pictures
    for _, _, on_robot, on_grid in rows:
        assert len(on_robot) == len(on_grid) == RUNS


def test_the_paper_rule_has_no_false_stops_and_the_range_sensor_stops_on_every_picture(recorded):
    folder, _, _ = recorded
    exp = load_experiment(folder)
    for name, cell in exp.cells.items():
        figures = per_run(cell, read_extra(cell))
        if name.startswith("fewshot") and name.endswith("_paper"):
            assert figures.false_stops.sum() == 0, name
        if name.endswith("_range"):
            pictures = cell.recognitions.groupby("run").size().reindex(figures.runs, fill_value=0)
            assert (figures.right_stops + figures.false_stops).tolist() == pictures.tolist()
            assert figures.collisions.sum() == 0, name


def test_range_rule_never_collides(recorded):
    _, out, rep = recorded
    t = table(out, "robot3d_range")
    for column in ("collisions, grid", "collisions, robot"):
        assert (t[column] == "0.00 [0.00, 0.00]").all(), column
    assert (t["collisions, robot - grid (paired)"] == "+0.00 [+0.00, +0.00]").all()
    first = rep.sections[0]  # the section's first paragraph
    assert first.startswith("**What recognition adds over the range sensor")
    runs = len(FEW_SHOT_ROWS) * RUNS  # the range rule's robot runs
    assert f"none of its {runs} robot runs (nor their grid twins) collided" in first
    assert "0.00 (0.00) under `range`" in first


def test_shield_and_ssrl_collide_alike_on_the_robot_and_the_grid(recorded):
    folder, out, _ = recorded
    t = table(out, "robot3d_no_pictures")
    assert list(zip(t["method"], t["maze"])) == [
        ("Shield", "5x5"),
        ("Shield", "7x7"),
        ("SSRL", "5x5"),
        ("SSRL", "7x7"),
    ]
    assert (t["collisions, grid"] == t["collisions, robot"]).all()
    assert (t["runs where robot = grid"] == f"{RUNS} of {RUNS}").all()
    exp = load_experiment(folder)
    for method in ("shield", "ssrl"):
        for maze in ("5x5", "7x7"):
            robot = exp.cells[f"{method}_{maze}_robot3d"].collisions_per_run()
            grid = exp.cells[f"{method}_{maze}_grid"].collisions_per_run()
            assert robot.tolist() == grid.tolist()
    assert (out / "tables" / "robot3d_recognition.csv").exists()


def test_records_of_another_maze_are_refused_naming_the_file(recorded, tmp_path):
    folder, _, _ = recorded
    copy = tmp_path / "robot3d"
    shutil.copytree(folder, copy)
    swapped = copy / "fewshot_5x5_robot3d_paper" / "records.mcap"
    shutil.copyfile(copy / "fewshot_7x7_robot3d_paper" / "records.mcap", swapped)
    with pytest.raises(ReportInputError, match=re.escape(f"{swapped}: the records hold a 7x7")):
        section(copy, tmp_path / "report")


def test_a_robot_cell_without_its_grid_twin_is_refused(recorded, tmp_path):
    folder, _, _ = recorded
    copy = tmp_path / "robot3d"
    shutil.copytree(folder, copy)
    shutil.rmtree(copy / "fewshot_dss_7x7_grid_open_set")
    robot = copy / "fewshot_dss_7x7_robot3d_open_set" / "records.mcap"
    with pytest.raises(
        ReportInputError, match=re.escape(f"{robot}: a robot cell with no grid twin")
    ):
        section(copy, tmp_path / "report")


def test_a_robot_cell_must_hold_its_motion_table(recorded):
    folder, _, _ = recorded
    cell = load_experiment(folder).cells["shield_5x5_robot3d"]
    extra = read_extra(cell)
    assert extra.robot["cell"] == 1.0 and set(extra.robot["drives"]) >= {"free"}
    check_cell(cell, extra)
    with pytest.raises(ReportInputError, match=re.escape(f"{cell.path}: a robot cell (world")):
        check_cell(cell, extra._replace(robot=None))
    other = dataclasses.replace(cell, config={**cell.config, "robot": {"cell": 0.8}})
    with pytest.raises(
        ReportInputError,
        match=r"robot.cell=0.8\) whose records hold the motion table of 1.0 m cells",
    ):
        check_cell(other, extra)
