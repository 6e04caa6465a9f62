"""What happened in one run of the records, drawn the same way in every world's replay (issue 30:
the replay of a robot cell and of a grid cell share their drawing code): the names of categories
and actions (the file's maze metadata), the recognition views (the picture seen, its relation
scores (eq. 2) and the verdict: the robot stopped or drove on), the events log, the support set
(section 3.3) and the unsafe set A_d (eqs. 7-8).

:class:`Story` draws them. A world's replay subclasses it with its scene and its clock:
:class:`.draw.Replay` (the grid, timeline ``step``) and
:class:`.robot3d.RobotReplay` (the robot in 3D, timeline ``sim_time``). A subclass
says when a step's events happened (:meth:`Story.when`, :meth:`Story.at`) and draws A_d in its
scene (:meth:`Story.log_unsafe`).
"""

from __future__ import annotations

import abc

import numpy as np

from pipeline import palette
from pipeline.errors import UserError
from pipeline.records import Records
from pipeline.records import schema as S

from .notes import EmptyViews, log_empty
from .panels import SupportGrid, blueprint, categories_context, colour

#: (d_row, d_col) of files without moves
NESW = {"N": (-1, 0), "E": (0, 1), "S": (1, 0), "W": (0, -1)}
#: The support set's shots a category (the paper's K) when the file holds no support pictures.
SHOTS = 5
FREE, START, GOAL, RED, ORANGE, ROBOT = map(
    palette.rgb,
    (palette.FREE, palette.START, palette.GOAL, palette.UNSAFE, palette.RESELECTED, palette.ROBOT),
)


class ReplayError(UserError):
    """The run/episode is not in the records, or they cannot be drawn; ``key`` is the config key to
    blame (``"file"`` for a record file that cannot be read or drawn)."""

    def __init__(self, message: str, key: str = "run/episode"):
        super().__init__(message)
        self.key = key


class Story(abc.ABC):
    """Run ``run`` of the records ``recs``, told into the recording stream ``rec``: what every
    world's replay shows. Subclasses set :meth:`when` / :meth:`at` and :meth:`log_unsafe`, and may
    mark a step's outcome in their scene (:meth:`stopped`, :meth:`collided_where`)."""

    #: Where the picture seen goes (a 2D image: never inside a 3D space without a pinhole above
    #: it), and the corners of what its view shows when no picture comes.
    picture_entity = "recognition/picture"
    picture_box = ((-1.0, -1.0), (1.0, 1.0))

    def __init__(self, rec, recs: Records, run: int):
        meta, mz = recs.meta, recs.meta.maze
        self.rec, self.meta, self.run = rec, meta, run
        self.cats = mz.get("categories") or []
        self.names = mz.get("actions") or list(NESW)
        self.steps, self.recog, self.unsafe, self.subs = (
            df[df.run == run]
            for df in (recs.steps, recs.recognitions, recs.unsafe, recs.substitutions)
        )
        self.subs = self.subs[self.subs.picture >= 0]
        self.score_cols = [c for c in self.recog.columns if c.startswith("score_")]
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
        self.check_recognitions()
        shots = max([0, *(p + 1 for _, p in meta.support_pictures), *(self.subs.position + 1)])
        self.grid = SupportGrid(
            rec, self.labels, shots if meta.support_pictures else max(shots, SHOTS)
        )
        self.ad: list[list[int]] = []

    # ---------------------------------------------------------------- names
    def cat(self, c: int) -> str:
        """Category ``c``'s name; -1 is a recognition that named none (no category reached)."""
        if c == -1:
            return "no category"
        return self.cats[c] if 0 <= c < len(self.cats) else f"category {c}"

    def act(self, a: int) -> str:
        return self.names[a] if 0 <= a < len(self.names) else f"action {a}"

    def obstacle_label(self, o: dict) -> str:
        """An obstacle of the run's placement on hover: category, instance and orientation."""
        return f"{self.cat(o['category'])} #{o['instance']} r{o['orientation']}"

    def check_recognitions(self) -> None:
        """Every recognition names a category of the file: ``true`` one of them, ``predicted`` one of
        them or -1 (none reached); else the records are not of this maze (one :class:`ReplayError`
        naming the file, the field and the first odd row)."""
        n, rows = len(self.labels), self.recog
        odd = rows[~rows["true"].between(0, n - 1) | ~rows["predicted"].between(-1, n - 1)]
        if len(odd):
            r = odd.iloc[0]
            field, value = (
                ("true", r["true"]) if not 0 <= r["true"] < n else ("predicted", r["predicted"])
            )
            raise ReplayError(
                f"{self.meta.path}: recognitions.{field}: category {int(value)} at run {self.run} "
                f"episode {int(r.episode)} step {int(r.step)} is not one of the file's {n} "
                f"categories ({', '.join(self.labels)}; maze metadata 'categories')",
                key="file",
            )

    def log(self, entity: str, what, level: str = "INFO", **kw) -> None:
        """Log an archetype, or a text as a TextLog line of ``level``."""
        import rerun as rr

        self.rec.log(entity, rr.TextLog(what, level=level) if isinstance(what, str) else what, **kw)

    # ---------------------------------------------------------------- the world's (a subclass's)
    @abc.abstractmethod
    def blueprint(self, name: str, empty: EmptyViews):
        """The viewer's layout (:meth:`layout` around the world's views); ``name``: the recording's."""

    @abc.abstractmethod
    def draw(self, episodes: list[int], empty: EmptyViews) -> None:
        """Every step of ``episodes`` (consecutive recorded episodes of the run), after what the run
        held before them (:meth:`begin`); ``empty``: why views stay empty."""

    @abc.abstractmethod
    def when(self, t: int, picture: int | None = None, contact: bool = False) -> float:
        """The moment of step ``t`` of the episode being drawn, on the world's timeline; ``picture``:
        of the episode's recognition number ``picture``; ``contact``: of step ``t``'s collision."""

    @abc.abstractmethod
    def at(self, moment: float, t: int | None = None) -> None:
        """Set the recording's time to ``moment`` (a value of :meth:`when`), of step ``t`` of the
        episode being drawn when given."""

    @abc.abstractmethod
    def log_unsafe(self) -> None:
        """Draw A_d (``self.ad``, pairs (cell, action)) in the world's scene, at the current time."""

    def stopped(self, r, number: int) -> None:
        """Recognition ``r`` (the episode's ``number``-th) stopped the robot before the obstacle:
        mark it in the scene at the current time (the grid's action arrow shows it already)."""
        return None

    def collided_where(self, t: int) -> str:
        """What the events line of step ``t``'s collision adds: where, and what it hit."""
        return ""

    # ---------------------------------------------------------------- what does not change
    def layout(self, world, empty: EmptyViews, **views):
        """The viewer's layout around the world's views ``world`` (and ``views``: the picture view
        and the legend, :func:`.panels.blueprint`); the scores view says in its name why it is
        empty (``empty``)."""
        scores = "relation scores" + (f": {empty.scores_short}" if empty.scores else "")
        return blueprint(world, self.grid.bounds(), scores, **views)

    def begin(self, first: int, empty: EmptyViews) -> None:
        """What the replay of episodes from ``first`` starts from, at the current time: the category
        names and colours, why empty views are empty, and A_d and the support set as the run's
        earlier episodes left them."""
        self.log("/", categories_context(self.labels), static=True)
        log_empty(self.rec, empty, self.picture_entity, self.picture_box)
        self.ad = self.unsafe[self.unsafe.episode < first][["state", "action"]].to_numpy().tolist()
        self.start_support(first)

    def start_support(self, first: int) -> None:
        """The support set the replay starts from: the file's initial pictures with the run's earlier
        substitutions applied (framed); a note when the file holds no support pictures."""
        self.grid.frame(bool(self.meta.support_pictures))
        support = {k: (png, None) for k, png in self.meta.support_pictures.items()}
        for s in self.subs[self.subs.episode < first].itertuples():
            if int(s.picture) in self.meta.pictures:
                support[(int(s.category), int(s.position))] = (
                    self.meta.pictures[int(s.picture)],
                    self.mark(s),
                )
        for (c, p), (png, mark) in sorted(support.items()):
            self.grid.put(c, p, png, mark)

    @staticmethod
    def mark(s) -> str:
        """The label of a substituted support picture: when it came in."""
        return f"ep {int(s.episode)} t {int(s.step)}"

    # ---------------------------------------------------------------- the recognition views
    def picture(self, entity: str, pid: int) -> None:
        """Picture ``pid`` of the file (a grid's query picture, a robot's live picture)."""
        import rerun as rr

        if pid in self.meta.pictures:
            self.log(
                entity, rr.EncodedImage(contents=self.meta.pictures[pid], media_type="image/png")
            )

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

    def recognition(self, r, e: int, t: int, verdict: str) -> None:
        """The picture seen, its labelled scores, and what was predicted, what is true, the
        ``verdict`` and a table of the scores."""
        import rerun as rr

        self.picture(self.picture_entity, int(r.picture))
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
        right = "right" if int(r.predicted) == int(r.true) else "wrong"
        self.log(
            "recognition/result",
            rr.TextDocument(
                f"### picture {int(r.picture)}\n\nrun {self.run}, episode {e}, step {t}, "
                f"cell {int(r.state)}, action {self.act(int(r.action))}\n\npredicted "
                f"**{self.cat(int(r.predicted))}**, true **{self.cat(int(r.true))}** ({right}): "
                + verdict
                + table,
                media_type="text/markdown",
            ),
        )

    def verdict(self, r, drove_on: bool, flags: int, substituted: bool) -> str:
        """What recognition ``r`` led to, from what the step did (any decision rule): the robot
        stopped before the obstacle ((s, a) joins A_d, the action is reselected; eqs. 7-8), or drove
        on into it (a collision, self-recovery, the picture substituted into the support set)."""
        if not drove_on:
            pair = f"({int(r.state)}, {self.act(int(r.action))})"
            return f"stopped before it: {pair} joins A_d, the action is reselected"
        return (
            "drove on: collision"
            + (", self-recovery" if flags & S.FLAG_RECOVERED else "")
            + (", the picture substitutes into the support set" if substituted else "")
        )

    # ---------------------------------------------------------------- what changes
    def events(self, e: int, states, actions, flags) -> None:
        """The steps of episode ``e`` where something happened, each at its moment (:meth:`when`):
        flags, recognitions, A_d additions, substitutions."""
        ep_recog = self.recog[self.recog.episode == e]
        number = {idx: k for k, idx in enumerate(ep_recog.index)}  # the episode's k-th recognition
        seen, added, swapped = (
            {int(t): list(g.itertuples()) for t, g in df[df.episode == e].groupby("step")}
            for df in (ep_recog, self.unsafe, self.subs)
        )
        for t in sorted(
            {int(x) for x in np.flatnonzero(flags)} | seen.keys() | added.keys() | swapped.keys()
        ):
            where = f"run {self.run} ep {e} step {t}: "
            f = int(flags[t]) if t < len(flags) else 0
            if f:
                self.at(self.when(t, contact=bool(f & S.FLAG_COLLIDED)), t)
                self.log(
                    "events",
                    f"{where}cell {int(states[t])} action {self.act(int(actions[t]))}: "
                    + ", ".join(
                        name + (self.collided_where(t) if bit == S.FLAG_COLLIDED else "")
                        for name, bit in S.FLAG_NAMES.items()
                        if f & bit
                    ),
                    level="ERROR"
                    if f & S.FLAG_COLLIDED
                    else "WARN"
                    if f & S.FLAG_RESELECTED
                    else "INFO",
                )
            rows, subs = seen.get(t, []), swapped.get(t, [])
            for i, r in enumerate(rows):
                executed = t < len(actions) and int(r.action) == int(actions[t])
                drove_on = i == len(rows) - 1 and executed and bool(f & S.FLAG_COLLIDED)
                substituted = any(int(s.picture) == int(r.picture) for s in subs)
                self.at(self.when(t, picture=number[r.Index]), t)
                verdict = self.verdict(r, drove_on, f, substituted)
                self.recognition(r, e, t, verdict)
                right = "right" if int(r.predicted) == int(r.true) else "wrong"
                self.log(
                    "events",
                    f"{where}picture {int(r.picture)}: predicted {self.cat(int(r.predicted))}, "
                    f"true {self.cat(int(r.true))} ({right}): {verdict}",
                )
                if not drove_on:
                    self.stopped(r, number[r.Index])
            self.additions(e, t, added.get(t, []), rows, number)
            if subs:
                self.at(self.when(t, contact=True), t)
            for s in subs:
                c, p, pid = int(s.category), int(s.position), int(s.picture)
                if pid in self.meta.pictures:
                    self.grid.put(c, p, self.meta.pictures[pid], self.mark(s))
                self.log(
                    "events",
                    f"{where}picture {pid} replaces shot {p} of {self.cat(c)} in the support set",
                )

    def additions(self, e: int, t: int, added: list, rows: list, number: dict) -> None:
        """The pairs step ``t`` added to A_d: a recognition's at the moment of its picture, a
        collision's (and SSRL's rule's) at the collision; A_d redrawn once a moment."""
        moments: dict[float, list] = {}
        for u in added:
            by = [r for r in rows if (int(r.state), int(r.action)) == (int(u.state), int(u.action))]
            if S.SOURCE_NAMES[int(u.source)] == "recognition" and by:
                moment = self.when(t, picture=number[by[-1].Index])
            else:
                moment = self.when(t, contact=True)
            moments.setdefault(moment, []).append(u)
        for moment, group in moments.items():
            self.at(moment, t)
            self.ad.extend([int(u.state), int(u.action)] for u in group)
            self.log_unsafe()
            for u in group:
                self.log(
                    "events",
                    f"run {self.run} ep {e} step {t}: ({int(u.state)}, {self.act(int(u.action))}) "
                    f"joins A_d ({S.SOURCE_NAMES[int(u.source)]})",
                )
