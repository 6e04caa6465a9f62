"""Reading the rendered picture sets through their manifest (the render stage's output contract,
:mod:`pipeline.manifest`: columns, splits and what each column holds).

Meta-training can instead read any folder-per-class tree (:func:`load_folder`: ``<dir>/<class>/<picture>``,
such as miniImageNet in Ravi and Larochelle's split), one tree for the training classes and one for the
validation classes (``data=folder`` of the meta_train stage).

Pictures are resized once, at load time, to the model's input size and kept as uint8 arrays.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from PIL import Image
from tqdm.auto import tqdm

from pipeline.errors import UserError
from pipeline.manifest import COLUMNS, MANIFEST, SPLITS, WHOLE_NUMBERS

#: File endings :func:`load_folder` reads as pictures (any case); other files are left alone.
PICTURE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".webp")


class DataError(UserError):
    """The picture sets on disk do not match the manifest contract."""


@dataclass(frozen=True)
class PictureSet:
    """Pictures of one split: ``images`` (N, H, W, 3) uint8, ``labels`` (N,) class indices,
    ``picture_ids`` (N,) query ids or -1, ``class_names`` indexed by label, ``files``."""

    images: np.ndarray
    labels: np.ndarray
    picture_ids: np.ndarray
    class_names: tuple[str, ...]
    files: tuple[str, ...]

    @property
    def n_classes(self) -> int:
        return len(self.class_names)

    def by_class(self) -> list[np.ndarray]:
        """Indices of the pictures of each class, in manifest order."""
        return [np.flatnonzero(self.labels == c) for c in range(self.n_classes)]


def read_manifest(images_dir: str | Path) -> pd.DataFrame:
    """The manifest as a DataFrame, with its columns checked: a file that is not CSV, a missing
    column, an unknown split, a line whose category, instance, face or picture id is not a whole
    number, or whose file is empty is refused (:class:`DataError` naming the file and line)."""
    path = Path(images_dir) / MANIFEST
    try:
        found = path.is_file()
    except OSError as exc:  # a name over the file system's limit, a loop of links
        raise DataError(
            f"cannot open the picture manifest {path} ({exc.strerror or exc}); point images_dir "
            "at a rendered dataset"
        ) from None
    if not found:
        raise DataError(
            f"no picture manifest at {path}; render the pictures first (`python -m pipeline render`) "
            f"or point images_dir at a rendered dataset"
        )
    try:
        frame = pd.read_csv(path)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise DataError(
            f"{path}: not a picture manifest (a CSV file with the columns {', '.join(COLUMNS)}): "
            f"{' '.join(str(exc).split())}"
        ) from None
    except OSError as exc:
        raise DataError(
            f"cannot read the picture manifest {path} ({exc.strerror or exc})"
        ) from None
    missing = [c for c in COLUMNS if c not in frame.columns]
    if missing:
        raise DataError(f"{path}: missing column(s) {missing}; expected {list(COLUMNS)}")
    unknown = sorted(set(frame["split"].astype(str)) - set(SPLITS))
    if unknown:
        raise DataError(f"{path}: unknown split(s) {unknown}; expected {list(SPLITS)}")
    for column in WHOLE_NUMBERS:
        numbers = pd.to_numeric(frame[column], errors="coerce")
        bad = numbers.isna() | (numbers != numbers.round())
        if bad.any():
            row = int(np.flatnonzero(bad.to_numpy())[0])
            value = frame[column].iloc[row]
            shown = "no value" if pd.isna(value) else repr(str(value))
            raise DataError(
                f"{path}:{row + 2}: column {column!r} holds {shown}, not a whole number"
            )
        frame[column] = numbers.astype(np.int64)
    names = frame["file"]
    empty = names.isna() | (names.astype(str).str.strip() == "")
    if empty.any():
        row = int(np.flatnonzero(empty.to_numpy())[0])
        raise DataError(f"{path}:{row + 2}: column 'file' is empty; it names the picture's file")
    frame["file"] = names.astype(str)
    return frame


def load_image(path: Path, size: int) -> np.ndarray:
    """One picture as (size, size, 3) uint8 RGB, resized with antialiased bilinear filtering. A
    picture of more than PIL's ``Image.MAX_IMAGE_PIXELS`` (a decompression bomb) is refused."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", Image.DecompressionBombWarning)
            with Image.open(path) as im:
                im = im.convert("RGB")
                if im.size != (size, size):
                    im = im.resize((size, size), Image.Resampling.BILINEAR)
                return np.asarray(im, dtype=np.uint8)
    except (Image.DecompressionBombWarning, Image.DecompressionBombError) as exc:
        raise DataError(f"cannot read picture {path}: too large, {exc}") from None
    except (OSError, ValueError, RuntimeError) as exc:  # RuntimeError: a symbolic link loop
        raise DataError(f"cannot read picture {path}: {exc}") from exc


def class_folders(root: Path) -> list[Path]:
    """The class folders of a folder-per-class tree: its sub-folders in name order (hidden ones
    skipped). A symbolic link loop, or a link to ``root`` or a folder above it (which would make
    the tree a class of itself), is refused naming it."""
    top = root.resolve()
    out = []
    for p in sorted(root.iterdir()):
        if p.name.startswith("."):
            continue
        try:
            target = p.resolve(strict=True)
        except (OSError, RuntimeError):
            if p.is_symlink():
                raise DataError(f"{p}: a symbolic link that leads nowhere or to itself") from None
            raise
        if target.is_dir() and top.is_relative_to(target):
            raise DataError(f"{p}: links to {target}, which holds this tree; remove the link")
        if target.is_dir():
            out.append(p)
    return out


def load_split(
    images_dir: str | Path, split: str, size: int, frame: pd.DataFrame | None = None
) -> PictureSet:
    """Load every picture of ``split`` resized to ``size`` px. Rows are sorted by
    (category, instance, face, file) so the order does not depend on how the manifest was written."""
    if split not in SPLITS:
        raise DataError(f"unknown split {split!r}; expected one of {list(SPLITS)}")
    images_dir = Path(images_dir)
    frame = read_manifest(images_dir) if frame is None else frame
    rows = frame[frame["split"] == split].sort_values(
        ["category", "instance", "face", "file"], kind="stable"
    )
    if rows.empty:
        raise DataError(f"{images_dir / MANIFEST}: no rows for split {split!r}")
    categories = rows["category"].to_numpy(dtype=np.int64)
    n_classes = int(categories.max()) + 1
    present = np.unique(categories)
    if categories.min() < 0 or len(present) != n_classes:
        raise DataError(
            f"{images_dir / MANIFEST}: split {split!r} has categories {present.tolist()}; expected 0..{n_classes - 1} all present"
        )
    names = []
    for c in range(n_classes):
        cls = rows.loc[rows["category"] == c, "class_name"].astype(str).unique()
        if len(cls) != 1:
            raise DataError(
                f"{images_dir / MANIFEST}: split {split!r} category {c} has class names {list(cls)}"
            )
        names.append(cls[0])
    files = tuple(rows["file"].astype(str))
    images = np.stack([load_image(images_dir / f, size) for f in files])
    return PictureSet(
        images=images,
        labels=categories,
        picture_ids=rows["picture_id"].to_numpy(dtype=np.int64),
        class_names=tuple(names),
        files=files,
    )


def load_folder(root: str | Path, size: int, *, progress: bool = False) -> PictureSet:
    """Every picture of a folder-per-class tree ``root/<class>/<picture>``, resized to ``size`` x
    ``size`` px (the aspect ratio is not kept; miniImageNet's pictures are square). Classes are the
    sub-folders in name order (hidden ones skipped), a class's pictures the files with a
    :data:`PICTURE_SUFFIXES` ending in name order, so the same tree gives the same set anywhere.
    A missing folder, a tree without class folders, a class without pictures or a picture that
    cannot be read raises :class:`DataError` naming it."""
    root = Path(root)
    if not root.is_dir():
        raise DataError(
            f"{root}: no such folder (expected a folder-per-class tree: <dir>/<class>/<picture>)"
        )
    classes = class_folders(root)
    if not classes:
        raise DataError(
            f"{root}: no class folders (expected <dir>/<class>/<picture>, pictures ending in "
            f"{', '.join(PICTURE_SUFFIXES)})"
        )
    files: list[str] = []
    labels: list[int] = []
    for label, folder in enumerate(classes):
        named = [f for f in folder.iterdir() if f.suffix.lower() in PICTURE_SUFFIXES]
        for f in named:
            if f.is_symlink() and not f.exists():  # not left out without a word
                raise DataError(f"{f}: a symbolic link that leads nowhere or to itself")
        pictures = sorted(f.name for f in named if f.is_file())
        if not pictures:
            raise DataError(
                f"{folder}: class folder without pictures (files ending in {', '.join(PICTURE_SUFFIXES)})"
            )
        files += [f"{folder.name}/{name}" for name in pictures]
        labels += [label] * len(pictures)
    bar = tqdm(
        files, desc=f"load {root.name}", unit="picture", disable=not progress, mininterval=2.0
    )
    return PictureSet(
        images=np.stack([load_image(root / f, size) for f in bar]),
        labels=np.asarray(labels, dtype=np.int64),
        picture_ids=np.full(len(files), -1, dtype=np.int64),
        class_names=tuple(p.name for p in classes),
        files=tuple(files),
    )


def channel_stats(images: np.ndarray) -> tuple[list[float], list[float]]:
    """Per-channel mean and standard deviation of uint8 pictures, on the [0, 1] scale."""
    x = images.reshape(-1, 3).astype(np.float64) / 255.0
    return x.mean(axis=0).tolist(), np.maximum(x.std(axis=0), 1e-3).tolist()


def to_tensor(images: np.ndarray, mean: list[float], std: list[float]):
    """uint8 (N, H, W, 3) -> normalised float32 torch tensor (N, 3, H, W)."""
    import torch

    x = torch.from_numpy(np.ascontiguousarray(images)).permute(0, 3, 1, 2).float().div_(255.0)
    m = torch.tensor(mean, dtype=torch.float32).view(1, 3, 1, 1)
    s = torch.tensor(std, dtype=torch.float32).view(1, 3, 1, 1)
    return (x - m) / s
