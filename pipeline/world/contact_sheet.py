"""Contact sheets: grids of pictures with a label per row, so people can look at the datasets."""
from __future__ import annotations

from pathlib import Path

from PIL import Image, ImageDraw

from pipeline.files import atomic_output


def contact_sheet(rows: list[tuple[str, list[Path]]], tile: int, label_width: int = 150, pad: int = 2) -> Image.Image:
    """One row per ``(label, picture paths)``; pictures are resized to ``tile`` pixels."""
    ncol = max((len(p) for _, p in rows), default=1)
    w = label_width + ncol * (tile + pad) + pad
    h = len(rows) * (tile + pad) + pad
    sheet = Image.new("RGB", (w, max(h, 1)), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    for r, (label, paths) in enumerate(rows):
        y = pad + r * (tile + pad)
        draw.text((4, y + tile // 2 - 6), label[:24], fill=(0, 0, 0))
        for c, p in enumerate(paths):
            img = Image.open(p).convert("RGB")
            if img.size != (tile, tile):
                img = img.resize((tile, tile), Image.Resampling.BILINEAR)
            sheet.paste(img, (label_width + pad + c * (tile + pad), y))
    return sheet


def save_png_atomic(img: Image.Image, path: Path) -> None:
    with atomic_output(path) as f:
        img.save(f, format="PNG")


__all__ = ["contact_sheet", "save_png_atomic"]
