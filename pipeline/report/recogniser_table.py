"""The report's recogniser section: how well each few-shot recogniser sees (the test families'
accuracy quoted, the validation families' beside it, docs/fewshot.md) and whether it relies on
colour (:mod:`pipeline.fewshot.colour`). The test figures come from the model's metrics file, the
rest from its accuracy study's ``summary.json``; the tables' captions say how each is measured.

Beside them, the intervals at the level the data vary (issue 42): the held-out families' accuracy
with an episode-level and a family-level interval (the accuracy study's ``families``,
:mod:`pipeline.fewshot.family_accuracy`), and the colour test per hue shift with intervals that
resample obstacles (:func:`pipeline.fewshot.colour.shift_changes`). Both from the study's
``summary.json``; a study from before they were measured shows neither.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from pipeline.fewshot.colour import RESAMPLES, shift_changes
from pipeline.report.formats import estimate, interval, share
from pipeline.report.study import read_summary
from pipeline.stats import bootstrap_ci

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
#: The caption of the colour test per hue shift (:func:`shifts_table`).
SHIFTS_CAPTION = (
    "Colour test per hue shift: accuracy as rendered and with every picture's hue turned, "
    "and the change (turned minus as rendered, picture by picture) in points with a 95% "
    "percentile-bootstrap interval that resamples the obstacles (each with all its "
    f"pictures; {RESAMPLES} resamples), not the pictures: the pictures of one obstacle "
    "are not independent. An obstacle is a category's instance in the maze (the "
    "manifest's category and instance; `pipeline/fewshot/colour.py`)."
)
#: The held-out splits as the families' table names them, in its order.
SPLIT_WORDS = {"test": "test", "val": "validation"}


def recogniser_row(name: str, metrics: Path, accuracy_dir: Path) -> dict:
    """One row of the recogniser table (module docstring); a missing file is named in its cell."""
    row = dict.fromkeys(COLUMNS, "")
    row["recogniser"] = name
    if metrics.exists():
        m = json.loads(metrics.read_text())
        row["test [95%]"] = (
            f"{100 * m['accuracy']:.2f}% {interval(m['ci_lower'], m['ci_upper'], 1, 100)}"
        )
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
            f"{100 * acc:.2f}% {interval(acc - ci, acc + ci, 1, 100)} ({scores['val_episodes']} episodes, "
            f"{scores.get('n_val_classes', '?')} families)"
        )
    correct = int(sum(summary["baseline"]["correct"]))
    total = int(sum(summary["baseline"]["total"]))
    row["query pictures [95%]"] = share(correct, total)
    views = summary.get("colour_test_views")
    row["views of the query obstacles [95%]"] = (
        share(views["correct_original"], views["pictures"])
        if views
        else "not measured (no views split, or the study ran without the colour test)"
    )
    return row


def colour_tests(accuracy_dir: Path) -> list[tuple[str, dict]]:
    """The picture sets of :data:`COLOUR_SETS` the study's colour test measured: (words, the
    test's ``summary.json`` entry)."""
    summary = read_summary(accuracy_dir) or {}
    found = [(words, summary.get(key)) for key, words in COLOUR_SETS.items()]
    return [(words, colour) for words, colour in found if colour and colour["shifts_deg"]]


def colour_rows(name: str, accuracy_dir: Path) -> list[dict]:
    """The colour test's rows of one recogniser: one per picture set the study measured."""
    rows = []
    for words, colour in colour_tests(accuracy_dir):
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
                f"{100 * per_picture.mean():.1f}% {interval(*bootstrap_ci(per_picture), 1, 100)}",
                "drop, points [95%]": estimate(drop.mean(), *bootstrap_ci(drop), 1, 100),
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
        shifts_table(rep, studies)


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
            "episode-level [95%]": interval(*found[split]["episode_ci"], scale=100),
            "family-level [95%]": interval(*found[split]["family_ci"], scale=100),
        }
        for split, words in SPLIT_WORDS.items()
        if split in found
    ]


def shift_rows(name: str, accuracy_dir: Path) -> list[dict]:
    """One row per picture set (:func:`colour_tests`) and hue shift: the accuracy as rendered and
    hue-turned, and the change in points with its interval over obstacles; sets without obstacle
    ids (an older study) are left out."""
    rows = []
    for words, colour in colour_tests(accuracy_dir):
        if "obstacles" not in colour:
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
                    "change, points [95%, obstacles]": estimate(
                        change["change"], *change["change_ci"], scale=100, sign="+"
                    ),
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


def shifts_table(rep, studies: list[tuple[str, Path, Path]]) -> None:
    """The colour test per hue shift (module docstring), when a study kept the obstacles."""
    rows = [r for name, _, folder in studies for r in shift_rows(name, folder)]
    if rows:
        rep.table("colour_test_shifts", pd.DataFrame(rows), SHIFTS_CAPTION)
