"""Geometry vocabulary for procedural objects: parts (MuJoCo primitives or meshes) and mesh makers.

An object is a tuple of :class:`Part` in the object's own frame (x east, y north = the object's
front, face 0 of ``pictures.py``; z up, the floor at z = 0) plus a colour palette; a part names a
palette slot and a surface finish instead of a colour, so that one shape can be repainted per
picture without rebuilding the MuJoCo model. Pure data and numpy; no MuJoCo import here.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

PRIMITIVES = ("box", "cylinder", "capsule", "sphere", "ellipsoid", "mesh")
FINISHES = ("matte", "plastic", "metal", "weave", "speckle", "stripes")


@dataclass(frozen=True)
class Mesh:
    """Triangle mesh (vertices ``(n, 3)``, faces ``(m, 3)``, optional texture coordinates ``(n, 2)``)."""

    vertices: np.ndarray
    faces: np.ndarray
    texcoords: np.ndarray | None = None

    def radius(self) -> float:
        return float(np.linalg.norm(self.vertices, axis=1).max())


@dataclass(frozen=True)
class Part:
    """One rigid piece: a MuJoCo primitive with MuJoCo's ``size`` semantics, or a mesh.

    ``quat`` is (w, x, y, z); ``slot`` indexes the object's palette; ``finish`` one of FINISHES.
    """

    kind: str
    size: tuple[float, ...]
    pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
    quat: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    slot: int = 0
    finish: str = "matte"
    mesh: Mesh | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        if self.kind not in PRIMITIVES:
            raise ValueError(f"unknown part kind {self.kind!r}; expected one of {PRIMITIVES}")
        if self.finish not in FINISHES:
            raise ValueError(f"unknown finish {self.finish!r}; expected one of {FINISHES}")
        if (self.kind == "mesh") != (self.mesh is not None):
            raise ValueError("a part has a mesh if and only if its kind is 'mesh'")

    def bounding_radius(self) -> float:
        """Radius of a sphere about ``pos`` holding the part (for camera framing)."""
        s = self.size
        if self.kind == "box":
            return float(np.linalg.norm(s[:3]))
        if self.kind == "cylinder":
            return float(np.hypot(s[0], s[1]))
        if self.kind == "capsule":
            return float(s[0] + s[1])
        if self.kind == "sphere":
            return float(s[0])
        if self.kind == "ellipsoid":
            return float(max(s[:3]))
        assert self.mesh is not None
        return self.mesh.radius()


@dataclass(frozen=True)
class ObjectModel:
    """A procedural object: its parts, its palette (RGB in 0..1 per slot) and a readable name."""

    name: str
    parts: tuple[Part, ...]
    palette: tuple[tuple[float, float, float], ...]

    def scaled(self, factor: float) -> ObjectModel:
        """The same object uniformly scaled by ``factor`` about its foot."""
        f = float(factor)
        parts = []
        for p in self.parts:
            mesh = (
                None
                if p.mesh is None
                else Mesh(p.mesh.vertices * f, p.mesh.faces, p.mesh.texcoords)
            )
            parts.append(
                Part(
                    p.kind,
                    tuple(v * f for v in p.size),
                    tuple(v * f for v in p.pos),
                    p.quat,
                    p.slot,
                    p.finish,
                    mesh,
                )
            )
        return ObjectModel(self.name, tuple(parts), self.palette)

    def extent(self) -> tuple[float, float]:
        """``(height, horizontal radius)``: conservative size for framing the camera."""
        top = max(p.pos[2] + p.bounding_radius() for p in self.parts)
        rad = max(float(np.hypot(p.pos[0], p.pos[1])) + p.bounding_radius() for p in self.parts)
        return float(top), rad


# --------------------------------------------------------------------------- orientation helpers


def quat_from_axis_angle(
    axis: tuple[float, float, float], angle: float
) -> tuple[float, float, float, float]:
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    h = 0.5 * angle
    return (float(np.cos(h)), *(float(v) for v in np.sin(h) * a))


def quat_z_to(direction: np.ndarray) -> tuple[float, float, float, float]:
    """Quaternion turning the +z axis onto ``direction`` (MuJoCo cylinders/capsules lie along z)."""
    d = np.asarray(direction, dtype=float)
    d = d / np.linalg.norm(d)
    z = np.array([0.0, 0.0, 1.0])
    c = float(np.dot(z, d))
    if c > 1 - 1e-12:
        return (1.0, 0.0, 0.0, 0.0)
    if c < -1 + 1e-12:
        return (0.0, 1.0, 0.0, 0.0)
    axis = np.cross(z, d)
    return quat_from_axis_angle(tuple(axis), float(np.arccos(c)))


def rod(
    p0, p1, radius: float, kind: str = "cylinder", slot: int = 0, finish: str = "matte"
) -> Part:
    """A cylinder or capsule from point ``p0`` to point ``p1``."""
    a, b = np.asarray(p0, float), np.asarray(p1, float)
    half = float(np.linalg.norm(b - a)) / 2
    return Part(
        kind, (radius, half), tuple(float(v) for v in (a + b) / 2), quat_z_to(b - a), slot, finish
    )


def yaw_quat(deg: float) -> tuple[float, float, float, float]:
    """Rotation about +z by ``deg`` degrees (positive = counter-clockwise seen from above)."""
    return quat_from_axis_angle((0.0, 0.0, 1.0), np.deg2rad(deg))


# --------------------------------------------------------------------------- mesh makers


def revolve(
    profile: np.ndarray, sections: int = 32, u_repeat: float = 1.0, scale_y: float = 1.0
) -> Mesh:
    """Surface of revolution of ``profile`` (rows ``(r, z)``, in order along the surface) about z.

    Open surfaces (bowls, baskets, lamp shades) are fine: MuJoCo renders both sides of a face
    when the mesh is used for display only. Texture coordinates wrap ``u_repeat`` times around and
    follow the profile's arc length upward, so a woven texture follows the wall.
    """
    prof = np.asarray(profile, dtype=float)
    n = len(prof)
    ang = np.linspace(0.0, 2 * np.pi, sections + 1)
    r, z = prof[:, 0], prof[:, 1]
    xs = np.outer(np.cos(ang), r)
    ys = np.outer(np.sin(ang), r) * scale_y
    zs = np.broadcast_to(z, xs.shape)
    verts = np.stack([xs, ys, zs], axis=-1).reshape(-1, 3)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(prof, axis=0), axis=1))])
    u = np.outer(ang / (2 * np.pi) * u_repeat, np.ones(n))
    v = np.broadcast_to(arc / max(arc[-1], 1e-9), u.shape)
    tex = np.stack([u, v], axis=-1).reshape(-1, 2)
    faces = []
    for i in range(sections):
        for j in range(n - 1):
            a, b = i * n + j, (i + 1) * n + j
            faces.append((a, b, b + 1))
            faces.append((a, b + 1, a + 1))
    return Mesh(verts, np.asarray(faces, dtype=np.int64), tex)


def vessel(
    radii_heights: list[tuple[float, float]],
    thickness: float,
    sections: int = 32,
    u_repeat: float = 1.0,
    scale_y: float = 1.0,
) -> Mesh:
    """Open-topped vessel: outer wall through the given (r, z) points from the bottom centre up to
    the rim, then back down inside (offset by ``thickness``) to the inner floor."""
    outer = [(0.0, 0.0), *radii_heights]
    inner = [(max(r - thickness, 0.0), max(z, thickness)) for r, z in reversed(radii_heights)]
    prof = np.array(outer + inner + [(0.0, thickness)])
    return revolve(prof, sections, u_repeat, scale_y)


def frustum(r_bottom: float, r_top: float, height: float, sections: int = 32) -> Mesh:
    """Closed truncated cone standing on z = 0 (a cone when ``r_top`` is 0)."""
    prof = np.array([(0.0, 0.0), (r_bottom, 0.0), (r_top, height), (0.0, height)])
    return revolve(prof, sections)


def tube_arc(
    radius: float,
    tube: float,
    start_deg: float,
    stop_deg: float,
    segments: int = 20,
    sides: int = 8,
) -> Mesh:
    """Part of a torus in the x-z plane (centre at the origin): handles and hoops."""
    t = np.deg2rad(np.linspace(start_deg, stop_deg, segments + 1))
    p = np.linspace(0, 2 * np.pi, sides + 1)[:-1]
    centre = np.stack([radius * np.cos(t), np.zeros_like(t), radius * np.sin(t)], axis=1)
    radial = np.stack([np.cos(t), np.zeros_like(t), np.sin(t)], axis=1)
    ey = np.array([0.0, 1.0, 0.0])
    verts = centre[:, None, :] + tube * (
        np.cos(p)[None, :, None] * radial[:, None, :] + np.sin(p)[None, :, None] * ey[None, None, :]
    )
    verts = verts.reshape(-1, 3)
    faces = []
    for i in range(segments):
        for j in range(sides):
            a, b = i * sides + j, i * sides + (j + 1) % sides
            c, d = a + sides, b + sides
            faces.append((a, c, d))
            faces.append((a, d, b))
    return Mesh(verts, np.asarray(faces, dtype=np.int64))
