"""Named codes shared by the method specs, the step rules, the numba kernel, the runner and the
Gymnasium env: one IntEnum per family, so no integer code appears anywhere else.

Member names are the strings a config or a record uses (``method.safety=ssrl``, the records'
flag and source names); the values are what the kernel sees. numba compiles IntEnum members as
integer constants, so nothing here costs speed. (numba does not compile ``IntFlag``; the step
flags are an IntEnum of bits, combined with ``|`` into plain ints.)

Crossing from Python into numba, pass ``int(member)``: numba types an enum member argument far
more slowly than an int (tens of microseconds a call), which shows in the Gymnasium loop.
"""

from __future__ import annotations

from enum import IntEnum
from typing import TypeVar

E = TypeVar("E", bound=IntEnum)


class Learner(IntEnum):
    """The tabular learner's update (paper eqs. 6 and 9)."""

    q = 0  #: Q-learning: bootstrap from the best allowed action (eq. 9)
    sarsa = 1  #: Sarsa: bootstrap from the action actually chosen next


class Safety(IntEnum):
    """How a method's unsafe set A_d grows (paper section 3.2.2 and the baselines of 4.2.2).

    Each member's rule is a branch of ``rules.apply_action``; nothing else branches on these.
    Declared here, beside the other codes, so the method schema reads its names without numba.
    """

    none = 0  #: no safety layer (Q-learning, Sarsa, constrained RL)
    shield = 1  #: online shield: a collision from (s, a) adds (s, a)
    ssrl = 2  #: SSRL: a collision with o adds every (free neighbour of o, action toward o)
    fewshot = (
        3  #: Algorithm 1: a recognised obstacle adds (s, a); a misrecognition collides and adds it
    )


class Outcome(IntEnum):
    """What one chosen action did (``rules.apply_action``)."""

    moved = 0  #: the robot moved (or stayed put against the maze's border)
    collided = 1  #: it ran into an obstacle (reward -1)
    prevented = (
        2  #: the recogniser named the obstacle: not executed, reselect (Algorithm 1 lines 4-10)
    )


class Status(IntEnum):
    """Why ``kernel.advance_run`` handed a run back to the runner."""

    limit = 0  #: reached the requested episode limit (or finished all episodes)
    substitute = (
        1  #: a misrecognised picture waits for the support set's substitution (Algorithm 1 line 20)
    )
    flush = 2  #: the step trace is full: emit the finished episodes, then resume


class Source(IntEnum):
    """Why a pair (s, a) joined A_d: the ``source`` of the records' unsafe-set additions
    (same names and values as ``pipeline.records.schema.SOURCE_NAMES``; a test checks)."""

    recognition = 0  #: the recogniser named the obstacle ahead (few-shot)
    collision = 1  #: the robot collided from (s, a) (shield, SSRL, few-shot)
    ssrl_rule = 2  #: SSRL's rule: a free neighbour of the obstacle hit, action toward it


class StepFlag(IntEnum):
    """Bits of a step's ``flags`` in the records (same names and values as
    ``pipeline.records.schema.FLAG_NAMES``; a test checks)."""

    reselected = 1  #: the first choice was unsafe or prevented and the agent reselected
    collided = 2  #: the step ran into an obstacle
    recovered = 4  #: self-recovery reverted the robot to the previous safe state
    goal = 8  #: the step reached the goal
    truncated = 16  #: the episode hit its step limit (``max_steps``)


def member(enum: type[E], value: E | str) -> E:
    """``value`` as a member of ``enum``: a member passes through, a config string is looked up
    by name (``member(Safety, "ssrl") is Safety.ssrl``)."""
    if isinstance(value, enum):
        return value
    try:
        return enum[value]
    except KeyError:
        raise ValueError(f"{value!r}: expected one of {', '.join(enum.__members__)}") from None
