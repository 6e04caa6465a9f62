"""The typed schema of the render stage's config (``conf/render.yaml``): the maze camera of the
query pictures, the catalogue camera of the support set, the rendering quality and the
meta-training set's scale (registered: :mod:`pipeline.config.registry`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from omegaconf import MISSING

from pipeline.config.fields import setting
from pipeline.schemas.profile import Profile, profile_key
from pipeline.world.family_split import MAX_DISTANCE


@dataclass
class MazeCameraConfig:
    """The robot's camera in the maze (the query pictures)."""

    cell: float = setting(gt=0)
    """Metres per grid cell."""
    camera_distance: float = setting(gt=0)
    """Horizontal distance from the camera to the obstacle's centre, metres (one cell)."""
    camera_height: float = setting(gt=0)
    """The robot camera's height, metres."""
    target_height: float = setting(gt=0)
    """The camera aims at this height above the obstacle's foot, metres."""
    fovy: float = setting(gt=0, lt=180)
    """Vertical field of view, degrees."""


@dataclass
class CatalogueCameraConfig:
    """The product-photo setting of the support pictures."""

    fovy: float = setting(gt=0, lt=180)
    """Vertical field of view, degrees."""
    elevation: list[float] = MISSING
    """The range of camera elevations, degrees (negative: looking down)."""
    turn: list[float] = MISSING
    """The range of the object's turn away from a frontal view, degrees."""
    fill: float = setting(gt=0, le=1)
    """The fraction of the picture's height the object fills."""


@dataclass
class QualityConfig:
    """Anti-aliasing and shadows of the renderer."""

    offsamples: int = setting(ge=0)
    """Multisample anti-aliasing samples (0: none)."""
    supersample: int = setting(ge=1)
    """Draw at this multiple of the size and average blocks (anti-aliasing)."""
    shadow_size: int = setting(ge=1)
    """Shadow map resolution."""
    studio_shadows: bool = MISSING
    """Shadows in meta-training pictures (maze and catalogue pictures always have them)."""


@dataclass
class RenderConfig:
    """``python -m pipeline render``: the query, support and meta-training pictures and one manifest."""

    profile: Profile = field(default_factory=Profile)
    """The scale (``conf/profile/``): the class and picture counts default to its ``render`` keys."""
    out_dir: str = setting(nonempty=True, path=True)
    """The pictures and ``manifest.csv``; its parent folder must exist."""
    index_file: str | None = setting(None, path=True)
    """Every file of ``out_dir`` with its SHA-256 (``pipeline.files.write_index``), for dvc.yaml."""
    figures_dir: str = setting(nonempty=True, path=True)
    """The contact sheets (the report stage copies them)."""
    size: int = setting(ge=8)
    """Picture side in pixels (the paper's 84x84)."""
    seed: int = setting(ge=0)
    """Seeds every scene (classes, instances, views)."""
    workers: int = profile_key("render", "workers")
    categories: list[str] = MISSING
    """The query and support categories, in order."""
    n_train_classes: int = profile_key("render", "n_train_classes")
    n_val_classes: int = profile_key("render", "n_val_classes")
    n_test_classes: int = profile_key("render", "n_test_classes")
    min_family_distance: float = setting(ge=0, le=MAX_DISTANCE)
    """Least structural distance of every validation and test family from every training family
    (``pipeline/world/family_split.py``; no two families are further apart than 7)."""
    per_class: int = profile_key("render", "per_class")
    views_per_obstacle: int = profile_key("render", "views_per_obstacle")
    views_distance: list[float] = MISSING
    """The range of camera distances of those pictures, metres [low, high]."""
    views_per_instance: int = setting(ge=1)
    """Pictures per jittered instance of a class."""
    support_per_category: int = setting(ge=1)
    """Support pictures per category (K of the K-shot support set)."""
    maze: MazeCameraConfig = field(default_factory=MazeCameraConfig)
    """The robot's camera in the maze (the query pictures)."""
    catalogue: CatalogueCameraConfig = field(default_factory=CatalogueCameraConfig)
    """The product-photo setting (the support pictures)."""
    quality: QualityConfig = field(default_factory=QualityConfig)
    """Anti-aliasing and shadows."""
    contact_sheets: bool = MISSING
    """Write contact sheets of the pictures to ``figures_dir``."""
    contact_tile: int = setting(ge=8)
    """Tile side of the contact sheets, pixels."""
    contact_train_classes: int = setting(ge=1)
    """Rows (classes) of the meta-training and validation contact sheets."""
    contact_per_class: int = setting(ge=1)
    """Pictures per class in those two sheets."""
