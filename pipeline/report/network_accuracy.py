"""The accuracy of every trained network, and its spread across networks (issue 42).

Five networks of each kind (the same recipe, seeds 0-4: ``meta_train`` for seed 0 and dvc.yaml's
``networks_*`` stages for 1-4) each get the accuracy study (``accuracy`` and
``accuracy_networks_*``). Per recogniser kind and quantity the table gives each network's value,
their mean, the spread across networks (the standard deviation of the networks' values) and two
95% intervals of the mean:

* **these networks**: each network's own resampling (test and validation accuracy: its families,
  then their episodes, as the accuracy study's ``family_ci``; Tables 1-2: the study's draws,
  :mod:`pipeline.report.study`), averaged over the networks;
* **networks, then theirs**: the networks resampled with replacement first, each drawn network
  bringing its own resample (a two-level bootstrap; Davison and Hinkley 1997, section 3.8): the
  interval for a new draw of networks trained by the same recipe.

The test families are the same for every network (crossed, not nested), so every network's
resample ``b`` resamples the same families (one seed): the families' share of the variance is
counted once. The query pictures named right with the original support set involve no random draw,
so only the networks are resampled for them.
"""

from __future__ import annotations

import re
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from pipeline import palette
from pipeline.report import figures as F
from pipeline.report import formats
from pipeline.report.names import recogniser_colour, recogniser_name
from pipeline.report.study import RESAMPLES, SEED, Study, read_summary
from pipeline.stats import cluster_ratio_draws, percentile_ci

#: A network's study folder under ``networks_dir``: ``<kind>_seed<k>``.
FOLDER = re.compile(r"^(\w+?)_seed(\d+)$")
#: Test and validation accuracy from the study's ``families.csv``, by its ``split``.
SPLITS = {"test": "test accuracy (held-out families)", "val": "validation accuracy"}
#: The study's order of the splits: split ``s`` is resampled with the seed ``[seed, index of s]``
#: (``pipeline.fewshot.family_accuracy.SPLITS``, not imported: it brings torch).
STUDY_SPLITS = ("val", "test")


def network_folders(seed0: dict[str, Path], networks_dir: Path) -> dict[str, dict[int, Path]]:
    """kind -> seed -> accuracy study folder: ``seed0`` (each kind's study of its seed-0 network)
    and every ``<kind>_seed<k>`` folder of ``networks_dir`` holding a study; kinds in ``seed0``'s
    order, seeds ascending."""
    found = {
        kind: {0: folder} for kind, folder in seed0.items() if (folder / "summary.json").is_file()
    }
    if networks_dir.is_dir():
        for folder in sorted(networks_dir.iterdir()):
            match = FOLDER.match(folder.name)
            if match and match[1] in seed0 and (folder / "summary.json").is_file():
                found.setdefault(match[1], {})[int(match[2])] = folder
    return {kind: dict(sorted(seeds.items())) for kind, seeds in found.items()}


def split_draws(folder: Path, split: str) -> tuple[float, np.ndarray] | None:
    """A split's pooled accuracy and its bootstrap draws (families, then their episodes, seeded as
    the study seeds its ``family_ci``: every network resamples the same families), from
    ``families.csv`` and ``summary.json``."""
    path = folder / "families.csv"
    if not path.is_file():
        return None
    rows = pd.read_csv(path)
    rows = rows[rows["split"] == split]
    if rows.empty:
        return None
    correct, tested = rows["correct"].to_numpy(float), rows["tested"].to_numpy(float)
    seed = [read_summary(folder)["families"]["seed"], STUDY_SPLITS.index(split)]
    draws = cluster_ratio_draws(
        correct, tested, rows["family"], within=True, resamples=RESAMPLES, seed=seed
    )
    return float(correct.sum() / tested.sum()), draws


def quantities(folder: Path) -> dict[str, tuple[float, np.ndarray | None]]:
    """One network's quantities: label -> (value, bootstrap draws or None for no random draw)."""
    study = Study(folder)
    out = {}
    for split, label in SPLITS.items():
        found = split_draws(folder, split)
        if found is not None:
            out[label] = found
    correct, total = sum(study.baseline["correct"]), sum(study.baseline["total"])
    out[f"query pictures right ({total}), original support set"] = (correct / total, None)
    one, five = study.substitutions(1), study.substitutions(5)
    out["Table 1: mean after one substitution"] = (one.value, one.draws)
    out["Table 2: after five substitutions"] = (five.value, five.draws)
    return out


def networks_then_draws(values: np.ndarray, draws: np.ndarray | None) -> np.ndarray:
    """The two-level bootstrap of the mean over networks (module docstring): resample ``b`` draws
    the networks with replacement (seeded by :data:`SEED`) and averages the drawn networks' own
    resample ``b`` (``draws``: networks x resamples), or their values where there is no draw."""
    rng = np.random.default_rng(SEED)
    picked = rng.integers(0, values.size, size=(RESAMPLES, values.size))
    if draws is None:
        return values[picked].mean(axis=1)
    return draws[picked, np.arange(RESAMPLES)[:, None]].mean(axis=1)


def sd(values: np.ndarray) -> str:
    """The standard deviation across networks in points ("" for one network)."""
    return f"{100 * values.std(ddof=1):.2f}" if len(values) > 1 else ""


def interval(draws: np.ndarray) -> str:
    """The percentile interval of ``draws`` in percent."""
    return formats.interval(*percentile_ci(draws), scale=100)


def spread_rows(folders: dict[str, dict[int, Path]]) -> list[dict]:
    """Per recogniser kind and quantity: each network's value, the mean, the spread across
    networks and the two intervals (module docstring)."""
    rows = []
    for kind, seeds in folders.items():
        per_network = {seed: quantities(folder) for seed, folder in seeds.items()}
        first, *_ = per_network.values()
        labels = [label for label in first if all(label in q for q in per_network.values())]
        for label in labels:
            values = np.array([q[label][0] for q in per_network.values()])
            each = [q[label][1] for q in per_network.values()]
            draws = None if any(d is None for d in each) else np.stack(each)
            rows.append(
                {
                    "recogniser": recogniser_name(kind),
                    "quantity": label,
                    "networks": len(values),
                    "seeds": " ".join(map(str, seeds)),
                    "each network": " / ".join(f"{100 * v:.1f}" for v in values),
                    "mean": f"{100 * values.mean():.2f}%",
                    "s.d. across networks": sd(values),
                    "95% CI, these networks": "" if draws is None else interval(draws.mean(axis=0)),
                    "95% CI, networks then theirs": interval(networks_then_draws(values, draws)),
                }
            )
    return rows


def network_accuracy_section(rep, seed0: dict[str, Path], networks_dir: Path) -> None:
    """The table and its figure (module docstring); nothing without a second network."""
    folders = network_folders(seed0, networks_dir)
    if not any(len(seeds) > 1 for seeds in folders.values()):
        return
    table = pd.DataFrame(spread_rows(folders))
    rep.add("## Accuracy across networks\n")
    rep.add(
        "Each network of the same recipe (seeds 0-4; seed 0 is the network of Tables 1-2 above and "
        "of every other experiment) studied the same way. A figure that moves from network to "
        "network as much as between its interval's ends is a property of the network, not of the "
        "method.\n"
    )
    rep.table(
        "network_accuracy",
        table,
        "Accuracy (%) of each network, their mean, the spread across networks (s.d. of the "
        "networks' values, points) and two 95% intervals of the mean: each network's own "
        "resampling averaged (these networks: families then episodes for test and validation, the "
        "study's draws for Tables 1-2), and networks resampled first, each bringing its own "
        f"resample (a new draw of networks); {RESAMPLES} resamples, seed {SEED}. The query "
        "pictures involve no random draw: only the networks are resampled.",
    )
    accuracy_figure(rep, table)


def accuracy_figure(rep, table: pd.DataFrame) -> None:
    """Each network's value per quantity (a dot each) and the mean over networks (a bar), one
    colour per recogniser."""
    labels = list(dict.fromkeys(table["quantity"]))
    kinds = list(dict.fromkeys(table["recogniser"]))
    fig, ax = plt.subplots(
        figsize=(7.0, 0.6 + 0.55 * len(labels) * len(kinds)), layout="constrained"
    )
    for k, who in enumerate(kinds):
        colour = recogniser_colour(who) or palette.series(k)
        rows = table[table["recogniser"] == who].set_index("quantity")
        for i, label in enumerate(labels):
            if label not in rows.index:
                continue
            y = i * len(kinds) + k
            values = [float(v) for v in rows.loc[label, "each network"].split(" / ")]
            ax.plot(values, [y] * len(values), "o", color=colour, alpha=0.8)
            mean = float(rows.loc[label, "mean"].rstrip("%"))
            ax.plot([mean, mean], [y - 0.3, y + 0.3], "-", color=colour, linewidth=2.5)
        ax.plot([], [], "o", color=colour, label=f"{who}: a network (dot), the mean (bar)")
    ax.set_yticks(
        [i * len(kinds) + (len(kinds) - 1) / 2 for i in range(len(labels))], labels, fontsize=8
    )
    ax.invert_yaxis()
    ax.set_xlabel("accuracy (%)")
    F.figure_legend(fig, *ax.get_legend_handles_labels(), 1)
    F.save(fig, rep.out / "figures" / "network_accuracy.png")
    rep.figure(
        "figures/network_accuracy.png",
        "Accuracy of each network (dots) and the mean over the networks (bars), per recogniser.",
    )
