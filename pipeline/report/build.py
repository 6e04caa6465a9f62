"""Build ``reports/`` from the recorded data alone (issue 7; paper Tables 1-3, Figures 7-10).

Inputs: the MCAP records of the experiments (``<runs_dir>/<experiment>/<cell>/records.mcap``), the
accuracy study's data files and the validation metrics of the model, the render stage's contact
sheets. Outputs: ``index.md``, ``tables/*.md|csv``, ``figures/*.png`` (these three are replaced on every build;
the rest of the folder, e.g. ``benchmarks/``, is left alone). Deleting them and building again
gives the same bytes.
"""
from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from pipeline.records import read_records
from pipeline.report import figures as F
from pipeline.report import paper
from pipeline.report.experiments import Cell, load_all
from pipeline.report.stats import describe, fmt

MAZES = ("5x5", "7x7", "11x11")


@dataclass
class Inputs:
    runs_dir: Path
    accuracy_dir: Path
    model_metrics: Path
    contact_dir: Path
    out: Path


class Report:
    """Collects Markdown sections while tables and figures are written."""

    def __init__(self, out: Path):
        self.out = out
        self.sections: list[str] = []
        (out / "tables").mkdir(parents=True, exist_ok=True)
        (out / "figures").mkdir(parents=True, exist_ok=True)

    def add(self, text: str) -> None:
        self.sections.append(text.rstrip() + "\n")

    def table(self, name: str, df: pd.DataFrame, caption: str) -> None:
        df.to_csv(self.out / "tables" / f"{name}.csv", index=False, lineterminator="\n")
        md = df.to_markdown(index=False)
        (self.out / "tables" / f"{name}.md").write_text(f"{caption}\n\n{md}\n")
        self.add(f"{caption}\n\n{md}\n\n(`tables/{name}.csv`)\n")

    def figure(self, rel: str, caption: str) -> None:
        self.add(f"![{caption}]({rel})\n\n*{caption}*\n")

    def write(self) -> Path:
        path = self.out / "index.md"
        path.write_text("\n".join(self.sections))
        return path


def _collision_row(label: str, cell: Cell) -> dict:
    d = describe(cell.collisions_per_run())
    conv = cell.converged_episode()
    row = {"method": label, "runs": d["n"], "collisions (mean ± s.d. [95% CI])": fmt(d)}
    if conv:
        ok = [c for c in conv if c is not None]
        row["converged runs"] = f"{len(ok)}/{len(conv)}"
        row["converged episode (mean)"] = f"{np.mean(ok):.0f}" if ok else "not converged"
    return row


def experiment_fig8(rep: Report, cells: dict[str, Cell]) -> None:
    order = [n for n in ("qlearning", "shield", "ssrl", "fewshot", "fewshot_dss") if n in cells]
    rep.add("## Figure 8: collisions of the compared methods (5x5)\n\n"
            f"Paper: {paper.CLAIMS['fig8']}\n")
    rep.table("fig8", pd.DataFrame([_collision_row(n, cells[n]) for n in order]),
              "Collisions per run within the episodes of each run.")
    F.bars(order, [cells[n].collisions_per_run() for n in order], "Figure 8 (ours): collisions per run, 5x5",
           "collisions", rep.out / "figures" / "fig8_collisions.png")
    rep.figure("figures/fig8_collisions.png", "Figure 8 re-made: mean (bar), s.d. (thin), 95% bootstrap CI (thick), runs (dots).")
    curves = {n: cells[n].episodes.groupby("episode")["collisions"].mean().to_numpy() for n in order}
    pd.DataFrame({"episode": np.arange(len(next(iter(curves.values())))), **curves}).to_csv(
        rep.out / "tables" / "learning_curves.csv", index=False, lineterminator="\n", float_format="%.6g")
    F.learning_curves(curves, "Collisions per episode (mean over runs), 5x5", rep.out / "figures" / "fig8_learning_curves.png")
    rep.figure("figures/fig8_learning_curves.png", "Learning curves: collisions per episode, mean over runs, 10-episode moving average.")
    support_accuracy_figure(rep, {n: cells[n] for n in order}, "fig8_support_accuracy.png",
                            "Query accuracy of the run's support set over the run, 5x5")


def support_accuracy_figure(rep: Report, cells: dict[str, Cell], name: str, title: str) -> None:
    """Mean over runs of the support set's accuracy on the 40 query pictures, by episode."""
    curves = {n: a.mean(axis=0) for n, c in cells.items() if (a := c.support_accuracy()) is not None}
    if not curves:
        return
    F.learning_curves(curves, title, rep.out / "figures" / name, ylabel="query accuracy of the support set", window=1)
    starts = [float(c.substitutions.loc[c.substitutions["picture"] < 0, "support_accuracy"].mean())
              for c in cells.values() if c.support_accuracy() is not None]
    rep.figure(f"figures/{name}", f"{title}: mean over runs at the end of each episode (at the start of a run "
                                  f"the support set recognises {100 * np.mean(starts):.1f}% of the query pictures).")


def experiment_fig7(rep: Report, runs_dir: Path, cells: dict[str, Cell]) -> None:
    name = next((n for n in ("fewshot_dss", "fewshot", "ssrl") if n in cells), None)
    if name is None:
        return
    cell = cells[name]
    path = runs_dir / cell.experiment / name / "records.mcap"
    steps = read_records(path, pictures=False).steps
    width = len(cell.layout[0])
    goal = next(r * width + c for r, row in enumerate(cell.layout) for c, ch in enumerate(row) if ch == "G")
    cells_on_path = F.modal_final_path(steps, width, goal)
    F.optimal_path(cell.layout, cell.obstacles.get(0, []), cells_on_path,
                   f"Figure 7 (ours): the learned path ({name}, last episode, most common over runs)",
                   rep.out / "figures" / "fig7_optimal_path.png")
    rep.add(f"## Figure 7: the learned optimal path (5x5)\n\nPaper: {paper.CLAIMS['fig7']} "
            f"Ours: the most common path of the runs' last episodes, {len(cells_on_path) - 1} moves.\n")
    rep.figure("figures/fig7_optimal_path.png", "Figure 7 re-made; obstacles of run 0 coloured by category.")


def experiment_fig9(rep: Report, cells: dict[str, Cell]) -> None:
    order = sorted(cells)
    rep.add(f"## Figure 9: the four substitution ways (5x5)\n\nPaper: {paper.CLAIMS['fig9']}\n")
    rep.table("fig9", pd.DataFrame([_collision_row(n, cells[n]) for n in order]),
              "Collisions per run by substitution way.")
    F.bars(order, [cells[n].collisions_per_run() for n in order], "Figure 9 (ours): substitution ways, 5x5",
           "collisions", rep.out / "figures" / "fig9_substitution_ways.png")
    rep.figure("figures/fig9_substitution_ways.png", "Figure 9 re-made.")


def experiment_fig10(rep: Report, cells: dict[str, Cell]) -> None:
    if not {"restore", "carry"} <= set(cells):
        return
    restore, carry = cells["restore"].collisions_per_run(), cells["carry"].collisions_per_run()
    rep.add(f"## Figure 10: long-term autonomy (5x5)\n\nPaper: {paper.CLAIMS['fig10']}\n")
    rows = [{"support set": k, "collisions (mean ± s.d. [95% CI])": fmt(describe(v)),
             "after the first experiment": fmt(describe(v[1:])) if len(v) > 1 else ""}
            for k, v in (("restored before each experiment", restore), ("carried over", carry))]
    rep.table("fig10", pd.DataFrame(rows), "Collisions per experiment (consecutive runs).")
    F.long_term(restore, carry, rep.out / "figures" / "fig10_long_term.png")
    rep.figure("figures/fig10_long_term.png", "Figure 10 re-made: collisions of each consecutive experiment.")
    acc = {k: cells[k].support_accuracy() for k in ("restore", "carry")}
    if all(a is not None for a in acc.values()):
        F.learning_curves({k: a[:, -1] for k, a in acc.items()}, "Query accuracy of the support set at the end of each experiment",
                          rep.out / "figures" / "fig10_support_accuracy.png", ylabel="query accuracy", window=1,
                          xlabel="experiment (consecutive runs)")
        rep.figure("figures/fig10_support_accuracy.png", "Long-term autonomy: the carried-over support set keeps improving from one experiment to the next.")


def experiment_table3(rep: Report, cells: dict[str, Cell]) -> None:
    rows, csv = [], []
    for method in ("sarsa", "constrained", "fewshot", "fewshot_dss"):
        row = {"method": method}
        for maze in MAZES:
            if method == "fewshot_dss":
                group = [c for c in cells.values() if c.method == "fewshot_dss" and c.maze == maze]
            else:
                group = [c for c in cells.values() if c.method == method and c.maze == maze]
            if not group:
                continue
            # the paper's last row averages the four substitution ways: pool their runs
            values = np.concatenate([c.collisions_per_run() for c in group])
            d = describe(values)
            conv = sum((c.converged_episode() for c in group), [])
            converged = sum(x is not None for x in conv)
            text = fmt(d)
            if conv and converged == 0:
                text += " (not converged)"
            elif conv and converged < len(conv):
                text += f" ({converged}/{len(conv)} converged)"
            row[f"{maze} ours"] = text
            p = paper.TABLE3[method][maze]
            row[f"{maze} paper"] = "not converged" if p is None else p
            csv.append({"method": method, "maze": maze, **d, "converged_runs": converged, "paper": p})
        rows.append(row)
    rep.add(f"## Table 3: mean collisions within the episodes of a run, three mazes\n\nPaper: {paper.CLAIMS['table3']}\n")
    pd.DataFrame(csv).to_csv(rep.out / "tables" / "table3_data.csv", index=False, lineterminator="\n")
    rep.table("table3", pd.DataFrame(rows), "Mean ± s.d. [95% bootstrap CI] of collisions per run; the DSS row pools the four substitution ways.")
    curves = {}
    for maze in MAZES:
        for method in ("sarsa", "constrained", "fewshot", "fewshot_dss"):
            group = [c for c in cells.values() if c.method == method and c.maze == maze]
            if group:
                curves[f"{method} {maze}"] = pd.concat([c.episodes for c in group]).groupby("episode")["collisions"].mean().to_numpy()
    if curves:
        for maze in MAZES:
            sub = {k.split()[0]: v for k, v in curves.items() if k.endswith(maze)}
            if sub:
                F.learning_curves(sub, f"Collisions per episode, {maze}", rep.out / "figures" / f"table3_learning_curves_{maze}.png")
                rep.figure(f"figures/table3_learning_curves_{maze}.png", f"Learning curves on {maze}.")
        for maze in MAZES:
            group = {c.name: c for c in cells.values() if c.maze == maze and c.method in ("fewshot", "fewshot_dss")}
            support_accuracy_figure(rep, group, f"table3_support_accuracy_{maze}.png",
                                    f"Query accuracy of the support set over the run, {maze}")


def accuracy_section(rep: Report, accuracy_dir: Path, model_metrics: Path) -> None:
    from pipeline.report.accuracy import accuracy_tables
    accuracy_tables(rep, accuracy_dir, model_metrics)


def contact_sheets(rep: Report, contact_dir: Path) -> None:
    sheets = sorted(contact_dir.glob("*.png")) if contact_dir.is_dir() else []
    if not sheets:
        return
    rep.add("## The datasets\n")
    for sheet in sheets:
        target = rep.out / "figures" / sheet.name
        shutil.copyfile(sheet, target)
        rep.figure(f"figures/{sheet.name}", f"Contact sheet: {sheet.stem.replace('_', ' ')}")


def build_report(inputs: Inputs) -> Path:
    for old in ("tables", "figures"):
        if (inputs.out / old).exists():
            shutil.rmtree(inputs.out / old)
    (inputs.out / "index.md").unlink(missing_ok=True)
    rep = Report(inputs.out)
    rep.add("# Few-shot reasoning-based safe RL: our results beside the paper's\n\n"
            "Built by `python -m pipeline report` from the recorded data only (MCAP records of every "
            "episode, the accuracy study's data files, the model's validation metrics). Every number "
            "is mean ± standard deviation over independent runs with a 95% percentile-bootstrap "
            "interval of the mean (2000 resamples, seed 0).\n")
    experiments = load_all(inputs.runs_dir)
    if not experiments and not inputs.accuracy_dir.exists():
        raise FileNotFoundError(f"nothing to report: no experiments under {inputs.runs_dir} and no {inputs.accuracy_dir}")
    accuracy_section(rep, inputs.accuracy_dir, inputs.model_metrics)
    if "fig8" in experiments:
        experiment_fig7(rep, inputs.runs_dir, experiments["fig8"])
        experiment_fig8(rep, experiments["fig8"])
    if "fig9" in experiments:
        experiment_fig9(rep, experiments["fig9"])
    if "fig10" in experiments:
        experiment_fig10(rep, experiments["fig10"])
    if "table3" in experiments:
        experiment_table3(rep, experiments["table3"])
    contact_sheets(rep, inputs.contact_dir)
    missing = [e for e in ("fig8", "fig9", "fig10", "table3") if e not in experiments]
    if missing:
        rep.add(f"Not in this report (no records found): {', '.join(missing)}.\n")
    return rep.write()
