"""Few-shot network checkpoints (Relation Network or Prototypical Network): the weights with the
config and metrics that produced them and the input normalisation. The ``format`` entry names the
network (``relation-network/1``, ``prototypical-network/1``); loading one kind as the other is
refused. Written atomically (a temporary file in the same folder, then ``os.replace``),
read with ``torch.load(weights_only=True)``, and checked: a corrupt, foreign or mismatched file
raises :class:`CheckpointError` naming the file and the problem. So does one that loads but cannot
score: a normalisation that is not three finite means and three positive standard deviations, a
weight of another type than the network's or with a NaN or infinite value, or a network whose
scores of a fixed probe episode (:func:`probe`) are not finite or not of the episode's shape.
"""

from __future__ import annotations

import hashlib
import math
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
#: The colour channels the normalisation has a mean and a standard deviation for.
CHANNELS = 3


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
    try:
        exists = path.is_file()
    except OSError as exc:  # a name over the file system's limit, a loop of links
        raise CheckpointError(
            f"checkpoint {path} cannot be opened ({exc.strerror or exc})"
        ) from None
    if not exists:
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
        named = payload["format"] if isinstance(payload["format"], str) else None
        other = {v: k for k, v in FORMATS.items()}.get(named)
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
    problem = normalisation_problem(payload["normalisation"]) or weights_problem(
        payload["state_dict"], network
    )
    if problem is None:
        try:
            network.load_state_dict(payload["state_dict"], strict=True)
        except RuntimeError as exc:
            problem = f"does not match {NAMES[kind]}'s weights: {_folded(exc)}"
    if problem is None:
        network.eval()
        problem = probe_problem(network)
    if problem is not None:
        raise CheckpointError(f"checkpoint {path} {problem}; {hint}")
    return network, payload


def _folded(exc: BaseException, limit: int = 300) -> str:
    """An exception's message on one line, cut at ``limit`` characters."""
    text = " ".join(str(exc).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def normalisation_problem(norm: Any) -> str | None:
    """What makes ``norm`` unusable as the input normalisation (three finite means, three finite
    positive standard deviations), or None."""
    if not isinstance(norm, dict) or any(k not in norm for k in ("mean", "std")):
        have = sorted(norm) if isinstance(norm, dict) else type(norm).__name__
        return f"has a normalisation without 'mean' and 'std' (has {have})"
    for key in ("mean", "std"):
        values = norm[key]
        if not isinstance(values, (list, tuple)):
            return (
                f"has a normalisation '{key}' of type {type(values).__name__}, not a list of "
                f"{CHANNELS} numbers (one per colour channel)"
            )
        if len(values) != CHANNELS:
            return (
                f"has a normalisation '{key}' of {len(values)} values, expected {CHANNELS} "
                "(one per colour channel)"
            )
        if not all(_number(v) and math.isfinite(v) for v in values):
            return f"has a normalisation '{key}' that is not {CHANNELS} finite numbers: {values}"
        if key == "std" and not all(v > 0 for v in values):
            return f"has a normalisation 'std' that is not positive: {values}"
    return None


def weights_problem(state_dict: Any, network: torch.nn.Module) -> str | None:
    """A weight of ``state_dict`` that is not a tensor of the network's type for it, or that holds
    a NaN or an infinite value, or None (missing and extra names are left to ``load_state_dict``)."""
    if not isinstance(state_dict, dict):
        return f"has weights of type {type(state_dict).__name__}, not a mapping of names to tensors"
    expected = network.state_dict()
    for name, value in state_dict.items():
        if name not in expected:
            continue
        if not isinstance(value, torch.Tensor):
            return f"has weight {name!r} of type {type(value).__name__}, not a tensor"
        if value.dtype != expected[name].dtype:
            return f"has weight {name!r} of type {value.dtype}, expected {expected[name].dtype}"
        if value.is_floating_point() and not bool(torch.isfinite(value).all()):
            nan, inf = int(torch.isnan(value).sum()), int(torch.isinf(value).sum())
            return (
                f"has weight {name!r} with {nan} NaN and {inf} infinite values of {value.numel()}"
            )
    return None


def probe(network: RelationNetwork | PrototypicalNetwork) -> torch.Tensor:
    """The network's scores of a fixed 2-way 1-shot episode of 2 queries (normal noise of a fixed
    seed at the network's input size): a (2, 2) tensor of finite numbers for a usable network."""
    size = network.config.input_size
    noise = torch.randn(4, 3, size, size, generator=torch.Generator().manual_seed(0))
    with torch.no_grad():
        return network(noise[:2].unflatten(0, (2, 1)), noise[2:4])


def probe_problem(network: RelationNetwork | PrototypicalNetwork) -> str | None:
    """What is wrong with the network's :func:`probe` scores, or None."""
    scores = probe(network)
    if tuple(scores.shape) != (2, 2):
        return (
            f"scores a 2-way probe episode of 2 queries as shape {tuple(scores.shape)}, not (2, 2)"
        )
    if not bool(torch.isfinite(scores).all()):
        return f"gives scores that are not finite on a probe episode: {scores.tolist()}"
    return None
