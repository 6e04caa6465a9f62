"""The accuracy study's results as tables (pure functions; the ``accuracy`` stage writes them):
``baseline`` (one row per query picture), ``table1`` (long format, paper's Table 1 beside ours),
``table2`` (paper's Table 2 beside ours), ``draws`` (every random draw's outcome per tested category,
tidy: the report bootstraps Tables 1-2's intervals over its draws) and a JSON-ready ``summary``."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from .accuracy_study import DRAW_COLUMNS, PAPER_BASELINE, PAPER_TABLE1, PAPER_TABLE2, StudyResult


def baseline_frame(result: StudyResult, class_names: list[str]) -> pd.DataFrame:
    frame = pd.DataFrame(
        {
            "picture_id": np.arange(len(result.categories)),
            "category": result.categories,
            "class_name": [class_names[c] for c in result.categories],
            "predicted": result.baseline_predictions,
            "correct": result.baseline_predictions == result.categories,
        }
    )
    for c in range(result.baseline_scores.shape[1]):
        frame[f"score_{c}"] = result.baseline_scores[:, c]
    return frame


def table1_frame(result: StudyResult, repeats: int) -> pd.DataFrame:
    rows = []
    n_way = result.table1_correct.shape[0]
    paper_ok = n_way == 5 and repeats == 100
    for variant, correct, total, paper in (
        ("with_same", result.table1_correct, result.table1_total, PAPER_TABLE1["with_same"]),
        (
            "no_same",
            result.table1_no_same_correct,
            result.table1_no_same_total,
            PAPER_TABLE1["no_same"],
        ),
    ):
        for s in range(n_way):
            for t in range(n_way):
                paper_total = 800 - (100 if variant == "no_same" and s == t else 0)
                rows.append(
                    {
                        "variant": variant,
                        "substituted_category": s,
                        "tested_category": t,
                        "correct": int(correct[s, t]),
                        "total": int(total[s, t]),
                        "accuracy": float(correct[s, t] / total[s, t]),
                        "paper_correct": paper[s][t] if paper_ok else None,
                        "paper_total": paper_total if paper_ok else None,
                    }
                )
    return pd.DataFrame(rows)


def draws_frame(result: StudyResult, class_names: list[str]) -> pd.DataFrame:
    """One row per random draw and tested category (:data:`DRAW_COLUMNS`), with the categories'
    names beside their numbers."""
    frame = pd.DataFrame({k: result.draws[k] for k in DRAW_COLUMNS})
    for column in ("substituted_category", "tested_category"):
        at = frame.columns.get_loc(column) + 1
        frame.insert(
            at, column.replace("category", "name"), [class_names[c] for c in frame[column]]
        )
    return frame


def table2_frame(result: StudyResult) -> pd.DataFrame:
    return pd.DataFrame(
        [
            {
                "substitution_number": n,
                "mean_accuracy": with_same,
                "mean_accuracy_no_same": no_same,
                "paper_mean_accuracy": PAPER_TABLE2.get(n, (None, None))[0],
                "paper_mean_accuracy_no_same": PAPER_TABLE2.get(n, (None, None))[1],
            }
            for n, (with_same, no_same) in sorted(result.table2.items())
        ]
    )


def summary(result: StudyResult, class_names: list[str]) -> dict[str, Any]:
    def row_means(correct: np.ndarray, total: np.ndarray) -> list[float]:
        return (correct.sum(1) / total.sum(1)).tolist()

    t1_rows = row_means(result.table1_correct, result.table1_total)
    t1_ns_rows = row_means(result.table1_no_same_correct, result.table1_no_same_total)
    return {
        "class_names": class_names,
        "baseline": {
            "correct": result.baseline_correct.tolist(),
            "total": result.per_category_total.tolist(),
            "accuracy": result.baseline_accuracy,
            "paper": PAPER_BASELINE,
        },
        "table1": {
            "overall_by_substituted_category": t1_rows,
            "overall_by_substituted_category_no_same": t1_ns_rows,
            "mean": float(np.mean(t1_rows)),
            "mean_no_same": float(np.mean(t1_ns_rows)),
            "paper_mean": PAPER_TABLE1["mean_with_same"],
            "paper_mean_no_same": PAPER_TABLE1["mean_no_same"],
        },
        "table2": {
            str(n): {
                "mean_accuracy": w,
                "mean_accuracy_no_same": ns,
                "paper": list(PAPER_TABLE2.get(n, (None, None))),
            }
            for n, (w, ns) in sorted(result.table2.items())
        },
    }
