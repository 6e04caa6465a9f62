"""The one palette: every colour that stands for something in the study, declared once.

The replay (:mod:`pipeline.replay`), the Gymnasium frame (:mod:`pipeline.rl.gym_render`), the
report's figures (:mod:`pipeline.report`) and the DVC plots (the report's learning-curve tables
carry each series' colour) take their colours from here, so a chair is the same orange
everywhere. A method's colour is part of its declaration (:data:`pipeline.rl.rules.METHODS`).
Colours are ``#rrggbb``; :func:`rgb` gives the 0-255 triple.
"""

from __future__ import annotations

#: By category index (the order of ``pipeline.world.pictures.CATEGORIES``: chair, kettle, carton,
#: basin, basket); Okabe-Ito colours, apart from the start, goal and A_d colours below.
CATEGORY = ("#E69F00", "#56B4E9", "#CC79A7", "#0072B2", "#8C510A")
#: A category beyond those declared.
OTHER_CATEGORY = "#7F7F7F"
START = "#009E73"  # the start cell
GOAL = "#F0E442"  # the goal cell
UNSAFE = "#D62728"  # a pair of A_d, and a collision (which adds one)
RESELECTED = "#7B3294"  # a step whose action was reselected (eqs. 7-8)
ROBOT = "#1A1A1A"  # the robot and its path
FREE = "#FFFFFF"  # a free cell
GRID = "#BEBEBE"  # grid lines
PAPER = "#000000"  # the paper's numbers beside ours
#: Series that nothing above declares (support set restored / carried over, the ways of Figure 9),
#: by position, as many as Figure 9's rows (a DVC plot needs a colour a series); none of them a
#: method's or a recogniser's colour.
SERIES = ("#4D4D4D", "#B8860B", "#6B6ECF", "#3CB371", "#CD5C5C", "#20B2AA", "#000080", "#FF1493")


def series(k: int) -> str:
    """The ``k``-th colour of :data:`SERIES`, from the first again after the last."""
    return SERIES[k % len(SERIES)]


def category(c: int) -> str:
    """The colour of category ``c`` (:data:`OTHER_CATEGORY` beyond the declared ones)."""
    return CATEGORY[c] if 0 <= c < len(CATEGORY) else OTHER_CATEGORY


def rgb(colour: str) -> tuple[int, int, int]:
    """``"#rrggbb"`` as an (r, g, b) triple of 0-255 integers."""
    return tuple(int(colour[i : i + 2], 16) for i in (1, 3, 5))
