"""The report's headline: the few numbers ``dvc exp show`` and ``dvc metrics show`` print.

``reports/headline.json`` is the one metrics file ``dvc.yaml`` declares, so the table of
experiments fits one screen. Its keys (DVC joins nested keys with dots):

- ``accuracy.<model>``: each meta-trained model's quoted test accuracy (its ``metrics.json``);
- ``claims_held``: how many of the paper's claims hold with the report's main recogniser (its
  first claims table: the Relation Network), by the claims section's verdicts
  (:mod:`pipeline.report.claims_section`; the other recognisers' counts are in its tables);
- ``<experiment>.<cell>``: the mean collisions per run of each cell the experiment's
  ``report.headline`` names (:class:`pipeline.report.spec.ReportSpec`), in that order.

The detail is not declared: ``dvc metrics show datasets/metrics/<experiment>`` (docs/dvc.md).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

#: The claims section's verdict of a claim that holds.
HOLDS = "holds"
#: The headline's own keys; an experiment of one of these names is keyed ``experiment_<name>``.
OWN_KEYS = ("accuracy", "claims_held")


def model_accuracies(metrics_files: dict[str, Path]) -> dict[str, float]:
    """Each model's quoted test accuracy, by model name; a model without a metrics file is left
    out (the recogniser section says which file is missing)."""
    out = {}
    for model, path in metrics_files.items():
        if path.is_file():
            out[model] = round(float(json.loads(path.read_text())["accuracy"]), 5)
    return out


def claims_held(claims: dict[str, list]) -> int:
    """How many claims hold with the main recogniser (``claims``: the claims section's claims by
    recogniser, the main one first)."""
    main = next(iter(claims.values()))
    return sum(c.verdict == HOLDS for c in main)


def cell_collisions(experiments: list) -> dict[str, dict[str, float]]:
    """Mean collisions per run of every recorded cell an experiment's ``report.headline`` names,
    by experiment then cell."""
    out = {}
    for exp in experiments:
        named = [c for c in exp.spec.headline if c in exp.cells]
        if named:
            key = f"experiment_{exp.folder}" if exp.folder in OWN_KEYS else exp.folder
            out[key] = {
                c: round(float(np.mean(exp.cells[c].collisions_per_run())), 3) for c in named
            }
    return out


def headline(claims: dict[str, list], metrics_files: dict[str, Path], experiments: list) -> dict:
    """The content of ``headline.json`` (module docstring)."""
    out: dict = {}
    accuracies = model_accuracies(metrics_files)
    if accuracies:
        out["accuracy"] = accuracies
    if claims:
        out["claims_held"] = claims_held(claims)
    return out | cell_collisions(experiments)
