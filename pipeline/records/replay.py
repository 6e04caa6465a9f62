"""Replay a recorded episode (or a whole run) in Rerun from the MCAP records alone (the entities:
docs/records.md "Replay it in Rerun"); timelines ``step`` (global across the replayed episodes)
and ``episode``. Moves, action and category names come from the file's maze metadata; a file
without moves (written before the writer recorded them) gets :data:`NESW`, here and nowhere else.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from pipeline.errors import UserError

from . import RecordsError, read_records
from . import schema as S

NESW = {"N": (-1, 0), "E": (0, 1), "S": (1, 0), "W": (0, -1)}  # (d_row, d_col) of files without moves
COLOURS = np.array([[230, 159, 0], [86, 180, 233], [0, 158, 115], [240, 228, 66], [204, 121, 167],
                    [213, 94, 0], [0, 114, 178], [120, 120, 120]], dtype=np.uint8)  # by category
FREE, START, GOAL, RED = (235, 235, 235), (120, 200, 120), (255, 215, 0), (220, 30, 30)


class ReplayError(UserError):
    """The run/episode is not in the records, or they cannot be drawn; ``key`` is the config key to
    blame (``"file"`` for a record file that cannot be read or drawn)."""

    def __init__(self, message: str, key: str = "run/episode"):
        super().__init__(message)
        self.key = key


def _blueprint():
    import rerun.blueprint as rrb

    V, S2 = rrb.Vertical, rrb.Spatial2DView
    return rrb.Blueprint(rrb.Horizontal(
        V(S2(origin="maze", name="maze"), rrb.TimeSeriesView(origin="metrics", name="return"), row_shares=[3, 1]),
        V(S2(origin="recognition/picture", name="picture seen"),
          rrb.BarChartView(origin="recognition/scores", name="relation scores"),
          rrb.TextDocumentView(origin="recognition/result", name="recognition")),
        V(rrb.Grid(S2(origin="support", name="support set")),
          rrb.TensorView(origin="q_values", name="Q / visits", contents=["q_values/**", "derived/**"]),
          rrb.TextLogView(origin="events", name="events")), column_shares=[3, 2, 2]))


def build_replay(path: str | Path, run: int, episode: int | None = None, *, out: str | Path,
                 whole_run: bool = False) -> Path:
    """Write a Rerun ``.rrd`` replaying ``episode`` of ``run`` of the record file ``path`` (every
    episode of the run with ``whole_run=True``) and return its path. The reader's warnings about a
    damaged or cut file pass through to the caller."""
    import rerun as rr

    path, out = Path(path), Path(out)
    if not whole_run and episode is None:
        raise ReplayError("pass an episode, or whole_run=True to replay every episode of the run")
    try:
        recs = read_records(path, run=run)
    except RecordsError as exc:  # missing, empty, not MCAP, another program's
        raise ReplayError(str(exc), key="file") from None
    meta = recs.meta
    if meta.unusable:  # our magic bytes and nothing readable after them
        raise ReplayError(meta.unusable, key="file")
    why = f"; the file is damaged or cut: {meta.lost}" if meta.lost else ""
    have = recs.episodes.episode[recs.episodes.run == run]
    if have.empty:
        raise ReplayError(f"{path}: no recorded episode of run {run}{why}")
    if not whole_run and episode not in set(have):
        raise ReplayError(f"{path}: run {run} has no recorded episode {episode} "
                          f"(episodes {int(have.min())}..{int(have.max())}, {len(have)} recorded){why}")
    if not (mz := meta.maze):
        raise ReplayError(f"{path}: the file holds no maze metadata, so the maze cannot be drawn", key="file")
    width, shape, cats = mz["width"], (mz["height"], mz["width"]), mz.get("categories") or []
    names = mz.get("actions") or list(NESW)
    moves = np.array(mz.get("moves") or list(NESW.values()), np.float32)[:, ::-1]  # as (x, y)
    cat = lambda c: cats[c] if 0 <= c < len(cats) else f"category {c}"  # noqa: E731
    act = lambda a: names[a] if 0 <= a < len(names) else f"action {a}"  # noqa: E731

    def xy(cells) -> np.ndarray:
        rows, cols = np.divmod(np.asarray(cells, dtype=np.int64), width)
        return np.stack([cols, rows], axis=1).astype(np.float32) + 0.5

    def log(entity: str, what, level: str = "INFO", **kw) -> None:  # text: a TextLog line
        rec.log(entity, rr.TextLog(what, level=level) if isinstance(what, str) else what, **kw)

    def boxes(cells, size: float, **kw):
        return rr.Boxes2D(mins=xy(cells) - size / 2, sizes=np.full((len(cells), 2), size), **kw)

    def picture(entity: str, pid: int) -> None:
        if pid in meta.pictures:
            log(entity, rr.EncodedImage(contents=meta.pictures[pid], media_type="image/png"))

    def log_unsafe() -> None:
        arr = np.array(ad, dtype=np.int64).reshape(-1, 2)
        log("maze/unsafe", rr.Arrows2D(origins=xy(arr[:, 0]), vectors=moves[arr[:, 1]] * 0.45, colors=RED,
                                       radii=0.04, draw_order=3.0) if len(arr) else rr.Clear(recursive=False))

    def tensor(entity: str, values: np.ndarray) -> None:
        log(entity, rr.Tensor(values.reshape(shape), dim_names=["row", "col"]))

    episodes = sorted(have) if whole_run else [int(episode)]
    out.parent.mkdir(parents=True, exist_ok=True)
    rec = rr.RecordingStream("fewshot_safe_rl_replay", send_properties=False,
                             recording_id=f"{path.stem}-run{run}-" + ("all" if whole_run else f"ep{episode}"))
    rec.save(out, default_blueprint=_blueprint())
    grid = np.array([list(r) for r in mz["layout"]]).ravel()  # the maze, static
    free = np.flatnonzero(grid != "X")
    log("maze/cells", boxes(free, 1.0, draw_order=0.0, colors=np.array(
        [{"S": START, "G": GOAL}.get(ch, FREE) for ch in grid[free]], np.uint8)), static=True)
    if obstacles := meta.obstacles.get(run, []):  # coloured and labelled by this run's assignment
        ids = np.array([o["category"] for o in obstacles])
        log("maze/obstacles", boxes([o["cell"] for o in obstacles], 0.9, draw_order=1.0, class_ids=ids,
                                    colors=COLOURS[np.minimum(ids, len(COLOURS) - 1)], labels=[
                                        f"{cat(o['category'])} #{o['instance']} r{o['orientation']}"
                                        for o in obstacles]), static=True)
    else:
        log("maze/obstacles", boxes(np.flatnonzero(grid == "X"), 0.9, colors=[90, 90, 90], draw_order=1.0),
            static=True)
    log("metrics/return", rr.SeriesLines(names="return"), static=True)

    steps, recog, unsafe, subs = (df[df.run == run] for df in (recs.steps, recs.recognitions, recs.unsafe,
                                                              recs.substitutions))
    subs = subs[subs.picture >= 0]
    score_cols = [c for c in recog.columns if c.startswith("score_")]
    q = {e: v for (_, r, e), v in recs.q_values.items() if r == run}
    first = episodes[0]  # what the run held before it: A_d, the support set, the visits
    ad = unsafe[unsafe.episode < first][["state", "action"]].to_numpy().tolist()
    support = dict(meta.support_pictures)
    for s in subs[subs.episode < first].itertuples():
        if int(s.picture) in meta.pictures:
            support[(int(s.category), int(s.position))] = meta.pictures[int(s.picture)]
    visits = np.bincount(steps[steps.episode < first].state.to_numpy(), minlength=shape[0] * width)
    tick = 0
    for e in episodes:
        ep = steps[steps.episode == e]
        states, actions, flags = ep.state.to_numpy(), ep.action.to_numpy().astype(np.int64), ep["flags"].to_numpy()
        n, at = len(states), xy(states)
        seen, added, swapped = ({int(t): list(g.itertuples()) for t, g in df[df.episode == e].groupby("step")}
                                for df in (recog, unsafe, subs))
        rec.set_time("step", sequence=tick)
        rec.set_time("episode", sequence=e)
        log_unsafe()
        for (c, p), png in sorted(support.items()) if e == first else ():  # later: only the changes
            log(f"support/{c}/{p}", rr.EncodedImage(contents=png, media_type="image/png"))
        if e - 1 in q:  # the Q table the episode starts from
            tensor("q_values/max", q[e - 1].max(axis=1))
        if n:  # one row per recorded step on each of these entities
            ticks = [rr.TimeColumn("step", sequence=np.arange(tick, tick + n)),
                     rr.TimeColumn("episode", sequence=np.full(n, e))]
            colour = np.where((flags & S.FLAG_COLLIDED)[:, None] != 0, RED,
                              np.where((flags & S.FLAG_RESELECTED)[:, None] != 0, [255, 140, 0], [30, 30, 200]))
            for entity, columns in (
                    ("maze/robot", rr.Points2D.columns(positions=at, radii=np.full(n, 0.3, np.float32),
                                                       labels=[f"ep {e} step {t}" for t in range(n)])),
                    ("maze/robot/action", rr.Arrows2D.columns(origins=at, vectors=moves[actions] * 0.4,
                                                              colors=colour.astype(np.uint8))),
                    ("maze/robot/trajectory", rr.LineStrips2D.columns(strips=[at[:t + 1] for t in range(n)])),
                    ("metrics/return", rr.Scalars.columns(scalars=np.cumsum(ep.reward.to_numpy(np.float64))))):
                rec.send_columns(entity, indexes=ticks, columns=columns)
        if not q:
            tensor("derived/visits", visits)
        visits += np.bincount(states, minlength=visits.size)
        for t in sorted({int(x) for x in np.flatnonzero(flags)} | seen.keys() | added.keys() | swapped.keys()):
            rec.set_time("step", sequence=tick + t)
            where = f"run {run} ep {e} step {t}: "
            if f := int(flags[t]):
                log("events", f"{where}cell {int(states[t])} action {act(int(actions[t]))}: "
                    + ", ".join(name for name, bit in S.FLAG_NAMES.items() if f & bit),
                    level="ERROR" if f & S.FLAG_COLLIDED else "WARN" if f & S.FLAG_RESELECTED else "INFO")
            for r in seen.get(t, ()):
                picture("recognition/picture", int(r.picture))
                sc = np.array([getattr(r, c) for c in score_cols], dtype=np.float32)
                if score_cols and not np.isnan(sc).all():
                    log("recognition/scores", rr.BarChart(np.nan_to_num(sc)))
                log("recognition/result", rr.TextDocument(
                    f"### picture {int(r.picture)}\n\nrun {run}, episode {e}, step {t}, cell {int(r.state)}, "
                    f"action {act(int(r.action))}\n\npredicted **{cat(int(r.predicted))}**, true **{cat(int(r.true))}**: "
                    + ("recognised: unsafe pair added, action reselected" if r.predicted == r.true
                       else "misrecognised: collision, picture substitutes into the support set"),
                    media_type="text/markdown"))
            if t in added:
                ad.extend([int(u.state), int(u.action)] for u in added[t])
                log_unsafe()
                for u in added[t]:
                    log("events", f"{where}({int(u.state)}, {act(int(u.action))}) joins A_d "
                                  f"({S.SOURCE_NAMES[int(u.source)]})")
            for s in swapped.get(t, ()):
                c, p, pid = int(s.category), int(s.position), int(s.picture)
                picture(f"support/{c}/{p}", pid)
                log("events", f"{where}picture {pid} replaces shot {p} of {cat(c)} in the support set")
        tick += n
        rec.set_time("step", sequence=max(tick - 1, 0))
        if not q:
            tensor("derived/visits", visits)
        if e in q:
            tensor("q_values/max", q[e].max(axis=1))
    rec.flush()
    rec.disconnect()
    return out

