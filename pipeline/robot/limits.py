"""The robot world's settings that can run (imported by the config schema, so no MuJoCo here)."""

from __future__ import annotations

#: The robot world's defaults: a 1 m cell, the cell the query pictures were rendered for (the
#: obstacles' display scale fits it), and a 20 ms physics step (the planar base with velocity
#: actuators is stable there; a smaller step gives the same outcomes at a higher cost).
DEFAULT_CELL, DEFAULT_TIMESTEP = 1.0, 0.02
#: Cell sizes (m) the robot world is built for: the robot (0.178 m long, 0.112 m from its centre to a
#: corner) turns on a centre without touching an obstacle's box (at most 0.45 of a cell from its
#: centre) from 0.5 m on, and the range sensor (LDS-01, 3.5 m) reads a neighbour up to 2 m.
CELL_RANGE = (0.5, 2.0)
#: MuJoCo steps (s): from 1 ms (100 physics steps a control tick) to 50 ms (2 a tick), dividing the
#: controller's 0.1 s tick; the planar base with velocity actuators is stable over that range.
TIMESTEP_RANGE = (0.001, 0.05)
CONTROL_PERIOD = 0.1


def check_settings(cell: float, timestep: float) -> None:
    """Refuse a cell size or a physics step the robot world cannot run (``ValueError`` naming the
    value, the range and why)."""
    lo, hi = CELL_RANGE
    if not lo <= float(cell) <= hi:
        raise ValueError(
            f"cell={cell}: the robot world's cell must lie in {lo}-{hi} m (the robot turns on a "
            f"centre without touching a neighbour's obstacle from {lo} m on; its range sensor "
            f"reads a neighbour up to {hi} m)"
        )
    lo, hi = TIMESTEP_RANGE
    substeps = CONTROL_PERIOD / float(timestep) if float(timestep) > 0 else float("inf")
    if not lo <= float(timestep) <= hi or abs(substeps - round(substeps)) > 1e-6:
        raise ValueError(
            f"timestep={timestep}: MuJoCo's step must lie in {lo}-{hi} s and divide the "
            f"controller's {CONTROL_PERIOD} s tick evenly (0.001, 0.002, 0.005, 0.01, 0.02, 0.025, "
            "0.05)"
        )
