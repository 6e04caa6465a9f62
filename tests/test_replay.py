"""Replay of recorded episodes in Rerun (pipeline.replay, stage ``replay``)."""

from __future__ import annotations

import contextlib
import os
import queue
import re
import signal
import socket
import subprocess
import sys
import threading
import time
import urllib.parse
import urllib.request
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
from synthetic_records import make_batch, tiny_png, write_synthetic

from pipeline.records import FileMeta
from pipeline.replay import ReplayError, build_replay, recording_name, replay_stem
from pipeline.world.pictures import CATEGORIES

ROOT = Path(__file__).resolve().parents[1]


def _rows(rrd: Path) -> dict[str, int]:
    """Entity path -> number of temporal rows (static entities map to 0)."""
    import rerun.chunk

    rows: dict[str, int] = {}
    for ch in rerun.chunk.RrdReader(rrd).stream().to_chunks():
        path = str(ch.entity_path)
        rows[path] = rows.get(path, 0) + (0 if ch.is_static else ch.num_rows)
    return rows


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    d = tmp_path_factory.mktemp("rec")
    written = write_synthetic(d / "r.mcap", runs=2, episodes_per_run=5, seed=3)
    return d / "r.mcap", written


def test_replay_of_one_episode_has_the_entities_and_one_row_per_step(recorded, tmp_path):
    path, written = recorded
    f = next(w for w in written if w["run"] == 1 and w["episode"] == 3)
    rows = _rows(build_replay(path, 1, 3, out=tmp_path / "e.rrd"))
    n = len(f["states"])
    for entity in (
        "/maze/robot",
        "/maze/robot/action",
        "/maze/robot/trajectory",
        "/metrics/return",
    ):
        assert rows[entity] == n, entity
    assert {"/maze/cells", "/maze/obstacles"} <= rows.keys()
    n_rec = len(f["recognitions"]["step"])
    assert rows.get("/recognition/picture", 0) == n_rec > 0
    assert [rows.get(f"/recognition/scores/{name}", 0) for name in CATEGORIES] == [
        n_rec
    ] * 5  # a bar each
    assert rows["/maze/unsafe"] == 1 + len(set(f["unsafe_added"]["step"].tolist()))
    if f["_substitutions"]:
        assert any(k.startswith("/support/") for k in rows)
    assert rows["/events"] >= int((f["flags"] != 0).sum())


def test_replay_of_a_whole_run_covers_every_step(recorded, tmp_path):
    path, written = recorded
    rows = _rows(build_replay(path, 0, whole_run=True, out=tmp_path / "run.rrd"))
    assert rows["/maze/robot"] == sum(len(w["states"]) for w in written if w["run"] == 0)


def test_replay_names_a_missing_episode(recorded, tmp_path):
    path, _ = recorded
    with pytest.raises(ReplayError, match="run 1 has no recorded episode 7 \\(episodes 0..4"):
        build_replay(path, 1, 7, out=tmp_path / "x.rrd")
    with pytest.raises(ReplayError, match="no recorded episode of run 5"):
        build_replay(path, 5, 0, out=tmp_path / "x.rrd")


def test_replay_of_a_file_without_steps_says_so(tmp_path):
    """``record=episodes`` files hold no steps: the replay refuses them naming the level, and writes nothing."""
    write_synthetic(tmp_path / "e.mcap", runs=1, episodes_per_run=3, steps=False)
    with pytest.raises(
        ReplayError, match="recorded with record=episodes: it holds no steps to replay"
    ) as e:
        build_replay(tmp_path / "e.mcap", 0, 1, out=tmp_path / "x.rrd")
    assert e.value.key == "file" and not (tmp_path / "x.rrd").exists()


def test_replay_shows_recorded_q_values(tmp_path):
    from pipeline.records import RecordWriter

    n = 4
    with RecordWriter(tmp_path / "q.mcap", maze={"layout": ["S.", ".G"]}) as w:
        for e in range(2):
            w.episodes(
                **make_batch(
                    [
                        dict(
                            run=0,
                            episode=e,
                            states=np.array([0, 1, 3, 2])[:n],
                            actions=np.array([1, 2, 3, 0]),
                            rewards=np.zeros(n),
                            flags=np.zeros(n, np.uint8),
                            recognitions={},
                            unsafe_added={},
                            summary={
                                "collisions": 0,
                                "return_": 0.0,
                                "reached_goal": False,
                                "prevented": 0,
                                "epsilon": 0.1,
                                "greedy_optimal": False,
                            },
                            q_values=np.full((4, 4), e + 0.5),
                        )
                    ]
                )
            )
    rows = _rows(build_replay(tmp_path / "q.mcap", 0, 1, out=tmp_path / "q.rrd"))
    assert rows["/q_values/max"] == 2 and "/derived/visits" not in rows
    image = _columns(tmp_path / "q.rrd", "/q_values/max")
    assert (
        image["Image:format"][0][0]["width"] == image["Image:format"][0][0]["height"] == 2
    )  # a pixel a cell


def test_replay_stage_with_a_positional_file(recorded, tmp_path):
    path, written = recorded
    out = tmp_path / "stage.rrd"
    res = subprocess.run(
        [sys.executable, "-m", "pipeline", "replay", str(path), "run=0", "episode=2", f"out={out}"],
        check=False,
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert res.returncode == 0, res.stderr
    f = next(w for w in written if w["run"] == 0 and w["episode"] == 2)
    assert _rows(out)["/maze/robot"] == len(f["states"])
    bad = subprocess.run(
        [
            sys.executable,
            "-m",
            "pipeline",
            "replay",
            f"file={path}",
            "run=0",
            "episode=2",
            "viewer=desktop",
        ],
        check=False,
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert bad.returncode == 2 and "config key 'viewer'" in bad.stderr


def _columns(rrd: Path, entity: str) -> dict[str, list]:
    import rerun.chunk

    out: dict[str, list] = {}
    for ch in rerun.chunk.RrdReader(rrd).stream().to_chunks():
        if str(ch.entity_path) == entity:
            for k, v in ch.to_record_batch().to_pydict().items():
                out.setdefault(k, []).extend(v)
    return out


def test_the_trials_stage_records_the_worlds_moves_and_names(tmp_path):
    from pipeline.records import read_records
    from pipeline.stages import run_stage
    from pipeline.world.maze import ACTION_NAMES, MOVES
    from pipeline.world.pictures import CATEGORIES

    run_stage(
        "trials",
        [
            "method=shield",
            "maze=5x5",
            "runs=1",
            "episodes=2",
            "record=steps",
            f"out={tmp_path}",
            "progress=false",
        ],
    )
    (path,) = tmp_path.rglob("records.mcap")
    maze = read_records(path, pictures=False).meta.maze
    assert (maze["actions"], maze["moves"], maze["categories"]) == (
        list(ACTION_NAMES),
        list(MOVES),
        list(CATEGORIES),
    )


def test_replay_draws_with_the_files_moves_and_names(tmp_path):
    from pipeline.records import RecordWriter

    def write(path, **maze):
        with RecordWriter(path, maze={"layout": ["S.", ".G"], **maze}) as w:
            w.episodes(
                **make_batch(
                    [
                        dict(
                            run=0,
                            episode=0,
                            states=np.array([0, 1, 3, 2]),
                            actions=np.array([1, 2, 3, 0]),
                            rewards=np.zeros(4),
                            flags=np.array([1, 0, 0, 8], np.uint8),
                            recognitions={},
                            unsafe_added={},
                            summary={
                                "collisions": 0,
                                "return_": 0.0,
                                "reached_goal": True,
                                "prevented": 1,
                                "epsilon": 0.1,
                                "greedy_optimal": False,
                            },
                        )
                    ]
                )
            )
        return build_replay(path, 0, 0, out=path.with_suffix(".rrd"))

    own = write(
        tmp_path / "own.mcap",
        actions=["up", "right", "down", "left"],
        moves=[(-1, 0), (0, 2), (1, 0), (0, -2)],
    )
    vectors = [v[0] for v in _columns(own, "/maze/robot/action")["Arrows2D:vectors"]]
    assert np.allclose(
        vectors, [[0.8, 0], [0, 0.4], [-0.8, 0], [0, -0.4]]
    )  # (x, y) = (d_col, d_row) * 0.4
    assert [t[0] for t in _columns(own, "/events")["TextLog:text"]] == [
        "run 0 ep 0 step 0: cell 0 action right: reselected",
        "run 0 ep 0 step 3: cell 2 action up: goal",
    ]
    old = write(tmp_path / "old.mcap")  # a file without moves or names (as older files): N, E, S, W
    vectors = [v[0] for v in _columns(old, "/maze/robot/action")["Arrows2D:vectors"]]
    assert np.allclose(vectors, [[0.4, 0], [0, 0.4], [-0.4, 0], [0, -0.4]])
    assert "action E: reselected" in _columns(old, "/events")["TextLog:text"][0][0]


SUPPORT = {
    c: [tiny_png(100 + 5 * c + k) for k in range(5)] for c in range(5)
}  # category -> 5 shots


@pytest.fixture(scope="module")
def with_support(tmp_path_factory):
    """A record file with the initial support set, in an experiment's cell folder."""
    path = tmp_path_factory.mktemp("runs") / "fig8" / "fewshot_dss" / "records.mcap"
    return path, write_synthetic(path, runs=1, episodes_per_run=4, seed=3, support_pictures=SUPPORT)


def test_the_support_set_is_a_grid_of_25_with_substitutions_framed(with_support, tmp_path):
    path, written = with_support
    rrd = build_replay(path, 0, 2, out=tmp_path / "g.rrd")
    subs = [
        s for w in written for s in w["_substitutions"] if w["episode"] <= 2
    ]  # episode, then step order
    assert any(s["episode"] < 2 for s in subs) and any(s["episode"] == 2 for s in subs)
    before = {(s["category"], s["position"]): s["picture"] for s in subs if s["episode"] < 2}
    places = {}
    for c in range(5):
        for k in range(5):
            cols = _columns(rrd, f"/support/{c}/{k}")
            places[(c, k)] = tuple(cols["Transform3D:translation"][0][0][:2])
            shown = bytes(cols["EncodedImage:blob"][0][0])  # what the episode starts with
            assert shown == (tiny_png(before[(c, k)]) if (c, k) in before else SUPPORT[c][k]), (
                c,
                k,
            )
    xs, ys = sorted({x for x, _ in places.values()}), sorted({y for _, y in places.values()})
    assert len(xs) == len(ys) == 5 and all(
        places[(c, k)] == (xs[k], ys[c]) for c, k in places
    )  # none stacked
    marks = {(s["category"], s["position"]): f"ep {s['episode']} t {s['step']}" for s in subs}
    frames = _columns(rrd, "/support/substituted")
    centres = [tuple(np.round(np.add(places[ck], 0.5), 3)) for ck in sorted(marks)]
    assert [
        tuple(np.round(c, 3)) for c in frames["Boxes2D:centers"][-1]
    ] == centres  # frame the pictures
    assert frames["Boxes2D:labels"][-1] == [marks[ck] for ck in sorted(marks)]
    assert _columns(rrd, "/support/categories")["Points2D:class_ids"] == [
        [0, 1, 2, 3, 4]
    ]  # rows, named:
    context = _columns(rrd, "/")["AnnotationContext:context"][0][0]
    assert [c["class_description"]["info"]["label"] for c in context] == list(CATEGORIES)
    assert "/support/note" not in _rows(rrd)


def test_the_replay_says_when_the_file_holds_no_support_pictures(recorded, tmp_path):
    path, _ = recorded  # written without support pictures
    rrd = build_replay(path, 0, 1, out=tmp_path / "n.rrd")
    assert "holds no support pictures" in _columns(rrd, "/support/note")["Points2D:labels"][0][0]


def test_the_scores_are_labelled_by_category(recorded, tmp_path):
    path, written = recorded
    rrd = build_replay(path, 1, 3, out=tmp_path / "s.rrd")
    f = next(w for w in written if w["run"] == 1 and w["episode"] == 3)
    for c, name in enumerate(
        CATEGORIES
    ):  # each category its own bar, at its index, named by its entity
        bars = _columns(rrd, f"/recognition/scores/{name}")
        assert {v[0]["buffer"][0] for v in bars["BarChart:abscissa"]} == {c}
        assert np.allclose(
            [v[0]["buffer"][0] for v in bars["BarChart:values"]], f["recognitions"]["scores"][:, c]
        )
    text = _columns(rrd, "/recognition/result")["TextDocument:text"][-1][0]
    last, predicted = f["recognitions"]["scores"][-1], f["recognitions"]["predicted"][-1]
    assert text.endswith(
        "| category | relation score |\n|---|---|\n"
        + "\n".join(  # the predicted one in bold
            f"| {f'**{name}**' if c == predicted else name} | {last[c]:.3f} |"
            for c, name in enumerate(CATEGORIES)
        )
    )


def test_the_verdict_is_what_the_step_did(recorded, tmp_path):
    """A recognition's verdict comes from its step (under any decision rule): a reselected step
    stopped before the obstacle, a collided one drove on, its picture substituted (shared with the
    robot's replay: pipeline.replay.story)."""
    from collections import Counter

    from pipeline.records import schema as S

    path, written = recorded
    f = next(w for w in written if len(set(w["flags"][w["recognitions"]["step"]])) > 1)
    rrd = build_replay(path, f["run"], f["episode"], out=tmp_path / "v.rrd")
    texts = _columns(rrd, "/recognition/result")
    said = Counter(t[0].split("): ")[1].split("\n")[0] for t in texts["TextDocument:text"])
    stopped = [
        f"stopped before it: ({s}, {'NESW'[a]}) joins A_d, the action is reselected"
        for s, a, t in zip(*(f["recognitions"][k] for k in ("state", "action", "step")))
        if f["flags"][t] & S.FLAG_RESELECTED
    ]
    collided = int(((f["flags"][f["recognitions"]["step"]] & S.FLAG_COLLIDED) != 0).sum())
    drove_on = "drove on: collision, self-recovery, the picture substitutes into the support set"
    assert said == Counter(stopped) + Counter({drove_on: collided}) and stopped and collided


def test_the_recording_is_named_by_experiment_cell_run_and_episode(with_support, tmp_path):
    path, _ = with_support
    rrd = build_replay(path, 0, 2, out=tmp_path / "p.rrd")
    assert _columns(rrd, "/__properties")["RecordingInfo:name"] == [
        ["synthetic/fewshot_dss run 0 ep 2"]
    ]
    folders = FileMeta(path=Path("datasets/runs/fig8/fewshot_dss/records.mcap"), complete=True)
    assert (
        recording_name(folders, 3, 120) == "fig8/fewshot_dss run 3 ep 120"
    )  # no config: the folders
    trials = FileMeta(
        path=path,
        complete=True,
        config={"experiment": {"name": "table3"}},
        info={"info": {"cell": "dss_7x7"}},
    )
    assert (
        recording_name(trials, 3) == "table3/dss_7x7 run 3 all episodes"
    )  # the trials stage's metadata


def test_the_default_replay_file_names_the_cell(with_support, tmp_path, monkeypatch):
    from pipeline.stages import run_stage

    assert (
        replay_stem("datasets/runs/fig8/fewshot_dss/records.mcap", 3, 120)
        == "fig8-fewshot_dss-run3-ep120"
    )
    assert replay_stem("datasets/runs/fig8/ssrl/records.mcap.partial", 3) == "fig8-ssrl-run3-all"
    assert replay_stem("runs/mine/other.mcap", 0, 1) == "runs-mine-other-run0-ep1"
    path, _ = with_support
    monkeypatch.chdir(tmp_path)
    assert (
        run_stage("replay", [f"file={path}", "run=0", "episode=1"])
        == tmp_path / "replays/fig8-fewshot_dss-run0-ep1.rrd"
    )


def test_the_trials_stage_records_the_initial_support_set(tmp_path):
    import pandas as pd

    from pipeline.errors import ConfigError
    from pipeline.fewshot.synthetic import write_synthetic_dataset
    from pipeline.records import read_records
    from pipeline.stages import run_stage

    images = tmp_path / "images"
    write_synthetic_dataset(images, n_train=1, n_val=1, per_class=1, size=12)
    rows = pd.read_csv(images / "manifest.csv").query(
        "split == 'support'"
    )  # shot k: instance k here
    expected = {
        (int(r.category), int(r.instance)): (images / r.file).read_bytes()
        for r in rows.itertuples()
    }
    trial = [
        "method=fewshot_dss",
        "recogniser=fixed_accuracy",
        "runs=1",
        "episodes=2",
        "progress=false",
        f"out={tmp_path / 'cell'}",
        "overwrite=true",
    ]
    run_stage("trials", [*trial, f"images_dir={images}"])
    first = (tmp_path / "cell" / "records.mcap").read_bytes()
    meta = read_records(tmp_path / "cell" / "records.mcap").meta
    assert len(expected) == 25 and meta.support_pictures == expected and len(meta.pictures) == 40
    run_stage("trials", [*trial, f"images_dir={images}"])
    assert (tmp_path / "cell" / "records.mcap").read_bytes() == first  # same config, same bytes
    run_stage("trials", trial)  # no pictures of its own and no images_dir: none recorded
    assert read_records(tmp_path / "cell" / "records.mcap").meta.support_pictures == {}
    with pytest.raises(ConfigError, match="config key 'images_dir': .*manifest"):
        run_stage("trials", [*trial, f"images_dir={tmp_path}"])
    with pytest.raises(
        ConfigError, match="config key 'images_dir': read only by methods that recognise"
    ):
        run_stage(
            "trials",
            [
                "method=shield",
                "runs=1",
                "episodes=2",
                f"out={tmp_path / 's'}",
                f"images_dir={images}",
            ],
        )


# ---------------------------------------------------------------- viewer=web (serving, lifetime, ports, bind)
@contextmanager
def web_replay(path: Path, out: Path, *overrides: str, timeout: float = 120, episode: int = 1):
    """``python -m pipeline replay ... viewer=web`` of ``episode`` of run 0 on free ports, as a
    subprocess: yields it, the address it printed and its children, once it says "serving"; ends
    whatever is left afterwards."""
    import psutil

    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "pipeline",
            "replay",
            f"file={path}",
            "run=0",
            f"episode={episode}",
            f"out={out}",
            "viewer=web",
            "web_port=0",
            "grpc_port=0",
            *overrides,
        ],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    lines: queue.Queue = queue.Queue()
    threading.Thread(target=lambda: [lines.put(x) for x in proc.stdout], daemon=True).start()
    children: list = []
    try:
        url = _serving_url(lines, proc, timeout)
        children = psutil.Process(proc.pid).children(recursive=True)
        yield proc, url, children
    finally:
        for p in [proc, *children]:
            with contextlib.suppress(ProcessLookupError):
                os.kill(p.pid, signal.SIGKILL)
        proc.wait(10)


def _serving_url(lines: queue.Queue, proc: subprocess.Popen, timeout: float) -> str:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            line = lines.get(timeout=1)
        except queue.Empty:
            if proc.poll() is not None:
                raise AssertionError(
                    f"replay ended ({proc.returncode}) before serving: {proc.stderr.read()}"
                ) from None
            continue
        if line.startswith("serving "):
            return re.search(r"http://\S+", line).group(0)
    raise AssertionError(f"no 'serving' line within {timeout} s")


def _ports(url: str) -> tuple[int, int]:
    """(web port, gRPC port) of a printed address."""
    web = urllib.parse.urlsplit(url)
    grpc = urllib.parse.urlsplit(urllib.parse.parse_qs(web.query)["url"][0])
    return web.port, grpc.port


def _free(port: int) -> bool:
    with socket.socket() as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


def _gone(pid: int) -> bool:
    import psutil

    try:
        return psutil.Process(pid).status() == psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return True


@pytest.mark.parametrize(
    "sig, code",
    [(signal.SIGTERM, 143), (signal.SIGINT, 0), (signal.SIGKILL, -9)],
    ids=["SIGTERM", "Ctrl-C", "SIGKILL"],
)
def test_web_viewer_lives_and_dies_with_the_command(recorded, tmp_path, sig, code):
    path, _ = recorded
    with web_replay(path, tmp_path / "w.rrd") as (proc, url, children):
        web_port, grpc_port = _ports(url)
        assert url == (
            f"http://127.0.0.1:{web_port}?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A{grpc_port}%2Fproxy"
        )
        assert [c.name() for c in children] == [
            "rerun"
        ]  # the binary itself, not its Python wrapper
        assert str(tmp_path / "w.rrd") not in children[0].cmdline()  # it got the recording by gRPC
        assert not _free(web_port) and not _free(grpc_port)
        with urllib.request.urlopen(f"http://127.0.0.1:{web_port}/", timeout=10) as page:
            assert page.status == 200
        proc.send_signal(sig)
        assert proc.wait(30) == code
        if sig != signal.SIGKILL:  # Ctrl-C and SIGTERM both say where the recording is
            assert f"the recording stays at {tmp_path / 'w.rrd'}" in proc.stderr.read()
        deadline = (
            time.monotonic() + 10
        )  # SIGKILL: the child's parent-death signal, then its own exit
        while (
            not (_gone(children[0].pid) and _free(web_port) and _free(grpc_port))
            and time.monotonic() < deadline
        ):
            time.sleep(0.1)
        assert _gone(children[0].pid) and _free(web_port) and _free(grpc_port)


def test_web_viewer_refuses_a_busy_port(recorded, tmp_path):
    path, _ = recorded
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        for key, other in (("web_port", "grpc_port"), ("grpc_port", "web_port")):
            res = subprocess.run(
                [
                    sys.executable,
                    "-m",
                    "pipeline",
                    "replay",
                    f"file={path}",
                    "run=0",
                    "episode=1",
                    f"out={tmp_path / 'b.rrd'}",
                    "viewer=web",
                    f"{key}={port}",
                    f"{other}=0",
                ],
                check=False,
                cwd=ROOT,
                capture_output=True,
                text=True,
                timeout=120,
            )
            assert res.returncode == 2, res.stderr
            assert res.stderr.splitlines() == [
                (
                    f"error: config key '{key}': cannot listen on 127.0.0.1 port {port}: "
                    f"Address already in use (another viewer? {key}=0 picks a free port)"
                )
            ]
            assert (
                "serving" not in res.stdout and not (tmp_path / "b.rrd").exists()
            )  # refused before any work


def test_web_viewer_needs_allow_remote_off_the_loopback(recorded, tmp_path, capsys):
    from pipeline.config.compose import load_config
    from pipeline.replay.viewer import web_address

    path, _ = recorded
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "pipeline",
            "replay",
            f"file={path}",
            "run=0",
            "episode=1",
            f"out={tmp_path / 'r.rrd'}",
            "viewer=web",
            "bind=0.0.0.0",
        ],
        check=False,
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert res.returncode == 2 and len(res.stderr.splitlines()) == 1
    assert res.stderr.startswith(
        "error: config key 'bind': 0.0.0.0 is reachable from other machines"
    )
    assert "allow_remote=true" in res.stderr and not (tmp_path / "r.rrd").exists()

    def address(*overrides):
        cfg = load_config("replay", [f"file={path}", "web_port=0", "grpc_port=0", *overrides])
        return web_address(cfg.bind, cfg.allow_remote, cfg.web_port, cfg.grpc_port)

    web = address(
        "bind=0.0.0.0", "allow_remote=true"
    )  # checks the ports on every interface, serves nothing
    assert capsys.readouterr().err.startswith(
        "warning: bind=0.0.0.0: the viewer and the recording are served"
    )
    assert (
        web.bind == "0.0.0.0"
        and web.url.startswith("http://127.0.0.1:")
        and web.web_port != web.grpc_port
    )
    assert address("bind=::1").url.startswith("http://[::1]:")
    assert capsys.readouterr().err == ""  # loopback: no warning


def _recs(recognised: dict[int, list[int]], episodes: int = 6, scores: bool = True):
    """A stand-in for :class:`pipeline.records.Records`: ``recognised`` run -> episodes with a
    recognition (one each), every run ``episodes`` long."""
    import types

    import pandas as pd

    rows = [(r, e) for r, es in recognised.items() for e in es]
    recognitions = pd.DataFrame(rows, columns=["run", "episode"])
    if scores:
        recognitions["score_0"] = 0.5
    runs = [(r, e) for r in recognised for e in range(episodes)]
    return types.SimpleNamespace(
        recognitions=recognitions, episodes=pd.DataFrame(runs, columns=["run", "episode"])
    )


def test_without_an_episode_the_replay_opens_the_first_with_a_recognition():
    from pipeline.replay.notes import first_recognition

    recs = _recs({0: [], 1: [4, 2, 5]})
    episode, why = first_recognition(recs, 1)
    assert episode == 2 and "episodes 2, 4, 5 (3 episodes)" in why
    episode, why = first_recognition(recs, 0)
    assert episode == 0 and "holds no recognition" in why


def test_every_empty_recognition_view_says_why():
    from pipeline.replay.notes import empty_views

    recs = _recs({0: [], 1: [4, 2]})
    assert empty_views(recs, 1, [2]).recognition is None  # has data
    assert empty_views(recs, 1, [2]).scores is None
    other = empty_views(recs, 1, [3])
    assert "no recognition in episode 3" in other.recognition and "2, 4" in other.recognition
    assert other.scores == other.recognition
    assert "method recognises no pictures" in empty_views(recs, 0, [0]).recognition
    assert other.scores_short == "none, see below"  # the scores view's name
    no_scores = empty_views(_recs({0: [1]}, scores=False), 0, [1])
    assert "no scores" in no_scores.scores and no_scores.scores_short == "none recorded"
    assert empty_views(recs, 1, [0, 1, 2, 3]).recognition is None  # a whole run: some episode has


def test_the_stage_without_an_episode_prints_the_one_it_opens(recorded, tmp_path, capsys):
    from pipeline.errors import ConfigError
    from pipeline.stages import run_stage

    path, written = recorded
    first = min(w["episode"] for w in written if w["run"] == 1 and len(w["recognitions"]["step"]))
    rrd = run_stage("replay", [f"file={path}", "run=1", f"out={tmp_path}/x.rrd"])
    assert rrd == tmp_path / "x.rrd"
    assert f"episode={first}: the first of run 1 with a recognition" in capsys.readouterr().out
    with pytest.raises(ConfigError, match="config key 'episode': whole_run=true"):
        run_stage("replay", [f"file={path}", "run=1", "episode=2", "whole_run=true"])


def test_a_replay_without_recognitions_says_why_in_its_views(tmp_path):
    """The committed sample's shield cell recognises no pictures: the picture and recognition
    views get their note (static), and no picture or score is drawn."""
    path = ROOT / "datasets" / "sample" / "fig8" / "shield" / "records.mcap"
    rows = _rows(build_replay(path, 0, 0, out=tmp_path / "s.rrd"))
    assert {"/recognition/picture/note", "/recognition/result"} <= rows.keys()
    assert rows["/recognition/result"] == 0  # static: shown at every step
    assert "/recognition/picture" not in rows
    assert not [k for k in rows if k.startswith("/recognition/scores")]
