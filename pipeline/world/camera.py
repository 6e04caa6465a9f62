"""Where the camera stands for each kind of picture.

MuJoCo's free camera looks at ``lookat`` from ``distance`` along ``azimuth`` (degrees, the
direction the camera looks, counter-clockwise from +x) and ``elevation`` (degrees, negative =
looking down). World axes: x east, y north, z up.

Query pictures (paper eq. 1, ``d0 = 4``): the robot stands in the neighbouring cell on world side
``side`` (0 N, 1 E, 2 S, 3 W) at a constant distance and looks at the obstacle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.world.pictures import N_FACES


@dataclass(frozen=True)
class CameraPose:
    lookat: tuple[float, float, float]
    distance: float
    azimuth: float
    elevation: float
    fovy: float = 45.0

    def position(self) -> np.ndarray:
        a, e = np.deg2rad(self.azimuth), np.deg2rad(self.elevation)
        forward = np.array([np.cos(a) * np.cos(e), np.sin(a) * np.cos(e), np.sin(e)])
        return np.asarray(self.lookat) - self.distance * forward


def side_azimuth(side: int) -> float:
    """Azimuth of a camera standing on world side ``side`` and looking at the origin."""
    if not 0 <= side < N_FACES:
        raise ValueError(f"side must be 0..{N_FACES - 1}, got {side}")
    return float((-90.0 - 90.0 * side) % 360.0)


def robot_camera(
    side: int, distance: float, camera_height: float, target_height: float, fovy: float
) -> CameraPose:
    """The robot's camera on ``side`` at horizontal ``distance``, at ``camera_height``, aimed at
    the point ``target_height`` above the obstacle's foot."""
    elevation = float(np.rad2deg(np.arctan2(target_height - camera_height, distance)))
    slant = float(np.hypot(distance, target_height - camera_height))
    return CameraPose((0.0, 0.0, target_height), slant, side_azimuth(side), elevation, fovy)


def framing_distance(height: float, radius: float, fovy: float, fill: float) -> float:
    """Distance at which an object of ``height`` and horizontal ``radius`` fills ``fill`` of the
    picture's height (a bounding-sphere estimate)."""
    r = 0.5 * float(np.hypot(height, 2 * radius))
    return r / (fill * np.tan(np.deg2rad(fovy) / 2))
