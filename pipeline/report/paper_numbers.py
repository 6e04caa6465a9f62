"""The paper's numbers beside ours in every section with the same setting. The paper prints numbers
for its Table 3 only; Table 3's 5x5 column is also its only number for Figures 8-10, so a row of
another section whose cells ran the same setting (method, maze, episodes, recogniser, support
set) shows it, marked "ways 1-4 pooled" where the paper's number averages more ways than the row."""

from __future__ import annotations

import json
from dataclasses import dataclass

from pipeline.report.experiments import Cell, Experiment


@dataclass
class PaperValue:
    """The paper's number for a row, printed in another section for the same setting."""

    value: str  # as printed
    source: str  # the section's name ("Table 3")
    pools: str = ""  # what the paper's number pools beyond the row ("ways 1-4 pooled")

    def text(self) -> str:
        return f"{self.value} ({self.source}{', ' + self.pools if self.pools else ''})"

    def number(self) -> float | None:
        try:
            return float(self.value)
        except ValueError:
            return None


def setting_key(cell: Cell) -> str:
    """What a cell ran, except its substitution way: method, maze, episodes, support set and
    recogniser (JSON, to compare cells of different experiments)."""
    info = cell.info
    recogniser = (info.get("recogniser") or {}).get("kind")
    return json.dumps(
        [
            info["method"],
            info["maze"],
            (cell.config or {}).get("episodes"),
            recogniser,
            info.get("support") if recogniser else None,
        ],
        sort_keys=True,
    )


def way(cell: Cell):
    return cell.info.get("substitution") if cell.info["method"].get("dynamic_support") else None


def paper_for(cells: list[Cell], experiments: list[Experiment]) -> PaperValue | None:
    """The paper's number for ``cells`` (one setting, any substitution ways) from a group of any
    section that gives one for the same :func:`setting_key` on their maze, the group's ways
    including theirs; None if there is none."""
    keys, ways = {setting_key(c) for c in cells}, {way(c) for c in cells}
    if len(keys) != 1:
        return None
    for other in experiments:
        if not any(group.paper for group in other.spec.groups):
            continue  # only groups carry the paper's numbers (and naming 2,100 rows is slow)
        source = (other.spec.title or other.name).split(":")[0]
        for group, group_cells in other.rows():
            for maze, value in group.paper.items():
                on = [c for c in group_cells if c.maze == maze]
                if on and {setting_key(c) for c in on} == keys and ways <= {way(c) for c in on}:
                    wider = sorted({way(c) for c in on} - {None})
                    if not wider or ways == set(wider):
                        return PaperValue(str(value), source)
                    together = (
                        f"{wider[0]}-{wider[-1]}"
                        if wider == list(range(wider[0], wider[-1] + 1))
                        else ", ".join(map(str, wider))
                    )
                    return PaperValue(str(value), source, f"ways {together} pooled")
    return None


def paper_values(exp: Experiment, experiments: list[Experiment]) -> dict[str, PaperValue]:
    """By row key of ``exp`` (rows without their own ``paper``): :func:`paper_for` the row's
    cells. The paper prints no numbers for Figures 8-10; its Table 3 does for their 5x5 setting
    (the DSS row as the mean of the four ways)."""
    found = {row.key: paper_for(cells, experiments) for row, cells in exp.rows() if not row.paper}
    return {key: value for key, value in found.items() if value is not None}
