"""How the report presents one experiment: the optional ``report:`` block of
``conf/experiment/<name>.yaml`` (docs/extending.md, "How the report presents it"), which the trials
stage embeds in every record file, so a report is built from the records alone.

The trials stage's schema types the block by :class:`ReportSpec` (Hydra refuses unknown keys, the
field's ``choices`` a kind outside :data:`KINDS`); :meth:`ReportSpec.problems` refuses cell names the
experiment does not have. Reading a recorded block (:meth:`ReportSpec.from_dict`) refuses the same
unknown keys and kinds, in the same words.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field, fields
from typing import Any

from pipeline.config.fields import problem, setting

#: Section kinds (docs/extending.md's table; each is a function of :mod:`pipeline.report.sections`).
KINDS = (
    "default",
    "bars",
    "long_term",
    "by_maze",
    "accuracy_curve",
    "generalisation",
    "repetition",
    "robot",
    "networks",
)
#: Kinds that draw one point per cell (no pooled rows, no learning curves).
PER_CELL_KINDS = ("accuracy_curve", "generalisation", "repetition", "networks")


@dataclass
class Group:
    """One row of a section that pools the runs of several cells (Table 3's DSS row pools the
    four substitution ways). In a ``by_maze`` section the row has one entry per maze, each pooling
    the group's cells on that maze."""

    key: str = setting("", nonempty=True)
    """Names the row in CSV files (the ``key`` column of the learning curves' table)."""
    cells: list[str] = field(default_factory=list)
    """The cells whose runs count together."""
    paper: dict[str, str] = field(default_factory=dict)
    """The paper's figure for this row, by maze (``{5x5: 192.3, 7x7: not converged}``), as printed."""


@dataclass
class PathSpec:
    """A figure of the learned path (the paper's Figure 7): the most common path of the runs' last
    episodes, drawn on the maze of the first recorded cell of ``cells``."""

    cells: list[str] = field(default_factory=list)
    """Candidate cells in order of preference; the first one with records is drawn."""
    title: str = "The learned path"
    """The heading of the path's own section."""
    claim: str | None = None
    """What the paper says about it (quoted as ``Paper: ...``)."""


@dataclass
class ReportSpec:
    """``experiment.report``: how the report presents the experiment (every field optional)."""

    order: int = 100
    """Sections are sorted by ``order``, then by experiment name (the paper's use 1-4)."""
    title: str | None = None
    """The section's heading; default ``Experiment <name>``."""
    kind: str = setting("default", choices=KINDS)
    """One of :data:`KINDS`."""
    claim: str | None = None
    """The paper's claim for this experiment, quoted as ``Paper: ...`` under the heading."""
    row_header: str = "cell"
    """Header of the tables' first column (``method``, ``support set``...)."""
    cells: list[str] = field(default_factory=list)
    """Which cells, in which order, one row (and one curve) each; default: every cell, sorted by
    name (the records keep the config with sorted keys, so the file's order of cells is not
    kept). Give ``cells`` or ``groups``, not both."""
    groups: list[Group] = field(default_factory=list)
    """Rows that pool cells, in order (a list: order is kept in the records)."""
    curves: bool | None = None
    """Learning curves: collisions per episode, mean over runs with a 95% band, from episode 0
    (drawn unless false; a kind without learning curves refuses the key)."""
    support_accuracy: bool | None = None
    """The query accuracy of the support set over the run (rows whose cells have a recogniser;
    drawn unless false; a kind without it refuses the key)."""
    path: PathSpec | None = None
    """A learned-path figure in its own section before this one (the paper's Figure 7)."""
    headline: list[str] = field(default_factory=list)
    """Cells whose mean collisions per run go into ``reports/headline.json`` as
    ``<experiment>.<cell>``: the few numbers ``dvc exp show`` and ``dvc metrics show`` print
    (:mod:`pipeline.report.headline`); the per-cell detail is ``dvc metrics show
    datasets/metrics/<experiment>``."""

    # ------------------------------------------------------------------ reading and checking
    @classmethod
    def from_dict(cls, data: dict[str, Any] | None) -> ReportSpec:
        """The spec from a plain dict (the recorded config's ``experiment.report``); ``None``
        gives the default. Unknown keys and an unknown kind raise ``ValueError``."""
        if data is None:
            return cls()
        values = _known(cls, data, "report", LEGACY)
        if "groups" in values:
            values["groups"] = [
                Group(**_known(Group, g, f"report.groups.{i}", LEGACY_GROUP))
                for i, g in enumerate(values["groups"])
            ]
        if values.get("path") is not None:
            values["path"] = PathSpec(**_known(PathSpec, values["path"], "report.path"))
        spec = cls(**values)
        for f in fields(cls):
            wrong = problem(getattr(spec, f.name), f.metadata)
            if wrong:
                raise ValueError(f"report.{f.name}: {wrong}")
        return spec

    def problems(self, cells: Iterable[str]) -> list[tuple[str, str]]:
        """``(key, problem)`` for every cell name the block uses that is not a cell of the
        experiment (``cells``), and for ``cells`` given together with ``groups``."""
        known = list(cells)
        out = []
        if self.cells and self.groups:
            out.append(("groups", "give cells or groups, not both"))

        def need(key: str, name: str) -> None:
            if name not in known:
                out.append((key, f"no cell {name!r} in the experiment (cells: {', '.join(known)})"))

        for name in self.cells:
            need("cells", name)
        for name in self.headline:
            need("headline", name)
        if self.kind in PER_CELL_KINDS:
            kind = f"the {self.kind} kind"
            if self.groups:
                out.append(
                    ("groups", f"{kind} pools no cells (one point per cell); give cells or nothing")
                )
            drawn = [
                key for key in ("curves", "support_accuracy") if getattr(self, key) is not None
            ]
            out += [
                (key, f"{kind} draws no learning curves or support-set accuracy over the run")
                for key in drawn
            ]
        seen = set()
        for i, group in enumerate(self.groups):
            if not group.key.strip():
                out.append((f"groups.{i}.key", "must not be empty"))
            elif group.key in seen:
                out.append((f"groups.{i}.key", f"{group.key!r} names two groups"))
            seen.add(group.key)
            if not group.cells:
                out.append((f"groups.{i}.cells", "must name at least one cell"))
            for name in group.cells:
                need(f"groups.{i}.cells", name)
        if self.path is not None:
            if not self.path.cells:
                out.append(("path.cells", "must name at least one cell"))
            for name in self.path.cells:
                need("path.cells", name)
        return out

    def rows(self, cells: Iterable[str]) -> list[Row]:
        """The section's rows: its groups, or one row per cell (``cells`` of the block, else every
        cell of ``cells``, sorted by name)."""
        if self.groups:
            return [Row(g.key, g.key, list(g.cells), dict(g.paper)) for g in self.groups]
        return [Row(name, name, [name], {}) for name in (self.cells or sorted(cells))]


@dataclass
class Row:
    """One row of a section (one curve in its figures): a key, a label (the key until
    :meth:`pipeline.report.experiments.Experiment.rows` names it) and the cells it pools."""

    key: str
    label: str
    cells: list[str]
    paper: dict[str, str]


#: Keys of blocks recorded before rows were named from their cells (``labels``, a group's
#: ``label``): read and ignored, so those records still make a report.
LEGACY, LEGACY_GROUP = ("labels",), ("label",)


def _known(cls, data: Any, where: str, legacy: tuple[str, ...] = ()) -> dict[str, Any]:
    if not isinstance(data, dict):
        raise ValueError(f"{where}: expected a mapping; got {data!r}")
    names = {f.name for f in fields(cls)}
    unknown = sorted(set(data) - names - set(legacy))
    if unknown:
        raise ValueError(
            f"{where}: unknown key(s) {', '.join(unknown)} (known: {', '.join(sorted(names))})"
        )
    return {k: v for k, v in data.items() if k in names}
