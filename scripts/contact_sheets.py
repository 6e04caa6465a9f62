"""Redraw the contact sheets from pictures already rendered (no rendering): the render stage's
contact-sheet step on ``<out_dir>/manifest.csv``, with conf/render.yaml's settings and
overrides.

    python scripts/contact_sheets.py                                  # datasets/images -> its contact_sheets/
    python scripts/contact_sheets.py out_dir=/path/images figures_dir=/tmp/sheets
"""

import csv
import sys
from pathlib import Path

from pipeline.config.compose import load_config
from pipeline.stages.render import MANIFEST, write_contact_sheets


def main(overrides: list[str]) -> None:
    cfg = load_config("render", overrides)
    images = Path(cfg.out_dir)
    with (images / MANIFEST).open(newline="") as f:
        rows = [
            {**r, "category": int(r["category"]), "picture_id": int(r["picture_id"])}
            for r in csv.DictReader(f)
        ]
    for path in write_contact_sheets(
        rows,
        images,
        Path(cfg.figures_dir),
        cfg.contact_tile,
        cfg.contact_train_classes,
        cfg.contact_per_class,
    ):
        print(f"wrote {path}")


if __name__ == "__main__":
    main(sys.argv[1:])
