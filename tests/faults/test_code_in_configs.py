"""Configs that name code to run. A config names code only through a recogniser's ``_target_``,
and only one a recogniser of ``conf/recogniser/`` declares: every other target, from any
place a config comes from (the command line, an experiment's cell, the accuracy stage,
``gymnasium.make``'s options), is one clear error naming the key, before anything is imported or
called (Hydra's own blocklist stays behind it as a second line)."""

import sys

import pytest

from pipeline.config.recognisers import declared_targets
from pipeline.envs import make_recogniser
from pipeline.errors import UserError
from pipeline.stages import run_stage

CANARY = "tests.faults._canary"
HOSTILE = [
    "os.system",
    "builtins.print",
    "builtins.eval",
    "builtins.exec",
    "subprocess.run",
    "shutil.rmtree",
    "hydra.utils.instantiate",
    "hydra.utils.call",
    "importlib.import_module",
    "pipeline.files.write_atomic",  # the project's code, but not a recogniser
    "pipeline.rl.oracle",  # a module, not the class
    "pipeline.rl.oracle.OracleRecogniser.__init__",
    f"{CANARY}.boom",
]


@pytest.fixture(autouse=True)
def no_canary():
    sys.modules.pop(CANARY, None)
    yield
    assert CANARY not in sys.modules, "a refused _target_ was imported"


def refused(excinfo, key: str, target: str) -> None:
    message = str(excinfo.value)
    assert "\n" not in message
    assert message.startswith(f"config key '{key}._target_': {target!r} is not a recogniser")


@pytest.mark.parametrize("target", HOSTILE)
@pytest.mark.parametrize("how", ["++recogniser._target_", "recogniser._target_"])
def test_a_command_line_target_is_refused(target, how, tmp_path):
    out = tmp_path / "out"
    with pytest.raises(UserError) as excinfo:
        run_stage("trials", ["method=fewshot", f"{how}={target}", f"out={out}"])
    refused(excinfo, "recogniser", target)
    assert not out.exists()


@pytest.mark.parametrize("target", HOSTILE)
def test_an_experiment_cells_target_is_refused(target, tmp_path):
    key = "experiment.cells.fewshot.recogniser"
    with pytest.raises(UserError) as excinfo:
        run_stage(
            "trials",
            ["+experiment=fig8", "profile=smoke", f"++{key}._target_={target}", f"out={tmp_path}"],
        )
    refused(excinfo, key, target)


@pytest.mark.parametrize("target", HOSTILE)
def test_the_accuracy_stages_target_is_refused(target, tmp_path):
    with pytest.raises(UserError) as excinfo:
        run_stage("accuracy", [f"++recogniser._target_={target}", f"out_dir={tmp_path}/acc"])
    refused(excinfo, "recogniser", target)
    assert not (tmp_path / "acc").exists()


@pytest.mark.parametrize("target", HOSTILE)
def test_gymnasiums_recogniser_options_cannot_name_code(target):
    with pytest.raises(ValueError) as excinfo:
        make_recogniser("oracle", {"_target_": target})
    refused(excinfo, "recogniser", target)


def test_the_declared_recognisers_are_the_allow_list():
    assert declared_targets() == {
        "pipeline.rl.fixed_accuracy.FixedAccuracyRecogniser": "fixed_accuracy",
        "pipeline.rl.oracle.OracleRecogniser": "oracle",
        "pipeline.fewshot.paper_tables.PaperTablesRecogniser": "paper_tables",
        "pipeline.fewshot.recogniser.ProtoRecogniser.from_files": "protonet",
        "pipeline.fewshot.recogniser.RelationRecogniser.from_files": "relation_net",
    }


def test_a_declared_target_given_again_is_accepted(tmp_path):
    """Naming a declared recogniser's own ``_target_`` is not naming other code."""
    result = run_stage(
        "trials",
        [
            "method=fewshot",
            "recogniser=oracle",
            "recogniser._target_=pipeline.rl.oracle.OracleRecogniser",
            "runs=1",
            "episodes=2",
            "record=none",
            "progress=false",
            f"out={tmp_path}/out",
        ],
    )
    assert len(result["runs"]) == 1
