"""Meta-training classes: procedural object *families* (categories of varied instances).

The paper meta-trains its Relation Network on miniImageNet's 64 training classes (section 3.2.1,
Ravi and Larochelle's split), where a class is a category: many different objects that share a
kind of shape. We have no photographs, so each class here is a family drawn from a small shape
grammar. A family fixes the *structure*: a vertical stack of 1-4 tiers, each allowing one or two
part kinds (box, cylinder, sphere, ellipsoid, capsule, cone, torus, bowl, disc), the legs
(none, a pedestal, or a ring of legs), radial arms and a side handle, with typical proportions.
Every instance of a family then draws its own:

* proportions: an overall scale in [0.8, 1.25] and every width and height by a further factor
  in [0.65, 1.5];
* part kinds and counts: a tier's kind among the family's alternatives, an optional tier present
  or not, the number of legs and of arms from the family's range;
* colours and materials: a palette of 2-3 colours of any hue, and a finish (matte, plastic,
  metal, speckle, stripes, weave) per tier.

So colour says nothing about the class and recognising a class means recognising a shape kind,
which is what the query task asks (two instances per category; the support set shows other
instances). No two families share a *signature* (allowed tier kinds, leg style, arms, handle).

The grammar never uses the obstacle builders of ``obstacle_models.py``, so none of the five
query categories (chair, kettle, carton, basin, basket) is a meta-training class.
"""

from __future__ import annotations

import colorsys
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from pipeline.world import shapes
from pipeline.world.obstacle_models import hsv
from pipeline.world.shapes import ObjectModel, Part

TIER_KINDS = ("box", "cylinder", "sphere", "ellipsoid", "capsule", "cone", "torus", "bowl", "disc")
FINISH_CHOICES = ("matte", "plastic", "metal", "speckle", "stripes", "weave")
FINISH_WEIGHTS = (0.3, 0.3, 0.15, 0.1, 0.1, 0.05)
LEG_STYLES = ("none", "pedestal", "ring")
TIER_COUNT_P = (0.2, 0.35, 0.3, 0.15)  # the share of families with 1, 2, 3 and 4 tiers
MAX_TIERS = len(TIER_COUNT_P)
SCALE = (0.8, 1.25)  # an instance's overall scale
PROPORTION = (0.65, 1.5)  # an instance's factor on every width and height
OPTIONAL_TIER_P = 0.4  # an optional tier is left out of this share of instances
SECOND_KIND_P = 0.55  # share of a family's tiers that allow a second part kind
ALTERNATIVES = {  # a tier's second kind, if it has one: a part of similar bulk
    "box": ("cylinder", "disc"),
    "cylinder": ("box", "capsule", "cone"),
    "sphere": ("ellipsoid",),
    "ellipsoid": ("sphere", "capsule"),
    "capsule": ("cylinder", "ellipsoid"),
    "cone": ("cylinder", "bowl"),
    "torus": ("disc",),
    "bowl": ("cone", "sphere"),
    "disc": ("torus", "box"),
}


@dataclass(frozen=True)
class TierSpec:
    """One tier of a family: the part kinds it may take and its typical size."""

    kinds: tuple[str, ...]
    width: float  # typical half-width (radius) in metres
    height: float  # typical full height in metres (spheres: 2 x width; tori: tube diameter)
    taper: float  # top/bottom radius ratio (cones), depth ratio (boxes)
    optional: bool  # some instances leave it out (never every tier of an instance)


@dataclass(frozen=True)
class Family:
    """One meta-training class: the structure its instances share and the ranges they vary in."""

    name: str
    tiers: tuple[TierSpec, ...]
    leg_style: str  # LEG_STYLES
    leg_counts: tuple[int, ...]  # ring: the counts an instance may have
    leg_height: float
    leg_spread: float
    arm_counts: tuple[int, ...]  # (0,) = no arms
    arm_length: float
    arm_tier: int
    handle: bool
    n_colours: int

    def signature(self) -> tuple:
        return (
            tuple(t.kinds for t in self.tiers),
            self.leg_style,
            self.arm_counts != (0,),
            self.handle,
        )


def _tier_size(rng: np.random.Generator, kind: str) -> tuple[float, float]:
    width = float(rng.uniform(0.06, 0.28))
    if kind == "disc":
        return width, float(rng.uniform(0.015, 0.04))
    if kind == "sphere":
        return width, 2 * width
    if kind == "torus":
        return width, width * float(rng.uniform(0.25, 0.5))
    return width, float(rng.uniform(0.05, 0.4))


def _tier_spec(rng: np.random.Generator, optional: bool) -> TierSpec:
    first = str(rng.choice(TIER_KINDS))
    kinds = (first,)
    if (
        rng.random() < SECOND_KIND_P
    ):  # a second kind of similar bulk: round <-> square, cone <-> cylinder ...
        second = str(rng.choice(ALTERNATIVES[first]))
        kinds = tuple(sorted((first, second)))
    width, height = _tier_size(rng, first)
    taper = float(rng.uniform(0.2, 1.0))
    return TierSpec(kinds, width, height, taper, optional)


def make_family(rng: np.random.Generator, index: int) -> Family:
    n_tiers = int(rng.choice(list(range(1, MAX_TIERS + 1)), p=list(TIER_COUNT_P)))
    tiers = tuple(
        _tier_spec(rng, optional=n_tiers > 1 and k > 0 and rng.random() < 0.3)
        for k in range(n_tiers)
    )
    leg_style = str(rng.choice(LEG_STYLES, p=[0.5, 0.15, 0.35]))
    low = int(rng.integers(3, 6))
    leg_counts = {
        "none": (0,),
        "pedestal": (1,),
        "ring": tuple(range(low, low + int(rng.integers(1, 3)))),
    }[leg_style]
    arm_counts = (0,)
    if rng.random() < 0.35:
        low = int(rng.integers(2, 6))
        arm_counts = tuple(range(low, low + int(rng.integers(1, 4))))
    handle = bool(rng.random() < 0.15)
    kinds = "-".join("|".join(t.kinds) + ("?" if t.optional else "") for t in tiers)
    extra = {"none": "", "pedestal": "+pedestal", "ring": "+legs"}[leg_style] + (
        "+arms" if arm_counts != (0,) else ""
    )
    extra += "+handle" if handle else ""
    return Family(
        f"f{index:03d}_{kinds}{extra}",
        tiers,
        leg_style,
        leg_counts,
        float(rng.uniform(0.1, 0.45)),
        float(rng.uniform(0.4, 1.0)),
        arm_counts,
        float(rng.uniform(0.08, 0.25)),
        int(rng.integers(0, n_tiers)),
        handle,
        int(rng.integers(2, 4)),
    )


def family_stream(seed: int) -> Iterator[Family]:
    """Families with pairwise different signatures, one after another, deterministic in ``seed``
    (a family's index in its name is its place in the stream)."""
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 3]))
    seen: set[tuple] = set()
    tries = 0
    while True:
        tries += 1
        if tries > 200 * (len(seen) + 1):
            raise RuntimeError(
                f"the grammar could not produce more than {len(seen)} distinct families"
            )
        f = make_family(rng, len(seen))
        if f.signature() in seen:
            continue
        seen.add(f.signature())
        tries = 0
        yield f


def make_families(n: int, seed: int) -> list[Family]:
    """``n`` families with pairwise different signatures, deterministic in ``seed``."""
    if n < 0:
        raise ValueError(f"number of classes must be >= 0, got {n}")
    stream = family_stream(seed)
    return [next(stream) for _ in range(n)]


def _tier_part(
    kind: str, w: float, h: float, taper: float, z: float, slot: int, finish: str
) -> tuple[Part, float]:
    """The part of one tier of kind ``kind`` (half-width ``w``, height ``h``) standing at height ``z``."""
    if kind == "box":
        return Part(
            "box", (w, w * taper, h / 2), (0.0, 0.0, z + h / 2), slot=slot, finish=finish
        ), h
    if kind == "cylinder":
        return Part("cylinder", (w, h / 2), (0.0, 0.0, z + h / 2), slot=slot, finish=finish), h
    if kind == "disc":
        h = min(h, 0.05)
        return Part(
            "cylinder", (w * 1.3, h / 2), (0.0, 0.0, z + h / 2), slot=slot, finish=finish
        ), h
    if kind == "sphere":
        return Part("sphere", (w,), (0.0, 0.0, z + w), slot=slot, finish=finish), 2 * w
    if kind == "ellipsoid":
        return Part(
            "ellipsoid", (w, w * 0.7, h / 2), (0.0, 0.0, z + h / 2), slot=slot, finish=finish
        ), h
    if kind == "capsule":
        r = min(w, h / 2) * 0.8
        half = max(h / 2 - r, 0.005)
        return Part("capsule", (r, half), (0.0, 0.0, z + r + half), slot=slot, finish=finish), 2 * (
            r + half
        )
    if kind == "cone":
        return Part(
            "mesh",
            (),
            (0.0, 0.0, z),
            slot=slot,
            finish=finish,
            mesh=shapes.frustum(w, w * taper * 0.5, h, 24),
        ), h
    if kind == "torus":
        tube = min(h, w * 0.5) / 2
        ring = shapes.tube_arc(w, tube, 0, 360, segments=32)
        return Part(
            "mesh",
            (),
            (0.0, 0.0, z + tube),
            shapes.quat_from_axis_angle((1.0, 0.0, 0.0), np.pi / 2),
            slot=slot,
            finish=finish,
            mesh=ring,
        ), 2 * tube
    assert kind == "bowl"
    m = shapes.vessel([(w * 0.5, 0.0), (w * 0.9, h * 0.6), (w, h)], 0.01, 28)
    return Part("mesh", (), (0.0, 0.0, z), slot=slot, finish=finish, mesh=m), h


def _palette(rng: np.random.Generator, n: int) -> tuple[tuple[float, float, float], ...]:
    """An instance's colours: any hue; neighbouring slots apart in hue so the parts stay distinct."""
    h0 = rng.uniform(0, 1)
    return tuple(
        hsv(h0 + k * rng.uniform(0.15, 0.5), rng.uniform(0.15, 0.95), rng.uniform(0.3, 0.95))
        for k in range(n)
    )


def build_meta_instance(fam: Family, rng: np.random.Generator) -> ObjectModel:
    """One instance of ``fam`` (module docstring: what varies between instances)."""

    def vary() -> float:
        return float(rng.uniform(*PROPORTION))

    scale = float(rng.uniform(*SCALE))
    palette = _palette(rng, fam.n_colours)
    present = [not t.optional or rng.random() >= OPTIONAL_TIER_P for t in fam.tiers]
    first_slot = int(rng.integers(0, fam.n_colours))
    parts: list[Part] = []
    z = 0.0
    top_w = fam.tiers[0].width * scale
    if fam.leg_style != "none":
        lh = fam.leg_height * scale * vary()
        if fam.leg_style == "pedestal":
            parts.append(
                shapes.rod((0, 0, 0), (0, 0, lh), 0.02 * vary(), slot=first_slot, finish="metal")
            )
            parts.append(
                Part(
                    "cylinder",
                    (max(top_w * 0.7 * vary(), 0.05), 0.01),
                    (0.0, 0.0, 0.01),
                    slot=first_slot,
                    finish="metal",
                )
            )
        else:
            n_legs = int(rng.choice(fam.leg_counts))
            spread = fam.leg_spread * top_w * vary()
            finish = str(rng.choice(FINISH_CHOICES[:3]))
            for k in range(n_legs):
                a = 2 * np.pi * k / n_legs + np.pi / n_legs
                x, y = spread * np.cos(a), spread * np.sin(a)
                parts.append(
                    shapes.rod(
                        (x * 1.15, y * 1.15, 0),
                        (x, y, lh),
                        0.015 * vary(),
                        slot=first_slot,
                        finish=finish,
                    )
                )
        z = lh
    tier_z = []
    for k, (t, here) in enumerate(zip(fam.tiers, present)):
        if not here:
            continue
        kind = str(rng.choice(t.kinds))
        w = t.width * scale * vary()
        h = 2 * w if kind == "sphere" else t.height * scale * vary()
        taper = float(np.clip(t.taper * vary(), 0.15, 1.0))
        slot = (first_slot + k) % fam.n_colours
        part, h = _tier_part(
            kind, w, h, taper, z, slot, str(rng.choice(FINISH_CHOICES, p=FINISH_WEIGHTS))
        )
        tier_z.append((z, h, w, slot, k))
        parts.append(part)
        z += h
    arms = int(rng.choice(fam.arm_counts))
    if arms:
        z0, h, w, slot, _ = min(tier_z, key=lambda e: abs(e[4] - fam.arm_tier))
        zc = z0 + h * 0.6
        length = fam.arm_length * scale * vary()
        slot = (slot + 1) % fam.n_colours
        for k in range(arms):
            a = 2 * np.pi * k / arms
            r0 = w * 0.8
            p0 = (r0 * np.cos(a), r0 * np.sin(a), zc)
            p1 = ((r0 + length) * np.cos(a), (r0 + length) * np.sin(a), zc + length * 0.3)
            parts.append(shapes.rod(p0, p1, 0.012, kind="capsule", slot=slot, finish="plastic"))
            parts.append(Part("sphere", (0.025,), p1, slot=slot, finish="plastic"))
    if fam.handle:
        z0, h, w, slot, _ = tier_z[0]
        hr = max(h * 0.35, 0.04)
        parts.append(
            Part(
                "mesh",
                (),
                (w, 0.0, z0 + h / 2),
                slot=(slot + 1) % fam.n_colours,
                finish="plastic",
                mesh=shapes.tube_arc(hr, 0.012, -90, 90),
            )
        )
    return ObjectModel(fam.name, tuple(parts), palette)


def jitter_palette(
    palette: tuple[tuple[float, float, float], ...], rng: np.random.Generator
) -> tuple[tuple[float, float, float], ...]:
    """Per-picture colours: an instance's palette with small hue, saturation and value jitter."""
    out = []
    for rgb in palette:
        h, s, v = colorsys.rgb_to_hsv(*rgb)
        out.append(
            hsv(h + rng.normal(0, 0.025), s * rng.uniform(0.8, 1.15), v * rng.uniform(0.75, 1.15))
        )
    return tuple(out)
