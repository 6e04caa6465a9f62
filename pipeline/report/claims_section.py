"""The report's "Claims of the paper against our data" section and ``tables/claims.csv`` (one row
per recogniser and check): the claims of :mod:`pipeline.report.claims`, checked with each recogniser
that ran in the claims' experiments (grouped by :func:`~pipeline.report.names.recogniser_of`) or
has an accuracy study, one table per recogniser, the paper's first with the column "with the
paper's recognition" (the verdicts on the cells of :data:`PAPER_RECOGNITION`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from pipeline.report.checks import NOT_TESTABLE, VERDICTS, Check, Claim, Data, across_claims
from pipeline.report.claims import accuracy_claims, rl_claims
from pipeline.report.experiments import Experiment
from pipeline.report.names import (
    PAPER_RECOGNISER,
    recogniser_group,
    recogniser_name,
    recogniser_of,
)
from pipeline.report.study import read_summary
from pipeline.report.substitutions import substitution_part

#: The recogniser whose verdicts fill the column "with the paper's recognition": the paper's
#: Tables 1-2 as a recogniser (``conf/recogniser/paper_tables.yaml``).
PAPER_RECOGNITION = "paper_tables"

#: The experiments the claims read (their cells' recognisers get a claims table each).
CLAIM_EXPERIMENTS = ("fig8", "fig9", "fig10", "table3")


def study_recogniser(folder: Path) -> str | None:
    """The recogniser of an accuracy study (its ``summary.json``'s config), None without one."""
    summary = read_summary(folder)
    if summary is None:
        return None
    return recogniser_group(str(summary["config"]["recogniser"].get("_target_")))


def claims_by_recogniser(
    experiments: list[Experiment], accuracy_dirs: list[Path]
) -> dict[str, list[Claim]]:
    """Every claim checked with each recogniser that ran in the claims' experiments or has an
    accuracy study, the paper's (the Relation Network) first."""
    studies: dict[str, Path] = {}
    for folder in accuracy_dirs:
        if (kind := study_recogniser(folder)) is not None:
            studies.setdefault(kind, folder)
    found = {
        recogniser_of(c.info, c.config)
        for e in experiments
        if e.name in CLAIM_EXPERIMENTS
        for c in e.cells.values()
    } - {None}
    kinds = sorted(found | set(studies), key=lambda k: (k != PAPER_RECOGNISER, k))
    return {
        k: accuracy_claims(studies.get(k)) + rl_claims(Data(experiments, k))
        for k in kinds or [PAPER_RECOGNISER]
    }


def verdict_words(claim: Claim, verdict: str | None = None) -> str:
    """The claim's verdict (or ``verdict``), and how many of its checks are not testable where
    some, not all, are."""
    verdict = verdict or claim.verdict
    n = sum(c.verdict == NOT_TESTABLE for c in claim.checks)
    if n and verdict != NOT_TESTABLE:
        return f"{verdict} ({n} of {len(claim.checks)} checks not testable)"
    return verdict


def with_recogniser(claim: Claim, theirs: Claim | None) -> str:
    """The verdict of ``claim`` with another recogniser's cells: "not run" without them."""
    if not claim.recognised:
        return "no recogniser in it"
    if theirs is None or theirs.verdict == "not checked":
        return "not run"
    return verdict_words(theirs)


def shown_claims(claims: list[Claim], first: bool) -> list[int]:
    """The claims (numbered from 1) of a recogniser's table: all in the first table, elsewhere
    those its cells take part in."""
    return [
        i for i, c in enumerate(claims, 1) if first or (c.verdict != "not checked" and c.recognised)
    ]


def family_verdicts(claims: list[Claim], first: bool) -> dict[int, str]:
    """The verdicts of a recogniser's table with Holm's correction across its claims
    (:func:`~pipeline.report.checks.across_claims`; the family: the claims it shows)."""
    shown = shown_claims(claims, first)
    return dict(zip(shown, across_claims([claims[i - 1] for i in shown])))


#: How the claims' column with Holm across claims is decided (after :data:`RULE`).
ACROSS = (
    "**With Holm's correction across claims.** The column *with Holm across claims* decides the "
    "claims of a table as one family: every claim of the table whose verdict rests on bootstrap "
    "p-values (not the claims decided by observed shares of converged runs, not checked or not "
    "testable, which keep their verdict). A claim's p-value is the largest of its checks' "
    "Holm-adjusted p-values (the smallest level at which the rule above decides all of them; where "
    "a check does not hold, the smallest adjusted p-value of such a check), and the claims are "
    "taken in the order of these p-values: the i-th of the table's M claims (i from 0) keeps its "
    "verdict when its p-value is at most 0.05 / (M − i) and every earlier one did, and is not "
    "resolved otherwise. The bootstrap's 2000 resamples give no p-value below 2 / 2001 ≈ 0.001, so "
    "a claim of many checks can be left unresolved by this correction alone."
)


RULE = (
    "A claim is checked by one or more numbers, each with a 95% interval and a bootstrap p-value "
    '(two-sided, of zero; for "comparable", of the margin). **Verdict rule, with Holm\'s correction '
    "across the checks of a claim** (family level 5%): the checks are taken in the order of their "
    "p-values; the i-th of a claim's m checks (i from 0) is judged by its percentile interval at level "
    "1 − 0.05 / (m − i), and once one is undecided the rest are too. A judged check **holds** when "
    'that interval lies on the claimed side of zero ("comparable": within the margin) and **does '
    "not hold** when on the other side (outside the margin); otherwise it is **not resolved**. With "
    "one check this is the 95% interval shown. Shares of converged runs are observations, decided as "
    "observed. A claim holds when all its checks hold, does not hold when one does not, and is not "
    "resolved otherwise; each check names its p-value and Holm threshold. Differences in collisions "
    "are bootstrapped over run seeds (2000 resamples, seed 0), paired where the cells share run seeds "
    "on one maze and unpaired across mazes; a pooled row (the four substitution ways) is averaged per "
    "seed first; the runs of a carried-over support set are one robot's consecutive experiments, "
    "treated as if independent. Accuracies are bootstrapped over the accuracy study's random draws "
    "(2000 resamples, seed 0; `draws.csv`), within each substituted category, paired where the same "
    'draws are compared, for the 40 query pictures and the trained model as they are. "paper: a vs '
    "b\" gives the paper's numbers for the two sides of a difference; where it prints none for a "
    "side, the check says so. Each recogniser has its own table; the column *with the paper's "
    "recognition* gives the verdict of the same checks on the cells recorded with the "
    f"`{PAPER_RECOGNITION}` recogniser (the paper's Tables 1-2 as a recogniser: which claims are about "
    'the method and which turn on how well the recogniser sees), "not run" where it has none and '
    '"no recogniser in it" where no cell of the claim recognises pictures. Data: `tables/claims.csv`.'
)


def claims_section(rep, experiments: list[Experiment], accuracy_dirs: list[Path]) -> dict:
    """Write the claims section into ``rep`` and ``tables/claims.csv``: one table per recogniser
    (:func:`claims_by_recogniser`); returns the claims by recogniser."""
    by = claims_by_recogniser(experiments, accuracy_dirs)
    main = next(iter(by))
    theirs = by.get(PAPER_RECOGNITION) if main != PAPER_RECOGNITION else None
    column = {
        i: with_recogniser(c, theirs[i - 1] if theirs else None) for i, c in enumerate(by[main], 1)
    }
    across = {kind: family_verdicts(claims, kind == main) for kind, claims in by.items()}
    rows = [
        {
            "recogniser": kind,
            "claim": i,
            "source": c.source,
            "claim text": c.text(),
            "check": k.what,
            "estimate": k.estimate,
            "ci_low": k.low,
            "ci_high": k.high,
            "unit": k.unit,
            "interval over": k.basis,
            "p": k.p,
            "holm threshold": k.threshold if k.p is not None and not k.untestable else None,
            "paper": k.paper,
            "check verdict": k.verdict,
            "claim verdict": c.verdict,
            "claim p": c.p,
            "claim verdict, Holm across claims": across[kind].get(i, ""),
            "with the paper's recognition": column[i] if kind == main else "",
        }
        for kind, claims in by.items()
        for i, c in enumerate(claims, 1)
        for k in (c.checks or [Check(c.missing, *[np.nan] * 3, "", "", "")])
    ]
    rep.data("claims", pd.DataFrame(rows), float_format="%.6g")
    rep.add(f"## Claims of the paper against our data\n\n{RULE}\n\n{ACROSS}\n")
    substitution_part(rep, experiments)
    for kind, claims in by.items():
        rep.add(
            recogniser_block(kind, claims, column if kind == main else None, by[main], across[kind])
        )
    return by


def recogniser_block(
    kind: str, claims: list[Claim], column: dict | None, first: list, across: dict[int, str]
) -> str:
    """One recogniser's claims table and checks; beside the first table, only the claims its
    cells take part in; ``across``: their verdicts with Holm across claims."""
    name = recogniser_name(kind)
    name = name if name != kind else f"`{kind}` recogniser"
    shown = shown_claims(claims, column is not None)
    table = pd.DataFrame(
        [
            {
                "#": i,
                "where": claims[i - 1].source,
                "the paper": claims[i - 1].text(),
                "in our data": verdict_words(claims[i - 1]),
                "with Holm across claims": verdict_words(claims[i - 1], across[i]),
                **({"with the paper's recognition": column[i]} if column else {}),
            }
            for i in shown
        ]
    )
    tally = [sum(claims[i - 1].verdict == v for i in shown) for v in VERDICTS]
    counts = ", ".join(f"{n} {v}" for n, v in zip(tally, VERDICTS) if n)
    title = f"### With the {name}" + (
        " (the paper's recogniser)" if kind == PAPER_RECOGNISER else ""
    )
    left = [i for i in range(1, len(claims) + 1) if i not in shown]
    plain = [i for i in left if not first[i - 1].recognised]
    run = [i for i in left if i not in plain]
    notes = [f"Not run with the {name}: claims {', '.join(map(str, run))}"] if run else []
    if plain:
        notes.append(f"claims {', '.join(map(str, plain))} involve no recogniser (the first table)")
    details = "\n\n".join(
        f"{i}. **{c.source}: {c.verdict}.** {c.text()}\n"
        + (
            "\n".join(f"   - {k.text()}" for k in c.checks)
            if c.checks
            else f"   - not checked: {c.missing}"
        )
        for i, c in ((i, claims[i - 1]) for i in shown)
    )
    note = f"{'; '.join(notes)}.\n\n" if notes else ""
    return f"{title}\n\n{counts or 'no claims'}.\n\n{table.to_markdown(index=False)}\n\n{note}{details}\n"
