"""A robot episode replayed in 3D in Rerun (issue 30; docs/robot3d.md "Replay"): the scene (floor,
walls, the run's obstacle meshes as MuJoCo built them), the robot moving along its recorded path,
its camera picture at each recognition with the relation scores, and the collisions marked where
they happened.

``python -m pipeline replay file=<robot cell>/records.mcap run=R episode=E`` builds it for a robot
cell (one with ``robot.mcap`` beside its ``records.mcap``: the maze and each run's placement there;
poses, pictures and contacts here). Timeline ``sim_time``: the episode's simulated seconds.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import rerun as rr

from pipeline.records import read_records
from pipeline.robot.model import HEIGHT, LENGTH, WIDTH
from pipeline.robot.records import read_robot_records
from pipeline.robot.world import build_world
from pipeline.world.layout import parse_layout
from pipeline.world.pictures import CATEGORIES
from pipeline.world.placement import Placement
from pipeline.world.renderer_env import mujoco


def _quat_xyzw(xmat: np.ndarray) -> np.ndarray:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, xmat.reshape(9))
    return np.array([q[1], q[2], q[3], q[0]])


def log_scene(rec, model, data) -> None:
    """Every drawn static geom of the world (group 0-2; not the robot, not collision boxes)."""
    G = mujoco.mjtGeom
    robot_body = model.body("robot").id
    for g in range(model.ngeom):
        if model.geom_bodyid[g] == robot_body or model.geom_group[g] > 2:
            continue
        name = model.geom(g).name or f"geom{g}"
        rgba = model.geom_rgba[g]
        colour = (np.clip(rgba, 0, 1) * 255).astype(np.uint8)
        pos, xmat, size = data.geom_xpos[g], data.geom_xmat[g].reshape(3, 3), model.geom_size[g]
        quat = rr.Quaternion(xyzw=_quat_xyzw(xmat))
        kind, path = model.geom_type[g], f"scene/{name}"
        if kind == G.mjGEOM_MESH:
            m = model.geom_dataid[g]
            v0, nv = model.mesh_vertadr[m], model.mesh_vertnum[m]
            f0, nf = model.mesh_faceadr[m], model.mesh_facenum[m]
            verts = model.mesh_vert[v0 : v0 + nv] @ xmat.T + pos
            rec.log(path, rr.Mesh3D(vertex_positions=verts, triangle_indices=model.mesh_face[f0 : f0 + nf],
                                   albedo_factor=colour), static=True)  # fmt: skip
        elif kind == G.mjGEOM_PLANE:
            rec.log(path, rr.Boxes3D(centers=[pos], half_sizes=[[size[0], size[1], 0.001]],
                                    colors=[[150, 145, 135]], fill_mode="solid"), static=True)  # fmt: skip
        elif kind == G.mjGEOM_BOX:
            rec.log(path, rr.Boxes3D(centers=[pos], half_sizes=[size], quaternions=[quat],
                                    colors=[colour], fill_mode="solid"), static=True)  # fmt: skip
        elif kind in (G.mjGEOM_CYLINDER, G.mjGEOM_CAPSULE):
            make = rr.Cylinders3D if kind == G.mjGEOM_CYLINDER else rr.Capsules3D
            shift = pos - xmat[:, 2] * size[1]  # rerun's shapes start at their base
            kw = dict(lengths=[2 * size[1]], radii=[size[0]], colors=[colour], quaternions=[quat])
            kw["centers" if kind == G.mjGEOM_CYLINDER else "translations"] = [
                pos if kind == G.mjGEOM_CYLINDER else shift
            ]
            rec.log(path, make(**kw), static=True)
        elif kind in (G.mjGEOM_SPHERE, G.mjGEOM_ELLIPSOID):
            half = [size[0]] * 3 if kind == G.mjGEOM_SPHERE else size
            rec.log(path, rr.Ellipsoids3D(centers=[pos], half_sizes=[half], quaternions=[quat],
                                         colors=[colour], fill_mode="solid"), static=True)  # fmt: skip


def robot_replay(folder: Path, run: int, episode: int) -> bytes:
    """The ``.rrd`` bytes of the replay of ``run``/``episode`` of the robot cell in ``folder``; a
    run or episode the records lack is a ``ValueError``."""
    folder = Path(folder)
    meta = read_records(folder / "records.mcap").meta
    settings, episodes = read_robot_records(folder / "robot.mcap")
    chosen = [e for e in episodes if e["run"] == run and e["episode"] == episode]
    if not chosen:
        raise ValueError(f"{folder}: no run {run} episode {episode} in robot.mcap")
    ep = chosen[0]
    layout = parse_layout("\n".join(meta.maze["layout"]))
    obstacles = meta.obstacles[run]
    placement = Placement(
        np.array([o["physical"] for o in obstacles], np.int16),
        np.array([o["orientation"] for o in obstacles], np.int8),
    )
    spec, _ = build_world(layout, placement, settings["cell"])
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    rec = rr.RecordingStream(
        "robot3d_replay", send_properties=False, recording_id=f"{folder.name}-run{run}-ep{episode}"
    )
    stream = rec.binary_stream()  # in memory: the stage writes it whole (replay.build.write_rrd)
    rec.send_recording_name(f"{folder.name}: run {run}, episode {episode} (the robot in 3D)")
    rec.log("/", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    log_scene(rec, model, data)
    poses = np.array(ep["poses"], float)
    path = np.c_[poses[:, 1:3], np.full(len(poses), 0.02)]
    rec.log("robot/path", rr.LineStrips3D([path], colors=[[30, 120, 220]], radii=0.01), static=True)
    for t, x, y, yaw in poses:
        rec.set_time("sim_time", duration=float(t))
        quat = rr.Quaternion(xyzw=[0.0, 0.0, np.sin(yaw / 2), np.cos(yaw / 2)])
        rec.log("robot/body", rr.Boxes3D(centers=[[x, y, HEIGHT / 2]], half_sizes=[[LENGTH / 2, WIDTH / 2, HEIGHT / 2]],
                                         quaternions=[quat], colors=[[40, 40, 45]], fill_mode="solid"))  # fmt: skip
    for c in ep["contacts"]:
        rec.set_time("sim_time", duration=float(c["time"]))
        rec.log("collisions", rr.Points3D([c["point"]], colors=[[230, 30, 30]], radii=0.06))
    for k, p in enumerate(ep["pictures"]):
        rec.set_time("sim_time", duration=float(p["time"]) + 0.001 * k)
        rec.log("camera/picture", rr.Image(p["image"]))
        scores = ", ".join(f"{c} {s:.2f}" for c, s in zip(CATEGORIES, p["scores"]))
        verdict = "stopped (recognised)" if p["prevented"] else "drove on"
        truth = CATEGORIES[p["true"]] if p["true"] >= 0 else "none"
        rec.log(
            "camera/scores",
            rr.TextDocument(f"step {p['step']}: {verdict}; truth {truth}\n{scores}"),
        )
    data = stream.read(flush=True) or b""
    rec.disconnect()
    return data
