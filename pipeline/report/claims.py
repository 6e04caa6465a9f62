"""The paper's qualitative claims, each checked against our data with one recogniser's cells (the
report's claims section: :mod:`pipeline.report.claims_section`) by numbers from the records
(:mod:`pipeline.report.checks`) or the accuracy study's draws (:class:`~pipeline.report.study.Study`).
The claims name the experiments by their recorded names (``fig8``...) and select cells by what they
ran (method, maze, way, support set, recogniser); a claim whose records are missing is "not checked".
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations, pairwise
from pathlib import Path

import numpy as np
import pandas as pd

from pipeline.report.checks import Arm, Check, Claim, Data, checked, converged, fewer, from_draws
from pipeline.report.names import method_name
from pipeline.report.study import Estimate, Study
from pipeline.report.substitutions import cannot_differ

__all__ = ["Check", "Claim", "accuracy_claims", "rl_claims"]


@dataclass(frozen=True)
class Fewer:
    """A claim that in each of ``pairs`` of methods (config names) the first collides more than
    the second: checked on any arms of the methods, those of Figure 8, of one maze of Table 3 or of
    one generated layout (:mod:`pipeline.report.generalisation`)."""

    source: str
    says: str
    pairs: tuple[tuple[str, str], ...]
    quoted: bool = True

    def checks(self, data: Data, arm, where: str = "") -> list[Check]:
        """A check per pair on the arms ``arm(method)`` gives (``where``, e.g. ``, 7x7``, ends each
        check's name)."""
        arms = [(arm(more), arm(less)) for more, less in self.pairs]
        return [fewer(data, f"{a.name} − {b.name}{where}", a, b) for a, b in arms]


#: Figure 8's claims that compare methods.
FIGURE_8 = (
    Fewer(
        "Figure 8",
        "algorithms with the safety guarantee can significantly reduce the number of collisions "
        "than the algorithm without a safety guarantee",
        (("qlearning", "shield"), ("qlearning", "ssrl"), ("qlearning", "fewshot")),
    ),
    Fewer(
        "Figure 8",
        "SSRL and few-shot reasoning (without a dynamic support set) [...] both of them have a "
        "better performance in safety exploration than Q-learning with shield",
        (("shield", "ssrl"), ("shield", "fewshot")),
    ),
    Fewer(
        "Figure 8",
        "the performance of SSRL is slightly better than few-shot reasoning",
        (("fewshot", "ssrl"),),
    ),
)
#: Table 3's claim against constrained RL.
FEWER_THAN_CONSTRAINED = Fewer(
    "Table 3",
    "our method, no matter with or without the dynamic support set, has fewer collisions than "
    "constrained RL methods",
    (("constrained", "fewshot"), ("constrained", "fewshot_dss")),
)
#: Table 3's rows, most collisions first: the order its numbers show on every maze.
TABLE3_ORDER = tuple(pairwise(("sarsa", "constrained", "fewshot", "fewshot_dss")))
#: The dynamic support set's gain, as Table 3 shows it.
DSS_REDUCES = (("fewshot", "fewshot_dss"),)
#: What Table 3 shows without the paper saying it in words (our reading of the table).
TABLE3_READINGS = (
    Fewer(
        "Table 3",
        "collisions fall in the order of its rows on every maze: Sarsa, constrained RL, "
        "our method without, with the dynamic support set",
        TABLE3_ORDER,
        quoted=False,
    ),
    Fewer(
        "Table 3",
        "the dynamic support set reduces collisions on every maze",
        DSS_REDUCES,
        quoted=False,
    ),
)


def rl_claims(data: Data) -> list[Claim]:
    """Section 4.2.2: Figures 7-10 and Table 3."""
    mazes = ("5x5", "7x7", "11x11")

    def fig8(method: str) -> Arm:
        return data.arm("fig8", method)

    def t3(method: str, maze: str) -> Arm:
        return data.arm("table3", method, maze)

    def way(w: int) -> Arm:
        return data.arm("fig9", "fewshot_dss", ways=[w])

    def pair(more: Arm, less: Arm, maze: str) -> Check:
        return fewer(data, f"{more.name} − {less.name}, {maze}", more, less)

    def on_fig8(claim: Fewer) -> Claim:
        return checked(claim.source, claim.says, lambda: claim.checks(data, fig8))

    def on_every_maze(claim: Fewer) -> Claim:
        def make() -> list[Check]:
            return [c for m in mazes for c in claim.checks(data, lambda k, m=m: t3(k, m), f", {m}")]

        return checked(claim.source, claim.says, make, quoted=claim.quoted)

    def gains() -> list[Check]:
        arms = {m: (t3("fewshot", m), t3("fewshot_dss", m)) for m in mazes}
        papers = {m: [data.paper(a), data.paper(b)] for m, (a, b) in arms.items()}
        out = []
        for small, large in pairwise(mazes):
            check = fewer(
                data,
                f"DSS gain on {large} − on {small}",
                arms[large][0] - arms[large][1],
                arms[small][0] - arms[small][1],
            )
            try:  # the paper's gains, from its numbers of the two rows
                check.paper = " vs ".join(
                    f"{float(papers[m][0]) - float(papers[m][1]):.4g}" for m in (large, small)
                )
            except ValueError:
                check.paper = ""
            out.append(check)
        return out

    def between_ways(check: Check, a: int, b: int, cells: list) -> Check:
        """``check`` of ways ``a`` and ``b`` (0: static), not testable where no run lets them differ."""
        check.untestable = cannot_differ(cells, a, b, data.recogniser)
        return check

    def comparable() -> list[Check]:
        """Every pairwise difference within ±20% of the ways' mean collisions (the margin of
        bioequivalence studies, 80-125%, taken as ±20%)."""
        ways = {w: way(w) for w in (1, 2, 3, 4)}
        margin = 0.2 * float(np.mean([arm.values.mean() for arm in ways.values()]))
        return [
            between_ways(
                fewer(data, f"way {a} − way {b}", ways[a], ways[b], expect="≈", margin=margin),
                a,
                b,
                ways[a].cells + ways[b].cells,
            )
            for a, b in combinations(ways, 2)
        ]

    def reduce() -> list[Check]:
        static = fig8("fewshot")
        return [
            between_ways(pair(static, way(w), f"way {w}"), 0, w, way(w).cells) for w in (1, 2, 3, 4)
        ]

    def long_term() -> list[Check]:
        restore = data.arm("fig10", "fewshot_dss", support="restore", first=1)
        carry = data.arm("fig10", "fewshot_dss", support="carry", first=1)
        return [fewer(data, "restored − carried over", restore, carry)]

    return [
        checked(
            "Figure 7",
            "all the RL methods for comparison are able to find it [the optimal path] within 500 episodes",
            lambda: [
                converged(f"{method_name(c.info['method'])}: converged runs", [c], "all")
                for c in data.all("fig8")
            ],
            "every run of Figure 8's methods converges: its greedy path is optimal from some episode on",
        ),
        *(on_fig8(claim) for claim in FIGURE_8),
        checked(
            "Figure 9",
            "all the different substitution ways are comparable",
            comparable,
            "every difference between two ways within ±20% of the ways' mean collisions",
        ),
        checked(
            "Figure 9",
            "[all the different substitution ways] can further reduce the collision number than "
            "few-shot reasoning with no substitution",
            reduce,
        ),
        checked(
            "Figure 10",
            "the collision number can be reduced to a very low level if we do not restore the "
            "support set to the original set in the following experiments",
            long_term,
            "collisions per experiment after the first, restoring against carrying the support set over",
        ),
        checked(
            "Table 3",
            "in our 5 * 5 maze experiment, Sarsa has more collisions than Q-learning",
            lambda: [pair(t3("sarsa", "5x5"), fig8("qlearning"), "5x5")],
            "against Figure 8's Q-learning (Table 3 has no Q-learning row)",
        ),
        checked(
            "Table 3",
            "[Sarsa] can be found as not converged within 500 episodes in 7 * 7 and 11 * 11 environments",
            lambda: [
                converged(f"Sarsa, {m}: converged runs", data.cells("table3", "sarsa", m), "none")
                for m in ("7x7", "11x11")
            ],
        ),
        on_every_maze(FEWER_THAN_CONSTRAINED),
        *(on_every_maze(claim) for claim in TABLE3_READINGS),
        checked(
            "Table 3",
            "the gain of the dynamic support set (collisions without minus with it) grows with the maze",
            gains,
            quoted=False,
        ),
    ]


def accuracy_claims(accuracy_dir: Path | None) -> list[Claim]:
    """Section 4.2.1: Tables 1 and 2, from the accuracy study's data files (bootstrap over its
    random draws: :class:`~pipeline.report.study.Study`); None or a folder without the study:
    "not checked"."""
    gradually = (
        "the recognition accuracy increases gradually with the increase of substitution number"
    )
    claims = [
        Claim(
            "Table 1",
            "the test accuracy increases from 42.5% to 49.03%, 48.04% (no same picture) when the "
            "substituted picture number is 1",
        ),
        Claim(
            "Table 1",
            "The substituted category tends to have higher accuracy",
            how="each category's accuracy when one of its pictures is substituted, not counting that picture, "
            "against the original support set (categories below 100% there)",
        ),
        Claim("Table 2", gradually, how="the most substitutions against none"),
        Claim("Table 2", gradually, how="each further substitution"),
        Claim(
            "Table 2",
            "When it comes to the no same pic condition, the accuracy decreases a little compared to "
            "the previous result",
        ),
    ]
    if accuracy_dir is None or not (accuracy_dir / "summary.json").exists():
        for c in claims:
            c.missing = f"no accuracy study under {accuracy_dir}"
        return claims
    study = Study(accuracy_dir)
    basis = f"bootstrap over {study.draws} random draws per category"

    def rise(what: str, diff: Estimate, paper: tuple = (), basis: str = basis) -> Check:
        paper = " vs ".join(f"{100 * p:.2f}%" for p in paper) if paper and None not in paper else ""
        return from_draws(what, diff.value, diff.draws, "percentage points", basis, paper=paper)

    def table2(n: int, variant: str = "with_same") -> tuple[Estimate, float | None]:
        return study.substitutions(n, variant), study.paper(n, variant)

    top = int(study.table2.index.max())
    none, paper_none = table2(0)
    for label, variant in (("", "with_same"), (", no same picture", "no_same")):
        claims[0].checks.append(
            rise(
                f"one substitution{label} − none",
                study.mean(variant) - none,
                (study.paper(1, variant), paper_none),
            )
        )
    base = study.baseline
    for c, name in enumerate(study.names):
        before = base["correct"][c] / base["total"][c]
        row = study.cells("no_same", c).set_index("tested_category").loc[c]
        paper = (
            ""
            if pd.isna(row["paper_correct"])
            else (
                f"{int(row['paper_correct'])}/{int(row['paper_total'])} vs "
                f"{base['paper']['correct'][c]}/{base['total'][c]}"
            )
        )
        if before < 1:
            after = study.cell("no_same", c, c)
            check = rise(
                f"{name} when substituted − original support set", after - Estimate(before)
            )
            check.paper = paper
            claims[1].checks.append(check)
    claims[2].checks.append(
        rise(f"{top} substitutions − none", table2(top)[0] - none, (table2(top)[1], paper_none))
    )
    for n in range(1, top + 1):
        (now, paper_now), (before, paper_before) = table2(n), table2(n - 1)
        claims[3].checks.append(
            rise(
                f"{n} substitution{'s' if n > 1 else ''} − {n - 1}",
                now - before,
                (paper_now, paper_before),
                basis + (", independent draws" if n > 1 else ""),
            )
        )
    for n in range(1, top + 1):
        claims[4].checks.append(
            rise(
                f"{n} substitution{'s' if n > 1 else ''}: counting the substituted pictures − not",
                table2(n)[0] - table2(n, "no_same")[0],  # the same draws, resampled alike: paired
                (table2(n)[1], table2(n, "no_same")[1]),
                basis + ", paired",
            )
        )
    return [c.settle() for c in claims]
