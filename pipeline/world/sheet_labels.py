"""The contact sheets' rows in words: which pictures a row shows, said so a reader understands it.

A query row reads "chair as it stands in the maze: seen from north, east, south, west"; a family's
row spells its structure out ("family 65, bottom to top: cylinder; cylinder (some instances);
bowl; with a handle") instead of its code name (``f065_cylinder-cylinder?-bowl+handle``,
``metaset.make_family``).
"""

from __future__ import annotations

import re
from pathlib import Path

from pipeline.world.pictures import CATEGORIES, N_FACES

SIDES = ("north", "east", "south", "west")  # faces 0..3 (camera.py)
assert len(SIDES) == N_FACES
EXTRAS = {"legs": "legs", "pedestal": "a pedestal", "arms": "radial arms", "handle": "a handle"}


def family_words(name: str) -> str:
    """A family's code name (``f065_cylinder-cylinder?-bowl+handle``) in words: its tiers from the
    bottom up (``a|b``: a or b; ``?``: only some instances have it) and its extras."""
    match = re.fullmatch(r"f(\d+)_([a-z|?\-]+)((?:\+[a-z]+)*)", name)
    if match is None:
        return name
    index, tiers, extras = match.groups()
    parts = []
    for tier in tiers.split("-"):
        optional = tier.endswith("?")
        words = " or ".join(tier.rstrip("?").split("|"))
        parts.append(words + (" (some instances)" if optional else ""))
    text = f"family {int(index)}, bottom to top: " + "; ".join(parts)
    extra = [EXTRAS.get(e, e) for e in extras.split("+") if e]
    if extra:
        text += "; with " + (
            extra[0] if len(extra) == 1 else ", ".join(extra[:-1]) + " and " + extra[-1]
        )
    return text


def query_rows(rows: list[dict], out: Path) -> list[tuple[str, list[Path]]]:
    """Two rows per category: its two objects side by side, each seen from north, east, south and
    west (the query pictures, render_plan.query_batch)."""
    q = [r for r in rows if r["split"] == "query"]
    sheet = []
    for c in sorted({r["category"] for r in q}):
        for inst, how in ((0, "object 1"), (1, "object 2")):
            rs = sorted(
                (r for r in q if r["category"] == c and r["instance"] == inst),
                key=lambda r: r["face"],
            )
            if rs:
                sides = ", ".join(SIDES[r["face"]] for r in rs)
                label = f"{CATEGORIES[c]} {how}: seen from {sides}"
                sheet.append((label, [out / r["file"] for r in rs]))
    return sheet


def support_rows(rows: list[dict], out: Path) -> list[tuple[str, list[Path]]]:
    """A row per category: its support pictures (other instances, catalogue photographs)."""
    s = [r for r in rows if r["split"] == "support"]
    sheet = []
    for c in sorted({r["category"] for r in s}):
        rs = [r for r in s if r["category"] == c]
        label = f"{CATEGORIES[c]}: {len(rs)} catalogue photographs of other {CATEGORIES[c]}s"
        sheet.append((label, [out / r["file"] for r in rs]))
    return sheet


def family_rows(
    rows: list[dict], out: Path, split: str, n_classes: int, per_class: int
) -> list[tuple[str, list[Path]]]:
    """A row per family of ``split`` (at most ``n_classes``): ``per_class`` of its pictures,
    evenly spaced, labelled with the family's structure in words."""
    t = [r for r in rows if r["split"] == split]
    sheet = []
    for c in sorted({r["category"] for r in t})[:n_classes]:
        rs = [r for r in t if r["category"] == c]
        step = max(1, len(rs) // per_class)
        sheet.append(
            (family_words(rs[0]["class_name"]), [out / r["file"] for r in rs[::step][:per_class]])
        )
    return sheet


def views_rows(rows: list[dict], out: Path, per_row: int) -> list[tuple[str, list[Path]]]:
    """A row per query obstacle: the first ``per_row`` of its pictures in the colour test's larger
    set (random sides and distances in the maze)."""
    v = [r for r in rows if r["split"] == "views"]
    sheet = []
    for c in sorted({r["category"] for r in v}):
        for inst, how in ((0, "object 1"), (1, "object 2")):
            rs = [r for r in v if r["category"] == c and r["instance"] == inst]
            if rs:
                label = (
                    f"{CATEGORIES[c]} {how}: {min(per_row, len(rs))} of its {len(rs)} views "
                    "from random sides and distances"
                )
                sheet.append((label, [out / r["file"] for r in rs[:per_row]]))
    return sheet
