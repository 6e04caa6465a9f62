"""The claims per recogniser: cells are grouped by the recogniser they recorded (methods without one
belong to every group), one claims table each, the column "with the paper's recognition" from the
cells of ``paper_tables`` ("not run" without them), Holm's rule within a claim, unpaired intervals
across mazes. Synthetic cells in memory (collisions per run chosen to give known verdicts)."""

import numpy as np
import pandas as pd
import pytest

from pipeline.report.build import Report
from pipeline.report.checks import Data
from pipeline.report.claims_section import (
    PAPER_RECOGNITION,
    claims_by_recogniser,
    claims_section,
    with_recogniser,
)
from pipeline.report.experiments import Cell, Experiment
from pipeline.report.names import recogniser_of
from pipeline.report.spec import ReportSpec
from pipeline.rl.methods import get_method

RUNS = 30
TARGETS = {
    "relation_net": "pipeline.fewshot.recogniser.RelationRecogniser.from_files",
    "protonet": "pipeline.fewshot.recogniser.ProtoRecogniser.from_files",
}


def cell(experiment, name, method, mean, recogniser=None, maze="5x5", way=1, seed=0):
    """A cell whose runs collide ``mean`` + noise times (run ``r``'s noise shared by every cell
    of one seed, as run seeds are), converged in every run."""
    rng = np.random.default_rng([seed, 7])
    shared = rng.normal(0, 2, RUNS)
    own = np.random.default_rng(abs(hash((experiment, name))) % 2**32).normal(0, 0.3, RUNS)
    collisions = np.maximum(mean + shared + own, 0)
    episodes = pd.DataFrame(
        {
            "run": np.arange(RUNS),
            "episode": 0,
            "collisions": collisions,
            "greedy_optimal": True,
        }
    )
    spec = get_method(method).as_dict()
    kind = recogniser if recogniser in TARGETS or recogniser == PAPER_RECOGNITION else None
    info = {
        "method": spec,
        "maze": maze,
        "substitution": way,
        "support": "restore",
        "recogniser": {"kind": kind} if recogniser and kind else None,
    }
    config = {"seed": seed, "recogniser": {"_target_": TARGETS["relation_net"]}}
    if recogniser == "fixed_accuracy":
        config["recogniser"] = {"_target_": "pipeline.rl.fixed_accuracy.FixedAccuracyRecogniser"}
    return Cell(experiment, name, info, [], {}, episodes, pd.DataFrame(), None, config=config)


def experiment(name, cells):
    by = {c.name: c for c in cells}
    return Experiment(name, name, ReportSpec(), by, sorted(by))


def fig8(paper_tables: bool = True):
    cells = [
        cell("fig8", "qlearning", "qlearning", 170),
        cell("fig8", "shield", "shield", 15),
        cell("fig8", "ssrl", "ssrl", 7),
        cell("fig8", "fewshot", "fewshot", 6, "relation_net"),  # SSRL not better: does not hold
        cell("fig8", "fewshot_dss", "fewshot_dss", 6, "relation_net"),
        cell("fig8", "fewshot_protonet", "fewshot", 9, "protonet"),
        cell("fig8", "fewshot_dss_protonet", "fewshot_dss", 8, "protonet"),
    ]
    if paper_tables:  # the paper's recognition: few-shot collides more than SSRL, as the paper says
        cells.append(cell("fig8", "fewshot_paper", "fewshot", 9, PAPER_RECOGNITION))
    return experiment("fig8", cells)


def table3():
    cells = []
    for maze, gain in (("5x5", 0.0), ("7x7", 4.0), ("11x11", 20.0)):
        cells += [
            cell("table3", f"sarsa_{maze}", "sarsa", 200, maze=maze),
            cell("table3", f"constrained_{maze}", "constrained", 40 + gain, maze=maze),
            cell("table3", f"fewshot_{maze}", "fewshot", 10 + gain, "relation_net", maze),
        ]
        cells += [
            cell("table3", f"dss{w}_{maze}", "fewshot_dss", 10, "relation_net", maze, w)
            for w in (1, 2, 3, 4)
        ]
    return experiment("table3", cells)


def claim(claims, source, text):
    return next(c for c in claims if c.source == source and text in c.says)


def test_cells_are_grouped_by_their_recorded_recogniser():
    exp = fig8()
    kinds = {n: recogniser_of(c.info, c.config) for n, c in exp.cells.items()}
    assert kinds["qlearning"] is None and kinds["fewshot"] == "relation_net"
    assert kinds["fewshot_protonet"] == "protonet" and kinds["fewshot_paper"] == "paper_tables"
    fixed = cell("x", "f", "fewshot", 5, "fixed_accuracy")  # no recorded kind: its config group
    assert recogniser_of(fixed.info, fixed.config) == "fixed_accuracy"
    by = claims_by_recogniser([exp, table3()], [])
    assert list(by) == ["relation_net", "paper_tables", "protonet"]
    for kind, n in (("relation_net", 2), ("protonet", 2), ("paper_tables", 1)):
        figure7 = claim(by[kind], "Figure 7", "all the RL methods")  # Figure 7: no mixing
        names = [k.what for k in figure7.checks]
        assert len(names) == 3 + n and len(set(names)) == len(names), (kind, names)
    assert Data([exp], "protonet").arm("fig8", "fewshot").values.mean() == pytest.approx(
        exp.cells["fewshot_protonet"].collisions_per_run().mean()
    )


def test_the_column_with_the_papers_recognition():
    by = claims_by_recogniser([fig8(), table3()], [])
    main, paper = by["relation_net"], by[PAPER_RECOGNITION]
    i = next(k for k, c in enumerate(main) if "SSRL is slightly better" in c.says)
    assert main[i].verdict == "does not hold" and paper[i].verdict == "holds"
    assert with_recogniser(main[i], paper[i]) == "holds"
    table3_claim = next(
        k for k, c in enumerate(main) if "reduces collisions on every maze" in c.says
    )
    assert with_recogniser(main[table3_claim], paper[table3_claim]) == "not run"
    sarsa = next(k for k, c in enumerate(main) if "Sarsa has more collisions" in c.says)
    assert with_recogniser(main[sarsa], paper[sarsa]) == "no recogniser in it"
    none = claims_by_recogniser([fig8(paper_tables=False), table3()], [])
    assert PAPER_RECOGNITION not in none
    assert with_recogniser(none["relation_net"][i], None) == "not run"


def test_across_mazes_the_interval_is_unpaired_and_holm_is_stated(tmp_path):
    by = claims_by_recogniser([fig8(), table3()], [])
    grows = claim(by["relation_net"], "Table 3", "grows with the maze")
    assert [k.verdict for k in grows.checks] == ["holds", "holds"]
    assert all("unpaired (different mazes)" in k.basis for k in grows.checks)
    within = claim(by["relation_net"], "Table 3", "reduces collisions on every maze")
    assert all(k.basis == f"{RUNS} run seeds, paired" for k in within.checks)
    assert [k.threshold for k in sorted(within.checks, key=lambda k: k.p)] == pytest.approx(
        [0.05 / 3, 0.05 / 2, 0.05]
    )
    rep = Report(tmp_path)
    claims_section(rep, [fig8(), table3()], [tmp_path / "no_study"])
    text = "\n".join(rep.sections)
    assert "Holm's correction" in text and "1 − 0.05 / (m − i)" in text
    assert [line for line in text.splitlines() if line.startswith("### ")] == [
        "### With the Relation Network (the paper's recogniser)",
        "### With the paper's Tables 1-2",
        "### With the Prototypical Network",
    ]
    assert "—" not in text
    rows = pd.read_csv(tmp_path / "tables" / "claims.csv")
    assert set(rows["recogniser"]) == {"relation_net", "paper_tables", "protonet"}
    first = rows[rows["recogniser"] == "relation_net"]
    assert set(first["with the paper's recognition"]) == {
        "holds",
        "not run",
        "no recogniser in it",
    }
