"""What is structural in the claims: substitutions counted per category and run from the records,
comparisons of substitution ways that no run lets differ marked not testable, and Holm's correction
across the claims. Small synthetic cells, seeded; no trials."""

import numpy as np
import pandas as pd
import pytest

from pipeline.report.build import Report
from pipeline.report.checks import NOT_TESTABLE, Check, Claim, across_claims, from_draws
from pipeline.report.claims_section import claims_by_recogniser, claims_section
from pipeline.report.experiments import Cell, Experiment
from pipeline.report.spec import ReportSpec
from pipeline.report.substitutions import (
    cannot_differ,
    count_summary,
    substitution_counts,
    substitution_table,
    support_differs,
)
from pipeline.rl.methods import get_method
from pipeline.stats import holm, holm_adjusted

RUNS = 20
COLUMNS = ["run", "episode", "step", "picture", "category", "position"]
TARGET = "pipeline.fewshot.recogniser.RelationRecogniser.from_files"


def substitutions(counts: np.ndarray) -> pd.DataFrame:
    """A records' substitution frame with ``counts[r, c]`` substitutions of category ``c`` in run
    ``r``, after each run's starting row of -1s."""
    rows = [(r, 0, 0, -1, -1, -1) for r in range(len(counts))]
    for r, c in zip(*np.nonzero(counts)):
        rows += [(r, e, c, 8 * c + e % 8, c, e % 5) for e in range(counts[r, c])]
    return pd.DataFrame(rows, columns=COLUMNS)


def cell(name, method, mean, recogniser=None, way=1, counts=None, experiment="fig9"):
    """A cell of ``RUNS`` runs colliding ``mean`` + the run seed's noise (shared by every cell)."""
    shared = np.random.default_rng(7).normal(0, 2, RUNS)
    episodes = pd.DataFrame(
        {
            "run": np.arange(RUNS),
            "episode": 0,
            "collisions": np.maximum(mean + shared, 0),
            "greedy_optimal": True,
        }
    )
    info = {
        "method": get_method(method).as_dict(),
        "maze": "5x5",
        "substitution": way,
        "support": "restore",
        "recogniser": {"kind": recogniser} if recogniser else None,
    }
    subs = None if counts is None else substitutions(counts)
    config = {"seed": 0, "recogniser": {"_target_": TARGET}}
    return Cell(experiment, name, info, [], {}, episodes, pd.DataFrame(), subs, config=config)


def experiment(name, cells):
    by = {c.name: c for c in cells}
    return Experiment(name, name, ReportSpec(), by, sorted(by))


def few(most: int = 4) -> np.ndarray:
    """Substitutions per run and category, at most ``most`` (in run 3, category 2)."""
    counts = np.random.default_rng(1).integers(0, 3, (RUNS, 5))
    counts[3, 2] = most
    return counts


def recorded(most: int = 4):
    """Figures 8 and 9 with the Relation Network and the paper's Tables 1-2 recogniser: ways 3
    and 4 alike (as the records are below K substitutions), the paper's recognition alike in all
    four ways."""
    fig8, fig9 = [cell("qlearning", "qlearning", 170, experiment="fig8")], []
    for kind, suffix, ways in (
        ("relation_net", "", {1: 6.0, 2: 6.2, 3: 6.1, 4: 6.1}),
        ("paper_tables", "_paper", dict.fromkeys((1, 2, 3, 4), 6.5)),
    ):
        fig8.append(cell(f"fewshot{suffix}", "fewshot", 9, kind, experiment="fig8"))
        fig9 += [
            cell(f"way{w}{suffix}", "fewshot_dss", m, kind, w, few(most)) for w, m in ways.items()
        ]
    return [experiment("fig8", fig8), experiment("fig9", fig9)]


def test_substitutions_are_counted_per_run_and_category():
    counts = few()
    got = substitution_counts(substitutions(counts), range(RUNS))
    np.testing.assert_array_equal(got, counts)  # the starting rows (-1s) are not substitutions
    assert count_summary(got) == {"runs": RUNS, "mean": counts.mean(), "max": 4, "past_k": 0.0}
    past = few(7)
    past[5, 0] = 6
    assert count_summary(past)["past_k"] == pytest.approx(2 / RUNS)
    table = substitution_table(recorded())
    assert len(table) == 8 and set(table["way"]) == {1, 2, 3, 4}
    assert (table["max"] == 4).all() and (table["past_k"] == 0).all()
    assert (table["support_differs"] == 0).all()  # the same substitutions at the same positions


def test_support_sets_compared_as_the_recogniser_reads_them():
    def frame(positions, pictures=(1, 2)):
        rows = [(0, 0, 0, -1, -1, -1)] + [
            (0, e + 1, 3, pic, 0, pos) for e, (pic, pos) in enumerate(zip(pictures, positions))
        ]
        return pd.DataFrame(rows, columns=COLUMNS)

    way1, way3, way2 = frame([0, 1]), frame([3, 0]), frame([4, 4])  # way 2 re-hits position 4
    assert support_differs(way1, way3, [0], "positions").tolist() == [True]
    assert support_differs(way1, way3, [0], "substituted").tolist() == [False]
    assert support_differs(way1, way2, [0], "substituted").tolist() == [True]
    assert support_differs(way1, way2, [0], "nothing").tolist() == [False]
    assert support_differs(way1, frame([0, 1], (1, 3)), [0, 1], "substituted").tolist() == [
        True,  # another picture came in
        False,  # run 1: no substitutions in either
    ]


def test_ways_that_no_run_lets_differ_are_not_testable():
    cells = recorded()[1].cells
    pair = [cells["way3"], cells["way4"]]
    why = cannot_differ(pair, 3, 4, "relation_net")
    assert why.startswith("ways 3 and 4 place the same pictures at the same positions")
    assert "none of the 20 runs of each does one take more than 4" in why
    assert cannot_differ(pair, 1, 2, "relation_net") == ""
    assert "always hold the same substituted pictures" in cannot_differ(pair, 1, 4, "paper_tables")
    assert cannot_differ(pair, 2, 4, "paper_tables") == ""  # way 2 can differ from the 2nd
    past = [cell("w3", "fewshot_dss", 6, "relation_net", 3, few(6))]
    assert cannot_differ(past, 3, 4, "relation_net") == ""  # a 6th substitution: they can differ
    unknown = [cell("w3", "fewshot_dss", 6, "relation_net", 3)]
    assert cannot_differ(unknown, 3, 4, "relation_net") == ""  # no substitutions recorded


def test_claims_of_the_ways_with_each_recogniser():
    by = claims_by_recogniser(recorded(), [])
    comparable = {k: next(c for c in by[k] if "ways are comparable" in c.says) for k in by}
    untestable = {
        k: [x.what for x in c.checks if x.verdict == NOT_TESTABLE] for k, c in comparable.items()
    }
    assert untestable == {
        "relation_net": ["way 3 − way 4"],
        "paper_tables": ["way 1 − way 3", "way 1 − way 4", "way 3 − way 4"],
    }
    main = comparable["relation_net"]
    assert main.verdict == "holds"  # decided by the five testable checks, Holm over five
    held = sorted(x.threshold for x in main.checks if x.verdict != NOT_TESTABLE)
    assert held == pytest.approx([0.05 / 5, 0.05 / 4, 0.05 / 3, 0.05 / 2, 0.05])
    reduce = next(c for c in by["paper_tables"] if "further reduce" in c.says)
    assert NOT_TESTABLE not in [x.verdict for x in reduce.checks]  # static vs a way can differ
    alone = Claim("s", "t", [Check("x", 0, 0, 0, "≈", "u", "b", untestable="same")])
    assert alone.verdict == NOT_TESTABLE and alone.p is None


def test_holm_across_claims():
    p = [0.01, 0.04, 0.03, 0.001]
    adjusted = holm_adjusted(p)
    assert adjusted == pytest.approx([0.03, 0.06, 0.06, 0.004])
    assert [a <= 0.05 for a in adjusted] == holm(p)[1]
    draws = np.r_[np.full(19, -0.1), np.full(1981, 1.0)]  # p = 40 / 2001, holds at 5%

    def claim(n, sign=1.0):
        return Claim("s", "t", [from_draws(str(i), sign, sign * draws, "u", "b") for i in range(n)])

    one, fails = claim(1), claim(1, -1.0)
    assert one.p == pytest.approx(40 / 2001) and fails.verdict == "does not hold"
    converged = Claim("s", "t", [Check("c", 1.0, 0.9, 1.0, "all", "share", "runs")])
    assert converged.p is None  # an observation: outside the family
    # each alone decided at 5%, together (three claims with p = 0.02) not: Holm across them
    assert across_claims([one]) == ["holds"]
    assert across_claims([one, fails, claim(1), converged]) == [
        "not resolved",
        "not resolved",
        "not resolved",
        "holds",
    ]
    assert across_claims([one, Claim("s", "t", missing="none")]) == ["holds", "not checked"]


def test_the_section_shows_counts_and_holm_across_claims(tmp_path):
    rep = Report(tmp_path)
    claims_section(rep, recorded(), [tmp_path / "no_study"])
    text = "\n".join(rep.sections)
    assert "**Where the substitution ways can differ.**" in text
    assert "| fig9         | 5x5    | Relation Network   | 1 / 2 / 3 / 4 |" in text
    assert "with Holm across claims" in text and "0.05 / (M − i)" in text
    assert "holds (1 of 6 checks not testable)" in text
    assert "holds (3 of 6 checks not testable)" in text  # the paper's recognition
    rows = pd.read_csv(tmp_path / "tables" / "claims.csv")
    assert {"claim p", "claim verdict, Holm across claims"} <= set(rows.columns)
    untestable = rows[rows["check verdict"] == NOT_TESTABLE]
    assert untestable["holm threshold"].isna().all() and len(untestable) == 4
    counts = pd.read_csv(tmp_path / "tables" / "substitutions.csv")
    assert list(counts.columns) == [
        "experiment",
        "maze",
        "recogniser",
        "way",
        "runs",
        "mean",
        "max",
        "past_k",
        "compared_with_way",
        "support_differs",
    ]
