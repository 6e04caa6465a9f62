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

from dataclasses import dataclass, fields, replace
from pathlib import Path

import yaml

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


def load_method(path: str | Path) -> MethodSpec:
    """A method spec from a YAML file of MethodSpec fields (``conf/method/<name>.yaml``)."""
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, yaml.YAMLError) as exc:
        raise ValueError(f"{path}: cannot read method config ({exc})") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: a method config is a mapping of MethodSpec fields")
    unknown = set(data) - {f.name for f in fields(MethodSpec)}
    if unknown:
        raise ValueError(f"{path}: unknown method fields {sorted(unknown)}")
    return MethodSpec(**data)


#: The methods of the paper, one YAML file each in ``conf/method/`` (the single source: Hydra
#: composes the same files, and DVC stages depend on exactly the files they use).
METHOD_DIR = Path(__file__).resolve().parents[2] / "conf" / "method"
METHODS: dict[str, MethodSpec] = {p.stem: load_method(p) for p in sorted(METHOD_DIR.glob("*.yaml"))}


def get_method(name: str, **overrides) -> MethodSpec:
    if name not in METHODS:
        raise ValueError(f"method={name!r}: unknown method; expected one of {', '.join(METHODS)}")
    return METHODS[name].with_overrides(**overrides) if overrides else METHODS[name]
