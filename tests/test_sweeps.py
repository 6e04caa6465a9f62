"""Hydra multirun sweeps of the trials stage through the joblib and submitit_local launchers (the
latter under ``make test-slow``)."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize(
    "launcher",
    [  # README's sweep; submitit's local launcher (its SLURM launcher: tests/test_slurm.py) is slow
        "joblib",
        pytest.param("submitit_local", marks=pytest.mark.slow),
    ],
)
def test_sweep_over_methods(tmp_path, launcher):
    args = [
        sys.executable,
        "-m",
        "pipeline",
        "trials",
        "-m",
        "method=shield,ssrl",
        "maze=5x5",
        "profile=smoke",
        "record=none",
        "progress=false",
        f"out={tmp_path}/" + "${method.name}",
        f"hydra/launcher={launcher}",
        f"hydra.sweep.dir={tmp_path}/multirun",
    ]
    if launcher == "joblib":
        args.append("hydra.launcher.n_jobs=2")
    else:
        args += ["hydra.launcher.timeout_min=5", "hydra.launcher.cpus_per_task=1"]
    out = subprocess.run(
        args,
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
        env={**os.environ, "HYDRA_FULL_ERROR": "1"},
    )
    assert out.returncode == 0, out.stderr[-3000:]
    shield = json.loads((tmp_path / "shield" / "summary.json").read_text())
    ssrl = json.loads((tmp_path / "ssrl" / "summary.json").read_text())
    assert shield["method"] == "shield" and ssrl["method"] == "ssrl"
    assert ssrl["collisions"]["mean"] <= shield["collisions"]["mean"]
