"""Drawing one run of the records into a Rerun recording stream (:class:`Replay`): the maze, the
obstacles in their category colours, the unsafe set, the robot's path, every recognition with its
scores and every support-set change, on the timelines ``step`` and ``episode``.
"""

from __future__ import annotations

import numpy as np

from pipeline import palette
from pipeline.records import Records
from pipeline.records import schema as S

from .notes import EmptyViews, log_empty
from .panels import (
    SupportGrid,
    blueprint,
    categories_context,
    colour,
    heat_rgb,
    legend_positions,
)

#: (d_row, d_col) of files without moves
NESW = {"N": (-1, 0), "E": (0, 1), "S": (1, 0), "W": (0, -1)}
P = palette
FREE, START, GOAL, RED, ORANGE, ROBOT = map(
    P.rgb, (P.FREE, P.START, P.GOAL, P.UNSAFE, P.RESELECTED, P.ROBOT)
)
SHOTS = (
    5  # the support set's shots a category (the paper's K) when the file holds no support pictures
)


class Replay:
    """Run ``run`` of the records ``recs`` drawn into the recording stream ``rec``."""

    def __init__(self, rec, recs: Records, run: int):
        meta, mz = recs.meta, recs.meta.maze
        self.rec, self.meta, self.run = rec, meta, run
        self.width, self.shape, self.cats = (
            mz["width"],
            (mz["height"], mz["width"]),
            mz.get("categories") or [],
        )
        self.names = mz.get("actions") or list(NESW)
        self.moves = np.array(mz.get("moves") or list(NESW.values()), np.float32)[
            :, ::-1
        ]  # as (x, y)
        self.steps, self.recog, self.unsafe, self.subs = (
            df[df.run == run]
            for df in (recs.steps, recs.recognitions, recs.unsafe, recs.substitutions)
        )
        self.subs = self.subs[self.subs.picture >= 0]
        self.score_cols = [c for c in self.recog.columns if c.startswith("score_")]
        self.q = {e: v for (_, r, e), v in recs.q_values.items() if r == run}
        n_cats = max(
            [
                len(self.cats),
                len(self.score_cols),
                *(c + 1 for c, _ in meta.support_pictures),
                *(self.subs.category + 1),
                *(o["category"] + 1 for o in meta.obstacles.get(run, [])),
            ]
        )
        self.labels = [self.cat(c) for c in range(n_cats)]
        shots = max([0, *(p + 1 for _, p in meta.support_pictures), *(self.subs.position + 1)])
        self.grid = SupportGrid(
            rec, self.labels, shots if meta.support_pictures else max(shots, SHOTS)
        )
        self.ad: list[list[int]] = []

    # ---------------------------------------------------------------- names and geometry
    def cat(self, c: int) -> str:
        return self.cats[c] if 0 <= c < len(self.cats) else f"category {c}"

    def act(self, a: int) -> str:
        return self.names[a] if 0 <= a < len(self.names) else f"action {a}"

    def xy(self, cells) -> np.ndarray:
        """Cell centres as (x, y) = (col, row) + 0.5."""
        rows, cols = np.divmod(np.asarray(cells, dtype=np.int64), self.width)
        return np.stack([cols, rows], axis=1).astype(np.float32) + 0.5

    def boxes(self, cells, size: float, **kw):
        import rerun as rr

        return rr.Boxes2D(
            mins=self.xy(cells) - size / 2, sizes=np.full((len(cells), 2), size), **kw
        )

    def log(self, entity: str, what, level: str = "INFO", **kw) -> None:
        """Log an archetype, or a text as a TextLog line of ``level``."""
        import rerun as rr

        self.rec.log(entity, rr.TextLog(what, level=level) if isinstance(what, str) else what, **kw)

    # ---------------------------------------------------------------- what does not change
    def blueprint(self, name: str, empty: EmptyViews):
        """The viewer's layout, with views that fit this maze and support set; the scores view
        says in its name why it is empty (``empty``)."""
        return blueprint(
            name,
            "max Q per cell" if self.q else "visits per cell (log scale)",
            *self.shape,
            legend_positions(*self.shape, len(self.labels) + 2)[1],
            self.grid.bounds(),
            "relation scores" + (f": {empty.scores_short}" if empty.scores else ""),
        )

    def draw_static(self) -> None:
        """The maze (cells; obstacles in their category colours, named in the legend right of the
        maze and on hover, so no text covers the robot), the category names and colours, the series."""
        import rerun as rr

        self.log("/", categories_context(self.labels), static=True)
        grid = np.array([list(r) for r in self.meta.maze["layout"]]).ravel()
        free = np.flatnonzero(grid != "X")
        self.log(
            "maze/cells",
            self.boxes(
                free,
                1.0,
                draw_order=0.0,
                colors=np.array(
                    [{"S": START, "G": GOAL}.get(ch, FREE) for ch in grid[free]], np.uint8
                ),
            ),
            static=True,
        )
        if obstacles := self.meta.obstacles.get(self.run, []):  # this run's assignment
            self.log(
                "maze/obstacles",
                self.boxes(
                    [o["cell"] for o in obstacles],
                    0.9,
                    draw_order=1.0,
                    class_ids=[o["category"] for o in obstacles],
                    show_labels=False,
                    labels=[
                        f"{self.cat(o['category'])} #{o['instance']} r{o['orientation']}"
                        for o in obstacles
                    ],
                ),
                static=True,
            )
            n = len(self.labels)
            at = legend_positions(*self.shape, n + 2)[0]
            self.log(
                "maze/legend",
                rr.Points2D(at[:n], radii=0.15, class_ids=np.arange(n), show_labels=True),
                static=True,
            )
            self.log(
                "maze/legend/cells",
                rr.Points2D(at[n:], radii=0.15, colors=[START, GOAL], labels=["start", "goal"]),
                static=True,
            )
        else:
            self.log(
                "maze/obstacles",
                self.boxes(np.flatnonzero(grid == "X"), 0.9, colors=[90, 90, 90], draw_order=1.0),
                static=True,
            )
        self.log("metrics/return", rr.SeriesLines(names="return"), static=True)

    # ---------------------------------------------------------------- what changes
    def log_unsafe(self) -> None:
        """The unsafe set A_d so far, as red arrows."""
        import rerun as rr

        arr = np.array(self.ad, dtype=np.int64).reshape(-1, 2)
        self.log(
            "maze/unsafe",
            rr.Arrows2D(
                origins=self.xy(arr[:, 0]),
                vectors=self.moves[arr[:, 1]] * 0.45,
                colors=RED,
                radii=0.04,
                draw_order=3.0,
            )
            if len(arr)
            else rr.Clear(recursive=False),
        )

    def heat(self, entity: str, values: np.ndarray, what: str) -> None:
        """``values`` per cell as a heat map aligned with the maze (one pixel a cell), with its range below."""
        import rerun as rr

        rgb, lo, hi = heat_rgb(values.reshape(self.shape), log=what == "visits")
        self.log(entity, rr.Image(rgb, draw_order=-5.0))
        self.log(
            f"{entity}/range",
            rr.Points2D(
                [[self.shape[1] / 2, self.shape[0] + 0.4]],
                radii=0.01,
                labels=[f"{what}: {lo:.4g} (dark) .. {hi:.4g} (yellow)"],
                show_labels=True,
            ),
        )

    def picture(self, entity: str, pid: int) -> None:
        import rerun as rr

        if pid in self.meta.pictures:
            self.log(
                entity, rr.EncodedImage(contents=self.meta.pictures[pid], media_type="image/png")
            )

    def start_support(self, first: int) -> None:
        """The support set the replay starts from: the file's initial pictures with the run's earlier
        substitutions applied (framed); a note when the file holds no support pictures."""
        self.grid.frame(bool(self.meta.support_pictures))
        support = {k: (png, None) for k, png in self.meta.support_pictures.items()}
        for s in self.subs[self.subs.episode < first].itertuples():
            if int(s.picture) in self.meta.pictures:
                support[(int(s.category), int(s.position))] = (
                    self.meta.pictures[int(s.picture)],
                    self.when(s),
                )
        for (c, p), (png, mark) in sorted(support.items()):
            self.grid.put(c, p, png, mark)

    @staticmethod
    def when(s) -> str:
        return f"ep {int(s.episode)} t {int(s.step)}"

    def scores(self, r) -> list[float] | None:
        """The relation scores of recognition ``r`` by category (None when the file has none), each
        category its own bar chart: the chart's legend names the bars."""
        import rerun as rr

        sc = np.array([getattr(r, c) for c in self.score_cols], dtype=np.float32)
        if not self.score_cols or np.isnan(sc).all():
            return None
        sc = np.nan_to_num(sc)
        for c, value in enumerate(sc):
            self.log(
                f"recognition/scores/{rr.escape_entity_path_part(self.labels[c])}",
                rr.BarChart([value], abscissa=[c], color=colour(c)),
            )
        return sc.tolist()

    def recognition(self, r, e: int, t: int) -> None:
        """The picture seen, its labelled scores and the verdict with a table of the scores."""
        import rerun as rr

        self.picture("recognition/picture", int(r.picture))
        sc = self.scores(r)
        table = (
            ""
            if sc is None
            else "\n\n| category | relation score |\n|---|---|\n"
            + "\n".join(
                f"| {'**' + self.cat(c) + '**' if c == int(r.predicted) else self.cat(c)} | {v:.3f} |"
                for c, v in enumerate(sc)
            )
        )
        self.log(
            "recognition/result",
            rr.TextDocument(
                f"### picture {int(r.picture)}\n\nrun {self.run}, episode {e}, step {t}, cell {int(r.state)}, "
                f"action {self.act(int(r.action))}\n\npredicted **{self.cat(int(r.predicted))}**, true "
                f"**{self.cat(int(r.true))}**: "
                + (
                    "recognised: unsafe pair added, action reselected"
                    if r.predicted == r.true
                    else "misrecognised: collision, picture substitutes into the support set"
                )
                + table,
                media_type="text/markdown",
            ),
        )

    def draw(self, episodes: list[int], empty: EmptyViews) -> None:
        """Every step of ``episodes`` (consecutive recorded episodes of the run), after what the run
        held before them: A_d, the support set and the visits; ``empty``: why views stay empty."""
        first = episodes[0]
        self.draw_static()
        log_empty(self.rec, empty)
        self.ad = self.unsafe[self.unsafe.episode < first][["state", "action"]].to_numpy().tolist()
        visits = np.bincount(
            self.steps[self.steps.episode < first].state.to_numpy(),
            minlength=self.shape[0] * self.width,
        )
        tick = 0
        for e in episodes:
            self.rec.set_time("step", sequence=tick)
            self.rec.set_time("episode", sequence=e)
            if e == first:
                self.start_support(first)
            tick = self.episode(e, tick, visits)

    def episode(self, e: int, tick: int, visits: np.ndarray) -> int:
        """Episode ``e`` from global step ``tick``; ``visits`` grows by its states. Returns the next tick."""
        import rerun as rr

        ep = self.steps[self.steps.episode == e]
        states, actions, flags = (
            ep.state.to_numpy(),
            ep.action.to_numpy().astype(np.int64),
            ep["flags"].to_numpy(),
        )
        n, at = len(states), self.xy(states)
        self.log_unsafe()
        if e - 1 in self.q:  # the Q table the episode starts from
            self.heat("q_values/max", self.q[e - 1].max(axis=1), "max Q")
        if n:  # one row per recorded step on each of these entities
            ticks = [
                rr.TimeColumn("step", sequence=np.arange(tick, tick + n)),
                rr.TimeColumn("episode", sequence=np.full(n, e)),
            ]
            colours = np.where(
                (flags & S.FLAG_COLLIDED)[:, None] != 0,
                RED,
                np.where((flags & S.FLAG_RESELECTED)[:, None] != 0, ORANGE, ROBOT),
            )
            for entity, columns in (
                (
                    "maze/robot",
                    rr.Points2D.columns(
                        positions=at,
                        radii=np.full(n, 0.25, np.float32),
                        colors=np.tile(ROBOT, (n, 1)),
                    ),
                ),
                (
                    "maze/robot/action",
                    rr.Arrows2D.columns(
                        origins=at,
                        vectors=self.moves[actions] * 0.4,
                        colors=colours.astype(np.uint8),
                    ),
                ),
                (
                    "maze/robot/trajectory",
                    rr.LineStrips2D.columns(
                        strips=[at[: t + 1] for t in range(n)], colors=np.tile(ROBOT, (n, 1))
                    ),
                ),
                (
                    "metrics/return",
                    rr.Scalars.columns(scalars=np.cumsum(ep.reward.to_numpy(np.float64))),
                ),
            ):
                self.rec.send_columns(entity, indexes=ticks, columns=columns)
        if not self.q:
            self.heat("derived/visits", visits, "visits")
        visits += np.bincount(states, minlength=visits.size)
        self.events(e, tick, states, actions, flags)
        tick += n
        self.rec.set_time("step", sequence=max(tick - 1, 0))
        if not self.q:
            self.heat("derived/visits", visits, "visits")
        if e in self.q:
            self.heat("q_values/max", self.q[e].max(axis=1), "max Q")
        return tick

    def events(self, e: int, tick: int, states, actions, flags) -> None:
        """The steps of episode ``e`` where something happened: flags, recognitions, A_d, substitutions."""
        seen, added, swapped = (
            {int(t): list(g.itertuples()) for t, g in df[df.episode == e].groupby("step")}
            for df in (self.recog, self.unsafe, self.subs)
        )
        for t in sorted(
            {int(x) for x in np.flatnonzero(flags)} | seen.keys() | added.keys() | swapped.keys()
        ):
            self.rec.set_time("step", sequence=tick + t)
            where = f"run {self.run} ep {e} step {t}: "
            if f := int(flags[t]):
                self.log(
                    "events",
                    f"{where}cell {int(states[t])} action {self.act(int(actions[t]))}: "
                    + ", ".join(name for name, bit in S.FLAG_NAMES.items() if f & bit),
                    level="ERROR"
                    if f & S.FLAG_COLLIDED
                    else "WARN"
                    if f & S.FLAG_RESELECTED
                    else "INFO",
                )
            for r in seen.get(t, ()):
                self.recognition(r, e, t)
            if t in added:
                self.ad.extend([int(u.state), int(u.action)] for u in added[t])
                self.log_unsafe()
                for u in added[t]:
                    self.log(
                        "events",
                        f"{where}({int(u.state)}, {self.act(int(u.action))}) joins A_d "
                        f"({S.SOURCE_NAMES[int(u.source)]})",
                    )
            for s in swapped.get(t, ()):
                c, p, pid = int(s.category), int(s.position), int(s.picture)
                if pid in self.meta.pictures:
                    self.grid.put(c, p, self.meta.pictures[pid], self.when(s))
                self.log(
                    "events",
                    f"{where}picture {pid} replaces shot {p} of {self.cat(c)} in the support set",
                )
