"""The pieces behind the report's words and intervals: display names derived from the method
configs, intervals over run seeds (pooled cells count each seed once, cells sharing seeds are
paired), the accuracy study's conservative intervals, the claims' verdicts. Seeded; no trials."""

from pathlib import Path

import numpy as np
import pytest

from pipeline.report.accuracy import Study
from pipeline.report.claims import Check, Claim, accuracy_claims
from pipeline.report.names import method_name, row_names
from pipeline.report.stats import (
    bootstrap_ci,
    bootstrap_difference,
    bounded_sd,
    cluster_means,
    describe,
    wilson_ci,
)
from pipeline.rl.methods import get_method, method_names

ACCURACY = Path(__file__).resolve().parents[1] / "datasets" / "accuracy"


def info(method="fewshot_dss", maze="5x5", substitution=1, support="restore", **fields):
    spec = get_method(method, **fields).as_dict()
    recogniser = {"kind": "relation_net"} if spec["safety"] == "fewshot" else None
    return {
        "method": spec,
        "maze": maze,
        "substitution": substitution,
        "support": support,
        "recogniser": recogniser,
    }


def test_every_method_config_has_its_own_name():
    names = {m: method_name(get_method(m).as_dict()) for m in method_names()}
    assert names == {
        "constrained": "Constrained RL",
        "fewshot": "Few-shot (static support set)",
        "fewshot_dss": "Few-shot + DSS",
        "qlearning": "Q-learning",
        "sarsa": "Sarsa",
        "shield": "Shield",
        "ssrl": "SSRL",
    }


def test_row_names_show_what_tells_rows_apart():
    # Figure 8: methods differ (and so do fields their names imply, like recovery): names only
    fig8 = [[info(m)] for m in ("qlearning", "shield", "fewshot", "fewshot_dss")]
    assert row_names(fig8) == [
        "Q-learning",
        "Shield",
        "Few-shot (static support set)",
        "Few-shot + DSS",
    ]
    # Figure 9 / 10: one method, the way or the support set differs
    assert row_names([[info(substitution=w)] for w in (1, 2)]) == [
        "Few-shot + DSS, way 1",
        "Few-shot + DSS, way 2",
    ]
    assert row_names([[info(support="restore")], [info(support="carry")]]) == [
        "Few-shot + DSS, support set restored",
        "Few-shot + DSS, support set carried over",
    ]
    # a pooled row leaves out what varies inside it; a sweep shows the field it sweeps
    assert row_names([[info("fewshot")], [info(substitution=w) for w in (1, 2, 3, 4)]]) == [
        "Few-shot (static support set)",
        "Few-shot + DSS",
    ]
    assert row_names([[info("shield", alpha=0.01)], [info("shield", alpha=0.1)]]) == [
        "Shield, alpha 0.01",
        "Shield, alpha 0.1",
    ]


def test_pooled_cells_count_each_seed_once_and_shared_seeds_pair():
    rng = np.random.default_rng(0)
    seed_effect = rng.normal(10, 3, 50)
    a, b = seed_effect + rng.normal(0, 0.1, 50), seed_effect + 0.5 + rng.normal(0, 0.1, 50)
    # two copies of one cell pooled: the interval is that of one cell, not narrower
    runs = np.arange(50)
    assert describe(np.r_[a, a], np.r_[runs, runs])["ci_low"] == pytest.approx(
        describe(a)["ci_low"]
    )
    np.testing.assert_allclose(cluster_means([1.0, 3.0, 5.0], [0, 0, 1]), [2.0, 5.0])
    diff, lo, hi = bootstrap_difference(b, a, paired=True)
    assert diff == pytest.approx(0.5, abs=0.05) and lo > 0.4 and hi < 0.6  # the seed effect cancels
    _, lo, hi = bootstrap_difference(b, a, paired=False)
    assert lo < 0 < hi  # the same data, unpaired: the seed effect swamps the difference
    assert bootstrap_ci(a) == bootstrap_ci(a)  # seeded


def test_bounded_intervals():
    lo, hi = wilson_ci(0.0, 100)
    assert lo == pytest.approx(0, abs=1e-12) and hi == pytest.approx(0.037, abs=0.001)
    assert bounded_sd(1.0) == 0 and bounded_sd(0.5) == 0.5
    assert bounded_sd([0.0, 0.5], [0.5, 0.5]) == 0.25  # s.d.s of parts add at most
    assert bounded_sd(0.0, low=-1, high=1) == 1.0


def test_check_and_claim_verdicts():
    def check(lo, hi, expect=">", margin=0.0):
        return Check("x", (lo + hi) / 2, lo, hi, expect, "u", "b", margin=margin)

    assert [check(*ci).verdict for ci in ((0.1, 1), (-1, -0.1), (-1, 1))] == [
        "holds",
        "does not hold",
        "not resolved",
    ]
    assert [check(*ci, "≈", 1).verdict for ci in ((-0.5, 0.5), (1.5, 2), (0.5, 1.5))] == [
        "holds",
        "does not hold",
        "not resolved",
    ]
    assert Claim("s", "t", [check(0.1, 1), check(-1, 1)]).verdict == "not resolved"
    assert Claim("s", "t", [check(0.1, 1), check(-1, -0.5)]).verdict == "does not hold"
    assert Claim("s", "t", missing="no records").verdict == "not checked"


@pytest.mark.skipif(
    not (ACCURACY / "summary.json").exists(), reason="needs the committed accuracy study"
)
def test_accuracy_intervals_are_over_draws_and_conservative():
    study = Study(ACCURACY)
    assert study.substitutions(0).se == 0  # the original support set: no draw, no interval
    mean = study.mean("with_same")
    assert mean.value == pytest.approx(study.summary["table1"]["mean"])
    # Table 1's per-category sums bound the spread tighter than the mean alone, still over draws
    alone = bounded_sd(mean.value) / np.sqrt(len(study.names) * study.draws)
    assert 0 < mean.se < alone
    assert study.substitutions(1).se == mean.se and study.substitutions(2).se > 0
    claims = accuracy_claims(ACCURACY)
    assert [c.source for c in claims] == ["Table 1", "Table 1", "Table 2", "Table 2", "Table 2"]
    assert all(k.low <= k.estimate <= k.high for c in claims for k in c.checks)
    assert accuracy_claims(ACCURACY / "nothing")[0].verdict == "not checked"
