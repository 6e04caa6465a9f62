"""Obstacle categories, faces and picture ids: the vocabulary shared by the world, the renderer,
the recogniser and the records (paper section 4.1, Figure 6).

The query set holds 5 categories x 2 instances x 4 faces = 40 pictures. The two instances of a
category are two different objects of it (``obstacle_models.obstacle_instance``). A face is named in the obstacle's own frame (0 = its front/"north",
then clockwise: 1 east, 2 south, 3 west). An obstacle standing in the maze with orientation
``r`` (a quarter-turn count, clockwise) shows to a robot on its world side ``d`` the face
``(d - r) mod 4``.

    picture_id = category * 8 + instance * 4 + face
"""

from __future__ import annotations

CATEGORIES: tuple[str, ...] = ("chair", "kettle", "carton", "basin", "basket")
N_CATEGORIES = len(CATEGORIES)
INSTANCES_PER_CATEGORY = 2
N_FACES = 4
FACE_NAMES: tuple[str, ...] = ("north", "east", "south", "west")
N_PHYSICAL_OBSTACLES = N_CATEGORIES * INSTANCES_PER_CATEGORY  # 10
N_PICTURES = N_PHYSICAL_OBSTACLES * N_FACES  # 40


def picture_id(category: int, instance: int, face: int) -> int:
    """Query-picture id of ``face`` of ``instance`` of ``category``."""
    if not (
        0 <= category < N_CATEGORIES
        and 0 <= instance < INSTANCES_PER_CATEGORY
        and 0 <= face < N_FACES
    ):
        raise ValueError(
            f"no query picture for category={category} instance={instance} face={face}"
        )
    return (category * INSTANCES_PER_CATEGORY + instance) * N_FACES + face


def picture_parts(pid: int) -> tuple[int, int, int]:
    """Inverse of :func:`picture_id`: ``(category, instance, face)``."""
    if not 0 <= pid < N_PICTURES:
        raise ValueError(f"picture id {pid} out of range 0..{N_PICTURES - 1}")
    physical, face = divmod(pid, N_FACES)
    category, instance = divmod(physical, INSTANCES_PER_CATEGORY)
    return category, instance, face


def picture_category(pid: int) -> int:
    return picture_parts(pid)[0]


def face_seen(side: int, orientation: int) -> int:
    """Face shown on world side ``side`` (0 N, 1 E, 2 S, 3 W) by an obstacle turned ``orientation``
    quarter turns clockwise; on arrays (numpy), elementwise."""
    return (side - orientation) % N_FACES
