"""The report's section "On a simulated robot" (kind ``robot``; experiment ``robot3d``, issue 30,
docs/robot3d.md): the same methods with the camera robot in MuJoCo and on the grid, same seeds.

* collisions per run of each method, on the robot beside the grid, per maze and recogniser;
* live recognition accuracy per category and recogniser (the robot's own camera pictures) beside the accuracy on
  the pre-rendered query pictures the same methods met on the grid (the gap between what a robot
  sees and the photographs the paper used);
* the simulated robot time per run (what a real Burger would spend: the safety layer and
  self-recovery save it collisions and recoveries, and the prevented moves cost only a turn);
* the real-time factor, from the benchmark (``reports/benchmarks/robot3d.json``): wall-clock
  figures are never in the records.

A cell's world is its recorded config's ``world``; the robot's own records (``robot.mcap`` beside
``records.mcap``, :mod:`pipeline.robot.records`) are read here with ``mcap`` directly, so the
report does not import the robot package (.importlinter: siblings).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
from mcap.reader import make_reader

from pipeline.report.experiments import ReportInputError
from pipeline.report.names import method_name, method_order, recogniser_name, recogniser_of
from pipeline.report.stats import describe, fmt, wilson_ci
from pipeline.world.pictures import CATEGORIES

BENCHMARK = Path("reports/benchmarks/robot3d.json")


def world(cell) -> str:
    return (cell.config or {}).get("world", "grid")


def sim_time_per_run(cell) -> np.ndarray | None:
    """Simulated seconds of each run, from the cell's ``robot.mcap`` (None without one)."""
    path = cell.path.with_name("robot.mcap") if cell.path is not None else None
    if path is None or not path.exists():
        return None
    totals: dict[int, float] = {}
    try:
        with open(path, "rb") as f:
            for _, channel, message in make_reader(f).iter_messages(log_time_order=False):
                if channel.topic == "/robot/episode":
                    ep = json.loads(message.data)
                    totals[ep["run"]] = totals.get(ep["run"], 0.0) + ep["sim_time"]
    except Exception as exc:  # mcap's and JSON's errors on a damaged file
        raise ReportInputError(
            f"{path}: cannot read the robot's records ({type(exc).__name__}: "
            f"{(str(exc).splitlines() or [''])[0]}); re-run its trials"
        ) from None
    return np.array([totals[r] for r in sorted(totals)])


def _accuracy(recognitions: list[pd.DataFrame]) -> dict[int, tuple[int, int]]:
    frame = pd.concat(recognitions) if recognitions else pd.DataFrame(columns=["true", "predicted"])
    out = {}
    for c in range(len(CATEGORIES)):
        sel = frame[frame["true"] == c]
        out[c] = (int((sel["predicted"] == c).sum()), len(sel))
    return out


def _share(correct: int, n: int) -> str:
    if n == 0:
        return "-"
    lo, hi = wilson_ci(correct / n, n)
    return f"{correct / n:.2f} [{lo:.2f}, {hi:.2f}] (n={n})"


def _recogniser(cell) -> str:
    """The display name of the recogniser a cell ran ("none": its method looks at no pictures)."""
    kind = recogniser_of(cell.info, cell.config)
    return recogniser_name(kind) if kind else "none"


def robot_kind(rep, exp, paper) -> None:
    cells = list(exp.cells.values())
    keys = sorted({(method_order(c.method), c.method, c.maze, _recogniser(c)) for c in cells})
    rows, times = [], []
    for _, method, maze, recogniser in keys:
        pair = {w: [c for c in cells if c.method == method and c.maze == maze and world(c) == w
                    and _recogniser(c) == recogniser] for w in ("grid", "robot3d")}  # fmt: skip
        info = (pair["robot3d"] or pair["grid"])[0].info
        row = {"method": method_name(info["method"]), "recogniser": recogniser, "maze": maze}
        for w, label in (("grid", "grid"), ("robot3d", "robot (MuJoCo)")):
            runs = [c.collisions_per_run() for c in pair[w]]
            row[f"collisions, {label}"] = fmt(describe(np.concatenate(runs))) if runs else "-"
        rows.append(row)
        for c in pair["robot3d"]:
            t = sim_time_per_run(c)
            if t is not None:
                steps = c.episodes.groupby("run")["steps"].sum().to_numpy()
                times.append({"method": row["method"], "recogniser": recogniser, "maze": maze,
                              "simulated robot time per run (min)": fmt(describe(t / 60), 1),
                              "grid moves per run": fmt(describe(steps), 0),
                              "seconds per move": f"{t.sum() / max(steps.sum(), 1):.2f}"})  # fmt: skip
    rep.table(
        exp.folder,
        pd.DataFrame(rows),
        "Collisions per run (mean ± s.d. [95% bootstrap CI] over runs), the same methods and seeds on "
        "the grid and with the robot in MuJoCo (collisions: contacts). Recogniser none: the method "
        "looks at no pictures.",
    )
    seeing = sorted({_recogniser(c) for c in cells if len(c.recognitions)})
    columns = {}
    for name in seeing:
        for w, label in (("grid", "query pictures (grid)"), ("robot3d", "live pictures (robot)")):
            chosen = [c.recognitions for c in cells
                      if world(c) == w and _recogniser(c) == name and len(c.recognitions)]  # fmt: skip
            columns[f"{name}: {label}"] = _accuracy(chosen)
    acc = pd.DataFrame(
        [
            {"category": cat, **{col: _share(*by[c]) for col, by in columns.items()}}
            for c, cat in enumerate(CATEGORIES)
        ]
    )
    rep.table(
        f"{exp.folder}_recognition",
        acc,
        "Recognition accuracy per category and recogniser: every picture the few-shot cells "
        "classified (the category its scores name against the true one; share [95% Wilson CI], "
        "n pictures). Grid: the pre-rendered query pictures; robot: the robot's own camera pictures.",
    )
    if times:
        rep.table(
            f"{exp.folder}_robot_time",
            pd.DataFrame(times),
            "Simulated robot time per run (turns, drives at the Burger's 0.22 m/s, recoveries) and "
            "grid moves per run (mean ± s.d. [95% bootstrap CI]).",
        )
    if BENCHMARK.exists():
        bench = json.loads(BENCHMARK.read_text())
        rtf = bench.get("few_shot_oracle_5x5", {}).get("real_time_factor")
        phys = bench.get("physics", {})
        rep.add(
            f"Real-time factor (benchmark `{BENCHMARK}`): {rtf} simulated seconds per wall-clock "
            f"second; {phys.get('physics_steps_per_s_controlled')} physics steps/s under the "
            f"controller, {phys.get('pictures_per_s')} live pictures/s.\n"
        )
