"""Read the recorded experiments (``datasets/runs/<experiment>/<cell>/records.mcap``) into per-cell
tables for the report. Only the MCAP records are read."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from pipeline.records import read_records


@dataclass
class Cell:
    experiment: str
    name: str
    info: dict              # method spec, maze, substitution, support (from the file's metadata)
    layout: list[str]
    obstacles: dict         # run -> obstacle assignment
    episodes: pd.DataFrame  # run, episode, steps, collisions, ... (one row per episode)
    recognitions: pd.DataFrame
    substitutions: pd.DataFrame  # incl. one row per run (picture -1) with the initial support set

    @property
    def method(self) -> str:
        return self.info["method"]["name"]

    @property
    def maze(self) -> str:
        return self.info["maze"]

    def collisions_per_run(self) -> np.ndarray:
        return self.episodes.groupby("run")["collisions"].sum().to_numpy()

    def support_accuracy(self) -> np.ndarray | None:
        """(runs, episodes): query accuracy of each run's support set at the end of each episode
        (the initial set's until the first substitution); None without a recogniser."""
        subs = self.substitutions
        if subs is None or not len(subs) or "support_accuracy" not in subs:
            return None
        runs = sorted(self.episodes["run"].unique())
        n_ep = int(self.episodes["episode"].max()) + 1
        out = np.full((len(runs), n_ep), np.nan)
        for i, r in enumerate(runs):
            g = subs[subs["run"] == r].sort_values(["episode", "step", "picture"])
            for ep, acc in zip(g["episode"], g["support_accuracy"]):
                out[i, int(ep):] = acc
        return out

    def converged_episode(self) -> list[int | None]:
        """Per run, the first episode after which the greedy path stays optimal (None: never)."""
        if "greedy_optimal" not in self.episodes:
            return []
        out = []
        for _, g in self.episodes.sort_values(["run", "episode"]).groupby("run"):
            ok = g["greedy_optimal"].to_numpy(bool)
            bad = np.flatnonzero(~ok)
            out.append(0 if bad.size == 0 else (None if bad[-1] == ok.size - 1 else int(bad[-1] + 1)))
        return out


def load_experiment(folder: Path) -> dict[str, Cell]:
    cells = {}
    for path in sorted(folder.glob("*/records.mcap")):
        recs = read_records(path, pictures=False)
        meta = recs.meta
        info = meta.info.get("info", meta.info)
        cells[path.parent.name] = Cell(folder.name, path.parent.name, info, list(meta.maze["layout"]),
                                       meta.obstacles, recs.episodes, recs.recognitions, recs.substitutions)
    return cells


def load_all(runs_dir: Path, experiments=("fig8", "fig9", "fig10", "table3")) -> dict[str, dict[str, Cell]]:
    return {e: load_experiment(runs_dir / e) for e in experiments if (runs_dir / e).is_dir()}
