"""The robot's 3D scene in Rerun, the parts that need no records: the MuJoCo world's geoms as Rerun
shapes (:func:`log_scene`), the robot with its heading and camera (:func:`log_robot`), the eye that
opens on the whole maze (:func:`overview_eye`), the legend beside the maze
(:func:`legend_positions`) and in words (:func:`legend_text`), and the path so far as few points
(:func:`corners`). :mod:`.robot3d` draws a run with them.
"""

from __future__ import annotations

import math

import numpy as np
import rerun as rr

from pipeline import palette
from pipeline.world.renderer_env import mujoco

FLOOR = (150, 145, 135)  # a plane's colour (MuJoCo's floor is textured)
#: The cone (degrees) the whole maze must fit in: narrower than the field of view Rerun's 3D view
#: opens with, so that a view somewhat taller than wide (the replay's layout) shows it all.
FIT_FOV = 45.0
#: How steeply the opening eye looks down on the maze (degrees above the floor), from the south.
ELEVATION = 65.0
MARGIN = 0.2  # m around the floor the opening eye keeps in view: the walls (0.1 m thick) and room
#: The legend beside the maze: its column's distance east of the maze, its rows' pitch, and the room
#: its names take east of the column (m, whatever the cell size).
LEGEND_GAP, LEGEND_PITCH, LEGEND_TEXT = 0.6, 0.45, 1.4
#: What the legend beside the maze names after the categories, with their colours.
MARKS = {
    "start": palette.START,
    "goal": palette.GOAL,
    "robot": palette.ROBOT,
    "collision": palette.UNSAFE,
    "stop": palette.RESELECTED,
}
HEADING = 0.4  # m: the heading arrow's length


def log_scene(rec, model, data, root: str, skip_body: str = "robot") -> None:
    """Every drawn static geom of a compiled MuJoCo world as ``<root>/<geom>`` (group 0-2: not the
    collision boxes), but those of the body ``skip_body``."""
    G = mujoco.mjtGeom
    skip = model.body(skip_body).id
    for g in range(model.ngeom):
        if model.geom_bodyid[g] == skip or model.geom_group[g] > 2:
            continue
        colour = (np.clip(model.geom_rgba[g], 0, 1) * 255).astype(np.uint8)
        pos, xmat, size = data.geom_xpos[g], data.geom_xmat[g].reshape(3, 3), model.geom_size[g]
        # the geom's orientation and colour, as every posed shape takes them; a rod's length and radius
        posed = dict(quaternions=[rr.Quaternion(xyzw=_quat_xyzw(xmat))], colors=[colour])
        rod = dict(lengths=[2 * size[1]], radii=[size[0]], **posed)
        kind = model.geom_type[g]
        if kind == G.mjGEOM_MESH:
            m = model.geom_dataid[g]
            v0, nv = model.mesh_vertadr[m], model.mesh_vertnum[m]
            f0, nf = model.mesh_faceadr[m], model.mesh_facenum[m]
            shape = rr.Mesh3D(
                vertex_positions=model.mesh_vert[v0 : v0 + nv] @ xmat.T + pos,
                triangle_indices=model.mesh_face[f0 : f0 + nf],
                albedo_factor=colour,
            )
        elif kind == G.mjGEOM_PLANE:
            half = [[size[0], size[1], 0.001]]
            shape = rr.Boxes3D(centers=[pos], half_sizes=half, colors=[FLOOR], fill_mode="solid")
        elif kind == G.mjGEOM_BOX:
            shape = rr.Boxes3D(centers=[pos], half_sizes=[size], fill_mode="solid", **posed)
        elif kind == G.mjGEOM_CYLINDER:
            shape = rr.Cylinders3D(centers=[pos], **rod)
        elif kind == G.mjGEOM_CAPSULE:  # rerun's capsule starts at its base
            shape = rr.Capsules3D(translations=[pos - xmat[:, 2] * size[1]], **rod)
        elif kind in (G.mjGEOM_SPHERE, G.mjGEOM_ELLIPSOID):
            half = [size[0]] * 3 if kind == G.mjGEOM_SPHERE else size
            shape = rr.Ellipsoids3D(centers=[pos], half_sizes=[half], fill_mode="solid", **posed)
        else:
            continue
        rec.log(f"{root}/{model.geom(g).name or f'geom{g}'}", shape, static=True)


def _quat_xyzw(xmat: np.ndarray) -> np.ndarray:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, xmat.reshape(9))
    return np.array([q[1], q[2], q[3], q[0]])


def yaw_quaternions(yaw: np.ndarray) -> np.ndarray:
    """Rotations about +z by ``yaw`` (rad) as (x, y, z, w) quaternions, one row each."""
    yaw = np.asarray(yaw, np.float64)
    return np.c_[np.zeros((len(yaw), 2)), np.sin(yaw / 2), np.cos(yaw / 2)]


def legend_positions(x_range, y_range, n: int) -> np.ndarray:
    """``n`` legend rows (x, y) in a column :data:`LEGEND_GAP` east of the floor ``x_range`` x
    ``y_range`` (m), from its north edge southwards :data:`LEGEND_PITCH` apart."""
    east, north = x_range[1] + LEGEND_GAP, y_range[1] - LEGEND_PITCH / 2
    return np.array([[east, north - k * LEGEND_PITCH] for k in range(n)], np.float64).reshape(-1, 2)


def overview_eye(x_range, y_range) -> tuple[list[float], list[float]]:
    """The opening eye of the 3D view on the floor ``x_range`` x ``y_range`` (m, z = 0): looking at
    its centre from the south, :data:`ELEVATION` degrees up, far enough that a sphere around the
    whole floor fits in a :data:`FIT_FOV` degree cone. Returns (position, look target)."""
    (x0, x1), (y0, y1) = x_range, y_range
    target = [(x0 + x1) / 2, (y0 + y1) / 2, 0.0]
    distance = 0.5 * math.hypot(x1 - x0, y1 - y0) / math.sin(math.radians(FIT_FOV / 2))
    up = math.radians(ELEVATION)
    south_and_above = [0.0, -math.cos(up), math.sin(up)]
    return [centre + distance * way for centre, way in zip(target, south_and_above)], target


def corners(xy: np.ndarray, tol: float = 0.002) -> np.ndarray:
    """The indices of the points of the polyline ``xy`` (n, 2) that Ramer-Douglas-Peucker keeps at
    tolerance ``tol`` (m): the first, the last, and wherever the path leaves the straight segment
    between two kept points by more than ``tol`` (the distance to the segment, not its line, so a
    drive that goes out and comes back keeps its far end)."""
    xy = np.asarray(xy, np.float64)
    n = len(xy)
    keep = np.zeros(n, bool)
    keep[[0, n - 1] if n else []] = True
    stack = [(0, n - 1)] if n > 2 else []
    while stack:
        i, j = stack.pop()
        if j <= i + 1:
            continue
        away = _segment_distance(xy[i + 1 : j], xy[i], xy[j])
        far = int(np.argmax(away))
        if away[far] > tol:
            m = i + 1 + far
            keep[m] = True
            stack += [(i, m), (m, j)]
    return np.flatnonzero(keep)


def _segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The distance of each of ``points`` (k, 2) to the segment from ``a`` to ``b``."""
    ab = b - a
    length2 = float(ab @ ab)
    along = np.zeros(len(points)) if length2 == 0 else np.clip((points - a) @ ab / length2, 0, 1)
    return np.linalg.norm(points - (a + along[:, None] * ab), axis=1)


def log_robot(rec, root: str, half_sizes, camera) -> None:
    """The robot in its own frame ``root`` (x forward, z up; its pose: ``root``'s transform): its
    body box labelled *robot*, an arrow over it for its heading, and its camera (``root/camera``:
    ``camera``'s position and a pinhole, under which the live pictures go)."""
    colour = palette.rgb(palette.ROBOT)
    body = rr.Boxes3D(
        centers=[[0.0, 0.0, half_sizes[2]]],
        half_sizes=[half_sizes],
        colors=[colour],
        labels=["robot"],
        show_labels=True,
        fill_mode="solid",
    )
    rec.log(f"{root}/body", body, static=True)
    heading = rr.Arrows3D(
        origins=[[0.0, 0.0, 2 * half_sizes[2] + 0.03]],
        vectors=[[HEADING, 0.0, 0.0]],
        colors=[colour],
        radii=0.025,
    )
    rec.log(f"{root}/heading", heading, static=True)
    pinhole = rr.Pinhole(  # in pixels (fov_y with aspect_ratio would size the image plane 1 x 1)
        focal_length=camera.size / 2 / math.tan(math.radians(camera.fov_y) / 2),
        width=camera.size,
        height=camera.size,
        camera_xyz=rr.ViewCoordinates.FLU,  # the body's axes: x forward, z up
        image_plane_distance=0.25,
        color=colour,
    )
    rec.log(f"{root}/camera", rr.Transform3D(translation=camera.position), pinhole, static=True)


def legend_text(categories: list[str]) -> str:
    """The 3D scene's legend in words (markdown), naming the palette's colours; ``categories``: the
    names of the categories, by index."""
    marks = {name: f"**{name}** ({h})" for name, h in MARKS.items()}
    named = ", ".join(f"{name} ({palette.category(c)})" for c, name in enumerate(categories))
    return "\n".join(
        [
            f"- {marks['robot']}: the labelled box; arrow: its heading; frustum: its camera, with "
            "the last live picture",
            "- **path so far**: the line on the floor",
            f"- {marks['start']}, {marks['goal']}: the labelled tiles",
            f"- {marks['collision']}: a big ball where it hit an obstacle (events: ERROR)",
            f"- {marks['stop']}: a ball before an obstacle it recognised and stopped for (WARN)",
            f"- **A_d** ({palette.UNSAFE}): arrows on the floor, from a cell toward its unsafe move",
            f"- **categories**, the dot under each obstacle: {named}",
            "",
            "Drag to orbit, scroll to zoom, double-click for the whole maze. Timelines: `sim_time` "
            "(simulated seconds), `step`, `episode`.",
        ]
    )
