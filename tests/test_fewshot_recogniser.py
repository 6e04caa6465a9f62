"""The Relation Network recogniser: the trial runner's protocol, scores equal to the plain forward
pass, per-class recomputation after a substitution, run ownership and carry-over."""

import ast
from pathlib import Path

import numpy as np
import pytest
import torch
from fakes import SYNTHETIC_NORM, untrained_network

from pipeline.fewshot.data import load_split, to_tensor
from pipeline.fewshot.recogniser import RelationRecogniser
from pipeline.rl.recogniser import Recogniser

NORM = SYNTHETIC_NORM


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    root = tmp_path_factory.mktemp("fewshot_rec")
    ckpt, net = untrained_network(root)
    query = load_split(root / "images", "query", 24)
    support = load_split(root / "images", "support", 24)
    feats_q = net.embedding(to_tensor(query.images, **NORM)).detach()
    feats_s = net.embedding(to_tensor(support.images, **NORM)).detach()
    return root, ckpt, net, feats_q, feats_s, query


def _reference(net, feats_q, feats_s, members):
    """Scores of every query picture by the plain forward pass for a support set of member codes."""
    rows = [[feats_q[m] if m >= 0 else feats_s[-m - 1] for m in cls] for cls in members]
    class_f = torch.stack([torch.stack(r).sum(0) for r in rows])
    with torch.no_grad():
        return net.relation_scores(class_f, feats_q).numpy()


def test_protocol_and_scores_match_forward(setup):
    root, ckpt, net, fq, fs, query = setup
    rec = RelationRecogniser.from_files(ckpt, root / "images", substitution_way=1)
    assert isinstance(rec, Recogniser)
    rec.start_run(0, seed=5)
    ref = _reference(net, fq, fs, rec.support_members(0))
    np.testing.assert_allclose(rec.scores(0, np.arange(40)), ref, atol=1e-5)
    np.testing.assert_array_equal(rec.predictions(0), ref.argmax(1))
    assert rec.scores(0, np.array([3, 17])).shape == (2, 5)
    assert rec.class_names == tuple(f"category_{c}" for c in range(5))


def test_substitution_recomputes_only_its_class(setup):
    root, ckpt, net, fq, fs, query = setup
    rec = RelationRecogniser.from_files(ckpt, root / "images", substitution_way=1)
    rec.start_run(0, seed=5)
    before = rec.scores(0, np.arange(40)).copy()
    assert rec.learn_from_collision(0, picture_id=10, true_category=1) == 0
    assert rec.learn_from_collision(0, picture_id=12, true_category=1) == 1
    after = rec.scores(0, np.arange(40))
    np.testing.assert_array_equal(np.delete(after, 1, axis=1), np.delete(before, 1, axis=1))
    assert not np.allclose(after[:, 1], before[:, 1])
    members = rec.support_members(0)
    assert members[1, :2].tolist() == [10, 12]
    np.testing.assert_allclose(after, _reference(net, fq, fs, members), atol=1e-5)


def test_runs_own_their_support_sets_and_restart(setup):
    root, ckpt, *_ = setup
    rec = RelationRecogniser.from_files(ckpt, root / "images", substitution_way=3)
    rec.start_run(0, seed=1)
    rec.start_run(1, seed=1)
    original = rec.scores(1, np.arange(40)).copy()
    pos = rec.learn_from_collision(0, 33, 4)
    assert 0 <= pos < 5
    np.testing.assert_array_equal(rec.scores(1, np.arange(40)), original)
    rec.start_run(0, seed=1)  # restored
    np.testing.assert_array_equal(rec.scores(0, np.arange(40)), original)
    assert rec.learn_from_collision(0, 33, 4) == pos  # same seed, same position


def test_carry_over_keeps_the_support_set(setup):
    root, ckpt, *_ = setup
    rec = RelationRecogniser.from_files(ckpt, root / "images", substitution_way=1, carry_over=True)
    rec.start_run(0, seed=1)
    rec.learn_from_collision(0, 33, 4)
    rec.start_run(0, seed=2)
    assert rec.support_members(0)[4, 0] == 33
    assert rec.learn_from_collision(0, 34, 4) == 1  # the position state carries over too


def test_static_and_bad_calls(setup):
    root, ckpt, *_ = setup
    rec = RelationRecogniser.from_files(ckpt, root / "images", substitution_way=0)
    rec.start_run(0, seed=1)
    before = rec.scores(0, np.arange(40)).copy()
    assert rec.learn_from_collision(0, 5, 0) == -1
    np.testing.assert_array_equal(rec.scores(0, np.arange(40)), before)
    with pytest.raises(ValueError, match="shows category 0, not 2"):
        rec.learn_from_collision(0, 5, 2)
    with pytest.raises(KeyError, match="start_run"):
        rec.predictions(9)
    with pytest.raises(ValueError, match="picture ids"):
        rec.scores(0, np.array([40]))


def test_fewshot_imports_neither_rl_nor_world():
    package = Path(__file__).resolve().parents[1] / "pipeline" / "fewshot"
    for path in package.glob("*.py"):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            names = (
                [a.name for a in node.names]
                if isinstance(node, ast.Import)
                else [node.module or ""]
                if isinstance(node, ast.ImportFrom)
                else []
            )
            for name in names:
                assert not name.startswith(
                    ("pipeline.rl", "pipeline.world", "pipeline.records", "pipeline.stages")
                ), f"{path.name} imports {name}"


def test_a_recogniser_that_does_not_score_cannot_be_built():
    """The base class's scoring steps are abstract: a subclass that leaves one out fails at construction,
    naming it, not at its first score."""
    from pipeline.fewshot.recogniser import SupportSetRecogniser

    class NoForward(SupportSetRecogniser):
        def prepare(self, query_features, support_features):
            return query_features, support_features

    with pytest.raises(TypeError, match="abstract method.*forward"):
        NoForward(None, torch.zeros(0), np.zeros(0), torch.zeros(0))


def test_recognisers_of_one_checkpoint_share_its_network_until_the_file_changes(tmp_path):
    """Table 3's five recognisers (a substitution way each) load the checkpoint once, so the
    pictures are embedded once; a checkpoint file written again is loaded again."""
    import os

    from fakes import untrained_network

    ckpt, _ = untrained_network(tmp_path)
    first, other_way = (
        RelationRecogniser.from_files(ckpt, tmp_path / "images", substitution_way=w) for w in (1, 3)
    )
    assert first.network is other_way.network
    ckpt, _ = untrained_network(tmp_path)  # the same file written again
    os.utime(ckpt, ns=(1, 1))  # a modification time no first write has: surely another file
    again = RelationRecogniser.from_files(ckpt, tmp_path / "images", substitution_way=1)
    assert again.network is not first.network
