"""Contact sheets show every row given, with whole labels wrapped to the label column."""

import numpy as np
from PIL import Image, ImageFont

from pipeline.world.contact_sheet import FONT_SIZE, contact_sheet, wrap

LONG = "a062_cone-capsule-cone+5legs+3arms+handle"


def test_labels_wrap_whole():
    font = ImageFont.load_default(size=FONT_SIZE)
    for label, width in ((LONG, 120), ("x" * 80, 100), ("chair (i0 N E S W | i1)", 400)):
        lines = wrap(label, font, width)
        assert "".join(lines) == label and all(font.getlength(line) <= width for line in lines)
    assert len(wrap(LONG, font, 120)) > 1 and wrap("chair", font, 120) == ["chair"]


def test_every_row_is_drawn(tmp_path):
    paths = []
    for i in range(3):
        paths.append(tmp_path / f"{i}.png")
        Image.fromarray(np.full((8, 8, 3), 60 * i, np.uint8)).save(paths[-1])
    rows = [(f"{LONG}_{r}", paths) for r in range(20)]
    sheet = contact_sheet(rows, tile=16, label_width=100)
    assert sheet.width == 100 + 3 * 18 + 2 and sheet.height >= 20 * 16
    pixels = np.asarray(sheet)
    assert (pixels[:, :100] < 128).any(
        axis=2
    ).sum() > 20 * 50  # text in the label column of every row
    first_picture = pixels[:, 102:118]  # black in every row: 20 rows x 16 x 16 pixels
    assert (first_picture == 0).all(axis=2).sum() == 20 * 16 * 16
