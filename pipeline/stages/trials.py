"""Stage ``trials``: independent runs of the methods on the mazes, every episode recorded to MCAP.

    python -m pipeline trials method=ssrl maze=7x7 runs=100 episodes=500 seed=0 out=runs/ssrl7
    python -m pipeline trials +experiment=fig8            # every cell of one paper experiment

One cell (method, maze, substitution way, support restore/carry) writes ``summary.json`` and
``records.mcap`` into its folder: ``<out>/`` for a single cell, ``<out>/<cell>/`` for each cell
of an experiment, plus ``<out>/summary.json`` listing the cells.
"""
from __future__ import annotations

import sys
import time
from dataclasses import asdict
from pathlib import Path

import hydra
import numba
from omegaconf import DictConfig, OmegaConf

from pipeline.rl.methods import METHODS, MethodSpec
from pipeline.rl.rng import run_seeds
from pipeline.rl.runner import make_run_world, run_trials
from pipeline.stages._common import CONF_DIR, ConfigError, require, write_json_atomic
from pipeline.world.geometry import build_geometry
from pipeline.world.maze import MazeError, load_layout
from pipeline.world.pictures import CATEGORIES

CELL_KEYS = {"method", "maze", "substitution", "support"}


def method_from_config(node, key: str = "method") -> MethodSpec:
    try:
        return MethodSpec(**OmegaConf.to_container(node, resolve=True))
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"config key '{key}': {exc}") from None


def cells_from_config(cfg: DictConfig) -> dict[str, dict]:
    """The cells to run: the experiment's, or the single cell given by method/maze/... keys."""
    if "experiment" not in cfg or cfg.experiment is None:
        return {"": {"method": method_from_config(cfg.method), "maze": str(cfg.maze),
                     "substitution": int(cfg.substitution), "support": str(cfg.support)}}
    cells = {}
    for name, cell in cfg.experiment.cells.items():
        key = f"experiment.cells.{name}"
        unknown = set(cell) - CELL_KEYS
        require(not unknown, key, f"unknown keys {sorted(unknown)}; allowed {sorted(CELL_KEYS)}")
        require("method" in cell, key, "needs a 'method'")
        require(cell.method in METHODS, f"{key}.method", f"unknown method {cell.method!r}; expected one of {', '.join(METHODS)}")
        cells[str(name)] = {"method": METHODS[cell.method], "maze": str(cell.get("maze", cfg.maze)),
                            "substitution": int(cell.get("substitution", cfg.substitution)),
                            "support": str(cell.get("support", cfg.support))}
    require(bool(cells), "experiment.cells", "no cells")
    return cells


def validate(cfg: DictConfig) -> dict[str, dict]:
    require(int(cfg.runs) >= 1, "runs", f"must be >= 1, got {cfg.runs}")
    require(int(cfg.episodes) >= 1, "episodes", f"must be >= 1, got {cfg.episodes}")
    require(int(cfg.seed) >= 0, "seed", f"must be >= 0, got {cfg.seed}")
    require(int(cfg.flush_every) >= 1, "flush_every", f"must be >= 1, got {cfg.flush_every}")
    cells = cells_from_config(cfg)
    for name, cell in cells.items():
        prefix = f"experiment.cells.{name}." if name else ""
        try:
            cell["layout"] = load_layout(cell["maze"])
        except MazeError as exc:
            raise ConfigError(f"config key '{prefix}maze': {exc}") from None
        require(cell["substitution"] in (1, 2, 3, 4), f"{prefix}substitution",
                f"substitution way must be 1, 2, 3 or 4, got {cell['substitution']}")
        require(cell["support"] in ("restore", "carry"), f"{prefix}support",
                f"must be 'restore' or 'carry', got {cell['support']!r}")
        if cell["method"].uses_recogniser:
            require(cfg.recogniser.kind in ("relation_net", "oracle"), "recogniser.kind",
                    f"method {cell['method'].name!r} needs a recogniser: relation_net or oracle, got {cfg.recogniser.kind!r}")
            if cfg.recogniser.kind == "relation_net":
                for key in ("checkpoint", "images_dir"):
                    require(Path(cfg.recogniser[key]).exists(), f"recogniser.{key}",
                            f"{cfg.recogniser[key]} does not exist (run the render and meta_train stages first)")
    return cells


def build_recogniser(cfg: DictConfig, cell: dict):
    method = cell["method"]
    if not method.uses_recogniser:
        return None
    way = cell["substitution"] if method.dynamic_support else 0
    if cfg.recogniser.kind == "oracle":
        from pipeline.stages._recognisers import OracleRecogniser
        return OracleRecogniser()
    from pipeline.fewshot.recogniser import RelationRecogniser
    return RelationRecogniser.from_files(cfg.recogniser.checkpoint, cfg.recogniser.images_dir,
                                         substitution_way=way, carry_over=cell["support"] == "carry")


def query_pictures(images_dir: str) -> dict[int, bytes]:
    """PNG bytes of the query pictures by picture id, from the render stage's manifest."""
    import pandas as pd
    manifest = Path(images_dir) / "manifest.csv"
    if not manifest.exists():
        return {}
    df = pd.read_csv(manifest)
    df = df[df["split"] == "query"]
    return {int(p): (Path(images_dir) / f).read_bytes() for p, f in zip(df["picture_id"], df["file"])}


def run_cell(cfg: DictConfig, name: str, cell: dict, folder: Path) -> dict:
    layout, method = cell["layout"], cell["method"]
    runs, episodes, seed = int(cfg.runs), int(cfg.episodes), int(cfg.seed)
    recogniser = build_recogniser(cfg, cell)
    writer = None
    if bool(cfg.record):
        from pipeline.records.writer import RecordWriter
        geometry = build_geometry(layout)
        placements = [make_run_world(geometry, seed, r).placement.as_records(layout.obstacles) for r in range(runs)]
        pictures = query_pictures(cfg.recogniser.images_dir) if method.uses_recogniser and cfg.recogniser.kind == "relation_net" else {}
        writer = RecordWriter(
            folder / "records.mcap",
            metadata={"config": OmegaConf.to_container(cfg, resolve=True),
                      "seeds": {"seed": seed, "runs": {r: asdict(run_seeds(seed, r)) for r in range(runs)}},
                      "info": {"cell": name, "method": asdict(method), "maze": layout.name,
                               "substitution": cell["substitution"], "support": cell["support"]}},
            maze={"layout": list(layout.rows), "name": layout.name, "categories": list(CATEGORIES)},
            runs=placements, pictures=pictures, flush_every=int(cfg.flush_every))
    t0 = time.perf_counter()
    try:
        result = run_trials(layout, method, runs, episodes, seed, recogniser=recogniser, sink=writer,
                            progress=bool(cfg.progress), shared_support=cell["support"] == "carry")
    except BaseException:
        if writer is not None:
            writer.close(complete=False)
        raise
    if writer is not None:
        writer.close()
    seconds = time.perf_counter() - t0
    summary = result.summary()
    summary.update({"cell": name, "method_spec": asdict(method), "substitution": cell["substitution"],
                    "support": cell["support"]})
    write_json_atomic(folder / "summary.json", summary)  # no wall-clock figures: same seed, same bytes
    return summary, seconds


def run(cfg: DictConfig) -> dict:
    cells = validate(cfg)
    if int(cfg.threads) > 0:
        numba.set_num_threads(int(cfg.threads))
    out = Path(cfg.out)
    summaries, timing = {}, {}
    for name, cell in cells.items():
        summaries[name], timing[name] = run_cell(cfg, name, cell, out / name if name else out)
        c = summaries[name]["collisions"]
        label = f"{name}: " if name else ""
        print(f"{label}{cell['method'].name} on {cell['layout'].name}: collisions {c['mean']:.2f} +- "
              f"{c['std']:.2f} over {cfg.runs} runs, converged runs {summaries[name]['converged_runs']} "
              f"({timing[name]:.1f} s)")
    if cfg.get("timing_file"):
        write_json_atomic(cfg.timing_file, {n: round(t, 3) for n, t in timing.items()})
    if "" in summaries:
        return summaries[""]
    index = {"experiment": str(cfg.experiment.name), "cells": {
        n: {k: s[k] for k in ("method", "maze", "substitution", "support", "collisions", "converged_runs")}
        for n, s in summaries.items()}}
    write_json_atomic(out / "summary.json", index)
    if cfg.get("metrics_file"):
        write_json_atomic(cfg.metrics_file, {n: {"collisions_mean": s["collisions"]["mean"],
                                                 "collisions_std": s["collisions"]["std"],
                                                 "converged_runs": s["converged_runs"]}
                                             for n, s in summaries.items()})
    return index


@hydra.main(config_path=CONF_DIR, config_name="trials", version_base="1.3")
def main(cfg: DictConfig) -> None:
    try:
        run(cfg)
    except ConfigError as exc:
        print(f"error: {exc}", file=sys.stderr)
        raise SystemExit(2) from None
