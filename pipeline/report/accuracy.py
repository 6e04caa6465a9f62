"""Tables 1 and 2 (paper section 4.2.1) and the model's validation accuracy, from the accuracy
study's data files (``baseline.csv``, ``table1.csv``, ``table2.csv``, ``summary.json``) and the
meta-training metrics. The paper's numbers come in those files' ``paper_*`` columns."""
from __future__ import annotations

import json
from pathlib import Path

import matplotlib.pyplot as plt
import pandas as pd

from pipeline.report import figures as F

#: Table 2's columns (the accuracy study's ``table2.csv``) as the report prints them.
TABLE2_HEADERS = {"substitution_number": "substitutions", "mean_accuracy": "ours",
                  "mean_accuracy_no_same": "ours, no same picture", "paper_mean_accuracy": "paper",
                  "paper_mean_accuracy_no_same": "paper, no same picture"}


def accuracy_tables(rep, accuracy_dir: Path, model_metrics: Path) -> None:
    if model_metrics.exists():
        m = json.loads(model_metrics.read_text())
        rep.add("## The recogniser\n\n"
                f"Relation Network, 5-way 5-shot validation accuracy on held-out procedural classes: "
                f"**{100 * m['val_accuracy']:.2f}% ± {100 * m['val_ci95']:.2f}%** (95% interval, "
                f"{m['val_episodes']} episodes; model selected on validation classes only).\n")
    if not (accuracy_dir / "table2.csv").exists():
        rep.add(f"Accuracy study: no data under `{accuracy_dir}`.\n")
        return
    summary = json.loads((accuracy_dir / "summary.json").read_text())
    names = summary["class_names"]
    base = summary["baseline"]
    rows = [{"": "ours", **{n: f"{c}/{t}" for n, c, t in zip(names, base["correct"], base["total"])},
             "overall": f"{100 * base['accuracy']:.1f}%"}]
    paper_base = base.get("paper") or {}
    if paper_base:
        pc = paper_base.get("correct", paper_base) if isinstance(paper_base, dict) else paper_base
        if isinstance(pc, (list, tuple)):
            rows.append({"": "paper", **{n: f"{c}/8" for n, c in zip(names, pc)},
                         "overall": f"{100 * sum(pc) / 40:.1f}%"})
    rep.add("## Table 1: recognition accuracy of the 40 query pictures\n")
    rep.table("table1_no_substitution", pd.DataFrame(rows), "Original support set (no substitution), correct per category.")
    t1 = pd.read_csv(accuracy_dir / "table1.csv")
    for variant, title in (("with_same", "one substitution"), ("no_same", "one substitution, no same picture")):
        d = t1[t1["variant"] == variant]
        wide = d.pivot(index="substituted_category", columns="tested_category", values="correct").astype(int).astype(str) + \
            "/" + d.pivot(index="substituted_category", columns="tested_category", values="total").astype(int).astype(str)
        wide.columns = [names[int(c)] for c in wide.columns]
        wide.insert(0, "substituted", [names[int(i)] for i in wide.index])
        if d["paper_correct"].notna().all():
            pw = d.pivot(index="substituted_category", columns="tested_category", values="paper_correct").astype(int).astype(str) + \
                "/" + d.pivot(index="substituted_category", columns="tested_category", values="paper_total").astype(int).astype(str)
            for j, c in enumerate(pw.columns):
                wide[f"{names[int(c)]} (paper)"] = pw[c].to_numpy()
        rep.table(f"table1_{variant}", wide.reset_index(drop=True), f"Table 1, {title}: correct/tested per category.")
    mean_key = summary["table1"]
    rep.add(f"Mean accuracy after one substitution: ours {100 * mean_key['mean']:.2f}% "
            f"(no same picture {100 * mean_key['mean_no_same']:.2f}%); paper {100 * mean_key['paper_mean']:.2f}% "
            f"({100 * mean_key['paper_mean_no_same']:.2f}%).\n")
    t2 = pd.read_csv(accuracy_dir / "table2.csv")
    rep.add("## Table 2: accuracy against the number of substitutions\n")
    show = t2.copy()
    for col in [c for c in show.columns if "accuracy" in c]:
        show[col] = show[col].map(lambda v: "" if pd.isna(v) else f"{100 * v:.2f}%")
    show = show.rename(columns=TABLE2_HEADERS)
    rep.table("table2", show, "Mean accuracy over the 40 query pictures (ours and the paper's).")
    fig, ax = plt.subplots(figsize=(5.5, 3.4))
    n = t2["substitution_number"]
    ax.plot(n, 100 * t2["mean_accuracy"], "o-", label="ours")
    ax.plot(n, 100 * t2["mean_accuracy_no_same"], "o--", label="ours, no same picture")
    if t2["paper_mean_accuracy"].notna().any():
        ax.plot(n, 100 * t2["paper_mean_accuracy"], "s-", color="red", alpha=0.6, label="paper")
        ax.plot(n, 100 * t2["paper_mean_accuracy_no_same"], "s--", color="red", alpha=0.6, label="paper, no same picture")
    ax.set_xlabel("substitution number")
    ax.set_ylabel("mean accuracy (%)")
    ax.legend(fontsize=8)
    ax.set_title("Table 2 as a plot", fontsize=10)
    F.save(fig, rep.out / "figures" / "table2_accuracy.png")
    rep.figure("figures/table2_accuracy.png", "Accuracy rises with substitutions (ours beside the paper's).")
