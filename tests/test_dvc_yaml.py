"""dvc.yaml against conf/: one trials stage per experiment file, params that name keys that
exist, config as params and never as deps, the paper's scale, and a DVC site cache that does not
depend on the cwd. The derived parts (code deps, params, the experiments) are checked against
their derivation in tests/faults/test_dvc.py."""

import configparser
import os
from pathlib import Path

import yaml

from pipeline.config.compose import CONF_DIR

ROOT = Path(__file__).resolve().parents[1]
EXPERIMENT_DIR = Path(CONF_DIR) / "experiment"
DVC = yaml.safe_load((ROOT / "dvc.yaml").read_text())
STAGES = DVC["stages"]
EXPERIMENTS = STAGES["trials"]["foreach"]


def expanded(stage: str, item: str | None = None) -> dict:
    """A stage's definition with ``${item}`` filled in (the trials foreach template)."""
    text = yaml.safe_dump(STAGES[stage]["do"] if item else STAGES[stage])
    return yaml.safe_load(text.replace("${item}", str(item)) if item else text)


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


def differences(listed, wanted, where: str) -> list[str]:
    """What ``where`` lacks and what it lists in vain, in words (empty when they agree)."""
    listed, wanted = set(listed), set(wanted)
    out = [f"add {x} to {where}" for x in sorted(wanted - listed)]
    return out + [f"remove {x} from {where} (no such file)" for x in sorted(listed - wanted)]


def test_trials_foreach_is_every_experiment_file():
    files = sorted(p.stem for p in EXPERIMENT_DIR.glob("*.yaml"))
    problems = differences(EXPERIMENTS, files, "dvc.yaml's trials foreach")
    assert not problems, "; ".join(problems)
    assert len(set(EXPERIMENTS)) == len(EXPERIMENTS), "dvc.yaml's trials foreach repeats an item"


def test_report_depends_on_every_experiment():
    """Through the records' committed indexes (so ``dvc repro --dry`` hashes them on a fresh clone)."""
    deps = [d for d in STAGES["report"]["deps"] if d.startswith("datasets/index/runs/")]
    expected = [f"datasets/index/runs/{e}.json" for e in EXPERIMENTS]
    problems = differences(deps, expected, "the report's deps")
    assert not problems, "; ".join(problems)
    assert not [d for d in STAGES["report"]["deps"] if d.startswith("datasets/runs")]


def test_no_stage_depends_on_a_cached_folder():
    """A DVC-cached output is missing on a fresh clone, and ``dvc repro --dry`` fails hashing a
    missing dependency: stages depend on the committed index of such a folder instead."""
    cached = {
        o
        for s in STAGES.values()
        for o in s.get("do", s).get("outs", [])
        if isinstance(o, str)  # an out without options is cached
    }
    cached = {c.replace("${item}", e) for c in cached for e in EXPERIMENTS}
    for name, s in STAGES.items():
        deps = s.get("do", s).get("deps", [])
        assert not cached & set(deps), f"{name} depends on a cached folder: {cached & set(deps)}"


def test_differences_name_what_is_missing_and_what_is_extra():
    assert differences(["a.yaml", "c.yaml"], ["a.yaml", "b.yaml"], "params") == [
        "add b.yaml to params",
        "remove c.yaml from params (no such file)",
    ]
    assert differences(["a"], ["a"], "params") == []


def _get(data: dict, dotted: str):
    for part in dotted.split("."):
        assert isinstance(data, dict) and part in data, dotted
        data = data[part]
    return data


def test_params_name_existing_files_and_keys_and_deps_hold_no_config_but_experiments():
    """Config files are params, but for an experiment's (its cells and report text are structure:
    a dependency, whole; scripts/dvc_deps.py)."""
    for name, stage in all_stages().items():
        for file, keys in params_entries(stage):
            path = ROOT / file
            assert path.is_file(), f"{name}: params file {file} missing"
            data = yaml.safe_load(path.read_text()) or {}
            for key in keys:  # `dvc exp run -S file:key=...` needs the key in the file
                _get(data, key)
        for dep in stage.get("deps", []):
            config = dep.startswith("conf/") and dep.endswith(".yaml")
            assert not config or dep.startswith("conf/experiment/"), (
                f"{name}: {dep} belongs in params"
            )


def test_default_scale_is_the_paper_profile():
    """Every stage but ``sample`` (the committed records sample, at smoke scale on purpose)."""
    for name, stage in all_stages().items():
        if name == "sample":
            assert "profile=smoke" in stage["cmd"]
            assert {f for f, _ in params_entries(stage) if "/profile/" in f} == {
                "conf/profile/smoke.yaml"
            }
            continue
        assert "profile=" not in stage["cmd"], name
        profiles = {f for f, _ in params_entries(stage) if f.startswith("conf/profile/")}
        assert profiles <= {"conf/profile/paper.yaml"}, name


def test_the_records_sample_is_committed_and_small():
    """``datasets/sample``: in git (``cache: false``), so the README's records and replay examples
    work on a fresh clone; under 2 MB."""
    outs = STAGES["sample"]["outs"]
    assert outs == [{"datasets/sample/fig8": {"cache": False, "persist": True}}]
    folder = ROOT / "datasets" / "sample" / "fig8"
    if folder.is_dir():
        size = sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())
        assert 0 < size < 2 * 2**20
        assert len(list(folder.glob("*/records.mcap"))) >= 3


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
