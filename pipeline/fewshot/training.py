"""Episodic meta-training of the Relation Network (Sung et al. 2018, section 3; the paper's
section 3.2.1): C-way K-shot episodes from the training classes, MSE between relation scores and
one-hot targets, Adam. ``train.model=protonet`` trains a Prototypical Network (Snell et al. 2017,
:mod:`.protonet`) in the same loop, on the same episodes, with its own loss (cross-entropy of the
negative squared distances to the prototypes).

Model selection uses the *validation classes* only (a fixed, seeded list of validation episodes,
evaluated every ``val_every`` training episodes); the obstacle query and support pictures are never
seen. Evaluation runs in ``eval()`` mode, so batch norm uses its running statistics and one
query cannot leak into another's score. The reference implementation of Sung et al. instead
keeps batch norm in training mode at test time and picks its checkpoint on the test episodes; we do
neither. The quoted figure is the mean accuracy over ``eval_episodes`` (600) episodes of the *test
classes* (Ravi and Larochelle's third split, never seen in training or selection), with its 95%
interval; beside it, the same over fresh validation episodes (another seed than the selection
episodes).

In eval mode a picture's embedding does not depend on the other pictures, so evaluation embeds
every validation picture once and runs only the relation module per episode.
"""

from __future__ import annotations

import copy
import logging
import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import torch
from tqdm.auto import tqdm

from .data import PictureSet, channel_stats, to_tensor
from .episodes import Episode, mean_and_ci95, sample_episode, sample_episodes
from .model import RelationNetwork
from .protonet import PrototypicalNetwork
from .settings import LR_SCHEDULES, ModelConfig, ProtoConfig, TrainConfig  # noqa: F401  (re-exported)

#: A few-shot network: ``kind``, ``embedding``, ``class_features``, ``scores``, ``loss``.
Network = RelationNetwork | PrototypicalNetwork

log = logging.getLogger(__name__)


@dataclass
class TrainResult:
    """The selected network (in eval mode) and everything measured while training it."""

    network: Network
    normalisation: dict[str, list[float]]
    metrics: dict[str, Any]
    history: list[dict[str, float]] = field(default_factory=list)


def _lr_lambda(config: TrainConfig):
    if config.lr_schedule == "constant":
        return lambda step: 1.0
    if config.lr_schedule == "step":
        return lambda step: 0.5 ** (step // config.lr_step)
    lo = config.min_lr_fraction
    return lambda step: (
        lo + (1 - lo) * 0.5 * (1 + math.cos(math.pi * min(step, config.episodes) / config.episodes))
    )


def _format(x: torch.Tensor, channels_last: bool) -> torch.Tensor:
    return x.contiguous(memory_format=torch.channels_last) if channels_last else x


@torch.no_grad()
def embed_all(
    network: Network, images: torch.Tensor, channels_last: bool = True, batch: int = 256
) -> torch.Tensor:
    """f_varphi of every picture, in eval mode, in fixed-size batches (N, 64, s, s)."""
    network.eval()
    out = [
        network.embedding(_format(images[i : i + batch], channels_last))
        for i in range(0, len(images), batch)
    ]
    return torch.cat(out).contiguous()


@torch.no_grad()
def evaluate(network: Network, features: torch.Tensor, episodes: list[Episode]) -> np.ndarray:
    """Accuracy of every episode from precomputed eval-mode embeddings ``features``."""
    network.eval()
    acc = np.empty(len(episodes))
    for i, ep in enumerate(episodes):
        class_f = network.class_features(features[torch.from_numpy(ep.support)])
        scores = network.scores(class_f, features[torch.from_numpy(ep.query)])
        acc[i] = float((scores.argmax(1).numpy() == ep.labels).mean())
    return acc


def build_network(config: TrainConfig) -> Network:
    """A freshly initialised network of the kind ``config.model`` names."""
    shape = config.network_config()
    return PrototypicalNetwork(shape) if config.model == "protonet" else RelationNetwork(shape)


def _train_step(network: Network, optimiser, scheduler, rng, x_train, by_train, labels, config):
    """One meta-training episode: sample it, (optionally) flip pictures, one Adam step; returns
    the episode's loss."""
    network.train()
    ep = sample_episode(rng, by_train, config.n_way, config.k_shot, config.n_query)
    idx = torch.from_numpy(np.concatenate([ep.support.reshape(-1), ep.query]))
    images = x_train[idx]
    if config.flip:
        flip = torch.from_numpy(rng.random(len(idx)) < 0.5)
        images = torch.where(flip.view(-1, 1, 1, 1), images.flip(3), images)
    images = _format(images, config.channels_last)
    n_support = config.n_way * config.k_shot
    support = images[:n_support].unflatten(0, (config.n_way, config.k_shot))
    scores = network(support, images[n_support:])
    loss = network.loss(scores, labels)
    optimiser.zero_grad(set_to_none=True)
    loss.backward()
    optimiser.step()
    scheduler.step()
    return float(loss.detach())


@dataclass
class _Selection:
    """Checkpoint selection on the validation classes: the best accuracy so far, its episode and
    weights, the validation history and when the target accuracy was first reached."""

    val_accuracy: float = -1.0
    episode: int = 0
    state: dict | None = None
    history: list[dict[str, float]] = field(default_factory=list)
    time_to_goal: float | None = None

    def check(
        self,
        network: Network,
        accuracy: float,
        *,
        done: int,
        loss: float,
        elapsed: float,
        lr: float,
        target: float,
    ) -> None:
        """Record one validation of the network after ``done`` episodes; keep it if it is best."""
        self.history.append(
            {
                "episode": done,
                "loss": loss,
                "val_accuracy": accuracy,
                "elapsed_s": elapsed,
                "lr": lr,
            }
        )
        if accuracy > self.val_accuracy:
            self.val_accuracy, self.episode = accuracy, done
            self.state = copy.deepcopy(network.state_dict())
        if self.time_to_goal is None and accuracy >= target:
            self.time_to_goal = elapsed
        log.info(
            "episode %d: loss %.4f, selection accuracy %.4f (best %.4f), %.0f s",
            done,
            loss,
            accuracy,
            self.val_accuracy,
            elapsed,
        )


def meta_train(
    train: PictureSet,
    val: PictureSet,
    config: TrainConfig,
    progress: bool = True,
    test: PictureSet | None = None,
    clock: Callable[[], float] = time.perf_counter,
) -> TrainResult:
    """Meta-train on ``train``'s classes, select the checkpoint on ``val``'s classes and, given
    ``test``, measure it on the test classes (``test_*`` metrics; without it there are none).
    ``clock`` (seconds) times the loop against ``max_minutes``: the loop stops after the first
    episode that ends with the budget spent."""
    torch.manual_seed(config.seed)
    rng = np.random.default_rng(config.seed)
    mean, std = channel_stats(train.images)
    x_train = to_tensor(train.images, mean, std)
    x_val = to_tensor(val.images, mean, std)
    by_train, by_val = train.by_class(), val.by_class()
    select_eps = sample_episodes(
        config.seed + 1,
        config.val_episodes,
        by_val,
        config.n_way,
        config.k_shot,
        config.eval_queries,
    )

    network = build_network(config)
    if config.channels_last:
        network = network.to(memory_format=torch.channels_last)
    optimiser = torch.optim.Adam(network.parameters(), lr=config.lr)
    scheduler = torch.optim.lr_scheduler.LambdaLR(optimiser, _lr_lambda(config))
    labels = torch.from_numpy(np.repeat(np.arange(config.n_way), config.n_query))

    best = _Selection()
    losses: list[float] = []
    start = clock()
    budget = config.max_minutes * 60.0
    done = 0
    bar = tqdm(range(config.episodes), desc="meta-train", disable=not progress, mininterval=2.0)
    for step in bar:
        losses.append(
            _train_step(network, optimiser, scheduler, rng, x_train, by_train, labels, config)
        )
        done = step + 1
        out_of_time = clock() - start > budget
        if done % config.val_every == 0 or done == config.episodes or out_of_time:
            acc = float(
                evaluate(
                    network, embed_all(network, x_val, config.channels_last), select_eps
                ).mean()
            )
            loss = float(np.mean(losses[-config.val_every :]))
            best.check(
                network,
                acc,
                done=done,
                loss=loss,
                elapsed=clock() - start,
                lr=scheduler.get_last_lr()[0],
                target=config.target_accuracy,
            )
            bar.set_postfix(loss=f"{loss:.4f}", val=f"{acc:.3f}", best=f"{best.val_accuracy:.3f}")
        if out_of_time:
            break
    bar.close()
    train_seconds = clock() - start
    network.load_state_dict(best.state)
    network.eval()
    val_accuracy, val_ci95, eval_seconds = _final_evaluation(network, x_val, by_val, config)
    tested = {}
    if test is not None:
        x_test = to_tensor(test.images, mean, std)
        test_accuracy, test_ci95, test_seconds = _final_evaluation(
            network, x_test, test.by_class(), config, seed_offset=3
        )
        eval_seconds += test_seconds
        tested = {
            "test_accuracy": test_accuracy,
            "test_ci95": test_ci95,
            "test_episodes": config.eval_episodes,
            "n_test_classes": test.n_classes,
        }
    metrics = {
        **tested,
        "val_accuracy": val_accuracy,
        "val_ci95": val_ci95,
        "val_episodes": config.eval_episodes,
        "selection_val_accuracy": best.val_accuracy,
        "selected_episode": best.episode,
        "episodes_trained": done,
        "stopped_by_time_budget": done < config.episodes,
        "train_seconds": train_seconds,
        "eval_seconds": eval_seconds,
        "time_to_target_s": best.time_to_goal,
        "target_accuracy": config.target_accuracy,
        "n_train_classes": train.n_classes,
        "n_val_classes": val.n_classes,
        "torch_threads": torch.get_num_threads(),
        "model": config.model,
    }
    network = network.to(memory_format=torch.contiguous_format)
    return TrainResult(
        network=network,
        normalisation={"mean": mean, "std": std},
        metrics=metrics,
        history=best.history,
    )


def _final_evaluation(network: Network, x_val, by_val, config: TrainConfig, seed_offset: int = 2):
    """The selected network's mean accuracy on ``eval_episodes`` fresh episodes of the classes
    ``by_val`` (validation: another seed than the selection episodes; test: ``seed_offset`` 3),
    its 95% interval and the seconds it took."""
    t0 = time.perf_counter()
    eval_eps = sample_episodes(
        config.seed + seed_offset,
        config.eval_episodes,
        by_val,
        config.n_way,
        config.k_shot,
        config.eval_queries,
    )
    acc = evaluate(network, embed_all(network, x_val, config.channels_last), eval_eps)
    mean_acc, ci95 = mean_and_ci95(acc)
    return mean_acc, ci95, time.perf_counter() - t0


def config_dict(config: TrainConfig) -> dict[str, Any]:
    return asdict(config)
