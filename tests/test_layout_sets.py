"""experiment.layouts: cell templates crossed with sets of generated layouts
(pipeline/world/layout_sets.py), as the schema and the trials stage apply it, and the stage's
``workers`` giving the same bytes as one process."""

import hashlib
import multiprocessing

import pytest
from omegaconf import OmegaConf
from omegaconf.errors import ConfigKeyError

from pipeline.cells.plan import experiment_cells
from pipeline.config.compose import load_config
from pipeline.errors import ConfigError
from pipeline.schemas.experiment import Cell, Experiment, Layouts, LayoutSet
from pipeline.stages import run_stage
from pipeline.world.layout_sets import GeneratedCell, LayoutSetError, expand, layout_mazes
from pipeline.world.maze import load_layout


def test_expand_names_and_mazes_exactly():
    cells = expand(
        [
            {"size": "5x5", "obstacles": 9, "count": 2, "seed": 3, "unique": True},
            {"size": "7x7", "obstacles": 16, "count": 1, "seed": 0, "unique": False},
        ],
        ["ssrl", "fewshot"],
    )
    assert cells == {
        "ssrl_5x5_L3": GeneratedCell("ssrl", 0, 0, "random:5x5:9:3:unique"),
        "fewshot_5x5_L3": GeneratedCell("fewshot", 0, 0, "random:5x5:9:3:unique"),
        "ssrl_5x5_L4": GeneratedCell("ssrl", 0, 1, "random:5x5:9:4:unique"),
        "fewshot_5x5_L4": GeneratedCell("fewshot", 0, 1, "random:5x5:9:4:unique"),
        "ssrl_7x7_L0": GeneratedCell("ssrl", 1, 0, "random:7x7:16:0"),
        "fewshot_7x7_L0": GeneratedCell("fewshot", 1, 0, "random:7x7:16:0"),
    }
    assert list(cells) == [
        "ssrl_5x5_L3",
        "fewshot_5x5_L3",
        "ssrl_5x5_L4",
        "fewshot_5x5_L4",
        "ssrl_7x7_L0",
        "fewshot_7x7_L0",
    ]


@pytest.mark.parametrize(
    "entry,key",
    [
        ({"size": "5by5", "obstacles": 9, "count": 2}, "0.size"),
        ({"size": "5x5", "obstacles": 17, "count": 2}, "0.obstacles"),
        ({"size": "0x5", "obstacles": 0, "count": 2}, "0.size"),
        ({"size": "5x5", "obstacles": 9, "count": 0}, "0.count"),
    ],
)
def test_a_bad_set_is_refused_naming_its_key(entry, key):
    with pytest.raises(LayoutSetError) as caught:
        expand([entry], ["ssrl"])
    assert caught.value.key == key


def test_two_sets_of_one_size_need_seeds_that_do_not_overlap():
    with pytest.raises(LayoutSetError, match="overlap set 0") as caught:
        expand(
            [
                {"size": "5x5", "obstacles": 9, "count": 3},
                {"size": "5x5", "obstacles": 8, "count": 1, "seed": 2},
            ],
            ["a"],
        )
    assert caught.value.key == "1.seed"
    cells = expand(
        [
            {"size": "11x11", "obstacles": 20, "count": 2, "seed": 1000},
            {"size": "11x11", "obstacles": 30, "count": 1, "seed": 2000},
        ],
        ["a"],
    )
    assert {n: c.maze for n, c in cells.items()} == {
        "a_11x11_L1000": "random:11x11:20:1000:unique",
        "a_11x11_L1001": "random:11x11:20:1001:unique",
        "a_11x11_L2000": "random:11x11:30:2000:unique",
    }


def test_the_papers_sizes_generate_unique_layouts():
    """The paper's obstacle counts admit the paper's kind of layout (a single shortest path lined by
    obstacles) for the first layouts of each size, 11x11/49 included."""
    for size, obstacles in (("5x5", 9), ("7x7", 16), ("11x11", 49)):
        for maze in layout_mazes(size, obstacles, 5):
            layout = load_layout(maze)
            assert len(layout.obstacles) == obstacles and layout.name == maze


def test_a_layout_set_has_no_unknown_keys():
    with pytest.raises(ConfigKeyError):
        OmegaConf.merge(
            OmegaConf.structured(LayoutSet),
            {"size": "5x5", "obstacles": 9, "count": 1, "colour": "red"},
        )


def test_the_experiment_expands_over_the_profile():
    cfg = load_config("trials", ["+experiment=generalisation", "profile=smoke"])
    cells = experiment_cells(cfg, ["+experiment=generalisation", "profile=smoke"])
    assert len(cells) == 3 * 2 * 7  # sizes x smoke layouts x methods
    assert cells["fewshot_dss_11x11_L1"].maze == "random:11x11:49:1:unique"
    assert (
        cells["fewshot_dss_11x11_L1"].method.name == "fewshot_dss"
        and cells["sarsa_5x5_L0"].runs == 3
    )
    paper = load_config("trials", ["+experiment=generalisation"])
    assert len(paper.experiment.all_cells()) == 2100 and paper.runs == 20 and paper.episodes == 500


@pytest.mark.parametrize(
    "override,message",
    [
        (
            "experiment.layouts.sizes.0.obstacles=99",
            "config key 'experiment.layouts.sizes.0.obstacles': .*too many",
        ),
        ("experiment.layouts.sizes.1.size=7y7", "config key 'experiment.layouts.sizes.1.size'"),
        ("experiment.layouts.sizes.2.count=0", "config key 'experiment.layouts.sizes.2.count'"),
        (
            "+experiment.layouts.cells.ssrl.maze=5x5",
            "config key 'experiment.layouts.cells.ssrl.maze'",
        ),
        ("workers=0", "config key 'workers'"),
    ],
)
def test_a_bad_entry_is_refused_with_one_line_naming_the_key(tmp_path, override, message):
    with pytest.raises(ConfigError, match=message) as caught:
        run_stage(
            "trials",
            [
                "+experiment=generalisation",
                "profile=smoke",
                override,
                f"out={tmp_path}",
                "progress=false",
            ],
        )
    assert "\n" not in str(caught.value)
    assert not list(tmp_path.iterdir())


def test_a_listed_cell_with_a_generated_name_is_refused():
    exp = Experiment(
        "e",
        cells={"ssrl_5x5_L0": Cell("ssrl", maze="5x5")},
        layouts=Layouts([LayoutSet("5x5", 9, 1)], {"ssrl": Cell("ssrl")}),
    )
    with pytest.raises(
        ConfigError, match="config key 'experiment.cells.ssrl_5x5_L0': the layout sets generate"
    ):
        exp.all_cells()
    exp.cells = {"ssrl_paper": Cell("ssrl", maze="5x5")}
    assert list(exp.all_cells()) == ["ssrl_paper", "ssrl_5x5_L0"]


def digest(folder):
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def test_workers_give_the_same_bytes_as_one_process(tmp_path):
    """The cells of one layout set in two processes and in one: every file the same bytes (the
    recorded config leaves ``workers`` out; both runs write to the same ``out``)."""
    args = [
        "+experiment=generalisation",
        "profile=smoke",
        "profile.trials.layouts=1",
        "episodes=8",
        "recogniser=fixed_accuracy",
        "recogniser.p=0.5",
        "progress=false",
        f"out={tmp_path / 'out'}",
    ]
    run_stage("trials", [*args, "workers=1"])
    one = digest(tmp_path / "out")
    (tmp_path / "out").rename(tmp_path / "one")
    run_stage("trials", [*args, "workers=2"])
    assert digest(tmp_path / "out") == one and len(one) == 3 * 7 * 2 + 1
    # the idle workers are ended when the stage returns (not left to wind down on their own)
    assert multiprocessing.active_children() == []
