"""Robot benchmark: ``python -m benchmarks.robot3d [--cell]``.

Prints (and writes ``reports/benchmarks/robot3d.json``), for the camera robot of issue 30
(docs/robot3d.md):

* physics steps per second: raw ``mj_step`` on the 5x5 world (robot driving), and as the
  controller uses it (10 Hz ticks of 5 steps at the 20 ms timestep, with contact checks and the
  pose), per grid move;
* live pictures per second (the forward camera, 84 x 84 crop of a 112 x 84 frame) and the live
  scores per second of each few-shot network (Relation and Prototypical);
* the real-time factor: simulated robot seconds per wall-clock second of a few-shot run with the
  oracle (the controller, range sensor, camera and rules);
* with ``--cell``: one cell of the ``robot3d`` experiment at its scale (fewshot_dss, 7x7, relation_net,
  10 runs x 100 episodes) in this process: its wall time and real-time factor;
* the 1-minute load average before and after: other work on the 2 cores lowers every rate.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402

from benchmarks._output import write_figures  # noqa: E402
from pipeline.rl.oracle import OracleRecogniser  # noqa: E402
from pipeline.rl.runner import make_run_world  # noqa: E402
from pipeline.robot.live import LiveView, live  # noqa: E402
from pipeline.robot.sim import RobotSim  # noqa: E402
from pipeline.world.geometry import build_geometry  # noqa: E402
from pipeline.world.maze import load_layout  # noqa: E402
from pipeline.world.renderer_env import mujoco  # noqa: E402


def physics() -> dict:
    layout = load_layout("5x5")
    geometry = build_geometry(layout)
    sim = RobotSim(layout, make_run_world(geometry, 0, 0).placement)
    m, d = sim.model, sim.data
    sim.reset(layout.start, heading=2)
    d.ctrl[:] = [0.0, -0.2, 0.0]
    n = 20_000
    t0 = time.perf_counter()
    mujoco.mj_step(m, d, nstep=n)
    raw = n / (time.perf_counter() - t0)
    moves, steps0, t0 = 0, sim.physics_steps, time.perf_counter()
    for _ in range(20):
        for s, a in [(layout.start, 2), (layout.start + layout.width, 0)]:
            sim.reset(s)
            sim.move(s, a)
            moves += 1
    wall = time.perf_counter() - t0
    controlled = (sim.physics_steps - steps0) / wall
    t0 = time.perf_counter()
    for _ in range(50):
        sim.picture(84)
    pictures = 50 / (time.perf_counter() - t0)
    sim.close()
    return {
        "timestep_s": float(m.opt.timestep),
        "physics_steps_per_s_raw": round(raw),
        "physics_steps_per_s_controlled": round(controlled),
        "ms_per_grid_move": round(wall / moves * 1000, 2),
        "pictures_per_s": round(pictures, 1),
    }


def live_scores() -> dict | None:
    """Live scores per second of each few-shot network whose checkpoint is on disk."""
    from pipeline.fewshot.recogniser import ProtoRecogniser, RelationRecogniser

    out = {}
    image = np.random.default_rng(0).integers(0, 255, (84, 84, 3), dtype=np.uint8)
    view = LiveView(image, truth=-1, picture=-1)
    for cls, checkpoint in ((RelationRecogniser, "datasets/models/relation_net.pt"),
                            (ProtoRecogniser, "datasets/models/protonet.pt")):  # fmt: skip
        if not os.path.exists(checkpoint) or not os.path.exists("datasets/images"):
            continue
        rec = live(cls.from_files(checkpoint, "datasets/images"))
        rec.start_run(0, 0)
        t0 = time.perf_counter()
        for _ in range(100):
            rec.live_scores(0, view)
        out[f"{cls.kind}_live_scores_per_s"] = round(100 / (time.perf_counter() - t0), 1)
    return out or None


def real_time_factor(maze: str, method: str, runs: int, episodes: int, recogniser=None) -> dict:
    from pipeline.rl.methods import get_method
    from pipeline.robot.trials import run_robot_trials

    class Clock:
        sim_time = 0.0
        pictures = 0

        def episode(self, **k):
            self.sim_time += k["sim_time"]
            self.pictures += len(k["pictures"])

    clock = Clock()
    t0 = time.perf_counter()
    result = run_robot_trials(
        load_layout(maze), get_method(method), runs, episodes, 0,
        recogniser=recogniser or OracleRecogniser(), robot_sink=clock,
    )  # fmt: skip
    wall = time.perf_counter() - t0
    return {
        "maze": maze,
        "method": method,
        "runs": runs,
        "episodes": episodes,
        "grid_moves": int(result.steps.sum()),
        "live_pictures": clock.pictures,
        "wall_s": round(wall, 1),
        "simulated_robot_s": round(clock.sim_time, 1),
        "real_time_factor": round(clock.sim_time / wall, 1),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cell", action="store_true", help="also one robot3d cell at its scale")
    ap.add_argument("--out", default="reports/benchmarks/robot3d.json")
    args = ap.parse_args()
    load_before = round(os.getloadavg()[0], 2)  # other work on the 2 cores lowers every rate
    figures = {
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version()},
        "physics": physics(),
        "recognition": live_scores(),
        "few_shot_oracle_5x5": real_time_factor("5x5", "fewshot_dss", 2, 20),
    }
    if args.cell:
        from pipeline.fewshot.recogniser import RelationRecogniser

        rec = RelationRecogniser.from_files("datasets/models/relation_net.pt", "datasets/images")
        figures["cell_fewshot_dss_7x7_relation_net"] = real_time_factor(
            "7x7", "fewshot_dss", 10, 100, rec
        )
    figures["load_average_1min"] = {"before": load_before, "after": round(os.getloadavg()[0], 2)}
    path = write_figures(args.out, figures, "benchmarks.robot3d")
    print(path.read_text())


if __name__ == "__main__":
    main()
