"""dvc.yaml against conf/: one trials stage per experiment file, config declared as params (keys
that exist), code and data as deps, and a DVC site cache that does not depend on the cwd."""

import configparser
import os
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
DVC = yaml.safe_load((ROOT / "dvc.yaml").read_text())
STAGES = DVC["stages"]
EXPERIMENTS = STAGES["trials"]["foreach"]


def expanded(stage: str, item: str | None = None) -> dict:
    """A stage's definition with ``${item}`` filled in (the trials foreach template)."""
    text = yaml.safe_dump(STAGES[stage]["do"] if item else STAGES[stage])
    return yaml.safe_load(text.replace("${item}", item) if item else text)


def all_stages() -> dict[str, dict]:
    out = {}
    for name, stage in STAGES.items():
        if "foreach" in stage:
            out.update({f"{name}@{item}": expanded(name, item) for item in stage["foreach"]})
        else:
            out[name] = stage
    return out


def params_entries(stage: dict) -> list[tuple[str, list[str]]]:
    out = []
    for entry in stage.get("params", []):
        assert isinstance(entry, dict), (
            f"params entry {entry!r}: name its file (there is no params.yaml)"
        )
        out.extend((file, keys or []) for file, keys in entry.items())
    return out


def test_trials_foreach_is_every_experiment_file():
    files = sorted(p.stem for p in (ROOT / "pipeline" / "conf" / "experiment").glob("*.yaml"))
    assert sorted(EXPERIMENTS) == files, (
        "list every pipeline/conf/experiment/*.yaml in dvc.yaml's trials foreach"
    )
    assert len(set(EXPERIMENTS)) == len(EXPERIMENTS)


def test_report_depends_on_every_experiment():
    assert {f"datasets/runs/{e}" for e in EXPERIMENTS} <= set(STAGES["report"]["deps"])


@pytest.mark.parametrize("exp", EXPERIMENTS)
def test_each_trials_stage_tracks_its_experiment_and_every_method(exp):
    stage = expanded("trials", exp)
    files = dict(params_entries(stage))
    assert files[f"pipeline/conf/experiment/{exp}.yaml"] == []  # the whole file
    methods = {
        f"pipeline/conf/method/{p.name}"
        for p in (ROOT / "pipeline" / "conf" / "method").glob("*.yaml")
    }
    assert methods <= {f for f, keys in files.items() if keys == []}
    assert (
        f"+experiment={exp} " in stage["cmd"]
        and f"metrics_file=datasets/metrics/{exp}.json" in stage["cmd"]
    )
    assert stage["outs"] == [f"datasets/runs/{exp}"]


def _get(data: dict, dotted: str):
    for part in dotted.split("."):
        assert isinstance(data, dict) and part in data, dotted
        data = data[part]
    return data


def test_params_name_existing_files_and_keys_and_deps_hold_no_config():
    for name, stage in all_stages().items():
        for file, keys in params_entries(stage):
            path = ROOT / file
            assert path.is_file(), f"{name}: params file {file} missing"
            data = yaml.safe_load(path.read_text()) or {}
            for key in keys:  # `dvc exp run -S file:key=...` needs the key in the file
                _get(data, key)
        for dep in stage.get("deps", []):
            assert not (dep.startswith("pipeline/conf/") and dep.endswith(".yaml")), (
                f"{name}: {dep} belongs in params"
            )


def test_default_scale_is_the_paper_profile():
    for name, stage in all_stages().items():
        assert "profile=" not in stage["cmd"], name
        profiles = {f for f, _ in params_entries(stage) if f.startswith("pipeline/conf/profile/")}
        assert profiles <= {"pipeline/conf/profile/paper.yaml"}, name


def test_site_cache_dir_is_not_relative():
    """A relative core.site_cache_dir is taken from the cwd: `dvc exp run --temp` (and queued runs)
    fail with "unable to open database file" and a run from a subfolder makes a second cache there.
    setup.sh puts an absolute one in .dvc/config.local (tests/test_dvc_experiments.py runs it)."""
    for name in ("config", "config.local"):
        path = ROOT / ".dvc" / name
        if not path.exists():
            continue
        parser = configparser.ConfigParser()
        parser.read_string(path.read_text())
        value = parser.get("core", "site_cache_dir", fallback=None)
        assert value is None or os.path.isabs(value), (
            f".dvc/{name}: core.site_cache_dir = {value!r}"
        )
