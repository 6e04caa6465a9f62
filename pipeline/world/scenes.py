"""The three settings pictures are taken in, built as MuJoCo ``MjSpec`` scenes (no XML).

* ``maze``: where the robot meets obstacles (query pictures, paper Figure 6 middle): a tiled floor
  with grid lines, the 5x5 maze's outer walls, two dark blocks standing for other obstacles, warm
  ceiling light. The obstacle stands in the centre cell at the origin; one cell is ``cell`` metres.
* ``catalogue``: where the support pictures come from (Figure 6 right): a bright, seamless studio
  backdrop, soft frontal light. Its gap to ``maze`` (background, light, viewpoint, instance) is
  what the paper's dynamic support set closes.
* ``studio``: the meta-training world: a floor and a backdrop whose colour and texture change
  per picture, a light whose direction and colour change per picture.

A scene holds several objects at the origin; a picture shows exactly one of them (the others are
made fully transparent, which MuJoCo skips when drawing), so one compiled model and one renderer
serve many pictures. Materials are shared by name (:data:`MATERIALS`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.world.renderer_env import mujoco
from pipeline.world.shapes import ObjectModel, Part

SETTINGS = ("maze", "catalogue", "studio")


@dataclass(frozen=True)
class SceneLayout:
    """Names to look up after compiling: per object its body and its geoms (in part order)."""

    setting: str
    bodies: tuple[str, ...]
    geoms: tuple[tuple[str, ...], ...]
    slots: tuple[tuple[int, ...], ...]
    has_backdrop: bool


@dataclass(frozen=True)
class Texture:
    """A built-in 2D texture: MuJoCo's ``mjBUILTIN_<builtin>`` of two colours, ``size`` pixels
    square, with an optional ``mjMARK_<mark>`` in ``markrgb`` (``random``: the share of random
    pixels)."""

    builtin: str
    rgb1: tuple[float, float, float]
    rgb2: tuple[float, float, float]
    size: int = 64
    mark: str | None = None
    markrgb: tuple[float, float, float] = (0.0, 0.0, 0.0)
    random: float = 0.0

    def add(self, spec, name: str):
        kw = dict(
            name=name,
            type=mujoco.mjtTexture.mjTEXTURE_2D,
            builtin=getattr(mujoco.mjtBuiltin, f"mjBUILTIN_{self.builtin}"),
            width=self.size,
            height=self.size,
            rgb1=list(self.rgb1),
            rgb2=list(self.rgb2),
        )
        if self.mark is not None:
            mark = getattr(mujoco.mjtMark, f"mjMARK_{self.mark}")
            kw.update(mark=mark, markrgb=list(self.markrgb), random=self.random)
        return spec.add_texture(**kw)


WHITE = (1.0, 1.0, 1.0)
#: The textures of every scene, by name (``weave`` is drawn: :func:`_weave_texture`).
TEXTURES = {
    "speckle": Texture("FLAT", WHITE, WHITE, 64, "RANDOM", (0.75, 0.75, 0.75), 0.08),
    "stripes": Texture("GRADIENT", WHITE, (0.55, 0.55, 0.55), 32),
    "bg_checker": Texture("CHECKER", WHITE, (0.6, 0.6, 0.6), 64),
    "bg_speckle": Texture("FLAT", WHITE, WHITE, 128, "RANDOM", (0.5, 0.5, 0.5), 0.15),
    "bg_stripes": Texture("GRADIENT", WHITE, (0.5, 0.5, 0.5), 32),
}
#: The materials of every scene, by name: an object's finishes (``shapes.FINISHES``), then the
#: backgrounds (``bg_``); a material named as a texture wears it (MuJoCo's keyword arguments).
MATERIALS = {
    "matte": dict(specular=0.05, shininess=0.1),
    "plastic": dict(specular=0.45, shininess=0.6),
    "metal": dict(specular=0.9, shininess=0.9),
    "weave": dict(texrepeat=(1.0, 6.0), specular=0.05, shininess=0.1),
    "speckle": dict(texrepeat=(2.0, 2.0), texuniform=True, specular=0.05, shininess=0.1),
    "stripes": dict(texrepeat=(4.0, 4.0), texuniform=True, specular=0.2, shininess=0.3),
    "bg_plain": dict(specular=0.0, shininess=0.0),
    "bg_checker": dict(texrepeat=(2.0, 2.0), texuniform=True, specular=0.0),
    "bg_speckle": dict(texrepeat=(1.0, 1.0), texuniform=True, specular=0.0),
    "bg_stripes": dict(texrepeat=(3.0, 3.0), texuniform=True, specular=0.0),
}
#: The maze floor's (:func:`add_floor_tiles`: its material's repeat depends on the cell size).
TILES = Texture("CHECKER", (0.62, 0.60, 0.55), (0.55, 0.53, 0.49), 128, "EDGE", (0.25, 0.25, 0.25))
BACKGROUND_MATERIALS = tuple(name for name in MATERIALS if name.startswith("bg_"))


def _material(spec, name: str, texture: str | None, texrepeat=(1.0, 1.0), texuniform=False, **kw):
    mat = spec.add_material(name=name, texrepeat=list(texrepeat), texuniform=texuniform, **kw)
    if texture is not None:
        mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = texture
    return mat


def _weave_texture(spec) -> None:
    """Over-under basket weave as an explicit RGB texture (light strands, dark gaps)."""
    n = 32
    y, x = np.mgrid[0:n, 0:n]
    cell = ((x // 8) + (y // 8)) % 2
    strand = np.where(cell == 0, np.abs((y % 8) - 3.5) / 3.5, np.abs((x % 8) - 3.5) / 3.5)
    v = 1.0 - 0.55 * strand**2
    gaps = (x % 8 == 0) | (y % 8 == 0)
    v = np.where(gaps, 0.35, v)
    img = np.clip(np.stack([v, v, v], axis=-1) * 255, 0, 255).astype(np.uint8)
    tex = spec.add_texture(
        name="weave", type=mujoco.mjtTexture.mjTEXTURE_2D, width=n, height=n, nchannel=3
    )
    tex.data = img.tobytes()


def _add_materials(spec) -> None:
    """Every scene's textures (:data:`TEXTURES`) and materials (:data:`MATERIALS`)."""
    _weave_texture(spec)
    for name, texture in TEXTURES.items():
        texture.add(spec, name)
    textured = {"weave", *TEXTURES}
    for name, kw in MATERIALS.items():
        _material(spec, name, name if name in textured else None, **kw)


def _add_part(spec, body, part: Part, name: str, mesh_name: str) -> None:
    G = mujoco.mjtGeom
    kw = dict(
        name=name,
        pos=list(part.pos),
        quat=list(part.quat),
        material=part.finish,
        rgba=[1.0, 1.0, 1.0, 1.0],
        contype=0,
        conaffinity=0,
        group=1,
    )
    if part.kind == "mesh":
        m = part.mesh
        assert m is not None
        mesh = spec.add_mesh(
            name=mesh_name,
            uservert=m.vertices.astype(float).ravel().tolist(),
            userface=m.faces.astype(int).ravel().tolist(),
        )
        if m.texcoords is not None:
            mesh.usertexcoord = m.texcoords.astype(float).ravel().tolist()
        mesh.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
        body.add_geom(type=G.mjGEOM_MESH, meshname=mesh_name, **kw)
        return
    size = list(part.size) + [0.0] * (3 - len(part.size))
    gtype = {
        "box": G.mjGEOM_BOX,
        "cylinder": G.mjGEOM_CYLINDER,
        "capsule": G.mjGEOM_CAPSULE,
        "sphere": G.mjGEOM_SPHERE,
        "ellipsoid": G.mjGEOM_ELLIPSOID,
    }[part.kind]
    body.add_geom(type=gtype, size=size, **kw)


#: Each setting's sky, a vertical gradient (top, bottom).
SKIES = {
    "maze": ((0.35, 0.33, 0.30), (0.12, 0.12, 0.12)),
    "catalogue": ((1.0, 1.0, 1.0), (0.85, 0.85, 0.88)),
    "studio": ((0.6, 0.65, 0.7), (0.2, 0.2, 0.22)),
}
#: The maze's border walls (the query pictures' and the robot's).
WALL_RGBA = (0.78, 0.80, 0.84, 1.0)


def add_sky(spec, setting: str) -> None:
    """The skybox of ``setting`` (:data:`SKIES`)."""
    top, bottom = SKIES[setting]
    spec.add_texture(
        name="sky",
        type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
        builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT,
        width=64,
        height=64,
        rgb1=list(top),
        rgb2=list(bottom),
    )


def add_floor_tiles(spec, cell: float) -> None:
    """The maze floor's material ``tiles``: a checker of 0.5 m squares, whatever the cell size."""
    TILES.add(spec, "tiles")
    repeat = (0.5 / cell, 0.5 / cell)
    _material(spec, "tiles", "tiles", texrepeat=repeat, texuniform=True, specular=0.1)


def add_walls(worldbody, boxes, height: float) -> None:
    """Border walls ``wall<k>``: a box ``(x, y, half_x, half_y)`` each, ``height`` tall, in
    :data:`WALL_RGBA`."""
    for k, (x, y, sx, sy) in enumerate(boxes):
        worldbody.add_geom(
            name=f"wall{k}",
            type=mujoco.mjtGeom.mjGEOM_BOX,
            size=[sx, sy, height / 2],
            pos=[x, y, height / 2],
            rgba=list(WALL_RGBA),
            material="bg_plain",
        )


def add_maze_lights(worldbody, shadows: bool) -> None:
    """The maze's light: a warm key light from above (casting shadows with ``shadows``) and a
    cool fill."""
    worldbody.add_light(
        name="key",
        type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
        pos=[0, 0, 3],
        dir=[-0.35, -0.25, -1],
        diffuse=[0.70, 0.63, 0.52],
        specular=[0.2, 0.2, 0.2],
        ambient=[0.36, 0.34, 0.32],
        castshadow=bool(shadows),
    )
    worldbody.add_light(
        name="fill",
        type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
        pos=[0, 0, 3],
        dir=[0.3, 0.5, -0.7],
        diffuse=[0.22, 0.22, 0.25],
        specular=[0.0, 0.0, 0.0],
        castshadow=False,
    )


def build_scene(
    setting: str,
    objects: list[ObjectModel],
    cell: float = 1.0,
    shadow_size: int = 512,
    offsamples: int = 0,
    shadows: bool = True,
):
    """``(MjSpec, SceneLayout)`` of ``objects`` (all at the origin) in ``setting``; ``shadows``
    says whether the key light casts shadows (they double the drawing time on llvmpipe)."""
    if setting not in SETTINGS:
        raise ValueError(f"unknown setting {setting!r}; expected one of {SETTINGS}")
    spec = mujoco.MjSpec()
    spec.modelname = f"{setting}_scene"
    spec.visual.quality.offsamples = offsamples
    spec.visual.quality.shadowsize = shadow_size
    spec.visual.global_.offwidth = 512
    spec.visual.global_.offheight = 512
    spec.visual.map.znear = 0.01
    _add_materials(spec)
    G = mujoco.mjtGeom
    wb = spec.worldbody
    add_sky(spec, setting)
    if setting == "maze":
        add_floor_tiles(spec, cell)
        wb.add_geom(
            name="floor",
            type=G.mjGEOM_PLANE,
            size=[3 * cell, 3 * cell, 0.1],
            material="tiles",
            pos=[0.0, 0.0, 0.0],
        )
        half, hw = 2.5 * cell, 0.05  # walls straddle the border of the 5x5 cells
        long, thick = half + hw, hw + hw
        walls = [(0, half, long, thick), (0, -half, long, thick)]
        walls += [(half, 0, thick, long), (-half, 0, thick, long)]
        add_walls(wb, walls, 0.6)
        for k, (cx, cy) in enumerate([(-2, 1), (1, -2), (2, 2)]):  # other obstacles: dark blocks
            wb.add_geom(
                name=f"block{k}",
                type=G.mjGEOM_BOX,
                size=[0.35 * cell, 0.35 * cell, 0.3],
                pos=[cx * cell, cy * cell, 0.3],
                rgba=[0.12, 0.12, 0.13, 1.0],
                material="bg_plain",
            )
        add_maze_lights(wb, shadows=True)
        has_backdrop = False
    else:
        wb.add_geom(
            name="floor",
            type=G.mjGEOM_PLANE,
            size=[6.0, 6.0, 0.1],
            material="bg_plain",
            rgba=[0.92, 0.92, 0.92, 1.0],
        )
        bd = wb.add_body(name="backdrop", pos=[0.0, -3.0, 0.0])
        bd.add_geom(
            name="backdrop",
            type=G.mjGEOM_BOX,
            size=[6.0, 0.05, 3.0],
            pos=[0.0, 0.0, 3.0],
            material="bg_plain",
            rgba=[0.95, 0.95, 0.95, 1.0],
        )
        wb.add_light(
            name="key",
            type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
            pos=[0, 0, 4],
            dir=[0.3, -0.5, -1],
            diffuse=[0.7, 0.7, 0.7],
            specular=[0.3, 0.3, 0.3],
            ambient=[0.35, 0.35, 0.35],
            castshadow=True,
        )
        wb.add_light(
            name="fill",
            type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
            pos=[0, 0, 4],
            dir=[-0.4, 0.5, -0.6],
            diffuse=[0.3, 0.3, 0.3],
            specular=[0.0, 0.0, 0.0],
            castshadow=False,
        )
        has_backdrop = True
    for light in spec.lights:
        light.castshadow = bool(shadows) and light.name == "key"
    spec.visual.headlight.ambient = [0.1, 0.1, 0.1]
    spec.visual.headlight.diffuse = [0.2, 0.2, 0.2]
    spec.visual.headlight.specular = [0.0, 0.0, 0.0]

    bodies, geoms, slots = [], [], []
    for i, obj in enumerate(objects):
        body = wb.add_body(name=f"obj{i}", pos=[0.0, 0.0, 0.0])
        names = []
        for j, part in enumerate(obj.parts):
            gname = f"obj{i}_g{j}"
            _add_part(spec, body, part, gname, f"obj{i}_m{j}")
            names.append(gname)
        bodies.append(f"obj{i}")
        geoms.append(tuple(names))
        slots.append(tuple(p.slot for p in obj.parts))
    return spec, SceneLayout(setting, tuple(bodies), tuple(geoms), tuple(slots), has_backdrop)
