"""Procedural obstacles of the five query categories (paper section 4.1, Figure 6): category ids,
one seed per instance, the toy world's display scale, :func:`build_obstacle` and every instance by its id (:func:`obstacle_instance`). Each category is
a seeded family of objects (``obstacle_families.py``) coloured from ``obstacle_palette.py``.
"""

from __future__ import annotations

import numpy as np

from pipeline.world.obstacle_families import BUILDERS
from pipeline.world.obstacle_palette import hsv
from pipeline.world.pictures import CATEGORIES
from pipeline.world.shapes import ObjectModel

__all__ = [
    "DISPLAY_SCALE",
    "build_obstacle",
    "category_index",
    "hsv",
    "obstacle_seed",
    "obstacle_instance",
]


def category_index(category: str | int) -> int:
    """Category id (``pictures.CATEGORIES`` order) of a name or id; a clear error otherwise."""
    if isinstance(category, (int, np.integer)) and not isinstance(category, bool):
        if 0 <= int(category) < len(CATEGORIES):
            return int(category)
        raise ValueError(
            f"unknown category id {category}; ids are 0..{len(CATEGORIES) - 1} ({', '.join(CATEGORIES)})"
        )
    if category in BUILDERS:
        return CATEGORIES.index(str(category))
    raise ValueError(f"unknown category {category!r}; known categories: {', '.join(CATEGORIES)}")


def obstacle_seed(seed: int, category: int, instance: int) -> np.random.SeedSequence:
    """One seed per (category, geometric instance): the same instance is the same object everywhere."""
    return np.random.SeedSequence([int(seed), 1, int(category), int(instance)])


# Toy-world scale: the maze's obstacles all fit a 1 m cell and a low robot camera, so chairs are
# shrunk and small things enlarged (the paper's photographed objects differ; see docs/render.md).
DISPLAY_SCALE = {"chair": 0.7, "kettle": 1.25, "carton": 1.0, "basin": 1.2, "basket": 1.3}


def build_obstacle(category: str | int, rng: np.random.Generator) -> ObjectModel:
    """A random instance of ``category`` (name or id), at display scale."""
    name = CATEGORIES[category_index(category)]
    return BUILDERS[name](rng).scaled(DISPLAY_SCALE[name])


def obstacle_instance(category: str | int, instance: int, seed: int) -> ObjectModel:
    """Geometric instance ``instance`` of ``category``, the same object everywhere it appears.
    Instances 0 and 1 are the category's two physical obstacles (query pictures, views, the
    robot's maze), 2, 3, ... the support set's catalogue objects. Every instance is its own draw
    of the category's family (proportions, part styles, colours), so the maze holds two different
    objects per category, as the paper's photographed obstacles are, not one object turned."""
    rng = np.random.default_rng(obstacle_seed(seed, category_index(category), instance))
    return build_obstacle(category, rng)
