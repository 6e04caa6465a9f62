"""The accuracy study's data files (``summary.json``, ``table1.csv``, ``table2.csv``, ``draws.csv``:
:mod:`pipeline.fewshot.study_tables`) and the intervals of Tables 1-2 (paper section 4.2.1).

Intervals: the study's random unit is a draw (which query pictures replace which support pictures;
``repeats`` independent draws per substituted category and number of substitutions), and its
``draws.csv`` keeps every draw's outcome. An accuracy is a mean over draws, and its 95% interval a
percentile bootstrap over them (:data:`RESAMPLES` resamples, seeded by :data:`SEED` and the number of
substitutions), resampling draws within each substituted category (:func:`~pipeline.stats.
stratified_means`). The two variants (with and without the substituted pictures) of one number of
substitutions resample the same draws (their difference is paired); different numbers are
independent streams. The intervals are over the draws, for the 40 query pictures and the trained
model as they are (other pictures or another training run are not resampled). The original support
set involves no draw, so its accuracy has no interval.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from pipeline.report.experiments import ReportInputError
from pipeline.stats import percentile_ci, stratified_means

#: ``table2.csv``'s column of each variant of Table 1 (``table1.csv``'s ``variant``).
VARIANTS = {"with_same": "mean_accuracy", "no_same": "mean_accuracy_no_same"}

#: Bootstrap resamples and seed of the accuracy study's intervals.
RESAMPLES, SEED = 2000, 0


@dataclass
class Estimate:
    """A number and its bootstrap draws (None: no random draw behind it, no interval)."""

    value: float
    draws: np.ndarray | None = None

    def ci(self) -> tuple[float, float]:
        return (self.value,) * 2 if self.draws is None else percentile_ci(self.draws)

    def __sub__(self, other: Estimate) -> Estimate:
        """The difference: paired where both resampled the same draws with the same indices (the
        two variants of one number of substitutions), else of independent resamples."""
        if self.draws is None and other.draws is None:
            return Estimate(self.value - other.value)
        mine = self.value if self.draws is None else self.draws
        theirs = other.value if other.draws is None else other.draws
        return Estimate(self.value - other.value, np.asarray(mine - theirs, dtype=float))


def read_summary(accuracy_dir: Path) -> dict | None:
    """The accuracy study's ``summary.json`` (None without the study)."""
    path = accuracy_dir / "summary.json"
    return json.loads(path.read_text()) if path.is_file() else None


class Study:
    """The accuracy study's data files and each accuracy's bootstrap over its draws."""

    def __init__(self, accuracy_dir: Path):
        self.summary = json.loads((accuracy_dir / "summary.json").read_text())
        self.table1 = pd.read_csv(accuracy_dir / "table1.csv")
        self.table2 = pd.read_csv(accuracy_dir / "table2.csv").set_index("substitution_number")
        path = accuracy_dir / "draws.csv"
        if not path.is_file():
            raise ReportInputError(
                f"{path}: the accuracy study's draws are missing (a study from before they were "
                "kept); run its accuracy stage again"
            )
        self.draw_rows = pd.read_csv(path)
        self.names = self.summary["class_names"]
        self.draws = int(self.summary["config"]["repeats"])
        self.baseline = self.summary["baseline"]
        self.pictures = int(sum(self.baseline["total"]))

    def cells(self, variant: str, substituted: int) -> pd.DataFrame:
        t = self.table1
        return t[
            (t["variant"] == variant) & (t["substituted_category"] == substituted)
        ].sort_values("tested_category")

    def per_draw(self, n: int, variant: str, tested: int | None = None) -> np.ndarray:
        """(substituted categories x draws): each draw's accuracy with ``n`` substitutions, on all
        query pictures or on those of category ``tested``."""
        d = self.draw_rows[self.draw_rows["substitutions"] == n]
        if tested is not None:
            d = d[d["tested_category"] == tested]
        suffix = "_no_same" if variant == "no_same" else ""
        sums = d.groupby(["substituted_category", "draw"])[
            ["correct" + suffix, "tested" + suffix]
        ].sum()
        acc = (sums["correct" + suffix] / sums["tested" + suffix]).unstack("draw")
        return acc.to_numpy(dtype=float)

    def _estimate(self, values: np.ndarray, seed: list[int]) -> Estimate:
        draws = stratified_means(values, resamples=RESAMPLES, seed=[SEED, *seed])
        return Estimate(float(values.mean()), draws)

    def row(self, variant: str, substituted: int) -> Estimate:
        """Table 1: accuracy on all pictures with one picture of ``substituted`` substituted."""
        return self._estimate(self.per_draw(1, variant)[substituted], [1, substituted])

    def cell(self, variant: str, substituted: int, tested: int) -> Estimate:
        """Table 1: accuracy on category ``tested`` with one picture of ``substituted`` substituted."""
        values = self.per_draw(1, variant, tested)[substituted]
        return self._estimate(values, [1, substituted, tested])

    def mean(self, variant: str) -> Estimate:
        """Table 1's mean over the substituted categories (Table 2's one substitution)."""
        return self.substitutions(1, variant)

    def substitutions(self, n: int, variant: str = "with_same") -> Estimate:
        """Table 2: mean accuracy with ``n`` substitutions (no draw for 0)."""
        if n == 0:
            return Estimate(float(self.table2.loc[0, VARIANTS[variant]]))
        return self._estimate(self.per_draw(n, variant), [n])

    def paper(self, n: int, variant: str = "with_same") -> float | None:
        value = self.table2.loc[n].get("paper_" + VARIANTS[variant])
        return None if value is None or pd.isna(value) else float(value)
