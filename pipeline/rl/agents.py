"""Tabular Q-learning and Sarsa agents for the Gymnasium environment (eqs. 7-9).

The agent's choices and updates are ``policy.select_action`` / ``policy.td_update``, the very
functions of the batched kernel; ``run_episode`` composes them with the environment in the same
order as ``kernel.advance_run``, so a seed gives the identical trajectory through both doors.
"""

from __future__ import annotations

import numpy as np

from pipeline.rl.codes import Learner, StepFlag, member
from pipeline.rl.methods import MethodSpec
from pipeline.rl.policy import max_allowed, select_action, td_update


class TabularAgent:
    def __init__(self, method: MethodSpec, n_states: int, stream_seed: int):
        self.method = method
        self.q = np.zeros((n_states, 4))
        self.rng = np.array([stream_seed], dtype=np.uint64)
        self.epsilon = method.epsilon

    def act(self, state: int, action_mask: np.ndarray) -> tuple[int, bool]:
        """epsilon-greedy with the safety guarantee (eqs. 7-8); returns (action, reselected)."""
        a, reselected = select_action(self.q[state], action_mask == 0, self.epsilon, self.rng, 0)
        return int(a), bool(reselected)

    def on_collision(self) -> None:
        if self.method.constrained:
            self.epsilon = max(self.method.epsilon_min, self.epsilon - self.method.epsilon_decay)

    def target(
        self, reward: float, next_state: int, terminated: bool, next_mask: np.ndarray
    ) -> float:
        """Q-learning's target of eq. 9 (bootstrap over Q', the actions outside A_d)."""
        if terminated:
            return reward
        return reward + self.method.gamma * max_allowed(self.q[next_state], next_mask == 0)

    def update(self, state: int, action: int, target: float) -> None:
        td_update(self.q, state, action, target, self.method.alpha)


def run_episode(env, agent: TabularAgent, seed: int | None = None) -> dict:
    """One episode through the Gymnasium API; returns the per-step arrays like the runner's sink."""
    sarsa = member(Learner, agent.method.learner) == Learner.sarsa
    s, info = env.reset(seed=seed)
    mask = info["action_mask"]
    states, actions, rewards, flags = [], [], [], []
    pending = None
    while True:
        if sarsa and pending is not None and mask[pending[0]]:
            a, resel = pending
        else:
            a, resel = agent.act(s, mask)
        pending = None
        while True:
            s2, r, terminated, truncated, info = env.step(a)
            if not info["prevented"]:
                break
            resel = True
            mask = info["action_mask"]
            a, _ = agent.act(s, mask)
        if info["collided"]:
            agent.on_collision()
        next_mask = info["action_mask"]
        if terminated or not sarsa:
            target = agent.target(r, s2, terminated, next_mask)
        else:
            pending = agent.act(s2, next_mask)
            target = r + agent.method.gamma * agent.q[s2, pending[0]]
        agent.update(s, a, target)
        states.append(s)
        actions.append(a)
        rewards.append(r)
        flags.append(info["flags"] | (StepFlag.reselected if resel else 0))
        s, mask = s2, next_mask
        if terminated or truncated:
            break
    return {
        "states": np.array(states, np.int32),
        "actions": np.array(actions, np.int8),
        "rewards": np.array(rewards, np.float32),
        "flags": np.array(flags, np.uint8),
    }
