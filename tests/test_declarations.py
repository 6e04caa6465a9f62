"""One declaration per thing: the methods' declarations (``METHODS`` in ``pipeline/rl/rules.py``)
match ``conf/method/``, the report's names, colours and orders come from them, a method nothing
declares keeps its recorded name, and every recogniser that records a kind declares its display
name. Each failure names what to add."""

from __future__ import annotations

import inspect
from types import SimpleNamespace

import pytest
from omegaconf import OmegaConf

from pipeline import palette
from pipeline.config.recognisers import RECOGNISER_DIR, recogniser_names, recogniser_target
from pipeline.report.layout_cells import LayoutCells, methods_of
from pipeline.report.names import (
    method_colour,
    method_name,
    recogniser_colour,
    recogniser_declarations,
    recogniser_name,
    row_names,
    row_styles,
    settings,
    shade,
)
from pipeline.rl.methods import declaration, get_method, method_names
from pipeline.rl.rules import METHODS


def recorded(name: str, **fields) -> dict:
    """A method's fields as a record keeps them (``MethodSpec.as_dict()``)."""
    return get_method(name, **fields).as_dict()


def test_every_method_file_has_one_declaration_and_every_declaration_a_file():
    declared = [m.name for m in METHODS]
    assert len(set(declared)) == len(declared), "a method is declared twice in rules.METHODS"
    missing = sorted(set(method_names()) - set(declared))
    assert not missing, f"declare {missing} in pipeline/rl/rules.py METHODS (display, colour)"
    orphans = sorted(set(declared) - set(method_names()))
    assert not orphans, f"rules.METHODS declares {orphans}, which have no conf/method/<name>.yaml"


def test_display_names_and_colours_tell_methods_apart():
    assert len({m.display for m in METHODS}) == len(METHODS)
    assert len({m.colour.lower() for m in METHODS}) == len(METHODS)


@pytest.mark.parametrize("method", METHODS, ids=lambda m: m.name)
def test_the_report_names_and_colours_each_method_as_declared(method):
    fields = recorded(method.name)
    assert declaration(fields) is method
    assert method_name(fields) == method.display
    assert method_colour(fields) == method.colour
    assert settings({"method": fields, "maze": "5x5"})["method"] == method.display


def test_a_variant_is_named_by_what_it_ran_and_says_how_it_differs():
    # the fields of another declared method: that method's name
    assert method_name(recorded("qlearning", learner="sarsa")) == "Sarsa"
    # fields no declaration has: its own name, and the field that differs shows as a setting
    variant = recorded("sarsa", constrained=True)
    assert method_name(variant) == "Sarsa"
    names = row_names(
        [[{"method": recorded("sarsa"), "maze": "5x5"}], [{"method": variant, "maze": "5x5"}]]
    )
    assert names == ["Sarsa, constrained False", "Sarsa, constrained True"]


def test_a_method_nothing_declares_keeps_its_recorded_name():
    mine = {**recorded("shield"), "name": "mine"}
    assert declaration(mine) is None
    assert method_name(mine) == "mine" and method_colour(mine) is None
    rows = [[{"method": mine, "maze": "5x5"}], [{"method": recorded("qlearning"), "maze": "5x5"}]]
    assert row_names(rows) == ["mine", "Q-learning"]
    assert row_styles(rows)[0]["color"] == "#7f7f7f"  # grey: nothing declares its colour
    assert row_styles(rows)[1]["color"] == METHODS[0].colour


def test_rows_of_distinct_methods_take_their_declared_colours():
    rows = [[{"method": recorded(m.name), "maze": "5x5"}] for m in METHODS[:3]]
    assert [s["color"] for s in row_styles(rows)] == [m.colour for m in METHODS[:3]]
    assert {s["ls"] for s in row_styles(rows)} == {"-"}
    ways = [
        [{"method": recorded("fewshot_dss"), "maze": "5x5", "substitution": w}]
        for w in (1, 2, 3, 4)
    ]
    styles = row_styles(ways)  # ways of one method alone: distinct series colours, a dash each
    assert [s["color"] for s in styles] == list(palette.SERIES[:4])
    assert len({s["ls"] for s in styles}) == 4 and len({s["marker"] for s in styles}) == 4
    assert styles == row_styles(ways)  # the same in every figure
    beside = row_styles([[{"method": recorded("shield"), "maze": "5x5"}], *ways])
    assert beside[0]["color"] == declaration(recorded("shield")).colour
    dss = declaration(recorded("fewshot_dss")).colour  # beside another method: shades of its colour
    assert beside[1]["color"] == shade(dss, 0, 4) and len({s["color"] for s in beside}) == 5


def test_generalisation_orders_methods_as_declared():
    layout = LayoutCells("5x5", "random:5x5:4:0:unique", 0, [])
    layout.cells = {name: None for name in ["zeta", *reversed(method_names()), "alpha"]}
    assert methods_of([layout]) == [m.name for m in METHODS] + ["alpha", "zeta"]


@pytest.mark.parametrize("name", recogniser_names())
def test_every_recogniser_that_records_a_kind_declares_its_display_name(name):
    node = OmegaConf.to_container(OmegaConf.load(RECOGNISER_DIR / f"{name}.yaml"))
    target = recogniser_target(node, f"recogniser {name}")
    cls = getattr(target, "__self__", target)  # ``Class.from_files``: the class
    assert inspect.isclass(cls)
    if getattr(cls, "kind", ""):
        assert cls.display_name, f"{cls.__name__} records kind {cls.kind!r}: give it a display_name"
        assert recogniser_name(cls.kind) == cls.display_name
        assert cls.colour, f"{cls.__name__} records kind {cls.kind!r}: give it a colour"
        assert recogniser_colour(cls.kind) == recogniser_colour(cls.display_name) == cls.colour
    assert recogniser_name("unheard_of") == "unheard_of"
    assert recogniser_colour("unheard_of") is None


def test_recognisers_have_distinct_colours_of_their_own():
    """A recogniser is drawn in its declared colour in every figure (Table 2's plot, the accuracy
    curve's mark, the repetition study): no two alike, none a method's, the paper's or a series'."""
    colours = [d.colour for d in recogniser_declarations() if d.colour]
    assert len(colours) >= 3 and len(set(colours)) == len(colours)
    others = {m.colour for m in METHODS} | {palette.PAPER, *palette.SERIES}
    assert not set(colours) & others


def test_recognisers_without_a_recorded_kind_are_named_by_their_config_file():
    """A recogniser that records no ``kind`` (fixed_accuracy, oracle) is found by its recorded
    ``_target_``: rows of two such recognisers never share a name."""
    declared = {d.group: d for d in recogniser_declarations()}
    cells = [
        SimpleNamespace(
            info={"method": recorded("fewshot"), "maze": "5x5"},
            config={"recogniser": {"_target_": declared[group].target}},
        )
        for group in ("fixed_accuracy", "oracle")
    ]
    names = row_names([[cell] for cell in cells])
    assert names == [
        f"{method_name(recorded('fewshot'))}, {declared[g].display} recogniser"
        for g in ("fixed_accuracy", "oracle")
    ]
