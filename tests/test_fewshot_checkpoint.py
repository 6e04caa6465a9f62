"""Checkpoint round trip and the errors for corrupt, foreign and mismatched files."""

import numpy as np
import pytest
import torch

from pipeline.fewshot.checkpoint import CheckpointError, load_checkpoint, save_checkpoint
from pipeline.fewshot.model import ModelConfig, RelationNetwork

NORM = {"mean": [0.5, 0.4, 0.3], "std": [0.2, 0.2, 0.2]}


def _saved(tmp_path):
    torch.manual_seed(3)
    net = RelationNetwork(ModelConfig(24, 1))
    with torch.no_grad():  # move the running statistics away from their defaults
        net(torch.randn(2, 5, 3, 24, 24), torch.randn(4, 3, 24, 24))
    net.eval()
    path = save_checkpoint(
        tmp_path / "m" / "rn.pt",
        net,
        normalisation=NORM,
        config={"seed": 3},
        metrics={"val_accuracy": 0.8},
    )
    return net, path


def test_round_trip(tmp_path):
    net, path = _saved(tmp_path)
    loaded, payload = load_checkpoint(path, expected_model=ModelConfig(24, 1))
    assert not loaded.training
    assert payload["config"] == {"seed": 3} and payload["metrics"] == {"val_accuracy": 0.8}
    assert payload["normalisation"] == NORM
    x_s, x_q = torch.randn(5, 5, 3, 24, 24), torch.randn(3, 3, 24, 24)
    with torch.no_grad():
        np.testing.assert_array_equal(net(x_s, x_q).numpy(), loaded(x_s, x_q).numpy())
    assert [p.name for p in path.parent.iterdir()] == ["rn.pt"]  # no temporary file left


@pytest.mark.parametrize("damage", ["garbage", "truncated", "empty"])
def test_corrupt_checkpoint_names_file(tmp_path, damage):
    _, path = _saved(tmp_path)
    data = path.read_bytes()
    path.write_bytes(
        {"garbage": b"not a checkpoint at all", "truncated": data[: len(data) // 2], "empty": b""}[
            damage
        ]
    )
    with pytest.raises(CheckpointError, match=r"rn\.pt is corrupt"):
        load_checkpoint(path)


def test_missing_and_foreign_and_mismatched(tmp_path):
    with pytest.raises(CheckpointError, match="does not exist"):
        load_checkpoint(tmp_path / "nope.pt")
    torch.save({"weights": torch.zeros(3)}, tmp_path / "foreign.pt")
    with pytest.raises(CheckpointError, match="foreign.pt lacks required entries"):
        load_checkpoint(tmp_path / "foreign.pt")
    _, path = _saved(tmp_path)
    with pytest.raises(CheckpointError, match="was trained for"):
        load_checkpoint(path, expected_model=ModelConfig(84, 0))
    payload = torch.load(path, weights_only=True)
    payload["model"]["input_size"] = 84  # claims another shape than its weights have
    torch.save(payload, tmp_path / "mismatch.pt")
    with pytest.raises(CheckpointError, match="mismatch.pt does not match"):
        load_checkpoint(tmp_path / "mismatch.pt")
