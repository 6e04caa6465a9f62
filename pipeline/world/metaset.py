"""Meta-training classes: procedurally generated object *archetypes* from a seeded grammar.

The paper meta-trains its Relation Network on miniImageNet's 64 training classes (section 3.2.1,
Ravi and Larochelle's split). We have no photographs, so each class here is an archetype drawn
from a small shape grammar: an optional ring of legs, a vertical stack of 1-4 *tiers* (box,
cylinder, sphere, ellipsoid, capsule, cone, torus, bowl, disc, each with its own proportions),
optional radial arms or a side handle, and a 2-3 colour palette with finishes. Tables, lamps,
bottles, mugs, stools, cone stacks, totems and trees all fall out of it. Classes are kept
distinct: no two archetypes share the same *signature* (tier kinds, leg count, arm count).
An instance of a class jitters every proportion (about +-15%) and, per picture, the colours.

The grammar never uses the obstacle builders of ``obstacle_models.py``, so none of the five
query categories (chair, kettle, carton, basin, basket) is a meta-training class.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.world.obstacle_models import hsv
from pipeline.world.shapes import ObjectModel, Part, frustum, quat_from_axis_angle, rod, tube_arc, vessel

TIER_KINDS = ("box", "cylinder", "sphere", "ellipsoid", "capsule", "cone", "torus", "bowl", "disc")
FINISH_CHOICES = ("matte", "plastic", "metal", "speckle", "stripes", "weave")


@dataclass(frozen=True)
class Tier:
    kind: str
    width: float   # half-width (radius) in metres
    height: float  # full height in metres
    slot: int
    finish: str
    taper: float = 1.0  # top/bottom radius ratio (cones), depth ratio (boxes)


@dataclass(frozen=True)
class Archetype:
    """One meta-training class."""

    name: str
    tiers: tuple[Tier, ...]
    legs: int           # 0 = none
    leg_height: float
    leg_spread: float
    arms: int           # 0 = none
    arm_length: float
    arm_tier: int
    handle: bool
    palette_hsv: tuple[tuple[float, float, float], ...]

    def signature(self) -> tuple:
        return (tuple(t.kind for t in self.tiers), self.legs, self.arms, self.handle)


def _tier(rng: np.random.Generator, slot: int) -> Tier:
    kind = str(rng.choice(TIER_KINDS))
    width = float(rng.uniform(0.06, 0.28))
    height = {"disc": rng.uniform(0.015, 0.04), "torus": 0.0, "sphere": 0.0}.get(kind, rng.uniform(0.05, 0.4))
    if kind == "sphere":
        height = 2 * width
    if kind == "torus":
        height = width * rng.uniform(0.25, 0.5)
    return Tier(kind, width, float(height), slot, str(rng.choice(FINISH_CHOICES, p=[.3, .3, .15, .1, .1, .05])),
                float(rng.uniform(0.2, 1.0) if kind in ("cone", "box") else 1.0))


def make_archetype(rng: np.random.Generator, index: int) -> Archetype:
    n_tiers = int(rng.choice([1, 2, 3, 4], p=[0.2, 0.35, 0.3, 0.15]))
    n_colours = int(rng.integers(2, 4))
    first = int(rng.integers(0, n_colours))  # neighbouring tiers get different colours
    tiers = tuple(_tier(rng, (first + k) % n_colours) for k in range(n_tiers))
    legs = int(rng.choice([0, 0, 0, 0, 1, 3, 4, 5]))
    arms = int(rng.choice([0, 0, 0, 0, 0, 2, 3, 4, 6]))
    handle = bool(rng.random() < 0.15)
    base_h = rng.uniform(0, 1)
    palette = []
    for k in range(n_colours):  # spread hues so that a class has a recognisable colour pattern
        palette.append((float((base_h + k * rng.uniform(0.15, 0.5)) % 1.0), float(rng.uniform(0.3, 0.95)),
                        float(rng.uniform(0.35, 0.95))))
    kinds = "-".join(t.kind for t in tiers)
    extra = (f"+{legs}legs" if legs else "") + (f"+{arms}arms" if arms else "") + ("+handle" if handle else "")
    return Archetype(f"a{index:03d}_{kinds}{extra}", tiers, legs, float(rng.uniform(0.1, 0.45)),
                     float(rng.uniform(0.4, 1.0)), arms, float(rng.uniform(0.08, 0.25)),
                     int(rng.integers(0, n_tiers)), handle, tuple(palette))


def make_archetypes(n: int, seed: int) -> list[Archetype]:
    """``n`` archetypes with pairwise different signatures, deterministic in ``seed``."""
    if n < 0:
        raise ValueError(f"number of classes must be >= 0, got {n}")
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 2]))
    out: list[Archetype] = []
    seen: set[tuple] = set()
    tries = 0
    while len(out) < n:
        tries += 1
        if tries > 200 * (n + 1):
            raise RuntimeError(f"the grammar could not produce {n} distinct archetypes")
        a = make_archetype(rng, len(out))
        if a.signature() in seen:
            continue
        seen.add(a.signature())
        out.append(a)
    return out


def _tier_part(t: Tier, z: float, j: float) -> tuple[list[Part], float]:
    """Parts of tier ``t`` standing at height ``z`` with proportions jittered by ``j`` factors."""
    w, h = t.width * j, t.height * j
    if t.kind == "box":
        return [Part("box", (w, w * t.taper, h / 2), (0.0, 0.0, z + h / 2), slot=t.slot, finish=t.finish)], h
    if t.kind == "cylinder":
        return [Part("cylinder", (w, h / 2), (0.0, 0.0, z + h / 2), slot=t.slot, finish=t.finish)], h
    if t.kind == "disc":
        return [Part("cylinder", (w * 1.3, h / 2), (0.0, 0.0, z + h / 2), slot=t.slot, finish=t.finish)], h
    if t.kind == "sphere":
        return [Part("sphere", (w,), (0.0, 0.0, z + w), slot=t.slot, finish=t.finish)], 2 * w
    if t.kind == "ellipsoid":
        return [Part("ellipsoid", (w, w * 0.7, h / 2), (0.0, 0.0, z + h / 2), slot=t.slot, finish=t.finish)], h
    if t.kind == "capsule":
        r = min(w, h / 2) * 0.8
        half = max(h / 2 - r, 0.005)
        return [Part("capsule", (r, half), (0.0, 0.0, z + r + half), slot=t.slot, finish=t.finish)], 2 * (r + half)
    if t.kind == "cone":
        return [Part("mesh", (), (0.0, 0.0, z), slot=t.slot, finish=t.finish,
                     mesh=frustum(w, w * t.taper * 0.5, h, 24))], h
    if t.kind == "torus":
        tube = h / 2
        ring = tube_arc(w, tube, 0, 360, segments=32)
        return [Part("mesh", (), (0.0, 0.0, z + tube), quat_from_axis_angle((1.0, 0.0, 0.0), np.pi / 2),
                     slot=t.slot, finish=t.finish, mesh=ring)], h
    assert t.kind == "bowl"
    m = vessel([(w * 0.5, 0.0), (w * 0.9, h * 0.6), (w, h)], 0.01, 28)
    return [Part("mesh", (), (0.0, 0.0, z), slot=t.slot, finish=t.finish, mesh=m)], h


def build_meta_instance(arch: Archetype, rng: np.random.Generator) -> ObjectModel:
    """One instance of ``arch``: every proportion jittered by a factor in [0.85, 1.15]."""
    def jit() -> float:
        return float(rng.uniform(0.85, 1.15))

    parts: list[Part] = []
    z = 0.0
    top_w = arch.tiers[0].width
    if arch.legs:
        lh = arch.leg_height * jit()
        spread = arch.leg_spread * top_w * jit()
        leg_slot = arch.tiers[0].slot
        if arch.legs == 1:  # a pedestal
            parts.append(rod((0, 0, 0), (0, 0, lh), 0.02 * jit(), slot=leg_slot, finish="metal"))
            parts.append(Part("cylinder", (max(top_w * 0.7, 0.05), 0.01), (0.0, 0.0, 0.01), slot=leg_slot, finish="metal"))
        else:
            for k in range(arch.legs):
                a = 2 * np.pi * k / arch.legs + np.pi / arch.legs
                x, y = spread * np.cos(a), spread * np.sin(a)
                parts.append(rod((x * 1.15, y * 1.15, 0), (x, y, lh), 0.015 * jit(), slot=leg_slot, finish="matte"))
        z = lh
    tier_z = []
    for t in arch.tiers:
        ps, h = _tier_part(t, z, jit())
        tier_z.append((z, h, t))
        parts += ps
        z += h
    if arch.arms:
        z0, h, t = tier_z[arch.arm_tier]
        zc = z0 + h * 0.6
        L = arch.arm_length * jit()
        slot = (t.slot + 1) % len(arch.palette_hsv)
        for k in range(arch.arms):
            a = 2 * np.pi * k / arch.arms
            r0 = t.width * 0.8
            p0 = (r0 * np.cos(a), r0 * np.sin(a), zc)
            p1 = ((r0 + L) * np.cos(a), (r0 + L) * np.sin(a), zc + L * 0.3)
            parts.append(rod(p0, p1, 0.012, kind="capsule", slot=slot, finish="plastic"))
            parts.append(Part("sphere", (0.025,), p1, slot=slot, finish="plastic"))
    if arch.handle:
        z0, h, t = tier_z[0]
        hr = max(h * 0.35, 0.04)
        arc = tube_arc(hr, 0.012, -90, 90)
        parts.append(Part("mesh", (), (t.width, 0.0, z0 + h / 2), slot=(t.slot + 1) % len(arch.palette_hsv),
                          finish="plastic", mesh=arc))
    palette = tuple(hsv(*c) for c in arch.palette_hsv)
    return ObjectModel(arch.name, tuple(parts), palette)


def jitter_palette(arch: Archetype, rng: np.random.Generator) -> tuple[tuple[float, float, float], ...]:
    """Per-picture colours: the class palette with small hue, saturation and value jitter."""
    return tuple(hsv(h + rng.normal(0, 0.025), s * rng.uniform(0.8, 1.15), v * rng.uniform(0.75, 1.15))
                 for h, s, v in arch.palette_hsv)
