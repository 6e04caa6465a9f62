"""The colour test with power: the query obstacles from many viewpoints (issue 29, Deliver 6).

The paper's 40 query pictures (two instances x four sides x five categories) stay the query set of
every experiment; they are too few for the colour test (:mod:`.colour`): a drop of 4 points has a
95% interval of about +-8.5 points over 40 pictures. The render stage's ``views`` split shows the
same ten obstacles (each category's two objects, instances 0 and 1) in the maze,
``views_per_obstacle`` pictures each from random sides and distances (``render_plan.views_batch``):
400 pictures at the paper's scale. A few-shot recogniser classifies each against the *original*
support set (no substitution, ``substitution_way`` 0), as rendered and with each hue shift;
:func:`.colour.colour_test` counts the outcomes as for the 40 query pictures.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .colour import hue_rotate
from .data import load_split, read_manifest, to_tensor
from .support_recogniser import SupportSetRecogniser

SPLIT = "views"


def has_views(images_dir: str | Path) -> bool:
    """Whether ``images_dir``'s manifest holds the ``views`` split (a render with
    ``views_per_obstacle`` 0, or an older one, has none)."""
    return bool((read_manifest(images_dir)["split"] == SPLIT).any())


def views_predictions(
    recogniser: SupportSetRecogniser,
    images_dir: str | Path,
    shifts: list[float],
    base_shift: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[float, np.ndarray]]:
    """The true categories of the ``views`` pictures of ``images_dir``, the obstacle each shows
    (its manifest category and instance, numbered 0, 1, ... in that order), the recogniser's
    predictions for them turned by ``base_shift`` (the recogniser's own ``query_hue_shift``; 0: as
    rendered), and per hue shift (degrees, on top of it), all against its network's original support
    set (the same pictures, size and normalisation the recogniser was loaded with)."""
    network = recogniser.network
    size = network.config.input_size
    norm = recogniser.checkpoint["normalisation"]
    frame = read_manifest(images_dir)
    views = load_split(images_dir, SPLIT, size, frame)
    support = load_split(images_dir, "support", size, frame)
    if views.class_names != support.class_names:
        raise ValueError(
            f"{images_dir}: the views split's categories {views.class_names} are not the support "
            f"set's {support.class_names}"
        )
    support_images = to_tensor(support.images, norm["mean"], norm["std"])
    rows = frame[frame["split"] == SPLIT].set_index("file")
    instances = rows.loc[list(views.files), "instance"].to_numpy()
    _, obstacles = np.unique(np.stack([views.labels, instances], 1), axis=0, return_inverse=True)

    def predict(shift: float) -> np.ndarray:
        rec = type(recogniser)(
            network,
            to_tensor(hue_rotate(views.images, shift), norm["mean"], norm["std"]),
            views.labels,
            support_images,
            n_way=recogniser.n_way,
            k_shot=recogniser.k_shot,
            substitution_way=0,
        )
        rec.start_run(0, 0)
        return rec.predictions(0)

    return (
        views.labels,
        obstacles,
        predict(base_shift),
        {float(s): predict(base_shift + s) for s in shifts},
    )
