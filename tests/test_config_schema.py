"""The typed schema: every stage composes; wrong types, unknown keys and out-of-range values are
refused naming the key (one line, exit 2 on the command line); experiments honour the command line
or refuse it; the recorded config is the config that ran."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest
import yaml
from entry import cli
from fakes import FIG8_WITHOUT_MODELS

from pipeline.cells.plan import experiment_cells
from pipeline.config.compose import load_config
from pipeline.config.recognisers import recogniser_names
from pipeline.config.registry import schemas
from pipeline.errors import ConfigError
from pipeline.rl.fixed_accuracy import FixedAccuracyRecogniser
from pipeline.rl.methods import METHOD_DIR, MethodSpec, get_method, method_names
from pipeline.rl.oracle import TRUE_CATEGORY
from pipeline.stages import run_stage

SCHEMAS = schemas()  # every stage's schema class

ROOT = Path(__file__).resolve().parents[1]
SMOKE = ["profile=smoke", "progress=false"]


@pytest.mark.parametrize("stage", sorted(SCHEMAS))
@pytest.mark.parametrize("profile", ["paper", "smoke"])
def test_every_stage_composes_to_its_schema(stage, profile):
    """``replay`` and ``report`` have no profile (the report reads the scale from the records)."""
    extra = {"replay": ["file=x.mcap"], "report": []}.get(stage, [f"profile={profile}"])
    cfg = load_config(stage, extra)
    assert isinstance(cfg, SCHEMAS[stage])


def test_the_report_refuses_a_profile():
    from pipeline.errors import ConfigError

    with pytest.raises(ConfigError, match="profile"):
        load_config("report", ["profile=smoke"])


@pytest.mark.parametrize(
    "override,key,problem",
    [
        ("runs=2.7", "runs", "could not be converted to Integer"),
        ("record=maybe", "record", "must be one of steps, episodes, none; got 'maybe'"),
        (
            "record=false",
            "record",
            "must be one of steps, episodes, none",
        ),  # the old boolean key: refused
        ("episodes=abc", "episodes", "could not be converted to Integer"),
        ("method.alpha=abc", "method.alpha", "could not be converted to Float"),
        ("method.alpha=1.5", "method.alpha", "must be <= 1.0"),
        ("method.safety=wall", "method.safety", "must be one of none, shield, ssrl, fewshot"),
        ("runs=0", "runs", "must be >= 1"),
        ("threads=-1", "threads", "must be >= 0"),
        ("seed=-1", "seed", "must be >= 0"),
        ("substitution=7", "substitution", "must be one of 1, 2, 3, 4"),
        ("support=sometimes", "support", "must be one of restore, carry"),
        ("out=", "out", "must not be empty"),
        ("flush_every=0", "flush_every", "must be >= 1"),
        ("bogus=1", "bogus", "not in 'TrialsConfig'"),
        ("+bogus=1", "bogus", ""),
        ("profile.trials.runs=x", "profile.trials.runs", "could not be converted to Integer"),
    ],
)
def test_trials_refuses_bad_values_naming_the_key(override, key, problem):
    with pytest.raises(ConfigError) as err:
        load_config("trials", [override])
    message = str(err.value)
    assert f"'{key}'" in message and problem in message and "\n" not in message


@pytest.mark.parametrize(
    "stage,override,key",
    [
        ("render", "size=-5", "size"),
        ("render", "quality.supersample=zero", "quality.supersample"),
        ("render", "catalogue.fill=2", "catalogue.fill"),
        ("meta_train", "train.lr=-1", "train.lr"),
        ("meta_train", "threads=0", "threads"),
        ("accuracy", "study.repeats=0", "study.repeats"),
        ("replay", "viewer=tv", "viewer"),
        ("replay", "web_port=70000", "web_port"),
        ("report", "out=", "out"),
    ],
)
def test_other_stages_refuse_bad_values_naming_the_key(stage, override, key):
    extra = ["file=x.mcap"] if stage == "replay" else []
    with pytest.raises(ConfigError, match=f"config key '{key}'"):
        load_config(stage, [*extra, override])


@pytest.mark.parametrize(
    "stage,args,key",
    [
        ("trials", ["runs=2.7"], "runs"),
        ("trials", ["method=nope"], "method/nope"),
        ("render", ["size=abc"], "size"),
        ("meta_train", ["train.episodes=-1"], "train.episodes"),
        ("accuracy", ["study.repeats=abc"], "study.repeats"),
        ("report", ["bogus=1"], "bogus"),
        ("replay", ["run=-1", "file=x.mcap"], "run"),
    ],
)
def test_command_line_errors_are_one_line_exit_2(stage, args, key):
    out = cli(stage, *args)
    assert out.returncode == 2, out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and key in lines[0], out.stderr


def test_method_files_hold_only_what_differs_from_the_base():
    base = MethodSpec()
    names = {f.name for f in fields(MethodSpec)}
    for path in sorted(METHOD_DIR.glob("*.yaml")):
        data = yaml.safe_load(path.read_text())
        assert set(data) <= names, path
        assert data["name"] == path.stem
        for key, value in data.items():
            if key != "name":
                assert getattr(base, key) != value, f"{path.name}: {key} repeats the base value"


def test_methods_load_as_the_paper_defines_them():
    assert get_method("ssrl").safety == "ssrl" and get_method("ssrl").recovery
    assert get_method("sarsa").learner == "sarsa" and not get_method("sarsa").recovery
    assert get_method("fewshot_dss").dynamic_support and get_method("fewshot_dss").uses_recogniser
    assert {get_method(n).alpha for n in method_names()} == {0.01}
    with pytest.raises(ConfigError, match="config key 'method.alpha'"):
        get_method("ssrl", alpha=3.0)


def test_experiment_overrides_apply_to_every_cell(tmp_path):
    index = run_stage(
        "trials",
        [
            "+experiment=fig8",
            "method.alpha=0.5",
            "recogniser=oracle",
            f"out={tmp_path}",
            "runs=2",
            "episodes=5",
            *SMOKE,
            *FIG8_WITHOUT_MODELS,
        ],
    )
    assert set(index["cells"]) == {
        "qlearning",
        "shield",
        "ssrl",
        "fewshot",
        "fewshot_dss",
        "fewshot_protonet",
        "fewshot_dss_protonet",
        "fewshot_paper",
        "fewshot_dss_paper",
    }  # the protonet and paper_tables cells keep their own recogniser
    from pipeline.records import read_records

    for cell in index["cells"]:
        summary = json.loads((tmp_path / cell / "summary.json").read_text())
        method = cell.removesuffix("_protonet").removesuffix("_paper")
        assert summary["method_spec"]["alpha"] == 0.5 and summary["method"] == method
        config = read_records(tmp_path / cell / "records.mcap", pictures=False).meta.config
        assert (
            config["method"]["alpha"] == 0.5 and config["method"]["name"] == method
        )  # the config that ran
        assert config["runs"] == 2 and config["maze"] == "5x5"


def test_experiment_globals_yield_to_the_command_line():
    cells = experiment_cells(
        load_config("trials", ["+experiment=fig8", "maze=7x7"]), ["+experiment=fig8", "maze=7x7"]
    )
    assert {c.maze for c in cells.values()} == {"7x7"}


@pytest.mark.parametrize(
    "overrides,key",
    [
        (["method=ssrl"], "method"),
        (["substitution=2"], "substitution"),  # fig9's cells are the four ways
    ],
)
def test_overrides_no_cell_can_take_are_refused(overrides, key):
    args = ["+experiment=fig9", *overrides]
    with pytest.raises(ConfigError, match=f"config key '{key}'"):
        experiment_cells(load_config("trials", args), args)


def test_a_cell_keeps_what_it_pins():
    args = ["+experiment=fig9", "method.alpha=0.5", "method.gamma=0.8"]
    cfg = load_config("trials", args)
    cfg.experiment.cells["way1"].params = {"alpha": 0.2}
    cells = experiment_cells(cfg, args)
    assert cells["way1"].method.alpha == 0.2 and cells["way2"].method.alpha == 0.5
    assert {c.method.gamma for c in cells.values()} == {0.8}
    assert [c.substitution for c in cells.values()] == [1, 2, 3, 4] * 2  # RN, then paper_tables
    only = load_config("trials", args)
    only.experiment.cells = {"way1": only.experiment.cells["way1"]}
    only.experiment.cells["way1"].params = {"alpha": 0.2}
    with pytest.raises(ConfigError, match="config key 'method.alpha'.*every cell"):
        experiment_cells(only, args)


def test_fixed_accuracy_recogniser_is_seeded_and_has_its_accuracy():
    rec = FixedAccuracyRecogniser(p=0.7)
    hits = []
    for run in range(400):
        rec.start_run(run, seed=run)
        hits.append((rec.predictions(run) == TRUE_CATEGORY).mean())
    assert abs(np.mean(hits) - 0.7) < 0.02
    again = FixedAccuracyRecogniser(p=0.7)
    again.start_run(5, seed=5)
    assert (again.predictions(5) == rec.predictions(5)).all()
    wrong = np.flatnonzero(rec.predictions(5) != TRUE_CATEGORY)[0]
    rec.learn_from_collision(5, int(wrong), int(TRUE_CATEGORY[wrong]))
    assert rec.predictions(5)[wrong] == TRUE_CATEGORY[wrong]
    zero = FixedAccuracyRecogniser(p=0.0)
    zero.start_run(0, seed=1)
    assert not (zero.predictions(0) == TRUE_CATEGORY).any()


def test_recognisers_are_chosen_by_name(tmp_path):
    perfect = run_stage(
        "trials",
        [
            "method=fewshot",
            "recogniser=fixed_accuracy",
            "recogniser.p=1.0",
            "record=none",
            f"out={tmp_path / 'a'}",
            *SMOKE,
        ],
    )
    oracle = run_stage(
        "trials",
        ["method=fewshot", "recogniser=oracle", "record=none", f"out={tmp_path / 'b'}", *SMOKE],
    )
    assert perfect["runs"] == oracle["runs"] and perfect["collisions"]["mean"] == 0
    blind = run_stage(
        "trials",
        [
            "method=fewshot",
            "recogniser=fixed_accuracy",
            "recogniser.p=0.0",
            "record=none",
            f"out={tmp_path / 'c'}",
            *SMOKE,
        ],
    )
    assert blind["collisions"]["mean"] > 0
    with pytest.raises(ConfigError, match="config key 'recogniser.p'"):
        run_stage(
            "trials", ["recogniser=fixed_accuracy", "recogniser.p=abc", "method=fewshot", *SMOKE]
        )
    with pytest.raises(
        ConfigError, match=r"config key 'recogniser': p must lie in \[0, 1\], got 1.5"
    ):
        run_stage(
            "trials", ["recogniser=fixed_accuracy", "recogniser.p=1.5", "method=fewshot", *SMOKE]
        )


def test_accuracy_study_takes_any_recogniser(tmp_path):
    """The study runs with a recogniser that has no support positions: a perfect one scores 100%
    throughout, and one at p=0 gains exactly the substituted pictures it learns."""
    perfect = run_stage(
        "accuracy",
        [
            "recogniser=fixed_accuracy",
            "recogniser.p=1.0",
            "study.repeats=3",
            f"out_dir={tmp_path / 'a'}",
            *SMOKE,
        ],
    )
    assert perfect["baseline"]["accuracy"] == 1.0
    assert {v["mean_accuracy"] for v in perfect["table2"].values()} == {1.0}
    blind = run_stage(
        "accuracy",
        [
            "recogniser=fixed_accuracy",
            "recogniser.p=0.0",
            "study.repeats=3",
            f"out_dir={tmp_path / 'b'}",
            *SMOKE,
        ],
    )
    table2 = blind["table2"]
    assert blind["baseline"]["accuracy"] == 0.0
    assert [round(table2[str(n)]["mean_accuracy"] * 40) for n in range(6)] == [0, 1, 2, 3, 4, 5]
    assert {table2[str(n)]["mean_accuracy_no_same"] for n in range(6)} == {0.0}


def test_a_bad_sweep_value_is_refused_before_any_job(tmp_path):
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "pipeline",
            "trials",
            "-m",
            "runs=2,2.7",
            f"out={tmp_path}/o",
            f"hydra.sweep.dir={tmp_path}/sweep",
            "episodes=2",
            "record=none",
            "progress=false",
        ],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert (
        out.returncode == 2
        and out.stderr.strip()
        == "error: config key 'runs': Value '2.7' of type 'float' could not be converted to Integer"
    )
    assert not (tmp_path / "o").exists() and not (tmp_path / "sweep").exists()


@pytest.mark.parametrize(
    "args,key",
    [
        (["method=ssrl", "recogniser=fixed_accuracy"], "recogniser"),
        (["method=ssrl", "recogniser.checkpoint=x.pt"], "recogniser.checkpoint"),
        (["method=shield", "support=carry"], "support"),
        (["method=fewshot", "substitution=2"], "substitution"),
        (
            [
                "+experiment=table3",
                "method.alpha=0.5",
                "recogniser=oracle",
                "substitution=3",
                "method=qlearning",
            ],
            "method",
        ),
    ],
)
def test_overrides_that_no_cell_reads_are_refused(args, key, tmp_path):
    with pytest.raises(ConfigError, match=f"config key '{key}'.*cannot apply"):
        run_stage("trials", [*args, f"out={tmp_path}", *SMOKE])
    assert not list(tmp_path.iterdir())


def test_a_cell_pins_recogniser_arguments_and_its_records_say_so(tmp_path):
    """``experiment.cells.<name>.recogniser`` ({p: ...}) is applied to that cell only, over the top
    level's recogniser, and the records hold the config that ran."""
    from pipeline.records import read_records
    from pipeline.schemas.experiment import Cell
    from pipeline.stages.trials import run

    args = [
        "+experiment=fig8",
        "recogniser=fixed_accuracy",
        "recogniser.learn=false",
        f"out={tmp_path}",
        *SMOKE,
    ]
    cfg = load_config("trials", args)
    cfg.experiment.cells = {
        "blind": Cell(method="fewshot", recogniser={"p": 0.0}),
        "perfect": Cell(method="fewshot", recogniser={"p": 1.0}),
        "top": Cell(method="fewshot"),
        "ssrl": Cell(method="ssrl"),
    }
    cfg.experiment.report = None
    index = run(cfg, args)
    collisions = {name: cell["collisions"]["mean"] for name, cell in index["cells"].items()}
    assert collisions["perfect"] == 0 and collisions["blind"] > collisions["top"] > 0
    for name, p in (
        ("blind", 0.0),
        ("perfect", 1.0),
        ("top", 0.5),
    ):  # top: conf/recogniser/fixed_accuracy.yaml's
        config = read_records(tmp_path / name / "records.mcap", pictures=False).meta.config
        assert config["recogniser"]["p"] == p and config["recogniser"]["learn"] is False


@pytest.mark.parametrize(
    "cells,args,message",
    [
        (
            {"s": {"method": "ssrl", "recogniser": {"p": 0.3}}},
            [],
            r"config key 'experiment.cells.s.recogniser': method ssrl recognises no pictures",
        ),
        (
            {"a": {"method": "fewshot", "recogniser": {"p": 0.3}}, "s": {"method": "ssrl"}},
            ["recogniser.p=0.4"],
            r"config key 'recogniser.p': every cell of experiment fig8 with a recogniser pins it",
        ),
        (
            {"a": {"method": "fewshot", "recogniser": {"q": 0.3}}},
            [],
            r"config key 'experiment.cells.a.recogniser.q': .*parameters of .*FixedAccuracyRecogniser: p, learn",
        ),
        (
            {"a": {"method": "fewshot", "recogniser": {"p": 1.5}}},
            [],
            r"config key 'experiment.cells.a.recogniser': p must lie in \[0, 1\], got 1.5",
        ),
        (
            {"s": {"method": "ssrl", "recogniser_group": "protonet"}},
            [],
            r"config key 'experiment.cells.s.recogniser_group': method ssrl recognises no pictures",
        ),
        (
            {"a": {"method": "fewshot", "recogniser_group": "nope"}, "b": {"method": "fewshot"}},
            [],
            r"config key 'experiment.cells.a.recogniser_group': no recogniser 'nope' "
            + re.escape(f"(conf/recogniser/: {', '.join(recogniser_names())})"),
        ),
        (
            {"a": {"method": "fewshot", "recogniser_group": "oracle"}, "s": {"method": "ssrl"}},
            ["recogniser.p=0.4"],
            r"config key 'recogniser(.p)?': every cell of experiment fig8 with a recogniser pins it .* or runs its own",
        ),
        (
            {
                "a": {
                    "method": "fewshot",
                    "recogniser_group": "protonet",
                    "recogniser": {"relation_padding": 1},
                },
                "b": {"method": "fewshot"},
            },
            [],
            r"config key 'experiment.cells.a.recogniser.relation_padding'",
        ),
    ],
)
def test_recogniser_pins_that_cannot_apply_are_refused(cells, args, message):
    from pipeline.schemas.experiment import Cell
    from pipeline.stages.trials import resolve_cells

    args = ["+experiment=fig8", "recogniser=fixed_accuracy", *args, *SMOKE]
    cfg = load_config("trials", args)
    cfg.experiment.cells = {name: Cell(**cell) for name, cell in cells.items()}
    cfg.experiment.report = None
    with pytest.raises(ConfigError, match=message):
        resolve_cells(cfg, args)


def test_a_cell_can_run_its_own_recogniser_group():
    """fig8's protonet cells run conf/recogniser/protonet.yaml whatever the top level
    chooses; their own pins (from the experiment file or the command line) apply over it."""
    args = [
        "+experiment=fig8",
        "recogniser=oracle",
        "+experiment.cells.fewshot_dss_protonet.recogniser.checkpoint=x.pt",
    ]
    cells = experiment_cells(load_config("trials", args), args)
    proto = "pipeline.fewshot.recogniser.ProtoRecogniser.from_files"
    assert cells["fewshot_protonet"].recogniser == {
        "_target_": proto,
        "checkpoint": "datasets/models/protonet.pt",
        "images_dir": "datasets/images",
        "input_size": 48,
        "query_hue_shift": 0.0,
    }
    assert cells["fewshot_dss_protonet"].recogniser["checkpoint"] == "x.pt"
    assert cells["fewshot_dss"].recogniser == {"_target_": "pipeline.rl.oracle.OracleRecogniser"}
    assert (
        cells["fewshot_dss_protonet"].method.dynamic_support
        and not cells["fewshot_protonet"].method.dynamic_support
    )


def test_accuracy_curve_pins_each_cells_accuracy():
    args = ["+experiment=accuracy_curve", *SMOKE]
    cells = experiment_cells(load_config("trials", args), args)
    assert len(cells) == 60
    assert (
        cells["fewshot_dss_11x11_p30"].recogniser["p"] == 0.3
        and cells["fewshot_5x5_p100"].recogniser["p"] == 1.0
    )
    assert {c.recogniser["_target_"] for c in cells.values()} == {
        "pipeline.rl.fixed_accuracy.FixedAccuracyRecogniser"
    }
    assert {(c.method.name, c.maze) for n, c in cells.items() if not c.method.uses_recogniser} == {
        (m, z) for m in ("shield", "ssrl") for z in ("5x5", "7x7", "11x11")
    }
    with pytest.raises(ConfigError, match="config key 'recogniser.p': every cell"):
        experiment_cells(
            load_config("trials", [*args, "recogniser.p=0.5"]), [*args, "recogniser.p=0.5"]
        )
