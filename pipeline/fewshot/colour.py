"""The colour test: does the recogniser rely on colour? (issue: a recogniser of categories)

A test-time transform rotates the hue of every query picture by a fixed angle (in HSV, so
saturation and value, and with them shading and texture, stay as they were) and the query
pictures are classified against the original support set, which is left as rendered. A recogniser
that matches shapes keeps its accuracy; one that matches colours loses it. Not in the paper: its
photographs fix each object's colour.
"""

from __future__ import annotations

import numpy as np
from matplotlib.colors import hsv_to_rgb, rgb_to_hsv

from pipeline.fewshot.settings import HUE_SHIFTS  # noqa: F401  (the colour test's turns)


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
) -> dict:
    """The colour test's counts: correct query pictures with the original colours and with each hue
    shift (every query picture turned, the original support set), and each picture's predictions
    (for a paired interval of the drop over pictures). Plain numbers, for ``summary.json``."""
    cats = np.asarray(categories)
    shifts = sorted(shifted_predictions)
    return {
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
