"""The Gymnasium conventions of the safe-navigation environment (in the style of Farama Minigrid's
tests): registration on ``import pipeline`` (plain ``register()`` calls), ``check_env`` on every registered id, determinism,
the rgb_array picture, recognisers by name and the step limit."""

import subprocess
import sys
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from fakes import always_right
from gymnasium.utils.env_checker import check_env, data_equivalence

import pipeline
from pipeline import palette, registration
from pipeline.config.recognisers import recogniser_names
from pipeline.errors import ConfigError
from pipeline.rl import gym_render
from pipeline.rl.codes import StepFlag
from pipeline.rl.gym_env import SafeNavigationEnv
from pipeline.rl.methods import get_method, method_names
from pipeline.world.pictures import CATEGORIES

ROOT = Path(__file__).resolve().parents[1]
OUR_IDS = sorted(
    i for i, spec in gym.registry.items() if spec.entry_point == registration.ENTRY_POINT
)
N, E, S, W = 0, 1, 2, 3


def run_python(code: str) -> str:
    out = subprocess.run(
        [sys.executable, "-c", code], check=False, capture_output=True, text=True, cwd=ROOT
    )
    assert out.returncode == 0, out.stderr
    return out.stdout


def test_the_registered_ids_and_their_step_limit():
    assert (
        OUR_IDS
        == sorted(pipeline.ENV_IDS)
        == ["SafeNav-11x11-v0", "SafeNav-5x5-v0", "SafeNav-7x7-v0", "SafeNav-v0"]
    )
    for env_id in OUR_IDS:
        spec = gym.spec(env_id)
        assert spec.kwargs["method"] == registration.DEFAULT_METHOD
        assert spec.kwargs.get("registered_maze", "any") in env_id.replace("SafeNav-v0", "any")
        assert spec.max_episode_steps == get_method(registration.DEFAULT_METHOD).max_steps


def test_an_id_runs_the_maze_it_names():
    """A sized id refuses another maze (the id would name a maze it does not run); ``SafeNav-v0``
    takes any."""
    with pytest.raises(ValueError, match="SafeNav-5x5-v0 is the 5x5 maze.*SafeNav-v0"):
        gym.make("SafeNav-5x5-v0", maze="random:7x7:16:3")
    assert gym.make("SafeNav-7x7-v0", maze="7x7").unwrapped.layout.width == 7
    env = gym.make("SafeNav-v0", maze="random:7x7:16:3")
    assert (env.unwrapped.layout.width, env.unwrapped.layout.height) == (7, 7)
    assert gym.make("SafeNav-v0").unwrapped.layout.width == 5


def test_info_has_the_same_keys_after_reset_and_step():
    env = gym.make("SafeNav-5x5-v0")
    _, info = env.reset(seed=0)
    assert info["recognition"] is None
    assert set(env.step(S)[4]) == set(info)


def test_import_pipeline_registers_without_importing_the_environment_torch_or_fewshot():
    out = run_python(
        "import sys, pipeline, gymnasium\n"
        "print(sorted(i for i in gymnasium.registry if i.startswith('SafeNav')))\n"
        "print(sorted(m for m in ('pipeline.envs', 'torch', 'pipeline.fewshot') if m in sys.modules))\n"
        "env = gymnasium.make('SafeNav-5x5-v0'); env.reset(seed=0); env.step(1)\n"
        "print('torch' in sys.modules, 'pipeline.fewshot' in sys.modules)\n"
    )
    ids = sorted(pipeline.ENV_IDS + pipeline.ENV_IDS_3D)
    assert out.splitlines() == [str(ids), "[]", "False False"]


@pytest.mark.parametrize(
    "code",
    [
        "import gymnasium, pipeline\ngymnasium.make('SafeNav-7x7-v0')",  # Gymnasium first: registered at once
        "import gymnasium\ngymnasium.make('pipeline:SafeNav-7x7-v0')",  # the module:id form imports pipeline
        "import gymnasium.envs.registration as r, pipeline\nprint(r.registry['SafeNav-7x7-v0'].entry_point)",
    ],
)
def test_every_way_of_importing_registers(code):
    run_python(code)


def test_gymnasium_has_no_plugin_entry_points():
    """Why pyproject.toml declares no ``gymnasium.envs`` entry point: Gymnasium 1.x does not read
    them. Should a version load plugins again, this fails: then add
    ``[project.entry-points."gymnasium.envs"] __root__ = "pipeline.registration"``."""
    from gymnasium.envs import registration as gymnasium_registration

    assert not hasattr(gymnasium_registration, "load_plugin_envs") and not hasattr(
        gymnasium_registration, "load_env_plugins"
    )


@pytest.mark.parametrize("env_id", OUR_IDS)
def test_check_env_passes_for_every_registered_id(env_id):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        env = gym.make(env_id)
        check_env(env.unwrapped, skip_render_check=False)  # also makes one env per render mode
        env.close()


@pytest.mark.parametrize(
    "method, recogniser, options",
    [("fewshot", "oracle", None), ("fewshot_dss", "fixed_accuracy", {"p": 0.5})],
)
def test_check_env_passes_with_a_recogniser_by_name(method, recogniser, options):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        env = gym.make(
            "SafeNav-5x5-v0", method=method, recogniser=recogniser, recogniser_options=options
        )
        check_env(env.unwrapped, skip_render_check=False)


def scripted_actions(n=50, seed=5):
    return np.random.default_rng(seed).integers(0, 4, size=n).tolist()


@pytest.mark.parametrize(
    "method, recogniser",
    [("shield", None), ("ssrl", None), ("fewshot_dss", "fixed_accuracy"), ("qlearning", None)],
)
def test_same_seed_same_episode(method, recogniser):
    """Two environments, the same seed, 50 scripted steps: identical observations, rewards and infos
    (the fixed-accuracy recogniser draws its mistakes from the run's seed)."""
    envs = [gym.make("SafeNav-7x7-v0", method=method, recogniser=recogniser) for _ in range(2)]
    first = [env.reset(seed=42) for env in envs]
    assert data_equivalence(first[0], first[1], exact=True)
    saw = set()
    for a in scripted_actions():
        out = [env.step(a) for env in envs]
        assert data_equivalence(out[0], out[1], exact=True), a
        saw |= {k for k in ("prevented", "collided") if out[0][4][k]}
        if out[0][2] or out[0][3]:
            assert data_equivalence(envs[0].reset(), envs[1].reset(), exact=True)
    assert np.array_equal(envs[0].unwrapped.unsafe, envs[1].unwrapped.unsafe)
    assert "collided" in saw  # the script runs into obstacles


def test_rgb_array_picture():
    env = gym.make("SafeNav-5x5-v0", render_mode="rgb_array", tile_size=20)
    env.reset(seed=3)
    u = env.unwrapped
    layout, t = u.layout, 20

    def centre(cell, img):
        r, c = layout.cell(cell)
        return tuple(int(x) for x in img[r * t + t // 2, c * t + t // 2])

    img = env.render()
    strip = gym_render.legend_strip(5 * t).shape[0]
    assert img.shape == (5 * t + strip, 5 * t, 3) and img.dtype == np.uint8
    assert centre(layout.goal, img) == gym_render.GOAL_RGB == palette.rgb(palette.GOAL)
    assert centre(layout.start, img) == gym_render.ROBOT_RGB == palette.rgb(palette.ROBOT)
    for o, cell in enumerate(layout.obstacles):
        assert centre(cell, img) == gym_render.CATEGORY_RGB[u.world.true_category[o]]
    assert (
        not (img[: 5 * t] == gym_render.UNSAFE_RGB).all(axis=2).any()
    )  # the maze; the legend has one
    # 5x5: S X X . . -- moving east from the start runs into an obstacle: (0, E) joins A_d
    s, reward, *_ = env.step(E)
    assert (s, reward) == (0, -1.0) and u.unsafe[0, E]
    img = env.render()
    assert (
        tuple(int(x) for x in img[t // 2, t - 2])
        == gym_render.UNSAFE_RGB
        == palette.rgb(palette.UNSAFE)
    )  # east edge of cell 0
    assert tuple(int(x) for x in img[t // 2, 2]) == gym_render.START_RGB  # west edge: not in A_d
    assert centre(layout.start, img) == gym_render.ROBOT_RGB
    env.step(S)
    img = env.render()
    assert (
        centre(layout.start, img) == gym_render.START_RGB and centre(5, img) == gym_render.ROBOT_RGB
    )


def test_category_colours_are_distinct_and_apart_from_the_markers():
    colours = set(gym_render.CATEGORY_RGB)
    assert len(gym_render.CATEGORY_RGB) == len(CATEGORIES) == len(colours)
    assert not colours & {
        gym_render.GOAL_RGB,
        gym_render.ROBOT_RGB,
        gym_render.UNSAFE_RGB,
        gym_render.FREE_RGB,
        gym_render.START_RGB,
        gym_render.GRID_RGB,
    }


def test_the_legend_strip_names_every_colour_of_the_frame():
    """Below the maze: a swatch of each category, start, goal, A_d and robot colour, in a line
    or more (a narrow maze wraps it)."""
    for width in (60, 160, 400):
        strip = gym_render.legend_strip(width)
        assert strip.shape[1] == width
        found = {tuple(int(x) for x in px) for px in strip.reshape(-1, 3)}
        assert {colour for _, colour in gym_render.LEGEND} <= found
    assert [name for name, _ in gym_render.LEGEND][: len(CATEGORIES)] == list(CATEGORIES)


def test_ansi_text_grid():
    env = gym.make("SafeNav-5x5-v0", render_mode="ansi")
    env.reset(seed=3)
    env.step(S)
    text = env.render()
    rows = text.splitlines()
    cats = env.unwrapped.world.true_category
    assert rows[0] == "S" + str(cats[0]) + str(cats[1]) + ".."
    assert rows[1] == "R." + str(cats[2]) + ".."
    assert rows[4].endswith("G") and rows[5].startswith("step 1  |A_d| = 0")
    assert "0 chair" in rows[6]


def test_render_modes_and_their_errors():
    assert SafeNavigationEnv.metadata["render_modes"] == ["ansi", "rgb_array"]
    assert SafeNavigationEnv.metadata["render_fps"] > 0
    frames = gym.make(
        "SafeNav-5x5-v0", render_mode="rgb_array_list"
    )  # Gymnasium's RenderCollection
    frames.reset(seed=0)
    frames.step(S)
    assert [f.shape for f in frames.render()] == [
        (160 + gym_render.legend_strip(160).shape[0], 160, 3)
    ] * 2
    with pytest.raises(ValueError, match="render_mode='human'.*ansi, rgb_array"):
        SafeNavigationEnv("5x5", render_mode="human")
    with pytest.raises(ValueError, match="tile_size=4"):
        SafeNavigationEnv("5x5", tile_size=4)
    env = SafeNavigationEnv("5x5")
    env.reset(seed=0)
    with pytest.warns(UserWarning, match="without a render_mode"):
        assert env.render() is None


def test_recognisers_by_name_and_as_objects():
    env = gym.make("SafeNav-5x5-v0", method="fewshot", recogniser="oracle")
    assert type(env.unwrapped.recogniser).__name__ == "OracleRecogniser"
    env = gym.make(
        "SafeNav-5x5-v0",
        method="fewshot_dss",
        recogniser="fixed_accuracy",
        recogniser_options={"p": 0.25},
        substitution=3,
    )
    rec = env.unwrapped.recogniser
    assert (rec.p, rec.substitution_way, rec.carry_over) == (0.25, 3, False)
    obj = always_right()
    assert gym.make("SafeNav-5x5-v0", method="fewshot", recogniser=obj).unwrapped.recogniser is obj
    # methods that see no pictures build none (as the trials stage), but the name is still checked
    assert (
        gym.make("SafeNav-5x5-v0", method="ssrl", recogniser="relation_net").unwrapped.recogniser
        is None
    )


def test_recogniser_errors_say_what_to_pass():
    with pytest.raises(
        ValueError,
        match=r"unknown recogniser 'relnet'; expected one of " + ", ".join(recogniser_names()),
    ):
        gym.make("SafeNav-5x5-v0", method="fewshot", recogniser="relnet")
    with pytest.raises(
        ValueError,
        match=r"'fewshot' reasons with pictures and needs a recogniser: pass recogniser=<name>.*"
        + ", ".join(recogniser_names())
        + ".*recogniser='oracle'",
    ):
        gym.make("SafeNav-5x5-v0", method="fewshot")
    with pytest.raises(TypeError, match="not the name 'oracle'.*gymnasium.make"):
        SafeNavigationEnv("5x5", "fewshot", recogniser="oracle")
    with pytest.raises(ValueError, match="needs a recogniser: pass recogniser=<name>"):
        SafeNavigationEnv("5x5", "fewshot_dss")
    with pytest.raises(
        ConfigError, match=r"config key 'recogniser': p must lie in \[0, 1\], got 2"
    ):
        gym.make(
            "SafeNav-5x5-v0",
            method="fewshot",
            recogniser="fixed_accuracy",
            recogniser_options={"p": 2.0},
        )
    with pytest.raises(ConfigError, match=r"config key 'recogniser\.q'"):
        gym.make(
            "SafeNav-5x5-v0",
            method="fewshot",
            recogniser="fixed_accuracy",
            recogniser_options={"q": 1},
        )
    with pytest.raises(ValueError, match="recogniser_options go with a recogniser name"):
        gym.make(
            "SafeNav-5x5-v0",
            method="fewshot",
            recogniser=always_right(),
            recogniser_options={"p": 1},
        )


def test_relation_net_by_name_goes_through_the_stage_builder(tmp_path):
    """The same builder as the trials stage: its checks and messages (here: a checkpoint that is not there)."""
    with pytest.raises(ConfigError, match=r"config key 'recogniser'.*nowhere\.pt"):
        gym.make(
            "SafeNav-5x5-v0",
            method="fewshot",
            recogniser="relation_net",
            recogniser_options={
                "checkpoint": str(tmp_path / "nowhere.pt"),
                "images_dir": str(tmp_path),
            },
        )


@pytest.mark.skipif(
    not (ROOT / "datasets/images/manifest.csv").exists(),
    reason="needs datasets/images (make repro)",
)
def test_relation_net_by_name_builds_the_trained_recogniser(monkeypatch):
    monkeypatch.chdir(ROOT)
    env = gym.make(
        "SafeNav-5x5-v0", method="fewshot_dss", recogniser="relation_net", render_mode="rgb_array"
    )
    assert type(env.unwrapped.recogniser).__name__ == "RelationRecogniser"
    env.reset(seed=0)
    env.step(E)
    assert env.render().shape == (160 + gym_render.legend_strip(160).shape[0], 160, 3)


def test_time_limit_and_the_environments_own_truncation_agree():
    """Registered ``max_episode_steps`` = the method's ``max_steps``: with no prevented action the
    TimeLimit wrapper and the environment truncate on the same step."""
    env = gym.make("SafeNav-5x5-v0")
    env.reset(seed=0)
    for k in range(1, 201):
        _, _, term, trunc, info = env.step(W)  # against the border: the robot stays put
        assert trunc == (k == 200) and not term
    assert info["step"] == 200 and info["flags"] & StepFlag.truncated
    limit = get_method("fewshot").max_steps
    # a few-shot method prevents actions without a move; max_episode_steps=-1 keeps the paper's count
    env = gym.make("SafeNav-5x5-v0", method="fewshot", recogniser="oracle", max_episode_steps=-1)
    env.reset(seed=0)
    calls = 0
    while True:
        calls += 1
        *_, trunc, info = env.step(E if calls % 2 else W)  # east from S sees an obstacle: prevented
        if trunc:
            break
    assert info["step"] == limit and calls > limit


@pytest.mark.parametrize("name", method_names())
def test_every_method_keeps_the_registered_step_limit(name):
    """One ``max_episode_steps`` serves every method made through the ids: they all stop at 200."""
    assert get_method(name).max_steps == registration.MAX_EPISODE_STEPS


def test_rl_imports_neither_fewshot_nor_the_wiring():
    """The science packages stay independent (README "Layout"): the environment gets recognisers as
    objects; names are resolved by ``pipeline.envs`` (wiring, like the stages)."""
    import ast

    for path in (ROOT / "pipeline" / "rl").glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = (
                [a.name for a in node.names]
                if isinstance(node, ast.Import)
                else [node.module or ""]
                if isinstance(node, ast.ImportFrom)
                else []
            )
            for name in names:
                assert not name.startswith(
                    ("pipeline.fewshot", "pipeline.stages", "pipeline.envs")
                ), f"{path.name} imports {name}"
