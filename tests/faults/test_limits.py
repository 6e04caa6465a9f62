"""Values past what the machine, the grammar or the file system can hold (docs/reliability.md,
"Configs"): the render stage's family distance and class counts, the Gymnasium environment's
substitution way and every path key's names. Each is one line naming the key, before any work;
the command line prints it and exits 2."""

from __future__ import annotations

import dataclasses
import math
import re
import subprocess
import sys

import gymnasium as gym
import pytest
from entry import ROOT

import pipeline  # noqa: F401  (registers the SafeNav ids)
import pipeline.stages.render as render
from pipeline.config.compose import load_config
from pipeline.config.fields import path_problem
from pipeline.config.registry import schemas
from pipeline.errors import ConfigError
from pipeline.fewshot.data import DataError, read_manifest
from pipeline.rl.oracle import OracleRecogniser
from pipeline.world.family_split import MAX_DISTANCE, split_families
from pipeline.world.render_plan import PlanConfig, make_plan, plan_size

GB = 1e9
LONG = "a" * 300


# ----------------------------------------------------------------------------- render


@pytest.mark.parametrize("distance", ["inf", "1e9", "7.5", "nan", "-1"])
def test_a_family_distance_no_families_have_is_refused_by_the_schema(distance):
    with pytest.raises(ConfigError, match=r"^config key 'min_family_distance': must be [<>]= "):
        load_config("render", [f"min_family_distance={distance}"])
    assert MAX_DISTANCE == 7.0  # 4 tiers, legs, arms and a handle


@pytest.mark.parametrize("distance", [MAX_DISTANCE, 6.0])
def test_a_split_the_grammar_cannot_give_stops_after_its_misses(distance):
    with pytest.raises(
        ConfigError, match=r"config key 'min_family_distance': only 0 of 1 validation "
    ):
        split_families(4, 1, 1, 0, min_distance=distance)
    with pytest.raises(ConfigError, match="no two families are further apart than 7"):
        split_families(4, 1, 1, 0, min_distance=math.inf)
    with pytest.raises(ConfigError, match="no two families are further apart than 7"):
        split_families(0, 1, 1, 0, min_distance=math.inf)  # test kept apart from validation
    assert split_families(0, 0, 1, 0, min_distance=math.inf)["test"]  # nothing to keep apart from


@pytest.fixture
def machine(monkeypatch):
    """A machine of 16 GB of memory and 100 GB free (the refusals do not depend on this one);
    a plan that starts raises ``Planned``."""

    class Planned(Exception):
        pass

    def planned(plan_cfg):
        raise Planned

    monkeypatch.setattr(render, "machine_memory", lambda: 16 * GB)
    monkeypatch.setattr(render, "free_space", lambda folder: 100 * GB)
    monkeypatch.setattr(render, "make_plan", planned)
    monkeypatch.setattr(render, "backend_problem", lambda: None)
    return Planned


def _render_config(tmp_path, *extra):
    return load_config(
        "render", [f"out_dir={tmp_path / 'images'}", f"figures_dir={tmp_path / 'f'}", *extra]
    )


@pytest.mark.parametrize(
    "extra, said",
    [
        (
            ["n_train_classes=100000"],
            r"6,002,625 pictures of 84 px \(100,036 classes x 60\) holds ",
        ),
        (["n_test_classes=5000", "size=1024"], r"take about 224\.\d GB; the disk of out_dir"),
        (["per_class=100000"], r"pictures of 84 px \(100 classes x 100000\) holds about"),
        (["n_val_classes=100000", "views_per_instance=1"], "in memory; this machine has 16.0 GB"),
    ],
)
def test_class_counts_that_do_not_fit_are_refused_before_planning(
    machine, tmp_path, capsys, extra, said
):
    cfg = _render_config(tmp_path, *extra)
    with pytest.raises(ConfigError, match=said) as caught:
        render.run(cfg)
    assert str(caught.value).startswith("config keys 'n_train_classes'/")
    assert "[render] " in capsys.readouterr().out  # the estimate came first
    assert not (tmp_path / "images").exists()


def test_a_large_render_says_its_pictures_size_and_time_before_planning(machine, tmp_path, capsys):
    with pytest.raises(machine):  # the plan would start here: nothing written yet
        render.run(_render_config(tmp_path, "n_test_classes=5000"))
    (said,) = capsys.readouterr().out.splitlines()
    assert re.fullmatch(
        r"\[render\] 305,265 pictures of 84 px \(5,080 classes x 60\): about 1\.5 GB on disk, "
        r"about \d+ (s|min|h) with 2 worker\(s\)",
        said,
    )
    assert not (tmp_path / "images").exists()


def test_a_split_that_cannot_be_made_leaves_no_out_dir(monkeypatch, tmp_path):
    monkeypatch.setattr(render, "backend_problem", lambda: None)
    cfg = _render_config(tmp_path, "min_family_distance=6.5", "n_train_classes=8")
    with pytest.raises(
        ConfigError, match=r"config key 'min_family_distance': only 0 of 16 validation"
    ):
        render.run(cfg)
    assert not (tmp_path / "images").exists()


def test_the_estimate_counts_what_the_plan_builds():
    cfg = PlanConfig(
        n_train_classes=2,
        n_val_classes=1,
        n_test_classes=1,
        per_class=5,
        views_per_instance=2,
        views_per_obstacle=1,
        categories=("chair", "basket"),
    )
    batches, rows = make_plan(cfg)
    size = plan_size(cfg)
    assert size["pictures"] == {s: sum(r["split"] == s for r in rows) for s in size["pictures"]}
    assert size["objects"] == sum(len(b.objects) for b in batches)
    assert size["batches"] == len(batches)
    assert [render.duration_text(s) for s in (40, 600, 12600)] == ["40 s", "10 min", "3.5 h"]


# ----------------------------------------------------------------------------- Gymnasium


@pytest.mark.parametrize("way", [9, 0, -1, 5, True, 2.0, "2", None])
@pytest.mark.parametrize(
    "env_id, method, recogniser",
    [
        ("SafeNav-5x5-v0", "fewshot_dss", "oracle"),
        ("SafeNav-5x5-v0", "fewshot", "fixed_accuracy"),
        ("SafeNav-v0", "shield", None),
        ("SafeNav-7x7-v0", "fewshot_dss", OracleRecogniser()),
        ("SafeNav3D-5x5-v0", "fewshot_dss", "oracle"),
    ],
)
def test_a_substitution_way_outside_1_to_4_is_refused_whatever_the_recogniser(
    env_id, method, recogniser, way
):
    with pytest.raises(ConfigError, match=rf"^substitution={way!r}: .* one of 1, 2, 3, 4"):
        gym.make(env_id, method=method, recogniser=recogniser, substitution=way)


def test_every_substitution_way_is_taken():
    for way in (1, 2, 3, 4):
        env = gym.make("SafeNav-5x5-v0", method="fewshot", recogniser="oracle", substitution=way)
        env.close()


# ----------------------------------------------------------------------------- path keys


def _path_keys(obj, prefix=""):
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if f.metadata.get("path"):
            yield prefix + f.name
        elif dataclasses.is_dataclass(value):
            yield from _path_keys(value, f"{prefix}{f.name}.")


#: Keys a stage's config leaves to the command line.
REQUIRED = {"replay": ["file=records.mcap"]}
#: Every path key of every stage (declared ``setting(path=True)``), as ``(stage, key)``.
PATH_KEYS = [(stage, key) for stage, cls in schemas().items() for key in _path_keys(cls())]


def test_the_path_keys_are_declared():
    declared = {f"{stage}.{key}" for stage, key in PATH_KEYS}
    for key in (
        "trials.out",
        "trials.metrics_dir",
        "trials.index_file",
        "trials.timing_file",
        "trials.maze",
        "accuracy.out_dir",
        "render.out_dir",
        "meta_train.checkpoint",
        "meta_train.data.test_dir",
        "replay.file",
        "report.out",
        "report.contact_dir",
    ):
        assert key in declared
    for stage, cls in schemas().items():  # every key named like a path is declared one
        for f in dataclasses.fields(cls):
            if (
                "str" in str(f.type)
                and f.name in ("file", "out", "maze", "checkpoint")
                or f.name.endswith(("_dir", "_file", "_metrics"))
            ):
                assert f.metadata.get("path"), f"{stage}.{f.name} is a path: setting(path=True)"


@pytest.mark.parametrize("stage, key", PATH_KEYS, ids=[f"{s}.{k}" for s, k in PATH_KEYS])
def test_a_name_over_the_file_system_limit_is_refused_naming_the_key(stage, key, tmp_path):
    with pytest.raises(ConfigError, match=rf"^config key '{key}': the name 'a{{24}}\.\.\.' is 300"):
        load_config(stage, [*REQUIRED.get(stage, []), f"{key}={tmp_path / LONG / 'x'}"])


def test_the_limits_are_the_file_systems(tmp_path):
    assert path_problem(str(tmp_path / ("a" * 255))) is None  # NAME_MAX, usually 255 bytes
    assert "is 256 bytes long" in path_problem(str(tmp_path / ("a" * 256)))
    assert "is 256 bytes long" in path_problem(str(tmp_path / ("é" * 128)))  # bytes, not letters
    assert "choose a shorter one" in path_problem(str(tmp_path / "/".join(["b" * 200] * 21)))
    assert path_problem("relative/path/" + "c" * 255) is None


def test_the_command_line_says_it_in_one_line_and_exits_2(tmp_path):
    done = subprocess.run(
        [sys.executable, "-m", "pipeline", "trials", f"out={tmp_path / LONG}"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        check=False,
    )
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.startswith("error: config key 'out': the name 'aaaa")
    assert done.stderr.count("\n") == 1 and "Traceback" not in done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_a_recogniser_images_dir_over_the_limit_is_one_line_too(tmp_path):
    """The recogniser's arguments are typed by its ``_target_`` (``pipeline.config.recognisers``),
    not by a schema: its manifest is refused where it is read."""
    with pytest.raises(DataError, match=r"cannot open the picture manifest .*File name too long"):
        read_manifest(tmp_path / LONG)
