"""What to render: batches of pictures (one scene, one renderer each) and their manifest rows.

* query (paper section 4.1, Figure 6 middle): for each category, geometric instances 0 and 1,
  two distinct objects of the category (``obstacle_models.obstacle_instance``), stand in the maze;
  each is photographed from world sides N, E, S, W (faces 0..3) by the robot's camera at a fixed
  distance and height. 5 x 2 x 4 = 40 pictures, ids from ``pictures.picture_id``.
* support (Figure 6 right): per category ``support_per_category`` OTHER geometric instances
  (instance ids 2, 3, ...), one catalogue picture each: studio backdrop, bright light, raised
  camera, a three-quarter front view, object framed to fill the picture.
* train / val / test: meta-training families (``metaset.py``), split so that every validation
  and test family is at least ``min_family_distance`` from every training family
  (``family_split.py``); ``per_class`` pictures per class from
  ``ceil(per_class / views_per_instance)`` instances, random view, light, background and a
  little per-picture colour jitter.
* views: the ten query obstacles (each category's instances 0 and 1) in the maze, ``views_per_obstacle`` pictures each by the robot's camera (at its height) from a
  random side and a random distance in ``views_distance``: a larger query-like set for the
  colour test (``pipeline/fewshot/colour.py``); never a support or query picture.

Every random draw comes from a ``SeedSequence`` keyed by (seed, purpose, indices), so a picture
does not depend on which worker renders it or in which order.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from pipeline.manifest import SPLITS, Row
from pipeline.world.camera import CameraPose, framing_distance, robot_camera
from pipeline.world.family_split import MIN_DISTANCE, split_families
from pipeline.world.metaset import Family, build_meta_instance, jitter_palette
from pipeline.world.obstacle_models import (
    category_index,
    hsv,
    obstacle_instance,
)
from pipeline.world.pictures import CATEGORIES, INSTANCES_PER_CATEGORY, N_FACES, picture_id
from pipeline.world.renderer import Background, Lighting, Shot
from pipeline.world.scenes import BACKGROUND_MATERIALS
from pipeline.world.shapes import ObjectModel

META_SPLITS = ("train", "val", "test")  # the meta-training families' splits


@dataclass(frozen=True)
class MazeCamera:
    cell: float = 1.0
    camera_distance: float = 1.0
    camera_height: float = 0.35
    target_height: float = 0.22
    fovy: float = 55.0


@dataclass(frozen=True)
class CatalogueCamera:
    fovy: float = 40.0
    elevation: tuple[float, float] = (-35.0, -20.0)
    turn: tuple[float, float] = (20.0, 50.0)
    fill: float = 0.8


@dataclass(frozen=True)
class PlanConfig:
    seed: int = 0
    categories: tuple[str, ...] = CATEGORIES
    n_train_classes: int = 64
    n_val_classes: int = 16
    per_class: int = 60
    views_per_instance: int = 3
    support_per_category: int = 5
    maze: MazeCamera = MazeCamera()
    catalogue: CatalogueCamera = CatalogueCamera()
    n_test_classes: int = 20
    min_family_distance: float = MIN_DISTANCE
    views_per_obstacle: int = 40
    views_distance: tuple[float, float] = (0.7, 1.8)


@dataclass
class Batch:
    """Pictures sharing one scene (and so one compiled model and one renderer)."""

    name: str
    setting: str
    objects: list[ObjectModel]
    shots: list[Shot] = field(default_factory=list)
    files: list[str] = field(default_factory=list)


def _rng(*key: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence([int(k) for k in key]))


def _obstacle_instances(cfg: PlanConfig, name: str) -> tuple[Batch, list[tuple[int, int, int]]]:
    """A maze batch of the ten query obstacles (instances 0 and 1 of each category, two distinct
    objects) and, for each, its object in the batch, its category and its instance."""
    cats = [category_index(c) for c in cfg.categories]
    obstacles = [(c, inst) for c in cats for inst in range(INSTANCES_PER_CATEGORY)]
    objs = [obstacle_instance(c, inst, cfg.seed) for c, inst in obstacles]
    return Batch(name, "maze", objs), [(k, c, inst) for k, (c, inst) in enumerate(obstacles)]


def query_batch(cfg: PlanConfig) -> tuple[Batch, list[dict]]:
    (batch, obstacles), rows, mz = _obstacle_instances(cfg, "query"), [], cfg.maze
    for k, c, inst in obstacles:
        for face in range(N_FACES):
            cam = robot_camera(
                face, mz.camera_distance, mz.camera_height, mz.target_height, mz.fovy
            )
            pid = picture_id(c, inst, face)
            f = f"query/{CATEGORIES[c]}/q{pid:02d}_i{inst}_f{face}.png"
            batch.shots.append(Shot(k, 0.0, batch.objects[k].palette, cam))
            batch.files.append(f)
            rows.append(Row("query", c, CATEGORIES[c], inst, face, 0.0, pid, f)._asdict())
    return batch, rows


def support_batch(cfg: PlanConfig) -> tuple[Batch, list[dict]]:
    cats = [category_index(c) for c in cfg.categories]
    batch, rows = Batch("support", "catalogue", []), []
    cc = cfg.catalogue
    for c in cats:
        for j in range(cfg.support_per_category):
            inst = INSTANCES_PER_CATEGORY + j  # never a query instance
            obj = obstacle_instance(c, inst, cfg.seed)
            batch.objects.append(obj)
            r = _rng(cfg.seed, 4, c, inst)
            turn = float(r.uniform(*cc.turn)) * (1 if r.random() < 0.5 else -1)
            h, rad = obj.extent()
            cam = CameraPose(
                (0.0, 0.0, h * 0.45),
                framing_distance(h, rad, cc.fovy, cc.fill),
                -90.0 + float(r.uniform(-5, 5)),
                float(r.uniform(*cc.elevation)),
                cc.fovy,
            )
            bg = hsv(r.uniform(0, 1), r.uniform(0.0, 0.12), r.uniform(0.85, 1.0))
            shot = Shot(
                len(batch.objects) - 1,
                turn,
                obj.palette,
                cam,
                Lighting(
                    (float(r.uniform(-0.3, 0.3)), 0.6, -1.0), (0.8, 0.8, 0.8), (0.5, 0.5, 0.5)
                ),
                Background(bg, "bg_plain", bg, "bg_plain"),
            )
            f = f"support/{CATEGORIES[c]}/s_i{inst}.png"
            batch.shots.append(shot)
            batch.files.append(f)
            rows.append(
                Row("support", c, CATEGORIES[c], inst, -1, round(-turn, 3), -1, f)._asdict()
            )
    return batch, rows


def views_batch(cfg: PlanConfig) -> tuple[Batch, list[dict]]:
    """The colour test's larger query-like set (module docstring): ``views_per_obstacle`` maze
    pictures of each of the ten query obstacles, from random sides and distances."""
    (batch, obstacles), rows, mz = _obstacle_instances(cfg, "views"), [], cfg.maze
    for k, c, inst in obstacles:
        for j in range(cfg.views_per_obstacle):
            r = _rng(cfg.seed, 7, c, inst, j)
            distance = float(r.uniform(*cfg.views_distance))
            azimuth = float(r.uniform(0.0, 360.0))
            drop = mz.target_height - mz.camera_height
            cam = CameraPose(
                (0.0, 0.0, mz.target_height),
                float(np.hypot(distance, drop)),
                azimuth,
                float(np.rad2deg(np.arctan2(drop, distance))),
                mz.fovy,
            )
            f = f"views/{CATEGORIES[c]}/v_i{inst}_{j:03d}.png"
            batch.shots.append(Shot(k, 0.0, batch.objects[k].palette, cam))
            batch.files.append(f)
            rows.append(Row("views", c, CATEGORIES[c], inst, -1, 0.0, -1, f)._asdict())
    return batch, rows


def meta_batch(cfg: PlanConfig, split: str, index: int, fam: Family) -> tuple[Batch, list[dict]]:
    """One meta-training class: ``per_class`` studio pictures of instances of ``fam``."""
    sid = SPLITS.index(split)
    n_inst = math.ceil(cfg.per_class / cfg.views_per_instance)
    objs = [build_meta_instance(fam, _rng(cfg.seed, 5, sid, index, i)) for i in range(n_inst)]
    batch, rows = Batch(f"{split}{index:03d}", "studio", objs), []
    for k in range(cfg.per_class):
        i = k // cfg.views_per_instance
        r = _rng(cfg.seed, 6, sid, index, k)
        yaw = float(r.uniform(0, 360))
        h, rad = objs[i].extent()
        fovy = float(r.uniform(35, 55))
        dist = framing_distance(h, rad, fovy, float(r.uniform(0.55, 0.9)))
        look = (float(r.normal(0, 0.03)), float(r.normal(0, 0.03)), h * float(r.uniform(0.4, 0.55)))
        cam = CameraPose(look, dist, float(r.uniform(0, 360)), float(r.uniform(-45, -5)), fovy)
        la, le = r.uniform(0, 2 * np.pi), r.uniform(0.4, 1.4)
        key = (float(np.cos(la) * np.cos(le)), float(np.sin(la) * np.cos(le)), -float(np.sin(le)))
        inten = float(r.uniform(0.6, 1.0))
        tint = hsv(r.uniform(0, 1), r.uniform(0, 0.25), 1.0)
        amb = float(r.uniform(0.3, 0.5))
        light = Lighting(key, tuple(inten * t for t in tint), (amb, amb, amb))
        bgr = Background(
            hsv(r.uniform(0, 1), r.uniform(0, 0.6), r.uniform(0.2, 0.95)),
            str(r.choice(BACKGROUND_MATERIALS)),
            hsv(r.uniform(0, 1), r.uniform(0, 0.6), r.uniform(0.2, 0.95)),
            str(r.choice(BACKGROUND_MATERIALS)),
        )
        batch.shots.append(Shot(i, yaw, jitter_palette(objs[i].palette, r), cam, light, bgr))
        f = f"{split}/c{index:03d}/p{k:03d}.png"
        batch.files.append(f)
        rows.append(Row(split, index, fam.name, i, -1, round(-yaw % 360, 3), -1, f)._asdict())
    return batch, rows


def plan_size(cfg: PlanConfig) -> dict:
    """What :func:`make_plan` builds, counted without building it: ``pictures`` of each split,
    ``objects`` (the geometric instances the batches hold) and ``batches`` (one renderer each)."""
    n_cat = len(cfg.categories)
    classes = {"train": cfg.n_train_classes, "val": cfg.n_val_classes, "test": cfg.n_test_classes}
    pictures = {
        "query": n_cat * INSTANCES_PER_CATEGORY * N_FACES,
        "support": n_cat * cfg.support_per_category,
        **{split: n * cfg.per_class for split, n in classes.items()},
        "views": n_cat * INSTANCES_PER_CATEGORY * cfg.views_per_obstacle,
    }
    n_classes = sum(classes.values())
    per_class = math.ceil(cfg.per_class / cfg.views_per_instance)
    views = 1 if cfg.views_per_obstacle else 0
    return {
        "pictures": pictures,
        "objects": n_cat * (INSTANCES_PER_CATEGORY * (1 + views) + cfg.support_per_category)
        + n_classes * per_class,
        "batches": 2 + n_classes + views,
    }


def make_plan(cfg: PlanConfig) -> tuple[list[Batch], list[dict]]:
    """All batches and the manifest rows (in manifest order: query, support, train, val, test,
    views)."""
    for key in (
        "n_train_classes",
        "n_val_classes",
        "n_test_classes",
        "per_class",
        "views_per_instance",
        "support_per_category",
    ):
        v = getattr(cfg, key)
        if not isinstance(v, (int, np.integer)) or v < (0 if key.startswith("n_") else 1):
            raise ValueError(
                f"{key} must be a {'non-negative' if key.startswith('n_') else 'positive'} integer, got {v!r}"
            )
    if not cfg.categories:
        raise ValueError("categories must name at least one category")
    for c in cfg.categories:
        category_index(c)
    batches, rows = [], []
    for make in (query_batch, support_batch):
        b, r = make(cfg)
        batches.append(b)
        rows += r
    if cfg.views_per_obstacle < 0:
        raise ValueError(
            f"views_per_obstacle must be a non-negative integer, got {cfg.views_per_obstacle!r}"
        )
    lo, hi = cfg.views_distance
    if not 0 < lo <= hi:
        raise ValueError(f"views_distance must be [low, high] with 0 < low <= high, got {[lo, hi]}")
    families = split_families(
        cfg.n_train_classes,
        cfg.n_val_classes,
        cfg.n_test_classes,
        cfg.seed,
        cfg.min_family_distance,
    )
    for split in META_SPLITS:
        for idx, fam in enumerate(families[split]):
            b, r = meta_batch(cfg, split, idx, fam)
            batches.append(b)
            rows += r
    if cfg.views_per_obstacle:
        b, r = views_batch(cfg)
        batches.append(b)
        rows += r
    return batches, rows
