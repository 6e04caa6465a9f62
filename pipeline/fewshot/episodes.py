"""Episodic sampling for C-way K-shot meta-training and evaluation (Sung et al. 2018, section 3.1;
the paper's section 3.2.1): each episode draws C classes, K support and Q query pictures per class.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .data import DataError


@dataclass(frozen=True)
class Episode:
    """Picture indices of one episode: ``support`` (C, K), ``query`` (C * Q,) and the query
    ``labels`` (C * Q,) in 0..C-1 (episode-local class order)."""

    support: np.ndarray
    query: np.ndarray
    labels: np.ndarray


def sample_episode(
    rng: np.random.Generator, by_class: list[np.ndarray], n_way: int, k_shot: int, n_query: int
) -> Episode:
    """Draw ``n_way`` distinct classes, then ``k_shot + n_query`` distinct pictures of each."""
    if n_way > len(by_class):
        raise DataError(
            f"{n_way}-way episodes need at least {n_way} classes, the split has {len(by_class)}"
        )
    need = k_shot + n_query
    classes = rng.choice(len(by_class), size=n_way, replace=False)
    support = np.empty((n_way, k_shot), dtype=np.int64)
    query = np.empty((n_way, n_query), dtype=np.int64)
    for i, c in enumerate(classes):
        members = by_class[c]
        if len(members) < need:
            raise DataError(
                f"class {c} has {len(members)} pictures; an episode needs {need} (k_shot + n_query)"
            )
        pick = rng.choice(members, size=need, replace=False)
        support[i], query[i] = pick[:k_shot], pick[k_shot:]
    labels = np.repeat(np.arange(n_way), n_query)
    return Episode(support=support, query=query.reshape(-1), labels=labels)


def require_episodes(
    by_class: list[np.ndarray], class_names: tuple[str, ...], n_way: int, need: int, where: str
) -> None:
    """Refuse, before any training, a split that cannot give ``n_way``-way episodes of ``need``
    pictures per class (:func:`sample_episode` would fail only when it draws a short class)."""
    if len(by_class) < n_way:
        raise DataError(
            f"{where}: {len(by_class)} classes; {n_way}-way episodes need at least {n_way}"
        )
    short = [f"{class_names[c]} ({len(m)})" for c, m in enumerate(by_class) if len(m) < need]
    if short:
        shown = ", ".join(short[:5]) + (f" and {len(short) - 5} more" if len(short) > 5 else "")
        raise DataError(
            f"{where}: an episode needs {need} pictures of a class (k_shot + queries); too few in {shown}"
        )


def sample_episodes(
    seed: int, n: int, by_class: list[np.ndarray], n_way: int, k_shot: int, n_query: int
) -> list[Episode]:
    """``n`` episodes from one seeded stream (the same list for the same arguments)."""
    rng = np.random.default_rng(seed)
    return [sample_episode(rng, by_class, n_way, k_shot, n_query) for _ in range(n)]


def mean_and_ci95(accuracies: np.ndarray) -> tuple[float, float]:
    """Mean accuracy and the half-width of its 95% confidence interval (1.96 standard errors), as
    Sung et al. report over 600 test episodes."""
    acc = np.asarray(accuracies, dtype=np.float64)
    if acc.size == 0:
        raise ValueError("no episodes to average")
    half = 1.96 * acc.std(ddof=1) / np.sqrt(acc.size) if acc.size > 1 else float("nan")
    return float(acc.mean()), float(half)
