"""A tiny synthetic picture set in the render stage's manifest format (see :mod:`.data`), for tests
and smoke runs: each class is a coloured shape (disc, square, cross, stripes...) on a noisy
background, with per-picture jitter of position, size and brightness. Deterministic for a seed.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from PIL import Image

from .data import COLUMNS, MANIFEST

SHAPES = ("disc", "square", "cross", "hstripes", "vstripes", "ring", "triangle", "diamond")


def _draw(
    rng: np.random.Generator, size: int, shape: str, colour: np.ndarray, background: np.ndarray
) -> np.ndarray:
    yy, xx = np.mgrid[0:size, 0:size].astype(np.float64) / size
    cx, cy = 0.5 + rng.uniform(-0.12, 0.12, 2)
    r = rng.uniform(0.22, 0.32)
    dx, dy = xx - cx, yy - cy
    if shape == "disc":
        mask = dx**2 + dy**2 < r**2
    elif shape == "square":
        mask = (abs(dx) < r) & (abs(dy) < r)
    elif shape == "cross":
        mask = ((abs(dx) < r / 3) & (abs(dy) < r)) | ((abs(dy) < r / 3) & (abs(dx) < r))
    elif shape == "hstripes":
        mask = (np.floor(yy * 8) % 2 == 0) & (abs(dx) < r) & (abs(dy) < r)
    elif shape == "vstripes":
        mask = (np.floor(xx * 8) % 2 == 0) & (abs(dx) < r) & (abs(dy) < r)
    elif shape == "ring":
        d = np.sqrt(dx**2 + dy**2)
        mask = (d < r) & (d > r / 2)
    elif shape == "triangle":
        mask = (dy < r) & (dy > -r) & (abs(dx) < (dy + r) / 2)
    else:  # diamond
        mask = abs(dx) + abs(dy) < r
    img = background + rng.normal(0, 12, (size, size, 3))
    img[mask] = colour * rng.uniform(0.8, 1.2) + rng.normal(0, 8, (int(mask.sum()), 3))
    return np.clip(img, 0, 255).astype(np.uint8)


def write_synthetic_dataset(
    images_dir: str | Path,
    *,
    n_train: int = 8,
    n_val: int = 4,
    n_test: int = 5,
    per_class: int = 20,
    views_per_category: int = 0,
    size: int = 24,
    seed: int = 0,
) -> Path:
    """Write PNGs and ``manifest.csv`` under ``images_dir``; returns the manifest path. The train,
    val and test splits hold ``n_train``, ``n_val`` and ``n_test`` classes, the views split
    ``views_per_category`` pictures of each query category (like its query pictures); the query
    and support splits hold 5 categories (2 instances x 4 faces, and 5 pictures each)."""
    images_dir = Path(images_dir)
    rng = np.random.default_rng(seed)
    n_classes = n_train + n_val + n_test + 5
    colours = rng.uniform(40, 255, (n_classes, 3))
    backgrounds = rng.uniform(0, 120, (n_classes, 3))
    shapes = [SHAPES[i % len(SHAPES)] for i in rng.permutation(n_classes)]
    rows = []

    def write(
        split: str,
        cls: int,
        label: int,
        name: str,
        instance: int,
        face: int,
        pid: int,
        bg_shift: float,
    ) -> None:
        rel = f"{split}/{name}/{instance}_{face}_{len(rows):05d}.png"
        path = images_dir / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        img = _draw(
            rng, size, shapes[cls], colours[cls], np.clip(backgrounds[cls] + bg_shift, 0, 255)
        )
        Image.fromarray(img).save(path)
        rows.append((split, label, name, instance, face, 0.0, pid, rel))

    for split, first, count in (
        ("train", 0, n_train),
        ("val", n_train, n_val),
        ("test", n_train + n_val, n_test),
    ):
        for label in range(count):
            cls = first + label
            for i in range(per_class):
                write(split, cls, label, f"{split}_class_{label:03d}", i, 0, -1, 0.0)
    for category in range(5):
        cls = n_train + n_val + n_test + category
        name = f"category_{category}"
        for instance in range(2):
            for face in range(4):
                write(
                    "query",
                    cls,
                    category,
                    name,
                    instance,
                    face,
                    (category * 2 + instance) * 4 + face,
                    0.0,
                )
        for k in range(5):  # the support pictures: a different "catalogue" background
            write("support", cls, category, name, k, 0, -1, 40.0)
        for k in range(views_per_category):
            write("views", cls, category, name, k % 2, -1, -1, 0.0)
    pd.DataFrame(rows, columns=list(COLUMNS)).to_csv(images_dir / MANIFEST, index=False)
    return images_dir / MANIFEST
