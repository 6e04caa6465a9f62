"""Few-shot accuracy on the held-out families with intervals at the level the data vary (issue 42).

Meta-training quotes its test accuracy as a mean over 600 episodes with a 95% interval over those
episodes (:func:`.training._final_evaluation`): an interval for *these* 20 test families, narrow
because episodes are cheap. The families are the sample: a new draw of 20 families would give
another accuracy. Here the checkpoint a recogniser loaded (its network and input normalisation, as
the ``accuracy`` stage builds it) classifies ``episodes`` fresh C-way K-shot episodes (the
checkpoint's ``n_way``, ``k_shot`` and ``eval_queries``, in ``eval()`` mode) of the validation and
of the test families of the render (``images_dir``'s ``val`` and ``test`` splits), and every
episode keeps which families it drew and how many queries of each it got right
(:data:`OUTCOME_COLUMNS`, one row per episode and family: the unit of the two-level bootstrap).

Intervals (:func:`family_intervals`), both percentile bootstraps of the pooled accuracy (correct
over tested queries; every episode has ``n_way * eval_queries`` queries, so this is the mean
episode accuracy):

- episode-level: resample episodes with replacement (the families as they are);
- family-level (two-level, :func:`pipeline.stats.cluster_ratio_draws` with ``within``): resample
  the families that appear (as many as there are, with replacement), then, for each family drawn,
  its rows (the episodes it appeared in, as many as it has, with replacement). A row counts the
  queries whose true class is that family, in one episode (its support pictures and its four
  confusers). This resamples what a new set of families would change; it treats a family's rows
  as independent of other families' (they share episodes), and errs wide by counting the
  within-family variance twice (the docstring of the bootstrap).

Validation families chose the checkpoint, so their figure is optimistic. They are not apart from
the test families in the render's family split (only each from the training families): a check
of that needs a new split and a new training.
"""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from pipeline.stats import cluster_ratio_draws, percentile_ci

from .data import DataError, PictureSet, load_split, read_manifest, to_tensor
from .episodes import Episode, require_episodes, sample_episodes
from .settings import TrainConfig
from .training import embed_all

#: The splits measured (the render's held-out families), in this order.
SPLITS = ("val", "test")
#: One row per split, episode and family drawn: the family's index in its split (its name is
#: ``family_names[family]`` of the split's summary), its queries in the episode and those
#: classified right.
OUTCOME_COLUMNS = ("split", "episode", "family", "tested", "correct")
#: Bootstrap resamples of :func:`family_intervals`.
RESAMPLES = 2000
#: Embedding values of the query-class pairs :func:`episode_outcomes` scores at once (32 M floats,
#: 128 MB: 13 episodes of 5 x 75 pairs at 48 px, 3 at 84 px).
PAIR_VALUES = 32_000_000


def _scorer(network, features: torch.Tensor):
    """``score(support (E, C, K), query (E, Q)) -> (E, Q, C)``: the scores of ``E`` episodes from
    the eval-mode embeddings ``features``. The Relation Network's first relation convolution is
    split into class and query halves, each computed once per picture
    (:meth:`~.model.RelationModule.first_conv_halves`, as the recogniser does), so an episode runs
    only the rest of g_phi; scores agree with the plain forward pass to float rounding. Other
    networks score each episode as the training loop's evaluation does."""
    if network.kind != "relation_net":
        return lambda support, query: torch.stack(
            [
                network.scores(network.class_features(features[s]), features[q])
                for s, q in zip(torch.from_numpy(support), torch.from_numpy(query))
            ]
        )
    relation = network.relation
    class_half, query_half = relation.first_conv_halves(features, features)
    bias = relation.first_conv_bias()

    def score(support: np.ndarray, query: np.ndarray) -> torch.Tensor:
        classes = class_half[torch.from_numpy(support)].sum(2) + bias  # (E, C, 64, s, s)
        pairs = classes.unsqueeze(1) + query_half[torch.from_numpy(query)].unsqueeze(2)
        return relation.after_first_conv(pairs.flatten(0, 2)).view(*query.shape, -1)

    return score


@torch.no_grad()
def episode_outcomes(
    network,
    features: torch.Tensor,
    labels: np.ndarray,
    episodes: list[Episode],
    batch: int | None = None,
) -> dict[str, np.ndarray]:
    """Per episode and family drawn (way order): ``episode``, ``family`` (the class index of
    ``labels``), ``tested`` and ``correct`` queries of that family (arrays of equal length).
    Episodes are scored ``batch`` at a time (all of one shape, as :func:`.sample_episodes` draws
    them); by default as many as keep a batch's query-class pairs within :data:`PAIR_VALUES`
    embedding values (at most 16)."""
    network.eval()
    score = _scorer(network, features)
    if batch is None and episodes:
        pairs = episodes[0].query.size * episodes[0].support.shape[0]
        batch = int(np.clip(PAIR_VALUES // (pairs * features[0].numel()), 1, 16))
    rows = []
    for first in range(0, len(episodes), batch):
        chunk = episodes[first : first + batch]
        predicted = score(
            np.stack([ep.support for ep in chunk]), np.stack([ep.query for ep in chunk])
        ).argmax(2)
        for e, (ep, guess) in enumerate(zip(chunk, predicted.numpy()), start=first):
            n_way = ep.support.shape[0]
            tested = np.bincount(ep.labels, minlength=n_way)
            correct = np.bincount(ep.labels[guess == ep.labels], minlength=n_way)
            families = labels[ep.support[:, 0]]
            rows += [(e, int(families[w]), int(tested[w]), int(correct[w])) for w in range(n_way)]
    cols = np.array(rows, dtype=np.int64).reshape(-1, 4).T
    return dict(zip(("episode", "family", "tested", "correct"), cols))


def family_intervals(
    outcomes: dict[str, np.ndarray], *, resamples: int = RESAMPLES, seed=0
) -> dict:
    """The pooled accuracy of :func:`episode_outcomes` and its two 95% intervals (module
    docstring: ``episode_ci`` resamples episodes, ``family_ci`` families then their rows), with
    the episodes, the families and each family's own accuracy (by its class index, as text: a
    JSON key). Plain numbers, for ``summary.json``."""
    correct = np.asarray(outcomes["correct"], dtype=float)
    tested = np.asarray(outcomes["tested"], dtype=float)
    family = np.asarray(outcomes["family"])
    by_episode = cluster_ratio_draws(
        correct, tested, outcomes["episode"], within=False, resamples=resamples, seed=seed
    )
    by_family = cluster_ratio_draws(
        correct, tested, family, within=True, resamples=resamples, seed=seed
    )
    ids = np.unique(family)
    per_family = {
        str(int(f)): float(correct[family == f].sum() / tested[family == f].sum()) for f in ids
    }
    return {
        "accuracy": float(correct.sum() / tested.sum()),
        "episodes": int(np.unique(outcomes["episode"]).size),
        "families": int(ids.size),
        "episode_ci": list(percentile_ci(by_episode)),
        "family_ci": list(percentile_ci(by_family)),
        "per_family": per_family,
    }


def episode_shape(checkpoint_config: dict) -> TrainConfig:
    """The episode shape the checkpoint was evaluated with (``n_way``, ``k_shot``,
    ``eval_queries``, ``channels_last``; the training defaults where its config has none)."""
    keys = ("n_way", "k_shot", "eval_queries", "channels_last")
    return TrainConfig(**{k: checkpoint_config[k] for k in keys if k in checkpoint_config})


def _split_sets(images_dir: str | Path, size: int) -> dict[str, PictureSet]:
    frame = read_manifest(images_dir)
    have = set(frame["split"].astype(str))
    return {s: load_split(images_dir, s, size, frame) for s in SPLITS if s in have}


def family_study(
    network,
    checkpoint: dict,
    images_dir: str | Path,
    episodes: int,
    seed: int,
    *,
    resamples: int = RESAMPLES,
) -> tuple[pd.DataFrame, dict]:
    """Every episode's outcomes (:data:`OUTCOME_COLUMNS`) and, per split of :data:`SPLITS` that
    ``images_dir`` holds, :func:`family_intervals` and its ``family_names``, with the episode shape
    and the bootstrap's settings. ``checkpoint`` holds the loaded checkpoint's ``config`` and
    ``normalisation``. Split ``s``'s episodes come from ``sample_episodes([seed, i], ...)`` with
    ``i = SPLITS.index(s)`` (other episodes than meta-training's evaluation), and its bootstrap is
    seeded by ``[seed, i]`` too."""
    shape = episode_shape(checkpoint.get("config") or {})
    norm = checkpoint["normalisation"]
    frames, out = [], {}
    for split, pictures in _split_sets(images_dir, network.config.input_size).items():
        stream = [seed, SPLITS.index(split)]
        by_class = pictures.by_class()
        need = shape.k_shot + shape.eval_queries
        where = f"the {split} families of {images_dir}"
        require_episodes(by_class, pictures.class_names, shape.n_way, need, where)
        drawn = sample_episodes(
            stream,
            episodes,
            by_class,
            shape.n_way,
            shape.k_shot,
            shape.eval_queries,
        )
        images = to_tensor(pictures.images, norm["mean"], norm["std"])
        features = embed_all(network, images, shape.channels_last)
        outcomes = episode_outcomes(network, features, pictures.labels, drawn)
        summary = family_intervals(outcomes, resamples=resamples, seed=stream)
        out[split] = {**summary, "family_names": list(pictures.class_names)}
        frames.append(pd.DataFrame({"split": split, **outcomes}))
    if not out:
        raise DataError(f"{images_dir}: no val or test split, so no held-out families to measure")
    settings = {k: v for k, v in asdict(shape).items() if k in ("n_way", "k_shot", "eval_queries")}
    return pd.concat(frames, ignore_index=True)[list(OUTCOME_COLUMNS)], {
        **out,
        "episode_shape": settings,
        "episodes_per_split": int(episodes),
        "resamples": int(resamples),
        "seed": int(seed),
    }
