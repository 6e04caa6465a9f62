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

``recovery`` is configurable for every method (on by default for the shield, SSRL and few-shot
reasoning; README "Where we differ from the paper", Collisions): with it a collision reverts the
robot to the previous safe state and the episode goes on; without it the collision ends the episode.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from functools import cache
from pathlib import Path
from typing import Any

from omegaconf import OmegaConf
from omegaconf.errors import OmegaConfBaseException

from pipeline.config.fields import check, refuse, setting
from pipeline.config.folder import conf_dir
from pipeline.rl.codes import Learner
from pipeline.rl.rules import METHODS, Method, Safety, reasons_with_pictures

#: ``conf/method/<name>.yaml``: each file holds only what differs from :class:`MethodSpec`'s defaults.
METHOD_DIR: Path = conf_dir("method")


@dataclass
class MethodSpec:
    """One method of the comparison; the defaults are the base method (tabular Q-learning with the
    paper's hyperparameters, section 4.1), and ``conf/method/<name>.yaml`` states what differs.
    This dataclass is also the Hydra schema of the ``method`` config group."""

    name: str = setting("qlearning", nonempty=True)
    """The method's name (its file in ``conf/method/``), carried into the records."""
    learner: str = setting(Learner.q.name, choices=[m.name for m in Learner])
    """``q`` (Q-learning, eq. 9) or ``sarsa``."""
    safety: str = setting(Safety.none.name, choices=[m.name for m in Safety])
    """How A_d grows (``pipeline.rl.rules.Safety`` and its rule there)."""
    recovery: bool = False
    """Self-recovery: a collision reverts the robot to the previous safe state and the episode goes on."""
    constrained: bool = False
    """Constrained RL (section 4.2.2): the episode ends at the first violation; epsilon decays per violation."""
    epsilon: float = setting(0.1, ge=0.0, le=1.0)
    """Exploration rate of the epsilon-greedy choice (eq. 7)."""
    gamma: float = setting(0.9, ge=0.0, le=1.0)
    """Discount factor."""
    alpha: float = setting(0.01, ge=0.0, le=1.0)
    """Learning rate of the TD update."""
    max_steps: int = setting(200, ge=1)
    """Steps after which an episode is cut."""
    epsilon_decay: float = setting(0.03, ge=0.0, le=1.0)
    """Constrained RL: epsilon drops by this much per violation ..."""
    epsilon_min: float = setting(0.01, ge=0.0, le=1.0)
    """... down to this floor."""
    dynamic_support: bool = False
    """Few-shot methods: each misrecognised picture substitutes into the support set (section 3.3)."""

    @property
    def uses_recogniser(self) -> bool:
        """Whether its safety rule looks at pictures (``pipeline.rl.rules.reasons_with_pictures``,
        its Python function: asked thousands of times while cells are planned, where numba's
        dispatch would cost more than the answer)."""
        rule = getattr(reasons_with_pictures, "py_func", reasons_with_pictures)  # NUMBA_DISABLE_JIT
        return bool(rule(Safety[self.safety]))

    def with_overrides(self, **kw) -> MethodSpec:
        return check_method(replace(self, **kw))

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def check_method(spec: MethodSpec, key: str = "method") -> MethodSpec:
    check(spec, key + ".")
    return spec


def method_names() -> list[str]:
    """The methods of ``conf/method/``, sorted."""
    return sorted(p.stem for p in METHOD_DIR.glob("*.yaml"))


#: The fields that make a method what it is (its display name says them); the others
#: (``alpha``, ``recovery``, ...) are settings a cell may change.
IDENTITY = ("learner", "safety", "constrained", "dynamic_support")


@cache
def declared_fields() -> dict[str, dict[str, Any]]:
    """The fields of every declared method (:data:`pipeline.rl.rules.METHODS`) that has a file
    in ``conf/method/``, by name, in the declared order."""
    return {m.name: load_method(m.name).as_dict() for m in METHODS if m.name in method_names()}


def declaration(method: dict[str, Any]) -> Method | None:
    """The declaration (:data:`pipeline.rl.rules.METHODS`) of a method as recorded (its
    ``MethodSpec`` fields), found by its ``name``; when its :data:`IDENTITY` fields are not that
    method's but another declared method's, that one (``method=qlearning method.learner=sarsa``
    ran Sarsa). None for a name nothing declares: the caller shows the recorded name."""
    fields = declared_fields()
    own = next((m for m in METHODS if m.name == method.get("name") and m.name in fields), None)
    if own is None:
        return None

    def same(name: str) -> bool:
        return all(method.get(k) == fields[name][k] for k in IDENTITY)

    if same(own.name):
        return own
    return next((m for m in METHODS if m.name in fields and same(m.name)), own)


def load_method(
    name: str, overrides: dict[str, Any] | None = None, key: str = "method"
) -> MethodSpec:
    """``conf/method/<name>.yaml`` merged onto the base method, then ``overrides`` (field -> value),
    type- and range-checked by the schema; errors name ``key``."""
    path = METHOD_DIR / f"{name}.yaml"
    if not path.is_file():
        refuse(key, f"unknown method {name!r}; expected one of {', '.join(method_names())}")
    try:
        node = OmegaConf.merge(OmegaConf.structured(MethodSpec), OmegaConf.load(path))
        for field, value in (overrides or {}).items():
            OmegaConf.update(node, field, value, merge=True)
        spec = OmegaConf.to_object(node)
    except OmegaConfBaseException as exc:
        refuse(f"{key}.{getattr(exc, 'full_key', '') or ''}", f"{str(exc).splitlines()[0]}")
    return check_method(spec, key)


def get_method(name: str, **overrides) -> MethodSpec:
    """A method by name, with field overrides (``get_method("ssrl", alpha=0.1)``)."""
    return load_method(name, overrides)
