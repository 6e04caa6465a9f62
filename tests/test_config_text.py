"""The recorded config's text from per-key pieces (pipeline/records/config_text.py) is the text of
the whole config, and a cell's recorded config (its shared pieces kept across the cells of a
study) is the text of its own whole config."""

import json
from dataclasses import replace
from pathlib import Path

import pytest
import yaml
from omegaconf import OmegaConf

from pipeline.cells.plan import experiment_cells
from pipeline.cells.run import NOT_RECORDED, CellRun, recorded_config
from pipeline.config.compose import load_config
from pipeline.records.config_text import ConfigText, config_text, joined, pieces, to_json
from pipeline.world.maze import load_layout


def whole_text(config) -> ConfigText:
    """The texts as the writer made them from the whole config in one dump."""
    parsed = json.loads(to_json(config))
    return ConfigText(yaml.dump(parsed, Dumper=yaml.CSafeDumper, sort_keys=True), to_json(parsed))


ODD = {
    "maze": "a maze: with 'quotes', a # and unicode é",
    "long": "x " * 80,
    "looks_like": ["yes", "null", "1e3", "011", ""],
    "nested": {"b": {"c": [1, 2.5, None, True]}, "a": []},
    "empty": {},
}


@pytest.mark.parametrize("config", [ODD, {}, {"one": 1}], ids=["odd values", "empty", "one key"])
def test_the_pieces_joined_are_the_whole_text(config):
    assert config_text(config) == whole_text(config)
    assert joined(pieces(config)) == whole_text(config)


def test_a_trials_config_and_a_changed_key():
    cfg = OmegaConf.to_container(OmegaConf.structured(load_config("trials")), resolve=True)
    parts = pieces(cfg)
    assert joined(parts) == whole_text(cfg)
    changed = {**cfg, "maze": "layouts/gen_07x07_013.txt"}
    assert joined(parts | pieces({"maze": changed["maze"]})) == whole_text(changed)


def test_every_cell_of_the_generalisation_study_records_its_own_whole_config():
    overrides = ["+experiment=generalisation", "profile=smoke"]
    cfg = load_config("trials", overrides)
    for name, cell in list(experiment_cells(cfg, overrides).items())[:12]:
        run = CellRun(name, cell, load_layout(cell.maze))
        whole = OmegaConf.to_container(OmegaConf.structured(cell), resolve=True)
        expected = whole_text({k: v for k, v in whole.items() if k not in NOT_RECORDED})
        assert recorded_config(run) == expected
        assert recorded_config(replace(run, config=replace(cell, maze="5x5"))).json != expected.json


EXPERIMENTS = sorted(p.stem for p in Path("conf/experiment").glob("*.yaml"))


@pytest.mark.parametrize("experiment", EXPERIMENTS)
def test_a_cell_records_what_omegaconf_renders_of_its_config(experiment):
    """The recorded config is read from the cell's dataclass directly, not through OmegaConf:
    the same text, for the first cells and the last of every experiment (pinned recognisers,
    worlds, support modes and rules come last)."""
    overrides = [f"+experiment={experiment}", "profile=smoke"]
    cells = list(experiment_cells(load_config("trials", overrides), overrides).items())
    for name, cell in cells[:6] + cells[-3:]:
        whole = OmegaConf.to_container(OmegaConf.structured(cell), resolve=True)
        expected = whole_text({k: v for k, v in whole.items() if k not in NOT_RECORDED})
        assert recorded_config(CellRun(name, cell, load_layout(cell.maze))) == expected, name
