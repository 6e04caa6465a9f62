"""Replay a recorded episode (or a whole run) in Rerun, from the MCAP records alone (DESIGN.md
"Records"; paper section 3, Algorithm 1 as it unfolded).

What the recording shows, on the timelines ``step`` (global across the replayed episodes) and
``episode``:

* ``maze/cells``, ``maze/obstacles``: the layout; obstacles coloured by category, labelled with
  category, instance and orientation of this run's assignment (static);
* ``maze/robot``: the robot's cell before each step (exactly one point per recorded step),
  ``maze/robot/action`` the executed action (red on a collision, orange after a reselection),
  ``maze/robot/trajectory`` the path so far in the episode;
* ``maze/unsafe``: the unsafe set A_d (eqs. 7-8) as arrows (cell -> forbidden direction), growing
  as pairs are added; it starts with everything the run added in earlier episodes;
* ``recognition/picture`` + ``recognition/scores`` + ``recognition/result``: the query picture seen
  at each recognition, the relation scores (eq. 2) and predicted vs. true category;
* ``support/<category>/<position>``: the support set's thumbnails (when the file holds them) and
  every substituted picture at its position (section 3.3);
* ``events``: collisions, recoveries, reselections, goal; ``metrics/return``: the return so far;
* ``q_values/max`` (H x W): the greedy value max_a Q at the end of the episode when the file holds
  Q tables (the trial runner does not record them by default); otherwise ``derived/visits``, the
  run's cumulative visit count per cell, derived from the recorded states.

Default: save an ``.rrd`` file. :func:`open_viewer` then serves it to a web viewer bound to
127.0.0.1 or spawns the native viewer.
"""
from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np

from . import schema as S
from .reader import Records, RecordsWarning, read_records
from .scan import RecordsError
from pipeline.errors import UserError

APP_ID = "fewshot_safe_rl_replay"
CATEGORY_COLOURS = np.array([[230, 159, 0], [86, 180, 233], [0, 158, 115], [240, 228, 66], [204, 121, 167],
                             [213, 94, 0], [0, 114, 178], [120, 120, 120]], dtype=np.uint8)
FREE, START, GOAL = (235, 235, 235), (120, 200, 120), (255, 215, 0)


class ReplayError(UserError):
    """The requested run/episode is not in the records, or the records cannot be drawn; ``key`` is
    the config key to blame (``"file"`` for a record file that cannot be read or drawn)."""

    def __init__(self, message: str, key: str = "run/episode"):
        super().__init__(message)
        self.key = key


def _centres(cells: np.ndarray, width: int) -> np.ndarray:
    rows, cols = np.divmod(np.asarray(cells, dtype=np.int64), width)
    return np.stack([cols + 0.5, rows + 0.5], axis=1).astype(np.float32)


def _by_step(df) -> dict[int, list]:
    """Rows of one episode's frame grouped by step (named tuples), built once per episode."""
    out: dict[int, list] = {}
    for row in df.itertuples(index=False):
        out.setdefault(int(row.step), []).append(row)
    return out


def _blueprint():
    import rerun.blueprint as rrb

    return rrb.Blueprint(rrb.Horizontal(
        rrb.Vertical(rrb.Spatial2DView(origin="maze", name="maze"),
                     rrb.TimeSeriesView(origin="metrics", name="return"), row_shares=[3, 1]),
        rrb.Vertical(rrb.Spatial2DView(origin="recognition/picture", name="picture seen"),
                     rrb.BarChartView(origin="recognition/scores", name="relation scores"),
                     rrb.TextDocumentView(origin="recognition/result", name="recognition")),
        rrb.Vertical(rrb.Grid(rrb.Spatial2DView(origin="support", name="support set")),
                     rrb.TensorView(origin="q_values" , name="Q / visits", contents=["q_values/**", "derived/**"]),
                     rrb.TextLogView(origin="events", name="events")),
        column_shares=[3, 2, 2]))


def build_replay(path: str | Path, run: int, episode: int | None = None, *, out: str | Path,
                 whole_run: bool = False, records: Records | None = None) -> Path:
    """Write a Rerun ``.rrd`` replaying ``episode`` of ``run`` of the record file ``path`` (all
    episodes of the run with ``whole_run=True``). Returns the ``.rrd`` path."""
    import rerun as rr

    path, out = Path(path), Path(out)
    if not whole_run and episode is None:
        raise ReplayError("pass an episode, or whole_run=True to replay every episode of the run")
    if records is None:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", RecordsWarning)
            try:
                records = read_records(path, run=run)
            except (RecordsError, FileNotFoundError) as exc:  # empty, not MCAP, another program's, missing
                raise ReplayError(str(exc), key="file") from None
        for meta in records.files.values():
            if meta.unusable:  # our magic bytes and nothing readable after them
                raise ReplayError(meta.unusable, key="file")
        for w in caught:  # a damaged or truncated file that can be replayed: say what it lost
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    recs = records
    meta = recs.files[str(path)] if str(path) in recs.files else recs.meta
    why = f"; the file is damaged or cut: {meta.lost}" if meta.lost else ""
    eps_of_run = recs.episodes[recs.episodes.run == run]
    if eps_of_run.empty:
        raise ReplayError(f"{path}: no recorded episode of run {run}{why}")
    if not whole_run and episode not in set(eps_of_run.episode):
        have = eps_of_run.episode
        raise ReplayError(f"{path}: run {run} has no recorded episode {episode} "
                          f"(episodes {int(have.min())}..{int(have.max())}, {len(have)} recorded){why}")
    if not meta.maze:
        raise ReplayError(f"{path}: the file holds no maze metadata, so the maze cannot be drawn", key="file")
    layout, width, height = meta.maze["layout"], meta.maze["width"], meta.maze["height"]
    names = meta.maze.get("categories") or []
    cat_name = (lambda c: names[c] if 0 <= c < len(names) else f"category {c}")
    replay_eps = sorted(eps_of_run.episode) if whole_run else [int(episode)]
    first = replay_eps[0]

    out.parent.mkdir(parents=True, exist_ok=True)
    rid = f"{path.stem}-run{run}-" + ("all" if whole_run else f"ep{episode}")
    rec = rr.RecordingStream(APP_ID, recording_id=rid, send_properties=False)
    rec.save(out, default_blueprint=_blueprint())

    # ---- static world
    grid = np.array([list(r) for r in layout])
    cells = np.arange(width * height)
    free = cells[(grid.ravel() != "X")]
    colours = np.array([START if grid.flat[c] == "S" else GOAL if grid.flat[c] == "G" else FREE for c in free],
                       dtype=np.uint8)
    rec.log("maze/cells", rr.Boxes2D(mins=_centres(free, width) - 0.5, sizes=np.ones((len(free), 2)),
                                     colors=colours, draw_order=0.0), static=True)
    obstacles = meta.obstacles.get(run, [])
    if obstacles:
        oc = np.array([o["cell"] for o in obstacles])
        cats = np.array([o["category"] for o in obstacles])
        labels = [f"{cat_name(o['category'])} #{o['instance']} r{o['orientation']}" for o in obstacles]
        rec.log("maze/obstacles", rr.Boxes2D(mins=_centres(oc, width) - 0.45, sizes=np.full((len(oc), 2), 0.9),
                                             colors=CATEGORY_COLOURS[np.minimum(cats, len(CATEGORY_COLOURS) - 1)],
                                             labels=labels, class_ids=cats, draw_order=1.0), static=True)
    else:
        xs = cells[grid.ravel() == "X"]
        rec.log("maze/obstacles", rr.Boxes2D(mins=_centres(xs, width) - 0.45, sizes=np.full((len(xs), 2), 0.9),
                                             colors=[90, 90, 90], draw_order=1.0), static=True)
    rec.log("metrics/return", rr.SeriesLines(names="return"), static=True)

    steps = recs.steps[recs.steps.run == run]
    recog = recs.recognitions[recs.recognitions.run == run]
    unsafe = recs.unsafe[recs.unsafe.run == run]
    subs = recs.substitutions[(recs.substitutions.run == run) & (recs.substitutions.picture >= 0)]
    score_cols = [c for c in recog.columns if c.startswith("score_")]

    # ---- state before the first replayed episode: A_d, support set, visits
    ad = unsafe[unsafe.episode < first][["state", "action"]].to_numpy().tolist()
    support = dict(meta.support_pictures)
    for s in subs[subs.episode < first].itertuples():
        if int(s.picture) in meta.pictures:
            support[(int(s.category), int(s.position))] = meta.pictures[int(s.picture)]
    visits = np.bincount(steps[steps.episode < first].state.to_numpy(), minlength=width * height)

    def log_unsafe() -> None:
        if ad:
            arr = np.array(ad, dtype=np.int64)
            vec = np.array(S.ACTION_DELTAS, dtype=np.float32)[arr[:, 1]][:, ::-1] * 0.45
            rec.log("maze/unsafe", rr.Arrows2D(origins=_centres(arr[:, 0], width), vectors=vec,
                                               colors=[220, 30, 30], radii=0.04, draw_order=3.0))
        else:
            rec.log("maze/unsafe", rr.Clear(recursive=False))

    q_has = {(k[1], k[2]): v for k, v in recs.q_values.items() if k[1] == run}
    tick = 0
    for e in replay_eps:
        ep_steps = steps[steps.episode == e]
        states, actions = ep_steps.state.to_numpy(), ep_steps.action.to_numpy()
        flags, rewards = ep_steps["flags"].to_numpy(), ep_steps.reward.to_numpy()
        centres = _centres(states, width)
        ep_rec = _by_step(recog[recog.episode == e])
        ep_un = _by_step(unsafe[unsafe.episode == e])
        ep_sub = _by_step(subs[subs.episode == e])
        rec.set_time("step", sequence=tick)
        rec.set_time("episode", sequence=e)
        log_unsafe()
        for (c, p), png in sorted(support.items()) if e == first else ():  # later: only the changes
            rec.log(f"support/{c}/{p}", rr.EncodedImage(contents=png, media_type="image/png"))
        if (e - 1 >= 0) and (run, e - 1) in q_has:  # the Q table the episode starts from
            rec.log("q_values/max", rr.Tensor(q_has[(run, e - 1)].max(axis=1).reshape(height, width),
                                              dim_names=["row", "col"]))
        n = len(states)
        ticks = [rr.TimeColumn("step", sequence=np.arange(tick, tick + n)),
                 rr.TimeColumn("episode", sequence=np.full(n, e))]
        colour = np.where((flags & S.FLAG_COLLIDED)[:, None] != 0, [220, 30, 30],
                          np.where((flags & S.FLAG_RESELECTED)[:, None] != 0, [255, 140, 0], [30, 30, 200]))
        vec = np.array(S.ACTION_DELTAS, dtype=np.float32)[actions.astype(np.int64)][:, ::-1] * 0.4
        if n:  # one row per recorded step on each of these entities
            rec.send_columns("maze/robot", indexes=ticks, columns=rr.Points2D.columns(
                positions=centres, radii=np.full(n, 0.3, np.float32),
                labels=[f"ep {e} step {t}" for t in range(n)]))
            rec.send_columns("maze/robot/action", indexes=ticks, columns=rr.Arrows2D.columns(
                origins=centres, vectors=vec, colors=colour.astype(np.uint8)))
            rec.send_columns("maze/robot/trajectory", indexes=ticks, columns=rr.LineStrips2D.columns(
                strips=[centres[:t + 1] for t in range(n)]))
            rec.send_columns("metrics/return", indexes=ticks,
                             columns=rr.Scalars.columns(scalars=np.cumsum(rewards.astype(np.float64))))
        if not q_has:
            rec.log("derived/visits", rr.Tensor(visits.reshape(height, width), dim_names=["row", "col"]))
        visits += np.bincount(states, minlength=width * height)
        events = set(np.flatnonzero(flags)) | set(ep_rec) | set(ep_un) | set(ep_sub)
        for t in sorted(int(x) for x in events):
            rec.set_time("step", sequence=tick + t)
            rec.set_time("episode", sequence=e)
            f = int(flags[t])
            if f:
                what = [name for name, bit in S.FLAG_NAMES.items() if f & bit]
                level = "ERROR" if f & S.FLAG_COLLIDED else "WARN" if f & S.FLAG_RESELECTED else "INFO"
                rec.log("events", rr.TextLog(f"run {run} ep {e} step {t}: cell {int(states[t])} action "
                                             f"{S.ACTION_NAMES[int(actions[t])]}: {', '.join(what)}", level=level))
            for r in ep_rec.get(t, ()):
                pid = int(r.picture)
                if pid in meta.pictures:
                    rec.log("recognition/picture", rr.EncodedImage(contents=meta.pictures[pid], media_type="image/png"))
                sc = np.array([getattr(r, c) for c in score_cols], dtype=np.float32)
                if score_cols and not np.isnan(sc).all():
                    rec.log("recognition/scores", rr.BarChart(np.nan_to_num(sc)))
                verdict = "recognised: unsafe pair added, action reselected" if r.predicted == r.true \
                    else "misrecognised: collision, picture substitutes into the support set"
                rec.log("recognition/result", rr.TextDocument(
                    f"### picture {pid}\n\nrun {run}, episode {e}, step {t}, cell {int(r.state)}, action "
                    f"{S.ACTION_NAMES[int(r.action)]}\n\npredicted **{cat_name(int(r.predicted))}**, "
                    f"true **{cat_name(int(r.true))}**: {verdict}", media_type="text/markdown"))
            added = ep_un.get(t, ())
            if added:
                ad.extend([int(u.state), int(u.action)] for u in added)
                log_unsafe()
                for u in added:
                    rec.log("events", rr.TextLog(f"run {run} ep {e} step {t}: ({int(u.state)}, "
                                                 f"{S.ACTION_NAMES[int(u.action)]}) joins A_d "
                                                 f"({S.SOURCE_NAMES[int(u.source)]})", level="INFO"))
            for s in ep_sub.get(t, ()):
                c, p, pid = int(s.category), int(s.position), int(s.picture)
                if pid in meta.pictures:
                    support[(c, p)] = meta.pictures[pid]
                    rec.log(f"support/{c}/{p}", rr.EncodedImage(contents=meta.pictures[pid], media_type="image/png"))
                rec.log("events", rr.TextLog(f"run {run} ep {e} step {t}: picture {pid} replaces shot {p} of "
                                             f"{cat_name(c)} in the support set", level="INFO"))
        tick += n
        rec.set_time("step", sequence=max(tick - 1, 0))
        if not q_has:
            rec.log("derived/visits", rr.Tensor(visits.reshape(height, width), dim_names=["row", "col"]))
        if (run, e) in q_has:
            rec.log("q_values/max", rr.Tensor(q_has[(run, e)].max(axis=1).reshape(height, width),
                                              dim_names=["row", "col"]))
    rec.flush()
    rec.disconnect()
    return out


def rerun_command() -> list[str]:
    """The Rerun CLI shipped in the rerun-sdk wheel, run with this interpreter."""
    exe = Path(sys.executable).with_name("rerun")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "rerun_cli"]


def open_viewer(rrd: str | Path, viewer: str, *, bind: str = "127.0.0.1", web_port: int = 9090,
                grpc_port: int = 9876) -> subprocess.Popen | None:
    """``viewer="web"``: serve ``rrd`` to a web viewer on ``bind`` (127.0.0.1 by default: never
    all interfaces unless asked) and block until Ctrl-C; ``"native"``: spawn the desktop viewer
    (needs a display) and return; ``"none"``: do nothing."""
    if viewer == "none":
        return None
    if viewer == "web":
        cmd = rerun_command() + ["--serve-web", "--bind", bind, "--web-viewer-port", str(web_port),
                                 "--port", str(grpc_port), str(rrd)]
        print(f"serving {rrd} at http://{bind}:{web_port} (Ctrl-C to stop)", flush=True)
        try:
            subprocess.run(cmd, check=False)
        except KeyboardInterrupt:
            pass
        return None
    if viewer == "native":
        return subprocess.Popen(rerun_command() + [str(rrd)])
    raise ValueError(f"viewer must be 'none', 'web' or 'native', got {viewer!r}")
