"""Which physical obstacle stands on which obstacle cell, turned how (paper section 4.1; README
"Where we differ from the paper", Obstacles).

Ten physical obstacles (5 categories x 2 instances). Each independent run assigns them to the
maze's obstacle cells at random, without repetition while there are enough (the paper's 5x5 maze
uses nine of the ten), and in balanced rounds of fresh permutations otherwise; each cell gets a
random orientation (quarter turns), so the face a robot sees from a side depends on the run.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.world.geometry import Geometry
from pipeline.world.pictures import INSTANCES_PER_CATEGORY, N_FACES, N_PHYSICAL_OBSTACLES, face_seen


@dataclass(frozen=True)
class Placement:
    """One run's obstacles. Arrays are indexed by obstacle index (order of ``layout.obstacles``)."""

    physical: np.ndarray  # int16, 0..9
    orientation: np.ndarray  # int8, quarter turns clockwise

    @property
    def category(self) -> np.ndarray:
        return (self.physical // INSTANCES_PER_CATEGORY).astype(np.int8)

    @property
    def instance(self) -> np.ndarray:
        return (self.physical % INSTANCES_PER_CATEGORY).astype(np.int8)

    def as_records(self, obstacle_cells) -> list[dict]:
        return [
            {
                "cell": int(cell),
                "physical": int(p),
                "category": int(p // INSTANCES_PER_CATEGORY),
                "instance": int(p % INSTANCES_PER_CATEGORY),
                "orientation": int(r),
            }
            for cell, p, r in zip(obstacle_cells, self.physical.tolist(), self.orientation.tolist())
        ]


def random_placement(n_obstacles: int, rng: np.random.Generator) -> Placement:
    rounds = -(-n_obstacles // N_PHYSICAL_OBSTACLES)
    physical = np.concatenate(
        [np.empty(0, np.int64)] + [rng.permutation(N_PHYSICAL_OBSTACLES) for _ in range(rounds)]
    )[:n_obstacles]
    orientation = rng.integers(0, N_FACES, size=n_obstacles)
    return Placement(physical.astype(np.int16), orientation.astype(np.int8))


def picture_table(geometry: Geometry, placement: Placement) -> np.ndarray:
    """Query-picture id seen from each (cell, action), or -1 where no obstacle is ahead.

    Eq. 1: the picture of the obstacle's side that faces the robot, ``x_{j s(Area_di)}``. Faces
    toward another obstacle or off the grid have no (free cell, action) pair, so they are never seen.
    """
    table = np.full(geometry.obstacle.shape, -1, dtype=np.int16)
    s, a = np.nonzero(geometry.obstacle >= 0)
    o = geometry.obstacle[s, a]
    faces = face_seen(geometry.side[s, a].astype(np.int16), placement.orientation[o])
    table[s, a] = placement.physical[o].astype(np.int16) * N_FACES + faces
    return table
