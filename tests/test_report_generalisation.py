"""The generalisation section's pure parts (pipeline/report/generalisation.py): layout features,
the fitted lines and the DSS gain's growth, pinned on small exact cases."""

import numpy as np
import pytest

from pipeline.report.generalisation import CLAIMS, growth
from pipeline.report.layout_cells import features, fit, no_line
from pipeline.stats import t_quantile_975

ROWS_5X5 = ["SXX..", "..X..", "X..XX", ".X..X", "..X.G"]  # conf/mazes/5x5.txt


def test_features_of_the_papers_5x5():
    # the walled-off top-right corner (4 free cells) is not reachable: its obstacle sides do not count
    assert features(ROWS_5X5) == {"unsafe_pairs": 14, "obstacles_reachable": 7, "shortest_path": 8}


def test_features_of_a_small_layout_by_hand():
    # the centre obstacle is met from its 4 free neighbours; the path goes around it
    assert features(["S..", ".X.", "..G"]) == {
        "unsafe_pairs": 4,
        "obstacles_reachable": 1,
        "shortest_path": 4,
    }


def test_fit_is_least_squares_with_a_t_interval():
    x = np.array([0.0, 1.0, 2.0, 3.0])
    y = np.array([1.0, 3.0, 5.0, 7.5])
    b, a, low, high = fit(x, y)
    assert b == pytest.approx(2.15) and a == pytest.approx(0.9)
    resid = y - (a + b * x)
    se = np.sqrt(resid @ resid / 2 / 5.0)
    assert high - b == pytest.approx(t_quantile_975(2) * se) and b - low == pytest.approx(high - b)


def test_no_line_for_a_constant_feature_or_too_few_layouts():
    assert fit(np.array([8.0, 8.0, 8.0]), np.array([1.0, 2.0, 3.0])) is None
    assert no_line(np.array([8.0, 8.0, 8.0])) == "constant (8)"
    assert fit(np.array([1.0, 2.0]), np.array([1.0, 2.0])) is None
    assert no_line(np.array([1.0, 2.0])) == "no line: 2 layouts"


def test_growth_compares_consecutive_sizes():
    rows = growth(
        {
            "5x5": np.array([1.0, 1.0, 1.0]),
            "7x7": np.array([3.0, 3.0, 3.0]),
            "11x11": np.array([2.0, 2.0, 2.0]),
        }
    )
    assert [(r["check"], r["estimate"], r["verdict"]) for r in rows] == [
        ("DSS gain on 7x7 − on 5x5", 2.0, "holds"),
        ("DSS gain on 11x11 − on 7x7", -1.0, "does not hold"),
    ]


def test_the_claims_checked_per_layout():
    assert [c.source for c in CLAIMS] == ["Figure 8"] * 4 + ["Table 3"] * 4
