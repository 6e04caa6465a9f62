"""What a trial returns: per-episode outcomes of every run (paper section 4.2.2 reports their
means over runs) and the per-run summary the stages write to ``summary.json``."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pipeline.rl.methods import MethodSpec
from pipeline.rl.structs import Results
from pipeline.world.maze import Layout
from pipeline.world.placement import Placement


@dataclass
class TrialResult:
    """Per-episode outcomes, arrays of shape (runs, episodes)."""

    layout: Layout
    method: MethodSpec
    seed: int
    steps: np.ndarray
    collisions: np.ndarray
    returns: np.ndarray
    reached_goal: np.ndarray
    prevented: np.ndarray
    greedy_optimal: np.ndarray
    epsilon: np.ndarray
    placements: list[Placement] = field(default_factory=list)
    kernel_seconds: float = 0.0
    """Wall seconds inside the compiled kernel (``kernel.advance_batch``): the trial's own work,
    beside which set-up and recording are measured (``benchmarks.generalisation``). Never recorded."""

    @classmethod
    def of(cls, layout, method, seed, results: Results, placements, kernel_seconds) -> TrialResult:
        """The result of a trial whose kernel filled ``results`` (``structs.Results``)."""
        outcomes = (results.steps, results.collisions, results.returns, results.reached_goal)
        more = (results.prevented, results.greedy_optimal, results.epsilon)
        return cls(layout, method, seed, *outcomes, *more, list(placements), kernel_seconds)

    @property
    def runs(self) -> int:
        return self.steps.shape[0]

    @property
    def episodes(self) -> int:
        return self.steps.shape[1]

    def converged_episode(self) -> list[int | None]:
        """Per run: the 0-based index of the first episode after which the greedy policy follows
        an optimal path and keeps doing so to the end of the run; None if it never settles."""
        out: list[int | None] = []
        for row in self.greedy_optimal:
            bad = np.flatnonzero(~row)
            if bad.size == 0:
                out.append(0)
            elif bad[-1] == row.size - 1:
                out.append(None)
            else:
                out.append(int(bad[-1] + 1))
        return out

    def summary(self) -> dict:
        conv = self.converged_episode()
        runs = [
            {
                "run": r,
                "collisions": int(self.collisions[r].sum()),
                "steps": int(self.steps[r].sum()),
                "converged_episode": conv[r],
                "goals": int(self.reached_goal[r].sum()),
                "prevented": int(self.prevented[r].sum()),
            }
            for r in range(self.runs)
        ]

        def stats(values):
            v = np.asarray([x for x in values if x is not None], dtype=float)
            if v.size == 0:
                return {"mean": None, "std": None, "n": 0}
            return {
                "mean": float(v.mean()),
                "std": float(v.std(ddof=1)) if v.size > 1 else 0.0,
                "n": int(v.size),
            }

        return {
            "maze": self.layout.name,
            "method": self.method.name,
            "seed": self.seed,
            "n_runs": self.runs,
            "n_episodes": self.episodes,
            "collisions": stats(r["collisions"] for r in runs),
            "steps": stats(r["steps"] for r in runs),
            "converged_episode": stats(conv),
            "converged_runs": int(sum(c is not None for c in conv)),
            "runs": runs,
        }
