"""The recogniser section's intervals at the level the data vary (issue 42): the held-out families'
accuracy with an episode-level and a family-level interval (the accuracy study's ``families``,
:mod:`pipeline.fewshot.family_accuracy`), and the colour test per hue shift with intervals that
resample obstacles (:func:`pipeline.fewshot.colour.shift_changes`). Both from the study's
``summary.json``; a study from before they were measured shows neither.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from pipeline.fewshot.colour import RESAMPLES, shift_changes
from pipeline.report.study import read_summary

#: The held-out splits as the table names them, in its order.
SPLIT_WORDS = {"test": "test", "val": "validation"}


def _points(lo: float, hi: float) -> str:
    return f"[{100 * lo:.2f}, {100 * hi:.2f}]"


def family_rows(name: str, accuracy_dir: Path) -> list[dict]:
    """One row per held-out split the study measured: its accuracy over fresh episodes, the
    interval over those episodes and the interval over families (two-level)."""
    found = (read_summary(accuracy_dir) or {}).get("families")
    if not found:
        return []
    return [
        {
            "recogniser": name,
            "families": f"{words} ({found[split]['families']})",
            "episodes": found[split]["episodes"],
            "accuracy": f"{100 * found[split]['accuracy']:.2f}%",
            "episode-level [95%]": _points(*found[split]["episode_ci"]),
            "family-level [95%]": _points(*found[split]["family_ci"]),
        }
        for split, words in SPLIT_WORDS.items()
        if split in found
    ]


def shift_rows(name: str, accuracy_dir: Path, sets: dict[str, str]) -> list[dict]:
    """One row per picture set of ``sets`` (``summary.json`` key: words) and hue shift: the
    accuracy as rendered and hue-turned, and the change in points with its interval over
    obstacles; sets without obstacle ids (an older study) are left out."""
    summary = read_summary(accuracy_dir) or {}
    rows = []
    for key, words in sets.items():
        colour = summary.get(key)
        if not colour or not colour["shifts_deg"] or "obstacles" not in colour:
            continue
        changes = shift_changes(
            colour["categories"],
            colour["predictions_original"],
            colour["predictions_per_shift"],
            colour["obstacles"],
        )
        obstacles = len(np.unique(colour["obstacles"]))
        for shift, change in zip(colour["shifts_deg"], changes):
            rows.append(
                {
                    "recogniser": name,
                    "pictures": f"{words} ({colour['pictures']}, {obstacles} obstacles)",
                    "hue shift (deg)": f"{shift:g}",
                    "as rendered": f"{100 * change['as_rendered']:.1f}%",
                    "hue-turned": f"{100 * change['turned']:.1f}%",
                    "change, points [95%, obstacles]": f"{100 * change['change']:+.2f} "
                    + "[{:+.2f}, {:+.2f}]".format(*(100 * x for x in change["change_ci"])),
                }
            )
    return rows


def families_table(rep, studies: list[tuple[str, Path, Path]]) -> None:
    """The held-out families' table (module docstring), when a study measured them."""
    rows = [r for name, _, folder in studies for r in family_rows(name, folder)]
    if not rows:
        return
    summary = next(
        read_summary(folder)["families"]
        for _, _, folder in studies
        if (read_summary(folder) or {}).get("families")
    )
    shape = summary["episode_shape"]
    rep.table(
        "recogniser_families",
        pd.DataFrame(rows),
        f"Accuracy on the held-out families with intervals at the level the data vary: "
        f"{summary['episodes_per_split']} fresh {shape['n_way']}-way {shape['k_shot']}-shot "
        f"episodes ({shape['eval_queries']} queries a family) per split, other episodes than the "
        "quoted figure's above (`families.csv`). Episode-level: percentile bootstrap over the "
        "episodes, for these families; family-level: a two-level bootstrap that resamples the "
        "families, then the episodes each family appeared in (the queries of that family in "
        f"them), for a new draw of families ({summary['resamples']} resamples; "
        "`pipeline/fewshot/family_accuracy.py`). The validation families chose the checkpoint and "
        "are not kept apart from the test families (that needs a new split and training).",
    )


def shifts_table(rep, studies: list[tuple[str, Path, Path]], sets: dict[str, str]) -> None:
    """The colour test per hue shift (module docstring), when a study kept the obstacles."""
    rows = [r for name, _, folder in studies for r in shift_rows(name, folder, sets)]
    if rows:
        rep.table(
            "colour_test_shifts",
            pd.DataFrame(rows),
            "Colour test per hue shift: accuracy as rendered and with every picture's hue turned, "
            "and the change (turned minus as rendered, picture by picture) in points with a 95% "
            "percentile-bootstrap interval that resamples the obstacles (each with all its "
            f"pictures; {RESAMPLES} resamples), not the pictures: the pictures of one obstacle "
            "are not independent. An obstacle is a category's instance in the maze (the "
            "manifest's category and instance; `pipeline/fewshot/colour.py`).",
        )
