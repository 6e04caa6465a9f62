"""The colour test: does the recogniser rely on colour? (issue: a recogniser of categories)

A test-time transform rotates the hue of every query picture by a fixed angle (in HSV, so
saturation and value, and with them shading and texture, stay as they were) and the query
pictures are classified against the original support set, which is left as rendered. A recogniser
that matches shapes keeps its accuracy; one that matches colours loses it. Not in the paper: its
photographs fix each object's colour.

The pictures are not independent: each shows one of the ten query obstacles (a category's
instance in the maze), four query pictures or ``views_per_obstacle`` views of each. :func:`shift_changes` gives each hue shift's
change of accuracy with an interval that resamples obstacles, not pictures.
"""

from __future__ import annotations

import numpy as np
from matplotlib.colors import hsv_to_rgb, rgb_to_hsv

from pipeline.fewshot.settings import HUE_SHIFTS  # noqa: F401  (the colour test's turns)
from pipeline.stats import cluster_ratio_draws, percentile_ci

#: Bootstrap resamples of :func:`shift_changes`.
RESAMPLES = 2000


def hue_rotate(images: np.ndarray, degrees: float) -> np.ndarray:
    """uint8 pictures (..., 3) with every pixel's hue turned by ``degrees`` (HSV; greys unchanged)."""
    if degrees % 360.0 == 0.0:
        return images
    hsv = rgb_to_hsv(images.astype(np.float64) / 255.0)
    hsv[..., 0] = (hsv[..., 0] + degrees / 360.0) % 1.0
    return np.clip(np.rint(hsv_to_rgb(hsv) * 255.0), 0, 255).astype(np.uint8)


def colour_test(
    baseline_predictions: np.ndarray,
    shifted_predictions: dict[float, np.ndarray],
    categories: np.ndarray,
    obstacles: np.ndarray | None = None,
) -> dict:
    """The colour test's counts: correct query pictures with the original colours and with each hue
    shift (every query picture turned, the original support set), and each picture's predictions
    and, given, its obstacle (an id per picture; for intervals of the drop that resample
    obstacles, :func:`shift_changes`). Plain numbers, for ``summary.json``."""
    cats = np.asarray(categories)
    shifts = sorted(shifted_predictions)
    extra = {} if obstacles is None else {"obstacles": np.asarray(obstacles).astype(int).tolist()}
    return {
        **extra,
        "shifts_deg": [float(s) for s in shifts],
        "pictures": int(len(cats)),
        "correct_original": int((np.asarray(baseline_predictions) == cats).sum()),
        "correct_per_shift": [
            int((np.asarray(shifted_predictions[s]) == cats).sum()) for s in shifts
        ],
        "categories": cats.astype(int).tolist(),
        "predictions_original": np.asarray(baseline_predictions).astype(int).tolist(),
        "predictions_per_shift": [
            np.asarray(shifted_predictions[s]).astype(int).tolist() for s in shifts
        ],
    }


def shift_changes(
    categories, original, per_shift, obstacles, *, resamples: int = RESAMPLES, seed=0
) -> list[dict]:
    """Per hue shift (row ``s`` of ``per_shift``, shifts x pictures of predictions): the accuracy
    as rendered (``original``: each picture's prediction), hue-turned, and the change (turned minus
    as rendered, a share: paired, picture by picture) with its 95% percentile-bootstrap interval
    that resamples obstacles (one-level cluster bootstrap, :func:`pipeline.stats.
    cluster_ratio_draws`: as many obstacles as there are, with replacement, each with all its
    pictures). Every shift resamples the same obstacles (one seed)."""
    cats = np.asarray(categories)
    before = (np.asarray(original) == cats).astype(float)
    rows = []
    for turned in np.atleast_2d(np.asarray(per_shift)):
        after = (turned == cats).astype(float)
        draws = cluster_ratio_draws(
            after - before,
            np.ones_like(before),
            obstacles,
            within=False,
            resamples=resamples,
            seed=seed,
        )
        rows.append(
            {
                "as_rendered": float(before.mean()),
                "turned": float(after.mean()),
                "change": float(after.mean() - before.mean()),
                "change_ci": list(percentile_ci(draws)),
            }
        )
    return rows
