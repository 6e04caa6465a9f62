"""The few-shot accuracy study of the paper's section 4.2.1 (Tables 1 and 2).

- Baseline: the 40 query pictures classified against the original support set (paper: 17/40, 42.5%).
- Table 1: for each category ``c``, ``repeats`` (100) times from the original support set, one
  randomly chosen query picture of ``c`` replaces one randomly chosen support position of ``c``
  and all 40 query pictures are classified; per tested category the correct counts add up to
  x / (repeats * 8) (x/800). The "no same picture" variant does not count the substituted picture,
  so the substituted category is out of repeats * 7 (x/700).
- Table 2: the same with ``n`` = 0..K substitutions in one category (``n`` distinct query pictures
  into ``n`` distinct positions), mean accuracy over all categories and repetitions, with and
  without the substituted pictures counted. ``n = 1`` is Table 1's experiment (the same draws).

Draws come from ``numpy.random.default_rng([seed, n])``, so each substitution number has its own
stream. Every draw's outcome is kept (:attr:`StudyResult.draws`: per draw and tested category, the
correct count with and without the substituted pictures), so the report bootstraps its intervals
over draws; the tables' sums are the sums of those rows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.fewshot.settings import StudyConfig

# The paper's figures (Tables 1 and 2), for the report to put beside ours.
PAPER_BASELINE = {"correct": [0, 3, 2, 8, 4], "total": [8, 8, 8, 8, 8], "mean": 0.425}
#: Table 1, pictures named right of 800 with the substituted picture counted and of 700 without it
#: ("no same picture"): a row per substituted category, a column per tested category.
_TABLE1_ROWS = (
    ((186, 495, 168, 748, 364), (95, 496, 155, 747, 373)),
    ((0, 689, 132, 771, 292), (0, 596, 134, 756, 303)),
    ((5, 581, 383, 742, 388), (11, 574, 331, 748, 389)),
    ((4, 500, 136, 792, 314), (0, 500, 127, 697, 316)),
    ((12, 500, 335, 692, 577), (13, 500, 334, 685, 487)),
)
PAPER_TABLE1 = {
    "with_same": [list(with_same) for with_same, _ in _TABLE1_ROWS],
    "no_same": [list(no_same) for _, no_same in _TABLE1_ROWS],
    "mean_with_same": 0.4903,
    "mean_no_same": 0.4804,
}
#: Table 2, mean accuracy with and without the substituted pictures, by number of substitutions.
PAPER_TABLE2 = {
    0: (0.425, 0.425),
    1: (0.4903, 0.4804),
    2: (0.5083, 0.4846),
    3: (0.5247, 0.4841),
    4: (0.5364, 0.4868),
    5: (0.5491, 0.4860),
}


#: The columns of :attr:`StudyResult.draws`: the number of substitutions, the substituted category,
#: the draw (0..repeats-1 per substituted category and number), the substituted pictures and support
#: positions (space-separated ids), the tested (query) category, its query pictures, those of them
#: correct, those not substituted in the draw and those of them correct.
DRAW_COLUMNS = (
    "substitutions",
    "substituted_category",
    "draw",
    "pictures",
    "positions",
    "tested_category",
    "tested",
    "correct",
    "tested_no_same",
    "correct_no_same",
)


@dataclass
class StudyResult:
    """``baseline_correct`` (C,), ``per_category_total`` (C,), ``baseline_predictions`` (P,),
    ``baseline_scores`` (P, C); Table 1 as (substituted category, tested category) counts
    ``table1_correct``, ``table1_no_same_correct`` with totals ``table1_total``,
    ``table1_no_same_total``; Table 2 as {n: (mean with, mean without the same pictures)};
    ``draws``: one row per draw and tested category (:data:`DRAW_COLUMNS`, arrays of equal length)."""

    categories: np.ndarray
    baseline_predictions: np.ndarray
    baseline_scores: np.ndarray
    baseline_correct: np.ndarray
    per_category_total: np.ndarray
    table1_correct: np.ndarray
    table1_total: np.ndarray
    table1_no_same_correct: np.ndarray
    table1_no_same_total: np.ndarray
    table2: dict[int, tuple[float, float]]
    draws: dict[str, np.ndarray]

    @property
    def baseline_accuracy(self) -> float:
        return float(self.baseline_correct.sum() / self.per_category_total.sum())


def run_study(
    recogniser, categories: np.ndarray, config: StudyConfig, k_shot: int = 5, progress: bool = False
) -> StudyResult:
    """Run the baseline, Table 1 and Table 2 with any recogniser of the trials' protocol
    (``start_run``, ``predictions``, ``scores``, ``learn_from_collision``); ``categories`` are the
    query pictures' true categories. A recogniser with a support set of positions (``replace(run,
    category, position, picture)``, the Relation Network) gets the paper's random positions; any
    other learns each substituted picture through ``learn_from_collision``."""
    from tqdm.auto import tqdm

    cats = np.asarray(categories, dtype=np.int64)
    n_way = int(cats.max()) + 1
    k_shot = int(getattr(recogniser, "k_shot", k_shot))
    substitute = getattr(recogniser, "replace", None)
    members = [np.flatnonzero(cats == c) for c in range(n_way)]
    per_cat = np.array([len(m) for m in members])
    run = 0
    recogniser.start_run(run, config.seed)
    base_pred = recogniser.predictions(run).copy()
    base_scores = recogniser.scores(run, np.arange(len(cats))).copy()
    base_correct = np.bincount(cats[base_pred == cats], minlength=n_way)

    t1 = np.zeros((n_way, n_way), dtype=np.int64)
    t1_ns = np.zeros((n_way, n_way), dtype=np.int64)
    t1_ns_total = np.zeros((n_way, n_way), dtype=np.int64)
    table2: dict[int, tuple[float, float]] = {0: (float(base_correct.sum() / per_cat.sum()),) * 2}
    max_n = min(k_shot, int(per_cat.min()))
    rows: list[tuple] = []
    bar = tqdm(
        total=max_n * n_way * config.repeats,
        desc="accuracy study",
        disable=not progress,
        mininterval=1.0,
    )
    for n in range(1, max_n + 1):
        rng = np.random.default_rng([config.seed, n])
        with_same = [0, 0]
        no_same = [0, 0]
        for c in range(n_way):
            for draw in range(config.repeats):
                recogniser.start_run(run, config.seed)
                pictures = rng.choice(members[c], size=n, replace=False)
                positions = rng.choice(k_shot, size=n, replace=False)
                for pic, pos in zip(pictures, positions):
                    if substitute is not None:
                        substitute(run, c, int(pos), int(pic))
                    else:
                        recogniser.learn_from_collision(run, int(pic), c)
                correct = recogniser.predictions(run) == cats
                counted = np.ones(len(cats), dtype=bool)
                counted[pictures] = False
                with_same[0] += int(correct.sum())
                with_same[1] += len(cats)
                no_same[0] += int(correct[counted].sum())
                no_same[1] += int(counted.sum())
                by_cat = [np.bincount(cats[m], minlength=n_way) for m in (correct, counted)]
                both = np.bincount(cats[correct & counted], minlength=n_way)
                ids = [" ".join(map(str, map(int, x))) for x in (pictures, positions)]
                rows += [
                    (n, c, draw, *ids, t, per_cat[t], by_cat[0][t], by_cat[1][t], both[t])
                    for t in range(n_way)
                ]
                if n == 1:
                    t1[c] += np.bincount(cats[correct], minlength=n_way)
                    t1_ns[c] += np.bincount(cats[correct & counted], minlength=n_way)
                    t1_ns_total[c] += np.bincount(cats[counted], minlength=n_way)
                bar.update()
        table2[n] = (with_same[0] / with_same[1], no_same[0] / no_same[1])
    bar.close()
    return StudyResult(
        categories=cats,
        baseline_predictions=base_pred,
        baseline_scores=base_scores,
        baseline_correct=base_correct,
        per_category_total=per_cat,
        table1_correct=t1,
        table1_total=np.tile(per_cat * config.repeats, (n_way, 1)),
        table1_no_same_correct=t1_ns,
        table1_no_same_total=t1_ns_total,
        table2=table2,
        draws={k: np.array([r[i] for r in rows]) for i, k in enumerate(DRAW_COLUMNS)},
    )
