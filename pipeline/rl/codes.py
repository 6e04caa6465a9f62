"""Named codes shared by the method specs, the step rules, the numba kernel and the Gymnasium env.

Member names are the strings a config uses (``method.safety=ssrl``); the values are what the
kernel sees. numba compiles IntEnum members as integer constants, so nothing here costs speed.
"""
from __future__ import annotations

from enum import IntEnum


class Learner(IntEnum):
    """The tabular learner's update (paper eqs. 6 and 9)."""

    q = 0       #: Q-learning: bootstrap from the best allowed action (eq. 9)
    sarsa = 1   #: Sarsa: bootstrap from the action actually chosen next


class Safety(IntEnum):
    """How a method's unsafe set A_d grows (paper section 3.2.2 and the baselines of 4.2.2)."""

    none = 0     #: no safety layer (Q-learning, Sarsa, constrained RL)
    shield = 1   #: online shield: a collision from (s, a) adds (s, a)
    ssrl = 2     #: SSRL: a collision with o adds every (free neighbour of o, action toward o)
    fewshot = 3  #: Algorithm 1: a recognised obstacle adds (s, a); a misrecognition collides and adds it
