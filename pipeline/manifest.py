"""The picture sets' manifest, ``<images_dir>/manifest.csv``: the contract between the render
stage, which writes it (:mod:`pipeline.world.render_plan`), and the few-shot code, which reads it
(:mod:`pipeline.fewshot.data`). Declared once, here.

Its columns are :class:`Row`'s fields (:data:`COLUMNS`): ``file`` is relative to ``images_dir``; for the ``query`` and
``support`` splits ``category`` is the obstacle category (0..4, the paper's chair, kettle, carton,
basin, basket); for ``train`` and ``val`` it is a class index within the split; ``picture_id`` is
the query-picture id (``category * 8 + instance * 4 + face``) on query rows and -1 elsewhere.
"""

from typing import NamedTuple

MANIFEST = "manifest.csv"


class Row(NamedTuple):
    """One picture's line (``face`` and ``picture_id`` are -1 where they do not apply)."""

    split: str
    category: int
    class_name: str
    instance: int
    face: int
    orientation_deg: float  #: rounded to 3 decimals
    picture_id: int
    file: str


COLUMNS = Row._fields
SPLITS = ("query", "support", "train", "val", "test", "views")
#: Columns that hold whole numbers (a manifest line with another value is refused, naming it).
WHOLE_NUMBERS = ("category", "instance", "face", "picture_id")
