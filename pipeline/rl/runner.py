"""Run many independent runs of one method on one maze (paper section 4.2.2: 100 runs x 500
episodes per cell), with optional recogniser in the loop and optional episode sink (records).

Usage::

    result = run_trials(load_layout("5x5"), get_method("ssrl"), runs=100, episodes=500, seed=0)
    result.summary()["collisions"]["mean"]
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from tqdm.auto import tqdm

from pipeline.rl import kernel
from pipeline.rl.codes import Learner, Safety
from pipeline.rl.methods import MethodSpec
from pipeline.rl.recogniser import Recogniser
from pipeline.rl.rng import run_seeds
from pipeline.rl.sink import EpisodeSink
from pipeline.world.geometry import Geometry, build_geometry
from pipeline.world.maze import Layout, shortest_path_length
from pipeline.world.pictures import N_PICTURES, picture_category

#: True category of every query picture id.
PICTURE_CATEGORY = np.array([picture_category(p) for p in range(N_PICTURES)], dtype=np.int8)
from pipeline.world.placement import Placement, picture_table, random_placement


@dataclass(frozen=True)
class RunWorld:
    """One run's obstacles and what the robot sees from each (cell, action)."""

    placement: Placement
    pictures: np.ndarray       # (n_cells, 4) picture id or -1
    true_category: np.ndarray  # (n_obstacles,)


def make_run_world(geometry: Geometry, seed: int, run: int) -> RunWorld:
    rng = np.random.default_rng(run_seeds(seed, run).placement)
    placement = random_placement(len(geometry.layout.obstacles), rng)
    return RunWorld(placement, picture_table(geometry, placement), placement.category.copy())


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
            {"run": r, "collisions": int(self.collisions[r].sum()), "steps": int(self.steps[r].sum()),
             "converged_episode": conv[r], "goals": int(self.reached_goal[r].sum()),
             "prevented": int(self.prevented[r].sum())}
            for r in range(self.runs)
        ]

        def stats(values):
            v = np.asarray([x for x in values if x is not None], dtype=float)
            if v.size == 0:
                return {"mean": None, "std": None, "n": 0}
            return {"mean": float(v.mean()), "std": float(v.std(ddof=1)) if v.size > 1 else 0.0, "n": int(v.size)}

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


def _emit(sink, r, run_id, first_ep, last_ep, res, buf, scores, cursors):
    """Hand episodes ``first_ep..last_ep-1`` of run ``r`` to the sink as one columnar batch."""
    if last_ep > first_ep:
        eps = slice(first_ep, last_ep)
        steps = res["steps"][r, eps]
        n = int(steps.sum())
        lo, hi = cursors["rec"][r], int(buf["rec_len"][r])
        rec = buf["rec"][r, lo:hi]
        part = scores[r][lo:hi]
        sc = np.stack(part).astype(np.float32) if len(part) == hi - lo and hi > lo else np.zeros((hi - lo, 0), np.float32)
        alo, ahi = cursors["add"][r], int(buf["add_len"][r])
        add = buf["add"][r, alo:ahi]
        cursors["rec"][r], cursors["add"][r] = hi, ahi
        sink.episodes(
            run=run_id, episode=np.arange(first_ep, last_ep, dtype=np.int32), steps=steps.astype(np.int32),
            states=buf["trace_s"][r, :n].copy(), actions=buf["trace_a"][r, :n].copy(),
            rewards=buf["trace_r"][r, :n].copy(), flags=buf["trace_f"][r, :n].copy(),
            recognitions={
                "episode": rec[:, 0].astype(np.int32), "step": rec[:, 1].astype(np.int32),
                "state": rec[:, 2].astype(np.int32), "action": rec[:, 3].astype(np.int8),
                "picture": rec[:, 4].astype(np.int16), "predicted": rec[:, 5].astype(np.int8),
                "true": rec[:, 6].astype(np.int8), "scores": sc,
            },
            unsafe_added={
                "episode": add[:, 0].astype(np.int32), "step": add[:, 1].astype(np.int32),
                "state": add[:, 2].astype(np.int32), "action": add[:, 3].astype(np.int8),
                "source": add[:, 4].astype(np.int8),
            },
            summary={
                "collisions": res["col"][r, eps].copy(), "return_": res["ret"][r, eps].copy(),
                "reached_goal": res["goal"][r, eps].copy(), "prevented": res["prev"][r, eps].copy(),
                "epsilon": res["eps"][r, eps].copy(), "greedy_optimal": res["greedy"][r, eps].copy(),
            },
        )
    buf["trace_len"][r] = 0


def run_trials(layout: Layout, method: MethodSpec, runs: int, episodes: int, seed: int = 0, *,
               recogniser: Recogniser | None = None, sink: EpisodeSink | None = None,
               run_offset: int = 0, progress: bool = True, chunk_episodes: int = 100,
               trace_capacity: int = 16384, shared_support: bool = False) -> TrialResult:
    """Run ``runs`` independent runs (ids ``run_offset ..``) of ``episodes`` episodes each.

    Run ``r`` draws its obstacle placement, its agent's random stream and its recogniser seed from
    ``run_seeds(seed, r)``, so a run's outcome does not depend on the batch it is in.

    ``shared_support`` (long-term autonomy, paper Figure 10): the runs are consecutive experiments
    of one robot. They execute one after another and all use recogniser slot ``run_offset``, so a
    recogniser built to carry its support set over hands each run the set the previous run left.
    Q, A_d and the obstacle placement are still fresh for every run.
    """
    if runs < 1:
        raise ValueError(f"runs={runs}: must be >= 1")
    if episodes < 1:
        raise ValueError(f"episodes={episodes}: must be >= 1")
    if method.uses_recogniser and recogniser is None:
        raise ValueError(f"method {method.name!r} reasons with pictures: pass a recogniser")
    geometry = build_geometry(layout)
    opt_len = shortest_path_length(layout)
    n_cells, n_obs = layout.n_cells, len(layout.obstacles)
    n_dangerous = max(1, int((geometry.obstacle >= 0).sum()))
    record = sink is not None

    worlds = [make_run_world(geometry, seed, run_offset + r) for r in range(runs)]
    pictures = np.stack([w.pictures for w in worlds]).astype(np.int16)
    true_category = np.stack([w.true_category for w in worlds]).astype(np.int8) if n_obs else np.zeros((runs, 1), np.int8)
    predicted = np.zeros((runs, N_PICTURES), dtype=np.int8)
    rng = np.array([run_seeds(seed, run_offset + r).agent for r in range(runs)], dtype=np.uint64)
    uses_recogniser = recogniser is not None and method.uses_recogniser

    def slot(r: int) -> int:
        return run_offset if shared_support else run_offset + r

    def start(r: int) -> None:
        if uses_recogniser:
            recogniser.start_run(slot(r), run_seeds(seed, run_offset + r).recogniser)
            predicted[r] = recogniser.predictions(slot(r))
            if sink is not None:
                sink.substitution(run=run_offset + r, episode=0, step=0, picture=-1, category=-1,
                                  position=-1, support_accuracy=float((predicted[r] == PICTURE_CATEGORY).mean()))

    q = np.zeros((runs, n_cells, 4))
    unsafe = np.zeros((runs, n_cells, 4), dtype=np.bool_)
    cur = np.zeros((runs, 7), dtype=np.int64)
    cur[:, 2] = layout.start
    cur[:, 3] = -1
    eps = np.full(runs, method.epsilon)
    ep_ret = np.zeros(runs)
    res = {
        "steps": np.zeros((runs, episodes), np.int32), "col": np.zeros((runs, episodes), np.int32),
        "ret": np.zeros((runs, episodes), np.float32), "goal": np.zeros((runs, episodes), np.bool_),
        "prev": np.zeros((runs, episodes), np.int32), "greedy": np.zeros((runs, episodes), np.bool_),
        "eps": np.zeros((runs, episodes), np.float32),
    }
    cap = max(trace_capacity, method.max_steps) if record else 1
    buf = {
        "trace_s": np.zeros((runs, cap), np.int32), "trace_a": np.zeros((runs, cap), np.int8),
        "trace_r": np.zeros((runs, cap), np.float32), "trace_f": np.zeros((runs, cap), np.uint8),
        "trace_len": np.zeros(runs, np.int64),
        "rec": np.zeros((runs, n_dangerous, 7), np.int64), "rec_len": np.zeros(runs, np.int64),
        "add": np.zeros((runs, n_dangerous, 5), np.int64), "add_len": np.zeros(runs, np.int64),
        "sub": np.zeros((runs, 4), np.int64),
    }
    scores: list[list] = [[] for _ in range(runs)]
    cursors = {"rec": [0] * runs, "add": [0] * runs}
    emitted = [0] * runs
    params = np.array([method.gamma, method.alpha, method.epsilon_decay, method.epsilon_min])
    iparams = np.array([Learner[method.learner], Safety[method.safety], int(method.recovery),
                        int(method.constrained), int(method.dynamic_support), method.max_steps,
                        layout.start, layout.goal, opt_len, int(record)], dtype=np.int64)
    status = np.zeros(runs, np.int64)
    want_scores = record and uses_recogniser

    def score_pending(r: int) -> None:
        if not want_scores:
            return
        lo, hi = len(scores[r]), int(buf["rec_len"][r])
        if hi > lo:
            pics = buf["rec"][r, lo:hi, 4].astype(np.int64)
            scores[r].extend(np.asarray(recogniser.scores(slot(r), pics), dtype=np.float32))

    def advance(pending: np.ndarray, limit: int) -> None:
        while pending.size:
            kernel.advance_batch(pending, status, limit, params, iparams,
                                 geometry.next_cell, geometry.obstacle, geometry.ssrl_pairs,
                                 pictures, true_category, predicted, q, unsafe, rng, cur, eps, ep_ret,
                                 res["steps"], res["col"], res["ret"], res["goal"], res["prev"],
                                 res["greedy"], res["eps"], buf["trace_s"], buf["trace_a"],
                                 buf["trace_r"], buf["trace_f"], buf["trace_len"], buf["rec"],
                                 buf["rec_len"], buf["add"], buf["add_len"], buf["sub"])
            again = []
            for r in pending:
                r = int(r)
                score_pending(r)
                if status[r] == kernel.STATUS_SUBSTITUTE:
                    ep, step, pic, cat = (int(x) for x in buf["sub"][r])
                    position = recogniser.learn_from_collision(slot(r), pic, cat)
                    predicted[r] = recogniser.predictions(slot(r))
                    if sink is not None:
                        sink.substitution(run=run_offset + r, episode=ep, step=step, picture=pic,
                                          category=cat, position=int(position),
                                          support_accuracy=float((predicted[r] == PICTURE_CATEGORY).mean()))
                    again.append(r)
                elif status[r] == kernel.STATUS_FLUSH:
                    _emit(sink, r, run_offset + r, emitted[r], int(cur[r, 0]),
                          res, buf, scores, cursors)
                    emitted[r] = int(cur[r, 0])
                    again.append(r)
            pending = np.array(again, dtype=np.int64)

    limits = list(range(min(chunk_episodes, episodes), episodes, chunk_episodes)) + [episodes]
    bar = tqdm(total=runs * episodes, disable=not progress, unit="ep",
               desc=f"{method.name} {layout.name}", leave=False)
    groups = [np.array([r], np.int64) for r in range(runs)] if shared_support else [np.arange(runs, dtype=np.int64)]
    for group in groups:
        for r in group:
            start(int(r))
        for limit in ([episodes] if shared_support else limits):
            before = int(cur[group, 0].sum())
            advance(group, limit)
            bar.update(int(cur[group, 0].sum()) - before)
            if record:  # hand finished episodes over as we go: a killed run loses little
                for r in group:
                    r = int(r)
                    _emit(sink, r, run_offset + r, emitted[r], int(cur[r, 0]), res, buf, scores, cursors)
                    emitted[r] = int(cur[r, 0])
    bar.close()
    return TrialResult(layout, method, seed, res["steps"], res["col"], res["ret"], res["goal"],
                       res["prev"], res["greedy"], res["eps"], [w.placement for w in worlds])
