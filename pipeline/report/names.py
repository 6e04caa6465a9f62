"""Display names of methods and report rows, derived from what each record file says its cell ran
(the method's fields, maze, substitution way, support set, recogniser): the one mapping from a
cell to the words in tables, legends and the claims, so config ids (``dss_way1_5x5``) never show.

A row's name is its method's name followed by the settings that tell it apart from the other rows
of its section (``Few-shot + DSS, way 2``); settings that vary inside a row (the four ways a
pooled row averages) are left out: the captions say what a row pools.
"""

from __future__ import annotations

#: Methods whose safety rule names them (``MethodSpec.safety``, ``pipeline.rl.rules.Safety``).
SAFETY_NAMES = {"shield": "Shield", "ssrl": "SSRL"}

#: Words for the values of trial settings that are not numbers.
SUPPORT_NAMES = {"restore": "support set restored", "carry": "support set carried over"}

#: Words for the recognisers (``describe()["kind"]`` in the records).
RECOGNISER_NAMES = {"relation_net": "Relation Network", "protonet": "Prototypical Network"}

#: Fields of the method that its name says (the rest show as ``alpha 0.05`` where rows differ).
NAMED_FIELDS = ("name", "learner", "safety", "constrained", "dynamic_support")

#: Settings of a trial rather than of its method.
TRIAL_SETTINGS = ("maze", "way", "support", "recogniser")


def method_name(method: dict) -> str:
    """The method's display name from its recorded fields (``conf/method/*.yaml`` over
    ``MethodSpec``): Q-learning, Sarsa, Shield, SSRL, Constrained RL, Few-shot (static support
    set), Few-shot + DSS."""
    safety = method.get("safety", "none")
    if safety == "fewshot":
        return (
            "Few-shot + DSS" if method.get("dynamic_support") else "Few-shot (static support set)"
        )
    if safety in SAFETY_NAMES:
        return SAFETY_NAMES[safety]
    learner = "Sarsa" if method.get("learner") == "sarsa" else "Q-learning"
    if method.get("constrained"):
        return "Constrained RL" if learner == "Q-learning" else f"Constrained {learner}"
    return learner


def settings(info: dict) -> dict[str, str]:
    """A cell's settings as words, by setting (the recorded ``info`` of its records)."""
    method = info["method"]
    out = {"method": method_name(method), "maze": str(info["maze"])}
    if method.get("dynamic_support"):
        out["way"] = f"way {info.get('substitution')}"
    recogniser = info.get("recogniser") or {}
    if recogniser:
        out["support"] = SUPPORT_NAMES.get(info.get("support"), f"support {info.get('support')}")
        kind = recogniser.get("kind")
        out["recogniser"] = f"{RECOGNISER_NAMES.get(kind, kind)} recogniser"
    elif method.get("safety") == "fewshot":  # oracle, fixed_accuracy: they record no description
        out["recogniser"] = "recogniser without a model"
    for key, value in sorted(method.items()):
        if key not in NAMED_FIELDS:
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
