"""How a claim of the paper is checked: a :class:`Check` is one number with its 95% interval and
what the claim expects of it; a :class:`Claim` holds when all its checks hold and does not hold
when one does not. The numbers come from the recorded cells, selected by what they ran
(:class:`Data`): differences in collisions per run between cells are bootstrapped over run seeds
(2000 resamples, seed 0), paired where the cells share run seeds, a pooled arm (the four
substitution ways) averaged per seed first; shares of converged runs have Wilson score intervals.

A check **holds** when its interval lies on the claimed side of zero, **does not hold** when it lies
on the other side, and is **not resolved** when it contains zero; "comparable" holds when the
interval lies within a stated margin (and does not hold when it lies outside)."""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import pairwise

import pandas as pd

from pipeline.report.experiments import Cell, Experiment
from pipeline.report.names import method_name
from pipeline.report.paper_numbers import paper_for
from pipeline.report.pooling import same_seeds
from pipeline.report.stats import bootstrap_difference, wilson_ci

VERDICTS = ("holds", "does not hold", "not resolved", "not checked")


@dataclass
class Check:
    """One number behind a verdict: ``estimate`` [``low``, ``high``] and what the claim expects
    of it: ``>`` (above zero), ``≈`` (within ``±margin``), ``all`` / ``none`` (a share of 1 / 0)."""

    what: str
    estimate: float
    low: float
    high: float
    expect: str
    unit: str
    basis: str  # what the interval is over
    paper: str = ""  # the paper's numbers for it, as printed
    margin: float = 0.0  # ``≈``: the largest difference that counts as comparable

    @property
    def verdict(self) -> str:
        if self.expect == ">":
            return "holds" if self.low > 0 else "does not hold" if self.high < 0 else "not resolved"
        if self.expect == "≈":
            inside = -self.margin <= self.low and self.high <= self.margin
            return (
                "holds"
                if inside
                else "does not hold"
                if self.low > self.margin or self.high < -self.margin
                else "not resolved"
            )
        return (
            "holds" if self.estimate == (1.0 if self.expect == "all" else 0.0) else "does not hold"
        )

    def text(self) -> str:
        scale, digits = (
            (100, 1)
            if self.unit.startswith("percentage") or self.unit.startswith("share")
            else (1, 2)
        )
        numbers = f"{scale * self.estimate:.{digits}f} [{scale * self.low:.{digits}f}, {scale * self.high:.{digits}f}]"
        paper = f"; paper: {self.paper}" if self.paper else ""
        margin = f"; comparable within ±{self.margin:.2f}" if self.expect == "≈" else ""
        return f"{self.what}: {numbers} {self.unit} ({self.basis}{margin}){paper}: {self.verdict}"


@dataclass
class Claim:
    source: str  # where the paper says it
    says: str  # the paper's words (quoted), or our reading of a table (``quoted=False``)
    checks: list[Check] = field(default_factory=list)
    missing: str = ""  # why it is not checked
    how: str = ""  # how the check reads the claim, where that needs saying
    quoted: bool = True

    def text(self) -> str:
        says = f'"{self.says}"' if self.quoted else f"{self.says} (our reading of the table)"
        return says + (f"; checked: {self.how}" if self.how else "")

    @property
    def verdict(self) -> str:
        verdicts = [c.verdict for c in self.checks]
        if self.missing or not verdicts:
            return "not checked"
        if "does not hold" in verdicts:
            return "does not hold"
        return "holds" if all(v == "holds" for v in verdicts) else "not resolved"


# ------------------------------------------------------------------------------------ records
class Missing(Exception):
    """The records a claim needs are not in the report."""


@dataclass
class Arm:
    """Collisions per run of some cells by run index (pooled cells averaged per run seed)."""

    values: pd.Series
    cells: list[Cell]

    def __sub__(self, other: Arm) -> Arm:
        return Arm(self.values - other.values, self.cells + other.cells)

    @property
    def name(self) -> str:
        return " / ".join(dict.fromkeys(method_name(c.info["method"]) for c in self.cells))


class Data:
    """Cells of the recorded experiments, selected by what they ran."""

    def __init__(self, experiments: list[Experiment]):
        self.experiments = experiments
        self.by_name = {e.name: e for e in experiments}

    def cells(
        self, experiment: str, method: str, maze: str | None = None, ways=None, support=None
    ) -> list[Cell]:
        exp = self.by_name.get(experiment)
        found = [
            c
            for c in (exp.cells.values() if exp else ())
            if c.method == method
            and maze in (None, c.maze)
            and (ways is None or c.info.get("substitution") in ways)
            and support in (None, c.info.get("support"))
            and (c.info.get("recogniser") or {}).get("kind") not in BESIDE_THE_PAPER
        ]
        if not found:
            where = ", ".join(str(x) for x in (method, maze, support) if x)
            raise Missing(f"no records of {experiment} ({where})")
        return found

    def all(self, experiment: str) -> list[Cell]:
        exp = self.by_name.get(experiment)
        if exp is None:
            raise Missing(f"no records of {experiment}")
        return [cell for _, cells in exp.rows() for cell in cells]

    def arm(self, *args, first: int = 0, **kw) -> Arm:
        """The cells' collisions per run (from run index ``first`` on)."""
        cells = self.cells(*args, **kw)
        values = pd.concat(
            [pd.Series(c.collisions_per_run(), index=c.runs()) for c in cells], axis=1
        ).mean(axis=1)
        return Arm(values[values.index >= first], cells)

    def paper(self, arm: Arm) -> str:
        """The paper's number for exactly these cells' setting (not one that pools more ways)."""
        found = (
            paper_for(arm.cells, self.experiments)
            if len({c.maze for c in arm.cells}) == 1
            else None
        )
        return found.value if found and not found.pools else ""


def fewer(data: Data, what: str, more: Arm, less: Arm) -> Check:
    """``less`` collides less than ``more``: the difference ``more - less`` per run."""
    paired = same_seeds(more.cells + less.cells) and more.values.index.equals(less.values.index)
    est, lo, hi = bootstrap_difference(
        more.values.to_numpy(), less.values.to_numpy(), paired=paired
    )
    papers = [data.paper(more), data.paper(less)]
    paper = f"{papers[0] or '—'} vs {papers[1] or '—'}" if any(papers) else ""
    basis = f"{len(more.values)} run seeds{', paired' if paired else ''}"
    return Check(what, est, lo, hi, ">", "collisions per run", basis, paper)


def converged(what: str, cells: list[Cell], expect: str) -> Check:
    runs = [e for c in cells for e in c.converged_episode()]
    share = sum(e is not None for e in runs) / len(runs)
    return Check(
        what, share, *wilson_ci(share, len(runs)), expect, "share of runs (%)", f"{len(runs)} runs"
    )


#: Recognisers the paper did not use: their cells (fig8's Prototypical Network cells; the cells run
#: with the paper's Tables 1-2 as the recogniser) are shown beside the paper's in the sections, not
#: pooled into the claims about its Relation Network.
BESIDE_THE_PAPER = ("protonet", "paper_tables")


#: Table 3's rows, most collisions first: the order its numbers show on every maze.
TABLE3_ORDER = ("sarsa", "constrained", "fewshot", "fewshot_dss")


def order_checks(data: Data, arm_of, order=TABLE3_ORDER, where: str = "") -> list[Check]:
    """Each method of ``order`` collides more than the next one: ``arm_of(method)`` gives its
    :class:`Arm` (``where``, e.g. ``, 7x7``, ends each check's name)."""
    arms = [arm_of(method) for method in order]
    return [
        fewer(data, f"{more.name} − {less.name}{where}", more, less)
        for more, less in pairwise(arms)
    ]


def checked(source: str, says: str, make, how: str = "", quoted: bool = True) -> Claim:
    """The claim with the checks ``make()`` returns, or "not checked" if their records are missing."""
    try:
        return Claim(source, says, make(), how=how, quoted=quoted)
    except Missing as exc:
        return Claim(source, says, missing=str(exc), how=how, quoted=quoted)
