"""The package carries its configs: the wheel built from this checkout holds every file of the
top-level ``conf/`` as the package ``pipeline.conf`` (each stage's yaml, the methods, recognisers, experiments, profiles, models, data
sources and the built-in mazes), and the pipeline installed from it, away from the checkout, finds
them (Hydra and the code through :func:`pipeline.config.folder.conf_dir`); a copy of a checkout reads its
own ``conf/``."""

import json
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from pipeline.__main__ import available_stages
from pipeline.config.folder import conf_dir

ROOT = Path(__file__).resolve().parents[1]
CONF = ROOT / "conf"

#: Run by the installed pipeline, from a folder outside the checkout: where it was imported from,
#: and what it finds in its configs.
INSTALLED_PROBE = """
import json, pipeline
from pipeline.config.folder import conf_dir
from pipeline.config.recognisers import recogniser_names
from pipeline.rl.methods import method_names
from pipeline.config.compose import load_config
from pipeline.world.maze import load_layout

cfg = load_config("trials", ["+experiment=fig10", "method=ssrl", "profile=smoke"])
print(json.dumps({
    "module": pipeline.__file__,
    "conf": str(conf_dir()),
    "methods": method_names(),
    "recognisers": recogniser_names(),
    "maze": list(load_layout("7x7").rows),
    "runs": cfg.runs,
    "cells": sorted(cfg.experiment.cells),
}))
"""


def conf_files(folder: Path) -> set[str]:
    """The yaml and txt files under ``folder``, relative to it."""
    return {
        p.relative_to(folder).as_posix()
        for p in folder.rglob("*")
        if p.is_file() and p.suffix in (".yaml", ".txt")
    }


#: What a copy of the sources leaves out: byte code and numba's caches.
BUILD_LEFTOVERS = shutil.ignore_patterns("__pycache__", "*.pyc", "*.nbi", "*.nbc")


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """The wheel of a copy of this checkout's package (the build writes beside its sources)."""
    tmp = tmp_path_factory.mktemp("package")
    src = tmp / "src"
    src.mkdir()
    for build_file in ("pyproject.toml", "setup.py"):
        shutil.copy(ROOT / build_file, src)
    for folder in ("pipeline", "conf"):
        shutil.copytree(ROOT / folder, src / folder, ignore=BUILD_LEFTOVERS)
    out = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--no-index"]
        + ["-q", "-w", str(tmp / "dist"), str(src)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    (built,) = (tmp / "dist").glob("*.whl")
    return built


def test_conf_dir_is_the_package_folder():
    assert conf_dir() == CONF and conf_dir("method") == CONF / "method"


def test_the_wheel_holds_every_config_file(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    packed = {n.removeprefix("pipeline/conf/") for n in names if n.startswith("pipeline/conf/")}
    assert conf_files(CONF) <= packed, sorted(conf_files(CONF) - packed)
    assert "__init__.py" in packed  # the marker pipeline.config.folder looks for
    for stage in available_stages():
        assert f"{stage}.yaml" in packed, stage
    for group, suffix in (
        ("method", ".yaml"),
        ("recogniser", ".yaml"),
        ("experiment", ".yaml"),
        ("profile", ".yaml"),
        ("model", ".yaml"),
        ("data", ".yaml"),
        ("mazes", ".txt"),
    ):
        expected = {f"{group}/{p.name}" for p in (CONF / group).glob(f"*{suffix}")}
        assert expected and expected <= packed, group


def test_the_installed_package_finds_its_configs(wheel, tmp_path):
    """Installed from the wheel (not editable) and run from another folder, the pipeline reads its
    configs from where it is installed, never from this checkout."""
    site = tmp_path / "site"
    out = subprocess.run(
        [sys.executable, "-m", "pip", "install", "--no-deps", "--no-index", "-q"]
        + ["--target", str(site), str(wheel)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    probe = subprocess.run(
        [sys.executable, "-c", INSTALLED_PROBE],
        capture_output=True,
        text=True,
        cwd=elsewhere,
        env={"PYTHONPATH": str(site), "PATH": "/usr/bin:/bin", "NUMBA_CACHE_DIR": str(tmp_path)},
        timeout=300,
    )
    assert probe.returncode == 0, probe.stderr[-3000:]
    found = json.loads(probe.stdout.strip().splitlines()[-1])
    assert Path(found["module"]).is_relative_to(site)
    assert Path(found["conf"]) == site / "pipeline" / "conf"
    assert found["methods"] == sorted(p.stem for p in (CONF / "method").glob("*.yaml"))
    assert found["recognisers"] == sorted(p.stem for p in (CONF / "recogniser").glob("*.yaml"))
    assert found["maze"] == (CONF / "mazes" / "7x7.txt").read_text().split()
    assert found["runs"] == 3 and found["cells"] == [
        "carry",
        "carry_paper",
        "restore",
        "restore_paper",
    ]  # profile smoke, fig10


def probe_conf_dir(checkout: Path) -> subprocess.CompletedProcess:
    """``conf_dir()`` as the pipeline imported from ``checkout`` (the current folder) finds it."""
    return subprocess.run(
        [sys.executable, "-c", "from pipeline.config.folder import conf_dir; print(conf_dir())"],
        capture_output=True,
        text=True,
        cwd=checkout,
        timeout=120,
    )


def test_a_copy_of_the_checkout_reads_its_own_configs_past_a_leftover_folder(tmp_path):
    """A copy of the checkout reads the ``conf/`` beside its package, not this checkout's. An
    untracked ``pipeline/conf/`` of byte code (left by git in a checkout from before the move to
    ``conf/``) is not taken for the configs."""
    for folder in ("pipeline", "conf"):
        shutil.copytree(ROOT / folder, tmp_path / folder, ignore=BUILD_LEFTOVERS)
    (tmp_path / "pipeline" / "conf" / "__pycache__").mkdir(parents=True)
    probe = probe_conf_dir(tmp_path)
    assert probe.returncode == 0, probe.stderr[-3000:]
    assert probe.stdout.strip() == str(tmp_path / "conf")


def test_a_package_without_configs_is_refused_by_name(tmp_path):
    shutil.copytree(ROOT / "pipeline", tmp_path / "pipeline", ignore=BUILD_LEFTOVERS)
    probe = probe_conf_dir(tmp_path)
    assert probe.returncode != 0
    assert f"neither {tmp_path / 'pipeline' / 'conf'} (an installed pipeline) nor" in probe.stderr
    assert "restore conf/ with `git checkout -- conf`" in probe.stderr
