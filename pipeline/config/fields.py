"""The config schema's mechanism: a key's type, range, choices and description, each declared once,
on its dataclass field.

Every config is a dataclass: a stage's (``pipeline/schemas/``) or a config group's, beside
the science it configures (``MethodSpec``, ``TrainConfig``, ``StudyConfig``, ``ReportSpec``). A field
declares its key: the annotation is the type, :func:`setting` adds a range (``ge``/``gt``/``le``/``lt``),
``choices``, ``nonempty`` or ``path`` (a file or folder: a name the file system can hold) as metadata, and the string literal under the field (an attribute
docstring, read by :func:`field_docs`) is its description. From these alone, Hydra's structured
configs refuse wrong types and unknown keys, :func:`check` refuses values out of range and
:func:`constraint` and :func:`field_docs` give ``python -m pipeline <stage> --help`` its text.
What the fields cannot say (a folder that must exist, two keys that exclude each other) a stage or
a science module refuses with :func:`refuse`, so every refusal is raised here, in one form naming
the key. This module sits below the science packages, so they declare their fields with it.
"""

from __future__ import annotations

import ast
import dataclasses
import functools
import inspect
import math
import os
import textwrap
import types
import typing
from collections.abc import Iterable, Mapping, Sequence
from typing import Any, NoReturn

from omegaconf import MISSING

from pipeline.errors import ConfigError


def same_key(cls: type, name: str, default: Any = MISSING):
    """A field that is the key ``name`` of ``cls`` under another name or with another ``default``
    (a stage key whose default is a profile key): its range, choices and words (:func:`field_docs`)
    are that key's, declared once."""
    (source,) = [f for f in dataclasses.fields(cls) if f.name == name]
    words = {"doc": field_docs(cls).get(name, "")}
    return dataclasses.field(default=default, metadata={**source.metadata, **words})


def refusal(key: str | Sequence[str], problem: str) -> ConfigError:
    """The refusal of a config value: ``config key '<key>': <problem>``, or ``config keys
    'a'/'b': <problem>`` for a problem of several keys together. Every refusal of the package
    takes this form, whether the schema, a stage or a science module finds the problem."""
    if isinstance(key, str):
        return ConfigError(f"config key '{key}': {problem}")
    return ConfigError(f"config keys {'/'.join(f'{k!r}' for k in key)}: {problem}")


def refuse(key: str | Sequence[str], problem: str) -> NoReturn:
    """Raise :func:`refusal`; called while handling another error, it hides that error, whose
    point the problem states."""
    raise refusal(key, problem) from None


def refuse_argument(name: str, value: Any, problem: str) -> NoReturn:
    """Refuse a keyword argument that no config file names (``gymnasium.make(id, name=value)``):
    :class:`ConfigError` ``<name>=<value>: <problem>``."""
    raise ConfigError(f"{name}={value!r}: {problem}")


def setting(
    default: Any = MISSING,
    *,
    ge: float | None = None,
    gt: float | None = None,
    le: float | None = None,
    lt: float | None = None,
    choices: Iterable[Any] | None = None,
    nonempty: bool = False,
    path: bool = False,
    default_factory: Any = None,
):
    """A dataclass field with a range (``ge``/``gt``/``le``/``lt``), a set of ``choices``,
    ``nonempty`` (strings) or ``path`` (a file or folder, :func:`path_problem`), checked by
    :func:`check`."""
    flags = {"nonempty": nonempty or None, "path": path or None}
    meta = {
        k: v for k, v in {"ge": ge, "gt": gt, "le": le, "lt": lt, **flags}.items() if v is not None
    }
    if choices is not None:
        meta["choices"] = tuple(choices)
    if default_factory is not None:
        return dataclasses.field(default_factory=default_factory, metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def problem(value: Any, meta: Mapping[str, Any]) -> str | None:
    """What is wrong with ``value`` under a field's metadata (``must be >= 1; got 0``), or None."""
    if value is None:
        return None
    if "choices" in meta and value not in meta["choices"]:
        return f"must be one of {', '.join(map(str, meta['choices']))}; got {value!r}"
    if meta.get("nonempty") and not str(value).strip():
        return "must not be empty"
    if meta.get("path") and (wrong := path_problem(str(value))):
        return wrong
    for key, ok, word in (
        ("ge", lambda v, b: v >= b, ">="),
        ("gt", lambda v, b: v > b, ">"),
        ("le", lambda v, b: v <= b, "<="),
        ("lt", lambda v, b: v < b, "<"),
    ):
        if key in meta and not ok(value, meta[key]):
            return f"must be {word} {meta[key]}; got {value!r}"
    return None


def _existing(path: str) -> str:
    """The nearest folder of ``path`` (itself or a parent) that exists."""
    folder = os.path.abspath(path)
    while not os.path.isdir(folder) and os.path.dirname(folder) != folder:
        folder = os.path.dirname(folder)
    return folder


def _limit(folder: str, name: str, default: int) -> int:
    try:
        return os.pathconf(folder, name)
    except (OSError, ValueError):
        return default


def path_problem(path: str) -> str | None:
    """What keeps the file system from holding ``path``: a file or folder name longer than its
    limit (``PC_NAME_MAX`` of the nearest existing folder, 255 bytes on most), or the whole path
    longer than ``PC_PATH_MAX``; or None."""
    folder = _existing(path)
    longest = max(os.fsencode(path).split(b"/"), key=len)
    name_max = _limit(folder, "PC_NAME_MAX", 255)
    if len(longest) > name_max:
        shown = os.fsdecode(longest[:24]) + "..."
        return (
            f"the name {shown!r} is {len(longest)} bytes long; the file system of {folder} allows "
            f"{name_max}: choose a shorter name"
        )
    whole = len(os.fsencode(os.path.abspath(path)))
    path_max = _limit(folder, "PC_PATH_MAX", 4096)
    if whole >= path_max:
        return f"the path is {whole} bytes long; the file system allows {path_max - 1}: choose a shorter one"
    return None


def check(obj: Any, prefix: str = "") -> None:
    """Raise :class:`ConfigError` naming the first value of ``obj`` (recursively) that breaks its
    field's constraints."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        known = {f.name for f in dataclasses.fields(obj)}
        extra = sorted(
            k for k in vars(obj) if k not in known
        )  # added with '+key=' past Hydra's struct mode
        if extra:
            refuse(f"{prefix}{extra[0]}", f"unknown key; known: {', '.join(sorted(known))}")
        hints = _hints(type(obj))
        for f in dataclasses.fields(obj):
            value = getattr(obj, f.name)
            key = f"{prefix}{f.name}"
            wrong = problem(value, f.metadata) or element_problem(value, hints.get(f.name))
            if wrong:
                refuse(key, wrong)
            check(value, key + ".")
    elif isinstance(obj, float) and not math.isfinite(obj):
        refuse(prefix.rstrip("."), f"must be a finite number; got {obj}")
    elif isinstance(obj, dict):
        for k, v in obj.items():
            check(v, f"{prefix}{k}.")
    elif isinstance(obj, (list, tuple)):
        for i, v in enumerate(obj):
            check(v, f"{prefix}{i}.")


@functools.cache
def _hints(cls: type) -> dict[str, Any]:
    try:
        return typing.get_type_hints(cls)
    except (NameError, TypeError):  # a dataclass made at run time with unresolvable hints
        return {}


def element_problem(value: Any, hint: Any) -> str | None:
    """What is wrong with the elements of a list typed ``list[str]`` (or ``tuple[str, ...]``,
    optional or not) whose elements are not strings (``categories=[[1]]``), or None."""
    if not isinstance(value, (list, tuple)):
        return None
    optional = typing.get_origin(hint) in (typing.Union, types.UnionType)
    kinds = [a for a in typing.get_args(hint) if a is not type(None)] if optional else [hint]
    for kind in kinds:
        if typing.get_origin(kind) in (list, tuple) and typing.get_args(kind)[:1] == (str,):
            bad = next((v for v in value if not isinstance(v, str)), None)
            if bad is not None:
                return f"must be a list of words; got {bad!r} in {list(value)!r}"
    return None


def constraint(f: dataclasses.Field) -> str:
    """A field's range or choices in words (``>= 1``, ``> 0, < 180``, ``one of a, b``), or ``""``."""
    meta = f.metadata
    words = [
        f"{word} {meta[key]}"
        for key, word in (("ge", ">="), ("gt", ">"), ("le", "<="), ("lt", "<"))
        if key in meta
    ]
    if "choices" in meta:
        words.append("one of " + ", ".join(map(str, meta["choices"])))
    if meta.get("nonempty"):
        words.append("not empty")
    return ", ".join(words)


@functools.cache
def field_docs(cls: type) -> dict[str, str]:
    """Field name -> its description: the string literal right under the field in ``cls``'s source
    (and its bases'), whitespace folded into one line; a field made by :func:`same_key`, the words
    of the key it is."""
    fields = dataclasses.fields(cls) if dataclasses.is_dataclass(cls) else ()
    docs = {f.name: f.metadata["doc"] for f in fields if "doc" in f.metadata}
    for klass in reversed(cls.__mro__[:-1]):
        try:
            source = textwrap.dedent(inspect.getsource(klass))
        except (OSError, TypeError):
            continue
        body = ast.parse(source).body[0].body
        for stmt, after in zip(body, body[1:]):
            if (
                isinstance(stmt, ast.AnnAssign)
                and isinstance(stmt.target, ast.Name)
                and isinstance(after, ast.Expr)
                and isinstance(after.value, ast.Constant)
                and isinstance(after.value.value, str)
            ):
                docs[stmt.target.id] = " ".join(after.value.value.split())
    return docs
