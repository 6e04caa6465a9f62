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

from functools import cache

from pipeline import palette
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


def row_styles(rows: list[list[dict]]) -> list[dict]:
    """A line colour and style per row (each a list of its cells' ``info``), the same in every
    figure: a row of one declared method takes the method's colour (:data:`METHODS`); rows that
    share a method take shades of it, a dash and a marker each (:data:`DASHES`, :data:`MARKERS`);
    a row of several or undeclared methods takes grey shades. When every row is of one method
    (Figure 10: the ways of one method), the rows take the palette's distinct series colours
    (:data:`pipeline.palette.SERIES`) instead of shades that would tell them apart poorly."""
    keys = [" / ".join(sorted({method_name(info["method"]) for info in infos})) for infos in rows]
    if len(rows) > 1 and len(set(keys)) == 1:  # one method throughout: its colour tells nothing
        return [
            {
                "color": palette.SERIES[k % len(palette.SERIES)],
                "ls": DASHES[k % len(DASHES)],
                "marker": MARKERS[k % len(MARKERS)],
            }
            for k in range(len(rows))
        ]
    out = []
    for i, key in enumerate(keys):
        peers = [j for j, other in enumerate(keys) if other == key]
        k = peers.index(i)
        one = rows[i][0]["method"] if " / " not in key else None
        colour = (method_colour(one) if one is not None else None) or "#7f7f7f"
        shared = len(peers) > 1
        out.append(
            {
                "color": shade(colour, k, len(peers)),
                "ls": DASHES[k % len(DASHES)],
                "marker": MARKERS[k % len(MARKERS)] if shared else None,
            }
        )
    return out


def sees_pictures(method: dict) -> bool:
    """Whether the recorded method's safety rule looks at pictures (so it ran a recogniser)."""
    safety = method.get("safety")
    return safety in Safety.__members__ and bool(reasons_with_pictures(Safety[safety]))


@cache
def recogniser_declarations() -> dict[str, tuple[str, str | None]]:
    """The recognisers that record a ``kind`` (``describe()`` in the records), by kind: the
    display name and colour each declares beside its ``kind`` (``display_name``, ``colour``:
    :class:`pipeline.fewshot.recogniser.SupportSetRecogniser`'s subclasses, and
    :class:`pipeline.fewshot.paper_tables.PaperTablesRecogniser`, which scores without a network)."""
    from pipeline.fewshot.paper_tables import PaperTablesRecogniser
    from pipeline.fewshot.recogniser import SupportSetRecogniser

    found, todo = {}, [SupportSetRecogniser, PaperTablesRecogniser]
    while todo:
        cls = todo.pop()
        todo += cls.__subclasses__()
        if getattr(cls, "kind", "") and getattr(cls, "display_name", ""):
            found[cls.kind] = (cls.display_name, getattr(cls, "colour", None))
    return found


def recogniser_names() -> dict[str, str]:
    """Display names of the recognisers that record a ``kind``, by kind."""
    return {kind: name for kind, (name, _) in recogniser_declarations().items()}


def recogniser_name(kind: str) -> str:
    """A recorded recogniser kind's display name (the kind itself when nothing declares one)."""
    return recogniser_names().get(kind, kind)


def recogniser_colour(name: str) -> str | None:
    """The colour a recogniser declares, found by its kind or its display name (None when nothing
    declares one): a recogniser is drawn in one colour in every figure."""
    for kind, (display, colour) in recogniser_declarations().items():
        if name in (kind, display):
            return colour
    return None


@cache
def recogniser_groups() -> dict[str, str]:
    """The recognisers' config groups (``conf/recogniser/<name>.yaml``) by the ``_target_``
    each builds (the first name, sorted, where two share one)."""
    import yaml

    from pipeline.config.folder import conf_dir

    found: dict[str, str] = {}
    for path in sorted(conf_dir("recogniser").glob("*.yaml")):
        target = (yaml.safe_load(path.read_text()) or {}).get("_target_")
        found.setdefault(str(target), path.stem)
    return found


def recogniser_of(info: dict, config: dict | None) -> str | None:
    """The recogniser a cell ran, from its records: None when its method looks at no pictures; else
    the kind it recorded (``relation_net``, ``protonet``), else the config group whose
    ``_target_`` its recorded config names (``fixed_accuracy``...), else that ``_target_``."""
    if not sees_pictures(info["method"]):
        return None
    kind = (info.get("recogniser") or {}).get("kind")
    if kind:
        return kind
    target = str(((config or {}).get("recogniser") or {}).get("_target_"))
    return recogniser_groups().get(target, target)


def settings(info: dict) -> dict[str, str]:
    """A cell's settings as words, by setting (the recorded ``info`` of its records)."""
    method = info["method"]
    out = {"method": method_name(method), "maze": str(info["maze"])}
    if method.get("dynamic_support"):
        out["way"] = f"way {info.get('substitution')}"
    recogniser = info.get("recogniser") or {}
    if recogniser:
        out["support"] = SUPPORT_NAMES.get(info.get("support"), f"support {info.get('support')}")
        out["recogniser"] = f"{recogniser_name(recogniser.get('kind'))} recogniser"
    elif sees_pictures(method):  # oracle, fixed_accuracy: they record no description
        out["recogniser"] = "recogniser without a model"
    for key, value in sorted(method.items()):
        if key != "name":  # shown where it tells rows of one method apart (row_names)
            out[key] = f"{key.replace('_', ' ')} {value}"
    return out


def row_names(rows: list[list[dict]]) -> list[str]:
    """One name per row (each a list of its cells' ``info``): the method name(s), then the settings
    that are the same for all cells of the row but differ between rows: trial settings (maze, way,
    support set, recogniser) between any rows, method fields (``alpha 0.05``) between rows of one
    method (Q-learning and Shield differ in ``recovery`` by definition)."""
    per_row = []
    for infos in rows:
        values: dict[str, set] = {}
        for info in infos:
            for key, word in settings(info).items():
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
