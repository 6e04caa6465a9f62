"""The few-shot reasoning module as the RL loop uses it (paper section 3.2.1, eq. 2, and the
dynamic support set of section 3.3). It implements the trial runner's ``Recogniser`` protocol
(``pipeline/rl/recogniser.py``) structurally, without importing ``pipeline.rl``.

:class:`.support_recogniser.SupportSetRecogniser` owns what both few-shot methods share (the runs,
their support sets, the score table, loading from files); the two subclasses here implement its two
hooks, ``prepare`` (each picture's part of a class state) and ``forward`` (every picture's score
against one category's members): :class:`RelationRecogniser` and :class:`ProtoRecogniser` (a
prototype, the mean embedding; Prototypical Networks).

Cost model of the Relation Network. Every picture (the 40 query pictures and the original support pictures) is embedded
once by f_varphi. g_phi's first convolution is linear in the concatenated pair, so it splits into a
class half and a query half (:meth:`RelationModule.first_conv_halves`); the class half of a summed
class feature map is the sum of its members' halves plus the bias. Both halves are computed once per
picture. A run keeps, per category, its class half and its column of the (pictures x categories)
score table; a substitution in category ``c`` re-sums ``c``'s K halves and invalidates column ``c``
only, which is recomputed (the rest of g_phi on 40 pairs) the next time a score is asked for.
The columns are always computed for all pictures in one fixed-size batch, so a score does not depend
on which picture was asked for first. Scores agree with the plain forward pass to float rounding.

Cost model of the Prototypical Network: every picture is embedded once; a category's state is
its prototype (the mean of its K members' embeddings), and a substitution re-averages that one
prototype and recomputes its column of negative squared distances. Its scores are the softmax of
a row (a probability per category, in [0, 1]).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from pipeline.torch_later import import_torch

from .from_files import RecogniserFiles, load_recogniser
from .settings import ModelConfig, ProtoConfig
from .support_recogniser import SupportSetRecogniser

if TYPE_CHECKING:
    import torch

__all__ = ["ProtoRecogniser", "RelationRecogniser", "SupportSetRecogniser", "softmax_rows"]


def softmax_rows(table: np.ndarray) -> np.ndarray:
    """Each row's softmax (Snell et al. eq. 2): raw scores (logits) to a probability a category."""
    torch = import_torch()
    return torch.softmax(torch.from_numpy(table), dim=1).numpy()


class RelationRecogniser(SupportSetRecogniser):
    """Relation Network recogniser (paper section 3.2.1, eq. 2): a category's state is the class
    half of g_phi's first convolution (with its bias) of the summed K feature maps; the rest of
    g_phi on every picture's query half scores it. Scores are relation scores in [0, 1]."""

    kind = "relation_net"
    display_name = "Relation Network"
    colour = "#17becf"

    @classmethod
    def from_files(
        cls,
        checkpoint: str | Path,
        images_dir: str | Path,
        input_size: int | None = None,
        relation_padding: int | None = None,
        query_hue_shift: float = 0.0,
        learn_from: str = "all",
        *,
        substitution_way: int = 1,
        carry_over: bool = False,
    ) -> RelationRecogniser:
        """Load a trained Relation Network checkpoint and the pictures of ``images_dir`` (see
        :func:`.from_files.load_recogniser`). ``input_size`` and ``relation_padding``, when given,
        are the model shape the config expects; ``query_hue_shift`` turns the query pictures' hue;
        ``learn_from`` which substituted pictures a query sees (:mod:`.learn_from`)."""
        shape = None
        if input_size is not None or relation_padding is not None:
            shape = ModelConfig(
                input_size if input_size is not None else 84,
                relation_padding if relation_padding is not None else 0,
            )
        files = RecogniserFiles(checkpoint, images_dir, shape, query_hue_shift)
        return load_recogniser(
            cls,
            files,
            substitution_way=substitution_way,
            carry_over=carry_over,
            learn_from=learn_from,
        )

    def prepare(self, query_features, support_features):
        """Every picture's class half; the query pictures' query halves and the bias are kept."""
        relation = self.network.relation
        q_class, self._query_half = relation.first_conv_halves(query_features, query_features)
        s_class, _ = relation.first_conv_halves(support_features, support_features[:1])
        self._bias = relation.first_conv_bias().detach().clone()
        return q_class, s_class

    def forward(self, parts: torch.Tensor) -> np.ndarray:
        """The class half of the members' summed maps (the sum of their halves, plus the bias)
        added to every query half, through the rest of g_phi."""
        h = (self._bias + parts.sum(0)).unsqueeze(0) + self._query_half
        return self.network.relation.after_first_conv(h).numpy()


class ProtoRecogniser(SupportSetRecogniser):
    """Prototypical Network recogniser (Snell et al. 2017, eqs. 1-2): a category's state is its
    prototype, the mean of its K members' embeddings; every picture's raw score is its negative
    squared distance to it; a picture's scores are the softmax of its row, p(category | picture)."""

    kind = "protonet"
    display_name = "Prototypical Network"
    colour = "#e377c2"

    @classmethod
    def from_files(
        cls,
        checkpoint: str | Path,
        images_dir: str | Path,
        input_size: int | None = None,
        query_hue_shift: float = 0.0,
        learn_from: str = "all",
        *,
        substitution_way: int = 1,
        carry_over: bool = False,
    ) -> ProtoRecogniser:
        """Load a trained Prototypical Network checkpoint and the pictures of ``images_dir`` (see
        :func:`.from_files.load_recogniser`). ``input_size``, when given, is the input side the
        config expects; ``query_hue_shift`` turns the query pictures' hue; ``learn_from`` which
        substituted pictures a query sees (:mod:`.learn_from`)."""
        shape = ProtoConfig(input_size) if input_size is not None else None
        files = RecogniserFiles(checkpoint, images_dir, shape, query_hue_shift)
        return load_recogniser(
            cls,
            files,
            substitution_way=substitution_way,
            carry_over=carry_over,
            learn_from=learn_from,
        )

    def prepare(self, query_features, support_features):
        """Every picture's flattened embedding; the query pictures' are kept."""
        self._queries = query_features.flatten(1)
        return self._queries, support_features.flatten(1)

    def forward(self, parts: torch.Tensor) -> np.ndarray:
        """Negative squared distances to the prototype, the mean of the members' embeddings."""
        from .protonet import negative_squared_distances

        return negative_squared_distances(parts.mean(0).unsqueeze(0), self._queries)[:, 0].numpy()

    def scores(self, run: int, picture_ids: np.ndarray) -> np.ndarray:
        """The softmax of each picture's row: p(category | picture), in [0, 1]."""
        return softmax_rows(super().scores(run, picture_ids))
