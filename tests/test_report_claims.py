"""The pieces behind the report's words and intervals: display names derived from the method
configs, intervals over run seeds (pooled cells count each seed once, cells sharing seeds are
paired), the accuracy study's bootstrap over its draws, the claims' verdicts with Holm's rule.
Seeded; no trials."""

from pathlib import Path

import numpy as np
import pytest

from pipeline.report.checks import from_draws
from pipeline.report.claims import Check, Claim, accuracy_claims
from pipeline.report.experiments import ReportInputError
from pipeline.report.names import method_name, row_names
from pipeline.report.study import Study
from pipeline.rl.methods import get_method, method_names
from pipeline.stats import (
    bootstrap_ci,
    bootstrap_difference,
    bootstrap_p,
    cluster_means,
    describe,
    holm,
    stratified_means,
    wilson_ci,
)

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


def test_wilson_stratified_bootstrap_and_p_values():
    lo, hi = wilson_ci(0.0, 100)
    assert lo == pytest.approx(0, abs=1e-12) and hi == pytest.approx(0.037, abs=0.001)
    # strata of draws: each resample keeps every stratum's draws, so a between-strata spread
    # (the categories differ) adds nothing, unlike resampling the pooled draws
    strata = np.array([[0.0] * 50, [1.0] * 50])
    assert np.ptp(stratified_means(strata)) == 0 and np.ptp(bootstrap_ci_draws(strata)) > 0
    assert np.array_equal(
        stratified_means(strata, seed=[0, 1]), stratified_means(strata, seed=[0, 1])
    )
    assert bootstrap_p(np.full(1999, 1.0)) == pytest.approx(2 / 2000)  # every draw above zero
    assert bootstrap_p(np.linspace(-1, 1, 2001)) == 1.0


def bootstrap_ci_draws(values):
    rng = np.random.default_rng(0)
    v = np.ravel(values)
    return v[rng.integers(0, v.size, size=(200, v.size))].mean(axis=1)


def test_holm_step_down():
    thresholds, rejected = holm([0.01, 0.04, 0.03])
    assert thresholds == pytest.approx([0.05 / 3, 0.05, 0.05 / 2])
    assert rejected == [True, False, False]  # 0.03 > 0.025: it and every larger one stay
    assert holm([0.004, 0.02, 0.04])[1] == [True, True, True]
    # three checks, each alone decided at 5% (p = 0.02), together not: Holm's rule at work
    draws = np.r_[np.full(19, -0.1), np.full(1981, 1.0)]
    one = from_draws("x", 1.0, draws, "u", "b")
    assert (
        one.p == pytest.approx(2 * 20 / 2001) and Claim("s", "t", [one]).settle().verdict == "holds"
    )
    three = Claim("s", "t", [from_draws(str(i), 1.0, draws, "u", "b") for i in range(3)])
    assert three.verdict == "not resolved"
    assert [c.threshold for c in three.checks] == pytest.approx([0.05 / 3, 0.05 / 2, 0.05])
    # comparable: within the margin holds, outside it does not
    inside = from_draws("w", 0.0, np.linspace(-0.5, 0.5, 2000), "u", "b", expect="≈", margin=1)
    outside = from_draws("w", 3.0, np.linspace(2, 4, 2000), "u", "b", expect="≈", margin=1)
    assert (inside.verdict, outside.verdict) == ("holds", "does not hold")
    assert "p = 0.001, Holm threshold 0.05" in inside.text()
    assert "not reached: an earlier check undecided" in three.checks[2].text()


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
    not (ACCURACY / "draws.csv").exists(), reason="needs the committed accuracy study"
)
def test_accuracy_intervals_are_bootstrapped_over_the_draws():
    study = Study(ACCURACY)
    assert study.substitutions(0).draws is None  # the original support set: no draw, no interval
    mean = study.mean("with_same")
    assert mean.value == pytest.approx(study.summary["table1"]["mean"])
    for n in study.table2.index[1:]:  # the draws' means are the tables' numbers
        for variant, column in (
            ("with_same", "mean_accuracy"),
            ("no_same", "mean_accuracy_no_same"),
        ):
            assert study.substitutions(n, variant).value == pytest.approx(
                study.table2.loc[n, column]
            )
    lo, hi = mean.ci()
    assert lo < mean.value < hi and len(mean.draws) == 2000
    assert np.array_equal(study.mean("with_same").draws, mean.draws)  # seeded
    row = study.row("no_same", 0)
    d = study.cells("no_same", 0)
    assert row.value == pytest.approx(d["correct"].sum() / d["total"].sum())
    # the two variants of one number of substitutions are paired: their difference's interval is
    # narrower than that of independent resamples
    paired = study.substitutions(3) - study.substitutions(3, "no_same")
    other = study.substitutions(3) - study.substitutions(2, "no_same")
    assert np.ptp(paired.ci()) < np.ptp(other.ci())
    claims = accuracy_claims(ACCURACY)
    assert [c.source for c in claims] == ["Table 1", "Table 1", "Table 2", "Table 2", "Table 2"]
    assert all(k.low <= k.estimate <= k.high and k.p is not None for c in claims for k in c.checks)
    assert accuracy_claims(ACCURACY / "nothing")[0].verdict == "not checked"


def test_a_study_without_its_draws_is_refused(tmp_path):
    for name in ("summary.json", "table1.csv", "table2.csv"):
        (tmp_path / name).write_text((ACCURACY / name).read_text())
    with pytest.raises(ReportInputError, match="draws.csv: the accuracy study's draws are missing"):
        Study(tmp_path)
