"""What happened in one run of the records, drawn the same way in every world's replay: the names
of categories and actions (the file's maze metadata), the recognition views (the picture seen, its
relation scores (eq. 2) and the verdict: the robot stopped or drove on), the events log, the
support set (section 3.3) and the unsafe set A_d (eqs. 7-8).

:class:`Story` draws them. A world's replay subclasses it with its scene and its clock:
:class:`.draw.Replay` (the grid, timeline ``step``) and
:class:`.robot3d.RobotReplay` (the robot in 3D, timeline ``sim_time``). A subclass
draws what does not change and each episode (:meth:`Story.draw_static`, :meth:`Story.episode`),
says when a step's events happened (:meth:`Story.when`, :meth:`Story.at`) and how A_d looks in
its scene (:meth:`Story.unsafe_arrows`).
"""

from __future__ import annotations

import abc

import numpy as np
import rerun as rr

from pipeline import palette
from pipeline.records import Records
from pipeline.records import schema as S

from .notes import EmptyViews, ReplayError
from .panels import SupportGrid, blueprint, categories_context, colour

#: (d_row, d_col) of files without moves
NESW = {"N": (-1, 0), "E": (0, 1), "S": (1, 0), "W": (0, -1)}
#: The support set's shots a category (the paper's K) when the file holds no support pictures.
SHOTS = 5
FREE, START, GOAL, RED, ORANGE, ROBOT = map(
    palette.rgb,
    (palette.FREE, palette.START, palette.GOAL, palette.UNSAFE, palette.RESELECTED, palette.ROBOT),
)


class Story(abc.ABC):
    """Run ``run`` of the records ``recs``, told into the recording stream ``rec``: what every
    world's replay shows. Subclasses draw the world (the abstract methods), and may mark a step's
    outcome in their scene (:meth:`stopped`, :meth:`collided_where`)."""

    #: Where the picture seen goes (a 2D image: never inside a 3D space without a pinhole above
    #: it), and the corners of what its view shows when no picture comes.
    picture_entity = "recognition/picture"
    picture_box = ((-1.0, -1.0), (1.0, 1.0))
    #: Where the world's scene shows A_d.
    unsafe_entity = "maze/unsafe"

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
        self.rec.log(entity, rr.TextLog(what, level=level) if isinstance(what, str) else what, **kw)

    # ---------------------------------------------------------------- the world's (a subclass's)
    @abc.abstractmethod
    def blueprint(self, name: str, empty: EmptyViews):
        """The viewer's layout (:meth:`layout` around the world's views); ``name``: the recording's."""

    @abc.abstractmethod
    def draw_static(self) -> None:
        """What does not change: the world's scene, its legend, the series."""

    @abc.abstractmethod
    def episode(self, e: int, start: float) -> float:
        """Every step of episode ``e`` from ``start`` on the world's timeline (at the time of its
        first step); returns where the next episode starts."""

    @abc.abstractmethod
    def when(self, t: int, picture: int | None = None, contact: bool = False) -> float:
        """The moment of step ``t`` of the episode being drawn, on the world's timeline; ``picture``:
        of the episode's recognition number ``picture``; ``contact``: of step ``t``'s collision."""

    @abc.abstractmethod
    def at(self, moment: float, t: int | None = None) -> None:
        """Set the recording's time to ``moment`` (a value of :meth:`when`), of step ``t`` of the
        episode being drawn when given."""

    @abc.abstractmethod
    def unsafe_arrows(self, pairs: np.ndarray):
        """A_d's ``pairs`` (cell, action; at least one) in the world's scene: arrows from each
        pair's cell toward its move."""

    def stopped(self, r, number: int) -> None:
        """Recognition ``r`` (the episode's ``number``-th) stopped the robot before the obstacle:
        mark it in the scene at the current time (the grid's action arrow shows it already)."""
        return None

    def collided_where(self, t: int) -> str:
        """What the events line of step ``t``'s collision adds: where, and what it hit."""
        return ""

    # ---------------------------------------------------------------- what does not change
    def draw(self, episodes: list[int], empty: EmptyViews) -> None:
        """Every step of ``episodes`` (consecutive recorded episodes of the run, back to back on the
        world's timeline), after what the run held before them (:meth:`begin`); ``empty``: why
        views stay empty."""
        self.draw_static()
        self.at(0.0)
        self.rec.set_time("episode", sequence=episodes[0])
        self.begin(episodes[0], empty)
        start = 0.0
        for e in episodes:
            self.rec.set_time("episode", sequence=e)
            start = self.episode(e, start)

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
        self.log_empty(empty)
        self.ad = self.unsafe[self.unsafe.episode < first][["state", "action"]].to_numpy().tolist()
        self.start_support(first)

    def start_support(self, first: int) -> None:
        """The support set the replay starts from: the file's initial pictures with the run's earlier
        substitutions applied (framed); a note when the file holds no support pictures."""
        self.grid.frame(bool(self.meta.support_pictures))
        support = {k: (png, None) for k, png in self.meta.support_pictures.items()}
        for s in self.subs[self.subs.episode < first].itertuples():
            if int(s.picture) in self.meta.pictures:
                png = self.meta.pictures[int(s.picture)]
                support[(int(s.category), int(s.position))] = (png, self.mark(s))
        for (c, p), (png, mark) in sorted(support.items()):
            self.grid.put(c, p, png, mark)

    @staticmethod
    def mark(s) -> str:
        """The label of a substituted support picture: when it came in."""
        return f"ep {int(s.episode)} t {int(s.step)}"

    def log_empty(self, empty: EmptyViews) -> None:
        """Say in the picture and recognition views why they stay empty (static: for every step);
        the picture's view shows :attr:`picture_box` (two corners) without pictures."""
        if empty.recognition is None:
            return
        self.log(
            "recognition/result",
            rr.TextDocument(
                f"### No recognition to show\n\n{empty.recognition}.", media_type="text/markdown"
            ),
            static=True,
        )
        (x0, y0), (x1, y1) = self.picture_box
        self.log(  # the corners keep the label, centred on the middle point, inside the view
            f"{self.picture_entity}/note",
            rr.Points2D(
                [[x0, y0], [(x0 + x1) / 2, (y0 + y1) / 2], [x1, y1]],
                radii=[0.0, 0.01, 0.0],
                labels=["", "no picture seen: see the recognition view", ""],
                show_labels=True,
            ),
            static=True,
        )

    # ---------------------------------------------------------------- the recognition views
    def scores(self, r) -> list[float] | None:
        """The relation scores of recognition ``r`` by category (None when the file has none), each
        category its own bar chart: the chart's legend names the bars."""
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
        """The picture seen (the file's picture: a grid's query picture, a robot's live picture), its
        labelled scores, and what was predicted, what is true, the ``verdict`` and a table of the
        scores; and the line of the events log that says so."""
        if int(r.picture) in self.meta.pictures:
            png = self.meta.pictures[int(r.picture)]
            self.log(self.picture_entity, rr.EncodedImage(contents=png, media_type="image/png"))
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
        self.log(
            "events",
            f"run {self.run} ep {e} step {t}: picture {int(r.picture)}: predicted "
            f"{self.cat(int(r.predicted))}, true {self.cat(int(r.true))} ({right}): {verdict}",
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
    def log_unsafe(self) -> None:
        """A_d so far (``self.ad``) in the world's scene (:meth:`unsafe_arrows`), at the current time."""
        pairs = np.array(self.ad, dtype=np.int64).reshape(-1, 2)
        arrows = self.unsafe_arrows(pairs) if len(pairs) else rr.Clear(recursive=False)
        self.log(self.unsafe_entity, arrows)

    def events(self, e: int, states, actions, flags) -> None:
        """The steps of episode ``e`` where something happened, each at its moment (:meth:`when`):
        flags, recognitions, A_d additions, substitutions."""
        ep_recog = self.recog[self.recog.episode == e]
        number = {idx: k for k, idx in enumerate(ep_recog.index)}  # the episode's k-th recognition
        seen, added, swapped = (
            {int(t): list(g.itertuples()) for t, g in df[df.episode == e].groupby("step")}
            for df in (ep_recog, self.unsafe, self.subs)
        )
        flagged = {int(x) for x in np.flatnonzero(flags)}
        for t in sorted(flagged | seen.keys() | added.keys() | swapped.keys()):
            where = f"run {self.run} ep {e} step {t}: "
            f = int(flags[t]) if t < len(flags) else 0
            if f:
                self.at(self.when(t, contact=bool(f & S.FLAG_COLLIDED)), t)
                level = (
                    "ERROR" if f & S.FLAG_COLLIDED else "WARN" if f & S.FLAG_RESELECTED else "INFO"
                )
                self.log(
                    "events",
                    f"{where}cell {int(states[t])} action {self.act(int(actions[t]))}: "
                    + ", ".join(
                        name + (self.collided_where(t) if bit == S.FLAG_COLLIDED else "")
                        for name, bit in S.FLAG_NAMES.items()
                        if f & bit
                    ),
                    level=level,
                )
            rows, subs = seen.get(t, []), swapped.get(t, [])
            for i, r in enumerate(rows):
                executed = t < len(actions) and int(r.action) == int(actions[t])
                drove_on = i == len(rows) - 1 and executed and bool(f & S.FLAG_COLLIDED)
                substituted = any(int(s.picture) == int(r.picture) for s in subs)
                self.at(self.when(t, picture=number[r.Index]), t)
                self.recognition(r, e, t, self.verdict(r, drove_on, f, substituted))
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
