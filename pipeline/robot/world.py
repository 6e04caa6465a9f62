"""The maze as a MuJoCo world for the robot (issue 30; paper section 5's future work), built with
``MjSpec`` from any layout the grid accepts (built-in, generated or a file) and one run's
:class:`~pipeline.world.placement.Placement`.

* Cells: cell ``row * width + col`` is centred at ``x = (col - (W - 1) / 2) * cell``,
  ``y = ((H - 1) / 2 - row) * cell`` (north is +y, as the query pictures' sides).
* Floor: the maze scene's tiles; border walls: boxes around the grid (collision geometry).
* Obstacles: on every obstacle cell, the physical obstacle the placement gives (category,
  instance), the very object of its query pictures (``obstacle_models.obstacle_instance`` with
  ``render.yaml``'s ``seed``: two distinct objects per category), painted with its palette and
  turned by the cell's orientation in quarter turns clockwise (``pictures.face_seen``). Collision
  geometry: a box around the unturned object's footprint (its geoms' bounding boxes, capped at
  ``0.45 * cell``), turned with it, from the floor to its top.

The default cell is 1.0 m: the query pictures were rendered for a 1 m cell (``render.yaml``
``maze.cell``; the camera one cell away), and the obstacles' display scale fits it; the Burger
(0.178 m long) then keeps at least 0.2 m from an obstacle's box at a cell centre.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from pipeline.robot.limits import DEFAULT_CELL, DEFAULT_TIMESTEP, check_settings
from pipeline.robot.model import add_robot
from pipeline.world.layout import Layout
from pipeline.world.obstacle_models import obstacle_instance
from pipeline.world.pictures import INSTANCES_PER_CATEGORY
from pipeline.world.placement import Placement
from pipeline.world.renderer_env import mujoco
from pipeline.world.scenes import (
    _add_materials,
    _add_part,
    add_floor_tiles,
    add_maze_lights,
    add_sky,
    add_walls,
)
from pipeline.world.shapes import ObjectModel, yaw_quat

ARENA_BYTES, ARENA_BYTES_PER_OBSTACLE = 64 * 2**20, 16 * 2**10
#: The most geoms MuJoCo's renderer draws (``mujoco.Renderer``'s ``max_geom``); an obstacle is at
#: most 8 drawn parts, the robot, floor and walls fewer than 100: the live pictures' limit.
RENDER_GEOMS, GEOMS_PER_OBSTACLE, OTHER_GEOMS = 10_000, 8, 100
MAX_SEEN_OBSTACLES = (RENDER_GEOMS - OTHER_GEOMS) // GEOMS_PER_OBSTACLE
WALL_HEIGHT = 0.4
WALL_HALF_THICKNESS = 0.05
FOOTPRINT_CAP = 0.45  # of a cell: an obstacle's collision box stays inside its cell


def centre_of(cell: int, width: int, height: int, size: float) -> np.ndarray:
    """World (x, y) of cell ``row * width + col``'s centre in a maze of ``size`` m cells:
    ``((col - (W-1)/2) size, ((H-1)/2 - row) size)``, north is +y."""
    row, col = divmod(int(cell), width)
    return np.array([(col - (width - 1) / 2) * size, ((height - 1) / 2 - row) * size])


@dataclass(frozen=True)
class WorldMap:
    """What the simulator needs to know of a built world besides the model."""

    layout: Layout
    cell: float
    obstacle_cells: tuple[int, ...]
    obstacle_geoms: tuple[str, ...]  # collision box per obstacle (order of layout.obstacles)

    def centre(self, cell: int) -> np.ndarray:
        """World (x, y) of a cell's centre (:func:`centre_of`)."""
        return centre_of(cell, self.layout.width, self.layout.height, self.cell)

    def cell_at(self, xy) -> int:
        """The cell holding world point ``xy`` (clamped to the grid)."""
        w, h = self.layout.width, self.layout.height
        col = int(np.clip(np.floor(xy[0] / self.cell + w / 2), 0, w - 1))
        row = int(np.clip(np.floor(h / 2 - xy[1] / self.cell), 0, h - 1))
        return row * w + col


@lru_cache(maxsize=32)
def obstacle_model(category: int, instance: int, seed: int = 0) -> ObjectModel:
    """Physical obstacle ``instance`` of ``category``: the object of its query pictures
    (render_plan.query_batch)."""
    return obstacle_instance(category, instance, seed)


@lru_cache(maxsize=32)
def footprint(category: int, instance: int, seed: int = 0) -> tuple[float, float, float]:
    """``(half_x, half_y, top)`` of the unturned object: the union of its geoms' bounding boxes."""
    spec = mujoco.MjSpec()
    _add_materials(spec)
    body = spec.worldbody.add_body(name="o")
    obj = obstacle_model(category, instance, seed)
    for j, part in enumerate(obj.parts):
        _add_part(spec, body, part, f"g{j}", f"m{j}")
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
    for g in range(model.ngeom):
        c, h = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
        pts = data.geom_xpos[g] + (c + signs * h) @ data.geom_xmat[g].reshape(3, 3).T
        lo, hi = np.minimum(lo, pts.min(0)), np.maximum(hi, pts.max(0))
    return float(max(-lo[0], hi[0])), float(max(-lo[1], hi[1])), float(hi[2])


def obstacle_yaw(orientation: int) -> float:
    """Degrees (counter-clockwise) of an obstacle: the cell's orientation in quarter turns
    clockwise (``pictures.face_seen``)."""
    return float(-90.0 * orientation)


def build_world(
    layout: Layout,
    placement: Placement,
    cell: float = DEFAULT_CELL,
    render_seed: int = 0,
    shadows: bool = False,
):
    """``(MjSpec, WorldMap)``: floor, walls, the placed obstacles and the robot (at the origin;
    :class:`pipeline.robot.sim.RobotSim` puts it on the start cell)."""
    check_settings(cell, DEFAULT_TIMESTEP)
    if len(placement.physical) != len(layout.obstacles):
        raise ValueError(
            f"placement has {len(placement.physical)} obstacles, layout {len(layout.obstacles)}"
        )
    spec = mujoco.MjSpec()
    spec.modelname = "robot_maze"
    # MuJoCo's arena (its stack): the collision pass of a large maze needs about 10 kB an obstacle
    spec.memory = ARENA_BYTES + ARENA_BYTES_PER_OBSTACLE * len(layout.obstacles)
    spec.option.timestep = DEFAULT_TIMESTEP
    spec.option.gravity = [0.0, 0.0, -9.81]
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.visual.global_.offwidth = 640
    spec.visual.global_.offheight = 480
    spec.visual.map.znear = 0.01
    spec.visual.quality.shadowsize = 1024
    _add_materials(spec)
    G = mujoco.mjtGeom
    add_sky(spec, "maze")
    add_floor_tiles(spec, cell)
    wb = spec.worldbody
    hx, hy = layout.width * cell / 2, layout.height * cell / 2
    wb.add_geom(
        name="floor",
        type=G.mjGEOM_PLANE,
        size=[hx + 1.0, hy + 1.0, 0.1],
        material="tiles",
        contype=0,
        conaffinity=0,
    )
    t = WALL_HALF_THICKNESS
    walls = [(0, hy + t, hx + 2 * t, t), (0, -hy - t, hx + 2 * t, t)]
    walls += [(hx + t, 0, t, hy), (-hx - t, 0, t, hy)]
    add_walls(wb, walls, WALL_HEIGHT)
    wmap = WorldMap(layout, float(cell), tuple(layout.obstacles), ())
    boxes = []
    for o, c in enumerate(layout.obstacles):
        category = int(placement.physical[o]) // INSTANCES_PER_CATEGORY
        instance = int(placement.physical[o]) % INSTANCES_PER_CATEGORY
        x, y = wmap.centre(c)
        body = wb.add_body(
            name=f"obstacle{o}",
            pos=[float(x), float(y), 0.0],
            quat=list(yaw_quat(obstacle_yaw(int(placement.orientation[o])))),
        )
        obj = obstacle_model(category, instance, render_seed)
        for j, part in enumerate(obj.parts):
            _add_part(spec, body, part, f"obstacle{o}_g{j}", f"obstacle{o}_m{j}")
            body.geoms[-1].rgba = [*obj.palette[part.slot], 1.0]
        fx, fy, top = footprint(category, instance, render_seed)
        cap = FOOTPRINT_CAP * cell
        box = body.add_geom(
            name=f"obstacle{o}_box",
            type=G.mjGEOM_BOX,
            size=[min(fx, cap), min(fy, cap), top / 2],
            pos=[0.0, 0.0, top / 2],
            rgba=[1.0, 0.2, 0.2, 0.25],
            group=3,
            contype=1,
            conaffinity=1,
        )
        boxes.append(box.name)
    add_maze_lights(wb, shadows)
    spec.visual.headlight.ambient = [0.1, 0.1, 0.1]
    spec.visual.headlight.diffuse = [0.2, 0.2, 0.2]
    spec.visual.headlight.specular = [0.0, 0.0, 0.0]
    add_robot(spec)
    return spec, WorldMap(layout, float(cell), tuple(layout.obstacles), tuple(boxes))
