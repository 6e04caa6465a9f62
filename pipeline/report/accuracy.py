"""Tables 1 and 2 (paper section 4.2.1), after the recogniser section (:mod:`.recogniser_table`), from the accuracy
study's data files (``baseline.csv``, ``table1.csv``, ``table2.csv``, ``summary.json``) and the
meta-training metrics. The paper's numbers come in those files' ``paper_*`` columns. The Relation
Network (the paper's recogniser) fills the tables; other few-shot methods studied the same way
(the Prototypical Network: ``accuracy_protonet``) are shown beside it, row by row.

Intervals: :mod:`pipeline.report.study` (bootstrap over the study's random draws).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.ticker import MaxNLocator

from pipeline import palette
from pipeline.report import figures as F
from pipeline.report.formats import interval
from pipeline.report.names import PAPER_RECOGNISER, recogniser_colour, recogniser_name
from pipeline.report.recogniser_table import recogniser_section
from pipeline.report.study import RESAMPLES, SEED, VARIANTS, Estimate, Study, read_summary

#: Table 2's columns (the accuracy study's ``table2.csv``) as the report prints them.
TABLE2_HEADERS = {
    "substitution_number": "substitutions",
    "mean_accuracy": "ours [95% CI]",
    "mean_accuracy_no_same": "ours, no same picture [95% CI]",
    "paper_mean_accuracy": "paper",
    "paper_mean_accuracy_no_same": "paper, no same picture",
}


def query_accuracy(accuracy_dir: Path) -> tuple[int, int] | None:
    """Correct and tested query pictures of the Relation Network with the original support set
    (the accuracy study's ``summary.json``, Table 1's first row); None without the study."""
    summary = read_summary(accuracy_dir)
    if summary is None:
        return None
    return int(sum(summary["baseline"]["correct"])), int(sum(summary["baseline"]["total"]))


def percent(value, estimate: Estimate | None = None) -> str:
    """``57.71%`` or, with an estimate whose interval to show, ``57.71% [55.49, 59.93]``."""
    if value is None or pd.isna(value):
        return ""
    if estimate is None or estimate.draws is None:
        return f"{100 * value:.2f}%"
    return f"{100 * value:.2f}% {interval(*estimate.ci(), scale=100)}"


def intervals_note(study: Study) -> str:
    return (
        f"[95% CI] percentile bootstrap over the study's random draws ({study.draws} per substituted "
        f"category, resampled within each; {RESAMPLES} resamples, seed {SEED}: `draws.csv`), for these "
        "40 query pictures and this trained model; the original support set involves no draw."
    )


def accuracy_tables(
    rep, accuracy_dir: Path, model_metrics: Path, others: dict[str, tuple[Path, Path]] | None = None
) -> None:
    """The recognisers' validation accuracy and Tables 1-2 of the paper's recogniser's study
    (``accuracy_dir``, ``model_metrics``); ``others`` maps another recogniser (its kind) to its
    study folder and metrics file, shown beside it (missing files: said, not shown)."""
    main = recogniser_name(PAPER_RECOGNISER)
    others = {recogniser_name(kind): files for kind, files in (others or {}).items()}
    recogniser_section(
        rep,
        [(main, model_metrics, accuracy_dir), *((n, m, f) for n, (f, m) in others.items())],
    )
    if not (accuracy_dir / "table2.csv").exists():
        rep.add(f"Accuracy study: no data under `{accuracy_dir}`.\n")
        return
    studies = {main: Study(accuracy_dir)}  # the paper's recogniser's first, the others beside it
    for name, (folder, _) in others.items():
        if (folder / "table2.csv").exists():
            studies[name] = Study(folder)
        else:
            rep.add(
                f"{name}: no accuracy study under `{folder}` (its trained model and `accuracy` run), not shown.\n"
            )
    study, beside = studies[main], list(studies)[1:]
    names, base = study.names, study.baseline
    rows = [
        {
            "": f"ours, {name}",
            **{n: f"{c}/{t}" for n, c, t in zip(names, s.baseline["correct"], s.baseline["total"])},
            "overall": f"{100 * s.baseline['accuracy']:.1f}%",
        }
        for name, s in studies.items()
    ]
    paper = (base.get("paper") or {}).get("correct")
    if paper:
        rows.append(
            {
                "": "paper",
                **{n: f"{c}/{t}" for n, c, t in zip(names, paper, base["total"])},
                "overall": f"{100 * sum(paper) / study.pictures:.1f}%",
            }
        )
    rep.add("## Table 1: recognition accuracy of the 40 query pictures\n")
    rep.table(
        "table1_no_substitution",
        pd.DataFrame(rows),
        "Original support set (no substitution), correct per category (no random draw: no interval).",
    )
    for variant, title in (
        ("with_same", "one substitution"),
        ("no_same", "one substitution, no same picture"),
    ):
        rep.table(
            f"table1_{variant}",
            table1(studies, variant),
            f"Table 1, {title}: correct/tested per category ({main}"
            + "".join(f"; the {n}'s overall accuracy beside it" for n in beside)
            + f"); {intervals_note(study)}",
        )
    summary = study.summary["table1"]
    means = [
        f"ours, {name} {shown(s.mean('with_same'))} (no same picture {shown(s.mean('no_same'))})"
        for name, s in studies.items()
    ]
    rep.add(
        f"Mean accuracy after one substitution: {'; '.join(means)}; paper {percent(summary['paper_mean'])} "
        f"({percent(summary['paper_mean_no_same'])}); [95% CI] over the draws of the {len(names)} categories.\n"
    )
    rep.add("## Table 2: accuracy against the number of substitutions\n")
    rep.table(
        "table2",
        table2(studies),
        f"Mean accuracy over the {study.pictures} query pictures (ours, "
        f"{', '.join(studies)}, and the paper's); {intervals_note(study)}",
    )
    table2_figure(rep, studies)


def shown(estimate: Estimate) -> str:
    """:func:`percent` of an estimate, with its interval."""
    return percent(estimate.value, estimate)


def table1(studies: dict[str, Study], variant: str) -> pd.DataFrame:
    """Table 1 (one substitution) as correct/tested per substituted and tested category of the
    first study (with each row's accuracy and interval) beside the paper's; each other study adds
    its row's overall accuracy."""
    study, *_ = studies.values()
    names = study.names
    out = []
    for s in range(len(names)):
        d = study.cells(variant, s)
        line = {
            "substituted": names[s],
            **{
                names[int(t)]: f"{c}/{n}"
                for t, c, n in zip(d["tested_category"], d["correct"], d["total"])
            },
        }
        for name, other in zip(("ours", *list(studies)[1:]), studies.values()):
            line[f"overall, {name} [95% CI]"] = shown(other.row(variant, s))
        if d["paper_correct"].notna().all():
            line.update(
                {
                    f"{names[int(t)]} (paper)": f"{int(c)}/{int(n)}"
                    for t, c, n in zip(d["tested_category"], d["paper_correct"], d["paper_total"])
                }
            )
            line["overall, paper"] = (
                f"{int(d['paper_correct'].sum())}/{int(d['paper_total'].sum())}"
            )
        out.append(line)
    return pd.DataFrame(out)


def table2(studies: dict[str, Study]) -> pd.DataFrame:
    """Table 2: the first study's accuracies (the data file's, with their intervals) beside the
    paper's, then each other study's."""
    study, *_ = studies.values()
    show = study.table2.reset_index()
    for variant, column in VARIANTS.items():
        show[column] = [
            percent(v, study.substitutions(int(n), variant))
            for n, v in zip(show["substitution_number"], show[column])
        ]
        show["paper_" + column] = show["paper_" + column].map(percent)
    show = show.rename(columns=TABLE2_HEADERS)
    for name, other in list(studies.items())[1:]:
        for variant, column in VARIANTS.items():
            show[TABLE2_HEADERS[column].replace("ours", name)] = [
                shown(other.substitutions(int(n), variant)) if n in other.table2.index else ""
                for n in show["substitutions"]
            ]
    return show


def table2_figure(rep, studies: dict[str, Study]) -> None:
    study, *_ = studies.values()
    fig, ax = plt.subplots(figsize=(6.0, 4.2), layout="constrained")
    n = study.table2.index.to_numpy()
    for (variant, column), style, label in zip(
        VARIANTS.items(), ("o-", "o--"), ("ours", "ours, no same picture")
    ):
        for k, (who, s) in enumerate(studies.items()):
            estimates = [s.substitutions(int(i), variant) for i in s.table2.index.to_numpy()]
            values = np.array([100 * e.value for e in estimates])
            err = np.array(
                [[100 * (e.value - e.ci()[0]), 100 * (e.ci()[1] - e.value)] for e in estimates]
            ).T
            name = label if len(studies) == 1 else label.replace("ours", f"ours, {who}")
            ax.errorbar(
                s.table2.index.to_numpy(),
                values,
                yerr=err,
                fmt=("o" if k == 0 else "^") + style[1:],
                capsize=3,
                color=recogniser_colour(who) or palette.series(k),
                label=f"{name} (95% CI)",
            )
        paper = study.table2.get("paper_" + column)
        if paper is not None and paper.notna().any():
            ax.plot(
                n,
                100 * paper,
                "s" + style[1:],
                color=palette.PAPER,
                alpha=0.7,
                label=label.replace("ours", "paper"),
            )
    ax.set_xlabel("substitution number")
    ax.set_ylabel("mean accuracy (%)")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    F.figure_legend(fig, *ax.get_legend_handles_labels(), 2)
    ax.set_title("Table 2 as a plot", fontsize=10)
    F.save(fig, rep.out / "figures" / "table2_accuracy.png")
    rep.figure(
        "figures/table2_accuracy.png",
        "Table 2: mean accuracy against the number of substitutions, ours with "
        "95% bootstrap intervals over the draws, beside the paper's.",
    )
