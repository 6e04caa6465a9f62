"""Records of one config are byte-identical whatever CPU kernels torch picks (issue 31;
docs/records.md "The schema"): a Relation Network cell of each world run in two processes,
one with ``ATEN_CPU_CAPABILITY=default``, one with ``=avx2`` (oneDNN and MKL free to pick their
best), and the files compared; so is a meta-trained checkpoint (issue 42: unpinned, one seed gave
other weights on an AVX-512 machine). A subprocess each: the kernel path is chosen once per
process."""

import json
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


#: The worlds and their runs (the robot's cell: live pictures, mm-rounded motion table, issue 38).
WORLDS = {"grid": 10, "robot3d": 2}

#: One child process runs every world's cell: the kernel path is chosen once per process, and the
#: start-up (torch, numba, MuJoCo) is paid once per path instead of once per cell.
RUN_CELLS = """
import json, sys
from pipeline.__main__ import main
for args in json.loads(sys.argv[1]):
    main(args)
"""


@pytest.fixture(scope="module")
def under_two_kernel_paths(tmp_path_factory):
    """``{capability: {world: {file name: bytes}}}`` and the folder of the last run's cells."""
    tmp = tmp_path_factory.mktemp("same_bytes")
    images = tmp / "images"
    write_synthetic_dataset(images, n_train=6, n_val=5, per_class=4, seed=2)
    paths = [f"recogniser.checkpoint={CHECKPOINT}", f"recogniser.images_dir={images}"]
    cells = {  # the same out for both paths: the records keep the config
        world: ["trials", "method=fewshot_dss", "maze=5x5", f"runs={runs}", "episodes=100"]
        + [f"world={world}", *paths, f"images_dir={images}", f"out={tmp / world}"]
        + ["overwrite=true", "progress=false"]
        for world, runs in WORLDS.items()
    }
    trained, classes = tmp / "meta" / "rn.pt", tmp / "classes"
    write_synthetic_dataset(classes, n_train=6, n_val=5, per_class=10, seed=2)
    meta_train = ["meta_train", f"images_dir={classes}", f"checkpoint={trained}", "progress=false"]
    meta_train += [
        f"metrics_file={tmp / 'meta' / 'm.json'}",
        f"history_file={tmp / 'meta' / 'h.csv'}",
    ]
    meta_train += ["train.input_size=24", "train.relation_padding=1", "train.n_query=3"]
    meta_train += ["train.episodes=8", "train.val_every=4", "train.val_episodes=4"]
    meta_train += ["train.eval_episodes=4", "train.eval_queries=5"]
    got = {}
    for capability in ("default", "avx2"):
        env = {
            **os.environ,
            "ATEN_CPU_CAPABILITY": capability,
            "ONEDNN_MAX_CPU_ISA": "ALL",
            "MKL_CBWR": "AUTO",
        }
        proc = subprocess.run(
            [sys.executable, "-c", RUN_CELLS, json.dumps([meta_train, *cells.values()])],
            env=env,
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert proc.returncode == 0, proc.stderr
        got[capability] = {
            world: {n: (tmp / world / n).read_bytes() for n in ("records.mcap", "summary.json")}
            for world in WORLDS
        }
        got[capability]["meta_train"] = {"rn.pt": trained.read_bytes()}
    return got, tmp


@pytest.mark.skipif(not _cpu_has("avx2"), reason="this CPU has no AVX2 kernels to compare with")
@pytest.mark.parametrize("world,runs", WORLDS.items())
def test_a_cell_gives_the_same_record_bytes_under_two_kernel_paths(
    under_two_kernel_paths, world, runs
):
    got, tmp = under_two_kernel_paths
    assert got["default"][world] == got["avx2"][world]
    records = read_records(tmp / world / "records.mcap")
    assert len(records.recognitions) > 10 * runs and records.recognitions.score_0.notna().all()
    assert records.meta.config["recogniser"]["checkpoint"] == str(CHECKPOINT)
    assert records.meta.config["world"] == world


@pytest.mark.skipif(not _cpu_has("avx2"), reason="this CPU has no AVX2 kernels to compare with")
def test_meta_training_gives_the_same_checkpoint_bytes_under_two_kernel_paths(
    under_two_kernel_paths,
):
    got, tmp = under_two_kernel_paths
    assert got["default"]["meta_train"] == got["avx2"]["meta_train"]
    info = json.loads((tmp / "meta" / "rn.train_info.json").read_text())
    assert info["cpu_kernels"] == "avx2"  # pipeline/kernels.py: TRAINING
