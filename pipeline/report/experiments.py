"""Read the recorded experiments (``<runs_dir>/<folder>/<cell>/records.mcap``) into per-cell tables
for the report. Only the MCAP records are read: each file embeds the config its cell ran with,
including ``experiment.name``, ``experiment.cells`` and ``experiment.report`` (how to present it,
:class:`~pipeline.report.spec.ReportSpec`). Every folder of ``runs_dir`` with cell folders is an
experiment; a folder of runs made without an experiment (a sweep) gets the default section."""

from __future__ import annotations

import json
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pandas as pd

from pipeline.errors import UserError
from pipeline.records import read_records
from pipeline.records.reader import RecordsWarning
from pipeline.report.names import row_names
from pipeline.report.spec import ReportSpec, Row
from pipeline.world.layout_sets import expand


@dataclass
class Cell:
    experiment: str
    name: str
    info: dict  # method spec, maze, substitution, support (from the file's metadata)
    layout: list[str]
    obstacles: dict  # run -> obstacle assignment
    episodes: pd.DataFrame  # run, episode, steps, collisions, ... (one row per episode)
    recognitions: pd.DataFrame
    substitutions: pd.DataFrame  # incl. one row per run (picture -1) with the initial support set
    path: Path | None = None  # the records file
    config: dict | None = None  # the config the cell ran with (as recorded)

    @property
    def method(self) -> str:
        return self.info["method"]["name"]

    @property
    def maze(self) -> str:
        return self.info["maze"]

    def collisions_by_run(self) -> pd.Series:
        """Collisions per run, indexed by run (:meth:`runs`): cells that share run seeds pair by it."""
        return self.episodes.groupby("run")["collisions"].sum()

    def collisions_per_run(self) -> np.ndarray:
        return self.collisions_by_run().to_numpy()

    def runs(self) -> np.ndarray:
        """The run indices, in the order of :meth:`collisions_per_run` and the rows of the
        per-episode arrays; run ``r`` has the seed ``(seed, r)`` in every cell of ``seed``."""
        return np.sort(self.episodes["run"].unique())

    @property
    def seed(self):
        return (self.config or {}).get("seed")

    def collisions_by_episode(self) -> np.ndarray:
        """(runs, episodes): collisions of each run in each episode (NaN: episode not recorded)."""
        wide = self.episodes.pivot_table(
            index="run", columns="episode", values="collisions", aggfunc="sum"
        )
        wide = wide.reindex(columns=range(int(self.episodes["episode"].max()) + 1))
        return wide.to_numpy(dtype=float)

    @property
    def recognises(self) -> bool:
        """Whether the cell ran a recogniser (its substitutions hold the support set's accuracy)."""
        subs = self.substitutions
        return subs is not None and len(subs) > 0 and "support_accuracy" in subs

    def support_accuracy(self) -> np.ndarray | None:
        """(runs, episodes): query accuracy of each run's support set at the end of each episode
        (the initial set's until the first substitution); None without a recogniser."""
        if not self.recognises:
            return None
        subs = self.substitutions
        runs = sorted(self.episodes["run"].unique())
        n_ep = int(self.episodes["episode"].max()) + 1
        out = np.full((len(runs), n_ep), np.nan)
        for i, r in enumerate(runs):
            g = subs[subs["run"] == r].sort_values(["episode", "step", "picture"])
            for ep, acc in zip(g["episode"], g["support_accuracy"]):
                out[i, int(ep) :] = acc
        return out

    def start_accuracy(self) -> float | None:
        """Mean over runs of the initial support set's query accuracy (None without a recogniser)."""
        if not self.recognises:
            return None
        subs = self.substitutions
        return float(subs.loc[subs["picture"] < 0, "support_accuracy"].mean())

    def converged_episode(self) -> list[int | None]:
        """Per run, the first episode after which the greedy path stays optimal (None: never)."""
        if "greedy_optimal" not in self.episodes:
            return []
        out = []
        for _, g in self.episodes.sort_values(["run", "episode"]).groupby("run"):
            ok = g["greedy_optimal"].to_numpy(bool)
            bad = np.flatnonzero(~ok)
            out.append(
                0 if bad.size == 0 else (None if bad[-1] == ok.size - 1 else int(bad[-1] + 1))
            )
        return out


@dataclass
class Experiment:
    """One folder of ``runs_dir``: its recorded cells and how the report presents them."""

    folder: str  # the folder's name (names the tables and figures: unique)
    name: str  # ``experiment.name`` as recorded (the folder's name without one)
    spec: ReportSpec
    cells: dict[str, Cell]  # recorded cells, by name
    declared: list[str]  # the cells the recorded experiment has (sorted)
    notes: list[str] = field(default_factory=list)  # what the report should say about the block

    @property
    def missing(self) -> list[str]:
        """Cells of the experiment without records."""
        return [c for c in self.declared if c not in self.cells]

    def rows(self) -> list[tuple[Row, list[Cell]]]:
        """The section's rows with their recorded cells, named from them
        (:func:`~pipeline.report.names.row_names`); rows without any are left out."""
        out = []
        for row in self.spec.rows(self.declared or self.cells):
            cells = [self.cells[c] for c in row.cells if c in self.cells]
            if cells:
                out.append((row, cells))
        names = row_names([cells for _, cells in out])
        return [(replace(row, label=name), cells) for (row, cells), name in zip(out, names)]


def declared_cells(experiment: dict) -> set[str]:
    """The cells a recorded experiment has: those listed by hand and those of its layout sets
    (:func:`pipeline.world.layout_sets.expand`; the records keep the sets, not their cells)."""
    names = set(experiment.get("cells") or {})
    layouts = experiment.get("layouts")
    if layouts:
        names |= set(expand(layouts.get("sizes") or [], list(layouts.get("cells") or {})))
    return names


class ReportInputError(UserError):
    """Records the report cannot stand on: damaged, incomplete, or cells of different setups."""


def _read_whole(path: Path):
    """The records of a complete, undamaged file; anything less is refused, naming the file."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RecordsWarning)
        try:
            recs = read_records(path, pictures=False)
        except UserError:
            raise
        except Exception as exc:  # the reader's errors for files it cannot read at all
            raise ReportInputError(
                f"{path}: cannot read the records ({type(exc).__name__}: "
                f"{(str(exc).splitlines() or [''])[0]})"
            ) from None
    problems = [str(w.message) for w in caught if issubclass(w.category, RecordsWarning)]
    if problems:
        raise ReportInputError(
            f"{problems[0]}; re-run its trials (the report uses complete records only)"
        )
    return recs


#: Recorded keys that must agree across the cells of one table.
SAME_SETUP = ("seed", "runs", "episodes", "profile")


def check_same_setup(experiment: Experiment) -> None:
    """Cells recorded with another seed, run count, episode count or profile than the first cell
    are never put in one table: name the cell that differs."""
    cells = list(experiment.cells.values())
    first = cells[0]
    for cell in cells[1:]:
        for key in SAME_SETUP:
            a, b = (first.config or {}).get(key), (cell.config or {}).get(key)
            if a != b:
                raise ReportInputError(
                    f"{experiment.folder}/{cell.name}: recorded with {key}={b!r}, but {first.name} with "
                    f"{key}={a!r}; re-run the experiment so that its cells share one setup"
                )


def load_experiment(folder: Path) -> Experiment | None:
    """The experiment recorded under ``folder`` (one sub-folder per cell); None without records."""
    cells, blocks = {}, {}
    name, declared = folder.name, set()
    for path in sorted(folder.glob("*/records.mcap")):
        if path.parent.name.startswith("."):  # a staging folder of a run in progress
            continue
        recs = _read_whole(path)
        meta = recs.meta
        info = meta.info.get("info", meta.info)
        experiment = (meta.config or {}).get("experiment") or {}
        if experiment:
            name = experiment.get("name", name)
            declared |= declared_cells(experiment)
            blocks[path.parent.name] = experiment.get("report")
        cells[path.parent.name] = Cell(
            folder.name,
            path.parent.name,
            info,
            list(meta.maze["layout"]),
            meta.obstacles,
            recs.episodes,
            recs.recognitions,
            recs.substitutions,
            path,
            meta.config,
        )
    if not cells:
        return None
    spec, notes = ReportSpec(), []
    if blocks:
        first = next(iter(blocks))
        text = {c: json.dumps(b, sort_keys=True) for c, b in blocks.items()}
        others = [c for c in blocks if text[c] != text[first]]
        if others:
            notes.append(
                f"The cells' records hold different report blocks (cells {', '.join(others)} differ "
                f"from {first}); this section follows the one of {first}."
            )
        try:
            spec = ReportSpec.from_dict(blocks[first])
        except ValueError as exc:
            notes.append(
                f"The recorded report block cannot be read ({exc}); this is the default section."
            )
        problems = spec.problems(sorted(declared))
        if problems:
            notes.append(
                "The recorded report block names unknown cells: "
                + "; ".join(f"report.{k}: {p}" for k, p in problems)
                + "."
            )
    experiment = Experiment(folder.name, name, spec, cells, sorted(declared), notes)
    check_same_setup(experiment)
    return experiment


def load_all(
    runs_dir: Path, reading: Callable[[str, int, int], None] | None = None
) -> list[Experiment]:
    """Every experiment under ``runs_dir``, in the report's order (``report.order``, then name).
    ``reading(folder, bytes read, bytes in all)`` is told before each folder is read."""
    if not runs_dir.is_dir():
        return []
    folders = [f for f in sorted(runs_dir.iterdir()) if f.is_dir() and not f.name.startswith(".")]
    sizes = [sum(p.stat().st_size for p in f.rglob("*.mcap*")) for f in folders]
    found = []
    for k, folder in enumerate(folders):
        if reading is not None:
            reading(folder.name, sum(sizes[:k]), sum(sizes))
        if (e := load_experiment(folder)) is not None:
            found.append(e)
    return sorted(found, key=lambda e: (e.spec.order, e.name, e.folder))
