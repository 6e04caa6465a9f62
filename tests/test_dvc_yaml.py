"""dvc.yaml against pipeline/conf/: one trials stage per experiment file, config declared as params (keys
that exist, and every method and recogniser file an experiment reads), code and data as deps, and a
DVC site cache that does not depend on the cwd. The lists DVC forces are checked here, each
failure naming what to add or remove."""

import configparser
import os
from pathlib import Path

import pytest
import yaml

from pipeline.rl.methods import METHOD_DIR
from pipeline.stages._common import CONF_DIR
from pipeline.stages._recognisers import RECOGNISER_DIR

ROOT = Path(__file__).resolve().parents[1]
EXPERIMENT_DIR = Path(CONF_DIR) / "experiment"
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


def read_by_experiments() -> list[str]:
    """The method and recogniser files the experiments of ``pipeline/conf/experiment/`` read, as dvc.yaml
    names them: the methods of their cells (listed and layout templates), the recognisers their
    cells choose (``recogniser_group``), their defaults lists choose (``override /recogniser``) and
    ``pipeline/conf/trials.yaml`` chooses for the rest."""
    trials = yaml.safe_load((Path(CONF_DIR) / "trials.yaml").read_text())
    recognisers = {
        d["recogniser"] for d in trials["defaults"] if isinstance(d, dict) and "recogniser" in d
    }
    methods = set()
    for path in EXPERIMENT_DIR.glob("*.yaml"):
        data = yaml.safe_load(path.read_text()) or {}
        exp = data.get("experiment") or {}
        cells = [
            *(exp.get("cells") or {}).values(),
            *((exp.get("layouts") or {}).get("cells") or {}).values(),
        ]
        methods |= {c["method"] for c in cells if "method" in c}
        recognisers |= {c["recogniser_group"] for c in cells if c.get("recogniser_group")}
        for entry in data.get("defaults") or []:
            if isinstance(entry, dict):
                recognisers |= {v for k, v in entry.items() if k.endswith("/recogniser")}
    return [
        *(f"{METHOD_DIR.relative_to(ROOT).as_posix()}/{m}.yaml" for m in sorted(methods)),
        *(f"{RECOGNISER_DIR.relative_to(ROOT).as_posix()}/{r}.yaml" for r in sorted(recognisers)),
    ]


@pytest.mark.parametrize("exp", EXPERIMENTS)
def test_each_trials_stage_tracks_its_experiment_and_the_methods_and_recognisers_they_read(exp):
    """DVC cannot list per item the files an item reads: every item tracks every method and
    recogniser file any experiment reads, whole, so changing one reruns the trials (and a new
    recogniser or method an experiment uses is named here until dvc.yaml lists it)."""
    stage = expanded("trials", exp)
    files = dict(params_entries(stage))
    assert files[f"{EXPERIMENT_DIR.relative_to(ROOT).as_posix()}/{exp}.yaml"] == []  # whole file
    whole = {f for f, keys in files.items() if keys == []}
    missing = [f for f in read_by_experiments() if f not in whole]
    assert not missing, "; ".join(
        f"add {f} to dvc.yaml's trials params (whole file)" for f in missing
    )
    assert (
        f"+experiment={exp} " in stage["cmd"]
        and f"metrics_dir=datasets/metrics/{exp} " in stage["cmd"]
        and f"index_file=datasets/index/runs/{exp}.json" in stage["cmd"]
    )
    assert stage["outs"][0] == {f"datasets/runs/{exp}": {"persist": True}}


def test_the_files_experiments_read_include_their_methods_and_recognisers():
    read = read_by_experiments()
    method = METHOD_DIR.relative_to(ROOT).as_posix()
    recogniser = RECOGNISER_DIR.relative_to(ROOT).as_posix()
    assert f"{method}/fewshot_dss.yaml" in read  # a cell's method
    assert f"{recogniser}/protonet.yaml" in read  # fig8's recogniser_group
    assert f"{recogniser}/fixed_accuracy.yaml" in read  # accuracy_curve's override /recogniser
    assert f"{recogniser}/relation_net.yaml" in read  # pipeline/conf/trials.yaml's default


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
    """Every stage but ``sample`` (the committed records sample, at smoke scale on purpose)."""
    for name, stage in all_stages().items():
        if name == "sample":
            assert "profile=smoke" in stage["cmd"]
            assert {f for f, _ in params_entries(stage) if "/profile/" in f} == {
                "pipeline/conf/profile/smoke.yaml"
            }
            continue
        assert "profile=" not in stage["cmd"], name
        profiles = {f for f, _ in params_entries(stage) if f.startswith("pipeline/conf/profile/")}
        assert profiles <= {"pipeline/conf/profile/paper.yaml"}, name


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
