"""Run many independent runs of one method on one maze (paper section 4.2.2: 100 runs x 500
episodes per cell), with optional recogniser in the loop and optional episode sink (records).

Usage::

    result = run_trials(load_layout("5x5"), get_method("ssrl"), runs=100, episodes=500, seed=0)
    result.summary()["collisions"]["mean"]
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field

import numpy as np
from tqdm.auto import tqdm

from pipeline.rl import kernel, rules
from pipeline.rl.codes import Status
from pipeline.rl.methods import MethodSpec
from pipeline.rl.recogniser import Recogniser
from pipeline.rl.rng import run_seeds
from pipeline.rl.sink import EpisodeSink
from pipeline.rl.structs import (
    Additions,
    MazeArrays,
    MethodParams,
    Recognitions,
    Results,
    RunState,
    Sights,
    Substitution,
    Trace,
)
from pipeline.world.geometry import Geometry, build_geometry
from pipeline.world.maze import Layout
from pipeline.world.pictures import N_PICTURES, picture_category
from pipeline.world.placement import Placement, picture_table, random_placement

#: True category of every query picture id.
PICTURE_CATEGORY = np.array([picture_category(p) for p in range(N_PICTURES)], dtype=np.int8)

#: Steps a run's trace holds (10 bytes a step): a run's episodes go to the sink when it is full and at the end
#: of the trial, so a paper-scale 11x11 run (about 23,500 steps) is one batch (the recording costs per batch).
TRACE_CAPACITY = 32768


@dataclass(frozen=True)
class RunWorld:
    """One run's obstacles and what the robot sees from each (cell, action)."""

    placement: Placement
    pictures: np.ndarray  # (n_cells, 4) picture id or -1
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


def _emit(
    sink, r, run_id, first_ep, last_ep, results, trace, recognitions, additions, scores, cursors
):
    """Hand episodes ``first_ep..last_ep-1`` of run ``r`` to the sink as one columnar batch."""
    if last_ep > first_ep:
        eps = slice(first_ep, last_ep)
        steps = results.steps[r, eps]
        n = (
            int(steps.sum()) if trace.record else 0
        )  # a sink without steps (records_steps False) gets none
        lo = cursors["rec"][r]  # recognitions and additions of the finished episodes only
        hi = lo + int(
            np.searchsorted(recognitions.episode[r, lo : int(recognitions.length[r])], last_ep)
        )
        rec = slice(lo, hi)
        table = scores["table"]  # relation scores of run r's recognitions, when asked for
        sc = (
            table[r, lo:hi].copy()
            if table is not None and scores["done"][r] >= hi
            else np.zeros((hi - lo, 0), np.float32)
        )
        alo = cursors["add"][r]
        ahi = alo + int(
            np.searchsorted(additions.episode[r, alo : int(additions.length[r])], last_ep)
        )
        add = slice(alo, ahi)
        cursors["rec"][r], cursors["add"][r] = hi, ahi
        sink.episodes(
            run=run_id,
            episode=np.arange(first_ep, last_ep, dtype=np.int32),
            steps=steps.astype(np.int32),
            states=trace.states[r, :n].copy(),
            actions=trace.actions[r, :n].copy(),
            rewards=trace.rewards[r, :n].copy(),
            flags=trace.flags[r, :n].copy(),
            recognitions={
                "episode": recognitions.episode[r, rec].astype(np.int32),
                "step": recognitions.step[r, rec].astype(np.int32),
                "state": recognitions.state[r, rec].astype(np.int32),
                "action": recognitions.action[r, rec].astype(np.int8),
                "picture": recognitions.picture[r, rec].astype(np.int16),
                "predicted": recognitions.predicted[r, rec].astype(np.int8),
                "true": recognitions.true[r, rec].astype(np.int8),
                "scores": sc,
            },
            unsafe_added={
                "episode": additions.episode[r, add].astype(np.int32),
                "step": additions.step[r, add].astype(np.int32),
                "state": additions.state[r, add].astype(np.int32),
                "action": additions.action[r, add].astype(np.int8),
                "source": additions.source[r, add].astype(np.int8),
            },
            summary={
                "collisions": results.collisions[r, eps].copy(),
                "return_": results.returns[r, eps].copy(),
                "reached_goal": results.reached_goal[r, eps].copy(),
                "prevented": results.prevented[r, eps].copy(),
                "epsilon": results.epsilon[r, eps].copy(),
                "greedy_optimal": results.greedy_optimal[r, eps].copy(),
            },
        )
    trace.length[r] = 0


def run_trials(  # noqa: PLR0915 (to split)
    layout: Layout,
    method: MethodSpec,
    runs: int,
    episodes: int,
    seed: int = 0,
    *,
    recogniser: Recogniser | None = None,
    sink: EpisodeSink | None = None,
    run_offset: int = 0,
    progress: bool = True,
    chunk_episodes: int = 100,
    trace_capacity: int = TRACE_CAPACITY,
    shared_support: bool = False,
) -> TrialResult:
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
    params = MethodParams.of(method)
    reasons_with_pictures = rules.reasons_with_pictures(params.safety)
    if reasons_with_pictures and recogniser is None:
        raise ValueError(f"method {method.name!r} reasons with pictures: pass a recogniser")
    geometry = build_geometry(layout)
    maze = MazeArrays.of(layout, geometry)
    n_obs = len(layout.obstacles)
    # each dangerous pair (eq. 4) is seen and joins A_d at most once a run
    n_dangerous = max(1, int((geometry.obstacle >= 0).sum()))
    record = sink is not None
    trace_steps = record and getattr(sink, "records_steps", True)

    worlds = [make_run_world(geometry, seed, run_offset + r) for r in range(runs)]
    sights = Sights(
        pictures=np.stack([w.pictures for w in worlds]).astype(np.int16),
        true_category=np.stack([w.true_category for w in worlds]).astype(np.int8)
        if n_obs
        else np.zeros((runs, 1), np.int8),
        predicted=np.zeros((runs, N_PICTURES), dtype=np.int8),
    )
    predicted = sights.predicted
    rng = np.array([run_seeds(seed, run_offset + r).agent for r in range(runs)], dtype=np.uint64)
    uses_recogniser = recogniser is not None and reasons_with_pictures

    def slot(r: int) -> int:
        return run_offset if shared_support else run_offset + r

    def support_accuracy(r: int) -> float:  # of run r's support set on the query pictures
        return np.count_nonzero(predicted[r] == PICTURE_CATEGORY) / N_PICTURES

    def start(r: int) -> None:
        if uses_recogniser:
            recogniser.start_run(slot(r), run_seeds(seed, run_offset + r).recogniser)
            predicted[r] = recogniser.predictions(slot(r))
            if sink is not None:
                sink.substitution(
                    run=run_offset + r,
                    episode=0,
                    step=0,
                    picture=-1,
                    category=-1,
                    position=-1,
                    support_accuracy=support_accuracy(r),
                )

    state = RunState.fresh(runs, layout.n_cells, layout.start, method.epsilon, rng)
    results = Results.zeros(runs, episodes)
    trace = Trace.empty(
        runs, max(trace_capacity, method.max_steps) if trace_steps else 1, trace_steps
    )
    recognitions = Recognitions.empty(runs, n_dangerous)
    additions = Additions.empty(runs, n_dangerous)
    substitution = Substitution.empty(runs)
    scores = {
        "table": None,
        "done": [0] * runs,
    }  # (runs, n_dangerous, n_categories) and rows filled a run
    cursors = {"rec": [0] * runs, "add": [0] * runs}
    emitted = [0] * runs
    status = np.zeros(runs, np.int64)
    want_scores = record and uses_recogniser

    def score_pending(r: int) -> None:
        if not want_scores:
            return
        lo, hi = scores["done"][r], int(recognitions.length[r])
        if hi > lo:
            got = np.asarray(
                recogniser.scores(slot(r), recognitions.picture[r, lo:hi].astype(np.int64)),
                np.float32,
            )
            if scores["table"] is None:
                scores["table"] = np.zeros((runs, n_dangerous, got.shape[1]), np.float32)
            scores["table"][r, lo:hi], scores["done"][r] = got, hi

    def emit(r: int) -> None:
        score_pending(r)
        done = int(state.episode[r])
        _emit(
            sink,
            r,
            run_offset + r,
            emitted[r],
            done,
            results,
            trace,
            recognitions,
            additions,
            scores,
            cursors,
        )
        emitted[r] = done

    def advance(pending: np.ndarray, limit: int) -> None:
        while pending.size:
            kernel.advance_batch(
                pending,
                limit,
                status,
                params,
                maze,
                sights,
                state,
                results,
                trace,
                recognitions,
                additions,
                substitution,
            )
            again = []
            for r in pending:
                r = int(r)
                why = int(
                    status[r]
                )  # numpy compares its ints with an IntEnum member slowly (~8 us)
                if why == Status.substitute:
                    score_pending(
                        r
                    )  # the recognitions so far, under the support set they were made with
                    ep, step = int(substitution.episode[r]), int(substitution.step[r])
                    pic, cat = int(substitution.picture[r]), int(substitution.category[r])
                    position = recogniser.learn_from_collision(slot(r), pic, cat)
                    predicted[r] = recogniser.predictions(slot(r))
                    if sink is not None:
                        sink.substitution(
                            run=run_offset + r,
                            episode=ep,
                            step=step,
                            picture=pic,
                            category=cat,
                            position=int(position),
                            support_accuracy=support_accuracy(r),
                        )
                    again.append(r)
                elif why == Status.flush:
                    emit(r)
                    again.append(r)
            pending = np.array(again, dtype=np.int64)

    limits = list(range(min(chunk_episodes, episodes), episodes, chunk_episodes)) + [episodes]
    bar = tqdm(
        total=runs * episodes,
        disable=not progress,
        unit="ep",
        desc=f"{method.name} {layout.name}",
        leave=False,
    )
    groups = (
        [np.array([r], np.int64) for r in range(runs)]
        if shared_support
        else [np.arange(runs, dtype=np.int64)]
    )
    try:
        for group in groups:
            for r in group:
                start(int(r))
            for limit in [episodes] if shared_support else limits:
                before = int(state.episode[group].sum())
                advance(group, limit)
                bar.update(int(state.episode[group].sum()) - before)
                if record and (
                    limit == episodes or not trace_steps
                ):  # else when the trace is full (flush)
                    for r in group:
                        emit(int(r))
    except Exception:
        raise
    except BaseException:  # Ctrl-C or SIGTERM: every finished episode goes to the sink first
        for r in range(runs) if record else ():
            with contextlib.suppress(Exception):  # a batch the signal cut in two is not sent again
                if emitted[r] < int(state.episode[r]):
                    emit(r)
        raise
    finally:
        bar.close()
    return TrialResult(
        layout,
        method,
        seed,
        results.steps,
        results.collisions,
        results.returns,
        results.reached_goal,
        results.prevented,
        results.greedy_optimal,
        results.epsilon,
        [w.placement for w in worlds],
    )
