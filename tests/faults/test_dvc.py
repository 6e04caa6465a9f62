"""Changes DVC must not miss. dvc.yaml's code dependencies and config parameters are derived
(``scripts/dvc_deps.py``), and DVC sees every one of them: editing any module a stage's command imports, any config folder its
code reads, or any config key that shapes its outputs makes ``dvc status`` name that stage."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from scripts import dvc_deps

ROOT = Path(__file__).resolve().parents[2]
DVC = Path(sys.executable).parent / "dvc"
TEXT = dvc_deps.DVC_YAML.read_text()


class _Stages:
    """dvc.yaml's stages as ``scripts/dvc_deps.py`` derives them, derived at the first use: each
    composes its configs (seconds), once in the worker that runs these tests, not in every worker
    that collects this file."""

    def __init__(self) -> None:
        self._stages: dict | None = None

    def _derived(self) -> dict:
        if self._stages is None:
            self._stages = dvc_deps.stages_of(TEXT)
        return self._stages

    def __getitem__(self, name: str):
        return self._derived()[name]

    def __contains__(self, name: object) -> bool:
        return name in self._derived()

    def items(self):
        return self._derived().items()

    def values(self):
        return self._derived().values()


STAGES = _Stages()


def test_dvc_yaml_lists_the_derived_deps_and_params():
    wanted = dvc_deps.rewritten(TEXT, STAGES)
    if wanted != TEXT:
        import difflib

        diff = "\n".join(difflib.unified_diff(TEXT.splitlines(), wanted.splitlines(), n=0))
        pytest.fail(f"dvc.yaml is not the derived one: python -m scripts.dvc_deps --write\n{diff}")


def test_the_closure_follows_imports_inside_functions_targets_and_parent_packages():
    trials = STAGES["trials"].code()
    assert "pipeline/rl/rules.py" in trials  # imported by the kernel
    assert "pipeline/robot/live_world.py" in trials  # imported inside a function (world=robot3d)
    assert "pipeline/rl/fixed_accuracy.py" in trials  # accuracy_curve's recogniser's _target_
    assert "pipeline/robot/__init__.py" in trials  # runs before pipeline.robot.world
    assert "conf/mazes" in trials  # read as data by pipeline/world/maze.py
    report = STAGES["report"].code()
    assert "pipeline/report" in report  # every module of the folder: listed as the folder
    assert "pipeline/rl/rules.py" in report  # the deps the old hand-kept list missed
    assert {"conf/experiment", "conf/profile"} <= set(report)


def test_a_stage_depends_on_its_own_schema_and_not_on_the_others():
    """Each stage imports only its own config's schema (``pipeline.config.registry.SCHEMA_OF``):
    editing the trials' code does not make meta-training (70 minutes) look stale."""
    meta_train = STAGES["meta_train"].code()
    assert "pipeline/schemas/fewshot.py" in meta_train
    assert not [d for d in meta_train if d.startswith(("pipeline/rl", "pipeline/world"))]
    assert "pipeline/schemas/trials.py" not in STAGES["render"].code()


def test_params_are_the_composed_files_without_the_output_neutral_keys():
    trials = dict(STAGES["trials"].params())
    keys = trials["conf/trials.yaml"]
    assert {"seed", "robot", "world", "rule", "threshold", "maze"} <= set(keys)
    assert not {"out", "progress", "threads", "workers", "overwrite"} & set(keys)
    assert "conf/experiment/${item}.yaml" not in trials  # structure: a dependency, whole
    assert "conf/experiment/${item}.yaml" in STAGES["trials"].code()
    assert trials["conf/method/shield.yaml"] == []  # whole file
    assert "trials.layouts" in trials["conf/profile/paper.yaml"]  # generalisation's
    protonet = dict(STAGES["meta_train_protonet"].params())
    assert protonet["conf/model/protonet.yaml"] == []
    assert "meta_train.protonet_episodes" in protonet["conf/profile/paper.yaml"]
    assert "meta_train.episodes" not in protonet["conf/profile/paper.yaml"]


def test_a_foreach_wrapped_over_two_lines_is_rewritten_whole():
    """The trials' foreach outgrew one line: rewriting it replaces every line of the old list
    (it once kept the second line, and dvc.yaml stopped parsing)."""
    text = TEXT.replace(
        "\n    foreach: [fig8,", "\n    foreach: [fig8,\n              fig8_again,", 1
    )
    assert "fig8_again" in text
    wanted = dvc_deps.rewritten(text, STAGES)
    assert "fig8_again" not in wanted and wanted == dvc_deps.rewritten(TEXT, STAGES)
    yaml.safe_load(wanted)


def test_a_changed_stage_command_is_read_back():
    assert dvc_deps.parse_cmd("python -m pipeline trials +experiment=fig8 progress=false") == (
        "trials",
        ["+experiment=fig8", "progress=false"],
    )
    with pytest.raises(ValueError, match="not a stage command"):
        dvc_deps.parse_cmd("make repro")


# ------------------------------------------------------------------- what DVC itself sees
def code_and_params_only(text: str) -> str:
    """dvc.yaml without outs and data deps, each command ``true``: stages DVC can commit in a copy
    of the package and its configs alone."""
    data = yaml.safe_load(text)
    for definition in data["stages"].values():
        body = definition.get("do", definition)
        body["cmd"] = "true"
        body["deps"] = [d for d in body["deps"] if d.split("/")[0] in dvc_deps.derived_roots()]
        body.pop("outs", None)
        body.pop("metrics", None)
    data.pop("plots", None)
    return yaml.safe_dump(data, sort_keys=False)


def touch_everything(repo: Path) -> None:
    """Append a line to every file of the package and change every config value."""
    for path in (p for root in dvc_deps.derived_roots() for p in (repo / root).rglob("*")):
        if path.is_file() and path.suffix in (".py", ".txt"):
            path.write_text(path.read_text() + "\n# touched\n")
        elif path.is_file() and path.suffix == ".yaml":
            data = yaml.safe_load(path.read_text()) or {}
            path.write_text(yaml.safe_dump(changed(data)))


def changed(value):
    if isinstance(value, dict):
        return {k: changed(v) for k, v in value.items()}
    return ["changed", value]


def stage_items(name: str, stage) -> list[str | None]:
    """The items DVC names a stage's runs by: the experiments of the trials' ``foreach``, a
    ``foreach`` list of its own (the networks' seeds), or None for a plain stage."""
    if stage.items != [None]:
        return stage.items
    own = yaml.safe_load(TEXT)["stages"][name].get("foreach")
    return [str(item) for item in own] if own else [None]


@pytest.mark.slow  # real `dvc commit` and `dvc status` in a copy; fast: the derived listing above
@pytest.mark.skipif(not DVC.exists(), reason="dvc is not installed beside this python")
def test_dvc_status_names_every_stage_for_every_module_folder_and_key(tmp_path):
    repo = tmp_path / "repo"
    for root in dvc_deps.derived_roots():
        shutil.copytree(ROOT / root, repo / root, ignore=shutil.ignore_patterns("__pycache__"))
    (repo / ".dvc").mkdir()
    (repo / ".dvc" / "config").write_text("[core]\n    no_scm = true\n    analytics = false\n")
    (repo / "dvc.yaml").write_text(code_and_params_only(TEXT))
    env = {**os.environ, "DVC_NO_ANALYTICS": "1"}

    def dvc(*args: str) -> str:
        done = subprocess.run(
            [str(DVC), *args], cwd=repo, env=env, capture_output=True, text=True, timeout=300
        )
        assert done.returncode == 0, done.stderr
        return done.stdout

    dvc("commit", "--force", "--quiet")
    assert yaml.safe_load(dvc("status", "--json")) == {}
    touch_everything(repo)
    status = yaml.safe_load(dvc("status", "--json"))
    problems = []
    for name, stage in STAGES.items():
        for item in stage_items(name, stage):
            key = f"{name}@{item}" if item else name
            seen = {}
            for entry in status.get(key, []):
                seen.update(entry.get("changed deps", {}) if isinstance(entry, dict) else {})
            for dep in (d.replace("${item}", item or "") for d in stage.code()):
                if seen.get(dep) != "modified":
                    problems.append(f"{key}: editing {dep} is not seen")
            for file, keys in stage.params():
                file = file.replace("${item}", item or "")
                for k in keys or [None]:
                    if not seen.get(file) or (k and seen[file].get(k) != "modified"):
                        problems.append(f"{key}: changing {file}:{k or '(any key)'} is not seen")
    assert not problems, "\n".join(problems)
