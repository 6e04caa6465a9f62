"""One compiled scene + one ``mujoco.Renderer``, reused for every picture of that scene.

A :class:`Shot` says which object is shown, how it is turned and painted, where the camera
stands and how the scene is lit; :meth:`SceneRenderer.render` changes only model arrays that
MuJoCo reads at draw time (colours, body poses, lights, materials), so no recompilation and no
new OpenGL context per picture: creating a renderer costs far more than drawing a picture
(``python -m benchmarks.render`` measures both).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from PIL import Image

from pipeline.world.camera import CameraPose
from pipeline.world.renderer_env import make_renderer, mujoco
from pipeline.world.scenes import SceneLayout
from pipeline.world.shapes import yaw_quat

RGB = tuple[float, float, float]


@dataclass(frozen=True)
class Lighting:
    """Key light direction and colour, plus ambient; ``None`` keeps the scene's own."""

    key_dir: tuple[float, float, float] | None = None
    key_diffuse: RGB | None = None
    ambient: RGB | None = None


@dataclass(frozen=True)
class Background:
    """Floor and backdrop colour and material (``studio``/``catalogue`` scenes); ``None`` keeps."""

    floor_rgb: RGB | None = None
    floor_material: str | None = None
    backdrop_rgb: RGB | None = None
    backdrop_material: str | None = None


@dataclass(frozen=True)
class Shot:
    obj: int
    yaw_deg: float
    colours: tuple[RGB, ...]
    camera: CameraPose
    lighting: Lighting = Lighting()
    background: Background = Background()


class SceneRenderer:
    """Renders :class:`Shot` s of one scene at ``size`` x ``size`` pixels (RGB uint8).

    Anti-aliasing by supersampling: the scene is drawn at ``size * supersample`` pixels and each
    ``supersample`` x ``supersample`` block averaged (PIL ``reduce``). On llvmpipe this costs
    about half of 4x MSAA for the same smoothing.
    """

    def __init__(self, spec, layout: SceneLayout, size: int, supersample: int = 1):
        if int(size) <= 0:
            raise ValueError(f"picture size must be positive, got {size}")
        if int(supersample) <= 0:
            raise ValueError(f"supersample must be a positive integer, got {supersample}")
        self.supersample = int(supersample)
        self.layout = layout
        self.model = spec.compile()
        self.data = mujoco.MjData(self.model)
        m = self.model
        self._bodies = [m.body(b).id for b in layout.bodies]
        self._geoms = [np.array([m.geom(g).id for g in gs], dtype=int) for gs in layout.geoms]
        self._slots = [np.array(s, dtype=int) for s in layout.slots]
        self._all = np.concatenate(self._geoms) if self._geoms else np.zeros(0, int)
        self._floor = m.geom("floor").id
        self._key = m.light("key").id
        self._backdrop_body = m.body("backdrop").id if layout.has_backdrop else -1
        self._backdrop = m.geom("backdrop").id if layout.has_backdrop else -1
        self._cam = mujoco.MjvCamera()
        self._cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        side = int(size) * self.supersample
        if side > min(m.vis.global_.offwidth, m.vis.global_.offheight):
            m.vis.global_.offwidth = m.vis.global_.offheight = side
        self._renderer = make_renderer(m, side, side)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def __enter__(self) -> SceneRenderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _mat(self, name: str) -> int:
        return self.model.material(name).id

    def render(self, shot: Shot) -> np.ndarray:
        m = self.model
        if not 0 <= shot.obj < len(self._bodies):
            raise ValueError(
                f"scene has {len(self._bodies)} objects, shot asks for object {shot.obj}"
            )
        m.geom_rgba[self._all, 3] = 0.0  # hidden: MuJoCo skips fully transparent geoms
        ids, slots = self._geoms[shot.obj], self._slots[shot.obj]
        colours = np.asarray(shot.colours, dtype=float)
        m.geom_rgba[ids, :3] = colours[slots]
        m.geom_rgba[ids, 3] = 1.0
        m.body_quat[self._bodies[shot.obj]] = yaw_quat(shot.yaw_deg)
        lt = shot.lighting
        if lt.key_dir is not None:
            d = np.asarray(lt.key_dir, float)
            m.light_dir[self._key] = d / np.linalg.norm(d)
        if lt.key_diffuse is not None:
            m.light_diffuse[self._key] = lt.key_diffuse
        if lt.ambient is not None:
            m.light_ambient[self._key] = lt.ambient
        bg = shot.background
        if bg.floor_rgb is not None:
            m.geom_rgba[self._floor, :3] = bg.floor_rgb
        if bg.floor_material is not None:
            m.geom_matid[self._floor] = self._mat(bg.floor_material)
        cam = shot.camera
        if self._backdrop >= 0:
            if bg.backdrop_rgb is not None:
                m.geom_rgba[self._backdrop, :3] = bg.backdrop_rgb
            if bg.backdrop_material is not None:
                m.geom_matid[self._backdrop] = self._mat(bg.backdrop_material)
            a = np.deg2rad(cam.azimuth)
            behind = 2.5 + 0.5 * cam.distance
            m.body_pos[self._backdrop_body] = [
                cam.lookat[0] + behind * np.cos(a),
                cam.lookat[1] + behind * np.sin(a),
                0.0,
            ]
            m.body_quat[self._backdrop_body] = yaw_quat(cam.azimuth - 90.0)
        m.vis.global_.fovy = cam.fovy
        self._cam.lookat[:] = cam.lookat
        self._cam.distance = cam.distance
        self._cam.azimuth = cam.azimuth
        self._cam.elevation = cam.elevation
        mujoco.mj_kinematics(m, self.data)
        self._renderer.update_scene(self.data, camera=self._cam)
        img = self._renderer.render()
        if self.supersample > 1:
            return np.asarray(Image.fromarray(img).reduce(self.supersample))
        return img.copy()
