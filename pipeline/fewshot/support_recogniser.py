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
"""

from __future__ import annotations

import abc
import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from PIL import Image

from pipeline.kernels import kernel_path

from .checkpoint import file_sha256, load_checkpoint
from .colour import hue_rotate
from .data import DataError, PictureSet, load_split, read_manifest, to_tensor
from .learn_from import learning_groups, query_objects, table_by_group
from .model import RelationNetwork
from .protonet import PrototypicalNetwork
from .score_cache import source_key, store_for
from .support_set import SupportSet, check_picture, started
from .training import embed_all


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
    ) -> None:
        if len(support_images) != n_way * k_shot:
            raise ValueError(
                f"support set needs {n_way}x{k_shot} = {n_way * k_shot} pictures, got {len(support_images)}"
            )
        if len(query_images) != len(query_categories):
            raise ValueError("query_images and query_categories differ in length")
        cats = np.asarray(query_categories, dtype=np.int64)
        if cats.min() < 0 or cats.max() >= n_way:
            raise ValueError(f"query categories must lie in 0..{n_way - 1}")
        SupportSet(n_way, k_shot, substitution_way, 0)  # validates the way
        self.learn_from = learn_from
        self._groups = learning_groups(learn_from, cats, query_objects)
        self.network = network.eval()
        self._support_images = support_images
        self.n_way, self.k_shot = n_way, k_shot
        self.substitution_way, self.carry_over = substitution_way, carry_over
        self.query_categories = cats
        self.n_pictures = len(cats)
        self.class_names: tuple[str, ...] = tuple(f"category_{c}" for c in range(n_way))
        #: config and metrics of the checkpoint, when loaded from files
        self.checkpoint: dict | None = None
        with torch.no_grad():
            query_f = _embedded(network, query_images)
            support_f = _embedded(network, support_images)
            query_parts, support_parts = self.prepare(query_f, support_f)
        #: the part each support member contributes to its category's score: query picture p -> p,
        #: original support picture j -> -(j + 1) (the member codes of support_set.py)
        self.parts = {int(p): query_parts[p] for p in range(self.n_pictures)}
        for j in range(len(support_parts)):
            self.parts[-(j + 1)] = support_parts[j]
        self._runs: dict[int, _Run] = {}
        # columns shared with every recogniser of this process that scores the same way
        # (:mod:`.score_cache`): same kind, weights and pictures
        self._store = store_for(
            source_key(
                f"{type(self).__qualname__}:{self.kind}", network, query_images, support_images
            )
        )
        self._original_members = SupportSet(n_way, k_shot, 0, 0).members
        self._original_table = np.stack(
            [self._column(members) for members in self._original_members], axis=1
        )

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

    # -- construction from files -------------------------------------------------------------
    @classmethod
    def _load(
        cls,
        checkpoint,
        images_dir,
        expected,
        query_hue_shift,
        substitution_way,
        carry_over,
        learn_from="all",
    ):
        """Load a ``cls.kind`` checkpoint and the query/support pictures of ``images_dir``'s
        manifest, resized to the checkpoint's input size and normalised with its statistics.
        ``expected``, when given, is the model shape the config expects: a checkpoint of another
        shape or kind is refused (:class:`CheckpointError`). ``query_hue_shift`` (degrees) turns the
        hue of the query pictures only (:mod:`.colour`, the colour test); 0 leaves them as rendered."""
        if not np.isfinite(query_hue_shift):
            raise ValueError(
                f"query_hue_shift must be a finite number of degrees, got {query_hue_shift!r}"
            )
        network, payload = _loaded(checkpoint, expected, cls.kind)
        size = network.config.input_size
        frame = read_manifest(images_dir)
        query = load_split(images_dir, "query", size, frame)
        support = load_split(images_dir, "support", size, frame)
        q_images, q_cats, s_images, n_way, k_shot = cls._arrange(query, support, images_dir)
        q_images = hue_rotate(q_images, query_hue_shift)
        norm = payload["normalisation"]
        recogniser = cls(
            network,
            to_tensor(q_images, norm["mean"], norm["std"]),
            q_cats,
            to_tensor(s_images, norm["mean"], norm["std"]),
            n_way=n_way,
            k_shot=k_shot,
            substitution_way=substitution_way,
            carry_over=carry_over,
            learn_from=learn_from,
            query_objects=query_objects(frame),
        )
        recogniser.class_names = support.class_names
        recogniser.checkpoint = {
            k: payload[k] for k in ("model", "config", "metrics", "normalisation")
        }
        recogniser.checkpoint_file = {
            "path": str(checkpoint),
            "sha256": file_sha256(checkpoint),
            "model": dict(payload["model"]),
        }
        recogniser.query_hue_shift = float(query_hue_shift)
        return recogniser

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
            "torch_threads": torch.get_num_threads(),
            "cpu_kernels": kernel_path(),
        }
        if getattr(self, "query_hue_shift", 0.0):
            out["query_hue_shift"] = self.query_hue_shift
        if self.learn_from != "all":
            out["learn_from"] = self.learn_from
        return out

    @staticmethod
    def _arrange(
        query: PictureSet, support: PictureSet, images_dir
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, int]:
        order = np.argsort(query.picture_ids, kind="stable")
        ids = query.picture_ids[order]
        if not np.array_equal(ids, np.arange(len(ids))):
            raise DataError(
                f"{images_dir}: query picture ids must be 0..{len(ids) - 1}, each once; got {ids.tolist()}"
            )
        counts = np.bincount(support.labels)
        if len(set(counts.tolist())) != 1 or support.n_classes != query.n_classes:
            raise DataError(
                f"{images_dir}: the support split needs the same number of pictures in each of the {query.n_classes} categories; got {counts.tolist()}"
            )
        return (
            query.images[order],
            query.labels[order],
            support.images,
            support.n_classes,
            int(counts[0]),
        )

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
        size = self.network.config.input_size
        resized = np.stack([_resized(im, size) for im in images]) if len(images) else images
        norm = self.checkpoint["normalisation"]
        other = type(self)(
            self.network,
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

    @torch.no_grad()
    def _forward(self, ordered: np.ndarray) -> np.ndarray:
        return self.forward(torch.stack([self.parts[int(m)] for m in ordered]))

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


#: Networks already loaded in this process, by checkpoint file (its path, size, modification time
#: and inode) and expected shape: the recognisers of one study (Table 3's five, a substitution way
#: each) share one network, so their pictures are embedded once (:func:`_embedded`). A recogniser
#: only evaluates its network (eval mode, no gradients), never changes it.
_NETWORKS: dict[tuple, tuple[object, dict]] = {}
MAX_NETWORKS = 8  # the oldest goes first


def _loaded(checkpoint, expected, kind: str) -> tuple[object, dict]:
    """:func:`load_checkpoint`, once per checkpoint file as it is on disk (a file replaced or
    rewritten is loaded again; one that cannot be read is refused by ``load_checkpoint``)."""
    try:
        path = Path(checkpoint).resolve()
        st = path.stat()
    except (OSError, RuntimeError):  # missing, a loop of links: load_checkpoint says which
        return load_checkpoint(checkpoint, expected, kind=kind)
    key = (str(path), st.st_size, st.st_mtime_ns, st.st_ino, kind, repr(expected))
    if key not in _NETWORKS:
        if len(_NETWORKS) >= MAX_NETWORKS:
            del _NETWORKS[next(iter(_NETWORKS))]
        _NETWORKS[key] = load_checkpoint(checkpoint, expected, kind=kind)
    return _NETWORKS[key]


#: Embeddings of picture batches already embedded, by (network, the batch's bytes): the robot's
#: cells of one process ask the same network about the same live pictures (one rendering a run)
#: under several methods and rules. Bounded: the oldest go first.
_EMBEDDINGS: dict[tuple[int, bytes], tuple[object, torch.Tensor]] = {}
MAX_EMBEDDINGS = 4096


def _embedded(network, images: torch.Tensor) -> torch.Tensor:
    """``embed_all`` of ``images`` (eval mode), computed once per network and batch."""
    data = images.detach().contiguous().numpy().tobytes()
    key = (id(network), hashlib.sha256(data).digest())
    if key not in _EMBEDDINGS or _EMBEDDINGS[key][0] is not network:  # an id reused
        if len(_EMBEDDINGS) >= MAX_EMBEDDINGS:
            del _EMBEDDINGS[next(iter(_EMBEDDINGS))]
        _EMBEDDINGS[key] = (network, embed_all(network, images, channels_last=False))
    return _EMBEDDINGS[key][1]
