"""The recogniser both few-shot methods share (paper section 3.2.1, eq. 2, and the dynamic support
set of section 3.3): :class:`SupportSetRecogniser` owns the runs, their support sets
(:mod:`.support_set`, substitution ways 1-4, carry-over), the (pictures x categories) table and its
per-category invalidation, loading from files. A subclass (:mod:`.recogniser`) implements two
hooks, as easyfsl's ``FewShotClassifier`` asks for ``process_support_set`` and ``forward``:
:meth:`~SupportSetRecogniser.prepare` (what each picture contributes, computed once) and
:meth:`~SupportSetRecogniser.forward` (every picture's score against one category's members).

Each run owns its support set. ``start_run`` restores the original support set, or, with
``carry_over=True`` (long-term autonomy, paper Figure 10), keeps the run's current one and only reseeds
its substitution stream.

``learn_from`` (:mod:`.learn_from`) limits which substituted pictures a query picture's
recognition sees; ``all``, the default, is the paper's dynamic support set.

The network part (the pictures embedded, each picture's part) is made at the first column the
score store (:mod:`.score_cache`) does not hold: a recogniser loaded from files whose columns are
all in its score file never imports torch (:mod:`.from_files`). This module imports torch only
there.
"""

from __future__ import annotations

import abc
import hashlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from PIL import Image

from pipeline.torch_later import import_torch, kernel_path, torch_threads

from .data import to_tensor
from .learn_from import learning_groups, table_by_group
from .score_cache import ColumnStore, source_key, store_for
from .support_set import SupportSet, check_picture, started

if TYPE_CHECKING:
    import torch

    from .model import RelationNetwork
    from .protonet import PrototypicalNetwork

    Network = RelationNetwork | PrototypicalNetwork
    #: What the network part is made from: the network, the query and the support pictures.
    Inputs = Callable[[], tuple[Network, torch.Tensor, torch.Tensor]]


def canonical(members: np.ndarray) -> np.ndarray:
    """A category's support members in the one order its class state sums them: the original
    support pictures first, by position (``-1, -2, ...``), then query pictures by id. The state, and
    so every score, depends on the multiset of members only (the key of :mod:`.score_cache`), and
    the original support set sums in its own position order."""
    return np.array(sorted((int(m) for m in members), key=lambda m: (m >= 0, abs(m))))


@dataclass
class _Run:
    support: SupportSet
    table: np.ndarray  # (P, C) raw scores: relation scores, or logits
    valid: np.ndarray  # (C,) bool: column c of ``table`` is current


class SupportSetRecogniser(abc.ABC):
    """A few-shot recogniser over a dynamic C-way K-shot support set; a subclass implements the
    two hooks :meth:`prepare` and :meth:`forward`.

    ``query_images``: (P, 3, H, W) normalised, row ``p`` = query picture id ``p``;
    ``query_categories``: (P,) true categories; ``support_images``: (C*K, 3, H, W), class ``c`` in
    rows ``c*K .. c*K+K-1`` (position order). ``substitution_way``: 0 static, 1-4 as in section 3.3.
    ``learn_from`` and ``query_objects`` (each picture's obstacle): :mod:`.learn_from`.
    """

    kind = ""
    """The model's name in checkpoints and records (``describe()``)."""
    display_name = ""
    """The report's name for it (``pipeline.report.names``); never recorded."""
    colour: str | None = None
    """Its colour in the report's figures (``#rrggbb``; ``pipeline.report.names``); never recorded."""

    def __init__(
        self,
        network: RelationNetwork | PrototypicalNetwork,
        query_images: torch.Tensor,
        query_categories: np.ndarray,
        support_images: torch.Tensor,
        *,
        n_way: int = 5,
        k_shot: int = 5,
        substitution_way: int = 1,
        carry_over: bool = False,
        learn_from: str = "all",
        query_objects: np.ndarray | None = None,
        store: ColumnStore | None = None,
    ) -> None:
        if len(support_images) != n_way * k_shot:
            raise ValueError(
                f"support set needs {n_way}x{k_shot} = {n_way * k_shot} pictures, got {len(support_images)}"
            )
        if len(query_images) != len(query_categories):
            raise ValueError("query_images and query_categories differ in length")
        if store is None:
            # columns shared with every recogniser of this process that scores the same way
            # (:mod:`.score_cache`): same kind, weights and pictures
            kind = f"{type(self).__qualname__}:{self.kind}"
            store = store_for(source_key(kind, network, query_images, support_images))
        self._start(
            lambda: (network, query_images, support_images),
            store,
            query_categories,
            n_way=n_way,
            k_shot=k_shot,
            substitution_way=substitution_way,
            carry_over=carry_over,
            learn_from=learn_from,
            query_objects=query_objects,
        )
        self.checkpoint = None  # set by the loader (:mod:`.from_files`)

    def _start(
        self,
        inputs: Inputs,
        store: ColumnStore,
        query_categories: np.ndarray,
        *,
        n_way: int,
        k_shot: int,
        substitution_way: int,
        carry_over: bool,
        learn_from: str,
        query_objects: np.ndarray | None,
        checkpoint_later: bool = False,
    ) -> None:
        """Everything but the network part, which ``inputs`` gives when a column is first
        computed (:meth:`_network_part`); the original support set's table, from ``store``.
        ``checkpoint_later``: :attr:`checkpoint` is set when ``inputs`` is called."""
        cats = np.asarray(query_categories, dtype=np.int64)
        if cats.min() < 0 or cats.max() >= n_way:
            raise ValueError(f"query categories must lie in 0..{n_way - 1}")
        SupportSet(n_way, k_shot, substitution_way, 0)  # validates the way
        self.learn_from = learn_from
        self._groups = learning_groups(learn_from, cats, query_objects)
        self._inputs, self._network, self._parts = inputs, None, None
        self.n_way, self.k_shot = n_way, k_shot
        self.substitution_way, self.carry_over = substitution_way, carry_over
        self.query_categories = cats
        self.n_pictures = len(cats)
        self.class_names: tuple[str, ...] = tuple(f"category_{c}" for c in range(n_way))
        self._checkpoint, self._checkpoint_later = None, checkpoint_later
        self._runs: dict[int, _Run] = {}
        self._store = store
        self._original_members = SupportSet(n_way, k_shot, 0, 0).members
        self._original_table = np.stack(
            [self._column(members) for members in self._original_members], axis=1
        )

    @property
    def network(self) -> RelationNetwork | PrototypicalNetwork:
        """The network (eval mode), loaded now if it was not."""
        if self._network is None:
            self._network_part()
        return self._network

    @property
    def checkpoint(self) -> dict | None:
        """The checkpoint's model, config, metrics and normalisation, when loaded from files (read
        now if the recogniser started from its score file); None when built from tensors."""
        if self._checkpoint_later:
            self._network_part()
        return self._checkpoint

    @checkpoint.setter
    def checkpoint(self, contents: dict | None) -> None:
        self._checkpoint, self._checkpoint_later = contents, False

    @property
    def parts(self) -> dict[int, torch.Tensor]:
        """The part each support member contributes to its category's score: query picture p ->
        p, original support picture j -> -(j + 1) (the member codes of support_set.py)."""
        return self._network_part()

    def _network_part(self) -> dict[int, torch.Tensor]:
        """Embed the pictures and :meth:`prepare` each picture's part, once (torch from here)."""
        if self._parts is None:
            torch = import_torch()  # with the process's torch threads (pipeline.torch_later)
            network, query_images, support_images = self._inputs()
            self._network, self._support_images = network.eval(), support_images
            with torch.no_grad():
                query_f = _embedded(network, query_images)
                support_f = _embedded(network, support_images)
                query_parts, support_parts = self.prepare(query_f, support_f)
            parts = {int(p): query_parts[p] for p in range(self.n_pictures)}
            parts.update({-(j + 1): support_parts[j] for j in range(len(support_parts))})
            self._parts = parts
        return self._parts

    # -- the two hooks a recogniser implements -------------------------------------------------
    @abc.abstractmethod
    def prepare(
        self, query_features: torch.Tensor, support_features: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Called once, from the eval-mode embeddings of the query (P, ...) and original support
        (C*K, ...) pictures: return each picture's part of a category's state (row ``i`` of each),
        and keep what :meth:`forward` needs of the query pictures."""

    @abc.abstractmethod
    def forward(self, parts: torch.Tensor) -> np.ndarray:
        """Raw scores (P,) of every query picture against the category whose K members' parts are
        ``parts`` (K, ...), stacked in :func:`canonical` order; all pictures in one batch, no grad.
        :meth:`predictions` takes the arg max of a row; :meth:`scores` returns rows as they are."""

    def describe(self) -> dict:
        """What the records keep about this recogniser: the checkpoint's path, sha256 and shape, the
        torch threads that score (``pipeline.threads``; kernels may round differently on another
        count), ATen's kernel path (``pipeline.kernels``) and the query pictures' hue shift, when
        they are turned."""
        out = {
            "kind": self.kind,
            "checkpoint": getattr(self, "checkpoint_file", None),
            "substitution_way": self.substitution_way,
            "carry_over": self.carry_over,
            "torch_threads": torch_threads(),
            "cpu_kernels": kernel_path(),
        }
        if getattr(self, "query_hue_shift", 0.0):
            out["query_hue_shift"] = self.query_hue_shift
        if self.learn_from != "all":
            out["learn_from"] = self.learn_from
        return out

    # -- the Recogniser protocol -------------------------------------------------------------
    def start_run(self, run: int, seed: int) -> None:
        """Restore run ``run``'s original support set (or keep it with ``carry_over``) and seed its
        substitution stream."""
        if self.carry_over and run in self._runs:
            self._runs[run].support.reset_stream(seed)
            return
        self._runs[run] = _Run(
            support=SupportSet(self.n_way, self.k_shot, self.substitution_way, seed),
            table=self._original_table.copy(),
            valid=np.ones(self.n_way, dtype=bool),
        )

    def predictions(self, run: int) -> np.ndarray:
        """Predicted category of every query picture id under run ``run``'s support set."""
        return self._table(run).argmax(axis=1)

    def scores(self, run: int, picture_ids: np.ndarray) -> np.ndarray:
        """Scores (len(picture_ids), C) in [0, 1] under run ``run``'s support set."""
        ids = np.asarray(picture_ids, dtype=np.int64)
        if ids.size and (ids.min() < 0 or ids.max() >= self.n_pictures):
            raise ValueError(
                f"picture ids must lie in 0..{self.n_pictures - 1}, got {ids.tolist()}"
            )
        return self._table(run)[ids]

    def learn_from_collision(self, run: int, picture_id: int, true_category: int) -> int:
        """Substitute query picture ``picture_id`` into ``true_category`` at the position the
        substitution way chooses (section 3.3); return it, or -1 for a static support set."""
        state = self._run(run)
        check_picture(self.query_categories, picture_id, true_category)
        pos = state.support.substitute(true_category, int(picture_id))
        if pos >= 0:
            state.valid[true_category] = False
        return pos

    # -- extras for the accuracy study and the records ---------------------------------------
    def replace(self, run: int, category: int, position: int, picture_id: int) -> None:
        """Put query picture ``picture_id`` at ``position`` of ``category`` (the accuracy study's
        chosen substitutions, section 4.2.1), whatever the substitution way."""
        state = self._run(run)
        check_picture(self.query_categories, picture_id, category)
        if not 0 <= position < self.k_shot:
            raise ValueError(f"support position {position} out of range 0..{self.k_shot - 1}")
        state.support.members[category, position] = int(picture_id)
        state.valid[category] = False

    def support_members(self, run: int) -> np.ndarray:
        """(C, K) member codes of run ``run``'s support set: a query picture id (>= 0) or
        ``-(j + 1)`` for original support picture ``j``."""
        return self._run(run).support.members.copy()

    # -- another set of query pictures (the robot's live pictures, pipeline.robot.live) ------
    def for_pictures(self, images: np.ndarray, categories: np.ndarray) -> SupportSetRecogniser:
        """The same network and original support set over other query pictures: ``images``
        (n, H, W, 3) uint8, resized to the network's input (bilinear, as ``data.load_image``) and
        normalised with the checkpoint's statistics; ``categories`` their true categories. Its
        picture ids are the rows of ``images``; its substitution way and carry-over are this one's."""
        if self.checkpoint is None:
            raise ValueError(
                "other pictures need a recogniser loaded from a checkpoint (from_files)"
            )
        if self.learn_from != "all":
            raise ValueError(
                f"learn_from={self.learn_from!r} groups the query pictures by their ids; other "
                "pictures (the robot's) have none: use learn_from=all"
            )
        network = self.network
        size = network.config.input_size
        resized = np.stack([_resized(im, size) for im in images]) if len(images) else images
        norm = self.checkpoint["normalisation"]
        other = type(self)(
            network,
            to_tensor(resized, norm["mean"], norm["std"]),
            np.asarray(categories),
            self._support_images,
            n_way=self.n_way,
            k_shot=self.k_shot,
            substitution_way=self.substitution_way,
            carry_over=self.carry_over,
        )
        other.class_names, other.checkpoint = self.class_names, self.checkpoint
        other.checkpoint_file = getattr(self, "checkpoint_file", None)
        return other

    # -- internals ---------------------------------------------------------------------------
    def _run(self, run: int) -> _Run:
        return started(self._runs, run)

    def _column(self, members: np.ndarray) -> np.ndarray:
        """The column of a category whose support members are ``members`` (any order): from the
        shared store, computed by :meth:`forward` the first time."""
        ordered = canonical(members)
        key = tuple(int(m) for m in ordered)
        return self._store.column(key, lambda: self._forward(ordered))

    def _forward(self, ordered: np.ndarray) -> np.ndarray:
        parts = self._network_part()
        torch = import_torch()
        with torch.no_grad():
            return self.forward(torch.stack([parts[int(m)] for m in ordered]))

    def _table(self, run: int) -> np.ndarray:
        state = self._run(run)
        if self._groups is not None:
            if not state.valid.all():
                state.table = table_by_group(
                    self._column, state.support.members, self._original_members, self._groups
                )
                state.valid[:] = True
            return state.table
        for c in np.flatnonzero(~state.valid):
            state.table[:, c] = self._column(state.support.members[c])
            state.valid[c] = True
        return state.table


def _resized(image: np.ndarray, size: int) -> np.ndarray:
    im = Image.fromarray(np.asarray(image, dtype=np.uint8))
    if im.size != (size, size):
        im = im.resize((size, size), Image.Resampling.BILINEAR)
    return np.asarray(im)


#: Embeddings of picture batches already embedded, by (network, the batch's bytes): the robot's
#: cells of one process ask the same network about the same live pictures (one rendering a run)
#: under several methods and rules. Bounded: the oldest go first.
_EMBEDDINGS: dict[tuple[int, bytes], tuple[object, torch.Tensor]] = {}
MAX_EMBEDDINGS = 4096


def _embedded(network, images: torch.Tensor) -> torch.Tensor:
    """``embed_all`` of ``images`` (eval mode), computed once per network and batch."""
    from .training import embed_all

    data = images.detach().contiguous().numpy().tobytes()
    key = (id(network), hashlib.sha256(data).digest())
    if key not in _EMBEDDINGS or _EMBEDDINGS[key][0] is not network:  # an id reused
        if len(_EMBEDDINGS) >= MAX_EMBEDDINGS:
            del _EMBEDDINGS[next(iter(_EMBEDDINGS))]
        _EMBEDDINGS[key] = (network, embed_all(network, images, channels_last=False))
    return _EMBEDDINGS[key][1]
