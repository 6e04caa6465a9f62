"""Build a recogniser from its config group (``conf/recogniser/<name>.yaml``) through ``_target_``.

A recogniser is any callable returning an object of the ``pipeline.rl.recogniser.Recogniser``
protocol whose keyword arguments include ``substitution_way`` and ``carry_over`` (the trial stage
fills those from the cell). The callable's signature is its schema: the yaml's other keys must be
its parameters, with values of their annotated types. Adding a recogniser: its module, its yaml
and a test; the lists of recognisers (in messages, in tests) come from ``conf/recogniser/``.
"""

from __future__ import annotations

import dataclasses
import inspect
import typing
from collections.abc import Callable
from pathlib import Path
from typing import Any

from omegaconf import OmegaConf
from omegaconf.errors import OmegaConfBaseException

from pipeline.config.fields import refuse
from pipeline.config.folder import conf_dir
from pipeline.errors import UserError
from pipeline.kernels import pin_kernels

FILLED_BY_STAGE = ("substitution_way", "carry_over")

#: ``conf/recogniser/<name>.yaml``: one file per recogniser, the group ``recogniser=<name>`` chooses.
RECOGNISER_DIR = conf_dir("recogniser")


def recogniser_names() -> list[str]:
    """The recognisers of ``conf/recogniser/``, sorted."""
    return sorted(p.stem for p in RECOGNISER_DIR.glob("*.yaml"))


def recognisers_taking(parameter: str) -> list[str]:
    """The recognisers (of :func:`recogniser_names`) whose ``_target_`` takes ``parameter``."""
    out = []
    for name in recogniser_names():
        node = OmegaConf.to_container(OmegaConf.load(RECOGNISER_DIR / f"{name}.yaml"))
        if parameter in inspect.signature(recogniser_target(node, f"recogniser {name}")).parameters:
            out.append(name)
    return out


def _config_type(hint: Any) -> Any:
    """The annotation as OmegaConf can check it: int, float, bool, str (paths too), else Any."""
    if hint in (int, float, bool, str):
        return hint
    args = set(typing.get_args(hint))
    if args and args <= {str, Path, type(None)}:
        return str
    return Any


def declared_targets() -> dict[str, str]:
    """The ``_target_`` of every recogniser of ``conf/recogniser/``, with its name: the
    only code a config may name."""
    out = {}
    for name in recogniser_names():
        node = OmegaConf.load(RECOGNISER_DIR / f"{name}.yaml")
        out[str(node.get("_target_"))] = name
    return out


def recogniser_target(node: dict, key: str) -> Callable:
    """The recogniser ``node`` names. A config (a file, an experiment, an override, a DVC params
    file) names code only through ``_target_``, and only one a recogniser of
    ``conf/recogniser/`` declares: anything else is refused before it is imported."""
    target = node.get("_target_")
    choose = f"choose a recogniser: {key}={'|'.join(recogniser_names())}"
    if not target:
        refuse(f"{key}._target_", f"missing; {choose}")
    if str(target) not in declared_targets():
        refuse(
            f"{key}._target_",
            f"{str(target)!r} is not a recogniser of "
            f"conf/recogniser/ (a config may name no other code); {choose}",
        )
    from hydra.utils import get_method  # Hydra (slow to import) only when a recogniser is built

    try:
        return get_method(str(target))
    except Exception as exc:  # hydra raises ImportError/ValueError/InstantiationException variants
        refuse(f"{key}._target_", f"cannot import {target!r} ({str(exc).splitlines()[0]})")


def recogniser_arguments(node: dict, key: str = "recogniser") -> tuple[Callable, dict[str, Any]]:
    """The target and its checked arguments (without the ones the stage fills)."""
    target = recogniser_target(node, key)
    sig = inspect.signature(target)
    hints = typing.get_type_hints(target.__init__ if inspect.isclass(target) else target)
    params = {
        n: p
        for n, p in sig.parameters.items()
        if n not in FILLED_BY_STAGE
        and n != "self"
        and p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)
    }
    spec = [
        (
            n,
            _config_type(hints.get(n, Any)),
            dataclasses.field(default=p.default)
            if p.default is not p.empty
            else dataclasses.field(default="???"),
        )
        for n, p in params.items()
    ]
    schema = dataclasses.make_dataclass("RecogniserArgs", spec)
    given = {k: v for k, v in node.items() if k != "_target_"}
    try:
        merged = OmegaConf.merge(OmegaConf.structured(schema), given)
        args = OmegaConf.to_container(merged, resolve=True, throw_on_missing=True)
    except OmegaConfBaseException as exc:
        where = getattr(exc, "full_key", "") or ""
        refuse(
            f"{key}.{where}",
            f"{str(exc).splitlines()[0]} (parameters of {node['_target_']}: {', '.join(params)})",
        )
    return target, args


def build_recogniser(
    node: dict, *, substitution_way: int, carry_over: bool, key: str = "recogniser"
):
    target, args = recogniser_arguments(node, key)
    pin_kernels()  # before the recogniser runs its first torch kernel (pipeline/kernels.py)
    try:
        return target(**args, substitution_way=substitution_way, carry_over=carry_over)
    except (UserError, ValueError, FileNotFoundError) as exc:
        refuse(key, str(exc))
