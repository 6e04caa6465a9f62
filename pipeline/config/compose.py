"""A stage's config, composed and checked: ``conf/<stage>.yaml`` with the command line's overrides,
as the stage's typed schema (:mod:`pipeline.config.registry`), every range checked.

:func:`load_config` composes with Hydra's compose API, converts the result to the schema's
dataclasses and checks every range (:func:`pipeline.config.fields.check`). Whatever is wrong raises
:class:`~pipeline.errors.ConfigError` in one line naming the key: a bad override, a deleted or
emptied key, a key below a null one, a value out of range. A sweep (``a=1,2 b=x,y``) is checked
point by point (:func:`sweep_points`) before any of its jobs runs. Running a stage on that config
is :mod:`pipeline.stages`'s part.
"""

from __future__ import annotations

import dataclasses
import re
from typing import Any

from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from pipeline.config.fields import check, refuse
from pipeline.config.folder import conf_dir, hydra_configs
from pipeline.errors import ConfigError

#: The config folder shipped in the package (``conf``), as a file-system path.
CONF_DIR = str(conf_dir())


def dotted(key: str) -> str:
    """OmegaConf's ``sizes[0].count`` as the command line spells it: ``sizes.0.count``."""
    return re.sub(r"\[(\d+)\]", r".\1", key)


def one_line(exc: BaseException) -> str:
    """Hydra's and OmegaConf's multi-line messages folded into one line naming the key."""
    cause = exc
    while cause.__cause__ is not None and not isinstance(cause, OmegaConfBaseException):
        cause = cause.__cause__
    message = str(cause).split("Config search path")[
        0
    ]  # hydra's missing-option message lists its search path
    text = " ".join(
        line.strip()
        for line in message.splitlines()
        if line.strip()
        and not line.strip().startswith(("full_key:", "object_type=", "reference_type="))
    )
    key = getattr(cause, "full_key", None)
    if isinstance(cause, OmegaConfBaseException) and key:
        return f"config key '{dotted(key)}': {text}"
    named = [ln.split(":", 1)[1].strip() for ln in message.splitlines() if "full_key:" in ln]
    if named and named[0]:  # hydra's composition error quotes the key of the value it refused
        return f"config key '{dotted(named[0])}': {text}"
    if cause is not exc and str(exc).strip():
        head = str(exc).strip().splitlines()[0]
        if head not in text:
            text = f"{head} ({text})"
    return text


def typed(cfg: DictConfig) -> Any:
    """The composed config as its schema's dataclass objects, with every range checked."""
    try:
        obj = OmegaConf.to_object(cfg)
    except OmegaConfBaseException as exc:
        raise ConfigError(one_line(exc)) from None
    except ValueError as exc:  # a dataclass's __post_init__ (cross-field checks)
        raise ConfigError(f"config: {exc}") from None
    check(obj)
    return obj


def compose(config_name: str, overrides: list[str]) -> DictConfig:
    """``conf/<config_name>.yaml`` with ``overrides``; a bad override raises :class:`ConfigError`."""
    from hydra import compose as hydra_compose
    from hydra.errors import HydraException

    from pipeline.config.registry import register

    refuse_deleted(config_name, overrides)
    register(config_name)
    try:
        with hydra_configs():
            cfg = hydra_compose(config_name=config_name, overrides=overrides)
    except (HydraException, OmegaConfBaseException, ValueError) as exc:
        raise ConfigError(null_group(overrides) or one_line(exc)) from None
    except AssertionError:  # OmegaConf's update below a null key (experiment.name=x alone)
        raise ConfigError(below_null(config_name, overrides)) from None
    refuse_merged_away(cfg, overrides)
    return cfg


def groups() -> list[str]:
    """The config groups (``method``, ``experiment``...): the folders of ``conf``."""
    return sorted(p.name for p in conf_dir().iterdir() if p.is_dir() and any(p.glob("*.yaml")))


def options(group: str) -> str:
    return ", ".join(sorted(p.stem for p in conf_dir(group).glob("*.yaml")))


def override_key(override: str) -> str:
    return override.lstrip("+~").partition("=")[0].strip()


def refuse_deleted(config_name: str, overrides: list[str]) -> None:
    """``~key`` of a key the stage's schema declares is refused: the key would silently take the
    dataclass's default, or the placeholder ``???`` (``~out`` wrote to a folder named ``???``)."""
    from pipeline.config.registry import schema_of

    declared = {f.name for f in dataclasses.fields(schema_of(config_name))}
    for override in overrides:
        key = override_key(override)
        if override.startswith("~") and key.split(".")[0] in declared:
            refuse(
                key,
                f"cannot be deleted ({override}); every key of the "
                f"{config_name} config is needed: give it a value instead",
            )


def null_group(overrides: list[str]) -> str | None:
    """The message for ``<group>=null`` (Hydra's names no group), or None."""
    for override in overrides:
        key, _, value = override.lstrip("+").partition("=")
        if key.strip() in groups() and value.strip().lower() == "null":
            return (
                f"config key '{key.strip()}': null chooses no {key.strip()}; name one of "
                f"{options(key.strip())}"
            )
    return None


def below_null(config_name: str, overrides: list[str]) -> str:
    """The message for an override of a key below a null one (``experiment.name=x`` without
    ``+experiment=<name>``, where OmegaConf fails an assertion): the first such override, found by
    composing the value overrides one more at a time (only on this error path)."""
    from hydra import compose as hydra_compose

    chosen = [o for o in overrides if override_key(o) in groups() or o.startswith("hydra")]
    values = [o for o in overrides if o not in chosen]
    previous = None
    for i in range(len(values) + 1):
        try:
            with hydra_configs():
                cfg = hydra_compose(config_name=config_name, overrides=chosen + values[:i])
        except AssertionError:
            key = override_key(values[i - 1])
            parts = key.split(".")
            for j in range(1, len(parts)):
                parent = ".".join(parts[:j])
                if OmegaConf.select(previous, parent, default=0) is None:
                    hint = (
                        f"choose one first: +{parent}=<name> ({options(parent)})"
                        if parent in groups()
                        else f"set {parent} itself first, or leave {key} out"
                    )
                    rest = ".".join(parts[j:])
                    return f"config key '{key}': {parent} is null (not set), so it has no {rest}; {hint}"
            break
        except Exception:  # another override's error: the full compose would have raised it
            break
        previous = cfg
    return "config: an override sets a key below one that is null (not set): " + " ".join(values)


def refuse_merged_away(cfg: DictConfig, overrides: list[str]) -> None:
    """``key={}`` merges an empty mapping into the one there, which leaves it as it was: refused,
    naming the key, rather than ignored."""
    for override in overrides:
        key, _, value = override.lstrip("+~").partition("=")
        if value.strip() != "{}" or key.startswith("hydra"):
            continue
        kept = OmegaConf.select(cfg, key, default=None)
        if isinstance(kept, DictConfig) and len(kept) > 0:
            refuse(
                key,
                f"{{}} does not empty it (a mapping given here is merged into "
                f"the one there, {', '.join(map(str, list(kept)[:3]))}...); name what to keep, or "
                "edit the file",
            )


def load_config(stage: str, overrides: list[str] = ()) -> Any:
    """``conf/<stage>.yaml`` with ``overrides``, as the stage's typed config (checked)."""
    return typed(compose(stage, list(overrides)))


def parsed_overrides(overrides: list[str]) -> list[Any]:
    """Hydra's parsed ``overrides``; one it cannot parse raises :class:`ConfigError`."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    try:
        return OverridesParser.create().parse_overrides(list(overrides))
    except Exception as exc:  # hydra's OverrideParseException
        raise ConfigError(one_line(exc)) from None


def sweep_points(args: list[str]) -> list[list[str]]:
    """Override lists that together try every value of every swept key (``a=1,2 b=x,y`` gives
    ``[a=1 b=x], [a=2 b=x], [a=1 b=y]``): a linear number of checks, not the whole grid."""
    from hydra.core.override_parser.types import OverrideType

    parsed = parsed_overrides([a for a in args if not a.startswith("-")])
    prefix = {OverrideType.ADD: "+", OverrideType.FORCE_ADD: "++"}
    fixed, swept = [], []
    for o in parsed:
        if o.key_or_group.startswith("hydra"):
            continue
        if o.is_sweep_override():
            swept.append(
                (f"{prefix.get(o.type, '')}{o.key_or_group}", list(o.sweep_string_iterator()))
            )
        else:
            fixed.append(o.input_line)
    first = [f"{k}={values[0]}" for k, values in swept]
    points = [fixed + first]
    for i, (key, values) in enumerate(swept):
        for v in values[1:]:
            points.append(fixed + first[:i] + [f"{key}={v}"] + first[i + 1 :])
    return points
