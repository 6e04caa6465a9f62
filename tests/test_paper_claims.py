"""The paper's qualitative results at the paper's scale (100 runs x 500 episodes) with the committed
Relation Network: Table 3's order on every maze (the dynamic support set below the static one on
7x7 and 11x11; on the 5x5 the report finds that difference not resolved), the DSS gain growing
with the maze, Figure 10's carried-over support set ending with fewer collisions than restoring
it. Slow (about 2 minutes); needs the rendered images (`make repro`). Run with `make test-slow`."""

from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
CHECKPOINT = ROOT / "datasets/models/relation_net.pt"
IMAGES = ROOT / "datasets/images"

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(
        not (IMAGES / "manifest.csv").exists() or not CHECKPOINT.exists(),
        reason="needs datasets/images and the trained model (make repro)",
    ),
]


def mean_collisions(method, maze, way=1, support="restore"):
    from pipeline.fewshot.recogniser import RelationRecogniser
    from pipeline.rl.methods import get_method
    from pipeline.rl.runner import run_trials
    from pipeline.world.maze import load_layout

    spec = get_method(method)
    rec = None
    if spec.uses_recogniser:
        rec = RelationRecogniser.from_files(
            CHECKPOINT,
            IMAGES,
            substitution_way=way if spec.dynamic_support else 0,
            carry_over=support == "carry",
        )
    result = run_trials(
        load_layout(maze),
        spec,
        100,
        500,
        seed=0,
        recogniser=rec,
        progress=False,
        shared_support=support == "carry",
    )
    return float(result.collisions.sum(axis=1).mean())


def test_table3_order_and_growing_dss_gain():
    gains = []
    for maze in ("5x5", "7x7", "11x11"):
        sarsa, constrained = mean_collisions("sarsa", maze), mean_collisions("constrained", maze)
        fewshot = mean_collisions("fewshot", maze)
        dss = np.mean([mean_collisions("fewshot_dss", maze, way) for way in (1, 2, 3, 4)])
        assert sarsa > constrained > fewshot, (maze, sarsa, constrained, fewshot)
        if maze != "5x5":  # on the 5x5 nine of the ten obstacles appear once: the report finds the
            assert fewshot > dss, (maze, fewshot, dss)  # DSS's difference there not resolved
        gains.append(fewshot - dss)
    assert gains[0] < gains[1] < gains[2], gains


def test_long_term_autonomy_carries_the_support_set_over():
    restore = mean_collisions("fewshot_dss", "5x5", 1, "restore")
    carry = mean_collisions("fewshot_dss", "5x5", 1, "carry")
    assert carry < 0.5 * restore, (carry, restore)
