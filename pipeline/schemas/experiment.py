"""The typed schema of the ``experiment`` config group (``conf/experiment/<name>.yaml``): its cells,
the cells it generates over sets of layouts, and how the report presents it.

The trials stage's schema (:class:`pipeline.schemas.trials.TrialsConfig`) types its ``experiment``
key by :class:`Experiment`; ranges, choices and descriptions are declared on the fields as
everywhere (:mod:`pipeline.config.fields`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from typing import Any

from pipeline.config.fields import refuse, setting
from pipeline.report.spec import ReportSpec
from pipeline.robot.limits import CELL_RANGE, DEFAULT_CELL, DEFAULT_TIMESTEP, TIMESTEP_RANGE

SUPPORT_MODES = ("restore", "carry")
#: Where the methods run: the grid world, or the camera robot in MuJoCo (``pipeline/robot``).
WORLDS = ("grid", "robot3d")


#: The decision rules (``pipeline.rl.rules.Rule``): when a picture stops the robot.
RULES = ("paper", "open_set", "range")


@dataclass
class RobotConfig:
    """The camera robot's world (``world=robot3d``, docs/robot3d.md)."""

    cell: float = setting(DEFAULT_CELL, ge=CELL_RANGE[0], le=CELL_RANGE[1])
    """Metres per grid cell: 1.0, the cell the query pictures were rendered for (``render.maze.cell``); 0.5-2 m (the robot turns clear of a neighbour's obstacle; its range sensor reads the neighbour)."""
    timestep: float = setting(DEFAULT_TIMESTEP, ge=TIMESTEP_RANGE[0], le=TIMESTEP_RANGE[1])
    """MuJoCo's physics step (s), 0.001-0.05, dividing the controller's 0.1 s tick."""


SUBSTITUTION_WAYS = (1, 2, 3, 4)


@dataclass
class Cell:
    """One cell of an experiment: a method on a maze. Keys left out come from the top level
    (the experiment file's globals or the command line); keys given here are pinned."""

    method: str = setting(nonempty=True)
    """A method of ``conf/method/``."""
    maze: str | None = setting(None, path=True)
    """The cell's maze (as the top-level ``maze``); none: the top level's."""
    substitution: int | None = setting(None, choices=SUBSTITUTION_WAYS)
    """The cell's substitution way (as the top-level ``substitution``); none: the top level's."""
    support: str | None = setting(None, choices=SUPPORT_MODES)
    """The cell's support-set mode (as the top-level ``support``); none: the top level's."""
    world: str | None = setting(None, choices=WORLDS)
    """The cell's world (as the top-level ``world``); none: the top level's."""
    rule: str | None = setting(None, choices=RULES)
    """The cell's decision rule (as the top-level ``rule``); none: the top level's."""
    params: dict[str, Any] = field(default_factory=dict)
    """Method fields this cell pins (``{alpha: 0.05}``); the command line does not change them."""
    recogniser: dict[str, Any] = field(default_factory=dict)
    """Recogniser arguments this cell pins (``{p: 0.3}``) over the top level's recogniser
    (``recogniser=<name>``, ``recogniser.<arg>=``), checked against that recogniser's parameters;
    only for methods that recognise pictures. The command line does not change them."""
    recogniser_group: str | None = None
    """A recogniser of ``conf/recogniser/`` (``protonet``) this cell runs instead of the top level's;
    the top level's recogniser arguments do not reach it, its own ``recogniser`` pins do."""


@dataclass
class LayoutSet:
    """``count`` generated layouts of one size (``pipeline/world/layout_sets.py``): the mazes
    ``random:<size>:<obstacles>:<seed + k>[:unique]``, ``k = 0 .. count-1``."""

    size: str = setting(nonempty=True)
    """``<W>x<H>`` (W wide, H high)."""
    obstacles: int = setting(ge=0)
    """Obstacles in each layout."""
    count: int = setting(ge=1)
    """Layouts in the set."""
    seed: int = setting(0, ge=0)
    """The first layout's seed; layout ``k`` has seed ``seed + k``."""
    unique: bool = True
    """The paper's kind of layout: a single shortest path lined by obstacles (``:unique``)."""


@dataclass
class Layouts:
    """Cell templates crossed with sets of generated layouts: cell ``<template>_<size>_L<seed>`` is
    the template on the layout of ``size`` with that seed."""

    sizes: list[LayoutSet] = field(default_factory=list)
    """The sets of generated layouts (sets of one size with seeds that do not overlap)."""
    cells: dict[str, Cell] = field(default_factory=dict)
    """Templates: cells without a maze (each generated cell gets its layout's)."""


#: At most this many cells from generated layouts (the paper-scale study has 2,100); planning one
#: (its layout generated, checked and loaded) takes about 2 ms and 10 kB (2,100 cells: 4.7 s, 20 MB).
MAX_LAYOUT_CELLS, PLAN_SECONDS, PLAN_BYTES = 100_000, 0.0022, 10_000


def refuse_too_many(layouts: Layouts) -> None:
    """Layout counts that would give more than :data:`MAX_LAYOUT_CELLS` cells are refused before
    anything is generated, naming the largest set's count, with the cells, time and memory."""
    n = sum(s.count for s in layouts.sizes) * len(layouts.cells)
    if n <= MAX_LAYOUT_CELLS:
        return
    i = max(range(len(layouts.sizes)), key=lambda k: layouts.sizes[k].count)
    refuse(
        f"experiment.layouts.sizes.{i}.count",
        f"{layouts.sizes[i].count:,} layouts give "
        f"{n:,} cells in all ({len(layouts.sizes)} sets x {len(layouts.cells)} templates), at most "
        f"{MAX_LAYOUT_CELLS:,}: planning them alone would take about {n * PLAN_BYTES / 1e9:,.1f} GB "
        f"and {n * PLAN_SECONDS / 60:,.0f} min",
    )


@dataclass
class Experiment:
    """``conf/experiment/<name>.yaml``: the cells, and how the report presents them."""

    name: str = setting(nonempty=True)
    """The experiment's name (its file in ``conf/experiment/``), carried into the records."""
    cells: dict[str, Cell] = field(default_factory=dict)
    """The cells listed by hand, by name (the name of each cell's folder under ``out``)."""
    layouts: Layouts | None = None
    """Cells over generated layouts (``experiment.layouts``), besides the ``cells`` listed by hand."""
    report: ReportSpec | None = None
    """How the report presents the experiment (``pipeline/report/spec.py``); none: the default section."""

    def all_cells(self) -> dict[str, Cell]:
        """The cells listed by hand, then those of ``layouts`` (in set, layout, template order);
        a set that cannot be met, a template that pins a maze or a name given twice is refused
        (:class:`~pipeline.errors.ConfigError` naming the key)."""
        from pipeline.world.layout_sets import LayoutSetError, expand  # numba: not for --help

        if self.layouts is None:
            return dict(self.cells)
        for name, template in self.layouts.cells.items():
            if template.maze is not None:
                refuse(
                    f"experiment.layouts.cells.{name}.maze",
                    "the layout sets give "
                    "each generated cell its maze; leave maze out of the template",
                )
        if not self.layouts.cells:
            refuse(
                "experiment.layouts.cells",
                "no templates; name at least one (e.g. {ssrl: {method: ssrl}})",
            )
        if not self.layouts.sizes:
            refuse(
                "experiment.layouts.sizes",
                "no layout sets; give at least one (e.g. {size: 5x5, obstacles: 9, count: 100})",
            )
        refuse_too_many(self.layouts)
        try:
            generated = expand([asdict(s) for s in self.layouts.sizes], list(self.layouts.cells))
        except LayoutSetError as exc:
            refuse(f"experiment.layouts.sizes.{exc.key}", str(exc))
        out = dict(self.cells)
        for name, g in generated.items():
            if name in out:
                refuse(
                    f"experiment.cells.{name}",
                    "the layout sets generate a cell of that name; rename it",
                )
            out[name] = replace(self.layouts.cells[g.template], maze=g.maze)
        return out
