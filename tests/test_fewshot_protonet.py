"""Prototypical Networks (pipeline.fewshot.protonet): prototypes, distances and log-probabilities
pinned to hand-computed values; a seeded training run beats chance; checkpoints name their kind;
the recogniser keeps the dynamic support set and scores with the softmax of -distances."""

import math

import numpy as np
import pytest
import torch

from pipeline.errors import ConfigError
from pipeline.fewshot.checkpoint import CheckpointError, load_checkpoint, save_checkpoint
from pipeline.fewshot.data import load_split, to_tensor
from pipeline.fewshot.model import ModelConfig, RelationNetwork
from pipeline.fewshot.protonet import PrototypicalNetwork, negative_squared_distances, prototypes
from pipeline.fewshot.recogniser import ProtoRecogniser, RelationRecogniser
from pipeline.fewshot.settings import ProtoConfig
from pipeline.fewshot.synthetic import write_synthetic_dataset
from pipeline.fewshot.training import TrainConfig, meta_train
from pipeline.rl.recogniser import Recogniser
from pipeline.threads import cores

NORM = {"mean": [0.4, 0.4, 0.4], "std": [0.25, 0.25, 0.25]}

# 2-way 2-shot with 2-d embeddings: class 0 at (0,0), (2,0) -> prototype (1,0); class 1 at (0,2),
# (0,4) -> prototype (0,3). Query (1,1): distances 1 and 5; query (0,3): distances 10 and 0.
SUPPORT = torch.tensor([[[0.0, 0.0], [2.0, 0.0]], [[0.0, 2.0], [0.0, 4.0]]])
QUERY = torch.tensor([[1.0, 1.0], [0.0, 3.0]])


def test_prototypes_distances_and_log_probabilities_by_hand():
    protos = prototypes(SUPPORT)
    assert protos.tolist() == [[1.0, 0.0], [0.0, 3.0]]
    logits = negative_squared_distances(protos, QUERY)
    assert logits.tolist() == [[-1.0, -5.0], [-10.0, -0.0]]
    log_p = torch.log_softmax(logits, dim=1)
    expected = [
        [-math.log1p(math.exp(-4)), -4 - math.log1p(math.exp(-4))],
        [-10 - math.log1p(math.exp(-10)), -math.log1p(math.exp(-10))],
    ]
    np.testing.assert_allclose(log_p.numpy(), expected, atol=1e-6)  # float32
    loss = PrototypicalNetwork.loss(logits, torch.tensor([0, 1]))
    assert float(loss) == pytest.approx(
        (math.log1p(math.exp(-4)) + math.log1p(math.exp(-10))) / 2, abs=1e-6
    )
    net = PrototypicalNetwork(ProtoConfig(24))  # the network's methods are the same functions
    assert net.scores(net.class_features(SUPPORT), QUERY).tolist() == logits.tolist()


def test_forward_is_embedding_then_prototypes():
    torch.manual_seed(0)
    net = PrototypicalNetwork(ProtoConfig(24)).eval()
    support, query = torch.randn(3, 2, 3, 24, 24), torch.randn(4, 3, 24, 24)
    with torch.no_grad():
        logits = net(support, query)
        f_s = net.embedding(support.flatten(0, 1)).flatten(1).view(3, 2, -1)
        f_q = net.embedding(query).flatten(1)
    assert logits.shape == (4, 3) and f_q.shape[1] == ProtoConfig(24).embedding_dim == 64 * 4 * 4
    ref = -(torch.cdist(f_q, f_s.mean(1)) ** 2)
    torch.testing.assert_close(logits, ref, rtol=1e-4, atol=1e-3)


def test_protonet_config_refuses_relation_padding():
    with pytest.raises(ConfigError, match="train.relation_padding"):
        TrainConfig(model="protonet", relation_padding=1)
    assert isinstance(TrainConfig(model="protonet", input_size=24).network_config(), ProtoConfig)
    with pytest.raises(ConfigError, match="train.model"):
        TrainConfig(model="matching_net")


@pytest.fixture(scope="module")
def images(tmp_path_factory):
    root = tmp_path_factory.mktemp("protonet") / "images"
    write_synthetic_dataset(root, n_train=8, n_val=6, per_class=12, seed=0)
    return root


def test_seeded_training_beats_chance(images):
    train, val = load_split(images, "train", 24), load_split(images, "val", 24)
    torch.set_num_threads(cores())  # its share of the cores under pytest-xdist
    cfg = TrainConfig(
        model="protonet",
        input_size=24,
        n_query=3,
        episodes=10,
        val_every=5,
        val_episodes=30,
        eval_episodes=60,
        eval_queries=5,
    )
    # a clock that stands still: all 10 episodes run, however loaded the machine
    result = meta_train(train, val, cfg, progress=False, clock=lambda: 0.0)
    m = result.metrics
    assert isinstance(result.network, PrototypicalNetwork) and m["model"] == "protonet"
    assert m["val_accuracy"] - m["val_ci95"] > 0.5  # chance is 0.2
    assert m["episodes_trained"] == 10
    again = meta_train(train, val, cfg, progress=False, clock=lambda: 0.0)
    assert again.metrics["val_accuracy"] == m["val_accuracy"]  # seeded
    for k, v in result.network.state_dict().items():
        torch.testing.assert_close(v, again.network.state_dict()[k], rtol=0, atol=0)


def _checkpoint(root):
    torch.manual_seed(0)
    net = PrototypicalNetwork(ProtoConfig(24))
    with torch.no_grad():  # move the batch-norm statistics off their defaults
        net(torch.randn(5, 5, 3, 24, 24), torch.randn(10, 3, 24, 24))
    net.eval()
    return net, save_checkpoint(root / "pn.pt", net, normalisation=NORM, config={}, metrics={})


def test_checkpoints_name_their_kind(tmp_path):
    net, path = _checkpoint(tmp_path)
    loaded, payload = load_checkpoint(path, ProtoConfig(24), kind="protonet")
    assert payload["format"] == "prototypical-network/1" and isinstance(loaded, PrototypicalNetwork)
    x_s, x_q = torch.randn(5, 2, 3, 24, 24), torch.randn(3, 3, 24, 24)
    with torch.no_grad():
        np.testing.assert_array_equal(net(x_s, x_q).numpy(), loaded(x_s, x_q).numpy())
    with pytest.raises(
        CheckpointError,
        match=r"pn\.pt holds a Prototypical Network \(train.model=protonet\), "
        r"not a Relation Network; load it with recogniser=protonet",
    ):
        load_checkpoint(path)
    rn = save_checkpoint(
        tmp_path / "rn.pt",
        RelationNetwork(ModelConfig(24, 1)),
        normalisation=NORM,
        config={},
        metrics={},
    )
    with pytest.raises(
        CheckpointError, match="holds a Relation Network .* not a Prototypical Network"
    ):
        load_checkpoint(rn, kind="protonet")
    with pytest.raises(CheckpointError, match="was trained for"):
        load_checkpoint(path, ProtoConfig(48), kind="protonet")


@pytest.fixture(scope="module")
def recogniser_setup(tmp_path_factory):
    root = tmp_path_factory.mktemp("protonet_rec")
    write_synthetic_dataset(root / "images", n_train=5, n_val=5, per_class=2, seed=1)
    net, ckpt = _checkpoint(root)
    with torch.no_grad():
        f_q = net.embed(to_tensor(load_split(root / "images", "query", 24).images, **NORM))
        f_s = net.embed(to_tensor(load_split(root / "images", "support", 24).images, **NORM))
    return root, ckpt, f_q, f_s


def _reference(f_q, f_s, members):
    protos = torch.stack(
        [torch.stack([f_q[m] if m >= 0 else f_s[-m - 1] for m in cls]).mean(0) for cls in members]
    )
    return torch.softmax(-(torch.cdist(f_q.double(), protos.double()) ** 2), dim=1).numpy()


def test_recogniser_scores_are_the_softmax_of_minus_distances(recogniser_setup):
    root, ckpt, f_q, f_s = recogniser_setup
    rec = ProtoRecogniser.from_files(ckpt, root / "images", input_size=24, substitution_way=1)
    assert isinstance(rec, Recogniser) and rec.describe()["kind"] == "protonet"
    rec.start_run(0, seed=5)
    scores = rec.scores(0, np.arange(40))
    assert scores.min() >= 0 and scores.max() <= 1
    np.testing.assert_allclose(scores.sum(1), 1, atol=1e-5)
    np.testing.assert_allclose(scores, _reference(f_q, f_s, rec.support_members(0)), atol=1e-4)
    np.testing.assert_array_equal(rec.predictions(0), scores.argmax(1))
    with pytest.raises(CheckpointError, match="holds a Prototypical Network"):
        RelationRecogniser.from_files(ckpt, root / "images")


def test_substitution_updates_one_prototype(recogniser_setup):
    root, ckpt, f_q, f_s = recogniser_setup
    rec = ProtoRecogniser.from_files(ckpt, root / "images", substitution_way=1)
    rec.start_run(0, seed=5)
    rec.predictions(0)
    logits = rec._runs[0].table.copy()
    assert rec.learn_from_collision(0, picture_id=10, true_category=1) == 0
    assert rec.learn_from_collision(0, picture_id=12, true_category=1) == 1
    assert rec._runs[0].valid.tolist() == [True, False, True, True, True]  # only column 1 is stale
    after = rec.scores(0, np.arange(40))
    np.testing.assert_array_equal(np.delete(rec._runs[0].table, 1, 1), np.delete(logits, 1, 1))
    assert rec.support_members(0)[1, :2].tolist() == [10, 12]
    np.testing.assert_allclose(after, _reference(f_q, f_s, rec.support_members(0)), atol=1e-4)
    rec.start_run(0, seed=5)  # restored
    np.testing.assert_array_equal(rec._runs[0].table, logits)


def test_carry_over_and_static(recogniser_setup):
    root, ckpt, *_ = recogniser_setup
    rec = ProtoRecogniser.from_files(ckpt, root / "images", substitution_way=1, carry_over=True)
    rec.start_run(0, seed=1)
    rec.learn_from_collision(0, 33, 4)
    rec.start_run(0, seed=2)
    assert rec.support_members(0)[4, 0] == 33
    assert rec.learn_from_collision(0, 34, 4) == 1
    static = ProtoRecogniser.from_files(ckpt, root / "images", substitution_way=0)
    static.start_run(0, seed=1)
    assert static.learn_from_collision(0, 5, 0) == -1
