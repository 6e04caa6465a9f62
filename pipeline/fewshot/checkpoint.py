"""Few-shot network checkpoints (Relation Network or Prototypical Network): the weights with the
config and metrics that produced them and the input normalisation. The ``format`` entry names the
network (``relation-network/1``, ``prototypical-network/1``); loading one kind as the other is
refused. Written atomically (a temporary file in the same folder, then ``os.replace``),
read with ``torch.load(weights_only=True)``, and checked: a corrupt, foreign or mismatched file
raises :class:`CheckpointError` naming the file and the problem.
"""

from __future__ import annotations

import hashlib
from dataclasses import asdict
from pathlib import Path
from typing import Any

import torch

from pipeline.errors import UserError
from pipeline.files import atomic_output

from .model import ModelConfig, RelationNetwork
from .protonet import PrototypicalNetwork
from .settings import ProtoConfig

#: The ``format`` entry of each kind of network (``train.model``), its class and its shape.
FORMATS = {"relation_net": "relation-network/1", "protonet": "prototypical-network/1"}
NETWORKS = {
    "relation_net": (RelationNetwork, ModelConfig),
    "protonet": (PrototypicalNetwork, ProtoConfig),
}
NAMES = {"relation_net": "a Relation Network", "protonet": "a Prototypical Network"}
REQUIRED = ("format", "model", "state_dict", "normalisation", "config", "metrics")


class CheckpointError(UserError):
    """A checkpoint file cannot be used; the message names the file and what is wrong."""


def save_checkpoint(
    path: str | Path,
    network: RelationNetwork | PrototypicalNetwork,
    *,
    normalisation: dict[str, list[float]],
    config: dict[str, Any],
    metrics: dict[str, Any],
) -> Path:
    """Write the checkpoint atomically; returns its path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = {
        "format": FORMATS[network.kind],
        "model": asdict(network.config),
        "state_dict": {k: v.detach().clone().contiguous() for k, v in network.state_dict().items()},
        "normalisation": {
            "mean": [float(x) for x in normalisation["mean"]],
            "std": [float(x) for x in normalisation["std"]],
        },
        "config": config,
        "metrics": metrics,
    }
    with atomic_output(path) as f:
        torch.save(payload, f)
    return path


def file_sha256(path: str | Path) -> str:
    """SHA-256 of a file's bytes (the records name the exact checkpoint a trial used)."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def load_checkpoint(
    path: str | Path,
    expected_model: ModelConfig | ProtoConfig | None = None,
    kind: str = "relation_net",
) -> tuple[RelationNetwork | PrototypicalNetwork, dict[str, Any]]:
    """Load a checkpoint of network ``kind`` (``relation_net`` or ``protonet``) into a fresh
    network in ``eval()`` mode. Returns ``(network, payload)`` where the payload holds ``model``,
    ``normalisation``, ``config`` and ``metrics``. ``expected_model``, when given, must equal the
    checkpoint's model shape. A checkpoint of the other kind is refused."""
    path = Path(path)
    hint = "retrain it with `python -m pipeline meta_train" + (
        "`" if kind == "relation_net" else f" train.model={kind}`"
    )
    if not path.is_file():
        raise CheckpointError(f"checkpoint {path} does not exist; {hint}")
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises several types for truncated/garbage files
        first = (str(exc).strip().splitlines() or [""])[0][:200]
        raise CheckpointError(
            f"checkpoint {path} is corrupt or not a torch checkpoint ({type(exc).__name__}: {first}); {hint}"
        ) from None
    if not isinstance(payload, dict) or any(k not in payload for k in REQUIRED):
        have = sorted(payload) if isinstance(payload, dict) else type(payload).__name__
        raise CheckpointError(
            f"checkpoint {path} lacks required entries {list(REQUIRED)} (has {have}); {hint}"
        )
    if payload["format"] != FORMATS[kind]:
        other = {v: k for k, v in FORMATS.items()}.get(payload["format"])
        if other is not None:
            raise CheckpointError(
                f"checkpoint {path} holds {NAMES[other]} (train.model={other}), not {NAMES[kind]}; "
                f"load it with recogniser={other}"
            )
        raise CheckpointError(
            f"checkpoint {path} has format {payload['format']!r}, expected {FORMATS[kind]!r}; {hint}"
        )
    network_class, shape_class = NETWORKS[kind]
    try:
        model = shape_class(**payload["model"])
    except (TypeError, ValueError) as exc:
        raise CheckpointError(
            f"checkpoint {path} has an invalid model config {payload['model']}: {exc}"
        ) from exc
    if expected_model is not None and model != expected_model:
        raise CheckpointError(
            f"checkpoint {path} was trained for {model}, but {expected_model} was asked for; {hint}"
        )
    network = network_class(model)
    try:
        network.load_state_dict(payload["state_dict"], strict=True)
    except RuntimeError as exc:
        raise CheckpointError(
            f"checkpoint {path} does not match {NAMES[kind]}'s weights: {exc}"
        ) from exc
    network.eval()
    return network, payload
