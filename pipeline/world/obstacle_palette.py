"""The colours and finishes the procedural obstacles draw from (``obstacle_families.py``): wood,
bright paint, neutral plastics and steel, each a seeded range in HSV; also used by the meta-training
classes (``metaset.py``)."""

from __future__ import annotations

import colorsys

import numpy as np

RGB = tuple[float, float, float]


def hsv(h: float, s: float, v: float) -> RGB:
    r, g, b = colorsys.hsv_to_rgb(h % 1.0, float(np.clip(s, 0, 1)), float(np.clip(v, 0, 1)))
    return (r, g, b)


def wood(rng: np.random.Generator) -> RGB:
    return hsv(rng.uniform(0.05, 0.10), rng.uniform(0.45, 0.75), rng.uniform(0.30, 0.75))


def bright(rng: np.random.Generator) -> RGB:
    return hsv(rng.uniform(0, 1), rng.uniform(0.55, 0.95), rng.uniform(0.55, 0.95))


def neutral(rng: np.random.Generator) -> RGB:
    v = rng.choice([rng.uniform(0.08, 0.2), rng.uniform(0.75, 0.95)])
    return hsv(rng.uniform(0, 1), rng.uniform(0.0, 0.08), v)


def steel(rng: np.random.Generator) -> RGB:
    return hsv(rng.uniform(0.55, 0.65), rng.uniform(0.02, 0.10), rng.uniform(0.60, 0.85))
