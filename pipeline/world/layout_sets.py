"""Sets of generated layouts for an experiment: ``experiment.layouts`` crosses cell templates with
``count`` generated layouts of each size, to ask whether the paper's claims hold beyond its three
mazes.

The paper (section 4.2.2, Table 3) reports one layout per size: 5x5 with 9 obstacles, 7x7 with 16
and 11x11 with 49. A layout set ``{size: 5x5, obstacles: 9, count: 100, seed: 0, unique: true}``
stands for the layouts ``random:5x5:9:<seed + k>:unique`` for ``k = 0 .. count-1``
(:mod:`pipeline.world.generate`); crossed with the templates ``{qlearning: {...}, ...}`` it gives
the cells ``qlearning_5x5_L0 .. qlearning_5x5_L99``, each the template with that maze (``L`` and
the layout's seed, so a layout keeps its cells' names whatever the set's ``count``).

Pure functions on plain values: the trials stage expands the sets into its cells, and the report
expands the recorded sets into the experiment's declared cells (the records keep the sets, not
2,100 cells). A set that cannot be met raises :class:`LayoutSetError` with the key that is wrong
(relative to the set: ``size``, ``obstacles``, ``count``) and the reason.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from pipeline.world.generate import LayoutSpec, parse_spec
from pipeline.world.maze import MazeError

SIZE = re.compile(r"(\d+)x(\d+)")


class LayoutSetError(ValueError):
    """A layout set that cannot be expanded; ``key`` names the set's field that is wrong."""

    def __init__(self, key: str, problem: str):
        super().__init__(problem)
        self.key = key


@dataclass(frozen=True)
class GeneratedCell:
    """One cell of a layout set: its template, the set's index, the layout's index in the set
    and the maze spec."""

    template: str
    set_index: int
    layout: int
    maze: str


def layout_mazes(
    size: str, obstacles: int, count: int, seed: int = 0, unique: bool = True
) -> list[str]:
    """The maze specs of one set, in order: ``random:<size>:<obstacles>:<seed + k>[:unique]``."""
    match = SIZE.fullmatch(str(size))
    if match is None:
        raise LayoutSetError("size", f"expected <W>x<H> (whole numbers, e.g. 7x7); got {size!r}")
    if count < 1:
        raise LayoutSetError("count", f"must be >= 1; got {count}")
    width, height = (int(g) for g in match.groups())
    specs = [LayoutSpec(width, height, obstacles, seed + k, unique).name for k in range(count)]
    try:
        parse_spec(specs[0])  # the grid's bounds and the obstacle count (the same for every k)
    except MazeError as exc:
        raise LayoutSetError("obstacles" if "obstacles" in str(exc) else "size", str(exc)) from None
    return specs


def cell_name(template: str, size: str, seed: int) -> str:
    """``<template>_<size>_L<seed>``: the layout of ``size`` with that seed under ``template``."""
    return f"{template}_{size}_L{seed}"


def expand(sets: list[dict], templates: list[str]) -> dict[str, GeneratedCell]:
    """Every cell of ``sets`` (dicts with ``size``, ``obstacles``, ``count``, ``seed``,
    ``unique``) crossed with ``templates``, by name: per set, per layout, per template (so
    a layout's methods are neighbours). Sets of one size need seeds that do not overlap (cell
    names carry the size and the seed): overlapping ones are refused (:class:`LayoutSetError`
    with key ``<i>.seed``)."""
    out: dict[str, GeneratedCell] = {}
    seeds: dict[str, dict[int, int]] = {}  # size -> seed -> the set that has it
    for i, s in enumerate(sets):
        try:
            mazes = layout_mazes(
                s["size"], s["obstacles"], s["count"], s.get("seed", 0), s.get("unique", True)
            )
        except LayoutSetError as exc:
            raise LayoutSetError(f"{i}.{exc.key}", str(exc)) from None
        first = s.get("seed", 0)
        taken = seeds.setdefault(s["size"], {})
        clash = next((taken[k] for k in range(first, first + s["count"]) if k in taken), None)
        if clash is not None:
            raise LayoutSetError(
                f"{i}.seed",
                f"size {s['size']} seeds {first}..{first + s['count'] - 1} overlap set {clash}'s "
                "(cell names carry the size and the seed): start this set after the other's seeds",
            )
        taken.update(dict.fromkeys(range(first, first + s["count"]), i))
        for k, maze in enumerate(mazes):
            for t in templates:
                out[cell_name(t, s["size"], s.get("seed", 0) + k)] = GeneratedCell(t, i, k, maze)
    return out
