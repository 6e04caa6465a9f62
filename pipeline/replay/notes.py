"""What the replay says in words before it draws: why it cannot (:class:`ReplayError`), the episode
it opens on when none is asked for (:func:`first_recognition`), and for each view that would
otherwise say only "No data" the reason (:func:`empty_views`): the method recognises no pictures,
this episode holds no recognition (and which episodes do), or the recogniser records no scores.

Nothing here needs Rerun: ``import pipeline.replay`` (the stage's checks before any work) stays
light, and the drawing modules load with Rerun when a recording is drawn (:func:`.build.drawing_of`).
"""

from __future__ import annotations

from dataclasses import dataclass

from pipeline.errors import UserError
from pipeline.records import Records

#: Why a run holds no recognition.
NO_RECOGNITION = "the method recognises no pictures, or the robot never moved toward an obstacle"


class ReplayError(UserError):
    """The run/episode is not in the records, or they cannot be drawn; ``key`` is the config key to
    blame (``"file"`` for a record file that cannot be read or drawn)."""

    def __init__(self, message: str, key: str = "run/episode"):
        super().__init__(message)
        self.key = key


def episodes_with(frame, run: int) -> list[int]:
    """The episodes of ``run`` with a row in ``frame`` (recognitions, substitutions), in order."""
    if frame is None or frame.empty:
        return []
    return sorted({int(e) for e in frame.episode[frame.run == run]})


def shown(episodes: list[int], at_most: int = 8) -> str:
    """``0, 1, 4 (3 episodes)``; long lists cut after ``at_most`` with their count."""
    head = ", ".join(str(e) for e in episodes[:at_most])
    more = ", ..." if len(episodes) > at_most else ""
    return f"{head}{more} ({len(episodes)} episode{'s' * (len(episodes) != 1)})"


def first_recognition(recs: Records, run: int) -> tuple[int, str]:
    """The episode a replay of ``run`` opens on when no episode is given: the first with a
    recognition, else the first recorded; with a sentence saying which and why."""
    seen = episodes_with(recs.recognitions, run)
    if seen:
        why = f"the first of run {run} with a recognition; recognitions in episodes {shown(seen)}"
        return seen[0], why
    recorded = sorted(int(e) for e in recs.episodes.episode[recs.episodes.run == run])
    return recorded[
        0
    ], f"the first recorded of run {run}, which holds no recognition ({NO_RECOGNITION})"


@dataclass(frozen=True)
class EmptyViews:
    """The reason each recognition view is empty in the replayed episodes (None: it has data)."""

    recognition: str | None  # picture seen and recognition text
    scores: str | None  # relation scores bar chart

    @property
    def scores_short(self) -> str:
        """What the scores view's name says (a tab title: short): that the recognition view below
        says why, or that the recogniser records none."""
        return "none, see below" if self.scores == self.recognition else "none recorded"


def empty_views(recs: Records, run: int, episodes: list[int]) -> EmptyViews:
    """Why the picture, scores and recognition views of a replay of ``episodes`` of ``run`` show
    nothing, if they do (a whole run replay counts any of its episodes)."""
    seen = episodes_with(recs.recognitions, run)
    here = [e for e in seen if e in set(episodes)]
    if not seen:
        why = f"no recognition in run {run}: {NO_RECOGNITION}"
        return EmptyViews(why, why)
    if not here:
        why = (
            f"no recognition in episode {episodes[0]}; run {run} has them in episodes {shown(seen)}"
            f" (replay one with episode=<e>, or leave episode out for the first)"
        )
        return EmptyViews(why, why)
    scores = [c for c in recs.recognitions.columns if c.startswith("score_")]
    rows = recs.recognitions[recs.recognitions.run == run]
    if not scores or rows[scores].isna().all().all():
        return EmptyViews(None, "the recogniser records no scores (it names a category only)")
    return EmptyViews(None, None)
