"""Hostile config overrides derived from the schema declarations (docs/reliability.md "Configs").

For every stage (``pipeline.config.registry.schemas()``) and every key of its schema, nested ones
included (``train.lr``, ``robot.cell``, ``experiment.layouts.sizes.0.count``...), the cases come
from the key's declaration (its annotation and its :func:`pipeline.config.fields.setting` metadata), so a
key added to a schema gets its cases without an edit here:

- a value of the wrong type: a word for a number, a word that is no truth value for a bool, a list
  for a string, a word for a list or a mapping, a word for a config node or group;
- a value just outside each bound (``ge``/``gt``/``le``/``lt``: the next float past it, or the
  next whole number), one not among its ``choices``, an empty string where ``nonempty``, a name
  too long for the file system where ``path``;
- NaN and infinity for every float key (and as an element of a list of floats), a list in place of
  a name in a list of strings;
- an unknown key in every config node, set (``<node>.nosuchkey=1``) and forced (``++``), and at
  the top (``nosuchkey=1``, ``+nosuchkey=1``, ``++nosuchkey=1``); deleting a key (``~key``).

Each case asserts that loading the stage's config with it raises a
:class:`~pipeline.errors.UserError` of one line naming the key. A Hydra compose takes 0.1-0.3 s,
all the cases through :func:`pipeline.config.compose.load_config` about 70 s; so each stage (and
experiment) is composed once, and a case applies its override with Hydra's own code for
command-line overrides and then the stage's own refusals (:func:`load`); a config group's override
(``method=abc``) is composed. The first case of each kind and of each stage runs through
``load_config`` as well and must give the same line (``test_load_is_load_config``), and
``-m slow`` runs every case through it (``test_every_hostile_override_through_load_config``).

Where each key is reached: a declaration (a dataclass field) is tested once, at the first path
that reaches it: the ``Profile`` shared by four stages in the trials, the fields of an
experiment's cells, layout sets and report block under ``+experiment=<name>`` (each experiment of
``conf/experiment/`` is walked; ``test_every_declaration_is_reached`` fails for a
declaration none reaches). Not derived here: mappings typed ``Any`` (``recogniser``, a cell's
``params`` and ``recogniser``): their keys are the arguments of the code they configure, refused
there (``test_code_in_configs.py``, ``tests/test_config_schema.py``).

Accepted on purpose: OmegaConf's conversions of a value written another way, which name the same
value: ``yes``/``no``/``on``/``off`` and any whole number for a bool (0 false, others true; as
``1``/``0`` are), a quoted whole number for an int (``runs='5'``), a whole number for a float, a
number for a string (a folder named ``5``); ``test_the_conversions_accepted_on_purpose`` pins
them.
"""

from __future__ import annotations

import copy
import dataclasses
import importlib.util
import math
import re
import subprocess
import sys
import time
import types
import typing
from functools import cache

import gymnasium
import pytest
from entry import ROOT, cli
from hydra._internal.config_loader_impl import ConfigLoaderImpl
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.errors import HydraException
from omegaconf.errors import OmegaConfBaseException

import pipeline  # noqa: F401  (registers the Gymnasium environments)
from faults._checks import FAST, one_line_error
from pipeline.config.compose import (
    below_null,
    compose,
    groups,
    load_config,
    one_line,
    override_key,
    refuse_deleted,
    refuse_merged_away,
    typed,
)
from pipeline.config.folder import conf_dir
from pipeline.config.registry import schemas
from pipeline.errors import ConfigError, UserError

SCHEMAS = schemas()
#: What a stage needs to compose at all (``file`` has no default).
REQUIRED = {"replay": ["file=x.mcap"]}
#: The experiments, each walked for the keys only an experiment has.
EXPERIMENTS = sorted(p.stem for p in conf_dir("experiment").glob("*.yaml"))


@dataclasses.dataclass(frozen=True)
class Key:
    """One declared key, where it is reached: its stage, the overrides that make it exist, its
    dotted path, and its declaration."""

    stage: str
    base: tuple[str, ...]
    path: str
    owner: type
    name: str
    annotation: typing.Any
    optional: bool

    @property
    def meta(self) -> typing.Mapping[str, typing.Any]:
        return next(f for f in dataclasses.fields(self.owner) if f.name == self.name).metadata


def unwrap(annotation) -> tuple[typing.Any, bool]:
    """``X | None`` -> ``(X, True)``."""
    if typing.get_origin(annotation) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(annotation) if a is not type(None)]
        return args[0], len(args) < len(typing.get_args(annotation))
    return annotation, False


def walk(obj, prefix: str = ""):
    """(owner class, field name, dotted path, annotation, optional) of every field of ``obj`` and
    of the config nodes below it (the first entry of a mapping or list of nodes)."""
    hints = typing.get_type_hints(type(obj))
    for f in dataclasses.fields(obj):
        annotation, optional = unwrap(hints[f.name])
        value, path = getattr(obj, f.name), prefix + f.name
        if value is None and dataclasses.is_dataclass(annotation):
            continue  # a node left out here (experiment.layouts): reached where it is given
        yield type(obj), f.name, path, annotation, optional
        if dataclasses.is_dataclass(value):
            yield from walk(value, path + ".")
        elif (
            isinstance(value, dict)
            and value
            and dataclasses.is_dataclass(next(iter(value.values())))
        ):
            first = next(iter(value))
            yield from walk(value[first], f"{path}.{first}.")
        elif isinstance(value, list) and value and dataclasses.is_dataclass(value[0]):
            yield from walk(value[0], f"{path}.0.")


def bases(stage: str) -> list[tuple[str, ...]]:
    required = tuple(REQUIRED.get(stage, []))
    extra = [(f"+experiment={e}",) for e in EXPERIMENTS] if stage == "trials" else []
    return [required] + [required + b for b in extra]


@cache
def composed(stage: str, base: tuple[str, ...]):
    """The stage's config composed by Hydra with ``base`` (once: a compose takes 0.1-0.3 s)."""
    return compose(stage, list(base))


def load(stage: str, base: tuple[str, ...], override: str):
    """``load_config(stage, [*base, override])`` without composing again: ``override`` applied
    by Hydra's own code for command-line overrides to the config composed with ``base``, then the
    refusals of :func:`~pipeline.config.compose.compose` and :func:`~pipeline.config.compose.typed`.
    A config group (``method=...``) changes what is composed: through ``load_config``.
    ``test_load_is_load_config`` holds the two equal."""
    if override_key(override) in groups():
        return load_config(stage, [*base, override])
    refuse_deleted(stage, [override])
    cfg = copy.deepcopy(composed(stage, base))
    try:
        parsed = OverridesParser.create().parse_overrides([override])
        ConfigLoaderImpl._apply_overrides_to_config(parsed, cfg)
    except (HydraException, OmegaConfBaseException, ValueError) as exc:
        raise ConfigError(one_line(exc)) from None
    except AssertionError:
        raise ConfigError(below_null(stage, [*base, override])) from None
    refuse_merged_away(cfg, [override])
    return typed(cfg)


@cache
def keys() -> tuple[Key, ...]:
    """Every declaration once, at the first (stage, base, path) that reaches it."""
    seen, out = set(), []
    for stage in SCHEMAS:
        # the smallest configs first: a case copies its base's config
        for base in sorted(bases(stage), key=lambda b: len(str(composed(stage, b)))):
            for owner, name, path, annotation, optional in walk(typed(composed(stage, base))):
                if (owner, name) not in seen:
                    seen.add((owner, name))
                    out.append(Key(stage, base, path, owner, name, annotation, optional))
    return tuple(out)


def declared(cls: type, seen: set | None = None) -> set[tuple[type, str]]:
    """Every (class, field) a schema class declares, through its annotations."""
    seen = set() if seen is None else seen
    if cls in seen:
        return set()
    seen.add(cls)
    out = set()
    for name, annotation in typing.get_type_hints(cls).items():
        if name not in {f.name for f in dataclasses.fields(cls)}:
            continue
        out.add((cls, name))
        stack = [annotation]
        while stack:
            a = stack.pop()
            stack += list(typing.get_args(a))
            if dataclasses.is_dataclass(a):
                out |= declared(a, seen)
    return out


def untyped(annotation) -> bool:
    """A mapping of ``Any``: its keys are the arguments of the code it configures."""
    return typing.get_origin(annotation) is dict and typing.get_args(annotation)[1] is typing.Any


def outside(meta, annotation) -> list[tuple[str, str]]:
    """A value just outside each bound the declaration has."""
    out = []
    for bound, step in (("ge", -1), ("gt", 0), ("le", 1), ("lt", 0)):
        if bound in meta:
            b = meta[bound]
            if annotation is int:
                value = repr(int(b) + step)
            else:
                value = repr(math.nextafter(float(b), step * math.inf) if step else float(b))
            out.append((f"{bound} {b}", value))
    return out


def hostile(key: Key) -> list[tuple[str, str]]:
    """(what, the override's value) for ``key``, from its declaration alone."""
    a, meta = key.annotation, key.meta
    if dataclasses.is_dataclass(a):
        return [("a word for a node", "abc")]
    origin = typing.get_origin(a)
    cases = {
        int: [("a word for a number", "abc")],
        float: [("a word for a number", "abc"), ("nan", "nan"), ("inf", "inf")],
        bool: [("a word for a bool", "maybe")],
        str: [("a list for a string", "[1,2]")],
    }.get(a, [])
    if origin is list:
        cases = [("a word for a list", "abc")]
        (element,) = typing.get_args(a)
        if element is float:
            cases += [("element nan", "[nan]"), ("element inf", "[inf]")]
        elif element is str:
            cases += [("element list", "[[1]]")]
    elif origin is dict:
        cases = [("a word for a mapping", "abc")]
    cases += outside(meta, a)
    if "choices" in meta:
        choices = meta["choices"]
        numbers = all(isinstance(c, int) for c in choices)
        cases.append(("not a choice", str(max(choices) + 1) if numbers else "nosuchchoice"))
    if meta.get("nonempty"):
        cases.append(("empty", ""))
    if meta.get("path"):  # a file or folder: a name the file system cannot hold
        cases.append(("a name too long", "n" * 300))
    return cases


def nodes() -> list[Key]:
    return [k for k in keys() if dataclasses.is_dataclass(k.annotation)]


@cache
def derived() -> tuple[tuple[str, tuple[str, ...], str, str, str], ...]:
    """(stage, base, override, the key it must name, its kind)."""
    out = []
    for key in keys():
        if untyped(key.annotation):
            continue
        for what, value in hostile(key):
            out.append((key.stage, key.base, f"{key.path}={value}", key.path, what))
    for key in nodes():
        for prefix in ("", "++"):
            override, named = f"{prefix}{key.path}.nosuchkey=1", f"{key.path}.nosuchkey"
            out.append((key.stage, key.base, override, named, f"{prefix}unknown key"))
    for stage in SCHEMAS:
        base = tuple(REQUIRED.get(stage, []))
        for prefix in ("", "+", "++"):
            out.append((stage, base, f"{prefix}nosuchkey=1", "nosuchkey", f"{prefix}top"))
        first = next(k for k in keys() if k.stage == stage)
        out.append((stage, base, f"~{first.path}", first.path, "deleted"))
    return tuple(out)


def params(rows) -> list:
    return [
        pytest.param(
            stage,
            base,
            override,
            named,
            id=f"{stage}:{override}",
        )
        for stage, base, override, named, _ in rows
    ]


def sample() -> list:
    """The first case of each kind (a bound's of each bound) and of each stage."""
    first, out = set(), []
    for row in derived():
        stage, what = (
            row[0],
            row[4].split(" ")[0] if row[4][:2] in ("ge", "gt", "le", "lt") else row[4],
        )
        if what not in first or stage not in first:
            first |= {what, stage}
            out.append(row)
    return out


def names(message: str, key: str) -> bool:
    """``key`` is named as a whole dotted key (``config key 'train.lr'``, ``method/abc``)."""
    return re.search(rf"(?<![\w.]){re.escape(key)}(?![\w])", message) is not None


def outcome(loader, stage: str, base: tuple[str, ...], override: str) -> str | None:
    """The one-line message of the refusal, or None if the override was taken."""
    try:
        loader(stage, base, override)
    except UserError as exc:
        return str(exc)
    return None


def real(stage: str, base: tuple[str, ...], override: str):
    return load_config(stage, [*base, override])


@pytest.mark.parametrize("stage,base,override,named", params(derived()))
def test_a_hostile_override_is_one_line_naming_its_key(stage, base, override, named):
    message = outcome(load, stage, base, override)
    assert message is not None, f"{override} was taken"
    assert "\n" not in message and names(message, named), message


@pytest.mark.parametrize("stage,base,override,named", params(sample()))
def test_load_is_load_config(stage, base, override, named):
    """The first case of each kind and of each stage gives the same line through the stage's own
    ``load_config`` (a whole Hydra compose)."""
    message = outcome(real, stage, base, override)
    assert message == outcome(load, stage, base, override)
    assert message is not None, f"{override} was taken"


@pytest.mark.slow
@pytest.mark.parametrize("stage,base,override,named", params(derived()))
def test_every_hostile_override_through_load_config(stage, base, override, named):
    """Every case through the stage's own ``load_config`` (about 70 s; ``-m slow``)."""
    message = outcome(real, stage, base, override)
    assert message is not None, f"{override} was taken"
    assert "\n" not in message and names(message, named), message


def test_every_declaration_is_reached():
    """Every field of every schema (through its annotations) has a path some base reaches; a new
    optional node that no experiment fills fails here, naming it."""
    every = set().union(*(declared(cls) for cls in SCHEMAS.values()))
    reached = {(k.owner, k.name) for k in keys()}
    missing = sorted(f"{cls.__name__}.{name}" for cls, name in every - reached)
    assert not missing, f"no stage or experiment reaches {missing}; add a base that does"


#: The metadata :func:`pipeline.config.fields.setting` declares, each of which :func:`hostile` derives
#: cases from (``doc``, the words :func:`~pipeline.config.fields.same_key` carries over, is none).
DERIVED_FROM = {"ge", "gt", "le", "lt", "choices", "nonempty", "path"}


def test_the_derivation_covers_every_constraint():
    """Each bound, choice, nonempty and path of the declarations gives a case, and a kind of
    constraint the derivation does not know fails here (the derivation itself)."""
    for key in keys():
        kinds = set(key.meta) - {"doc"}
        assert kinds <= DERIVED_FROM, f"{key.path}: derive cases for {kinds}"
        what = {w for w, _ in hostile(key)}
        assert bool(key.meta.get("path")) == ("a name too long" in what), key.path
        for bound in ("ge", "gt", "le", "lt"):
            assert (bound in key.meta) == any(w.startswith(bound + " ") for w in what), key.path
        assert ("choices" in key.meta) == ("not a choice" in what), key.path
        assert bool(key.meta.get("nonempty")) == ("empty" in what), key.path
        if key.annotation is float:
            assert {"nan", "inf"} <= what, key.path


@pytest.mark.parametrize(
    "stage,override,key,value",
    [
        ("trials", "progress=yes", "progress", True),
        ("trials", "progress=off", "progress", False),
        ("trials", "progress=0", "progress", False),
        ("trials", "progress=2", "progress", True),
        ("trials", "runs='5'", "runs", 5),
        ("trials", "out=5", "out", "5"),
        ("trials", "threshold=1", "threshold", 1.0),
    ],
)
def test_the_conversions_accepted_on_purpose(stage, override, key, value):
    """OmegaConf's conversions of one value written another way: the same value, not a hole."""
    got = getattr(load_config(stage, [override]), key)
    assert got == value and type(got) is type(value)


@pytest.mark.parametrize(
    "overrides,message",
    [
        (
            ["experiment.name=x"],
            "config key 'experiment.name': experiment is null (not set), so it has no name; "
            "choose one first: +experiment=<name> (" + ", ".join(EXPERIMENTS) + ")",
        ),
        (
            ["+experiment=generalisation", "experiment.report.path.title=x"],
            "config key 'experiment.report.path.title': experiment.report.path is null (not "
            "set), so it has no title; set experiment.report.path itself first, or leave "
            "experiment.report.path.title out",
        ),
        (
            ["method=null"],
            "config key 'method': null chooses no method; name one of "
            + ", ".join(sorted(p.stem for p in conf_dir("method").glob("*.yaml"))),
        ),
        (
            ["~out"],
            "config key 'out': cannot be deleted (~out); every key of the trials config is "
            "needed: give it a value instead",
        ),
        (
            ["+experiment=generalisation", "experiment.layouts.sizes.0.count=abc"],
            "config key 'experiment.layouts.sizes.0.count': Value 'abc' of type 'str' could not "
            "be converted to Integer",
        ),
    ],
)
def test_the_fixed_tracebacks_and_silences_say_what_to_do(overrides, message):
    """A key below a null node (was an AssertionError traceback), a group set to null (named no
    key), a deleted key (was the value ``???``, or a TypeError traceback), a list index as the
    command line writes it (was ``sizes[0]``)."""
    with pytest.raises(UserError) as err:
        load_config("trials", overrides)
    assert str(err.value) == message


def test_the_command_line_says_one_line_and_exits_2(tmp_path):
    key = next(k for k in keys() if k.stage == "trials" and k.annotation is float)
    out = subprocess.run(
        [sys.executable, "-m", "pipeline", "trials", f"{key.path}=nan", f"out={tmp_path / 'o'}"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 2 and out.stdout == "", out.stderr
    assert (
        out.stderr.startswith(f"error: config key '{key.path}': ") and out.stderr.count("\n") == 1
    )
    assert not (tmp_path / "o").exists()


# ------------------------------------------------------- through the command line
@pytest.mark.parametrize(
    "args,words",
    [
        (["runs=2.7"], ["config key 'runs'", "Integer"]),
        (["episodes=abc"], ["config key 'episodes'"]),
        (["record=maybe"], ["config key 'record'"]),
        (["threads=-1"], ["config key 'threads'", ">= 0"]),
        (["threads=999"], ["config key 'threads'", "at most"]),
        (["out="], ["config key 'out'", "empty"]),
        (["bogus=1"], ["config key 'bogus'"]),
        (["method=nope"], ["method/nope"]),
        (["runs=100", "episodes=100000000000000"], ["need about", "GiB", "available"]),
        (["out=/proc/version/x"], ["config key 'out'"]),
    ],
)
def test_bad_trial_configs(tmp_path, args, words):
    one_line_error(cli("trials", *args, "progress=false"), *words)


def test_record_none_means_no_records(tmp_path):
    assert cli("trials", "record=none", f"out={tmp_path}", *FAST).returncode == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["summary.json"]


def test_out_that_is_a_file_is_refused_and_kept(tmp_path):
    target = tmp_path / "results"
    target.write_text("mine")
    one_line_error(cli("trials", f"out={target}", *FAST), "config key 'out'", "is a file")
    assert target.read_text() == "mine"


def test_every_stage_turns_a_bad_config_into_one_line(tmp_path):
    one_line_error(cli("render", "size=abc"), "config key 'size'")
    one_line_error(cli("meta_train", "train.lr=-1"), "config key 'train.lr'")
    one_line_error(cli("accuracy", "study.repeats=0"), "config key 'study.repeats'")
    one_line_error(cli("report", "out="), "config key 'out'")
    one_line_error(
        cli("replay", f"file={tmp_path / 'none.mcap'}"), "config key 'file'", "no such record file"
    )


def test_a_layout_count_that_would_plan_millions_of_cells_is_refused_at_once(tmp_path):
    start = time.perf_counter()
    one_line_error(
        cli(
            "trials",
            "+experiment=generalisation",
            "experiment.layouts.sizes.0.count=1000000",
            f"out={tmp_path}",
        ),
        "config key 'experiment.layouts.sizes.0.count': 1,000,000 layouts give 7,001,400 cells",
        "at most 100,000",
        "GB",
    )
    assert time.perf_counter() - start < 5


def test_an_empty_mapping_merged_away_is_refused_not_ignored(tmp_path):
    one_line_error(
        cli(
            "trials", "+experiment=generalisation", "experiment.layouts.cells={}", f"out={tmp_path}"
        ),
        "config key 'experiment.layouts.cells': {} does not empty it",
    )
    assert not any(tmp_path.iterdir())


@pytest.mark.skipif(
    importlib.util.find_spec("pygame") is not None, reason="pygame is installed: human works"
)
def test_render_mode_human_without_pygame_is_refused_at_make():
    with pytest.raises(ValueError, match="render_mode='human' opens a window through pygame"):
        gymnasium.make("SafeNav-5x5-v0", method="shield", render_mode="human")


def test_a_bad_value_in_a_config_file_names_its_key():
    """What Hydra raises when a file holds a value of the wrong type (``dvc exp run -S
    conf/profile/paper.yaml:trials.episodes=abc`` writes one): the key is in its text."""
    from hydra.errors import ConfigCompositionException

    from pipeline.config.compose import one_line

    exc = ConfigCompositionException(
        "In 'profile/paper': ValidationError raised while composing config:\n"
        "Value 'abc' of type 'str' could not be converted to Integer\n"
        "    full_key: profile.trials.episodes\n    reference_type=TrialsProfile"
    )
    assert one_line(exc) == (
        "config key 'profile.trials.episodes': In 'profile/paper': ValidationError raised while "
        "composing config: Value 'abc' of type 'str' could not be converted to Integer"
    )
