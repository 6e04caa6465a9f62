"""Display names of methods and report rows, derived from what each record file says its cell ran
(the method's fields, maze, substitution way, support set, recogniser): the one mapping from a
cell to the words in tables, legends and the claims, so config ids (``dss_way1_5x5``) never show.
A method's display name and colour come from its declaration (:data:`pipeline.rl.rules.METHODS`),
a recogniser's from its class (``display_name`` beside its ``kind``); nothing here lists them.

A row's name is its method's name followed by the settings that tell it apart from the other rows
of its section (``Few-shot + DSS, way 2``); settings that vary inside a row (the four ways a
pooled row averages) are left out: the captions say what a row pools.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

from pipeline import palette
from pipeline.config.recognisers import declared_targets, recogniser_target
from pipeline.rl.methods import declaration
from pipeline.rl.rules import METHODS, Safety, reasons_with_pictures

#: Words for the values of trial settings that are not numbers.
SUPPORT_NAMES = {"restore": "support set restored", "carry": "support set carried over"}

#: Settings of a trial rather than of its method.
TRIAL_SETTINGS = ("maze", "way", "support", "recogniser")


def method_name(method: dict) -> str:
    """The method's display name from its recorded fields: its declaration's
    (:data:`pipeline.rl.rules.METHODS`, found by :func:`pipeline.rl.methods.declaration`), or its
    recorded name when nothing declares it."""
    found = declaration(method)
    return found.display if found is not None else str(method.get("name") or "unnamed method")


def method_colour(method: dict) -> str | None:
    """The method's declared colour (None when nothing declares it)."""
    found = declaration(method)
    return found.colour if found is not None else None


def method_order(name: str) -> int:
    """Where a method (its config name) stands in tables: its place in
    :data:`pipeline.rl.rules.METHODS`, undeclared methods after."""
    order = [m.name for m in METHODS]
    return order.index(name) if name in order else len(order)


#: Line styles and markers of rows that share a method (ways of the DSS, support restored /
#: carried over): with the shades of its colour, no such row hides another, even where they agree.
DASHES = ("-", "--", "-.", ":")
MARKERS = ("o", "s", "^", "D", "v", "P")


def shade(colour: str, k: int, n: int) -> str:
    """The ``k``-th of ``n`` shades of ``colour``: from darker (k = 0) to lighter, so rows of one
    method stay in its colour yet tell apart (and none hides another of the same hue)."""
    from matplotlib.colors import to_hex, to_rgb

    if n <= 1:
        return colour
    t = -0.4 + 0.55 * k / (n - 1)  # < 0: toward black, > 0: toward white
    rgb = [c * (1 + t) if t < 0 else c + (1 - c) * t for c in to_rgb(colour)]
    return to_hex(rgb)


def row_styles(rows: list[list]) -> list[dict]:
    """A line colour and style per row (each a list of its cells, :func:`recorded`), the same in every
    figure: a row of one declared method takes the method's colour (:data:`METHODS`); rows that
    share a method take shades of it, a dash and a marker each (:data:`DASHES`, :data:`MARKERS`);
    a row of several or undeclared methods takes grey shades. When every row is of one method
    (Figure 10: the ways of one method), the rows take the palette's distinct series colours
    (:data:`pipeline.palette.SERIES`) instead of shades that would tell them apart poorly."""
    methods = [[recorded(cell)[0]["method"] for cell in cells] for cells in rows]
    keys = [" / ".join(sorted({method_name(m) for m in row})) for row in methods]
    one_method = len(rows) > 1 and len(set(keys)) == 1  # then its colour tells nothing
    out = []
    for i, key in enumerate(keys):
        peers = [j for j, other in enumerate(keys) if other == key]
        k = i if one_method else peers.index(i)
        one = methods[i][0] if " / " not in key else None
        colour = (method_colour(one) if one is not None else None) or "#7f7f7f"
        out.append(
            {
                "color": palette.series(k) if one_method else shade(colour, k, len(peers)),
                "ls": DASHES[k % len(DASHES)],
                "marker": MARKERS[k % len(MARKERS)] if len(peers) > 1 else None,
            }
        )
    return out


def sees_pictures(method: dict) -> bool:
    """Whether the recorded method's safety rule looks at pictures (so it ran a recogniser)."""
    safety = method.get("safety")
    return safety in Safety.__members__ and bool(reasons_with_pictures(Safety[safety]))


#: The paper's recogniser (section 3.2.1), by its config group: its claims table comes first, its
#: accuracy study fills Tables 1-2, its name labels what the paper's recognition did.
PAPER_RECOGNISER = "relation_net"


@dataclass(frozen=True)
class RecogniserDeclaration:
    """A recogniser as its config file declares it: ``conf/recogniser/<group>.yaml``, its
    ``_target_`` and what the class it builds declares: the ``kind`` its records say
    (``describe()``), its ``display_name`` and ``colour`` (the group's name and no colour when the
    class declares none) and what of the support set it ``reads_support``
    (:data:`~pipeline.fewshot.support_set.SUPPORT_READS`, ``positions`` when it declares nothing)."""

    group: str
    target: str
    kind: str
    display: str
    colour: str | None
    reads: str = "positions"


@cache
def recogniser_declarations() -> list[RecogniserDeclaration]:
    """Every recogniser of ``conf/recogniser/`` (:func:`~pipeline.config.recognisers.
    declared_targets`), from the class its ``_target_`` names (a class, or a class's constructor
    such as ``RelationRecogniser.from_files``): the one declaration of each."""
    found = []
    for target, group in sorted(declared_targets().items(), key=lambda item: item[1]):
        built = recogniser_target({"_target_": target}, f"recogniser {group}")
        cls = getattr(built, "__self__", built)  # ``Class.from_files``: the class
        kind = getattr(cls, "kind", "") or group
        display = getattr(cls, "display_name", "") or group
        found.append(
            RecogniserDeclaration(
                group,
                target,
                kind,
                display,
                getattr(cls, "colour", None),
                getattr(cls, "reads_support", "positions"),
            )
        )
    return found


def recogniser_declaration(name: str) -> RecogniserDeclaration | None:
    """The declaration a recorded recogniser kind, a config group or a display name names."""
    return next(
        (d for d in recogniser_declarations() if name in (d.kind, d.group, d.display)), None
    )


def recogniser_name(name: str) -> str:
    """A recogniser's display name, found by its kind or group (the name itself when nothing
    declares one)."""
    found = recogniser_declaration(name)
    return found.display if found is not None else name


def recogniser_colour(name: str) -> str | None:
    """The colour a recogniser declares, found by its kind, group or display name (None when
    nothing declares one): a recogniser is drawn in one colour in every figure."""
    found = recogniser_declaration(name)
    return found.colour if found is not None else None


def recogniser_reads(name: str) -> str:
    """What of the support set a recogniser reads, found by its kind or group (``positions``, the
    safe assumption, when nothing declares it)."""
    found = recogniser_declaration(name)
    return found.reads if found is not None else "positions"


def recogniser_group(target: str) -> str:
    """The config group whose ``_target_`` is ``target`` (``target`` itself when none is)."""
    return next((d.group for d in recogniser_declarations() if d.target == target), target)


def recogniser_of(info: dict, config: dict | None) -> str | None:
    """The recogniser a cell ran, from its records: None when its method looks at no pictures; else
    the kind it recorded (``relation_net``, ``protonet``), else the config group whose
    ``_target_`` its recorded config names (``fixed_accuracy``...), else that ``_target_``."""
    if not sees_pictures(info["method"]):
        return None
    kind = (info.get("recogniser") or {}).get("kind")
    if kind:
        return kind
    return recogniser_group(str(((config or {}).get("recogniser") or {}).get("_target_")))


def recorded(cell) -> tuple[dict, dict | None]:
    """A cell's recorded ``info`` and config (:class:`~pipeline.report.experiments.Cell`; a bare
    ``info`` dict has no config)."""
    return (cell, None) if isinstance(cell, dict) else (cell.info, cell.config)


def settings(info: dict, config: dict | None = None) -> dict[str, str]:
    """A cell's settings as words, by setting (the recorded ``info`` and config of its records)."""
    method = info["method"]
    out = {"method": method_name(method), "maze": str(info["maze"])}
    if method.get("dynamic_support"):
        out["way"] = f"way {info.get('substitution')}"
    if info.get("recogniser"):
        out["support"] = SUPPORT_NAMES.get(info.get("support"), f"support {info.get('support')}")
    if (recogniser := recogniser_of(info, config)) is not None:
        out["recogniser"] = f"{recogniser_name(recogniser)} recogniser"
    for key, value in sorted(method.items()):
        if key != "name":  # shown where it tells rows of one method apart (row_names)
            out[key] = f"{key.replace('_', ' ')} {value}"
    return out


def row_names(rows: list[list]) -> list[str]:
    """One name per row (each a list of its cells, :func:`recorded`): the method name(s), then the settings
    that are the same for all cells of the row but differ between rows: trial settings (maze, way,
    support set, recogniser) between any rows, method fields (``alpha 0.05``) between rows of one
    method (Q-learning and Shield differ in ``recovery`` by definition)."""
    per_row = []
    for cells in rows:
        values: dict[str, set] = {}
        for cell in cells:
            for key, word in settings(*recorded(cell)).items():
                values.setdefault(key, set()).add(word)
        per_row.append(values)

    def single(values: dict, key: str) -> str | None:
        return next(iter(values[key])) if len(values.get(key, ())) == 1 else None

    names = []
    for values in per_row:
        method = " / ".join(sorted(values["method"]))
        parts = [method]
        for key in [k for k in values if k != "method"]:
            peers = (
                per_row
                if key in TRIAL_SETTINGS
                else [v for v in per_row if v["method"] == values["method"]]
            )
            if single(values, key) and len({single(v, key) for v in peers} - {None}) > 1:
                parts.append(single(values, key))
        names.append(", ".join(parts))
    return names
