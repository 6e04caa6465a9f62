"""What one run's robot meets: the obstacle placement and the picture it sees from each dangerous
pair (s, a) (paper section 4.1 and eq. 4), from the world the trial runs in.

The runner (:mod:`.runner`) and the Gymnasium environment ask a :class:`World` for each run's
:class:`RunWorld`; the rest of the loop is the same in every world. Two worlds implement it:

* :class:`GridWorld`: the paper's grid. Picture ids are the 40 pre-rendered query pictures
  (``pipeline.world.pictures``), the same set in every run.
* ``pipeline.robot.world.RobotWorld``: the camera robot in MuJoCo. Picture ids are the live
  pictures its camera takes in each run's maze, their own ids in every run.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from pipeline.rl.rng import run_seeds
from pipeline.world.geometry import Geometry
from pipeline.world.pictures import N_PICTURES, picture_category
from pipeline.world.placement import Placement, picture_table, random_placement

#: True category of every query picture id.
PICTURE_CATEGORY = np.array([picture_category(p) for p in range(N_PICTURES)], dtype=np.int8)


@dataclass(frozen=True)
class RunWorld:
    """One run's obstacles and what the robot sees from each (cell, action)."""

    placement: Placement
    pictures: np.ndarray  # (n_cells, 4) picture id or -1
    true_category: np.ndarray  # (n_obstacles,)
    seen: np.ndarray  # the picture ids this run can meet (its support-set accuracy is over them)


def run_placement(geometry: Geometry, seed: int, run: int) -> Placement:
    """Run ``run``'s obstacle placement, from ``run_seeds(seed, run).placement``: the same in
    every world, so a robot run and a grid run with the same seed meet the same obstacles."""
    return _placement(len(geometry.layout.obstacles), seed, run)


@functools.lru_cache(maxsize=1 << 14)  # the cells of a study on mazes of as many obstacles share it
def _placement(n_obstacles: int, seed: int, run: int) -> Placement:
    placement = random_placement(n_obstacles, np.random.default_rng(run_seeds(seed, run).placement))
    for array in (placement.physical, placement.orientation):
        array.flags.writeable = False  # shared: no caller may change it
    return placement


def make_run_world(geometry: Geometry, seed: int, run: int) -> RunWorld:
    """Run ``run`` of the grid world: its placement and the query picture of each face seen."""
    placement = run_placement(geometry, seed, run)
    return RunWorld(
        placement,
        picture_table(geometry, placement),
        placement.category.copy(),
        np.arange(N_PICTURES),
    )


class World(Protocol):
    """A world the runner drives: each run's :class:`RunWorld`, and the pictures' categories."""

    name: str

    def run_world(self, geometry: Geometry, seed: int, run: int) -> RunWorld: ...

    @property
    def picture_category(self) -> np.ndarray:
        """(n_pictures,) the true category of every picture id handed out so far."""


class GridWorld:
    """The paper's grid world (section 4.1): a run sees the pre-rendered query pictures."""

    name = "grid"
    picture_category = PICTURE_CATEGORY

    def run_world(self, geometry: Geometry, seed: int, run: int) -> RunWorld:
        return make_run_world(geometry, seed, run)


GRID = GridWorld()
