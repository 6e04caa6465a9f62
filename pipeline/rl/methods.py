"""The methods compared in the paper (sections 4.2.2 and Table 3), as data.

=============  ========  ==========================================  =========  ===========
method         learner   safety (how A_d grows)                      recovery   constrained
=============  ========  ==========================================  =========  ===========
qlearning      Q         none                                        no         no
sarsa          Sarsa     none                                        no         no
shield         Q         online shield: a collision adds (s, a)      yes        no
ssrl           Q         SSRL: a collision with o adds every          yes        no
                         (free neighbour of o, action toward o)
constrained    Q         none; episode ends at the first violation,   no         yes
                         epsilon -= 0.03 per violation (min 0.01)
fewshot        Q         Algorithm 1: recognition adds (s, a), a     yes        no
                         misrecognition collides and adds (s, a)
fewshot_dss    Q         as fewshot, and each misrecognised picture   yes        no
                         substitutes into the dynamic support set
=============  ========  ==========================================  =========  ===========

``recovery`` is configurable for every method (DESIGN.md): with it a collision reverts the robot
to the previous safe state and the episode goes on; without it the collision ends the episode.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

LEARNERS = {"q": 0, "sarsa": 1}
SAFETY = {"none": 0, "shield": 1, "ssrl": 2, "fewshot": 3}


@dataclass(frozen=True)
class MethodSpec:
    name: str
    learner: str = "q"
    safety: str = "none"
    recovery: bool = False
    constrained: bool = False
    epsilon: float = 0.1
    gamma: float = 0.9
    alpha: float = 0.01
    max_steps: int = 200
    epsilon_decay: float = 0.03
    epsilon_min: float = 0.01
    dynamic_support: bool = False

    def __post_init__(self) -> None:
        if self.learner not in LEARNERS:
            raise ValueError(f"method.learner={self.learner!r}: expected one of {sorted(LEARNERS)}")
        if self.safety not in SAFETY:
            raise ValueError(f"method.safety={self.safety!r}: expected one of {sorted(SAFETY)}")
        for key in ("epsilon", "gamma", "alpha", "epsilon_decay", "epsilon_min"):
            value = getattr(self, key)
            if not 0.0 <= value <= 1.0:
                raise ValueError(f"method.{key}={value}: must lie in [0, 1]")
        if self.max_steps < 1:
            raise ValueError(f"method.max_steps={self.max_steps}: must be >= 1")

    @property
    def uses_recogniser(self) -> bool:
        return self.safety == "fewshot"

    def with_overrides(self, **kw) -> "MethodSpec":
        return replace(self, **kw)


METHODS: dict[str, MethodSpec] = {
    "qlearning": MethodSpec("qlearning"),
    "sarsa": MethodSpec("sarsa", learner="sarsa"),
    "shield": MethodSpec("shield", safety="shield", recovery=True),
    "ssrl": MethodSpec("ssrl", safety="ssrl", recovery=True),
    "constrained": MethodSpec("constrained", constrained=True),
    "fewshot": MethodSpec("fewshot", safety="fewshot", recovery=True),
    "fewshot_dss": MethodSpec("fewshot_dss", safety="fewshot", recovery=True, dynamic_support=True),
}


def get_method(name: str, **overrides) -> MethodSpec:
    if name not in METHODS:
        raise ValueError(f"method={name!r}: unknown method; expected one of {', '.join(METHODS)}")
    return METHODS[name].with_overrides(**overrides) if overrides else METHODS[name]
