"""Relation Network checkpoints: the weights with the config and metrics that produced them and the
input normalisation. Written atomically (a temporary file in the same folder, then ``os.replace``),
read with ``torch.load(weights_only=True)``, and checked: a corrupt, foreign or mismatched file
raises :class:`CheckpointError` naming the file and the problem.
"""
from __future__ import annotations

import os
import tempfile
from dataclasses import asdict
from pathlib import Path
from typing import Any

import torch

from .model import ModelConfig, RelationNetwork

FORMAT = "relation-network/1"
REQUIRED = ("format", "model", "state_dict", "normalisation", "config", "metrics")


class CheckpointError(RuntimeError):
    """A checkpoint file cannot be used; the message names the file and what is wrong."""


def save_checkpoint(
    path: str | Path,
    network: RelationNetwork,
    *,
    normalisation: dict[str, list[float]],
    config: dict[str, Any],
    metrics: dict[str, Any],
) -> Path:
    """Write the checkpoint atomically; returns its path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = {
        "format": FORMAT,
        "model": asdict(network.config),
        "state_dict": {k: v.detach().clone().contiguous() for k, v in network.state_dict().items()},
        "normalisation": {"mean": [float(x) for x in normalisation["mean"]], "std": [float(x) for x in normalisation["std"]]},
        "config": config,
        "metrics": metrics,
    }
    fd, tmp = tempfile.mkstemp(prefix=path.name + ".", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            torch.save(payload, f)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600 files
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def load_checkpoint(path: str | Path, expected_model: ModelConfig | None = None) -> tuple[RelationNetwork, dict[str, Any]]:
    """Load a checkpoint into a fresh network in ``eval()`` mode. Returns ``(network, payload)``
    where the payload holds ``model``, ``normalisation``, ``config`` and ``metrics``.
    ``expected_model``, when given, must equal the checkpoint's model shape."""
    path = Path(path)
    hint = "retrain it with `python -m pipeline meta_train`"
    if not path.is_file():
        raise CheckpointError(f"checkpoint {path} does not exist; {hint}")
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises several types for truncated/garbage files
        raise CheckpointError(f"checkpoint {path} is corrupt or not a torch checkpoint ({type(exc).__name__}: {exc}); {hint}") from exc
    if not isinstance(payload, dict) or any(k not in payload for k in REQUIRED):
        have = sorted(payload) if isinstance(payload, dict) else type(payload).__name__
        raise CheckpointError(f"checkpoint {path} lacks required entries {list(REQUIRED)} (has {have}); {hint}")
    if payload["format"] != FORMAT:
        raise CheckpointError(f"checkpoint {path} has format {payload['format']!r}, expected {FORMAT!r}; {hint}")
    try:
        model = ModelConfig(**payload["model"])
    except (TypeError, ValueError) as exc:
        raise CheckpointError(f"checkpoint {path} has an invalid model config {payload['model']}: {exc}") from exc
    if expected_model is not None and model != expected_model:
        raise CheckpointError(f"checkpoint {path} was trained for {model}, but {expected_model} was asked for; {hint}")
    network = RelationNetwork(model)
    try:
        network.load_state_dict(payload["state_dict"], strict=True)
    except RuntimeError as exc:
        raise CheckpointError(f"checkpoint {path} does not match the Relation Network's weights: {exc}") from exc
    network.eval()
    return network, payload


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
