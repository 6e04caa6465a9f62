"""The report's recogniser section: how well each few-shot recogniser sees (the test families'
accuracy quoted, the validation families' beside it, docs/fewshot.md) and whether it relies on
colour (:mod:`pipeline.fewshot.colour`). The test figures come from the model's metrics file, the
rest from its accuracy study's ``summary.json``; the tables' captions say how each is measured.
Beside them, the intervals at the level the data vary (:mod:`.recogniser_intervals`).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from pipeline.report.recogniser_intervals import families_table, shifts_table
from pipeline.report.study import read_summary
from pipeline.stats import bootstrap_ci, wilson_ci

COLUMNS = (
    "recogniser",
    "test [95%]",
    "validation [95%]",
    "query pictures [95%]",
    "views of the query obstacles [95%]",
)
#: The colour test's pictures, by their ``summary.json`` key.
COLOUR_SETS = {
    "colour_test": "the 40 query pictures",
    "colour_test_views": "views of the query obstacles",
}


def _interval(lo: float, hi: float) -> str:
    return f"[{100 * lo:.1f}, {100 * hi:.1f}]"


def recogniser_row(name: str, metrics: Path, accuracy_dir: Path) -> dict:
    """One row of the recogniser table (module docstring); a missing file is named in its cell."""
    row = dict.fromkeys(COLUMNS, "")
    row["recogniser"] = name
    if metrics.exists():
        m = json.loads(metrics.read_text())
        row["test [95%]"] = f"{100 * m['accuracy']:.2f}% {_interval(m['ci_lower'], m['ci_upper'])}"
    else:
        row["test [95%]"] = f"no metrics file `{metrics}`"
    summary = read_summary(accuracy_dir)
    if summary is None:
        row["query pictures [95%]"] = f"no study `{accuracy_dir / 'summary.json'}`"
        return row
    scores = summary.get("checkpoint_metrics") or {}
    if "test_episodes" in scores:
        row["test [95%]"] += (
            f" ({scores['test_episodes']} episodes, {scores['n_test_classes']} families)"
        )
    if "val_accuracy" in scores:
        acc, ci = scores["val_accuracy"], scores["val_ci95"]
        row["validation [95%]"] = (
            f"{100 * acc:.2f}% {_interval(acc - ci, acc + ci)} ({scores['val_episodes']} episodes, "
            f"{scores.get('n_val_classes', '?')} families)"
        )
    correct = int(sum(summary["baseline"]["correct"]))
    total = int(sum(summary["baseline"]["total"]))
    row["query pictures [95%]"] = _share(correct, total)
    views = summary.get("colour_test_views")
    row["views of the query obstacles [95%]"] = (
        _share(views["correct_original"], views["pictures"])
        if views
        else "not measured (no views split, or the study ran without the colour test)"
    )
    return row


def _share(correct: int, total: int) -> str:
    lo, hi = wilson_ci(correct / total, total)
    return f"{correct}/{total} = {100 * correct / total:.1f}% {_interval(lo, hi)}"


def colour_rows(name: str, accuracy_dir: Path) -> list[dict]:
    """The colour test's rows of one recogniser: one per picture set the study measured."""
    summary = read_summary(accuracy_dir) or {}
    rows = []
    for key, words in COLOUR_SETS.items():
        colour = summary.get(key)
        if not colour or not colour["shifts_deg"]:
            continue
        cats = np.asarray(colour["categories"])
        turned = np.asarray(colour["predictions_per_shift"])  # (shifts, pictures)
        original = (np.asarray(colour["predictions_original"]) == cats).astype(float)
        per_picture = (turned == cats).mean(axis=0)
        drop = original - per_picture
        rows.append(
            {
                "recogniser": name,
                "pictures": f"{words} ({colour['pictures']})",
                "as rendered": f"{100 * original.mean():.1f}%",
                "hue-turned [95%]": f"{int((turned == cats).sum())}/{turned.size} = "
                f"{100 * per_picture.mean():.1f}% {_interval(*bootstrap_ci(per_picture))}",
                "drop, points [95%]": f"{100 * drop.mean():.1f} "
                + "[{:.1f}, {:.1f}]".format(*(100 * x for x in bootstrap_ci(drop))),
            }
        )
    return rows


def recogniser_section(rep, studies: list[tuple[str, Path, Path]]) -> None:
    """The section's two tables for ``studies``: (name, metrics file, accuracy study folder)."""
    rows = [
        recogniser_row(name, metrics, folder)
        for name, metrics, folder in studies
        if metrics.exists() or (folder / "summary.json").exists()
    ]
    if not rows:
        return
    rep.add("## The recogniser\n")
    rep.table(
        "recogniser",
        pd.DataFrame(rows),
        "Test: 5-way 5-shot accuracy on the held-out test families (never trained on, never used to "
        "choose the checkpoint, each at least the render's min_family_distance from every training "
        "family: `pipeline/world/family_split.py`), mean "
        "over the episodes with its 95% interval: the figure to quote. Validation: the same on the "
        "validation families, which chose the checkpoint (optimistic). Query pictures: the 40 "
        "pictures the robot takes, against the original support set, with a Wilson 95% interval; "
        "views of the query obstacles: the same ten obstacles from many random sides and distances "
        "in the maze (`pipeline/fewshot/views.py`).",
    )
    families_table(rep, studies)
    colour = [r for name, _, folder in studies for r in colour_rows(name, folder)]
    if colour:
        rep.table(
            "colour_test",
            pd.DataFrame(colour),
            "Colour test: every picture's hue turned by each of the study's hue shifts (the support "
            "set as rendered; `pipeline/fewshot/colour.py`), correct over pictures x shifts; its "
            "interval and the drop's (paired, in points) are bootstrap 95% intervals over the "
            "pictures. The 400 views give the test its power; the 40 query pictures are the paper's.",
        )
        shifts_table(rep, studies, COLOUR_SETS)
