"""The records of an experiment over generated layouts (``experiment.layouts``), by layout: each
cell's maze is its layout's spec (``random:7x7:16:3:unique``), which gives the size, and its records
keep the layout's rows, from which the layout features are computed (:func:`features`). The
``generalisation`` section (:mod:`pipeline.report.generalisation`) is built on these."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from pipeline.report.checks import Arm, Missing
from pipeline.report.experiments import Cell, Experiment
from pipeline.report.names import method_colour, method_name, method_order
from pipeline.stats import t_quantile_975
from pipeline.world.generate import is_spec, parse_spec
from pipeline.world.geometry import build_geometry
from pipeline.world.maze import bfs_distances, parse_layout

FEATURES = {
    "unsafe_pairs": "unsafe (state, action) pairs from reachable cells",
    "obstacles_reachable": "obstacles next to a reachable cell",
    "shortest_path": "shortest path (moves)",
}


def features(rows: list[str]) -> dict[str, int]:
    """Features of a layout (its text rows): unsafe (state, action) pairs whose state the robot
    can reach (eq. 4's dangerous pairs it can meet), obstacles next to a reachable cell (the
    obstacles it can collide with) and the shortest start-goal path in moves."""
    layout = parse_layout("\n".join(rows), source="records")
    geometry = build_geometry(layout)
    blocked = np.zeros(layout.n_cells, dtype=np.bool_)
    blocked[list(layout.obstacles)] = True
    dist = bfs_distances(blocked, layout.height, layout.width, layout.start)
    reachable = dist >= 0
    hits = geometry.obstacle[reachable]
    return {
        "unsafe_pairs": int((hits >= 0).sum()),
        "obstacles_reachable": int(np.unique(hits[hits >= 0]).size),
        "shortest_path": int(dist[layout.goal]),
    }


@dataclass
class LayoutCells:
    """The cells run on one generated layout, by method (``conf/method/`` name)."""

    size: str
    maze: str
    seed: int
    rows: list[str]
    cells: dict[str, Cell] = field(default_factory=dict)
    _arms: dict[str, Arm] = field(default_factory=dict)

    def arm(self, method: str) -> Arm:
        """The method's collisions per run by run index (read once: 2,100 cells' frames add up)."""
        if method not in self._arms:
            if method not in self.cells:
                raise Missing(f"no records of {method} on {self.maze}")
            cell = self.cells[method]
            self._arms[method] = Arm(cell.collisions_by_run(), [cell])
        return self._arms[method]

    def mean(self, method: str) -> float:
        return float(self.arm(method).values.mean())


def by_size(exp: Experiment) -> tuple[dict[str, list[LayoutCells]], list[str]]:
    """The experiment's generated layouts grouped by size (sizes by their number of cells,
    layouts by seed), and notes on cells that are not on a generated layout."""
    found: dict[str, LayoutCells] = {}
    notes = []
    for cell in exp.cells.values():
        if not is_spec(cell.maze):
            notes.append(
                f"cell {cell.name} is not on a generated layout ({cell.maze}), so it is not shown"
            )
            continue
        spec = parse_spec(cell.maze)
        size = f"{spec.width}x{spec.height}"
        layout = found.setdefault(cell.maze, LayoutCells(size, cell.maze, spec.seed, cell.layout))
        layout.cells[cell.method] = cell
    sizes: dict[str, list[LayoutCells]] = {}
    for layout in sorted(found.values(), key=lambda lay: lay.seed):
        sizes.setdefault(layout.size, []).append(layout)
    order = sorted(sizes, key=lambda s: (np.prod([int(x) for x in s.split("x")]), s))
    return {s: sizes[s] for s in order}, notes


def methods_of(layouts: list[LayoutCells]) -> list[str]:
    """The methods every layout of a size has, in their declared order (``METHODS`` of
    :mod:`pipeline.rl.rules`; undeclared methods after, by name)."""
    common = set.intersection(*(set(lay.cells) for lay in layouts)) if layouts else set()
    return sorted(common, key=lambda m: (method_order(m), m))


def label(layouts: list[LayoutCells], method: str) -> str:
    return method_name(layouts[0].cells[method].info["method"])


def colours(sizes: dict[str, list[LayoutCells]]) -> dict[str, str]:
    """The declared colour of each method that has one, by method."""
    found = {
        m: method_colour(lay.cells[m].info["method"])
        for layouts in sizes.values()
        for lay in layouts[:1]
        for m in methods_of(layouts)
    }
    return {m: c for m, c in found.items() if c}


def fit(x: np.ndarray, y: np.ndarray) -> tuple[float, float, float, float] | None:
    """Least-squares line ``y = a + b x``: ``(b, a, b_low, b_high)`` with a 95% t interval of the
    slope; None when ``x`` takes one value (or there are fewer than three points)."""
    if x.size < 3 or np.ptp(x) == 0:
        return None
    b, a = np.polyfit(x, y, 1)
    resid = y - (a + b * x)
    se = np.sqrt(resid @ resid / (x.size - 2) / ((x - x.mean()) @ (x - x.mean())))
    half = t_quantile_975(x.size - 2) * se
    return float(b), float(a), float(b - half), float(b + half)


def data_frame(sizes: dict[str, list[LayoutCells]]) -> pd.DataFrame:
    rows = []
    for size, layouts in sizes.items():
        for lay in layouts:
            feats = features(lay.rows)
            for method in methods_of(layouts):
                v = lay.arm(method).values.to_numpy()
                rows.append(
                    {
                        "size": size,
                        "layout_seed": lay.seed,
                        "maze": lay.maze,
                        "method": method,
                        "label": label(layouts, method),
                        "cell": lay.cells[method].name,
                        "runs": v.size,
                        "collisions_mean": float(v.mean()),
                        "collisions_std": float(v.std(ddof=1)) if v.size > 1 else 0.0,
                        **feats,
                    }
                )
    return pd.DataFrame(rows)


def no_line(x: np.ndarray) -> str:
    """Why a feature has no fitted line: constant over the layouts, or too few of them."""
    return f"constant ({int(x[0])})" if np.ptp(x) == 0 else f"no line: {x.size} layouts"


def feature_rows(df: pd.DataFrame) -> list[dict]:
    out = []
    for size, feature in [(s, f) for s in dict.fromkeys(df["size"]) for f in FEATURES]:
        on = df[df["size"] == size]
        for method in dict.fromkeys(on["method"]):
            m = on[on["method"] == method]
            x, y = m[feature].to_numpy(float), m["collisions_mean"].to_numpy(float)
            line = fit(x, y)
            correlated = line is not None and np.ptp(y) > 0
            out.append(
                {
                    "size": size,
                    "feature": feature,
                    "method": m["label"].iloc[0],
                    "slope (collisions per unit) [95% CI]": (
                        f"{line[0]:.3g} [{line[2]:.3g}, {line[3]:.3g}]" if line else no_line(x)
                    ),
                    "r": f"{np.corrcoef(x, y)[0, 1]:.2f}" if correlated else "",
                    "feature range": f"{int(x.min())}-{int(x.max())}",
                }
            )
    return out
