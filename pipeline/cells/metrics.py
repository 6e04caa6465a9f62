"""An experiment's DVC metrics: what a person compares, one small JSON file per row.

``dvc metrics show`` prints one line per metrics file with a column per key, so an experiment's
metrics are a folder (``metrics_dir``) of files with the same few keys: ``<cell>.json`` for each
cell listed by hand, and ``<template>_<size>.json`` for each cell template over a set of generated
layouts (``<template>_<size>_<obstacles>obstacles.json`` where several sets share the size: the
``repetition`` experiment's) (the mean over layouts of each layout's mean collisions per run, with a 95% bootstrap
interval over layouts). Every number per cell and per layout stays in the report's CSV tables.
"""

from __future__ import annotations

import shutil
from dataclasses import asdict
from pathlib import Path

import numpy as np

from pipeline.files import write_json_atomic
from pipeline.stats import bootstrap_ci

#: The keys of every metrics file (the columns of ``dvc metrics show``): mean collisions per run,
#: its 95% bootstrap interval, the fraction of runs whose greedy path converged.
KEYS = ("collisions", "ci_lower", "ci_upper", "converged")


def rows(experiment, summaries: dict[str, dict]) -> dict[str, list[dict]]:
    """The cells' summaries grouped into metric rows: a hand-listed cell alone, generated cells by
    (template, size), and by obstacles where several sets share a size."""
    generated = {}
    if experiment is not None and experiment.layouts is not None:
        from pipeline.world.layout_sets import expand

        sets = [asdict(s) for s in experiment.layouts.sizes]
        sizes = [s["size"] for s in sets]
        for name, g in expand(sets, list(experiment.layouts.cells)).items():
            s = sets[g.set_index]
            shared = sizes.count(s["size"]) > 1  # sets of one size: told apart by obstacles
            tail = f"{s['size']}_{s['obstacles']}obstacles" if shared else s["size"]
            generated[name] = f"{g.template}_{tail}"
    out: dict[str, list[dict]] = {}
    for name, summary in summaries.items():
        out.setdefault(generated.get(name, name), []).append(summary)
    return out


def row_metrics(cells: list[dict]) -> dict:
    """Mean collisions per run (over runs for one cell, over layouts' means for several) with its
    95% bootstrap interval, and the fraction of runs whose greedy path converged."""
    if len(cells) == 1:
        values = [r["collisions"] for r in cells[0]["runs"]]
    else:
        values = [c["collisions"]["mean"] for c in cells]
    lo, hi = bootstrap_ci(values)
    runs = sum(c["n_runs"] for c in cells)
    return dict(
        zip(
            KEYS,
            (
                round(float(np.mean(values)), 3),
                round(lo, 3),
                round(hi, 3),
                round(sum(c["converged_runs"] for c in cells) / max(runs, 1), 3),
            ),
        )
    )


def write_metrics(folder: str | Path, experiment, summaries: dict[str, dict]) -> Path:
    """Replace ``folder`` with one ``<row>.json`` per metric row of the experiment."""
    folder = Path(folder)
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    for name, cells in rows(experiment, summaries).items():
        write_json_atomic(folder / f"{name}.json", row_metrics(cells))
    return folder
