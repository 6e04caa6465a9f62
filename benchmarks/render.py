"""Render benchmark: ``python -m benchmarks.render [--full]``.

Prints (and writes ``reports/benchmarks/render.json``):
* renderer start-up (compile + ``mujoco.Renderer``) per scene, in seconds;
* pictures per second of one renderer in one process, per setting (maze, catalogue, studio);
* the render stage end to end on a small config, and with ``--full`` the default config
  (4,865 pictures; the goal is at most 3 minutes on 2 cores, README "Measured").
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time

os.environ.setdefault("MUJOCO_GL", "egl")

from hydra import compose, initialize_config_dir  # noqa: E402

from benchmarks._output import write_figures
from pipeline.config.folder import conf_dir  # noqa: E402
from pipeline.world.render_plan import PlanConfig, make_plan  # noqa: E402
from pipeline.world.renderer import SceneRenderer  # noqa: E402
from pipeline.world.scenes import build_scene  # noqa: E402

CONF = str(conf_dir())


def per_setting(size: int, supersample: int) -> dict:
    batches, _ = make_plan(PlanConfig(n_train_classes=1, n_val_classes=0, per_class=60))
    out = {}
    for b in batches:
        t0 = time.perf_counter()
        spec, layout = build_scene(
            b.setting, b.objects, shadows=b.setting != "studio"
        )  # as the stage
        r = SceneRenderer(spec, layout, size, supersample)
        t1 = time.perf_counter()
        r.render(b.shots[0])
        t2 = time.perf_counter()
        for s in b.shots:
            r.render(s)
        t3 = time.perf_counter()
        r.close()
        out[b.setting] = {
            "startup_s": round(t1 - t0, 3),
            "pictures": len(b.shots),
            "ms_per_picture": round((t3 - t2) / len(b.shots) * 1000, 2),
            "pictures_per_second": round(len(b.shots) / (t3 - t2), 1),
        }
    return out


def stage(overrides: list[str]) -> dict:
    from pipeline.config.registry import register
    from pipeline.stages.render import run

    register("render")  # conf/render.yaml names render_schema
    with (
        tempfile.TemporaryDirectory() as tmp,
        initialize_config_dir(config_dir=CONF, version_base="1.3"),
    ):
        cfg = compose(
            "render",
            overrides=[
                *overrides,
                f"out_dir={tmp}/images",
                f"figures_dir={tmp}/figures",
                "contact_sheets=false",
            ],
        )
        t0 = time.perf_counter()
        fig = run(cfg)
        fig["wall_s"] = round(time.perf_counter() - t0, 2)
        fig.pop("contact_sheets", None)
        fig.pop("manifest", None)
        return fig


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--full", action="store_true", help="also time the default (full) render stage")
    args = ap.parse_args()
    res = {
        "machine": {
            "cpus": os.cpu_count(),
            "python": platform.python_version(),
            "MUJOCO_GL": os.environ.get("MUJOCO_GL"),
            "loadavg_at_start": [round(x, 2) for x in os.getloadavg()],
        }
    }
    res["one_renderer_84px_supersample2"] = per_setting(84, 2)
    res["one_renderer_84px_no_antialiasing"] = per_setting(84, 1)
    res["stage_small_1_worker"] = stage(
        ["n_train_classes=8", "n_val_classes=4", "per_class=10", "workers=1"]
    )
    res["stage_small_2_workers"] = stage(
        ["n_train_classes=8", "n_val_classes=4", "per_class=10", "workers=2"]
    )
    if args.full:
        res["stage_default_2_workers"] = stage([])
    print(json.dumps(res, indent=2))
    write_figures("reports/benchmarks/render.json", res, "benchmarks.render")


if __name__ == "__main__":
    main()
