"""The batched trial kernel: many independent runs of Algorithm 1 (and the baselines) at once.

Each run's whole state (Q table, A_d, position, epsilon, random stream, counters) lives in arrays
with a leading run axis, so a run can pause and resume exactly: at an episode limit (progress
bars, long-term autonomy), when its step trace must be flushed to the records, and after a
misrecognition when its dynamic support set must substitute the picture (the recogniser runs in
Python, Algorithm 1 line 20). Runs advance in parallel with ``numba.prange``.

The step rules are ``rules.apply_action`` and ``policy.select_action``; nothing here re-implements
them.
"""
from __future__ import annotations

import numba as nb
import numpy as np

# numba's OpenMP layer leaves its threads spinning after each parallel region; the recogniser's
# torch calls that follow a pause then fight them for the two cores (measured: 36 ms instead of
# 4 ms per support-set column). The workqueue layer does not spin.
if nb.config.THREADING_LAYER == "default":
    nb.config.THREADING_LAYER = "workqueue"

from pipeline.rl.policy import greedy_path_is_optimal, max_allowed, select_action, td_update
from pipeline.rl.rules import COLLIDED, PREVENTED, apply_action
from pipeline.rl.sink import FLAG_RESELECTED, FLAG_TRUNCATED

LEARNER_Q = 0
LEARNER_SARSA = 1

STATUS_LIMIT = 0       # reached the requested episode limit (or finished all episodes)
STATUS_SUBSTITUTE = 1  # misrecognised picture waiting for the support set's substitution
STATUS_FLUSH = 2       # the step trace is full: emit the finished episodes, then resume


@nb.njit(cache=True)
def advance_run(r, ep_limit, params, iparams,
                next_cell, obstacle, ssrl_pairs,
                pictures, true_category, predicted,
                q, unsafe, rng,
                cur, eps, ep_ret,
                res_steps, res_col, res_ret, res_goal, res_prev, res_greedy, res_eps,
                trace_s, trace_a, trace_r, trace_f, trace_len,
                rec, rec_len, add, add_len, sub):
    """Advance run ``r`` until episode ``ep_limit`` or a pause; returns a STATUS_* code.

    params  = (gamma, alpha, epsilon_decay, epsilon_min)
    iparams = (learner, safety, recovery, constrained, dynamic, max_steps, start, goal,
               optimal_length, record)
    cur[r]  = (episode, step, state, pending_action, pending_reselected, collisions, prevented)
    rec[r, i] = (episode, step, state, action, picture, predicted, true)
    add[r, i] = (episode, step, state, action, source)
    sub[r]  = (episode, step, picture, category) of a pending substitution
    """
    gamma, alpha, eps_decay, eps_min = params[0], params[1], params[2], params[3]
    learner, safety, recovery, constrained = iparams[0], iparams[1], iparams[2] != 0, iparams[3] != 0
    dynamic, max_steps, start, goal = iparams[4] != 0, iparams[5], iparams[6], iparams[7]
    optimal_length, record = iparams[8], iparams[9] != 0
    capacity = trace_s.shape[1]
    added = np.empty((8, 3), dtype=np.int64)
    qr = q[r]
    ur = unsafe[r]
    pic_r = pictures[r]
    true_r = true_category[r]
    pred_r = predicted[r]
    # the run's scalars live in locals while it advances and go back to ``cur`` when it pauses
    ep, t, s, pend = cur[r, 0], cur[r, 1], cur[r, 2], cur[r, 3]
    pend_resel, col, prev = cur[r, 4] != 0, cur[r, 5], cur[r, 6]
    e, ret = eps[r], ep_ret[r]
    status = STATUS_LIMIT
    while ep < ep_limit:
        if t == 0 and record and trace_len[r] + max_steps > capacity:
            status = STATUS_FLUSH
            break
        if learner == LEARNER_SARSA and pend >= 0 and not ur[s, pend]:
            a = pend
            resel = pend_resel
        else:
            a, resel = select_action(qr[s], ur[s], e, rng, r)
        pend = -1
        while True:
            out, s2, rew, term, flags, pic, n_added = apply_action(
                s, a, next_cell, obstacle, ssrl_pairs, goal, pic_r, true_r, pred_r, ur,
                safety, recovery, constrained, added)
            for k in range(n_added):
                i = add_len[r]
                add[r, i, 0] = ep
                add[r, i, 1] = t
                add[r, i, 2] = added[k, 0]
                add[r, i, 3] = added[k, 1]
                add[r, i, 4] = added[k, 2]
                add_len[r] = i + 1
            if pic >= 0:
                i = rec_len[r]
                rec[r, i, 0] = ep
                rec[r, i, 1] = t
                rec[r, i, 2] = s
                rec[r, i, 3] = a
                rec[r, i, 4] = pic
                rec[r, i, 5] = pred_r[pic]
                rec[r, i, 6] = true_r[obstacle[s, a]]
                rec_len[r] = i + 1
            if out != PREVENTED:
                break
            prev += 1
            resel = True
            a, _ = select_action(qr[s], ur[s], e, rng, r)
        if out == COLLIDED:
            col += 1
            if constrained:
                e = max(eps_min, e - eps_decay)
        if term:
            target = rew
        elif learner == LEARNER_Q:
            target = rew + gamma * max_allowed(qr[s2], ur[s2])
        else:
            pend, pend_resel = select_action(qr[s2], ur[s2], e, rng, r)
            target = rew + gamma * qr[s2, pend]
        td_update(qr, s, a, target, alpha)
        t += 1
        ret += rew
        end = term or t >= max_steps
        if resel:
            flags |= FLAG_RESELECTED
        if end and not term:
            flags |= FLAG_TRUNCATED
        if record:
            i = trace_len[r]
            trace_s[r, i] = s
            trace_a[r, i] = a
            trace_r[r, i] = rew
            trace_f[r, i] = flags
            trace_len[r] = i + 1
        substitute = out == COLLIDED and dynamic and pic >= 0
        if substitute:
            sub[r, 0] = ep
            sub[r, 1] = t - 1
            sub[r, 2] = pic
            sub[r, 3] = true_r[obstacle[s, a]]
        if end:
            res_steps[r, ep] = t
            res_col[r, ep] = col
            res_ret[r, ep] = ret
            res_goal[r, ep] = (flags & 8) != 0
            res_prev[r, ep] = prev
            res_eps[r, ep] = e
            res_greedy[r, ep] = greedy_path_is_optimal(qr, ur, next_cell, obstacle, start, goal, optimal_length)
            ep += 1
            t = 0
            s = start
            pend = -1
            col = 0
            prev = 0
            ret = 0.0
        else:
            s = s2
        if substitute:
            status = STATUS_SUBSTITUTE
            break
    cur[r, 0], cur[r, 1], cur[r, 2], cur[r, 3] = ep, t, s, pend
    cur[r, 4], cur[r, 5], cur[r, 6] = (1 if pend_resel else 0), col, prev
    eps[r], ep_ret[r] = e, ret
    return status


@nb.njit(cache=True, parallel=True)
def advance_batch(run_ids, status, ep_limit, params, iparams,
                  next_cell, obstacle, ssrl_pairs,
                  pictures, true_category, predicted,
                  q, unsafe, rng,
                  cur, eps, ep_ret,
                  res_steps, res_col, res_ret, res_goal, res_prev, res_greedy, res_eps,
                  trace_s, trace_a, trace_r, trace_f, trace_len,
                  rec, rec_len, add, add_len, sub):
    """``advance_run`` for every run in ``run_ids`` in parallel; writes ``status[r]``."""
    for k in nb.prange(run_ids.shape[0]):
        r = run_ids[k]
        status[r] = advance_run(r, ep_limit, params, iparams, next_cell, obstacle, ssrl_pairs,
                                pictures, true_category, predicted, q, unsafe, rng, cur, eps, ep_ret,
                                res_steps, res_col, res_ret, res_goal, res_prev, res_greedy, res_eps,
                                trace_s, trace_a, trace_r, trace_f, trace_len, rec, rec_len, add,
                                add_len, sub)
