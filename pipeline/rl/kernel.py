"""The batched trial kernel: many independent runs of Algorithm 1 (and the baselines) at once.

Each run's whole state (Q table, A_d, position, epsilon, random stream, counters: a
``structs.RunState``) lives in arrays with a leading run axis, so a run can pause and resume
exactly: at an episode limit (progress bars, long-term autonomy), when its step trace must be
flushed to the records, and after a misrecognition when its dynamic support set must substitute
the picture (the recogniser runs in Python, Algorithm 1 line 20). Runs advance in parallel with
``numba.prange``.

The step rules are ``rules.apply_action`` (the world and the safety layer) and
``policy.select_action`` / ``policy.td_update`` (the agent); nothing here re-implements them, and
nothing here tells safety methods apart.

The helpers above ``advance_run`` hold its rarer paths (logging a recognition or an A_d addition,
the step trace, an episode's end, pausing); they are plain numba calls, not inlined, which keeps
the step loop itself small.
"""

from __future__ import annotations

import numba as nb

# numba's OpenMP layer leaves its threads spinning after each parallel region; the recogniser's
# torch calls that follow a pause then fight them for the cores. The workqueue layer does not spin.
if nb.config.THREADING_LAYER == "default":
    nb.config.THREADING_LAYER = "workqueue"

from pipeline.rl.codes import Learner, Outcome, Status, StepFlag
from pipeline.rl.policy import greedy_path_is_optimal, max_allowed, select_action, td_update
from pipeline.rl.rules import apply_action, empty_added
from pipeline.rl.structs import Logs, Sights


@nb.njit(cache=True)
def _log_additions(additions, r, ep, t, added, n_added):
    """Append the ``n_added`` pairs that just joined A_d to run ``r``'s additions."""
    for k in range(n_added):
        i = additions.length[r]
        additions.episode[r, i] = ep
        additions.step[r, i] = t
        additions.state[r, i], additions.action[r, i], additions.source[r, i] = added[k]
        additions.length[r] = i + 1


@nb.njit(cache=True)
def _log_recognition(recognitions, r, ep, t, s, a, pic, predicted, true):
    """Append one recognition (the picture seen from ``(s, a)``) to run ``r``'s recognitions."""
    i = recognitions.length[r]
    recognitions.episode[r, i] = ep
    recognitions.step[r, i] = t
    recognitions.state[r, i] = s
    recognitions.action[r, i] = a
    recognitions.picture[r, i] = pic
    recognitions.predicted[r, i] = predicted
    recognitions.true[r, i] = true
    recognitions.length[r] = i + 1


@nb.njit(cache=True)
def _log_step(trace, r, s, a, rew, flags, reselected, truncated):
    """Append one step to run ``r``'s trace, with the agent's flags added to the world's."""
    if reselected:
        flags |= StepFlag.reselected
    if truncated:
        flags |= StepFlag.truncated
    i = trace.length[r]
    trace.states[r, i] = s
    trace.actions[r, i] = a
    trace.rewards[r, i] = rew
    trace.flags[r, i] = flags
    trace.length[r] = i + 1


@nb.njit(cache=True)
def _note_substitution(substitution, r, ep, t, pic, category):
    """Hand the picture misrecognised at step ``t`` to the runner (``Status.substitute``)."""
    substitution.episode[r] = ep
    substitution.step[r] = t
    substitution.picture[r] = pic
    substitution.category[r] = category


@nb.njit(cache=True)
def _end_episode(results, r, ep, t, col, ret, prev, e, flags, qr, ur, maze):
    """Write episode ``ep``'s outcome to run ``r``'s row of ``results``, including whether the
    greedy policy now walks an optimal path."""
    results.steps[r, ep] = t
    results.collisions[r, ep] = col
    results.returns[r, ep] = ret
    results.reached_goal[r, ep] = (flags & StepFlag.goal) != 0
    results.prevented[r, ep] = prev
    results.epsilon[r, ep] = e
    results.greedy_optimal[r, ep] = greedy_path_is_optimal(qr, ur, maze)


@nb.njit(cache=True)
def _resume(state, r):
    """Run ``r``'s scalars, which live in locals while it advances (``_pause`` puts them back):
    episode, step, cell, Sarsa's pending action and its reselected flag, the episode's
    collisions, prevented actions, epsilon and return so far."""
    return (
        state.episode[r],
        state.step[r],
        state.cell[r],
        state.pending_action[r],
        state.pending_reselected[r],
        state.collisions[r],
        state.prevented[r],
        state.epsilon[r],
        state.ep_return[r],
    )


@nb.njit(cache=True)
def _pause(state, r, ep, t, s, pend, pend_resel, col, prev, e, ret):
    """Put run ``r``'s scalars back into ``state`` (the inverse of ``_resume``)."""
    state.episode[r], state.step[r], state.cell[r] = ep, t, s
    state.pending_action[r], state.pending_reselected[r] = pend, pend_resel
    state.collisions[r], state.prevented[r] = col, prev
    state.epsilon[r], state.ep_return[r] = e, ret


@nb.njit(cache=True)
def advance_run(r, ep_limit, method, maze, sights, state, results, logs):
    """Advance run ``r`` until episode ``ep_limit`` or a pause; returns a ``Status``.

    ``method`` (``MethodParams``) and ``maze`` (``MazeArrays``) are shared by all runs; every
    array of ``sights`` (``Sights``), ``state`` (``RunState``), ``results`` (``Results``) and
    ``logs`` (``Logs``: the trace, recognitions, additions and substitution) has a leading run
    axis. One step (Algorithm 1 lines 3-25): choose ``a`` epsilon-greedily outside A_d (eqs. 7-8);
    apply it (``rules.apply_action``), reselecting while the recogniser prevents it; on a
    collision, constrained RL decays epsilon; update Q toward the Q-learning target (eq. 9,
    bootstrapping over the allowed actions Q') or the Sarsa target; log the step, the pictures
    seen and the pairs added to A_d. A misrecognised picture with a dynamic support set pauses
    the run (``Status.substitute``, its details in ``logs.substitution``); a full trace pauses
    it before an episode starts (``Status.flush``).
    """
    trace, recognitions, additions, substitution = logs
    capacity = trace.states.shape[1]
    added = empty_added()
    qr, ur = state.q[r], state.unsafe[r]
    sight = Sights(
        sights.pictures[r], sights.true_category[r], sights.predicted[r], sights.confident[r]
    )
    rng, sarsa = state.rng, method.learner == Learner.sarsa
    ep, t, s, pend, pend_resel, col, prev, e, ret = _resume(state, r)
    status = Status.limit
    while ep < ep_limit:
        if t == 0 and trace.record and trace.length[r] + method.max_steps > capacity:
            status = Status.flush
            break
        if sarsa and pend >= 0 and not ur[s, pend]:
            a = pend
            resel = pend_resel
        else:
            a, resel = select_action(qr[s], ur[s], e, rng, r)
        pend = -1
        while True:
            out, s2, rew, term, flags, pic, n_added = apply_action(
                s, a, method, maze, sight, ur, added
            )
            if n_added:
                _log_additions(additions, r, ep, t, added, n_added)
            if pic >= 0:
                true = sight.true_category[maze.obstacle[s, a]]
                _log_recognition(recognitions, r, ep, t, s, a, pic, sight.predicted[pic], true)
            if out != Outcome.prevented:
                break
            prev += 1
            resel = True
            a, _ = select_action(qr[s], ur[s], e, rng, r)
        if out == Outcome.collided:
            col += 1
            if method.constrained:
                e = max(method.epsilon_min, e - method.epsilon_decay)
        if term:
            target = rew
        elif sarsa:  # bootstrap from the next action, chosen now and taken next step
            pend, pend_resel = select_action(qr[s2], ur[s2], e, rng, r)
            target = rew + method.gamma * qr[s2, pend]
        else:  # Q-learning, eq. 9: bootstrap over the allowed actions Q'
            target = rew + method.gamma * max_allowed(qr[s2], ur[s2])
        td_update(qr, s, a, target, method.alpha)
        t += 1
        ret += rew
        end = term or t >= method.max_steps
        if trace.record:
            _log_step(trace, r, s, a, rew, flags, resel, end and not term)
        substitute = out == Outcome.collided and method.dynamic and pic >= 0
        if substitute:
            _note_substitution(
                substitution, r, ep, t - 1, pic, sight.true_category[maze.obstacle[s, a]]
            )
        if end:
            _end_episode(results, r, ep, t, col, ret, prev, e, flags, qr, ur, maze)
            # the next episode starts at the start cell with fresh counters
            ep, t, s, pend, col, prev, ret = ep + 1, 0, maze.start, -1, 0, 0, 0.0
        else:
            s = s2
        if substitute:
            status = Status.substitute
            break
    _pause(state, r, ep, t, s, pend, pend_resel, col, prev, e, ret)
    return status


@nb.njit(cache=True, parallel=True, nogil=True)  # the record writer runs meanwhile
def advance_batch(
    run_ids,
    ep_limit,
    status,
    method,
    maze,
    sights,
    state,
    results,
    trace,
    recognitions,
    additions,
    substitution,
):
    """``advance_run`` for every run in ``run_ids`` in parallel; writes its ``Status`` to
    ``status[r]``. A parallel loop takes records of arrays, not a record of records: the ``Logs``
    come in as their four parts (the runner passes ``*logs``)."""
    for k in nb.prange(run_ids.shape[0]):
        r = run_ids[k]
        logs = Logs(trace, recognitions, additions, substitution)
        status[r] = advance_run(r, ep_limit, method, maze, sights, state, results, logs)
