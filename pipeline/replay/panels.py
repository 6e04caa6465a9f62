"""What the replay's views show beyond the world itself: the layout of the viewer, the same for
every world (:func:`blueprint`; the grid's own views: :func:`maze_views`), category colours and
names (:func:`categories_context`), the heat map of visits or max Q (:func:`heat_rgb`) and the
support set as a grid of pictures (:class:`SupportGrid`).
"""

from __future__ import annotations

import io
from collections.abc import Sequence

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from pipeline import palette

MARK = palette.rgb(palette.RESELECTED)  # the frame of a substituted support picture
#: Viridis at 0, 1/4, 1/2, 3/4 and 1: the heat map's colours, dark (low) to yellow (high).
RAMP = np.array(
    [[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]], np.float64
)
#: The support grid: a picture is 1 x 1 scene units, its neighbours PITCH further (x, y), leaving
#: room under it for the label of a substitution.
PITCH = (1.12, 1.5)


def colour(category: int) -> np.ndarray:
    """The colour of ``category`` (:func:`pipeline.palette.category`)."""
    return np.array(palette.rgb(palette.category(category)), np.uint8)


Bounds = tuple[tuple[float, float], tuple[float, float]]  # (x range, y range) a 2D view shows


def legend_positions(height: int, width: int, n: int) -> tuple[list[list[float]], Bounds]:
    """Where the maze's legend puts category ``c`` (right of the maze), and the bounds of the maze
    view that keep the legend's names in sight."""
    points = [[width + 0.45, 0.4 + 0.75 * c] for c in range(n)]
    return points, ((-0.1, width + 2.6), (-0.1, max(height, 0.75 * n) + 0.3))


def blueprint(
    world,
    grid: Bounds,
    scores: str,
    picture=None,
    legend: str | None = None,
    timeline: str | None = None,
    shares=(3, 2, 3),
):
    """The viewer's layout, the same for every world: the world's views (``world``: the grid's
    :func:`maze_views`, or the robot in 3D) left; the picture seen (``picture``: a view; by default
    of ``recognition/picture``), the scores (the view named ``scores``) and the recognition; the
    legend (``legend``: the entity of a text document, if any), the support set grid (``grid``: its
    bounds) and the events; the time panel on ``timeline`` (the viewer's choice when None);
    ``shares``: the three columns' widths."""
    V, H = rrb.Vertical, rrb.Horizontal
    if picture is None:
        picture = rrb.Spatial2DView(origin="recognition/picture", name="picture seen")
    right = [
        _view2d(
            grid, origin="support", name="support set (framed: substituted at episode, step t)"
        ),
        rrb.TextLogView(origin="events", name="events"),
    ]
    if legend is not None:
        right.insert(0, rrb.TextDocumentView(origin=legend, name="legend"))
    return rrb.Blueprint(
        H(
            world,
            V(
                picture,
                rrb.BarChartView(  # bars in the category colours; the recognition names them
                    origin="recognition/scores",
                    name=scores,
                    plot_legend=rrb.PlotLegend(visible=False),
                ),
                rrb.TextDocumentView(origin="recognition/result", name="recognition"),
                row_shares=[2, 2, 3],
            ),
            V(*right, row_shares=[2, 3, 3] if legend else [3, 2]),
            column_shares=list(shares),
        ),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed", timeline=timeline),
    )


def maze_views(name: str, heat_name: str, height: int, width: int, maze: Bounds):
    """The grid's views: the maze (titled with the recording's ``name``; ``maze``: its bounds) over
    the heat map (``heat_name``) and the return."""
    heat = _view2d(
        ((0, width), (0, height + 0.8)),
        origin="/",
        name=heat_name,
        contents=["/derived/**", "/q_values/**", "/maze/obstacles", "/maze/robot"],
    )
    return rrb.Vertical(
        _view2d(maze, origin="maze", name=f"maze: {name}"),
        rrb.Horizontal(heat, rrb.TimeSeriesView(origin="metrics", name="return")),
        row_shares=[3, 2],
    )


def _view2d(bounds: Bounds, **kw):
    return rrb.Spatial2DView(
        visual_bounds=rrb.VisualBounds2D(x_range=bounds[0], y_range=bounds[1]), **kw
    )


def note(at, text: str, **kw):
    """``text`` at the 2D point ``at``, on a dot too small to see (``kw``: more of its fields)."""
    return rr.Points2D([at], radii=0.01, labels=[text], show_labels=True, **kw)


def categories_context(names: Sequence[str]):
    """Class id ``c`` -> category name and colour, for every entity (obstacles, legend, grid rows)."""
    return rr.AnnotationContext(
        [rr.AnnotationInfo(id=c, label=name, color=colour(c)) for c, name in enumerate(names)]
    )


def heat_rgb(values: np.ndarray, log: bool = False) -> tuple[np.ndarray, float, float]:
    """``values`` (rows x cols) as a viridis RGB image scaled from their minimum to their maximum
    (``log``: of log(1 + value), for counts); returns the image, the minimum and the maximum."""
    v = np.asarray(values, np.float64)
    lo, hi = float(v.min()), float(v.max())
    if not hi > lo:  # one value everywhere: all dark
        scaled = v * 0
    elif log:
        scaled = np.log1p(v - lo) / np.log1p(hi - lo)
    else:
        scaled = (v - lo) / (hi - lo)
    x = np.linspace(0.0, 1.0, len(RAMP))
    rgb = np.stack([np.interp(scaled, x, RAMP[:, i]) for i in range(3)], axis=-1)
    return np.round(rgb).astype(np.uint8), lo, hi


def picture_scale(png: bytes) -> float:
    """Scene units per pixel that make the picture 1 unit on its longer side."""
    from PIL import Image

    with Image.open(io.BytesIO(png)) as im:
        return 1.0 / max(im.size)


class SupportGrid:
    """The support set in one 2D view (origin ``support``): shot ``k`` of category ``c`` is the
    entity ``support/<c>/<k>``, placed at row ``c``, column ``k``; ``support/categories`` names the
    rows (left of them, in the category colours), ``support/substituted`` frames every picture
    substituted so far and says when, and ``support/note`` says when the file holds no support pictures."""

    def __init__(self, rec, names: Sequence[str], shots: int):
        self.rec, self.names, self.shots = rec, list(names), max(shots, 1)
        self.marks: dict[tuple[int, int], str] = {}

    def frame(self, has_pictures: bool) -> None:
        """The row names and, for a file without support pictures, the note (static)."""
        n = len(self.names)
        rows = rr.Points2D(
            [[-0.8, c * PITCH[1] + 0.35] for c in range(n)],
            radii=0.12,
            class_ids=np.arange(n),
            show_labels=True,
        )
        self.rec.log("support/categories", rows, static=True)
        if not has_pictures:  # the note: in the middle, over whatever substituted pictures come in
            middle = [self.shots * PITCH[0] / 2, n * PITCH[1] / 2]
            text = "this file holds no support pictures:\nthe grid shows substituted ones only"
            self.rec.log("support/note", note(middle, text, colors=[[90, 90, 90]]), static=True)

    def bounds(self) -> Bounds:
        """What the view shows: the grid and the row names left of it."""
        return (-1.6, self.shots * PITCH[0]), (-0.1, len(self.names) * PITCH[1])

    def put(self, category: int, position: int, png: bytes, mark: str | None = None) -> None:
        """Show ``png`` as shot ``position`` of ``category``; ``mark``: when it was substituted."""
        entity, at = f"support/{category}/{position}", [position * PITCH[0], category * PITCH[1], 0]
        self.rec.log(entity, rr.Transform3D(translation=at, scale=picture_scale(png)))
        self.rec.log(entity, rr.EncodedImage(contents=png, media_type="image/png"))
        if mark is not None:
            self.marks[(category, position)] = mark
            self.log_marks()

    def log_marks(self) -> None:
        """Frame the substituted pictures, each labelled with when it came in."""
        cells = sorted(self.marks)
        self.rec.log(
            "support/substituted",
            rr.Boxes2D(
                mins=[[p * PITCH[0] - 0.04, c * PITCH[1] - 0.04] for c, p in cells],
                sizes=[[1.08, 1.08]] * len(cells),
                colors=[MARK] * len(cells),
                radii=0.04,
                labels=[self.marks[k] for k in cells],
                show_labels=True,
                draw_order=20.0,
            ),
        )
