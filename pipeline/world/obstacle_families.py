"""How each of the five query categories builds a random instance (paper section 4.1, Figure 6).

The paper photographs real chairs, kettles, cartons, basins and baskets. We build each category
as a seeded *family*: every instance draws its proportions, part styles, colours and finishes
from the category's ranges, so a category is recognisable but never one fixed object. All sizes
are in metres; the floor is z = 0 and the object's front (face 0, "north") looks along +y.

Fronts: a chair's front is the side one sits down from (backrest at -y); a kettle's front is its
spout (handle at -y); a carton's front carries its label; a basin's front is where its lip dips
or, for round ones, the side of its front handle; a basket's handle spans x, so it is seen as an
arch from north and south and edge-on from east and west.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from pipeline.world.obstacle_palette import bright, hsv, neutral, steel, wood
from pipeline.world.pictures import CATEGORIES
from pipeline.world.shapes import (
    ObjectModel,
    Part,
    frustum,
    quat_from_axis_angle,
    rod,
    tube_arc,
    vessel,
    yaw_quat,
)

# --------------------------------------------------------------------------- chair


def chair(rng: np.random.Generator) -> ObjectModel:
    seat_h = rng.uniform(0.42, 0.50)
    w, d = rng.uniform(0.40, 0.52), rng.uniform(0.38, 0.50)
    t = rng.uniform(0.03, 0.07)
    back_h = rng.uniform(0.35, 0.55)
    style = str(rng.choice(["wood", "plastic", "metal"]))
    frame = {"wood": wood, "plastic": bright, "metal": steel}[style](rng)
    seat = bright(rng) if rng.random() < 0.5 else (frame if style != "metal" else wood(rng))
    ffin = {"wood": "matte", "plastic": "plastic", "metal": "metal"}[style]
    sfin = "plastic" if style == "plastic" else str(rng.choice(["matte", "plastic"]))
    legs_round = rng.random() < 0.5
    lr = rng.uniform(0.016, 0.028)
    parts = [Part("box", (w / 2, d / 2, t / 2), (0.0, 0.0, seat_h - t / 2), slot=0, finish=sfin)]
    xs, ys = w / 2 - lr, d / 2 - lr
    for sx in (-1, 1):
        for sy in (-1, 1):
            top = seat_h - t if sy > 0 else seat_h + back_h  # rear legs become back posts
            if legs_round:
                parts.append(
                    rod((sx * xs, sy * ys, 0.0), (sx * xs, sy * ys, top), lr, slot=1, finish=ffin)
                )
            else:
                parts.append(
                    Part("box", (lr, lr, top / 2), (sx * xs, sy * ys, top / 2), slot=1, finish=ffin)
                )
    back = str(rng.choice(["panel", "slats", "spindles"]))
    yb = -ys
    if back == "panel":
        ph = back_h * rng.uniform(0.45, 0.8)
        parts.append(
            Part(
                "box", (xs, 0.015, ph / 2), (0.0, yb, seat_h + back_h - ph / 2), slot=0, finish=sfin
            )
        )
    elif back == "slats":
        n = int(rng.integers(2, 5))
        for k in range(n):
            z = seat_h + back_h * (0.35 + 0.6 * (k + 1) / n)
            parts.append(Part("box", (xs, 0.012, 0.025), (0.0, yb, z), slot=1, finish=ffin))
    else:
        parts.append(
            Part("box", (xs, 0.015, 0.03), (0.0, yb, seat_h + back_h - 0.03), slot=1, finish=ffin)
        )
        n = int(rng.integers(3, 7))
        for k in range(n):
            x = -xs + 2 * xs * (k + 1) / (n + 1)
            parts.append(
                rod((x, yb, seat_h), (x, yb, seat_h + back_h - 0.05), 0.009, slot=1, finish=ffin)
            )
    if rng.random() < 0.3:  # arm rests
        arm_z = seat_h + rng.uniform(0.18, 0.25)
        for sx in (-1, 1):
            parts.append(
                Part("box", (0.025, d / 2, 0.015), (sx * xs, 0.0, arm_z), slot=1, finish=ffin)
            )
            parts.append(
                rod(
                    (sx * xs, ys * 0.85, seat_h),
                    (sx * xs, ys * 0.85, arm_z),
                    lr * 0.8,
                    slot=1,
                    finish=ffin,
                )
            )
    if rng.random() < 0.5:  # stretchers between the legs
        z = rng.uniform(0.10, 0.2)
        for sx in (-1, 1):
            parts.append(rod((sx * xs, -ys, z), (sx * xs, ys, z), lr * 0.6, slot=1, finish=ffin))
    return ObjectModel("chair", tuple(parts), (seat, frame))


# --------------------------------------------------------------------------- kettle


def kettle(rng: np.random.Generator) -> ObjectModel:
    style = str(rng.choice(["steel", "plastic", "enamel"]))
    body_c = {"steel": steel, "plastic": bright, "enamel": bright}[style](rng)
    trim_c = neutral(rng) if style != "enamel" else hsv(0, 0, rng.uniform(0.05, 0.2))
    bfin = "metal" if style == "steel" else "plastic"
    r = rng.uniform(0.12, 0.16)
    h = rng.uniform(0.20, 0.30)
    electric = style == "plastic" or rng.random() < 0.3
    z0 = 0.03 if electric else 0.0
    parts: list[Part] = []
    if electric:
        parts.append(
            Part("cylinder", (r * 1.05, 0.015), (0.0, 0.0, 0.015), slot=1, finish="plastic")
        )
    shape = str(rng.choice(["cylinder", "bulb", "cone"]))
    if shape == "cylinder":
        parts.append(Part("cylinder", (r, h / 2), (0.0, 0.0, z0 + h / 2), slot=0, finish=bfin))
        r_top = r
    elif shape == "bulb":
        parts.append(
            Part(
                "ellipsoid", (r * 1.1, r * 1.1, h / 2), (0.0, 0.0, z0 + h / 2), slot=0, finish=bfin
            )
        )
        r_top = r * 0.6
    else:
        r_top = r * rng.uniform(0.5, 0.7)
        parts.append(
            Part("mesh", (), (0.0, 0.0, z0), slot=0, finish=bfin, mesh=frustum(r * 1.1, r_top, h))
        )
    top = z0 + h
    lid = Part("cylinder", (r_top * 0.8, 0.012), (0.0, 0.0, top + 0.006), slot=1, finish="plastic")
    parts.append(lid)
    parts.append(
        Part("sphere", (rng.uniform(0.02, 0.03),), (0.0, 0.0, top + 0.03), slot=1, finish="plastic")
    )
    # spout toward +y (the front)
    sz = z0 + h * rng.uniform(0.25, 0.5)
    tip = (0.0, r + rng.uniform(0.07, 0.12), top + rng.uniform(-0.03, 0.03))
    parts.append(
        rod((0.0, r * 0.7, sz), tip, rng.uniform(0.015, 0.025), kind="capsule", slot=0, finish=bfin)
    )
    # handle toward -y: an arch over the top (stove kettles) or at the back (jugs)
    if not electric and rng.random() < 0.5:
        hr = r_top * rng.uniform(0.9, 1.2)
        arc = tube_arc(hr, 0.012, 0, 180)
        parts.append(
            Part(
                "mesh",
                (),
                (0.0, 0.0, top + 0.02),
                yaw_quat(90.0),
                slot=1,
                finish="plastic",
                mesh=arc,
            )
        )
    else:
        hr = h * rng.uniform(0.3, 0.4)
        arc = tube_arc(hr, 0.016, -90, 90)
        parts.append(
            Part(
                "mesh",
                (),
                (0.0, -r * 0.95, z0 + h * 0.55),
                yaw_quat(-90.0),
                slot=1,
                finish="plastic",
                mesh=arc,
            )
        )
    return ObjectModel("kettle", tuple(parts), (body_c, trim_c))


# --------------------------------------------------------------------------- carton


def carton(rng: np.random.Generator) -> ObjectModel:
    w, d, h = rng.uniform(0.34, 0.60), rng.uniform(0.28, 0.48), rng.uniform(0.26, 0.50)
    kraft = rng.random() < 0.75
    box_c = (
        hsv(rng.uniform(0.07, 0.11), rng.uniform(0.35, 0.6), rng.uniform(0.5, 0.8))
        if kraft
        else hsv(rng.uniform(0, 1), rng.uniform(0.0, 0.15), rng.uniform(0.75, 0.95))
    )
    tape_c = (
        hsv(rng.uniform(0.06, 0.12), rng.uniform(0.2, 0.5), rng.uniform(0.6, 0.9))
        if rng.random() < 0.6
        else bright(rng)
    )
    label_c = hsv(0, 0, rng.uniform(0.85, 1.0)) if rng.random() < 0.6 else bright(rng)
    parts = [Part("box", (w / 2, d / 2, h / 2), (0.0, 0.0, h / 2), slot=0, finish="speckle")]
    if rng.random() < 0.35:  # open flaps, tilted outward
        ang = np.deg2rad(rng.uniform(20, 70))
        fl = d / 2 * rng.uniform(0.8, 1.0)
        for sy in (-1, 1):
            q = quat_from_axis_angle((1.0, 0.0, 0.0), sy * ang)
            off = (0.0, sy * (d / 2 + np.sin(ang) * fl / 2), h + np.cos(ang) * fl / 2)
            parts.append(Part("box", (w / 2, 0.004, fl / 2), off, q, slot=0, finish="speckle"))
    else:
        tw = rng.uniform(0.03, 0.06)
        parts.append(
            Part("box", (tw, d / 2 + 0.002, 0.003), (0.0, 0.0, h + 0.001), slot=1, finish="plastic")
        )
        drop = h * rng.uniform(0.15, 0.3)
        for sy in (-1, 1):
            parts.append(
                Part(
                    "box",
                    (tw, 0.003, drop / 2),
                    (0.0, sy * (d / 2 + 0.001), h - drop / 2),
                    slot=1,
                    finish="plastic",
                )
            )
    lw, lh = w * rng.uniform(0.25, 0.45), h * rng.uniform(0.2, 0.35)
    lx, lz = rng.uniform(-w / 2 + lw, w / 2 - lw), rng.uniform(lh, h - lh)
    parts.append(Part("box", (lw, 0.003, lh), (lx, d / 2 + 0.002, lz), slot=2, finish="matte"))
    if rng.random() < 0.5:  # a printed stripe on the front and back
        sz = rng.uniform(0.1, 0.9) * h
        for sy in (-1, 1):
            parts.append(
                Part(
                    "box",
                    (w / 2 + 0.001, 0.002, 0.012),
                    (0.0, sy * (d / 2 + 0.001), sz),
                    slot=1,
                    finish="matte",
                )
            )
    return ObjectModel("carton", tuple(parts), (box_c, tape_c, label_c))


# --------------------------------------------------------------------------- basin


def basin(rng: np.random.Generator) -> ObjectModel:
    r0, r1 = rng.uniform(0.14, 0.2), rng.uniform(0.26, 0.34)
    h = rng.uniform(0.12, 0.2)
    bulge = rng.uniform(-0.02, 0.03)
    oval = rng.uniform(0.75, 1.0) if rng.random() < 0.4 else 1.0
    style = str(rng.choice(["plastic", "enamel", "metal"]))
    c0 = {
        "plastic": bright,
        "enamel": lambda g: hsv(0, 0, g.uniform(0.85, 0.97)),
        "metal": steel,
    }[style](rng)
    c1 = bright(rng) if style == "enamel" else c0
    fin = {"plastic": "plastic", "enamel": "plastic", "metal": "metal"}[style]
    wall = [(r0, 0.0), (0.5 * (r0 + r1) + bulge, h * 0.55), (r1, h)]
    parts = [
        Part(
            "mesh",
            (),
            (0.0, 0.0, 0.0),
            slot=0,
            finish=fin,
            mesh=vessel(wall, 0.012, 40, scale_y=oval),
        )
    ]
    rim = tube_arc(r1, rng.uniform(0.008, 0.016), 0, 360, segments=40)
    q = quat_from_axis_angle((1.0, 0.0, 0.0), np.pi / 2)
    parts.append(
        Part(
            "mesh",
            (),
            (0.0, 0.0, h),
            q,
            slot=1,
            finish=fin,
            mesh=type(rim)(rim.vertices * np.array([1.0, 1.0, oval]), rim.faces),
        )
    )
    if rng.random() < 0.5:  # two ear handles, on the front and the back
        for sy in (-1, 1):
            ear = tube_arc(0.04, 0.01, 0, 180)
            parts.append(
                Part("mesh", (), (0.0, sy * r1 * oval, h - 0.005), slot=1, finish=fin, mesh=ear)
            )
    elif rng.random() < 0.5:  # a pouring lip at the front
        parts.append(
            Part("ellipsoid", (0.05, 0.03, 0.012), (0.0, r1 * oval + 0.01, h), slot=1, finish=fin)
        )
    return ObjectModel("basin", tuple(parts), (c0, c1))


# --------------------------------------------------------------------------- basket


def basket(rng: np.random.Generator) -> ObjectModel:
    r0, r1 = rng.uniform(0.13, 0.19), rng.uniform(0.17, 0.26)
    h = rng.uniform(0.18, 0.32)
    oval = rng.uniform(0.65, 1.0) if rng.random() < 0.5 else 1.0
    wicker = rng.random() < 0.7
    c0 = (
        hsv(rng.uniform(0.07, 0.13), rng.uniform(0.35, 0.7), rng.uniform(0.45, 0.85))
        if wicker
        else bright(rng)
    )
    c1 = (
        hsv(rng.uniform(0.06, 0.12), rng.uniform(0.5, 0.8), rng.uniform(0.25, 0.55))
        if rng.random() < 0.7
        else bright(rng)
    )
    wall = [(r0, 0.0), (r1, h)]
    parts = [
        Part(
            "mesh",
            (),
            (0.0, 0.0, 0.0),
            slot=0,
            finish="weave",
            mesh=vessel(wall, 0.01, 40, u_repeat=float(rng.integers(12, 24)), scale_y=oval),
        )
    ]
    q = quat_from_axis_angle((1.0, 0.0, 0.0), np.pi / 2)
    tube = rng.uniform(0.01, 0.018)
    for z, rr in [(h, r1), (0.0 + tube, r0)]:
        ring = tube_arc(rr, tube, 0, 360, segments=40)
        parts.append(
            Part(
                "mesh",
                (),
                (0.0, 0.0, z),
                q,
                slot=1,
                finish="matte",
                mesh=type(ring)(ring.vertices * np.array([1.0, 1.0, oval]), ring.faces),
            )
        )
    if rng.random() < 0.75:  # the handle arches over the top across x
        hh = rng.uniform(0.12, 0.25)
        arch = tube_arc(r1, tube * 1.2, 0, 180, segments=24)
        v = arch.vertices * np.array([1.0, 1.0, hh / r1])
        parts.append(
            Part("mesh", (), (0.0, 0.0, h), slot=1, finish="matte", mesh=type(arch)(v, arch.faces))
        )
    else:  # two side grips
        for sx in (-1, 1):
            grip = tube_arc(0.045, tube, 0, 180)
            parts.append(
                Part(
                    "mesh",
                    (),
                    (sx * r1, 0.0, h - 0.06),
                    yaw_quat(90.0),
                    slot=1,
                    finish="matte",
                    mesh=grip,
                )
            )
    return ObjectModel("basket", tuple(parts), (c0, c1))


BUILDERS: dict[str, Callable[[np.random.Generator], ObjectModel]] = {
    "chair": chair,
    "kettle": kettle,
    "carton": carton,
    "basin": basin,
    "basket": basket,
}
assert tuple(BUILDERS) == CATEGORIES
