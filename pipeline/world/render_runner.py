"""Render batches to PNG files, on one or several worker processes, atomically per file.

Each batch gets one compiled scene and one ``mujoco.Renderer`` (creating one costs far more
than a picture, so it is reused for every picture of the batch, then closed). A picture is written to a
temporary name in its final folder and moved into place with ``os.replace``: an interrupted
render leaves either a complete picture or none (plus, at worst, a ``*.tmp`` file that no
manifest names). Worker processes are spawned, not forked, so no OpenGL state is inherited;
pixels are identical whichever worker renders a batch.
"""

from __future__ import annotations

import io
import multiprocessing as mp
import os
from collections.abc import Callable, Iterable
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image

from pipeline.files import write_atomic
from pipeline.world.render_plan import Batch
from pipeline.world.renderer import SceneRenderer
from pipeline.world.scenes import build_scene


def png_bytes(img: np.ndarray) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(img).save(buf, format="PNG", optimize=False, compress_level=6)
    return buf.getvalue()


@dataclass(frozen=True)
class Drawing:
    """How every picture is drawn: ``size`` pixels square, ``cell`` metres a maze cell, and the
    quality (render.yaml ``quality``: anti-aliasing samples, shadow map, supersampling, shadows in
    the meta-training studio)."""

    size: int
    cell: float = 1.0
    offsamples: int = 0
    shadow_size: int = 512
    supersample: int = 2
    studio_shadows: bool = False


def render_batch(batch: Batch, out_dir: str, drawing: Drawing) -> int:
    """Render every shot of ``batch`` into ``out_dir``; returns the number of pictures."""
    d = drawing
    shadows = batch.setting != "studio" or d.studio_shadows
    spec, layout = build_scene(
        batch.setting, batch.objects, d.cell, d.shadow_size, d.offsamples, shadows
    )
    root = Path(out_dir)
    with SceneRenderer(spec, layout, d.size, d.supersample) as r:
        for shot, rel in zip(batch.shots, batch.files):
            write_atomic(root / rel, png_bytes(r.render(shot)), fsync=False)
    return len(batch.shots)


def _worker_init(threads: int) -> None:
    os.environ.setdefault("LP_NUM_THREADS", str(threads))


def render_all(
    batches: list[Batch],
    out_dir: str,
    drawing: Drawing,
    workers: int = 2,
    progress: Callable[[Iterable, int], Iterable] | None = None,
) -> int:
    """Render all batches (largest first, for load balance) with ``workers`` processes."""
    order = sorted(range(len(batches)), key=lambda i: -len(batches[i].shots))
    total = sum(len(b.shots) for b in batches)
    done = 0
    if workers <= 1:
        it = (render_batch(batches[i], out_dir, drawing) for i in order)
        for n in progress(it, len(order)) if progress else it:
            done += n
        return done
    ctx = mp.get_context("spawn")
    with ProcessPoolExecutor(
        max_workers=workers, mp_context=ctx, initializer=_worker_init, initargs=(1,)
    ) as pool:
        futs = [pool.submit(render_batch, batches[i], out_dir, drawing) for i in order]
        it = as_completed(futs)
        for fut in progress(it, len(futs)) if progress else it:
            done += fut.result()
    assert done == total
    return done
