"""``python -m pipeline <stage> --help``: the stage's config groups and keys, from the schema
(``--help-all``: every key, where ``--help`` shows the common ones).

Every line comes from a declaration, none is kept by hand: the stage's description from its
module's docstring (:func:`describe`), its groups and their default options from
``conf/<stage>.yaml``'s defaults list (and the schema's fields named like a folder of ``conf/``,
such as ``experiment``), each option's summary from its file's leading comment (or, where every
option shares that comment, from the keys it sets), and each key's type, range or choices and
description from its dataclass field (:mod:`pipeline.config.fields`). A key's default is read from the
yaml files the stage composes by default, as plain YAML: no Hydra and no stage module, so the help
answers at once. Of the profile, only the sections the stage reads (its ``${profile...}`` values)
are listed.
"""

from __future__ import annotations

import ast
import dataclasses
import importlib.util
import re
import sys
import textwrap
import typing
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from pipeline.config.fields import constraint, field_docs
from pipeline.config.folder import conf_dir

#: The flags that print a stage's help instead of running it.
HELP_FLAGS = {"-h", "--help"}
#: Every key of the schema, where ``--help`` shows the common ones (``COMMON_KEYS``).
FULL_HELP_FLAG = "--help-all"

WIDTH = 100
GLOBAL = "@package _global_"
ROLE = re.compile(r":\w+:`~?([^`]+)`")
PROFILE_REF = re.compile(r"\$\{profile\.([\w.]+)\}")
SENTENCE_END = re.compile(r"(?<!\bal\.)(?<!e\.g\.)(?<!i\.e\.)(?<=[.?])\s")
Loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
#: The installed command (``[project.scripts]`` in pyproject.toml), named in the help it prints.
CONSOLE_SCRIPT = "safenav"


def program() -> str:
    """The command as the user typed it: ``safenav`` when run by the installed command (its
    ``sys.argv[0]``), else ``python -m pipeline``."""
    return CONSOLE_SCRIPT if Path(sys.argv[0]).name == CONSOLE_SCRIPT else "python -m pipeline"


def describe(stage: str) -> str:
    """The stage's one-line description: the first line of its module's docstring without the
    ``Stage ``<name>``:`` in front (read from the source: no import, so ``--help`` stays fast)."""
    spec = importlib.util.find_spec(f"pipeline.stages.{stage}")
    doc = ast.get_docstring(ast.parse(Path(spec.origin).read_text())) or ""
    first = doc.strip().splitlines()[0] if doc.strip() else ""
    return first.removeprefix(f"Stage ``{stage}``:").strip().replace("``", "")


@dataclass
class Group:
    """A config group a stage reads: ``<name>=<option>`` picks ``conf/<name>/<option>.yaml``."""

    name: str
    default: str | None
    options: dict[str, str]
    """Option -> its one-line summary."""
    package_global: bool
    """The options' keys land at the top level (``# @package _global_``), not under ``name``."""


def _load(path: Path) -> dict[str, Any]:
    return yaml.load(path.read_text(), Loader=Loader) or {}


def _comment(path: Path) -> str:
    """The first sentence of the file's leading comment (without its ``@package`` line)."""
    lines = []
    for line in path.read_text().splitlines():
        if not line.startswith("#"):
            break
        if GLOBAL not in line:
            lines.append(line.lstrip("#").strip())
    text = " ".join(" ".join(lines).split())
    return SENTENCE_END.split(text, maxsplit=1)[0].replace("`", "")


def _merge(base: dict, over: dict) -> dict:
    out = dict(base)
    for key, value in over.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _merge(out[key], value)
        else:
            out[key] = value
    return out


def _flat(data: dict, prefix: str = "") -> list[str]:
    """``key=value`` of every leaf of ``data`` (dotted keys)."""
    out = []
    for key, value in data.items():
        if isinstance(value, dict) and value:
            out += _flat(value, f"{prefix}{key}.")
        else:
            out.append(f"{prefix}{key}={show(value)}")
    return out


def show(value: Any) -> str:
    """A value as one would type it in an override."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, list):
        return "[" + ", ".join(show(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k}: {show(v)}" for k, v in value.items()) + "}"
    return str(value) if str(value) else "''"


def nested(hint: Any) -> tuple[type | None, str]:
    """The dataclass inside ``hint`` and the key step to reach one of it: ``X``, ``X | None``
    (``""``), ``dict[str, X]`` (``<name>.``) or ``list[X]`` (``<i>.``)."""
    if dataclasses.is_dataclass(hint):
        return hint, ""
    args = typing.get_args(hint)
    origin = typing.get_origin(hint)
    if origin is dict and args and dataclasses.is_dataclass(args[-1]):
        return args[-1], "<name>."
    if origin is list and args and dataclasses.is_dataclass(args[0]):
        return args[0], "<i>."
    inner = [a for a in args if dataclasses.is_dataclass(a)]
    return (inner[0], "") if inner else (None, "")


def _wrap(text: str, indent: int, hang: int = 0) -> list[str]:
    """``text`` wrapped at :data:`WIDTH`, without reST markup (````x````, ``:role:`x```)."""
    text = ROLE.sub(r"\1", text).replace("``", "")
    return textwrap.wrap(
        text, WIDTH, initial_indent=" " * indent, subsequent_indent=" " * (indent + hang)
    )


class StageHelp:
    """The help of one stage, read from its schema (``schema``) and its config folder (``conf``)."""

    def __init__(self, stage: str, schema: type, conf: Path):
        self.stage, self.schema, self.conf = stage, schema, Path(conf)
        self.groups = self._groups()
        self.values = self._composed()
        self.sections = self._profile_sections()

    def _defaults_list(self) -> list[Any]:
        return _load(self.conf / f"{self.stage}.yaml").get("defaults", [])

    def _group(self, name: str, default: str | None, dict_typed: bool) -> Group:
        files = sorted((self.conf / name).glob("*.yaml"))
        comments = {p.stem: _comment(p) for p in files}
        shared = len(set(comments.values())) == 1 and len(files) > 1
        options = {}
        for path in files:
            values = {k: v for k, v in _load(path).items() if k not in ("_target_", "name")}
            summary = "" if shared else comments[path.stem]
            if shared or dict_typed:
                keys = " ".join(_flat(values))
                summary = f"{summary} Arguments: {keys}" if dict_typed and keys else summary or keys
            options[path.stem] = summary.strip()
        package_global = any(GLOBAL in p.read_text().split("\n", 1)[0] for p in files)
        return Group(name, default, options, package_global)

    def _groups(self) -> list[Group]:
        """The groups of ``conf/<stage>.yaml``'s defaults list, then the schema's fields that
        name a folder of ``conf/`` without a default (``experiment``: ``+experiment=<name>``)."""
        hints = typing.get_type_hints(self.schema)
        chosen: dict[str, str | None] = {}
        for entry in self._defaults_list():
            if isinstance(entry, dict):
                ((name, option),) = entry.items()
                if not name.startswith(("override", "hydra")):
                    chosen[name] = option
        for f in dataclasses.fields(self.schema):
            if f.name not in chosen and (self.conf / f.name).is_dir():
                chosen[f.name] = None
        return [
            self._group(name, option, typing.get_origin(hints.get(name)) is dict)
            for name, option in chosen.items()
        ]

    def _composed(self) -> dict[str, Any]:
        """The stage's values as its defaults list composes them (plain YAML, no interpolation)."""
        own = _load(self.conf / f"{self.stage}.yaml")
        own = {k: v for k, v in own.items() if k not in ("defaults", "hydra")}
        by_name = {g.name: g for g in self.groups}
        out: dict[str, Any] = {}
        entries = self._defaults_list()
        for entry in entries if "_self_" in entries else [*entries, "_self_"]:
            if entry == "_self_":
                out = _merge(out, own)
            elif isinstance(entry, dict):
                ((name, option),) = entry.items()
                group = by_name.get(name)
                if group is not None and option is not None:
                    values = _load(self.conf / name / f"{option}.yaml")
                    out = _merge(out, values if group.package_global else {name: values})
        return out

    def _profile_sections(self) -> frozenset[str]:
        """The profile's sections the stage reads: ``${profile.<section>...}`` in its file or in
        an option of its other groups."""
        paths = [self.conf / f"{self.stage}.yaml"]
        for group in self.groups:
            if group.name != "profile":
                paths += [self.conf / group.name / f"{option}.yaml" for option in group.options]
        refs = PROFILE_REF.findall("".join(p.read_text() for p in paths))
        return frozenset(ref.split(".")[0] for ref in refs)

    def _profile_values(self, ref: str) -> str:
        """``paper: 100, smoke: 3``: what each profile gives the key ``ref`` (``trials.runs``)."""
        out = []
        for path in sorted((self.conf / "profile").glob("*.yaml")):
            node: Any = _load(path)
            for part in ref.split("."):
                node = node.get(part) if isinstance(node, dict) else None
            out.append(f"{path.stem}: {show(node)}")
        return ", ".join(out)

    def _default(self, f: dataclasses.Field, value: Any) -> str:
        if value is dataclasses.MISSING:
            if f.default is not dataclasses.MISSING:
                value = f.default
            elif f.default_factory is not dataclasses.MISSING:
                value = f.default_factory()
            else:
                return "required"
        if value == "???":
            return "required"
        text = show(value)
        ref = PROFILE_REF.fullmatch(text)
        return f"{text} ({self._profile_values(ref.group(1))})" if ref else text

    def key_lines(
        self, cls: type, values: Any, prefix: str = "", only: set[str] | None = None
    ) -> Iterator[str]:
        """Two or more lines per key of ``cls`` (recursively): ``key: type, allowed = default``
        and its description; a nested config gets a heading of its own description. Of the
        profile, only the sections the stage reads."""
        hints = typing.get_type_hints(cls)
        docs = field_docs(cls)
        for f in dataclasses.fields(cls):
            if only is not None and f.name not in only:
                continue
            key, doc = prefix + f.name, docs.get(f.name, "")
            value = values.get(f.name, dataclasses.MISSING) if isinstance(values, dict) else values
            inner, step = nested(hints[f.name])
            if inner is not None:
                yield ""
                yield from _wrap(f"{key}{'.' + step.rstrip('.') if step else ''}: {doc}", 2, 4)
                sub = value if isinstance(value, dict) and not step else {}
                keep = set(self.sections) if inner.__name__ == "Profile" else None
                yield from self.key_lines(inner, sub, f"{key}.{step}", keep)
                continue
            allowed = constraint(f)
            kind = f.type if isinstance(f.type, str) else getattr(f.type, "__name__", str(f.type))
            yield f"  {key}: {kind}{', ' + allowed if allowed else ''} = {self._default(f, value)}"
            yield from _wrap(doc, 6)

    def group_lines(self) -> Iterator[str]:
        docs = field_docs(self.schema)
        for group in self.groups:
            how = f"{group.name}=<option>" if group.default else f"+{group.name}=<option>"
            doc = docs.get(group.name) or f"conf/{group.name}/, each option sets the keys it names."
            yield from _wrap(f"{group.name} ({how}): {doc}", 2, 4)
            width = max(len(o) for o in group.options) + 3
            for option, summary in group.options.items():
                mark = "*" if option == group.default else " "
                line = f"{option}{mark}".ljust(width) + summary
                yield from textwrap.wrap(
                    line, WIDTH, initial_indent=" " * 6, subsequent_indent=" " * (6 + width)
                )

    def short_text(self) -> str:
        """``--help`` of a stage whose schema declares ``COMMON_KEYS``: each group's options on
        a line, then those keys with the first sentence of their words; ``--help-all`` for the
        rest. One screen where the whole schema is several."""
        lines = [f"{program()} {self.stage} [key=value ...]: {describe(self.stage)}", ""]
        lines.append("Config groups (group=option; * the default):")
        hows = [f"{g.name}=" if g.default else f"+{g.name}=" for g in self.groups]
        width = max(map(len, hows), default=0) + 2
        for how, group in zip(hows, self.groups):
            names = " ".join(o + ("*" if o == group.default else "") for o in group.options)
            lines += textwrap.wrap(
                how.ljust(width) + names,
                WIDTH,
                initial_indent="  ",
                subsequent_indent=" " * (width + 2),
            )
        lines += ["", "Common keys (key: type, allowed values = default):"]
        for name in self.schema.COMMON_KEYS:
            key_lines = self.key_lines(self.schema, self.values, only={name})
            head, *words = list(key_lines)
            first = SENTENCE_END.split(" ".join(w.strip() for w in words), maxsplit=1)[0]
            lines += [head, *_wrap(first, 6)]
        lines += [
            "",
            f"Every key and what each option does: {program()} {self.stage} --help-all",
        ]
        return "\n".join(lines) + "\n"

    def text(self) -> str:
        """The whole ``--help`` text (``--help-all`` where the schema declares ``COMMON_KEYS``)."""
        lines = [f"{program()} {self.stage} [key=value ...]: {describe(self.stage)}", ""]
        if self.groups:
            head = "Config groups (group=option; * the default):"
            lines += [head, *self.group_lines(), ""]
        hints = typing.get_type_hints(self.schema)
        grouped = {g.name for g in self.groups}
        keys = {  # a group typed as a mapping (recogniser): its options say it all
            f.name
            for f in dataclasses.fields(self.schema)
            if f.name not in grouped or nested(hints[f.name])[0] is not None
        }
        lines += [
            "Keys (key: type, allowed values = default):",
            *self.key_lines(self.schema, self.values, only=keys),
        ]
        return "\n".join(lines).replace("\n\n\n", "\n\n") + "\n"


def stage_help(stage: str, conf: str | Path, full: bool = False) -> str:
    """The ``--help`` text of ``stage``, whose configs are in the folder ``conf``: its common keys
    where its schema declares them (``COMMON_KEYS``), else (or ``full``) every key."""
    from pipeline.config.registry import schema_of

    found = StageHelp(stage, schema_of(stage), Path(conf))
    return found.text() if full or not hasattr(found.schema, "COMMON_KEYS") else found.short_text()


def wants_help(args: list[str]) -> bool:
    return bool((HELP_FLAGS | {FULL_HELP_FLAG}) & set(args))


def print_help(stage: str, full: bool = False) -> None:
    print(stage_help(stage, conf_dir(), full), end="", flush=True)
