"""The schema describes itself: every key of every stage carries a description on its field, and
``python -m pipeline <stage> --help`` lists that stage's groups and keys from the declarations."""

from __future__ import annotations

import dataclasses
import typing

import pytest

from pipeline.schema import constraint, field_docs, setting
from pipeline.stages._schema import SCHEMAS


def schema_classes() -> list[type]:
    """Every dataclass a stage's config is made of (the stages', their groups', their blocks')."""
    found: list[type] = []

    def walk(cls: type) -> None:
        if cls in found:
            return
        found.append(cls)
        for hint in typing.get_type_hints(cls).values():
            for arg in (hint, *typing.get_args(hint)):
                for inner in (arg, *typing.get_args(arg)):
                    if dataclasses.is_dataclass(inner):
                        walk(inner)

    for schema in SCHEMAS.values():
        walk(schema)
    return found


def test_every_key_of_every_stage_has_a_description():
    classes = schema_classes()
    assert {"TrialsConfig", "MethodSpec", "TrainConfig", "StudyConfig", "ReportSpec", "Cell"} <= {
        c.__name__ for c in classes
    }
    missing = [
        f"{cls.__module__}.{cls.__name__}.{f.name}"
        for cls in classes
        for f in dataclasses.fields(cls)
        if not field_docs(cls).get(f.name, "").strip()
    ]
    assert not missing, f"fields without a description (a string under the field): {missing}"


def test_a_description_is_the_string_under_its_field_folded_to_one_line():
    @dataclasses.dataclass
    class Example:
        a: int = setting(1, ge=0)
        """First line,
        second line."""
        b: str = "x"
        c: float = setting(0.5, gt=0, le=1)
        """Only c."""

    assert field_docs(Example) == {"a": "First line, second line.", "c": "Only c."}
    a, b, c = dataclasses.fields(Example)
    assert (constraint(a), constraint(b), constraint(c)) == (">= 0", "", "> 0, <= 1")


@pytest.mark.parametrize(
    "kw,words",
    [
        ({"choices": ("x", "y")}, "one of x, y"),
        ({"nonempty": True}, "not empty"),
        ({"ge": 0, "le": 65535}, ">= 0, <= 65535"),
    ],
)
def test_a_constraint_reads_as_the_refusal_does(kw, words):
    @dataclasses.dataclass
    class Example:
        a: typing.Any = setting(None, **kw)

    assert constraint(dataclasses.fields(Example)[0]) == words
