"""Contact sheets: grids of pictures with a label per row, so people can look at the datasets."""

from __future__ import annotations

import re
from pathlib import Path

from PIL import Image, ImageDraw, ImageFont

from pipeline.files import atomic_output

FONT_SIZE = 14  # pixels; Pillow's own scalable font (no system fonts needed)


def wrap(label: str, font, width: int) -> list[str]:
    """``label`` in lines no wider than ``width`` pixels, broken after ``_ - + space`` where it
    can be (class names like ``a062_cone-capsule-cone+5legs+3arms+handle``), anywhere where not."""
    lines, line = [], ""
    for part in re.findall(r"[^_\-+ ]+[_\-+ ]?|[_\-+ ]", label):
        if line and font.getlength(line + part) > width:
            lines.append(line)
            line = ""
        while font.getlength(part) > width:  # a part wider than a line on its own
            cut = max(
                1, next(i for i in range(len(part), 0, -1) if font.getlength(part[:i]) <= width)
            )
            lines.append(part[:cut])
            part = part[cut:]
        line += part
    return lines + ([line] if line else [])


def contact_sheet(
    rows: list[tuple[str, list[Path]]], tile: int, label_width: int = 150, pad: int = 2
) -> Image.Image:
    """One row per ``(label, picture paths)``, every row given (every class), pictures resized to
    ``tile`` pixels. Labels are whole, wrapped over lines in a column at least ``label_width``
    pixels wide, and widened (and the row made taller) when a label needs it."""
    font = ImageFont.load_default(size=FONT_SIZE)
    line_height = FONT_SIZE + 3
    width = max(
        [
            label_width,
            *(
                min(int(font.getlength(w)) + 1, 2 * label_width)
                for label, _ in rows
                for w in re.split(r"[_\-+ ]", label)
            ),
        ]
    )
    wrapped = [wrap(label, font, width - 8) for label, _ in rows]
    heights = [max(tile, len(lines) * line_height + 4) for lines in wrapped]
    ncol = max((len(p) for _, p in rows), default=1)
    sheet = Image.new(
        "RGB",
        (width + ncol * (tile + pad) + pad, max(sum(heights) + pad * (len(rows) + 1), 1)),
        (255, 255, 255),
    )
    draw = ImageDraw.Draw(sheet)
    y = pad
    for (_label, paths), lines, height in zip(rows, wrapped, heights):
        top = y + (height - len(lines) * line_height) // 2
        for i, line in enumerate(lines):
            draw.text((4, top + i * line_height), line, fill=(0, 0, 0), font=font)
        for c, p in enumerate(paths):
            img = Image.open(p).convert("RGB")
            if img.size != (tile, tile):
                img = img.resize((tile, tile), Image.Resampling.BILINEAR)
            sheet.paste(img, (width + pad + c * (tile + pad), y + (height - tile) // 2))
        y += height + pad
    return sheet


def save_png_atomic(img: Image.Image, path: Path) -> None:
    with atomic_output(path) as f:
        img.save(f, format="PNG")


__all__ = ["contact_sheet", "save_png_atomic"]
