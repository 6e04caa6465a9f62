"""The camera robot's pixel observations (``obs_type`` of ``SafeNav3D-*``): Gymnasium's
``check_env`` in every mode, observations in their space and the same for a seed, the default
observation unchanged (the grid's cell), the pixels the camera's picture from where the robot
stands, and an unknown ``obs_type`` refused."""

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.utils.env_checker import check_env, data_equivalence

import pipeline  # noqa: F401  (registers the ids)
from pipeline.robot.env import OBS_TYPES, SafeNavigation3DEnv
from pipeline.robot.live_world import PICTURE_SIZE
from pipeline.robot.sim import RobotSim

PIXELS = spaces.Box(0, 255, (PICTURE_SIZE, PICTURE_SIZE, 3), np.uint8)
PIXEL_TYPES = [t for t in OBS_TYPES if t != "state"]
#: The default observations 20-39 of :func:`scripted` (the robot leaving the start's corner).
CELLS_20_TO_40 = [0, 5, 6, 5, 6, 11, 12, 17, 17, 12, 17, 17, 18, 17, 12, 12, 17, 18, 23, 23]
SEEING = {"method": "fewshot_dss", "recogniser": "fixed_accuracy", "recogniser_options": {"p": 0.5}}


def scripted(env, seed: int = 3, steps: int = 60) -> list[tuple]:
    """``(observation, info)`` of a seeded reset and ``steps`` steps, each an allowed action drawn
    with ``seed``; a finished episode is followed by the next (``reset()``)."""
    choose = np.random.default_rng(seed)
    obs, info = env.reset(seed=seed)
    out = [(obs, info)]
    for _ in range(steps):
        action = choose.choice(np.flatnonzero(info["action_mask"]))
        obs, _, terminated, truncated, info = env.step(int(action))
        out.append((obs, info))
        if terminated or truncated:
            obs, info = env.reset()
            out.append((obs, info))
    return out


def pixels_of(obs) -> np.ndarray:
    return obs["pixels"] if isinstance(obs, dict) else obs


def test_the_observation_types_are_gymnasiums_state_and_pixels():
    assert OBS_TYPES == ("state", "pixels", "state+pixels")
    spaces_of = {t: gym.make("SafeNav3D-5x5-v0", obs_type=t).observation_space for t in OBS_TYPES}
    assert (
        spaces_of["state"] == gym.make("SafeNav3D-5x5-v0").observation_space == spaces.Discrete(25)
    )
    assert spaces_of["pixels"] == PIXELS
    assert spaces_of["state+pixels"] == spaces.Dict(state=spaces.Discrete(25), pixels=PIXELS)


def test_the_default_observation_is_the_grids_cell():
    """Without ``obs_type`` the robot observes its cell, as before pixels existed: the grid's
    observations and rewards, step for step (the robot's moves have the grid's outcomes)."""
    robot = scripted(gym.make("SafeNav3D-5x5-v0"))
    grid = scripted(gym.make("SafeNav-5x5-v0"))
    assert [obs for obs, _ in robot] == [obs for obs, _ in grid]
    assert all(type(obs) is int for obs, _ in robot)
    assert [obs for obs, _ in robot[20:40]] == CELLS_20_TO_40


@pytest.mark.parametrize("obs_type", PIXEL_TYPES)
def test_check_env_passes_in_the_pixel_modes(obs_type):
    env = gym.make("SafeNav3D-5x5-v0", obs_type=obs_type, render_mode="rgb_array", **SEEING)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped)
    assert [str(w.message) for w in caught] == []
    env.close()


@pytest.mark.parametrize("obs_type", PIXEL_TYPES)
def test_pixel_observations_lie_in_their_space_and_repeat_for_a_seed(obs_type):
    """Two environments, one seed, the same steps: the same observations, byte for byte; the
    state part is the default mode's observation."""
    first = scripted(gym.make("SafeNav3D-5x5-v0", obs_type=obs_type, **SEEING))
    second = scripted(gym.make("SafeNav3D-5x5-v0", obs_type=obs_type, **SEEING))
    cells = scripted(gym.make("SafeNav3D-5x5-v0", **SEEING))
    space = gym.make("SafeNav3D-5x5-v0", obs_type=obs_type).observation_space
    assert all(space.contains(obs) for obs, _ in first)
    assert all(data_equivalence(a, b) for (a, _), (b, _) in zip(first, second, strict=True))
    if obs_type == "state+pixels":
        assert [obs["state"] for obs, _ in first] == [obs for obs, _ in cells]
    assert len({pixels_of(obs).tobytes() for obs, _ in first}) > 10  # the view changes as it moves


def test_the_pixels_are_the_camera_from_the_cell_centre_and_the_live_picture_when_taken():
    """Every step has its picture: from the centre of the robot's cell toward its heading (north
    at the start), rendered here by a robot of its own; on a step that took a live picture, that
    picture itself (``info["camera"]``)."""
    env = gym.make("SafeNav3D-5x5-v0", obs_type="state+pixels", **SEEING)
    steps = scripted(env)
    robot = env.unwrapped
    sim = RobotSim(robot.layout, robot.world.placement)
    sim.place(robot.layout.start, 0)
    assert np.array_equal(steps[0][0]["pixels"], sim.picture(PICTURE_SIZE))
    live = [(obs, info) for obs, info in steps if info.get("camera") is not None]
    assert len(live) >= 5
    assert all(np.array_equal(obs["pixels"], info["camera"]) for obs, info in live)
    assert sum(info.get("camera") is None for _, info in steps) > len(live)
    sim.close()


def test_an_observation_handed_out_is_the_agents_to_change():
    env = gym.make("SafeNav3D-5x5-v0", obs_type="pixels")
    obs, _ = env.reset(seed=0)
    obs[:] = 0
    again, _ = env.reset(seed=0)
    assert again.any()


@pytest.mark.parametrize("obs_type", ["rgb", "cell", "Pixels", None, 3, ("state",)])
def test_an_unknown_obs_type_is_refused_in_one_line_naming_the_choices(obs_type):
    with pytest.raises(ValueError) as refused:
        gym.make("SafeNav3D-5x5-v0", obs_type=obs_type)
    assert str(refused.value) == (
        f"obs_type={obs_type!r}: expected one of state, pixels, state+pixels"
    )


def test_a_maze_the_camera_cannot_draw_is_refused_for_pixels():
    with pytest.raises(ValueError, match="obs_type='pixels': maze .* 5,000 obstacles"):
        SafeNavigation3DEnv("random:100x100:5000:0", obs_type="pixels")
