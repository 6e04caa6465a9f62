"""Render stage: ``python -m pipeline render [key=value ...]`` (config ``conf/render.yaml``).

Writes ``<out_dir>/{query,support,train,val}/**.png``, then ``<out_dir>/manifest.csv`` (last,
atomically: a manifest exists only for a complete render), then contact sheets under
``figures_dir``. The science is in ``pipeline.world`` (obstacle_models, metaset, scenes, camera,
renderer, render_plan, render_runner); this file validates the config and does the I/O.
"""
from __future__ import annotations

import csv
import io
import shutil
import time
from pathlib import Path

import hydra
from omegaconf import DictConfig, OmegaConf
from tqdm import tqdm

from pipeline.stages._common import CONF_DIR
from pipeline.world.contact_sheet import contact_sheet, save_png_atomic
from pipeline.world.obstacle_models import category_index
from pipeline.world.pictures import CATEGORIES
from pipeline.world.render_plan import (MANIFEST_COLUMNS, SPLITS, CatalogueCamera, MazeCamera, PlanConfig,
                                        make_plan)
from pipeline.world.render_runner import render_all, write_atomic
from pipeline.world.renderer_env import RendererUnavailable, backend_problem

MANIFEST = "manifest.csv"


def _positive_int(cfg: DictConfig, key: str, minimum: int = 1) -> int:
    v = OmegaConf.select(cfg, key)
    if isinstance(v, bool) or not isinstance(v, int) or v < minimum:
        raise ValueError(f"config key '{key}' must be an integer >= {minimum}, got {v!r}")
    return v


def validate(cfg: DictConfig) -> PlanConfig:
    """Check every key the stage reads; errors name the key."""
    _positive_int(cfg, "size")
    _positive_int(cfg, "workers")
    for key in ("n_train_classes", "n_val_classes"):
        _positive_int(cfg, key, 0)
    for key in ("per_class", "views_per_instance", "support_per_category", "contact_tile"):
        _positive_int(cfg, key)
    if not isinstance(cfg.seed, int) or cfg.seed < 0:
        raise ValueError(f"config key 'seed' must be a non-negative integer, got {cfg.seed!r}")
    cats = list(cfg.categories)
    for c in cats:
        try:
            category_index(c)
        except ValueError as exc:
            raise ValueError(f"config key 'categories': {exc}") from None
    if len(set(cats)) != len(cats):
        raise ValueError(f"config key 'categories' repeats a category: {cats}")
    out = Path(cfg.out_dir)
    if not out.resolve().parent.is_dir():
        raise FileNotFoundError(f"config key 'out_dir': the parent folder of {str(out)!r} does not exist "
                                f"({out.resolve().parent}); create it or choose another out_dir")
    fig = Path(cfg.figures_dir)
    inside_out = fig.resolve().is_relative_to(out.resolve())
    if cfg.contact_sheets and not inside_out and not fig.resolve().parent.is_dir():
        raise FileNotFoundError(f"config key 'figures_dir': the parent folder of {str(fig)!r} does not exist")
    mz = MazeCamera(**{k: float(v) for k, v in cfg.maze.items()})
    for k, v in vars(mz).items():
        if v <= 0:
            raise ValueError(f"config key 'maze.{k}' must be positive, got {v}")
    cc = CatalogueCamera(float(cfg.catalogue.fovy), tuple(map(float, cfg.catalogue.elevation)),
                         tuple(map(float, cfg.catalogue.turn)), float(cfg.catalogue.fill))
    if not 0 < cc.fill <= 1:
        raise ValueError(f"config key 'catalogue.fill' must be in (0, 1], got {cc.fill}")
    _positive_int(cfg, "quality.shadow_size")
    _positive_int(cfg, "quality.offsamples", 0)
    _positive_int(cfg, "quality.supersample")
    for key in ("quality.studio_shadows", "contact_sheets"):
        if not isinstance(OmegaConf.select(cfg, key), bool):
            raise ValueError(f"config key '{key}' must be true or false, got {OmegaConf.select(cfg, key)!r}")
    return PlanConfig(int(cfg.seed), tuple(cats), int(cfg.n_train_classes), int(cfg.n_val_classes),
                      int(cfg.per_class), int(cfg.views_per_instance), int(cfg.support_per_category), mz, cc)


def manifest_bytes(rows: list[dict]) -> bytes:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(MANIFEST_COLUMNS), lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    return buf.getvalue().encode()


def write_contact_sheets(rows: list[dict], out: Path, figures: Path, tile: int, n_classes: int, per_class: int) -> list[Path]:
    written = []
    q = [r for r in rows if r["split"] == "query"]
    sheet_rows = []
    for c in sorted({r["category"] for r in q}):
        rs = sorted((r for r in q if r["category"] == c), key=lambda r: r["picture_id"])
        sheet_rows.append((f"{CATEGORIES[c]} (i0 N E S W | i1)", [out / r["file"] for r in rs]))
    if sheet_rows:
        save_png_atomic(contact_sheet(sheet_rows, tile), figures / "contact_query.png")
        written.append(figures / "contact_query.png")
    s = [r for r in rows if r["split"] == "support"]
    sheet_rows = [(CATEGORIES[c], [out / r["file"] for r in s if r["category"] == c])
                  for c in sorted({r["category"] for r in s})]
    if sheet_rows:
        save_png_atomic(contact_sheet(sheet_rows, tile), figures / "contact_support.png")
        written.append(figures / "contact_support.png")
    for split in ("train", "val"):
        t = [r for r in rows if r["split"] == split]
        classes = sorted({r["category"] for r in t})[:n_classes]
        sheet_rows = []
        for c in classes:
            rs = [r for r in t if r["category"] == c]
            step = max(1, len(rs) // per_class)
            sheet_rows.append((rs[0]["class_name"], [out / r["file"] for r in rs[::step][:per_class]]))
        if sheet_rows:
            save_png_atomic(contact_sheet(sheet_rows, tile, label_width=190), figures / f"contact_{split}.png")
            written.append(figures / f"contact_{split}.png")
    return written


def run(cfg: DictConfig) -> dict:
    """The whole stage; returns figures (pictures, seconds, pictures per second)."""
    plan_cfg = validate(cfg)
    problem = backend_problem()
    if problem is not None:
        raise RendererUnavailable(problem)
    out = Path(cfg.out_dir)
    out.mkdir(exist_ok=True)
    (out / MANIFEST).unlink(missing_ok=True)  # no manifest until this render is complete
    for split in SPLITS:
        shutil.rmtree(out / split, ignore_errors=True)
    t0 = time.perf_counter()
    batches, rows = make_plan(plan_cfg)

    def bar(it, n):
        return tqdm(it, total=n, desc="render batches", unit="batch")

    n = render_all(batches, str(out), int(cfg.size), int(cfg.workers), int(cfg.quality.offsamples),
                   int(cfg.quality.shadow_size), float(cfg.maze.cell), int(cfg.quality.supersample),
                   bool(cfg.quality.studio_shadows), progress=bar)
    missing = [r["file"] for r in rows if not (out / r["file"]).is_file()]
    if missing:
        raise RuntimeError(f"{len(missing)} pictures missing after rendering, e.g. {missing[:3]}")
    write_atomic(out / MANIFEST, manifest_bytes(rows))
    seconds = time.perf_counter() - t0
    sheets = []
    if cfg.contact_sheets:
        sheets = write_contact_sheets(rows, out, Path(cfg.figures_dir), int(cfg.contact_tile),
                                      int(cfg.contact_train_classes), int(cfg.contact_per_class))
    figures = {"pictures": n, "seconds": round(seconds, 2), "pictures_per_second": round(n / seconds, 1),
               "manifest": str(out / MANIFEST), "contact_sheets": [str(p) for p in sheets]}
    print(f"[render] {n} pictures in {seconds:.1f} s ({n / seconds:.1f}/s) -> {out / MANIFEST}")
    for p in sheets:
        print(f"[render] contact sheet {p}")
    return figures


@hydra.main(version_base="1.3", config_path=CONF_DIR, config_name="render")
def main(cfg: DictConfig) -> None:
    run(cfg)


if __name__ == "__main__":
    main()
