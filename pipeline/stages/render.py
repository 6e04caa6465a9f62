"""Stage ``render``: the query, support and meta-training pictures, rendered with MuJoCo, and their manifest.

    python -m pipeline render [key=value ...]            # config conf/render.yaml

Renders into ``<out_dir>/.staging-<pid>/``, moves ``{query,support,train,val,test,views}/`` into
``<out_dir>`` when every picture is there (a failed render leaves the previous pictures and
removes its staging folder), then writes ``<out_dir>/manifest.csv`` (last, atomically: a manifest
exists only for a complete render), then contact sheets under
``figures_dir``. The science is in ``pipeline.world`` (obstacle_models, metaset, scenes, camera,
renderer, render_plan, render_runner); this file validates the config and does the I/O.
"""

from __future__ import annotations

import csv
import io
import os
import shutil
import time
from dataclasses import asdict
from pathlib import Path

from tqdm import tqdm

from pipeline.config.fields import refuse
from pipeline.files import (
    claim_folder,
    free_space,
    remove_abandoned,
    size_text,
    swap_in,
    work_folder,
    write_atomic,
    write_index,
)
from pipeline.manifest import COLUMNS, MANIFEST, SPLITS
from pipeline.schemas.render import RenderConfig
from pipeline.stages import stage_main
from pipeline.world.contact_sheet import contact_sheet, save_png_atomic
from pipeline.world.obstacle_models import category_index
from pipeline.world.render_plan import (
    META_SPLITS,
    CatalogueCamera,
    MazeCamera,
    PlanConfig,
    make_plan,
    plan_size,
)
from pipeline.world.render_runner import Drawing, render_all
from pipeline.world.renderer_env import RendererUnavailable, backend_problem
from pipeline.world.sheet_labels import family_rows, query_rows, support_rows, views_rows

#: Rough costs behind the up-front estimate (:func:`estimate`), fitted to the default render (2
#: workers: 6,465 pictures in 36 s) and ``profile=smoke`` (1 worker) on 2 CPU cores (llvmpipe),
#: with tracemalloc for the memory: PNG bytes per pixel (84 px studio pictures: 5 kB); memory the
#: plan holds per object and per picture; seconds to plan an object and a picture (this process),
#: to start a renderer and to draw a 168 x 168 picture (84 px supersampled twice; the time grows
#: with the pixels drawn).
PNG_BYTES_PER_PIXEL = 0.7
PLAN_BYTES = {"object": 16e3, "picture": 2.3e3}
PLAN_SECONDS = {"object": 0.7e-3, "picture": 0.3e-3}
RENDERER_SECONDS, DRAW_SECONDS, DRAWN_SIDE = 0.15, 8e-3, 168
#: The keys that set how many pictures there are.
SCALE_KEYS = ("n_train_classes", "n_val_classes", "n_test_classes", "per_class", "size")


def plan_config(cfg: RenderConfig) -> PlanConfig:
    """The render plan's settings; refuses what the schema cannot see (unknown categories, missing
    parent folders), naming the key."""
    for c in cfg.categories:
        try:
            category_index(c)
        except ValueError as exc:
            refuse("categories", str(exc))
    if len(set(cfg.categories)) != len(cfg.categories):
        refuse("categories", f"repeats a category: {cfg.categories}")
    out = Path(cfg.out_dir)
    if not out.resolve().parent.is_dir():
        refuse(
            "out_dir",
            f"the parent folder of {str(out)!r} does not exist "
            f"({out.resolve().parent}); create it or choose another out_dir",
        )
    fig = Path(cfg.figures_dir)
    inside_out = fig.resolve().is_relative_to(out.resolve())
    if cfg.contact_sheets and not inside_out and not fig.resolve().parent.is_dir():
        refuse("figures_dir", f"the parent folder of {str(fig)!r} does not exist")
    for key in ("elevation", "turn"):
        if len(getattr(cfg.catalogue, key)) != 2:
            refuse(f"catalogue.{key}", f"give [low, high]; got {getattr(cfg.catalogue, key)}")
    mz = MazeCamera(**asdict(cfg.maze))
    cc = CatalogueCamera(
        cfg.catalogue.fovy,
        tuple(cfg.catalogue.elevation),
        tuple(cfg.catalogue.turn),
        cfg.catalogue.fill,
    )
    if len(cfg.views_distance) != 2 or not 0 < cfg.views_distance[0] <= cfg.views_distance[1]:
        refuse("views_distance", f"give [low, high] with 0 < low <= high; got {cfg.views_distance}")
    return PlanConfig(
        cfg.seed,
        tuple(cfg.categories),
        cfg.n_train_classes,
        cfg.n_val_classes,
        cfg.per_class,
        cfg.views_per_instance,
        cfg.support_per_category,
        mz,
        cc,
        cfg.n_test_classes,
        cfg.min_family_distance,
        cfg.views_per_obstacle,
        tuple(cfg.views_distance),
    )


def manifest_bytes(rows: list[dict]) -> bytes:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(COLUMNS), lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    return buf.getvalue().encode()


def write_contact_sheets(
    rows: list[dict], out: Path, figures: Path, tile: int, n_classes: int, per_class: int
) -> list[Path]:
    """The contact sheets of every split the rows have, row labels in words
    (:mod:`pipeline.world.sheet_labels`); returns the files written."""
    sheets = [
        ("contact_query", query_rows(rows, out), 190),
        ("contact_support", support_rows(rows, out), 190),
        *(
            (f"contact_{split}", family_rows(rows, out, split, n_classes, per_class), 230)
            for split in META_SPLITS
        ),
        ("contact_views", views_rows(rows, out, per_class + 3), 190),
    ]
    written = []
    for stem, sheet_rows, label_width in sheets:
        if sheet_rows:
            path = figures / f"{stem}.png"
            save_png_atomic(contact_sheet(sheet_rows, tile, label_width=label_width), path)
            written.append(path)
    return written


def estimate(cfg: RenderConfig, plan_cfg: PlanConfig) -> dict:
    """The plan's pictures (counted without building it) and, roughly, the bytes they take on
    disk, the bytes the plan holds in memory and the seconds to plan and render them."""
    size = plan_size(plan_cfg)
    pictures, objects = sum(size["pictures"].values()), size["objects"]
    draw = DRAW_SECONDS * (cfg.size * cfg.quality.supersample / DRAWN_SIDE) ** 2
    plan = objects * PLAN_SECONDS["object"] + pictures * PLAN_SECONDS["picture"]
    return {
        "pictures": pictures,
        "classes": plan_cfg.n_train_classes + plan_cfg.n_val_classes + plan_cfg.n_test_classes,
        "disk": pictures * cfg.size**2 * PNG_BYTES_PER_PIXEL,
        "memory": objects * PLAN_BYTES["object"] + pictures * PLAN_BYTES["picture"],
        "seconds": plan + (size["batches"] * RENDERER_SECONDS + pictures * draw) / cfg.workers,
    }


def duration_text(seconds: float) -> str:
    """``seconds`` in the largest unit that keeps a number >= 1 (``40 s``, ``12 min``, ``3.5 h``)."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:,.1f} h"


def machine_memory() -> int:
    """The machine's physical memory, bytes."""
    return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")


def refuse_what_does_not_fit(cfg: RenderConfig, plan_cfg: PlanConfig) -> None:
    """Say how many pictures the render makes, their size on disk and its time, before anything
    is planned; refuse pictures that would not fit the free space of ``out_dir``'s disk, or a plan
    that would hold more than 80% of the machine's memory."""
    guess = estimate(cfg, plan_cfg)
    what = (
        f"{guess['pictures']:,} pictures of {cfg.size} px ({guess['classes']:,} classes x "
        f"{cfg.per_class})"
    )
    print(
        f"[render] {what}: about {size_text(guess['disk'])} on disk, about "
        f"{duration_text(guess['seconds'])} with {cfg.workers} worker(s)",
        flush=True,
    )
    free = free_space(cfg.out_dir)
    if guess["disk"] > free:
        refuse(
            SCALE_KEYS,
            f"{what} take about {size_text(guess['disk'])}; the disk "
            f"of out_dir {cfg.out_dir} has {size_text(free)} free; render fewer classes or "
            "pictures, or choose another out_dir",
        )
    memory = machine_memory()
    if guess["memory"] > 0.8 * memory:
        refuse(
            SCALE_KEYS,
            f"the plan of {what} holds about "
            f"{size_text(guess['memory'])} in memory; this machine has {size_text(memory)}; "
            "render fewer classes or pictures",
        )


def render_into(
    cfg: RenderConfig, plan: tuple[list, list[dict]], staging: Path, t0: float
) -> tuple[int, list, float]:
    """Every picture of the plan (its batches and manifest rows) into ``staging``; the count, the
    manifest rows and the seconds since ``t0``."""
    batches, rows = plan

    def bar(it, n):
        return tqdm(it, total=n, desc="render batches", unit="batch")

    q = cfg.quality
    drawing = Drawing(
        cfg.size, cfg.maze.cell, q.offsamples, q.shadow_size, q.supersample, q.studio_shadows
    )
    n = render_all(batches, str(staging), drawing, cfg.workers, progress=bar)
    missing = [r["file"] for r in rows if not (staging / r["file"]).is_file()]
    if missing:
        raise RuntimeError(f"{len(missing)} pictures missing after rendering, e.g. {missing[:3]}")
    return n, rows, time.perf_counter() - t0


def run(cfg: RenderConfig, overrides: list[str] = ()) -> dict:
    """The whole stage; returns figures (pictures, seconds, pictures per second)."""
    plan_cfg = plan_config(cfg)
    refuse_what_does_not_fit(cfg, plan_cfg)
    problem = backend_problem()
    if problem is not None:
        raise RendererUnavailable(problem)
    t0 = time.perf_counter()
    plan = make_plan(plan_cfg)  # before anything is written: a split it cannot make is refused
    out = Path(cfg.out_dir)
    out.mkdir(exist_ok=True)
    staging = work_folder(out, ".staging")  # the pictures, moved in when all are there
    try:
        claim_folder(staging)
        n, rows, seconds = render_into(cfg, plan, staging, t0)
        (out / MANIFEST).unlink(missing_ok=True)  # no manifest until the new pictures are in
        for split in SPLITS:  # a split this render has not is not kept either
            if not (staging / split).exists():
                shutil.rmtree(out / split, ignore_errors=True)
        swap_in(staging, out)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    remove_abandoned(out, ".staging")  # left by a killed render (never a live one's)
    write_atomic(out / MANIFEST, manifest_bytes(rows))
    sheets = []
    if cfg.contact_sheets:
        sheets = write_contact_sheets(
            rows,
            out,
            Path(cfg.figures_dir),
            cfg.contact_tile,
            cfg.contact_train_classes,
            cfg.contact_per_class,
        )
    if cfg.index_file:
        write_index(out, cfg.index_file)
    figures = {
        "pictures": n,
        "seconds": round(seconds, 2),
        "pictures_per_second": round(n / seconds, 1),
        "manifest": str(out / MANIFEST),
        "contact_sheets": [str(p) for p in sheets],
    }
    print(f"[render] {n} pictures in {seconds:.1f} s ({n / seconds:.1f}/s)")
    return figures


def written(cfg: RenderConfig, figures: dict) -> list[str]:
    """The pictures' folder (with its manifest), the contact sheets' folder, if any were made, and
    the index."""
    return [
        cfg.out_dir,
        *([cfg.figures_dir] if figures["contact_sheets"] else []),
        *([cfg.index_file] if cfg.index_file else []),
    ]


def main() -> None:
    stage_main("render", run)


if __name__ == "__main__":
    main()
