"""The paper's recognition as a recogniser (``recogniser=paper_tables``): seeded and deterministic,
its accuracy per category the paper's Tables 1-2 (exact where the draw allows it: the original
support set in every run; in expectation elsewhere), what a substitution changes, and a trial with
it through the stage."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.errors import ConfigError
from pipeline.fewshot.paper_tables import (
    CATEGORY,
    IN_SUPPORT,
    N_PICTURES,
    ORIGINAL,
    TABLE2_NO_SAME,
    PaperTablesRecogniser,
    not_in_support,
)
from pipeline.stages import run_stage
from pipeline.world.pictures import CATEGORIES, picture_category

PAPER_ORIGINAL = {"chair": 0, "kettle": 3, "carton": 2, "basin": 8, "basket": 4}  # of 8, Table 1
PAPER_TABLE1 = {  # the substituted category's own cell: (with the same picture /800, without /700)
    "chair": (186, 95),
    "kettle": (689, 596),
    "carton": (383, 331),
    "basin": (792, 697),
    "basket": (577, 487),
}


def right(rec: PaperTablesRecogniser, run: int) -> np.ndarray:
    return rec.predictions(run) == CATEGORY


def test_picture_ids_are_the_worlds():
    assert [picture_category(p) for p in range(N_PICTURES)] == CATEGORY.tolist()
    assert len(CATEGORIES) == len(ORIGINAL)


def test_the_original_support_set_names_exactly_the_papers_pictures_in_every_run():
    rec = PaperTablesRecogniser()
    for run in range(300):
        rec.start_run(run, seed=run)
        counts = np.bincount(CATEGORY[right(rec, run)], minlength=5)
        assert dict(zip(CATEGORIES, counts.tolist())) == PAPER_ORIGINAL


def test_seeded_and_deterministic():
    a, b = PaperTablesRecogniser(substitution_way=2), PaperTablesRecogniser(substitution_way=2)
    outs = []
    for rec in (a, b):
        rec.start_run(0, seed=11)
        rec.learn_from_collision(0, 9, 1)
        rec.learn_from_collision(0, 20, 2)
        outs.append((rec.predictions(0), rec.support_members(0), rec.scores(0, np.arange(40))))
    for x, y in zip(*outs):
        assert np.array_equal(x, y)
    a.start_run(1, seed=12)
    assert not np.array_equal(a.predictions(1), outs[0][0])  # another seed, another draw
    a.start_run(0, seed=11)  # restored: the original support set and the same draw
    assert (a.support_members(0) < 0).all()
    b.start_run(5, seed=11)
    assert np.array_equal(a.predictions(0), b.predictions(5))


def test_predictions_follow_every_change_of_the_support_set():
    """Predictions are kept per run while its members stay the same: each substitution, placement
    and new run changes them as a recogniser asked afresh would."""
    kept = PaperTablesRecogniser(substitution_way=1)
    kept.start_run(0, seed=3)
    kept.predictions(0)  # kept from here on

    def fresh() -> np.ndarray:
        again = PaperTablesRecogniser(substitution_way=1)
        again.start_run(0, seed=3)
        members = kept.support_members(0)
        for category, position in zip(*np.nonzero(members >= 0)):
            again.replace(0, int(category), int(position), int(members[category, position]))
        return again.predictions(0)

    for picture, category in ((9, 1), (20, 2), (12, 1), (33, 4)):
        kept.learn_from_collision(0, picture, category)
        assert np.array_equal(kept.predictions(0), fresh())
    kept.replace(0, category=0, position=2, picture_id=5)
    assert np.array_equal(kept.predictions(0), fresh())
    assert np.array_equal(kept.scores(0, np.arange(40)).argmax(axis=1), fresh())
    kept.predictions(0)[:] = 0  # a caller's copy
    assert np.array_equal(kept.predictions(0), fresh())
    kept.start_run(1, seed=3)
    before = kept.predictions(1)  # the original members, kept
    kept.start_run(1, seed=4)  # another draw over the same members
    again = PaperTablesRecogniser(substitution_way=1)
    again.start_run(1, seed=4)
    assert np.array_equal(kept.predictions(1), again.predictions(1))
    assert not np.array_equal(before, again.predictions(1))


@pytest.mark.parametrize("c", range(5), ids=CATEGORIES)
def test_one_substitution_gives_table_1(c):
    """As section 4.2.1 draws it: a random picture of c into a random position of c. The chance is
    Table 1's cell exactly; 4,000 draws agree within 4 standard errors."""
    name = CATEGORIES[c]
    with_same, no_same = PAPER_TABLE1[name]
    rec, rng = PaperTablesRecogniser(), np.random.default_rng(c)
    p_with, p_without, hits_with, hits_without, others = [], [], [], [], []
    ids = np.flatnonzero(CATEGORY == c)
    for run in range(4000):
        rec.start_run(run, seed=run)
        picture = int(rng.choice(ids))
        rec.replace(run, c, int(rng.integers(5)), picture)
        p, r = rec.probabilities(run), right(rec, run)
        rest = ids[ids != picture]
        p_with.append(p[ids].mean())
        p_without.append(p[rest].mean())
        hits_with.append(r[ids].mean())
        hits_without.append(r[rest].mean())
        others.append(p[CATEGORY != c])
        del rec._runs[run]
    assert np.mean(p_with) == pytest.approx(with_same / 800, abs=1e-12)
    assert np.mean(p_without) == pytest.approx(no_same / 700, abs=1e-12)
    for hits, target in ((hits_with, with_same / 800), (hits_without, no_same / 700)):
        se = np.std(hits) / np.sqrt(len(hits))
        assert abs(np.mean(hits) - target) < 4 * se + 1e-9
    assert np.allclose(others, ORIGINAL[CATEGORY[CATEGORY != c]])  # other categories unchanged


def test_more_substitutions_follow_table_2():
    """n substitutions in a category: its other pictures rise as Table 2's no-same-picture mean
    does (every category by the same factor), its substituted pictures are right with q_t, and
    the count stops at the five positions."""
    factor = (TABLE2_NO_SAME - 42.5) / (TABLE2_NO_SAME[1] - 42.5)
    one = not_in_support(1)
    for n in range(6):
        assert np.allclose(
            not_in_support(n), np.clip(ORIGINAL + (one - ORIGINAL) * factor[n], 0, 1)
        )
    assert np.array_equal(not_in_support(7), not_in_support(5))
    rec = PaperTablesRecogniser(substitution_way=1)
    rec.start_run(0, seed=3)
    kettle = np.flatnonzero(CATEGORY == 1)
    for k, picture in enumerate(kettle[:5], 1):
        assert rec.learn_from_collision(0, int(picture), 1) == k - 1  # way 1: in order
        p = rec.probabilities(0)
        assert np.allclose(p[kettle[:k]], IN_SUPPORT[1])
        assert np.allclose(p[kettle[k:]], not_in_support(k)[1])
    assert rec.learn_from_collision(0, int(kettle[5]), 1) == 0  # replaces the first substituted
    p = rec.probabilities(0)
    assert p[kettle[0]] == pytest.approx(not_in_support(5)[1])  # back under o_t
    assert p[kettle[5]] == pytest.approx(IN_SUPPORT[1])


def test_static_support_set_and_carry_over():
    static = PaperTablesRecogniser(substitution_way=0)
    static.start_run(0, seed=1)
    before = static.predictions(0)
    assert static.learn_from_collision(0, 0, 0) == -1
    assert np.array_equal(static.predictions(0), before)
    carry = PaperTablesRecogniser(substitution_way=1, carry_over=True)
    carry.start_run(0, seed=1)
    carry.learn_from_collision(0, 8, 1)
    carry.start_run(0, seed=2)  # the next experiment of the same robot: the support set stays
    assert carry.support_members(0)[1, 0] == 8


def test_a_wrong_name_is_one_of_the_other_four_uniformly():
    rec, named = PaperTablesRecogniser(), []
    for run in range(2000):
        rec.start_run(run, seed=run)
        pred = rec.predictions(run)
        chairs = pred[CATEGORY == 0]  # never right with the original support set
        assert (chairs != 0).all()
        named += chairs.tolist()
    share = np.bincount(named, minlength=5)[1:] / len(named)
    assert np.allclose(share, 0.25, atol=0.015)


def test_bad_input_is_refused():
    rec = PaperTablesRecogniser(substitution_way=1)
    with pytest.raises(KeyError, match="start_run"):
        rec.predictions(0)
    rec.start_run(0, seed=0)
    with pytest.raises(ValueError, match="shows category 0, not 1"):
        rec.learn_from_collision(0, 3, 1)
    with pytest.raises(ValueError, match="substitution way"):
        PaperTablesRecogniser(substitution_way=7)


def test_a_trial_runs_with_it_and_records_its_kind(tmp_path):
    from pipeline.records import read_records

    out = tmp_path / "t"
    summary = run_stage(
        "trials",
        ["method=fewshot_dss", "recogniser=paper_tables", f"out={out}", "profile=smoke"]
        + ["progress=false", "substitution=2"],
    )
    assert summary["collisions"]["mean"] > 0
    again = run_stage(
        "trials",
        ["method=fewshot_dss", "recogniser=paper_tables", f"out={tmp_path / 'u'}"]
        + ["profile=smoke", "progress=false", "substitution=2"],
    )
    assert again["runs"] == summary["runs"]
    info = read_records(out / "records.mcap").meta.info["info"]
    assert info["recogniser"]["kind"] == "paper_tables"
    with pytest.raises(ConfigError, match="recogniser.p"):
        run_stage("trials", ["method=fewshot", "recogniser=paper_tables", "+recogniser.p=0.5"])
