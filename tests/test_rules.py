"""Scripted episodes with exact returns (in the style of ai-safety-gridworlds' tests)."""

import pytest
from fakes import always_right, always_wrong

from pipeline.rl.codes import StepFlag
from pipeline.rl.gym_env import SafeNavigationEnv
from pipeline.world.maze import parse_layout

# S . X       cells 0 1 2
# . . G             3 4 5
LAYOUT = parse_layout("S.X\n..G\n")
N, E, S, W = 0, 1, 2, 3


def play(method, actions, recogniser=None):
    env = SafeNavigationEnv(LAYOUT, method, recogniser=recogniser)
    env.reset(seed=0)
    trace = []
    for a in actions:
        s, r, term, trunc, info = env.step(a)
        trace.append((s, r, term, info["flags"], info["prevented"]))
        if term or trunc:
            break
    return env, trace


def test_goal_path_returns_plus_one():
    env, trace = play("qlearning", [S, E, E])
    assert [t[:3] for t in trace] == [(3, 0.0, False), (4, 0.0, False), (5, 1.0, True)]
    assert trace[-1][3] == StepFlag.goal


def test_move_off_grid_stays_put_without_penalty():
    env, trace = play("qlearning", [N, W, S])
    assert [t[:3] for t in trace] == [(0, 0.0, False), (0, 0.0, False), (3, 0.0, False)]


def test_collision_ends_the_episode_without_self_recovery():
    env, trace = play("qlearning", [E, E, S])
    assert [t[:3] for t in trace] == [(1, 0.0, False), (1, -1.0, True)]
    assert trace[-1][3] == StepFlag.collided
    assert not env.unsafe.any()  # plain Q-learning learns no unsafe set


@pytest.mark.parametrize("method", ["shield", "ssrl"])
def test_self_recovery_reverts_and_the_episode_goes_on(method):
    env, trace = play(method, [E, E, S, E])
    assert [t[:3] for t in trace] == [
        (1, 0.0, False),
        (1, -1.0, False),
        (4, 0.0, False),
        (5, 1.0, True),
    ]
    assert sum(t[1] for t in trace) == 0.0
    assert trace[1][3] == StepFlag.collided | StepFlag.recovered
    assert env.unsafe[1, E]
    # SSRL also marks the obstacle's other free neighbour (cell 5, moving north)
    assert env.unsafe[5, N] == (method == "ssrl")


def test_constrained_rl_ends_at_first_violation():
    env, trace = play("constrained", [E, E])
    assert trace[-1][:3] == (1, -1.0, True)


def test_fewshot_recognition_prevents_the_action_without_a_step():
    env, trace = play("fewshot", [E, E, S, E], recogniser=always_right())
    assert trace[1] == (1, 0.0, False, 0, True)  # prevented, same cell, no reward
    assert env.unsafe[1, E] and env.t == 3
    assert sum(t[1] for t in trace) == 1.0


def test_fewshot_misrecognition_collides_and_learns():
    env, trace = play("fewshot", [E, E, E], recogniser=always_wrong())
    assert trace[1][:4] == (1, -1.0, False, StepFlag.collided | StepFlag.recovered)
    assert env.unsafe[1, E]
    assert env.action_mask(1).tolist() == [1, 0, 1, 1]


def test_gym_check_env_passes_for_every_registered_maze():
    import gymnasium as gym
    from gymnasium.utils.env_checker import check_env

    for name in ("5x5", "7x7", "11x11"):
        env = gym.make(f"SafeNav-{name}-v0")
        check_env(env.unwrapped, skip_render_check=True)
    check_env(
        SafeNavigationEnv("5x5", "fewshot", recogniser=always_wrong()), skip_render_check=True
    )


def test_env_rejects_bad_input():
    with pytest.raises(ValueError, match="needs a recogniser|pass a recogniser"):
        SafeNavigationEnv("5x5", "fewshot")
    env = SafeNavigationEnv("5x5", "shield")
    env.reset(seed=1)
    with pytest.raises(ValueError, match="outside Discrete"):
        env.step(7)


def test_codes_accept_config_strings_and_members():
    from pipeline.rl.codes import Learner, member
    from pipeline.rl.rules import Safety

    assert member(Safety, "ssrl") is Safety.ssrl and member(Safety, Safety.ssrl) is Safety.ssrl
    assert member(Learner, "sarsa") is Learner.sarsa
    with pytest.raises(ValueError, match="expected one of none, shield, ssrl, fewshot"):
        member(Safety, "nope")


def test_only_the_rules_tell_safety_methods_apart():
    """Adding a safety method touches codes.py (its Safety member) and rules.py (its branch), not
    the kernel, runner or env."""
    from pathlib import Path

    import pipeline.rl as rl

    for name in ("kernel.py", "runner.py", "gym_env.py", "agents.py", "structs.py"):
        src = (Path(rl.__file__).parent / name).read_text(encoding="utf-8")
        assert "Safety." not in src and ".uses_recogniser" not in src, name
