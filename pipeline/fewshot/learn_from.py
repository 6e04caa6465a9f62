"""Which substituted pictures a query picture's recognition sees (beyond the paper: the repetition
study's split of the dynamic support set's gain by where the substituted picture comes from).

With the paper's dynamic support set (section 3.3) a picture substituted after a collision changes
its category's class state for every query picture. ``learn_from`` keeps the collisions, the
substitution positions and the ways exactly as they are and limits what each query picture sees:

- ``all``: every substituted picture (the paper's DSS);
- ``same_category``: the substituted pictures of its own category; other categories show it
  their original samples;
- ``same_object``: those of its own physical obstacle (any face; the manifest's ``instance``);
- ``same_picture``: itself only.

A slot holding a picture the query may not see shows it that slot's original sample. From
``same_picture`` to ``all`` the reach only grows, so the gains of consecutive settings split the
DSS gain by source: the same picture, the other faces of the same obstacle, the other obstacle of
the category, the other categories (``pipeline/report/repetition_sources.py``).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pandas as pd

#: The settings, from the widest reach to the narrowest (module docstring).
LEARN_FROM = ("all", "same_category", "same_object", "same_picture")


def learning_groups(
    learn_from: str, query_categories: np.ndarray, query_objects: np.ndarray | None = None
) -> np.ndarray | None:
    """The group of every query picture id under ``learn_from``: a query sees the substituted
    pictures of its own group only. ``None`` for ``all`` (one support set for every picture).
    ``query_objects`` (P,) names each picture's physical obstacle (any labels), which
    ``same_object`` needs."""
    if learn_from not in LEARN_FROM:
        raise ValueError(f"learn_from must be one of {', '.join(LEARN_FROM)}; got {learn_from!r}")
    if learn_from == "all":
        return None
    if learn_from == "same_category":
        return np.asarray(query_categories, dtype=np.int64)
    if learn_from == "same_picture":
        return np.arange(len(query_categories))
    if query_objects is None or len(query_objects) != len(query_categories):
        raise ValueError(
            "learn_from=same_object needs each query picture's obstacle (the manifest's instance "
            "column, read by from_files)"
        )
    return np.unique(np.asarray(query_objects), return_inverse=True)[1].astype(np.int64)


def table_by_group(
    column: Callable[[np.ndarray], np.ndarray],
    members: np.ndarray,
    original_members: np.ndarray,
    groups: np.ndarray,
) -> np.ndarray:
    """The (P, C) score table when each group of query pictures sees only its own substituted
    pictures: ``members`` (C, K) the support set (a query picture id >= 0, or an original sample's
    code < 0), ``original_members`` the same slots as first filled, ``groups`` (P,) each picture's
    group and ``column(members)`` one category's (P,) scores for those members (paper eq. 2).

    A group none of whose pictures category c holds sees c's original members, so its rows take
    the original column; only the groups that gave c a picture need a column of their own (a few,
    not one a picture: ``same_picture`` has 40 groups)."""
    substituted = members >= 0
    source = np.where(substituted, groups[np.maximum(members, 0)], -1)
    table = np.empty((len(groups), len(members)))
    for c in range(len(members)):
        table[:, c] = column(original_members[c])
        for group in np.unique(source[c][substituted[c]]):
            rows = groups == group
            seen = np.where(substituted[c] & (source[c] == group), members[c], original_members[c])
            table[rows, c] = column(seen)[rows]
    return table


def query_objects(manifest: pd.DataFrame) -> np.ndarray:
    """Each query picture's physical obstacle, by picture id: its (category, instance) in the
    manifest (``pipeline.manifest``), as one number."""
    query = manifest[manifest["split"] == "query"].sort_values("picture_id")
    return (query["category"] * 1000 + query["instance"]).to_numpy(dtype=np.int64)
