"""A few-shot recogniser loaded from files: a trained checkpoint and the query and support pictures
of a rendered dataset (its manifest, :mod:`.data`), as ``conf/recogniser/`` builds it.

Loading costs seconds before the first score: importing torch, reading the checkpoint, embedding
every picture. A recogniser whose columns are all in its score file (:mod:`.score_cache`) needs
none of it, so the score file is keyed by the **files** instead of the tensors: the checkpoint's
sha256, every query and support picture's bytes and file name, the manifest's bytes, the model
shape the config expects, the hue shift, the versions of Pillow and numpy (the pictures' resizing)
and the bytes of the modules that turn them into scores (:data:`SCORING_MODULES`, and the module of
the recogniser's class: a subclass elsewhere too); torch's version and the kernel path are in the
file's name. The first process to load a source writes, beside its columns, what a recogniser needs
to start without its network (:meth:`Loaded.about`): the checkpoint's
model shape, the categories and obstacles of the query pictures, the class names. A later process
with the same files starts from that, and imports torch, reads the checkpoint and embeds the
pictures only at its first column not in the file, so a study whose columns were all computed
before never imports torch. Its scores, and so its records, are the same bits either way (tested).

A file that cannot be read while keying (a missing checkpoint, a manifest naming a missing
picture) leaves the recogniser to load now, and the loading refuses it naming the file, as before.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.metadata
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pipeline.errors import UserError

from .data import MANIFEST, DataError, PictureSet, load_split, read_manifest, to_tensor
from .learn_from import query_objects
from .score_cache import ColumnStore, store_for

if TYPE_CHECKING:
    import torch

    from .support_recogniser import SupportSetRecogniser

#: The modules whose code turns the files into scores: their bytes are part of the source key.
SCORING_MODULES = (
    "checkpoint.py",
    "colour.py",
    "data.py",
    "from_files.py",
    "model.py",
    "protonet.py",
    "recogniser.py",
    "settings.py",
    "support_recogniser.py",
    "training.py",
)


@dataclass(frozen=True)
class RecogniserFiles:
    """What a recogniser is loaded from: a trained ``checkpoint`` and the query and support
    pictures of ``images_dir``'s manifest; ``expected``, when given, the model shape the config
    expects (a checkpoint of another shape or kind is refused, ``CheckpointError``);
    ``query_hue_shift`` (degrees) turns the hue of the query pictures only (:mod:`.colour`, the
    colour test; 0 leaves them as rendered)."""

    checkpoint: str | Path
    images_dir: str | Path
    expected: Any = None
    query_hue_shift: float = 0.0

    def __post_init__(self):
        if not np.isfinite(self.query_hue_shift):
            raise ValueError(
                f"query_hue_shift must be a finite number of degrees, got {self.query_hue_shift!r}"
            )


def load_recogniser(
    cls: type[SupportSetRecogniser], files: RecogniserFiles, **settings: Any
) -> SupportSetRecogniser:
    """A ``cls`` recogniser of ``files`` (a ``cls.kind`` checkpoint), its pictures resized to the
    checkpoint's input size and normalised with its statistics; ``settings``: the recogniser's
    ``substitution_way``, ``carry_over`` and ``learn_from``. Started from its score file when that
    knows it (module docstring), else loaded now."""
    source = files_source(cls, files)
    store = store_for(source) if source is not None else None
    read = functools.partial(Loaded.read, cls, files)
    about = store.about if store is not None else None
    if about is not None:
        recogniser = _started_from(cls, store, source, read, settings)
    else:
        loaded = read()
        recogniser = cls(
            loaded.network,
            loaded.query_images,
            loaded.query_categories,
            loaded.support_images,
            n_way=loaded.n_way,
            k_shot=loaded.k_shot,
            query_objects=loaded.query_objects,
            store=store,
            **settings,
        )
        recogniser.checkpoint = loaded.checkpoint
        about = loaded.about()
        if store is not None:
            store.about = about
    recogniser.class_names = tuple(about["class_names"])
    recogniser.checkpoint_file = {
        "path": str(files.checkpoint),
        "sha256": about["checkpoint_sha256"],
        "model": dict(about["model"]),
    }
    recogniser.query_hue_shift = float(files.query_hue_shift)
    return recogniser


def _started_from(
    cls, store: ColumnStore, source: str, read, settings: dict
) -> SupportSetRecogniser:
    """A recogniser started from its score file's ``about``: its network part (and its
    checkpoint's contents) loaded by ``read`` at its first column not in the file, from the very
    files it was keyed by (files changed since are refused: its other columns came from those)."""
    about = store.about
    recogniser = cls.__new__(cls)

    def network_inputs():
        files = read.args[1]
        if files_source(cls, files) != source:
            raise DataError(
                f"the checkpoint {files.checkpoint} or the pictures of {files.images_dir} changed "
                "while the recogniser was in use; run again"
            )
        loaded = read()
        recogniser.checkpoint = loaded.checkpoint
        return loaded.network, loaded.query_images, loaded.support_images

    recogniser._start(
        network_inputs,
        store,
        np.asarray(about["query_categories"], dtype=np.int64),
        n_way=int(about["n_way"]),
        k_shot=int(about["k_shot"]),
        query_objects=np.asarray(about["query_objects"], dtype=np.int64),
        checkpoint_later=True,
        **settings,
    )
    return recogniser


@dataclass(frozen=True)
class Loaded:
    """What loading the files gives: the network, the normalised pictures as tensors, their
    categories and obstacles, and the checkpoint's contents."""

    network: Any
    checkpoint: dict
    checkpoint_sha256: str
    query_images: torch.Tensor
    query_categories: np.ndarray
    query_objects: np.ndarray
    support_images: torch.Tensor
    n_way: int
    k_shot: int
    class_names: tuple[str, ...]

    @classmethod
    def read(cls_, kind_class, files: RecogniserFiles) -> Loaded:
        """Load the checkpoint (once per file, :func:`network_of`) and the pictures."""
        checkpoint, images_dir = files.checkpoint, files.images_dir
        network, payload = network_of(checkpoint, files.expected, kind_class.kind)
        size = network.config.input_size
        frame = read_manifest(images_dir)
        query = load_split(images_dir, "query", size, frame)
        support = load_split(images_dir, "support", size, frame)
        q_images, q_cats, s_images, n_way, k_shot = _arranged(query, support, images_dir)
        from .colour import hue_rotate  # matplotlib's colour conversions: only when loading

        q_images = hue_rotate(q_images, files.query_hue_shift)
        norm = payload["normalisation"]
        return cls_(
            network=network,
            checkpoint={k: payload[k] for k in ("model", "config", "metrics", "normalisation")},
            checkpoint_sha256=file_sha256(Path(checkpoint)),
            query_images=to_tensor(q_images, norm["mean"], norm["std"]),
            query_categories=q_cats,
            query_objects=query_objects(frame),
            support_images=to_tensor(s_images, norm["mean"], norm["std"]),
            n_way=n_way,
            k_shot=k_shot,
            class_names=support.class_names,
        )

    def about(self) -> dict[str, Any]:
        """What a recogniser of these files needs to start without them (JSON-able)."""
        return {
            "model": dict(self.checkpoint["model"]),
            "checkpoint_sha256": self.checkpoint_sha256,
            "class_names": list(self.class_names),
            "query_categories": self.query_categories.tolist(),
            "query_objects": self.query_objects.tolist(),
            "n_way": self.n_way,
            "k_shot": self.k_shot,
        }


def files_source(cls, files: RecogniserFiles) -> str | None:
    """The sha256 of everything a ``cls`` recogniser loaded from ``files`` scores with (module
    docstring), or None when a file cannot be read (loading it then says which)."""
    class_module = getattr(sys.modules.get(cls.__module__), "__file__", None)
    if class_module is None:  # a class of no file (``python -c``): its code cannot be keyed
        return None
    h = hashlib.sha256(f"{cls.__module__}.{cls.__qualname__}:{cls.kind}".encode())
    code = _code_and_versions(class_module)
    h.update(f"|{files.expected!r}|{float(files.query_hue_shift)!r}|{code}".encode())
    try:
        h.update(file_sha256(Path(files.checkpoint)).encode())
        folder = Path(files.images_dir)
        h.update((folder / MANIFEST).read_bytes())
        frame = read_manifest(folder)
        pictures = frame.loc[frame["split"].isin(["query", "support"]), "file"]
        for name in sorted(pictures.astype(str)):
            h.update(f"|{name}|{file_sha256(folder / name)}".encode())
    except (OSError, UserError):
        return None
    return h.hexdigest()


def file_sha256(path: Path) -> str:
    """The sha256 of a file's bytes, as the records name a checkpoint (``hashlib.file_digest``)."""
    with open(path, "rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()


@functools.cache
def _code_and_versions(class_module: str) -> str:
    """The sha256 of the bytes of :data:`SCORING_MODULES` and of ``class_module`` (the file of the
    recogniser's class), and the versions of Pillow and numpy."""
    h = hashlib.sha256()
    for path in [*(Path(__file__).with_name(name) for name in SCORING_MODULES), class_module]:
        h.update(Path(path).read_bytes())
    versions = [importlib.metadata.version(p) for p in ("pillow", "numpy")]
    return f"{h.hexdigest()}|pillow {versions[0]}|numpy {versions[1]}"


def _arranged(
    query: PictureSet, support: PictureSet, images_dir
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, int]:
    """The query pictures by picture id, their categories, the support pictures in position order,
    the ways and the shots; a dataset whose ids or shots do not fit is refused."""
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


#: Networks already loaded in this process, by checkpoint file (its path, size, modification time
#: and inode) and expected shape: the recognisers of one study (Table 3's five, a substitution way
#: each) share one network, so their pictures are embedded once. A recogniser only evaluates its
#: network (eval mode, no gradients), never changes it.
_NETWORKS: dict[tuple, tuple[object, dict]] = {}
MAX_NETWORKS = 8  # the oldest goes first


def network_of(checkpoint, expected, kind: str) -> tuple[object, dict]:
    """``load_checkpoint``, once per checkpoint file as it is on disk (a file replaced or
    rewritten is loaded again; one that cannot be read is refused by ``load_checkpoint``)."""
    from .checkpoint import load_checkpoint

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
