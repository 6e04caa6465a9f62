"""Intervals at the level the data vary (issue 42): the cluster / two-level bootstrap
(pipeline/stats.py), the held-out families' accuracy (pipeline/fewshot/family_accuracy.py) and the
colour test per hue shift with obstacles resampled (pipeline/fewshot/colour.py); small synthetic
inputs, seeded, exact where the arithmetic is."""

import numpy as np
import pytest

from pipeline.fewshot.colour import shift_changes
from pipeline.fewshot.family_accuracy import episode_outcomes, family_intervals
from pipeline.stats import bootstrap_means, cluster_means, cluster_ratio_draws, percentile_ci

# six units in three clusters of two: cluster 0 half right, 1 all right, 2 none
NUM, DEN, CLUSTERS = [1, 0, 1, 1, 0, 0], [1] * 6, [0, 0, 1, 1, 2, 2]


def test_cluster_draws_are_pinned_and_seeded():
    # six resamples of three clusters; the draws are sixths (counts of right units over six)
    two_level = cluster_ratio_draws(NUM, DEN, CLUSTERS, within=True, resamples=6, seed=0)
    one_level = cluster_ratio_draws(NUM, DEN, CLUSTERS, within=False, resamples=6, seed=0)
    assert (two_level * 6).round(9).tolist() == [4.0, 3.0, 2.0, 2.0, 4.0, 4.0]
    assert (one_level * 6).round(9).tolist() == [4.0, 3.0, 3.0, 2.0, 4.0, 4.0]
    again = cluster_ratio_draws(NUM, DEN, CLUSTERS, within=True, resamples=6, seed=0)
    assert np.array_equal(two_level, again)
    other = cluster_ratio_draws(NUM, DEN, CLUSTERS, within=True, resamples=6, seed=1)
    assert not np.array_equal(two_level, other)


def test_one_level_cluster_draws_are_the_bootstrap_of_cluster_means():
    """Clusters of equal size, all their units kept: the draws are bootstrap_means of the cluster
    means with the same seed (one stream of cluster indices); the block size changes no draw."""
    rng = np.random.default_rng(3)
    clusters = np.repeat(np.arange(10), 40)[rng.permutation(400)]  # ids in any order
    v = (rng.random(400) < 0.7).astype(float)
    draws = cluster_ratio_draws(v, np.ones(400), clusters, within=False, resamples=500, seed=5)
    expected = bootstrap_means(cluster_means(v, clusters), resamples=500, seed=5)
    assert draws == pytest.approx(expected, abs=1e-12)
    for within in (False, True):
        whole = cluster_ratio_draws(v, np.ones(400), clusters, within=within, resamples=500)
        blocks = cluster_ratio_draws(
            v, np.ones(400), clusters, within=within, resamples=500, block=7
        )
        assert np.array_equal(whole, blocks)


def test_two_level_equals_one_level_where_units_of_a_cluster_agree():
    """Stage 2 resamples units within a drawn cluster: where they are all alike it changes
    nothing (the clusters drawn come from one stream, whatever ``within``)."""
    clusters = np.repeat(np.arange(6), [3, 5, 2, 4, 4, 7])
    values = np.repeat([0.2, 0.9, 0.5, 0.0, 1.0, 0.4], [3, 5, 2, 4, 4, 7])
    weights = np.ones_like(values)
    two = cluster_ratio_draws(values, weights, clusters, within=True, resamples=300, seed=2)
    one = cluster_ratio_draws(values, weights, clusters, within=False, resamples=300, seed=2)
    assert two == pytest.approx(one, abs=1e-12)


def test_cluster_draws_refuse_ragged_input():
    with pytest.raises(ValueError, match="one length"):
        cluster_ratio_draws([1, 0], [1, 1, 1], [0, 1], within=True)
    with pytest.raises(ValueError, match="non-empty"):
        cluster_ratio_draws([], [], [], within=False)


def _outcomes(family_accuracy: np.ndarray, episodes: int, seed: int = 0) -> dict:
    """Synthetic :func:`episode_outcomes`: 5-way episodes of 15 queries a family, each family
    right with its own probability."""
    rng = np.random.default_rng(seed)
    drawn = np.stack([rng.choice(len(family_accuracy), 5, replace=False) for _ in range(episodes)])
    correct = rng.binomial(15, family_accuracy[drawn])
    return {
        "episode": np.repeat(np.arange(episodes), 5),
        "family": drawn.reshape(-1),
        "tested": np.full(drawn.size, 15),
        "correct": correct.reshape(-1),
    }


def test_family_level_interval_is_wider_where_families_differ():
    """Twenty families from 40% to 95% right: over 300 episodes the episode-level interval is
    narrow, the family-level one (a new draw of families) about four times as wide; where every
    family is alike, the two agree to within a third."""
    spread = _outcomes(np.linspace(0.4, 0.95, 20), 300)
    found = family_intervals(spread, resamples=1000, seed=0)
    total = spread["correct"].sum() / spread["tested"].sum()
    assert found["accuracy"] == total and found["episodes"] == 300 and found["families"] == 20
    assert found["per_family"]["3"] == pytest.approx(
        spread["correct"][spread["family"] == 3].sum()
        / spread["tested"][spread["family"] == 3].sum()
    )
    episode_width = np.diff(found["episode_ci"])[0]
    family_width = np.diff(found["family_ci"])[0]
    assert found["family_ci"][0] < total < found["family_ci"][1]
    assert family_width > 3 * episode_width
    alike = family_intervals(_outcomes(np.full(20, 0.7), 300), resamples=1000, seed=0)
    ratio = np.diff(alike["family_ci"])[0] / np.diff(alike["episode_ci"])[0]
    assert 0.75 < ratio < 1.5
    assert family_intervals(spread, resamples=1000, seed=0) == found  # seeded


def test_episode_outcomes_agree_with_the_training_evaluation():
    """The Relation Network's split first convolution and the Prototypical Network's plain scores
    give every episode the accuracy the meta-training evaluation gives it, and keep which
    families each episode drew."""
    import torch

    from pipeline.fewshot.episodes import sample_episodes
    from pipeline.fewshot.model import ModelConfig, RelationNetwork
    from pipeline.fewshot.protonet import PrototypicalNetwork
    from pipeline.fewshot.settings import ProtoConfig
    from pipeline.fewshot.training import embed_all, evaluate

    torch.manual_seed(0)
    labels = np.repeat(np.arange(7), 9)
    images = torch.randn(len(labels), 3, 24, 24) + torch.from_numpy(labels).view(-1, 1, 1, 1) / 3
    episodes = sample_episodes(4, 11, [np.flatnonzero(labels == c) for c in range(7)], 5, 3, 4)
    for network in (RelationNetwork(ModelConfig(24, 1)), PrototypicalNetwork(ProtoConfig(24))):
        network.eval()
        features = embed_all(network, images, channels_last=False)
        out = episode_outcomes(network, features, labels, episodes, batch=4)
        per_episode = np.bincount(out["episode"], weights=out["correct"]) / 20
        assert per_episode == pytest.approx(evaluate(network, features, episodes), abs=1e-12)
        assert out["family"].tolist() == [
            int(labels[e.support[w, 0]]) for e in episodes for w in range(5)
        ]
        assert (out["tested"] == 4).all()


def test_colour_change_per_shift_resamples_obstacles():
    """Three obstacles of two pictures: the change is turned minus as rendered, picture by
    picture; the interval's ends are means of three resampled obstacles' changes (-1/2, +1/2,
    -1/2)."""
    cats, obstacles = [0, 0, 1, 1, 2, 2], [0, 0, 1, 1, 2, 2]
    rendered = [0, 0, 1, 0, 2, 2]  # five right
    turned = [[0, 1, 1, 1, 0, 2], [0, 0, 1, 0, 2, 2]]  # four right; the same as rendered
    first, same = shift_changes(cats, rendered, turned, obstacles, resamples=6, seed=0)
    assert first["as_rendered"] == pytest.approx(5 / 6) and first["turned"] == pytest.approx(4 / 6)
    assert first["change"] == pytest.approx(-1 / 6)
    assert first["change_ci"] == pytest.approx(
        percentile_ci(
            cluster_ratio_draws(
                np.array([1, 0, 1, 1, 0, 1]) - np.array([1, 1, 1, 0, 1, 1]),
                np.ones(6),
                obstacles,
                within=False,
                resamples=6,
                seed=0,
            )
        )
    )
    assert first["change_ci"] == pytest.approx([-0.5, 1 / 6])
    assert same == {"as_rendered": 5 / 6, "turned": 5 / 6, "change": 0.0, "change_ci": [0.0, 0.0]}
