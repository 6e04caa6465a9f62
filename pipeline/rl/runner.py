"""Run many independent runs of one method on one maze (paper section 4.2.2: 100 runs x 500
episodes per cell), with optional recogniser in the loop and optional episode sink (records).

Usage::

    result = run_trials(load_layout("5x5"), get_method("ssrl"), runs=100, episodes=500, seed=0)
    result.summary()["collisions"]["mean"]
"""

from __future__ import annotations

import contextlib
import time

import numpy as np
from tqdm.auto import tqdm

from pipeline.rl import kernel, rules, trace_pool
from pipeline.rl.codes import Status
from pipeline.rl.methods import MethodSpec
from pipeline.rl.recogniser import Recogniser
from pipeline.rl.rng import run_seeds
from pipeline.rl.rules import Rule
from pipeline.rl.run_world import GRID, RunWorld, World, make_run_world
from pipeline.rl.sink import EpisodeSink
from pipeline.rl.structs import (
    Logs,
    MazeArrays,
    MethodParams,
    Results,
    RunState,
    Sights,
    Trace,
)
from pipeline.rl.trace_pool import TRACE_CAPACITY
from pipeline.rl.trial_result import TrialResult
from pipeline.world.geometry import Geometry, build_geometry
from pipeline.world.maze import Layout

__all__ = ["RunWorld", "Trial", "make_run_world", "run_trials"]

#: A recording sink gets every run's finished episodes at least every this many episodes (and when
#: a run's step trace is full): with the writer's flush_seconds, what a killed run keeps.
EMIT_EVERY = 500


class Trial:
    """One call of :func:`run_trials`: the kernel's buffers for all its runs, and the Python side
    of the loop (the recogniser's support-set substitutions, Algorithm 1 line 20, and handing
    finished episodes to the sink)."""

    def __init__(
        self,
        layout: Layout,
        method: MethodSpec,
        *,
        runs: int,
        episodes: int,
        seed: int,
        recogniser: Recogniser | None,
        sink: EpisodeSink | None,
        run_offset: int,
        trace_capacity: int,
        shared_support: bool,
        world: World = GRID,
        rule: Rule = Rule.paper,
        threshold: float = 0.5,
    ) -> None:
        if runs < 1:
            raise ValueError(f"runs={runs}: must be >= 1")
        if episodes < 1:
            raise ValueError(f"episodes={episodes}: must be >= 1")
        self.params = MethodParams.of(method, rule)
        self.rule, self.threshold = Rule(self.params.rule), float(threshold)
        reasons_with_pictures = rules.reasons_with_pictures(self.params.safety)
        if reasons_with_pictures and recogniser is None:
            raise ValueError(f"method {method.name!r} reasons with pictures: pass a recogniser")
        self.layout, self.method, self.seed = layout, method, seed
        self.runs, self.episodes, self.run_offset = runs, episodes, run_offset
        self.recogniser, self.sink, self.shared_support = recogniser, sink, shared_support
        self.asks_recogniser = recogniser is not None and reasons_with_pictures
        self.record = sink is not None
        self.trace_steps = self.record and getattr(sink, "records_steps", True)
        self.want_scores = self.record and self.asks_recogniser
        geometry = build_geometry(layout)
        self.maze = MazeArrays.of(layout, geometry)
        self.world = world
        self.worlds = [world.run_world(geometry, seed, run_offset + r) for r in range(runs)]
        self.picture_category = np.asarray(world.picture_category)
        self.seen_category = [self.picture_category[w.seen] for w in self.worlds]
        self._allocate(geometry, trace_capacity)

    def _allocate(self, geometry: Geometry, trace_capacity: int) -> None:
        """The kernel's arrays (``structs.py``) and the per-run cursors of what was handed over."""
        runs, layout, method = self.runs, self.layout, self.method
        # each dangerous pair (eq. 4) is seen and joins A_d at most once a run
        self.n_dangerous = max(1, int((geometry.obstacle >= 0).sum()))
        n_pictures = max(1, len(self.picture_category))
        self.sights = Sights(
            pictures=np.stack([w.pictures for w in self.worlds]).astype(np.int16),
            true_category=np.stack([w.true_category for w in self.worlds]).astype(np.int8)
            if len(layout.obstacles)
            else np.zeros((runs, 1), np.int8),
            predicted=np.zeros((runs, n_pictures), dtype=np.int8),
            confident=np.zeros((runs, n_pictures), dtype=np.bool_),
        )
        seeds = [run_seeds(self.seed, self.run_offset + r).agent for r in range(runs)]
        rng = np.array(seeds, dtype=np.uint64)
        self.state = RunState.fresh(runs, layout.n_cells, layout.start, method.epsilon, rng)
        self.results = Results.zeros(runs, self.episodes)
        capacity = max(trace_capacity, method.max_steps)
        recording = self.trace_steps  # else a trace of one step that the kernel never writes
        trace = trace_pool.borrow(runs, capacity) if recording else Trace.empty(runs, 1, False)
        self.logs = Logs.empty(trace, runs, self.n_dangerous)
        self.status = np.zeros(runs, np.int64)
        self.score_table = None  # (runs, n_dangerous, n_categories) relation scores, when asked for
        self.scored = [0] * runs  # recognitions of each run with their scores in score_table
        self.handed_recognitions = [0] * runs  # rows already in a batch, per run
        self.handed_additions = [0] * runs
        self.emitted = [0] * runs  # episodes already in a batch, per run
        self.kernel_seconds = 0.0  # wall seconds inside kernel.advance_batch

    def slot(self, r: int) -> int:
        """The recogniser slot of run ``r`` (one slot for all runs with a shared support set)."""
        return self.run_offset if self.shared_support else self.run_offset + r

    def support_accuracy(self, r: int) -> float:
        """Accuracy of run ``r``'s current support set on the pictures the run can meet (the
        grid's 40 query pictures; the robot's live pictures of the run)."""
        seen = self.worlds[r].seen
        right = np.count_nonzero(self.sights.predicted[r, seen] == self.seen_category[r])
        return right / max(1, len(seen))

    def answer(self, r: int) -> None:
        """Run ``r``'s recogniser answers under its current support set: the predicted category of
        every picture and, under the open-set rule, whether its top score reaches the threshold."""
        self.sights.predicted[r] = self.recogniser.predictions(self.slot(r))
        if self.rule == Rule.open_set:
            seen = self.worlds[r].seen
            scores = np.asarray(self.recogniser.scores(self.slot(r), seen))
            self.sights.confident[r, seen] = scores.max(axis=1) >= self.threshold

    def start(self, r: int) -> None:
        """Give run ``r`` its recogniser (fresh or carried-over support set) and its answers."""
        if not self.asks_recogniser:
            return
        seed = run_seeds(self.seed, self.run_offset + r).recogniser
        self.recogniser.start_run(self.slot(r), seed)
        self.answer(r)
        self._tell_substitution(r, episode=0, step=0, picture=-1, category=-1, position=-1)

    def _tell_substitution(self, r: int, **where) -> None:
        if self.sink is not None:
            self.sink.substitution(
                run=self.run_offset + r, **where, support_accuracy=self.support_accuracy(r)
            )

    def substitute(self, r: int) -> None:
        """Run ``r`` paused on a misrecognised picture: substitute it into the support set."""
        self.score_pending(r)  # the recognitions so far, under the support set they were made with
        sub = self.logs.substitution
        picture, category = int(sub.picture[r]), int(sub.category[r])
        position = self.recogniser.learn_from_collision(self.slot(r), picture, category)
        self.answer(r)
        self._tell_substitution(
            r,
            episode=int(sub.episode[r]),
            step=int(sub.step[r]),
            picture=picture,
            category=category,
            position=int(position),
        )

    def score_pending(self, r: int) -> None:
        """Relation scores of run ``r``'s recognitions not yet scored (only when recording)."""
        if not self.want_scores:
            return
        recognitions = self.logs.recognitions
        lo, hi = self.scored[r], int(recognitions.length[r])
        if hi > lo:
            pictures = recognitions.picture[r, lo:hi].astype(np.int64)
            got = np.asarray(self.recogniser.scores(self.slot(r), pictures), np.float32)
            if self.score_table is None:
                self.score_table = np.zeros((self.runs, self.n_dangerous, got.shape[1]), np.float32)
            self.score_table[r, lo:hi], self.scored[r] = got, hi

    def emit(self, r: int) -> None:
        """Hand run ``r``'s finished episodes not yet handed over to the sink as one batch."""
        self.score_pending(r)
        done = int(self.state.episode[r])
        if done > self.emitted[r]:
            self.sink.episodes(**self._batch(r, self.emitted[r], done))
        self.logs.trace.length[r] = 0
        self.emitted[r] = done

    def _rows(self, table, r: int, handed: list[int], last_ep: int) -> slice:
        """Rows of ``table`` (recognitions or additions) of run ``r``'s episodes before
        ``last_ep`` not yet handed over; marks them handed."""
        lo = handed[r]
        hi = lo + int(np.searchsorted(table.episode[r, lo : int(table.length[r])], last_ep))
        handed[r] = hi
        return slice(lo, hi)

    def _batch(self, r: int, first_ep: int, last_ep: int) -> dict:
        """Episodes ``first_ep..last_ep-1`` of run ``r`` as the sink's columnar batch (sink.py)."""
        results, (trace, recognitions, additions, _) = self.results, self.logs
        eps = slice(first_ep, last_ep)
        steps = results.steps[r, eps]
        n = int(steps.sum()) if trace.record else 0  # a sink without steps gets none
        rec = self._rows(recognitions, r, self.handed_recognitions, last_ep)
        add = self._rows(additions, r, self.handed_additions, last_ep)
        table = self.score_table
        scores = (
            table[r, rec].copy()
            if table is not None and self.scored[r] >= rec.stop
            else np.zeros((rec.stop - rec.start, 0), np.float32)
        )
        return dict(
            run=self.run_offset + r,
            episode=np.arange(first_ep, last_ep, dtype=np.int32),
            steps=steps.astype(np.int32),
            states=trace.states[r, :n].copy(),
            actions=trace.actions[r, :n].copy(),
            rewards=trace.rewards[r, :n].copy(),
            flags=trace.flags[r, :n].copy(),
            recognitions={**_sink_columns(recognitions, r, rec), "scores": scores},
            unsafe_added=_sink_columns(additions, r, add),
            summary={
                "collisions": results.collisions[r, eps].copy(),
                "return_": results.returns[r, eps].copy(),
                "reached_goal": results.reached_goal[r, eps].copy(),
                "prevented": results.prevented[r, eps].copy(),
                "epsilon": results.epsilon[r, eps].copy(),
                "greedy_optimal": results.greedy_optimal[r, eps].copy(),
            },
        )

    def advance(self, pending: np.ndarray, limit: int, bar) -> None:
        """Advance the runs ``pending`` to episode ``limit``, serving their pauses on the way; the
        progress ``bar`` moves whenever the kernel returns (a pause too: from the first second)."""
        while pending.size:
            before = int(self.state.episode[pending].sum())
            started = time.perf_counter()
            kernel.advance_batch(
                pending,
                limit,
                self.status,
                self.params,
                self.maze,
                self.sights,
                self.state,
                self.results,
                *self.logs,
            )
            self.kernel_seconds += time.perf_counter() - started
            bar.update(int(self.state.episode[pending].sum()) - before)
            again = []
            for r in pending:
                r = int(r)
                why = int(self.status[r])  # numpy compares its ints with an IntEnum slowly
                if why == Status.substitute:
                    self.substitute(r)
                    again.append(r)
                elif why == Status.flush:
                    self.emit(r)
                    again.append(r)
            pending = np.array(again, dtype=np.int64)

    def run(self, *, progress: bool, chunk_episodes: int) -> TrialResult:
        """Every run to the last episode in chunks of ``chunk_episodes``: all runs at once
        (independent runs), or one after another (shared support set)."""
        runs, episodes = self.runs, self.episodes
        limits = list(range(min(chunk_episodes, episodes), episodes, chunk_episodes))
        limits += [episodes]
        groups = (
            [np.array([r], np.int64) for r in range(runs)]
            if self.shared_support
            else [np.arange(runs, dtype=np.int64)]
        )
        desc = f"{self.method.name} {self.layout.name}"
        bar = tqdm(total=runs * episodes, disable=not progress, unit="ep", desc=desc, leave=False)
        try:
            for group in groups:
                self._run_group(group, limits, bar)
        except Exception:
            raise
        except BaseException:  # Ctrl-C or SIGTERM: every finished episode goes to the sink first
            self._emit_finished()
            raise
        finally:
            bar.close()
            trace_pool.give_back(self.logs.trace)  # to this process's next trial of its shape
        return self.result()

    def _run_group(self, group: np.ndarray, limits: list[int], bar) -> None:
        for r in group:
            self.start(int(r))
        for limit in limits:
            self.advance(group, limit, bar)
            # finished episodes are handed over every EMIT_EVERY episodes (a trace also when full)
            if self.record and (limit % EMIT_EVERY == 0 or limit == self.episodes):
                for r in group:
                    self.emit(int(r))

    def _emit_finished(self) -> None:
        """After an interruption: hand every run's finished episodes not yet handed over."""
        for r in range(self.runs) if self.record else ():
            with contextlib.suppress(Exception):  # a batch the signal cut in two is not sent again
                if self.emitted[r] < int(self.state.episode[r]):
                    self.emit(r)

    def result(self) -> TrialResult:
        placements = [w.placement for w in self.worlds]
        args = (self.layout, self.method, self.seed, self.results, placements, self.kernel_seconds)
        return TrialResult.of(*args)


#: The sink's integer width of a logged column (``sink.py``); a column not named here is int8.
SINK_WIDTHS = {"episode": np.int32, "step": np.int32, "state": np.int32, "picture": np.int16}


def _sink_columns(log, r: int, rows: slice) -> dict:
    """Rows ``rows`` of run ``r``'s ``log`` (``Recognitions``, ``Additions``) as the sink's columns."""
    names = log._fields[:-1]  # all but ``length``
    return {
        name: getattr(log, name)[r, rows].astype(SINK_WIDTHS.get(name, np.int8)) for name in names
    }


def run_trials(
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
    world: World = GRID,
    rule: Rule = Rule.paper,
    threshold: float = 0.5,
) -> TrialResult:
    """Run ``runs`` independent runs (ids ``run_offset ..``) of ``episodes`` episodes each.

    Run ``r`` draws its obstacle placement, its agent's random stream and its recogniser seed from
    ``run_seeds(seed, r)``, so a run's outcome does not depend on the batch it is in.

    ``shared_support`` (long-term autonomy, paper Figure 10): the runs are consecutive experiments
    of one robot. They execute one after another and all use recogniser slot ``run_offset``, so a
    recogniser built to carry its support set over hands each run the set the previous run left.
    Q, A_d and the obstacle placement are still fresh for every run.

    ``world`` (:mod:`.run_world`): what each run meets, the grid (default) or the camera robot
    (``pipeline.robot.world.RobotWorld``); ``rule`` (:class:`~pipeline.rl.rules.Rule`) and
    ``threshold``: when a picture stops the robot (the threshold only under ``Rule.open_set``).
    """
    trial = Trial(
        layout,
        method,
        runs=runs,
        episodes=episodes,
        seed=seed,
        recogniser=recogniser,
        sink=sink,
        run_offset=run_offset,
        trace_capacity=trace_capacity,
        shared_support=shared_support,
        world=world,
        rule=rule,
        threshold=threshold,
    )
    return trial.run(progress=progress, chunk_episodes=chunk_episodes)
