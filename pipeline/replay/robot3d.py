"""The robot's replay in 3D (:class:`RobotReplay`; issue 30, docs/robot3d.md "Replay"): one run of
a robot cell's records drawn into a Rerun recording stream on the timelines ``sim_time`` (the
simulated seconds; a whole run: its episodes back to back) and ``episode``:

* the scene as MuJoCo builds it for the run (:func:`log_scene`): floor, walls, the obstacle
  meshes, and a dot in its category's colour under each obstacle (named on hover, as on the grid);
* the robot's body along its path at 10 Hz, the episode's path on the floor, the collisions (red
  points where its box met an obstacle's) and A_d (eqs. 7-8) as red arrows on the floor;
* what every world's replay shows (:class:`.story.Story`): the live picture the camera took at
  each recognition (the file's ``/pictures/<id>``) with its relation scores and verdict, the
  support set and its substitutions, the events, each at the moment it happened.

What the robot's records say (its path, its moments, its world) comes from a
:class:`pipeline.robot.replay.RobotRun`, handed in by :func:`.build.build_replay`'s ``worlds``
(``replay`` cannot import ``robot``: .importlinter).
"""

from __future__ import annotations

import numpy as np

from pipeline.records import Records
from pipeline.world.renderer_env import mujoco

from .notes import EmptyViews
from .story import RED, ROBOT, Story

#: What the 3D view shows (the other entities are the recognition and support views').
SCENE = ["/scene/**", "/robot/**", "/obstacles", "/collisions", "/unsafe"]
FLOOR = (150, 145, 135)  # a plane's colour (MuJoCo's floor is textured)


def log_scene(rec, model, data, skip_body: str = "robot") -> None:
    """Every drawn static geom of a compiled MuJoCo world as ``scene/<geom>`` (group 0-2: not the
    collision boxes), but those of the body ``skip_body``."""
    import rerun as rr

    G = mujoco.mjtGeom
    skip = model.body(skip_body).id
    for g in range(model.ngeom):
        if model.geom_bodyid[g] == skip or model.geom_group[g] > 2:
            continue
        colour = (np.clip(model.geom_rgba[g], 0, 1) * 255).astype(np.uint8)
        pos, xmat, size = data.geom_xpos[g], data.geom_xmat[g].reshape(3, 3), model.geom_size[g]
        quat = rr.Quaternion(xyzw=_quat_xyzw(xmat))
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
            shape = rr.Boxes3D(
                centers=[pos],
                half_sizes=[size],
                quaternions=[quat],
                colors=[colour],
                fill_mode="solid",
            )
        elif kind == G.mjGEOM_CYLINDER:
            shape = rr.Cylinders3D(
                centers=[pos],
                lengths=[2 * size[1]],
                radii=[size[0]],
                colors=[colour],
                quaternions=[quat],
            )
        elif kind == G.mjGEOM_CAPSULE:  # rerun's capsule starts at its base
            shape = rr.Capsules3D(
                translations=[pos - xmat[:, 2] * size[1]],
                lengths=[2 * size[1]],
                radii=[size[0]],
                colors=[colour],
                quaternions=[quat],
            )
        elif kind in (G.mjGEOM_SPHERE, G.mjGEOM_ELLIPSOID):
            shape = rr.Ellipsoids3D(
                centers=[pos],
                half_sizes=[[size[0]] * 3 if kind == G.mjGEOM_SPHERE else size],
                quaternions=[quat],
                colors=[colour],
                fill_mode="solid",
            )
        else:
            continue
        rec.log(f"scene/{model.geom(g).name or f'geom{g}'}", shape, static=True)


def _quat_xyzw(xmat: np.ndarray) -> np.ndarray:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, xmat.reshape(9))
    return np.array([q[1], q[2], q[3], q[0]])


class RobotReplay(Story):
    """Run ``run`` of the records ``recs`` of a robot cell drawn in 3D into the recording stream
    ``rec`` (the module docstring); ``robot``: the run as its records say
    (:class:`pipeline.robot.replay.RobotRun`, checked)."""

    def __init__(self, rec, recs: Records, run: int, robot):
        super().__init__(rec, recs, run)
        robot.check(self.steps, self.recog)
        self.robot, self.path, self.start = robot, None, 0.0  # the episode being drawn

    # ---------------------------------------------------------------- the clock
    def when(self, t: int, picture: int | None = None, contact: bool = False) -> float:
        """The simulated second of an event of step ``t`` of the episode being drawn, in the
        replay (:meth:`pipeline.robot.replay.EpisodePath.moment` after the episode's start)."""
        return self.start + self.path.moment(t, picture, contact)

    def at(self, moment: float) -> None:
        self.rec.set_time("sim_time", duration=float(moment))

    # ---------------------------------------------------------------- what does not change
    def blueprint(self, name: str, empty: EmptyViews):
        """The viewer's layout: the robot in 3D, then the views every replay has."""
        import rerun.blueprint as rrb

        return self.layout(rrb.Spatial3DView(origin="/", name=f"3D: {name}", contents=SCENE), empty)

    def draw_static(self) -> None:
        """The scene, a dot under each obstacle in its category's colour (named on hover) and the
        robot's body (its pose: per tick, :meth:`episode`)."""
        import rerun as rr

        self.log("/", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        log_scene(self.rec, *self.robot.scene())
        obstacles = self.robot.obstacles
        under = self.robot.centres([o["cell"] for o in obstacles])
        self.log(
            "obstacles",
            rr.Points3D(
                np.c_[under, np.full(len(under), 0.01)],
                radii=0.08,
                class_ids=[o["category"] for o in obstacles],
                labels=[self.obstacle_label(o) for o in obstacles],
                show_labels=False,
            ),
            static=True,
        )
        half = self.robot.half_sizes
        body = rr.Boxes3D(
            centers=[[0.0, 0.0, half[2]]], half_sizes=[half], colors=[ROBOT], fill_mode="solid"
        )
        self.log("robot/body", body, static=True)

    # ---------------------------------------------------------------- what changes
    def log_unsafe(self) -> None:
        """A_d so far as red arrows on the floor, from each pair's cell centre toward its move."""
        import rerun as rr

        pairs = np.array(self.ad, dtype=np.int64).reshape(-1, 2)
        if not len(pairs):
            self.log("unsafe", rr.Clear(recursive=False))
            return
        heading, reach, n = self.robot.headings(pairs[:, 1]), 0.45 * self.robot.cell, len(pairs)
        self.log(
            "unsafe",
            rr.Arrows3D(
                origins=np.c_[self.robot.centres(pairs[:, 0]), np.full(n, 0.03)],
                vectors=np.c_[reach * np.cos(heading), reach * np.sin(heading), np.zeros(n)],
                colors=RED,
                radii=0.02,
            ),
        )

    def draw(self, episodes: list[int], empty: EmptyViews) -> None:
        """Every step of ``episodes``, back to back on ``sim_time``, after what the run's earlier
        episodes left: A_d and the support set."""
        self.draw_static()
        self.at(0.0)
        self.rec.set_time("episode", sequence=episodes[0])
        self.begin(episodes[0], empty)
        start = 0.0
        for e in episodes:
            self.rec.set_time("episode", sequence=e)
            start = self.episode(e, start)

    def episode(self, e: int, start: float) -> float:
        """Episode ``e`` from ``start`` (s on ``sim_time``); returns when the next one starts."""
        import rerun as rr

        steps, seen = self.steps[self.steps.episode == e], self.recog[self.recog.episode == e]
        self.path, self.start = self.robot.episode(e, steps, seen), start
        poses, contacts = self.path.poses, self.path.contacts
        n = len(poses)
        self.at(start)
        self.log_unsafe()
        floor = np.c_[poses[:, 1:3], np.full(n, 0.02)]
        self.log("robot/path", rr.LineStrips3D([floor], colors=[ROBOT], radii=0.01))
        self.log("collisions", rr.Clear(recursive=False))
        yaw = poses[:, 3]
        self.rec.send_columns(
            "robot/body",
            indexes=[
                rr.TimeColumn("sim_time", duration=start + poses[:, 0]),
                rr.TimeColumn("episode", sequence=np.full(n, e)),
            ],
            columns=rr.Transform3D.columns(
                translation=np.c_[poses[:, 1:3], np.zeros(n)],
                quaternion=np.c_[np.zeros((n, 2)), np.sin(yaw / 2), np.cos(yaw / 2)],
            ),
        )
        for k, t in enumerate(sorted(self.path.contact_tick)):
            self.at(self.when(t, contact=True))
            hit = np.c_[contacts[: k + 1, 1:3], np.full(k + 1, 0.1)]
            self.log("collisions", rr.Points3D(hit, colors=[RED], radii=0.06))
        states, actions, flags = (steps[c].to_numpy() for c in ("state", "action", "flags"))
        self.events(e, states, actions, flags)
        return start + self.path.seconds
