"""Meta-training on tiny synthetic classes beats chance clearly and is deterministic; the time
budget (``max_minutes``) is honoured on an injected clock; the manifest contract is checked.

No test here depends on the machine's speed: training runs on a clock that stands still (the
budget never runs out), or on one where each episode takes a minute."""

import numpy as np
import pytest
import torch

from pipeline.fewshot.data import DataError, load_split, read_manifest
from pipeline.fewshot.episodes import mean_and_ci95, sample_episode
from pipeline.fewshot.synthetic import write_synthetic_dataset
from pipeline.fewshot.training import TrainConfig, meta_train
from pipeline.threads import cores

TINY = dict(
    input_size=24,
    relation_padding=1,
    n_query=2,
    episodes=20,
    val_every=10,
    val_episodes=10,
    eval_episodes=60,
    eval_queries=5,
)


def frozen() -> float:
    """A clock that stands still: the time budget never runs out, whatever the machine's load."""
    return 0.0


@pytest.fixture(scope="module")
def images(tmp_path_factory):
    root = tmp_path_factory.mktemp("fewshot_train") / "images"
    write_synthetic_dataset(root, n_train=8, n_val=6, per_class=12, seed=0)
    return root


def test_short_training_beats_chance(images):
    train, val = load_split(images, "train", 24), load_split(images, "val", 24)
    torch.set_num_threads(cores())  # its share of the cores under pytest-xdist
    result = meta_train(train, val, TrainConfig(**TINY), progress=False, clock=frozen)
    m = result.metrics
    assert m["val_accuracy"] - m["val_ci95"] > 0.5  # chance is 0.2
    assert m["val_episodes"] == 60 and m["episodes_trained"] == 20
    assert m["selected_episode"] in (10, 20) and not m["stopped_by_time_budget"]
    assert not result.network.training
    assert [h["episode"] for h in result.history] == [10, 20]


def test_training_is_deterministic(images):
    train, val = load_split(images, "train", 24), load_split(images, "val", 24)
    cfg = TrainConfig(
        **{**TINY, "episodes": 6, "val_every": 3, "val_episodes": 5, "eval_episodes": 5}
    )
    a = meta_train(train, val, cfg, progress=False, clock=frozen)
    b = meta_train(train, val, cfg, progress=False, clock=frozen)
    for k, v in a.network.state_dict().items():
        torch.testing.assert_close(v, b.network.state_dict()[k], rtol=0, atol=0)
    assert a.metrics["val_accuracy"] == b.metrics["val_accuracy"]


@pytest.mark.parametrize(
    "max_minutes, trained, history",
    [
        (2.5, 3, [(2, 120.0), (3, 180.0)]),  # past the budget in episode 3: validated, then stop
        (4.0, 5, [(2, 120.0), (4, 240.0), (5, 300.0)]),  # at 4 min the budget is spent, not past
        (10.0, 6, [(2, 120.0), (4, 240.0), (6, 360.0)]),  # every episode within the budget
    ],
)
def test_the_time_budget_stops_after_the_episode_that_spends_it(
    images, monkeypatch, max_minutes, trained, history
):
    """On a clock where each training episode takes one minute, ``max_minutes`` stops the loop
    after the episode that takes it past the budget; that episode is validated (a candidate for
    selection) and the metrics say the budget stopped it."""
    from pipeline.fewshot import training

    now, step = [0.0], training._train_step

    def one_minute(*args, **kwargs):
        now[0] += 60.0
        return step(*args, **kwargs)

    monkeypatch.setattr(training, "_train_step", one_minute)
    train, val = load_split(images, "train", 24), load_split(images, "val", 24)
    cfg = TrainConfig(
        **{**TINY, "episodes": 6, "val_every": 2, "val_episodes": 3, "eval_episodes": 3},
        max_minutes=max_minutes,
    )
    result = meta_train(train, val, cfg, progress=False, clock=lambda: now[0])
    m = result.metrics
    assert m["episodes_trained"] == trained
    assert m["stopped_by_time_budget"] == (trained < 6)
    assert m["train_seconds"] == 60.0 * trained
    assert [(h["episode"], h["elapsed_s"]) for h in result.history] == history
    assert m["selected_episode"] in [e for e, _ in history]


def test_episodes_and_interval():
    by_class = [np.arange(10 * c, 10 * c + 10) for c in range(6)]
    ep = sample_episode(np.random.default_rng(0), by_class, 5, 5, 3)
    assert ep.support.shape == (5, 5) and ep.query.shape == (15,)
    assert len(set(ep.support.ravel()) | set(ep.query)) == 40  # no picture twice
    for i in range(5):  # support and queries of row i come from one class
        assert (
            len({x // 10 for x in ep.support[i]} | {x // 10 for x in ep.query[ep.labels == i]}) == 1
        )
    mean, half = mean_and_ci95(np.array([0.5, 0.7, 0.6, 0.8]))
    assert mean == pytest.approx(0.65) and half == pytest.approx(
        1.96 * np.std([0.5, 0.7, 0.6, 0.8], ddof=1) / 2
    )


def test_manifest_contract(images, tmp_path):
    frame = read_manifest(images)
    q = load_split(images, "query", 24, frame)
    assert q.images.shape == (40, 24, 24, 3) and q.picture_ids.tolist() == list(range(40))
    assert load_split(images, "support", 24, frame).n_classes == 5
    with pytest.raises(DataError, match="no picture manifest"):
        read_manifest(tmp_path)
    frame.drop(columns=["face"]).to_csv(tmp_path / "manifest.csv", index=False)
    with pytest.raises(DataError, match=r"missing column\(s\) \['face'\]"):
        read_manifest(tmp_path)
    bad = frame.copy()
    bad["file"] = "missing/" + bad["file"]
    (tmp_path / "b").mkdir()
    bad.to_csv(tmp_path / "b" / "manifest.csv", index=False)
    with pytest.raises(DataError, match="cannot read picture"):
        load_split(tmp_path / "b", "val", 24)
    with pytest.raises(ValueError, match="config key 'train.episodes': must be >= 1; got 0"):
        TrainConfig(episodes=0)
