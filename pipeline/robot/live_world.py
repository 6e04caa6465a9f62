"""The camera robot as a world of the one runner (``pipeline.rl.run_world.World``): what each run's
robot meets in MuJoCo.

A run of the robot world has the grid run's obstacles (the same ``run_seeds``: a robot run and a grid
run with the same seed meet the same obstacles), built as a MuJoCo maze
(:func:`pipeline.robot.world.build_world`). At every dangerous pair (s, a) (eq. 4) the robot stands
on ``s``'s centre facing ``a``, its range sensor finds the neighbour occupied (checked: the layout
and the sensor agree on every neighbour of every free cell), and its camera takes the **live
picture** the recognisers are asked about: the centre 84 x 84 of its 62.2 x 48.8 degree frame. A run's
live pictures get their own picture ids, the next free ones, so the runner's tables, the
records' ``/pictures/<id>`` and the replay treat them as they treat the grid's query pictures.

The outcome of a move is the grid's (the motion table, :mod:`.motion`, checks that a free neighbour
is reached and an obstacle's box always hit); what the robot adds is its own pictures, and its
poses, which the records keep as the motion table plus the grid's steps.

Rendering a run's pictures (7x7: 42 pictures, about 1 s) is the robot world's cost; the pictures of
a run are kept (:func:`rendered_run`), so the cells of one process that share a maze, a seed and
the robot's settings render them once.
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from PIL import Image

from pipeline.rl.run_world import RunWorld, run_placement
from pipeline.robot.limits import DEFAULT_CELL, DEFAULT_TIMESTEP, check_settings
from pipeline.robot.motion import motion_table
from pipeline.robot.sim import RobotSim
from pipeline.robot.world import MAX_SEEN_OBSTACLES, RENDER_GEOMS
from pipeline.world.geometry import Geometry, build_geometry
from pipeline.world.layout import Layout, parse_layout
from pipeline.world.placement import picture_table

PICTURE_SIZE = 84  # the recognisers' input (the paper's 84 x 84)
#: The most live pictures one cell's records can name (picture ids are int16 in the records).
MAX_PICTURES = 32_767


@dataclass(frozen=True)
class RobotSettings:
    """The robot world's settings (``robot`` in ``conf/trials.yaml``; ranges in :mod:`.world`)."""

    cell: float = DEFAULT_CELL
    timestep: float = DEFAULT_TIMESTEP

    def __post_init__(self):
        check_settings(self.cell, self.timestep)


@dataclass(frozen=True)
class RenderedRun:
    """One run's live pictures, in the order of its dangerous pairs ``pairs`` (k, 2: s, a)."""

    pairs: np.ndarray
    images: np.ndarray  # (k, 84, 84, 3) uint8
    query: np.ndarray  # (k,) the query picture of the same face (grid's ``pictures[s, a]``)
    category: np.ndarray  # (k,) the true category of the obstacle seen


@lru_cache(maxsize=1024)
def rendered_run(
    rows: tuple[str, ...], seed: int, run: int, settings: RobotSettings
) -> RenderedRun:
    """Render run ``run``'s live pictures in the maze ``rows`` (and check its range sensor)."""
    layout = parse_layout("\n".join(rows))
    geometry = build_geometry(layout)
    placement = run_placement(geometry, seed, run)
    sim = RobotSim(layout, placement, settings.cell, settings.timestep)
    try:
        _check_range_sensor(sim, geometry)
        pairs = np.argwhere(geometry.obstacle >= 0)
        images = np.zeros((len(pairs), PICTURE_SIZE, PICTURE_SIZE, 3), np.uint8)
        for k, (s, a) in enumerate(pairs):
            sim.place(int(s), int(a))
            images[k] = sim.picture(PICTURE_SIZE)
    finally:
        sim.close()
    query = picture_table(geometry, placement)[pairs[:, 0], pairs[:, 1]]
    category = placement.category[geometry.obstacle[pairs[:, 0], pairs[:, 1]]]
    return RenderedRun(pairs, images, query.astype(np.int16), category.astype(np.int8))


def _check_range_sensor(sim: RobotSim, geometry: Geometry) -> None:
    """The range sensor and the layout agree on every on-grid neighbour of every free cell."""
    layout = geometry.layout
    for s in range(layout.n_cells):
        if s in layout.obstacles:
            continue
        sim.place(s, 0)
        scan = sim.scan()
        for a in range(4):
            if not sim.inside(s, a):
                continue
            if sim.occupied(a, scan) != (geometry.obstacle[s, a] >= 0):
                raise RuntimeError(
                    f"the robot's range sensor and the layout disagree at cell {s}, action {a} "
                    f"(cell size {sim.map.cell} m)"
                )


def png(image: np.ndarray) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(np.asarray(image, np.uint8)).save(buf, format="PNG", optimize=False)
    return buf.getvalue()


@lru_cache(maxsize=1024)
def run_pngs(
    rows: tuple[str, ...], seed: int, run: int, settings: RobotSettings
) -> tuple[bytes, ...]:
    """Run ``run``'s live pictures as PNG bytes (what the records keep), encoded once."""
    return tuple(png(im) for im in rendered_run(rows, seed, run, settings).images)


class RobotWorld:
    """The camera robot in MuJoCo, as the runner's world. ``live_pictures``: render the live pictures
    (methods that reason with pictures); without them a run is its placement and no pictures."""

    name = "robot3d"

    def __init__(self, layout: Layout, settings: RobotSettings, live_pictures: bool = True):
        n = len(layout.obstacles)
        if live_pictures and n > MAX_SEEN_OBSTACLES:
            raise ValueError(
                f"maze {layout.name} has {n:,} obstacles; the robot's camera sees a maze of at "
                f"most {MAX_SEEN_OBSTACLES:,} (MuJoCo's renderer draws {RENDER_GEOMS:,} geoms, an "
                "obstacle up to 8): use a smaller maze, world=grid, or a method without pictures"
            )
        self.layout, self.settings, self.live_pictures = layout, settings, live_pictures
        self._rendered: dict[tuple[int, int], int] = {}  # (seed, run) -> index in _order
        self._order: list[tuple[int, int, int, RenderedRun]] = []  # (first id, seed, run, pictures)
        self._latest: dict[int, int] = {}  # run -> index in _order of its latest rendering

    @property
    def n_pictures(self) -> int:
        return self._order[-1][0] + len(self._order[-1][3].pairs) if self._order else 0

    @property
    def picture_category(self) -> np.ndarray:
        parts = [got.category for *_, got in self._order]
        return np.concatenate(parts) if parts else np.zeros(0, np.int8)

    def run_world(self, geometry: Geometry, seed: int, run: int) -> RunWorld:
        placement = run_placement(geometry, seed, run)
        table = np.full((geometry.layout.n_cells, 4), -1, np.int16)
        if not self.live_pictures:
            return RunWorld(placement, table, placement.category.copy(), np.zeros(0, np.int64))
        key = (int(seed), int(run))
        if key not in self._rendered:
            got = rendered_run(self.layout.rows, *key, self.settings)
            first = self.n_pictures
            if first + len(got.pairs) > MAX_PICTURES:
                raise ValueError(
                    f"the robot world would take more than {MAX_PICTURES:,} live pictures "
                    f"({len(got.pairs)} a run in maze {self.layout.name}): run fewer runs or "
                    "a smaller maze"
                )
            self._rendered[key] = len(self._order)
            self._order.append((first, *key, got))
        self._latest[int(run)] = self._rendered[key]
        first, _, _, got = self._order[self._rendered[key]]
        ids = np.arange(first, first + len(got.pairs))
        table[got.pairs[:, 0], got.pairs[:, 1]] = ids
        return RunWorld(placement, table, placement.category.copy(), ids)

    def run_pictures(self, run: int) -> tuple[int, RenderedRun]:
        """The first id and the live pictures of run ``run`` (its latest ``run_world``)."""
        if run not in self._latest:
            raise KeyError(f"run {run} has no live pictures yet: ask run_world for it first")
        first, _, _, got = self._order[self._latest[run]]
        return first, got

    def image(self, picture: int) -> np.ndarray:
        """The live picture ``picture`` (H, W, 3 uint8)."""
        for first, _, _, got in self._order:
            if first <= picture < first + len(got.pairs):
                return got.images[picture - first]
        raise KeyError(f"no live picture {picture}")

    def picture_png(self) -> dict[int, bytes]:
        """Every live picture handed out, as PNG bytes by id (what the records keep)."""
        out: dict[int, bytes] = {}
        for first, seed, run, _ in self._order:
            for k, data in enumerate(run_pngs(self.layout.rows, seed, run, self.settings)):
                out[first + k] = data
        return out

    def describe(self) -> dict:
        """What the records keep of the world (``info.robot``): its settings and motion table."""
        return motion_table(self.settings.cell, self.settings.timestep)
