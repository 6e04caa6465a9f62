"""A sweep sent to a real SLURM scheduler through Hydra's submitit launcher: a one-node cluster is
started on this machine for the test (``tests/slurm_cluster.py``) and stopped again."""

import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest
from slurm_cluster import PARTITION, missing, one_node_cluster

ROOT = Path(__file__).resolve().parents[1]
METHODS = (
    "fewshot",
    "fewshot_dss",
)  # methods the recogniser override applies to (it is refused for others)


def completed_log(path: Path, jobs: int, timeout: float = 60.0) -> str:
    """slurmctld's log once it records ``jobs`` completions (a job's result can reach the launcher
    before the scheduler logs its end)."""
    end = time.monotonic() + timeout
    while (log := path.read_text()).count("_job_complete") < 2 * jobs and time.monotonic() < end:
        time.sleep(0.5)
    return log


@pytest.mark.slow  # a real scheduler's daemons and jobs: end to end
@pytest.mark.skipif(missing() is not None, reason=str(missing()))
def test_a_smoke_sweep_runs_as_slurm_jobs(tmp_path):
    out, sweep = tmp_path / "runs", tmp_path / "multirun"
    # slurmd's step sockets live in the spool folder and a Unix socket path has at most 108 bytes:
    # pytest's tmp_path under a test worker's folder is too long for it
    with (
        tempfile.TemporaryDirectory(prefix="slurm-") as short,
        one_node_cluster(cluster := Path(short) / "cluster") as env,
    ):
        res = subprocess.run(
            [
                sys.executable,
                "-m",
                "pipeline",
                "trials",
                "-m",
                f"method={','.join(METHODS)}",
                "maze=5x5",
                "profile=smoke",
                "recogniser=oracle",
                "record=episodes",
                "progress=false",
                f"out={out}/" + "${method.name}",
                "hydra/launcher=submitit_slurm",
                f"hydra.launcher.partition={PARTITION}",
                "hydra.launcher.timeout_min=5",
                "hydra.launcher.cpus_per_task=1",
                "hydra.launcher.mem_gb=1",
                f"hydra.sweep.dir={sweep}",
            ],
            cwd=ROOT,
            env={**env, "HYDRA_FULL_ERROR": "1"},
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert res.returncode == 0, res.stderr[-3000:]
        log = completed_log(cluster / "slurmctld.log", len(METHODS))
    # every job went through the scheduler: submitit's per-task folders are named by SLURM job id and
    # array index, and slurmctld allocated each of them on the node
    jobs = sorted(
        p.name for p in (sweep / ".submitit").iterdir() if re.fullmatch(r"\d+_\d+", p.name)
    )  # array tasks
    assert len(jobs) == len(METHODS), jobs
    for job in jobs:
        assert re.search(rf"sched: Allocate JobId={job}\(\d+\) NodeList=localnode", log), job
        assert re.search(rf"_job_complete: JobId={job}\(\d+\) WEXITSTATUS 0", log), job
    for method in METHODS:
        summary = json.loads((out / method / "summary.json").read_text())
        assert (
            summary["method"] == method and summary["n_runs"] == 3 and summary["n_episodes"] == 20
        )
        assert (out / method / "records.mcap").exists()
    assert not os.environ.get("SLURM_JOB_ID")  # the test itself ran outside the cluster
