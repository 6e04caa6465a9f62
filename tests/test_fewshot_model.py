"""Relation Network shapes, the golden output for a fixed seed, K-shot summing and the split of
g_phi's first convolution (pipeline.fewshot.model)."""

import numpy as np
import pytest
import torch

from pipeline.fewshot.model import CHANNELS, ModelConfig, RelationNetwork, feature_shapes


@pytest.mark.parametrize(
    "size,pad,expected",
    [
        (84, 0, (19, 3, 576)),
        (64, 0, (14, 2, 256)),
        (48, 0, (10, 1, 64)),
        (46, 0, (10, 1, 64)),
        (42, 1, (9, 2, 256)),
        (24, 1, (4, 1, 64)),
    ],
)
def test_feature_shapes(size, pad, expected):
    shapes = feature_shapes(size, pad)
    assert (shapes["embedding"], shapes["relation"], shapes["fc_in"]) == expected
    net = RelationNetwork(ModelConfig(size, pad)).eval()
    with torch.no_grad():
        f = net.embedding(torch.zeros(2, 3, size, size))
    assert f.shape == (2, CHANNELS, expected[0], expected[0])


def test_too_small_input_names_the_fix():
    with pytest.raises(ValueError, match="relation_padding=1"):
        ModelConfig(42, 0)
    with pytest.raises(ValueError, match="relation_padding must be 0 or 1"):
        ModelConfig(84, 2)


def _net_and_inputs():
    torch.manual_seed(0)
    net = RelationNetwork(ModelConfig(24, 1))
    g = torch.Generator().manual_seed(1)
    support = torch.randn(5, 5, 3, 24, 24, generator=g)
    query = torch.randn(3, 3, 24, 24, generator=g)
    return net, support, query


def test_forward_shape_and_golden_output():
    net, support, query = _net_and_inputs()
    with torch.no_grad():
        scores = net(support, query)  # training mode: batch statistics
    assert scores.shape == (3, 5)
    golden = [
        [0.412526, 0.441576, 0.462299, 0.371739, 0.449336],
        [0.406417, 0.412676, 0.429455, 0.386051, 0.452891],
        [0.390948, 0.419515, 0.430701, 0.380683, 0.448588],
    ]
    np.testing.assert_allclose(scores.numpy(), golden, atol=2e-5)


def test_k_shot_features_are_summed_not_averaged():
    net, support, query = _net_and_inputs()
    net.eval()
    with torch.no_grad():
        f = net.embedding(support.flatten(0, 1)).unflatten(0, (5, 5))
        torch.testing.assert_close(net.class_features(f), f.sum(1))
        manual = net.relation_scores(f.sum(1), net.embedding(query))
        torch.testing.assert_close(net(support, query), manual)


def test_first_conv_split_matches_concatenation():
    net, support, query = _net_and_inputs()
    net.eval()
    with torch.no_grad():
        a = net.embedding(support[:, 0])
        b = net.embedding(query[:1]).expand(5, -1, -1, -1)
        whole = net.relation(torch.cat([a, b], 1))
        ha, hb = net.relation.first_conv_halves(a, b)
        split = net.relation.after_first_conv(ha + hb + net.relation.first_conv_bias())
    torch.testing.assert_close(split, whole, atol=1e-6, rtol=0)
