"""Records of one config are byte-identical whatever CPU kernels torch picks (issue 31;
docs/records.md "The schema"): a Relation Network cell run in two processes,
one with ``ATEN_CPU_CAPABILITY=default``, one with ``=avx2`` (oneDNN and MKL free to pick their
best), and the files compared. A subprocess each: the kernel path is chosen once per process."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from pipeline.fewshot.synthetic import write_synthetic_dataset
from pipeline.records import read_records

ROOT = Path(__file__).resolve().parents[1]
CHECKPOINT = ROOT / "datasets" / "models" / "relation_net.pt"  # committed (dvc.yaml: cache: false)


def _cpu_has(flag: str) -> bool:
    try:
        return f" {flag}" in Path("/proc/cpuinfo").read_text()
    except OSError:
        return False


@pytest.mark.skipif(not _cpu_has("avx2"), reason="this CPU has no AVX2 kernels to compare with")
@pytest.mark.parametrize(  # the robot's cell: live pictures, mm-rounded motion table (issue 38)
    "world,runs", [("grid", 10), ("robot3d", 2)]
)
def test_a_cell_gives_the_same_record_bytes_under_two_kernel_paths(tmp_path, world, runs):
    images = tmp_path / "images"
    write_synthetic_dataset(images, n_train=6, n_val=5, per_class=4, seed=2)
    out = tmp_path / "out"  # the same out for both: the records keep the config
    got = {}
    for capability in ("default", "avx2"):
        env = {
            **os.environ,
            "ATEN_CPU_CAPABILITY": capability,
            "ONEDNN_MAX_CPU_ISA": "ALL",
            "MKL_CBWR": "AUTO",
        }
        args = ["method=fewshot_dss", "maze=5x5", f"runs={runs}", "episodes=100", f"world={world}"]
        paths = [f"recogniser.checkpoint={CHECKPOINT}", f"recogniser.images_dir={images}"]
        proc = subprocess.run(
            [sys.executable, "-m", "pipeline", "trials", *args, *paths, f"images_dir={images}"]
            + [f"out={out}", "overwrite=true", "progress=false"],
            env=env,
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert proc.returncode == 0, proc.stderr
        got[capability] = {n: (out / n).read_bytes() for n in ("records.mcap", "summary.json")}
    assert got["default"] == got["avx2"]
    records = read_records(out / "records.mcap")
    assert len(records.recognitions) > 10 * runs and records.recognitions.score_0.notna().all()
    assert records.meta.config["recogniser"]["checkpoint"] == str(CHECKPOINT)
