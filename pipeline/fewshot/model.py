"""The Relation Network of Sung et al. (CVPR 2018), as used by the paper's few-shot reasoning
module (section 3.2.1, eq. 2): ``r_ij = g_phi(C(f_varphi(x_i), f_varphi(x_j)))``.

- ``f_varphi`` (:class:`Embedding`): Conv-4, four blocks of 3x3 conv with 64 filters, batch norm
  and ReLU; the first two blocks end with 2x2 max-pooling. As in the reference code, the first two
  convolutions are unpadded and the last two are padded.
- ``C``: concatenation of the (K-shot *summed*) class feature map and the query feature map along
  the channels (128 channels).
- ``g_phi`` (:class:`RelationModule`): two blocks of 3x3 conv-64, batch norm, ReLU, 2x2
  max-pooling, then FC-8 with ReLU and FC-1 with a sigmoid.

The input size is a config value. Feature-map sizes it implies (relation padding 0, the reference's):

============  ===================  ====================  ========
input (px)    f_varphi output      g_phi after block 2   FC input
============  ===================  ====================  ========
84            64 x 19 x 19         64 x 3 x 3            576
64            64 x 14 x 14         64 x 2 x 2            256
48            64 x 10 x 10         64 x 1 x 1            64
============  ===================  ====================  ========

Below 46 px the unpadded relation blocks would shrink the map to nothing; ``relation_padding=1``
(same-padding in g_phi) keeps them alive, e.g. 42 px -> 64 x 9 x 9 -> 64 x 2 x 2 (FC input 256).
:func:`feature_shapes` computes the table for any size.

Because the first convolution of g_phi is linear in its 128 input channels, it splits into a
class half and a query half (:meth:`RelationModule.first_conv_halves`); the recogniser uses this to
recompute only the class half when a support set changes (section 3.3).
"""

from __future__ import annotations

import torch
from torch import nn

from .settings import CHANNELS, HIDDEN, ModelConfig, feature_shapes

__all__ = ["CHANNELS", "HIDDEN", "ModelConfig", "feature_shapes"]


def _block(in_ch: int, padding: int, pool: bool) -> nn.Sequential:
    layers: list[nn.Module] = [
        nn.Conv2d(in_ch, CHANNELS, kernel_size=3, padding=padding),
        nn.BatchNorm2d(CHANNELS),
        nn.ReLU(inplace=True),
    ]
    if pool:
        layers.append(nn.MaxPool2d(2))
    return nn.Sequential(*layers)


class Embedding(nn.Module):
    """f_varphi: Conv-4 (Sung et al. 2018, Figure 2)."""

    def __init__(self) -> None:
        super().__init__()
        self.layers = nn.Sequential(
            _block(3, 0, True),
            _block(CHANNELS, 0, True),
            _block(CHANNELS, 1, False),
            _block(CHANNELS, 1, False),
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.layers(x)


class RelationModule(nn.Module):
    """g_phi: two conv blocks on the concatenated pair, FC-8 (ReLU), FC-1 (sigmoid)."""

    def __init__(self, config: ModelConfig) -> None:
        super().__init__()
        p = config.relation_padding
        self.block1 = _block(2 * CHANNELS, p, True)
        self.block2 = _block(CHANNELS, p, True)
        self.fc1 = nn.Linear(feature_shapes(config.input_size, p)["fc_in"], HIDDEN)
        self.fc2 = nn.Linear(HIDDEN, 1)

    def forward(self, pairs: torch.Tensor) -> torch.Tensor:
        """``pairs``: (N, 128, s, s), class features first -> relation scores (N,) in [0, 1]."""
        return self.after_first_conv(self.block1[0](pairs))

    def after_first_conv(self, h: torch.Tensor) -> torch.Tensor:
        """The rest of g_phi from the output of its first convolution."""
        for layer in list(self.block1)[1:]:
            h = layer(h)
        h = self.block2(h)
        h = torch.relu(self.fc1(h.flatten(1)))
        return torch.sigmoid(self.fc2(h)).squeeze(1)

    def first_conv_halves(
        self, class_features: torch.Tensor, query_features: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Split the first convolution over C(class, query):
        ``conv(C(a, b)) = conv_a(a) + conv_b(b) + bias``. Returns the two halves without the bias
        (see :meth:`first_conv_bias`); convolution is linear, so the class half of a K-shot sum is
        the sum of the shots' class halves."""
        conv = self.block1[0]
        w_class, w_query = conv.weight[:, :CHANNELS], conv.weight[:, CHANNELS:]
        a = nn.functional.conv2d(class_features, w_class, None, padding=conv.padding)
        b = nn.functional.conv2d(query_features, w_query, None, padding=conv.padding)
        return a, b

    def first_conv_bias(self) -> torch.Tensor:
        """The first convolution's bias, shaped (64, 1, 1) to add to a half."""
        return self.block1[0].bias.view(-1, 1, 1)


class RelationNetwork(nn.Module):
    """f_varphi + g_phi with K-shot class features summed (Sung et al., section 3.3)."""

    kind = "relation_net"

    def __init__(self, config: ModelConfig | None = None) -> None:
        super().__init__()
        self.config = config or ModelConfig()
        self.embedding = Embedding()
        self.relation = RelationModule(self.config)

    def class_features(self, support_features: torch.Tensor) -> torch.Tensor:
        """(C, K, 64, s, s) -> (C, 64, s, s): element-wise sum over the K shots."""
        return support_features.sum(dim=1)

    def relation_scores(
        self, class_features: torch.Tensor, query_features: torch.Tensor
    ) -> torch.Tensor:
        """Scores (Q, C) of every query against every class feature map."""
        n_class, n_query = class_features.shape[0], query_features.shape[0]
        a = class_features.unsqueeze(0).expand(n_query, -1, -1, -1, -1)
        b = query_features.unsqueeze(1).expand(-1, n_class, -1, -1, -1)
        pairs = torch.cat([a, b], dim=2).flatten(0, 1)
        return self.relation(pairs).view(n_query, n_class)

    def scores(self, class_features: torch.Tensor, query_features: torch.Tensor) -> torch.Tensor:
        """The episode's scores (Q, C) as the training loop and evaluation ask every network:
        here the relation scores."""
        return self.relation_scores(class_features, query_features)

    @staticmethod
    def loss(scores: torch.Tensor, labels: torch.Tensor) -> torch.Tensor:
        """Sung et al.'s objective: mean squared error between relation scores and one-hot targets."""
        return nn.functional.mse_loss(scores, torch.eye(scores.shape[1])[labels])

    def forward(self, support: torch.Tensor, query: torch.Tensor) -> torch.Tensor:
        """``support``: (C, K, 3, H, W); ``query``: (Q, 3, H, W) -> relation scores (Q, C)."""
        n_class, k_shot = support.shape[:2]
        images = torch.cat([support.flatten(0, 1), query])
        features = self.embedding(images)
        support_f = features[: n_class * k_shot].unflatten(0, (n_class, k_shot))
        return self.relation_scores(self.class_features(support_f), features[n_class * k_shot :])
