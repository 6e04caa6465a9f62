"""The robot of the paper's future work (section 5: "the turtlebot3 robot ... in a manually created
maze"), as a MuJoCo body added to an ``MjSpec`` (no XML), with the TurtleBot3 Burger's published
figures (ROBOTIS).

* Body: a box of the Burger's footprint and height, 178 mm long (x, forward), 138 mm wide (y),
  192 mm high; two wheels of radius 0.033 m, 0.160 m apart (drawn; see Drive below).
* Drive: a planar base, joints x, y (slides) and yaw (hinge) with velocity actuators. The
  controller (:mod:`pipeline.robot.sim`) commands the two wheel speeds, limited to the
  Burger's 0.22 m/s and 2.84 rad/s, and turns them into the base's (v, omega) by the
  differential-drive kinematics ``v = r (wl + wr) / 2``, ``omega = r (wr - wl) / L``. Wheel-floor
  friction is not simulated (no slip): this keeps the physics stable at a 20 ms step, which the
  cost budget needs (docs/robot3d.md).
* Camera: forward, the Raspberry Pi Camera v2's field of view, 62.2 x 48.8 degrees (a 4:3 frame).
* Range sensor: :data:`N_RAYS` MuJoCo rangefinders in a ring at the LDS-01's height, one every
  ``360 / N_RAYS`` degrees; readings outside the LDS-01's 0.12-3.5 m count as no return.

Contacts: the body box collides (contype 1) with obstacles and walls; the floor collides with
nothing (the base is planar), so every contact of the robot is a collision.
"""

from __future__ import annotations

import numpy as np

from pipeline.world.renderer_env import mujoco
from pipeline.world.shapes import quat_z_to

LENGTH, WIDTH, HEIGHT = 0.178, 0.138, 0.192  # metres (x forward, y left, z up)
WHEEL_RADIUS = 0.033
WHEEL_SEPARATION = 0.160
MAX_SPEED = 0.22  # m/s
MAX_TURN = 2.84  # rad/s
MAX_WHEEL = MAX_SPEED / WHEEL_RADIUS  # rad/s of one wheel
CAMERA_FOV = (62.2, 48.8)  # degrees, horizontal x vertical
CAMERA_HEIGHT = 0.15
CAMERA_POS = (LENGTH / 2 + 0.002, 0.0, CAMERA_HEIGHT)  # in the body's frame (x forward, z up)
LDS_HEIGHT = 0.172
LDS_RANGE = (0.12, 3.5)
N_RAYS = 36
BODY, GEOM, CAMERA = "robot", "robot_box", "robot_camera"


def ray_angles() -> np.ndarray:
    """Angles (radians, in the robot's frame, counter-clockwise from forward) of the rangefinders."""
    return np.arange(N_RAYS) * (2 * np.pi / N_RAYS)


def add_robot(spec, kv: float = 40.0) -> None:
    """Add the robot to ``spec`` (its pose is the joints' ``qpos``: x, y, yaw): body, joints
    ``robot_x``, ``robot_y``, ``robot_yaw``, velocity actuators of the same names, camera,
    rangefinders ``lds<k>``."""
    G = mujoco.mjtGeom
    body = spec.worldbody.add_body(name=BODY, pos=[0.0, 0.0, 0.0])
    for name, kind, axis in (
        ("robot_x", mujoco.mjtJoint.mjJNT_SLIDE, (1, 0, 0)),
        ("robot_y", mujoco.mjtJoint.mjJNT_SLIDE, (0, 1, 0)),
        ("robot_yaw", mujoco.mjtJoint.mjJNT_HINGE, (0, 0, 1)),
    ):
        body.add_joint(name=name, type=kind, axis=list(axis))
    body.add_geom(
        name=GEOM,
        type=G.mjGEOM_BOX,
        size=[LENGTH / 2, WIDTH / 2, HEIGHT / 2 - 0.005],
        pos=[0.0, 0.0, HEIGHT / 2 + 0.005],
        rgba=[0.15, 0.15, 0.17, 1.0],
        mass=1.0,
        contype=1,
        conaffinity=1,
        group=0,
    )
    for k, side in enumerate((1, -1)):
        body.add_geom(
            name=f"robot_wheel{k}",
            type=G.mjGEOM_CYLINDER,
            size=[WHEEL_RADIUS, 0.009, 0],
            pos=[0.0, side * WHEEL_SEPARATION / 2, WHEEL_RADIUS],
            quat=list(quat_z_to(np.array([0.0, 1.0, 0.0]))),
            rgba=[0.05, 0.05, 0.05, 1.0],
            contype=0,
            conaffinity=0,
            mass=0.05,
        )
    body.add_geom(
        name="robot_lds",
        type=G.mjGEOM_CYLINDER,
        size=[0.035, 0.01, 0],
        pos=[0.0, 0.0, LDS_HEIGHT],
        rgba=[0.2, 0.5, 0.9, 1.0],
        contype=0,
        conaffinity=0,
        mass=0.01,
    )
    body.add_camera(
        name=CAMERA,
        pos=list(CAMERA_POS),
        xyaxes=[0, -1, 0, 0, 0, 1],  # looks along the body's +x
        fovy=CAMERA_FOV[1],
    )
    for k, a in enumerate(ray_angles()):
        d = np.array([np.cos(a), np.sin(a), 0.0])
        site = body.add_site(
            name=f"lds{k}", pos=[0.0, 0.0, LDS_HEIGHT], quat=list(quat_z_to(d)), group=4
        )
        sensor = spec.add_sensor(
            name=f"lds{k}",
            type=mujoco.mjtSensor.mjSENS_RANGEFINDER,
            objtype=mujoco.mjtObj.mjOBJ_SITE,
            objname=site.name,
        )
        sensor.intprm[0] = 1 << int(mujoco.mjtRayDataField.mjRAYDATA_DIST)  # distance only
    for joint in ("robot_x", "robot_y", "robot_yaw"):
        act = spec.add_actuator(
            name=joint, target=joint, trntype=mujoco.mjtTrn.mjTRN_JOINT, forcelimited=True
        )
        yaw = joint == "robot_yaw"
        act.set_to_velocity(kv=1.0 if yaw else kv)  # never saturated: the tracking stays implicit
        act.forcerange = [-5.0, 5.0] if yaw else [-20.0, 20.0]
