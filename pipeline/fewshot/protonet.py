"""Prototypical Networks (Snell, Swersky and Zemel, NeurIPS 2017), the second few-shot method
beside the Relation Network (:mod:`.model`), trained on the same classes and episodes.

- Embedding ``f``: the Relation Network's Conv-4 ``f_varphi`` (:class:`~.model.Embedding`),
  its 64 x s x s map flattened (6400 values at 48 px). Snell et al. use four blocks that all pool
  (a 1600-vector at 84 px); we keep one encoder for both methods so that they differ only in how
  they compare.
- Prototype of class k (Snell et al., eq. 1): ``c_k = 1/|S_k| sum_{x in S_k} f(x)``.
- Scores (eq. 2): ``p(y = k | x) = softmax_k(-d(f(x), c_k))`` with the squared Euclidean distance
  ``d(z, c) = ||z - c||^2``. :meth:`PrototypicalNetwork.scores` returns the logits ``-d``; the
  recogniser reports their softmax (a score in [0, 1] per category).
- Loss: cross-entropy of those logits (the negative log-probability of the true class), Adam.

We write it ourselves rather than use easyfsl: easyfsl needs torchvision, whose PyPI wheel does not
import beside our CPU torch and would pull in a second torch build.
"""

from __future__ import annotations

import torch
from torch import nn

from .model import Embedding
from .settings import ProtoConfig


def prototypes(support_embeddings: torch.Tensor) -> torch.Tensor:
    """(C, K, D) -> (C, D): the mean of each class's K support embeddings (eq. 1)."""
    return support_embeddings.mean(dim=1)


def negative_squared_distances(prototypes: torch.Tensor, queries: torch.Tensor) -> torch.Tensor:
    """(C, D) prototypes, (Q, D) queries -> (Q, C) logits ``-||q - c||^2`` (eq. 2), computed as
    the difference itself (not the ``|q|^2 - 2 q.c + |c|^2`` expansion, which loses precision)."""
    return -(queries.unsqueeze(1) - prototypes.unsqueeze(0)).pow(2).sum(-1)


class PrototypicalNetwork(nn.Module):
    """Conv-4 embedding, class prototypes and negative squared distances. The methods mirror
    :class:`~.model.RelationNetwork`'s, so one training loop and one evaluation serve both:
    ``class_features`` (prototypes), ``scores`` (logits), ``loss``."""

    kind = "protonet"

    def __init__(self, config: ProtoConfig | None = None) -> None:
        super().__init__()
        self.config = config or ProtoConfig()
        self.embedding = Embedding()

    def embed(self, images: torch.Tensor) -> torch.Tensor:
        """(N, 3, H, W) -> (N, D) flattened Conv-4 embeddings."""
        return self.embedding(images).flatten(1)

    def class_features(self, support_features: torch.Tensor) -> torch.Tensor:
        """(C, K, ...) embeddings -> (C, D) prototypes."""
        return prototypes(support_features.flatten(2))

    def scores(self, class_features: torch.Tensor, query_features: torch.Tensor) -> torch.Tensor:
        """(Q, C) logits: negative squared distances of every query to every prototype."""
        return negative_squared_distances(class_features, query_features.flatten(1))

    def forward(self, support: torch.Tensor, query: torch.Tensor) -> torch.Tensor:
        """``support``: (C, K, 3, H, W); ``query``: (Q, 3, H, W) -> logits (Q, C)."""
        n_class, k_shot = support.shape[:2]
        features = self.embed(torch.cat([support.flatten(0, 1), query]))
        support_f = features[: n_class * k_shot].unflatten(0, (n_class, k_shot))
        return self.scores(self.class_features(support_f), features[n_class * k_shot :])

    @staticmethod
    def loss(scores: torch.Tensor, labels: torch.Tensor) -> torch.Tensor:
        """Cross-entropy of the logits: mean of ``-log p(y = true class | x)``."""
        return nn.functional.cross_entropy(scores, labels)
