"""The schema describes itself: every key of every stage carries a description on its field, and
``python -m pipeline <stage> --help`` lists that stage's groups and keys from the declarations."""

from __future__ import annotations

import dataclasses
import re
import subprocess
import sys
import typing

import pytest

from pipeline.config.compose import CONF_DIR
from pipeline.config.fields import constraint, field_docs, setting
from pipeline.config.help import StageHelp, describe, nested, stage_help
from pipeline.config.registry import schemas

SCHEMAS = schemas()  # every stage's schema class


def schema_classes() -> list[type]:
    """Every dataclass a stage's config is made of (the stages', their groups', their blocks')."""
    found: list[type] = []

    def walk(cls: type) -> None:
        if cls in found:
            return
        found.append(cls)
        for hint in typing.get_type_hints(cls).values():
            for arg in (hint, *typing.get_args(hint)):
                for inner in (arg, *typing.get_args(arg)):
                    if dataclasses.is_dataclass(inner):
                        walk(inner)

    for schema in SCHEMAS.values():
        walk(schema)
    return found


def test_every_key_of_every_stage_has_a_description():
    classes = schema_classes()
    assert {"TrialsConfig", "MethodSpec", "TrainConfig", "StudyConfig", "ReportSpec", "Cell"} <= {
        c.__name__ for c in classes
    }
    missing = [
        f"{cls.__module__}.{cls.__name__}.{f.name}"
        for cls in classes
        for f in dataclasses.fields(cls)
        if not field_docs(cls).get(f.name, "").strip()
    ]
    assert not missing, f"fields without a description (a string under the field): {missing}"


def test_a_description_is_the_string_under_its_field_folded_to_one_line():
    @dataclasses.dataclass
    class Example:
        a: int = setting(1, ge=0)
        """First line,
        second line."""
        b: str = "x"
        c: float = setting(0.5, gt=0, le=1)
        """Only c."""

    assert field_docs(Example) == {"a": "First line, second line.", "c": "Only c."}
    a, b, c = dataclasses.fields(Example)
    assert (constraint(a), constraint(b), constraint(c)) == (">= 0", "", "> 0, <= 1")


@pytest.mark.parametrize(
    "kw,words",
    [
        ({"choices": ("x", "y")}, "one of x, y"),
        ({"nonempty": True}, "not empty"),
        ({"ge": 0, "le": 65535}, ">= 0, <= 65535"),
    ],
)
def test_a_constraint_reads_as_the_refusal_does(kw, words):
    @dataclasses.dataclass
    class Example:
        a: typing.Any = setting(None, **kw)

    assert constraint(dataclasses.fields(Example)[0]) == words


def leaf_keys(cls: type, prefix: str = "", sections: frozenset[str] = frozenset()) -> list[str]:
    """Every key of ``cls`` as the help spells it (``<name>``/``<i>`` for mapping and list items)."""
    keys = []
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        if cls.__name__ == "Profile" and f.name not in sections:
            continue
        inner, step = nested(hints[f.name])
        if inner is None:
            keys.append(prefix + f.name)
        else:
            keys += leaf_keys(inner, f"{prefix}{f.name}.{step}", sections)
    return keys


READS = {  # stage -> (its groups, the profile sections it reads)
    "trials": (["profile", "method", "recogniser", "experiment"], {"trials"}),
    "render": (["profile"], {"render"}),
    "meta_train": (["profile", "data", "model"], {"meta_train"}),
    "accuracy": (["profile", "recogniser"], {"accuracy"}),
    "report": ([], set()),  # the scale comes from the records (pipeline/report/scale.py)
    "replay": ([], set()),
}


@pytest.mark.parametrize("stage", sorted(SCHEMAS))
def test_a_stage_help_lists_its_own_groups_and_every_key_with_its_description(stage):
    lines = stage_help(stage, CONF_DIR, full=True).splitlines()
    assert lines[0] == f"python -m pipeline {stage} [key=value ...]: {describe(stage)}"
    groups, sections = READS[stage]
    reads = StageHelp(stage, SCHEMAS[stage], CONF_DIR)
    assert [g.name for g in reads.groups] == groups and reads.sections == sections
    headings = [line.split(" (")[0].strip() for line in lines if "=<option>): " in line]
    assert headings == groups
    schema = SCHEMAS[stage]
    expected = [
        k
        for k in leaf_keys(schema, sections=frozenset(sections))
        if k.split(".")[0] not in groups or "." in k  # a mapping-typed group: its options
    ]
    assert expected, stage
    for key in expected:
        at = [i for i, line in enumerate(lines) if line.startswith(f"  {key}: ")]
        assert len(at) == 1, f"{stage}: {key} is listed {len(at)} times"
        assert lines[at[0] + 1].startswith("      ") and lines[at[0] + 1].strip(), key
    listed = {
        line.split(": ")[0].strip() for line in lines if line.startswith("  ") and ": " in line
    }
    assert (
        not {k for k in listed if k.startswith("profile.")}
        - {k for k in expected if k.startswith("profile.")}
        - {f"profile.{s}" for s in sections}
    ), "profile sections the stage does not read"


def test_the_trials_help_gives_types_ranges_defaults_and_options():
    lines = stage_help("trials", CONF_DIR, full=True).splitlines()
    for line in (
        "  runs: int, >= 1 = ${profile.trials.runs} (paper: 100, smoke: 3)",
        "  method.alpha: float, >= 0.0, <= 1.0 = 0.01",
        "  method.safety: str, one of none, shield, ssrl, fewshot = none",
        "  record: str, one of steps, episodes, none = steps",
        "  maze: str, not empty = 5x5",
        "  experiment.cells.<name>.substitution: int | None, one of 1, 2, 3, 4 = null",
        "      ssrl          safety=ssrl recovery=true",
        "      qlearning*",
    ):
        assert line in lines, line
    assert "      Learning rate of the TD update." in lines
    assert any(line.startswith("      relation_net*    The Relation Network") for line in lines)
    assert not any(line.startswith(("  data", "  model", "  train.")) for line in lines)


def test_the_meta_train_help_takes_defaults_from_the_groups_it_composes():
    lines = stage_help("meta_train", CONF_DIR, full=True).splitlines()
    assert "  checkpoint: str, not empty = datasets/models/relation_net.pt" in lines  # model group
    assert "  data.source: str, one of rendered, folder = rendered" in lines  # data group
    assert "  train.model: str, one of relation_net, protonet = relation_net" in lines


def test_the_trials_help_shows_the_common_keys_in_one_screen():
    """``trials --help``: every group's options on one line each, the keys ``COMMON_KEYS`` declares
    with the first sentence of their words, and the way to the rest; ``--help-all`` is the whole
    schema."""
    from pipeline.schemas.trials import TrialsConfig

    lines = stage_help("trials", CONF_DIR).splitlines()
    assert len(lines) <= 50
    assert "  method=       constrained fewshot fewshot_dss qlearning* sarsa shield ssrl" in lines
    assert any(line.startswith("  +experiment=  accuracy_curve fig10 fig8") for line in lines)
    keys = [line.split(":")[0].strip() for line in lines if re.match(r"^  [a-z_.]+: ", line)]
    assert keys == list(TrialsConfig.COMMON_KEYS)
    assert "  runs: int, >= 1 = ${profile.trials.runs} (paper: 100, smoke: 3)" in lines
    assert lines[-1] == "Every key and what each option does: python -m pipeline trials --help-all"
    assert "  method.alpha: float, >= 0.0, <= 1.0 = 0.01" not in lines
    full = stage_help("trials", CONF_DIR, full=True)
    assert "  method.alpha: float, >= 0.0, <= 1.0 = 0.01" in full.splitlines()
    assert stage_help("render", CONF_DIR) == stage_help(
        "render", CONF_DIR, full=True
    )  # no COMMON_KEYS


@pytest.mark.parametrize("flag", ["--help", "--help-all"])
def test_the_command_line_gives_each_help(flag, capsys):
    from pipeline.__main__ import main

    with pytest.raises(SystemExit) as done:
        main(["trials", flag])
    assert done.value.code == 0
    assert capsys.readouterr().out == stage_help("trials", CONF_DIR, full=flag == "--help-all")


def test_help_on_the_command_line_imports_no_heavy_library():
    """``python -m pipeline <stage> --help`` reads the schema without the stage's module, Hydra,
    torch, MuJoCo or matplotlib (what keeps it quick). numba comes with the safety methods' names:
    ``Safety`` is declared beside its rules (``pipeline/rl/rules.py``), so a new method stays three
    files."""
    code = (
        "import sys\n"
        "from pipeline.__main__ import main\n"
        "for stage in ('trials', 'render', 'meta_train', 'accuracy', 'report', 'replay'):\n"
        "    try:\n"
        "        main([stage, '--help'])\n"
        "    except SystemExit as e:\n"
        "        assert e.code == 0\n"
        "heavy = ('hydra', 'torch', 'mujoco', 'matplotlib', 'pipeline.stages.trials')\n"
        "print('LOADED', sorted(m for m in heavy if m in sys.modules))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=False
    )
    assert out.returncode == 0, out.stderr
    heads = [line.split()[3] for line in out.stdout.splitlines() if line.startswith("python -m")]
    assert heads == ["trials", "render", "meta_train", "accuracy", "report", "replay"]
    assert out.stdout.splitlines()[-1] == "LOADED []"


def test_a_stage_entry_point_prints_the_help_instead_of_running(capsys):
    from pipeline.stages import stage_main

    def run(cfg, overrides):
        raise AssertionError("--help must not run the stage")

    stage_main("replay", run, ["-h", "file=x.mcap"])
    assert capsys.readouterr().out == stage_help("replay", CONF_DIR)
