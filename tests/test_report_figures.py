"""The figure checks (pipeline/report/overlap.py), the one palette, the report's statement of its
scale (pipeline/report/scale.py) and the trials stage's metrics files (pipeline/cells/metrics.py)."""

from __future__ import annotations

import types
import warnings

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from pipeline import palette  # noqa: E402
from pipeline.report import figures as F  # noqa: E402
from pipeline.report import learning_curves as LC  # noqa: E402
from pipeline.report.overlap import FigureOverlapWarning, problems  # noqa: E402
from pipeline.report.scale import (  # noqa: E402
    MixedScalesError,
    check_scales,
    profile_of,
    scales,
    title_and_scale,
)
from pipeline.rl.rules import METHODS  # noqa: E402
from pipeline.world.pictures import CATEGORIES  # noqa: E402


def test_overlapping_texts_are_found():
    fig, ax = plt.subplots()
    ax.text(0.5, 0.5, "mean 5.7", fontsize=12)
    ax.text(0.51, 0.5, "paper 8.77", fontsize=12)
    found = problems(fig)
    plt.close(fig)
    assert found == ["text 'mean 5.7' overlaps 'paper 8.77'"]


def test_a_legend_over_data_is_found_and_one_outside_is_not():
    fig, ax = plt.subplots()
    ax.plot(np.linspace(0, 1, 50), np.linspace(1, 0, 50), label="a falling line")
    ax.legend(loc="upper left")  # the line starts there
    assert any("legend" in p for p in problems(fig))
    ax.get_legend().remove()
    fig.legend(loc="outside lower center")
    assert problems(fig) == []
    plt.close(fig)


def test_save_warns_about_an_overlap(tmp_path):
    fig, ax = plt.subplots()
    ax.set_xticks([0, 0.01], ["a long tick label", "another long one"])
    with pytest.warns(FigureOverlapWarning, match="bad.png: text 'a long tick label'"):
        F.save(fig, tmp_path / "bad.png")


def test_the_report_figures_pass_the_check(tmp_path):
    """Bars with the paper's marks, curves of rows that share a method, the learned path: no
    overlap (the warning is an error in the tests: pyproject.toml)."""
    from pipeline.report.paper_numbers import PaperValue

    rng = np.random.default_rng(0)
    labels = [
        "Q-learning",
        "Few-shot (static support set), Relation Network recogniser",
        "Few-shot + DSS, Relation Network recogniser",
        "Few-shot (static support set), Prototypical Network recogniser",
    ]
    samples = [rng.normal(m, 1.0, 100) for m in (170, 5.7, 5.6, 8.0)]
    paper = [
        None,
        PaperValue("8.77", "Table 3"),
        PaperValue("7.145", "Table 3", "ways 1-4 pooled"),
        None,
    ]
    with warnings.catch_warnings():
        warnings.simplefilter("error", FigureOverlapWarning)
        F.bars(labels, samples, "Figure 8", "collisions per run", tmp_path / "b.png", paper=paper)
        ways = {f"Few-shot + DSS, way {w}": rng.poisson(2.0, (5, 300)) for w in (1, 2, 3, 4)}
        LC.curves(ways, "ways", tmp_path / "c.png")
        F.optimal_path(
            ["SXX..", ".....", "X...G"], [], [0, 5, 6, 7, 8, 9, 14], "a path", tmp_path / "p.png"
        )


def kept_figures(monkeypatch, module) -> list:
    """The figures ``module`` saves, kept open instead of written."""
    kept = []
    monkeypatch.setattr(module, "save", lambda fig, path: kept.append(fig))
    return kept


def test_bars_that_dwarf_the_others_break_the_axis(monkeypatch):
    """Figure 8: Q-learning's 170 collisions over the others' 5-13; the others keep their scale below
    the break, Q-learning's runs above it, and the caption is told."""
    kept = kept_figures(monkeypatch, F)
    rng = np.random.default_rng(0)
    samples = [rng.normal(m, 1.0, 100) for m in (170, 13.0, 5.7)]
    note = F.bars(["Q-learning", "Shield", "SSRL"], samples, "Figure 8", "collisions", "b.png")
    top, bottom = kept[0].axes
    assert bottom.get_ylim()[0] == 0 and bottom.get_ylim()[1] == pytest.approx(
        1.15 * samples[1].max()
    )
    assert top.get_ylim()[0] == pytest.approx(0.95 * samples[0].min())
    assert note == (
        f"the y axis is broken between {1.15 * samples[1].max():.3g} and "
        f"{0.95 * samples[0].min():.3g}"
    )
    assert F.dwarfing([170, 13.0, 5.7]) == [0] and F.dwarfing([13.0, 8.0, 5.7]) == []
    even = F.bars(["a", "b"], [rng.normal(9, 1, 50), rng.normal(6, 1, 50)], "t", "y", "e.png")
    assert even == "" and len(kept[1].axes) == 1
    plt.close("all")


def test_learning_curves_show_the_later_episodes_at_their_own_scale(monkeypatch):
    """Collisions per episode from 8 down to a few hundredths: the first 10 episodes at full scale
    on the left, the rest on the right at the few-shot rows' scale; a row that keeps colliding
    (Q-learning at 1) runs above the right panel's top, and the caption says so."""
    kept = kept_figures(monkeypatch, LC)
    episodes = np.arange(500)
    early = 8.0 * np.exp(-episodes)  # every row starts at 8 and learns within a few episodes
    rows = {
        "Q-learning": np.tile(np.maximum(early, 1.0), (4, 1)),
        "Few-shot": np.tile(early + 0.02, (4, 1)),
        "Few-shot + DSS": np.tile(early + 0.01, (4, 1)),
    }
    note = LC.curves(rows, "Figure 8", "c.png")
    left, right = kept[0].axes[:2]
    assert left.get_xlim() == (0, 10) and left.get_ylim()[1] >= 8
    assert right.get_xscale() == "log" and right.get_xlim() == (10, 499)
    assert right.get_ylim()[1] == pytest.approx(LC.HEADROOM * (early[10] + 0.02))
    assert note == (
        "left: episodes 0-10 at full scale; right: episodes 10-499 (episode logarithmic) at the "
        "scale of the later episodes, each point a run's mean over its last 20 episodes, where "
        "Q-learning (up to 1.00) runs above the top"
    )
    rare = np.zeros((1, 60))
    rare[0, [5, 30]] = 1  # a collision in episodes 5 and 30
    means = LC.window_means(rare)[0]
    assert means[4] == 0 and means[5] == pytest.approx(1 / 6) and means[24] == pytest.approx(1 / 20)
    assert means[25] == 0 and means[30] == pytest.approx(1 / 20)
    flat = LC.curves({"accuracy": np.full((4, 500), 0.6)}, "t", "a.png", ylabel="accuracy")
    assert flat == "episode linear up to 10, logarithmic above" and len(kept[1].axes) == 1
    plt.close("all")


def test_one_palette():
    """Every category, start, goal and A_d a colour of its own; the methods' declared colours
    distinct; the Gymnasium frame and the figures take theirs from it."""
    from pipeline.replay.panels import colour
    from pipeline.rl import gym_render

    marks = [palette.category(c) for c in range(len(CATEGORIES))]
    marks += [palette.START, palette.GOAL, palette.UNSAFE]
    assert len(set(marks)) == len(marks) == len(CATEGORIES) + 3
    assert len({m.colour for m in METHODS}) == len(METHODS)
    assert palette.PAPER not in {m.colour for m in METHODS} | set(palette.SERIES)
    for c in range(len(CATEGORIES)):
        rgb = palette.rgb(palette.category(c))
        assert gym_render.CATEGORY_RGB[c] == rgb == tuple(int(x) for x in colour(c))
    assert palette.category(len(CATEGORIES)) == palette.OTHER_CATEGORY


def _experiment(folder: str, profile_trials: dict, runs: int, episodes: int):
    config = {"profile": {"trials": profile_trials}, "runs": runs, "episodes": episodes}
    cell = types.SimpleNamespace(config=config)
    return types.SimpleNamespace(folder=folder, cells={"a": cell, "b": cell})


PROFILES = {
    "paper": {"runs": 100, "episodes": 500, "layouts": 100, "layout_runs": 20},
    "smoke": {"runs": 3, "episodes": 20, "layouts": 2, "layout_runs": 3},
}


def test_the_report_names_the_scale_it_was_built_from():
    paper = [
        _experiment("fig8", PROFILES["paper"], 100, 500),
        _experiment("generalisation", PROFILES["paper"], 20, 500),
    ]
    found = scales(paper, PROFILES)
    check_scales(found, "runs", allow_mixed=False)
    title, line = title_and_scale(found, "Results")
    assert title == "Results"
    assert line == (
        "**Built from** records of profile `paper`: 100 runs x 500 episodes a cell (fig8); "
        "20 runs x 500 episodes a cell (generalisation)."
    )
    smoke = scales([_experiment("fig8", PROFILES["smoke"], 3, 20)], PROFILES)
    assert title_and_scale(smoke, "Results")[0].startswith("Smoke-scale test data, not the paper's")
    assert profile_of({"profile": {"trials": {"runs": 7}}}, PROFILES) == "unnamed profile"


def test_records_of_two_profiles_are_refused_unless_asked_for():
    mixed = scales(
        [
            _experiment("fig8", PROFILES["smoke"], 3, 20),
            _experiment("table3", PROFILES["paper"], 100, 500),
        ],
        PROFILES,
    )
    with pytest.raises(MixedScalesError, match="different scales.*allow_mixed_scales=true"):
        check_scales(mixed, "datasets/runs", allow_mixed=False)
    check_scales(mixed, "datasets/runs", allow_mixed=True)
    assert "profile `paper`" in title_and_scale(mixed, "R")[1]
    assert "profile `smoke`" in title_and_scale(mixed, "R")[1]


def test_metrics_are_a_file_per_cell_and_per_template_and_size_over_layouts(tmp_path):
    """Hand-listed cells alone; generated cells pooled per template and size (the mean of the
    layouts' means with an interval over layouts)."""
    import json

    from pipeline.cells.metrics import KEYS, write_metrics
    from pipeline.schemas.experiment import Cell as CellSpec
    from pipeline.schemas.experiment import Experiment, Layouts, LayoutSet

    def summary(runs: list[int]) -> dict:
        return {
            "runs": [{"collisions": c} for c in runs],
            "collisions": {"mean": float(np.mean(runs))},
            "n_runs": len(runs),
            "converged_runs": len(runs) - 1,
        }

    exp = Experiment(
        name="x",
        cells={"ssrl_5x5": CellSpec(method="ssrl", maze="5x5")},
        layouts=Layouts(
            sizes=[LayoutSet(size="5x5", obstacles=9, count=2)],
            cells={"shield": CellSpec(method="shield")},
        ),
    )
    summaries = {
        "ssrl_5x5": summary([7, 7, 8, 6]),
        "shield_5x5_L0": summary([10, 12]),
        "shield_5x5_L1": summary([14, 16]),
    }
    folder = write_metrics(tmp_path / "m", exp, summaries)
    files = sorted(p.name for p in folder.iterdir())
    assert files == ["shield_5x5.json", "ssrl_5x5.json"]
    shield = json.loads((folder / "shield_5x5.json").read_text())
    assert tuple(shield) == KEYS and shield["collisions"] == 13.0 and shield["converged"] == 0.5
    assert shield["ci_lower"] <= 13.0 <= shield["ci_upper"]
    assert json.loads((folder / "ssrl_5x5.json").read_text())["collisions"] == 7.0
    # sets that share a size (the repetition experiment) are told apart by their obstacles
    exp.layouts.sizes.append(LayoutSet(size="5x5", obstacles=4, count=1, seed=10, unique=False))
    summaries["shield_5x5_L10"] = summary([1, 3])
    files = sorted(p.name for p in write_metrics(tmp_path / "n", exp, summaries).iterdir())
    assert files == ["shield_5x5_4obstacles.json", "shield_5x5_9obstacles.json", "ssrl_5x5.json"]


def test_the_index_of_a_folder_lists_every_file_with_its_hash(tmp_path):
    import hashlib
    import json

    from pipeline.files import write_index

    (tmp_path / "d" / "sub").mkdir(parents=True)
    (tmp_path / "d" / "a.txt").write_text("a")
    (tmp_path / "d" / "sub" / "b.bin").write_bytes(b"\0\1")
    (tmp_path / "d" / ".lock").write_text("hidden")
    index = json.loads(write_index(tmp_path / "d", tmp_path / "i.json").read_text())
    assert index["files"] == {
        "a.txt": hashlib.sha256(b"a").hexdigest(),
        "sub/b.bin": hashlib.sha256(b"\0\1").hexdigest(),
    }
