"""How a claim of the paper is checked: a :class:`Check` is one number with its 95% interval, its
bootstrap p-value and what the claim expects of it; a :class:`Claim` decides its checks together.
The numbers come from the recorded cells of one recogniser, selected by what they ran
(:class:`Data`): differences in collisions per run between cells are bootstrapped over run seeds
(2000 resamples, seed 0), paired where the cells share run seeds on one maze (unpaired across
mazes: run ``r`` of one maze shares nothing meaningful with run ``r`` of another), a pooled arm
(the four substitution ways) averaged per seed first; shares of converged runs have Wilson score
intervals. The verdict rule (Holm 1979 across the checks of a claim) is :meth:`Claim.settle`; the
report states it in words (:data:`pipeline.report.claims_section.RULE`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from pipeline.report import formats
from pipeline.report.experiments import Cell, Experiment
from pipeline.report.names import PAPER_RECOGNISER, method_name, recogniser_of
from pipeline.report.paper_numbers import paper_for
from pipeline.report.pooling import same_seeds
from pipeline.stats import (
    bootstrap_p,
    difference_draws,
    holm,
    holm_adjusted,
    percentile_ci,
    wilson_ci,
)

#: A check or claim of two substitution ways that cannot differ in any recorded run
#: (:func:`pipeline.report.substitutions.cannot_differ`).
NOT_TESTABLE = "not testable with this recogniser"
VERDICTS = ("holds", "does not hold", "not resolved", NOT_TESTABLE, "not checked")


#: The family-wise level of a claim's checks (Holm's correction).
LEVEL = 0.05


@dataclass
class Check:
    """One number behind a verdict: ``estimate`` [``low``, ``high``] and what the claim expects
    of it: ``>`` (above zero), ``≈`` (within ``±margin``), ``all`` / ``none`` (a share of 1 / 0).
    With bootstrap ``draws`` (:func:`from_draws`), Holm's rule (:meth:`Claim.settle`) sets the
    level of the interval that decides (``1 - threshold``); without, the 95% interval decides."""

    what: str
    estimate: float
    low: float
    high: float
    expect: str
    unit: str
    basis: str  # what the interval is over
    paper: str = ""  # the paper's numbers for it, as printed
    margin: float = 0.0  # ``≈``: the largest difference that counts as comparable
    p: float | None = None
    draws: np.ndarray | None = field(default=None, repr=False)  # bootstrap draws of the number
    threshold: float = LEVEL
    stopped: bool = False  # Holm's step-down stopped before this check
    recognised: bool = True  # whether a recogniser ran in its cells
    untestable: str = ""  # why the records cannot tell it (its sides cannot differ)

    def judge(self, low: float, high: float) -> str:
        """The verdict of an interval ``[low, high]``."""
        if self.expect == ">":
            return formats.verdict(low, high)
        inside = -self.margin <= low and high <= self.margin
        outside = low > self.margin or high < -self.margin
        return "holds" if inside else "does not hold" if outside else "not resolved"

    @property
    def verdict(self) -> str:
        if self.untestable:
            return NOT_TESTABLE
        if self.expect in (">", "≈"):
            if self.draws is None:
                return self.judge(self.low, self.high)
            if self.stopped:
                return "not resolved"
            return self.judge(*percentile_ci(self.draws, 1 - self.threshold))
        return (
            "holds" if self.estimate == (1.0 if self.expect == "all" else 0.0) else "does not hold"
        )

    def text(self) -> str:
        scale, digits = (100, 1) if self.unit.startswith(("percentage", "share")) else (1, 2)
        numbers = formats.estimate(self.estimate, self.low, self.high, digits, scale)
        paper = f"; paper: {self.paper}" if self.paper else ""
        margin = f"; comparable within ±{self.margin:.2f}" if self.expect == "≈" else ""
        if self.untestable:
            return f"{self.what}: {numbers} {self.unit}: {self.verdict}: {self.untestable}"
        holm_ = (
            ""
            if self.p is None
            else f"; p = {self.p:.2g}, Holm threshold {self.threshold:.2g}"
            + (", not reached: an earlier check undecided" if self.stopped else "")
        )
        return f"{self.what}: {numbers} {self.unit} ({self.basis}{margin}{holm_}){paper}: {self.verdict}"


def from_draws(what: str, estimate: float, draws, unit: str, basis: str, **kw) -> Check:
    """A check from bootstrap ``draws`` of its number: the 95% percentile interval, and the p-value
    that orders the checks of a claim for Holm's rule (``expect`` ``>``: of zero; ``≈``: the
    smaller of those of lying within and outside ``±margin``), each tail share counted as
    ``(k + 1) / (B + 1)``."""
    d = np.asarray(draws, dtype=float)
    expect, margin = kw.pop("expect", ">"), kw.get("margin", 0.0)

    def share(k) -> float:
        return 2 * (int(k) + 1) / (d.size + 1)

    if expect == "≈":
        inside = max(share(np.sum(d <= -margin)), share(np.sum(d >= margin)))
        outside = min(share(np.sum(d <= margin)), share(np.sum(d >= -margin)))
        p = min(inside, outside)
    else:
        p = bootstrap_p(d)
    low, high = percentile_ci(d)
    return Check(what, estimate, low, high, expect, unit, basis, p=min(p, 1.0), draws=d, **kw)


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

    def settle(self) -> Claim:
        """Holm's step-down over the checks with bootstrap draws: by p-value, the ``i``-th (from
        0) of ``m`` is judged by its interval at level ``1 - LEVEL / (m - i)``
        (:func:`~pipeline.stats.holm`'s thresholds); after the first undecided one, the
        rest are not resolved. Checks that are not testable take no part."""
        tested = [c for c in self.checks if c.draws is not None and not c.untestable]
        going = True
        for check, threshold in zip(tested, holm([c.p for c in tested], LEVEL)[0]):
            check.threshold, check.stopped = threshold, False
        for check in sorted(tested, key=lambda c: c.threshold):
            check.stopped = not going
            going = going and check.verdict != "not resolved"
        return self

    @property
    def p(self) -> float | None:
        """The p-value that decides the claim (None: no testable check has one): its checks'
        Holm-adjusted p-values (:func:`~pipeline.stats.holm_adjusted`, the smallest family level at
        which :meth:`settle` decides each), the smallest of those that do not hold where one does
        not, else the largest (every check must hold)."""
        tested = [c for c in self.settle().checks if c.p is not None and not c.untestable]
        if not tested:
            return None
        adjusted = holm_adjusted([c.p for c in tested])
        failing = [a for a, c in zip(adjusted, tested) if c.verdict == "does not hold"]
        return min(failing) if failing else max(adjusted)

    @property
    def recognised(self) -> bool:
        """Whether a recogniser ran in its cells (a claim not checked: assumed so)."""
        return not self.checks or any(c.recognised for c in self.checks)

    @property
    def verdict(self) -> str:
        """Holds when all its testable checks hold, does not hold when one does not; not testable
        when none of its checks is."""
        every = [c.verdict for c in self.settle().checks]
        verdicts = [v for v in every if v != NOT_TESTABLE]
        if self.missing or not every:
            return "not checked"
        return formats.combined(verdicts) if verdicts else NOT_TESTABLE


def across_claims(claims: list[Claim], level: float = LEVEL) -> list[str]:
    """Each claim's verdict with Holm's correction across ``claims`` (the family: those with a
    deciding p-value, :attr:`Claim.p`): in the order of those p-values, the ``i``-th (from 0) of
    ``m`` keeps its verdict when its p-value is at most ``level / (m - i)`` and every earlier one's
    was, else is not resolved. Claims outside the family (not checked, not testable, decided by
    observations) keep theirs."""
    family = [k for k, c in enumerate(claims) if c.p is not None]
    kept = holm([claims[k].p for k in family], level)[1]
    out = [c.verdict for c in claims]
    for k, ok in zip(family, kept):
        if not ok:
            out[k] = "not resolved"
    return out


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
    """Cells of the recorded experiments of one recogniser (:func:`~pipeline.report.names.
    recogniser_of`; the cells of methods without one belong to every recogniser), selected by what
    they ran."""

    def __init__(self, experiments: list[Experiment], recogniser: str | None = PAPER_RECOGNISER):
        self.experiments = experiments
        self.by_name = {e.name: e for e in experiments}
        self.recogniser = recogniser

    def mine(self, cell: Cell) -> bool:
        return recogniser_of(cell.info, cell.config) in (None, self.recogniser)

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
            and self.mine(c)
        ]
        if not found:
            where = ", ".join(str(x) for x in (method, maze, support) if x)
            raise Missing(f"no records of {experiment} ({where}) with {self.recogniser}")
        return found

    def all(self, experiment: str) -> list[Cell]:
        """The experiment's cells of this recogniser (Missing when it has none of them)."""
        exp = self.by_name.get(experiment)
        cells = [cell for _, cells in exp.rows() for cell in cells] if exp else []
        if not any(recogniser_of(c.info, c.config) == self.recogniser for c in cells):
            raise Missing(f"no records of {experiment} with {self.recogniser}")
        return [c for c in cells if self.mine(c)]

    def arm(self, *args, first: int = 0, **kw) -> Arm:
        """The cells' collisions per run (from run index ``first`` on)."""
        cells = self.cells(*args, **kw)
        values = pd.concat([c.collisions_by_run() for c in cells], axis=1).mean(axis=1)
        return Arm(values[values.index >= first], cells)

    def paper(self, arm: Arm) -> str:
        """The paper's number for exactly these cells' setting (not one that pools more ways)."""
        found = self.paper_value(arm)
        return found.value if found and not found.pools else ""

    def paper_value(self, arm: Arm):
        one_maze = len({c.maze for c in arm.cells}) == 1
        return paper_for(arm.cells, self.experiments) if one_maze else None

    def paper_words(self, arm: Arm) -> str:
        """``Few-shot + DSS 7.145`` or why the paper prints no number for the arm."""
        found = self.paper_value(arm)
        if found is None:
            return f"{arm.name}: no number printed"
        if found.pools:
            return f"{arm.name}: none for this way alone ({found.value} has {found.pools})"
        return f"{arm.name} {found.value}"


def recognised(cells: list[Cell]) -> bool:
    return any(recogniser_of(c.info, c.config) is not None for c in cells)


def fewer(data: Data, what: str, more: Arm, less: Arm, **expect) -> Check:
    """``less`` collides less than ``more``: the difference ``more - less`` per run, paired over
    run seeds only where all cells share them on one maze (``expect``: ``expect="≈"`` and
    ``margin``, :func:`from_draws`)."""
    cells = more.cells + less.cells
    paired = (
        same_seeds(cells)
        and more.values.index.equals(less.values.index)
        and len({c.maze for c in cells}) == 1
    )
    a, b = more.values.to_numpy(), less.values.to_numpy()
    papers = [data.paper(more), data.paper(less)]
    paper = (
        f"{papers[0]} vs {papers[1]}"
        if all(papers)
        else "; ".join(data.paper_words(x) for x in (more, less))
        if any(papers)
        else ""
    )
    basis = (
        f"{len(a)} run seeds, paired"
        if paired
        else f"{len(a)} and {len(b)} runs, unpaired"
        + (" (different mazes)" if len({c.maze for c in cells}) > 1 else "")
    )
    draws = difference_draws(a, b, paired=paired)
    return from_draws(
        what,
        float(a.mean() - b.mean()),
        draws,
        "collisions per run",
        basis,
        paper=paper,
        recognised=recognised(cells),
        **expect,
    )


def converged(what: str, cells: list[Cell], expect: str) -> Check:
    runs = [e for c in cells for e in c.converged_episode()]
    share = sum(e is not None for e in runs) / len(runs)
    return Check(
        what,
        share,
        *wilson_ci(share, len(runs)),
        expect,
        "share of runs (%)",
        f"{len(runs)} runs",
        recognised=recognised(cells),
    )


def checked(source: str, says: str, make, how: str = "", quoted: bool = True) -> Claim:
    """The claim with the checks ``make()`` returns, or "not checked" if their records are missing."""
    try:
        return Claim(source, says, make(), how=how, quoted=quoted).settle()
    except Missing as exc:
        return Claim(source, says, missing=str(exc), how=how, quoted=quoted)
