"""The commands README and docs show work as written.

Every stage command in a fenced ``bash`` block (``python -m pipeline <stage> key=value ...``, with or
without ``.venv/bin/``) must compose into a checked config: the stage exists and every key it gives
is one the stage takes, with a value it allows (each point of a ``-m`` sweep). A command with a
placeholder (``<file>``, ``...``) is a pattern, not a command, and is left out, as is one that
names what docs/extending.md has the reader write first (``mine``). The sweep of
docs/extending.md runs as written, and prints what its comment says it does; so does every records
listing and replay that reads only the committed records sample (they work on a fresh clone).
"""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from pipeline.__main__ import available_stages
from pipeline.config.compose import load_config, sweep_points

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"```bash\n(.*?)```", re.S)
PLACEHOLDER = re.compile(r"<[\w. |-]+>|\.\.\.")
#: What docs/extending.md has the reader make first (``method=mine``, ``+experiment=mine``).
READER_MADE = re.compile(r"=mine\b")


def fenced_commands(doc: Path) -> list[list[str]]:
    """The commands of ``doc``'s ``bash`` blocks, continuation lines joined, comments dropped."""
    out = []
    for block in FENCE.findall(doc.read_text()):
        for line in block.replace("\\\n", " ").splitlines():
            if line.strip():
                out.append(shlex.split(line, comments=True))
    return out


def stage_commands() -> list[tuple[str, str, list[str]]]:
    """(where, stage, arguments) of every documented stage command without a placeholder."""
    found = []
    for doc in DOCS:
        for argv in fenced_commands(doc):
            if argv[:3] in (["python", "-m", "pipeline"], [".venv/bin/python", "-m", "pipeline"]):
                args = argv[3:]
                if args and not any(PLACEHOLDER.search(a) or READER_MADE.search(a) for a in args):
                    found.append((doc.relative_to(ROOT).as_posix(), args[0], args[1:]))
    return found


COMMANDS = stage_commands()


def test_the_docs_show_stage_commands():
    stages = {stage for _, stage, _ in COMMANDS}
    assert {"trials", "render", "meta_train", "accuracy", "replay", "report"} <= stages


@pytest.mark.parametrize(
    "where, stage, args", COMMANDS, ids=[f"{w}: {s} {' '.join(a)}" for w, s, a in COMMANDS]
)
def test_a_documented_stage_command_composes(where, stage, args):
    """Its stage exists and its keys compose into the stage's checked config (every value of a
    sweep); the command runs nothing here."""
    assert stage in available_stages(), f"{where}: no stage {stage!r}"
    overrides = [a for a in args if a not in ("-m", "--multirun")]
    points = sweep_points(overrides) if len(overrides) < len(args) else [overrides]
    for point in points:
        load_config(stage, [o for o in point if not o.startswith("hydra")])


def test_the_documented_sweep_prints_what_its_comment_says(tmp_path):
    """docs/extending.md's sweep, run as written from a folder of its own: four cells, and the
    record listing's collisions are the ones the comment names (shield's change with exploration,
    SSRL's do not)."""
    doc = ROOT / "docs" / "extending.md"
    commands = fenced_commands(doc)
    at = next(
        i for i, argv in enumerate(commands) if argv[2:] == ["pipeline.records", "runs/epsilon"]
    )
    sweep, listing = commands[at - 1], commands[at]
    (tmp_path / ".venv").symlink_to(ROOT / ".venv")
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    for argv in (sweep, listing):
        done = subprocess.run(
            argv, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600
        )
        assert done.returncode == 0, done.stderr[-3000:]
    collisions = dict(
        re.findall(r"runs/epsilon/(\w+_[\d.]+)/records\.mcap: .*?, (\d+) collisions", done.stdout)
    )
    assert collisions == {
        "shield_0.05": "36",
        "shield_0.3": "39",
        "ssrl_0.05": "21",
        "ssrl_0.3": "21",
    }
    comment = doc.read_text().split("runs/epsilon   #", 1)[1].splitlines()[0]
    assert "shield 36 and 39 collisions, SSRL 21 and 21" in comment


def sample_commands() -> list[tuple[str, list[str]]]:
    """(where, argv) of every documented records listing or replay that reads only committed files
    (the records sample, ``datasets/sample/``): they must run on a fresh clone."""
    found = []
    for doc in DOCS:
        for argv in fenced_commands(doc):
            tool = argv[2:3] == ["pipeline.records"] or argv[2:4] == ["pipeline", "replay"]
            paths = [a.split("=", 1)[-1] for a in argv[3:] if "/" in a]
            if tool and paths and all(p.startswith("datasets/sample/") for p in paths):
                found.append((doc.relative_to(ROOT).as_posix(), argv))
    return found


SAMPLE_COMMANDS = sample_commands()


def test_the_docs_show_commands_on_the_committed_sample():
    assert {where for where, _ in SAMPLE_COMMANDS} >= {"README.md", "docs/replay.md"}


@pytest.mark.parametrize(
    "where, argv", SAMPLE_COMMANDS, ids=[f"{w}: {' '.join(a[2:])}" for w, a in SAMPLE_COMMANDS]
)
def test_a_documented_command_on_the_sample_runs_as_written(where, argv, tmp_path):
    """Run from a folder holding the venv and the datasets (the venv activated, as README says:
    ``python`` is the venv's); what it writes (``replays/``) stays in that folder."""
    (tmp_path / ".venv").symlink_to(ROOT / ".venv")
    (tmp_path / "datasets").symlink_to(ROOT / "datasets")
    python = str(ROOT / ".venv" / "bin" / "python")
    command = [python if a in ("python", ".venv/bin/python") else a for a in argv]
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    done = subprocess.run(
        command, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 0, f"{where}: {' '.join(argv)}\n{done.stderr[-3000:]}"


#: The DVC commands that only read; each documented one runs on the checkout as written.
DVC_VIEWS = (["metrics", "show"], ["metrics", "diff"], ["params", "diff"], ["exp", "show"])
DVC = Path(sys.executable).with_name("dvc")
#: A terminal's width for the views: a laptop's full-screen terminal.
SCREEN = 160


def dvc_views() -> list[tuple[str, list[str]]]:
    """(where, argv) of every documented ``dvc`` command that only reads."""
    return [
        (doc.relative_to(ROOT).as_posix(), argv)
        for doc in DOCS
        for argv in fenced_commands(doc)
        if argv[:1] == ["dvc"] and argv[1:3] in DVC_VIEWS
    ]


DVC_VIEW_COMMANDS = dvc_views()


def test_the_docs_show_each_dvc_view():
    shown = {tuple(argv[1:3]) for _, argv in DVC_VIEW_COMMANDS}
    assert shown == set(map(tuple, DVC_VIEWS))


@pytest.fixture(scope="module")
def fresh_clone(tmp_path_factory) -> Path:
    """A clone of the last commit: what a new user has (the checkout's own edits left out)."""
    clone = tmp_path_factory.mktemp("clone") / "repo"
    subprocess.run(
        ["git", "clone", "-q", "--depth", "1", ROOT.as_uri(), str(clone)], check=True, timeout=300
    )
    return clone


def git_status(repo: Path) -> str:
    done = subprocess.run(
        ["git", "status", "--porcelain"], cwd=repo, capture_output=True, text=True
    )
    return done.stdout


@pytest.mark.parametrize(
    "where, argv", DVC_VIEW_COMMANDS, ids=[f"{w}: {' '.join(a)}" for w, a in DVC_VIEW_COMMANDS]
)
def test_a_documented_dvc_view_runs_on_a_fresh_clone_within_a_screen(where, argv, fresh_clone):
    """Each runs as written on a clone of the last commit, prints no line wider than a screen,
    and leaves ``git status`` empty."""
    env = {**os.environ, "COLUMNS": str(SCREEN), "DVC_NO_ANALYTICS": "1"}
    done = subprocess.run(
        [str(DVC), *argv[1:]], cwd=fresh_clone, env=env, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, f"{where}: {' '.join(argv)}\n{done.stderr[-3000:]}"
    widest = max((len(line) for line in done.stdout.splitlines()), default=0)
    assert widest <= SCREEN, f"{where}: {' '.join(argv)} prints {widest} columns\n{done.stdout}"
    assert git_status(fresh_clone) == ""


def test_dvc_exp_show_opens_with_the_headline():
    """The first columns of ``dvc exp show`` after the experiment's are the headline's keys, in
    the order the report writes them."""
    env = {**os.environ, "DVC_NO_ANALYTICS": "1"}
    done = subprocess.run(
        [str(DVC), "exp", "show", "--csv"], cwd=ROOT, env=env, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    header = done.stdout.splitlines()[0].split(",")
    headline = json.loads((ROOT / "reports" / "headline.json").read_text())
    keys = [
        f"{group}.{key}" if isinstance(values, dict) else group
        for group, values in headline.items()
        for key in (values if isinstance(values, dict) else [None])
    ]
    assert keys[:2] == ["accuracy.relation_net", "accuracy.protonet"]
    first = header.index(keys[0])
    assert header[first : first + len(keys)] == keys
