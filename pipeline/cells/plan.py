"""Planning a trials run: every cell of an experiment as a single-cell config, and the refusal of
command-line overrides that no cell can take (an override is applied or refused, never ignored).

An experiment (``conf/experiment/<name>.yaml``) lists cells, or generates them from layout sets
(:meth:`~pipeline.schemas.experiment.Experiment.all_cells`); each cell pins some keys (its method,
maze, substitution way, support mode, method fields, recogniser arguments or group) and takes the
rest from the command line and the experiment's globals. Planning works on the stage's config
dataclasses (:mod:`pipeline.schemas.trials`, whose experiment schema imports the report's spec).
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import Any

from omegaconf import OmegaConf

from pipeline.config.compose import CONF_DIR, parsed_overrides
from pipeline.config.fields import check, refuse
from pipeline.rl.methods import MethodSpec, load_method
from pipeline.schemas.experiment import Experiment
from pipeline.schemas.trials import TrialsConfig

#: Keys a cell may pin; the top level (experiment globals, command line) gives the others. A cell
#: also pins method fields (``params``) and recogniser arguments (``recogniser``).
CELL_KEYS = ("maze", "substitution", "support", "world", "rule")


def parse_overrides(overrides: list[str]) -> dict[str, Any]:
    """``key -> value`` of the command line's overrides (group choices by group name)."""
    parsed = parsed_overrides(overrides)  # compose has refused those it cannot parse already
    return {o.key_or_group: (None if o.is_delete() else o.value()) for o in parsed}


def experiment_cells(cfg: TrialsConfig, overrides: list[str]) -> dict[str, TrialsConfig]:
    """Every cell of ``cfg.experiment`` (listed and generated: :meth:`Experiment.all_cells`) as a
    single-cell config. The command line applies to every cell that does not pin the key; an
    override that no cell can take is refused."""
    exp: Experiment = cfg.experiment
    declared = exp.all_cells()
    if not declared:
        refuse("experiment.cells", f"experiment {exp.name!r} has no cells")
    given = parse_overrides(overrides)
    methods = sorted({c.method for c in declared.values()})
    if "method" in given:
        refuse(
            "method",
            f"experiment {exp.name} chooses the method of each cell "
            f"({', '.join(methods)}), so the override cannot apply; override a method field instead (method.alpha=...), "
            f"or run method={given['method']} without +experiment",
        )
    method_over = {
        k.removeprefix("method."): v for k, v in given.items() if k.startswith("method.")
    }
    # one load per (method, fields): 2,100 generated cells share seven
    loaded: dict[str, MethodSpec] = {}

    def method_of(name: str, cell) -> MethodSpec:
        fields = {**method_over, **cell.params}
        key = json.dumps([cell.method, fields], sort_keys=True, default=str)
        if key not in loaded:
            loaded[key] = load_method(cell.method, fields, key=f"experiment.cells.{name}.method")
        return loaded[key]

    methods = {name: method_of(name, cell) for name, cell in declared.items()}
    refuse_pinned_overrides(exp, declared, methods, given, method_over)
    refuse_idle_recogniser_pins(exp, declared, methods, given)
    cells, checked, groups = {}, set(), {}
    for name, cell in declared.items():
        group = cell.recogniser_group
        if group and group not in groups:
            groups[group] = recogniser_group(group, f"experiment.cells.{name}.recogniser_group")
        base = groups[group] if group else cfg.recogniser
        cells[name] = replace(
            cfg,
            method=methods[name],
            recogniser={**base, **cell.recogniser},
            **{
                k: getattr(cell, k) if getattr(cell, k) is not None else getattr(cfg, k)
                for k in CELL_KEYS
            },
        )
        shape = json.dumps(
            [
                cell.method,
                cell.params,
                cell.recogniser,
                cell.recogniser_group,
                cell.substitution,
                cell.support,
                cell.world,
                cell.rule,
            ],
            default=str,
        )
        # ranges once per shape: a config differing from a checked one only by its maze is not rechecked
        if shape not in checked:
            check(cells[name])
            checked.add(shape)
    problems = exp.report.problems(declared) if exp.report is not None else []
    if problems:
        key, problem = problems[0]
        refuse(f"experiment.report.{key}", problem)
    return cells


def refuse_pinned_overrides(exp, declared, methods, given, method_over) -> None:
    """An override of a cell key (``rule=``) or a method field (``method.alpha=``) that every cell
    reading it pins would change nothing: refuse it, naming the key. A key only some methods read
    (:data:`ONLY_FOR`) counts the cells whose method reads it."""
    for key in [*CELL_KEYS, *method_over]:
        if key not in given and f"method.{key}" not in given:
            continue
        reads = ONLY_FOR[key][1] if key in ONLY_FOR else (lambda m: True)
        readers = [n for n in declared if reads(methods[n])]
        pinned = [
            n
            for n in readers
            if (
                getattr(declared[n], key) is not None
                if key in CELL_KEYS
                else key in declared[n].params
            )
        ]
        if readers and len(pinned) == len(readers):
            full = key if key in CELL_KEYS else f"method.{key}"
            which = "" if len(readers) == len(declared) else " that reads it"
            refuse(
                full,
                f"every cell of experiment {exp.name}{which} pins it "
                f"(experiment.cells.*.{key if key in CELL_KEYS else 'params.' + key}); "
                "the override cannot apply",
            )


def recogniser_group(name: str, key: str) -> dict[str, Any]:
    """The recogniser config ``conf/recogniser/<name>.yaml`` that a cell chooses."""
    folder = Path(CONF_DIR) / "recogniser"
    path = folder / f"{name}.yaml"
    if not path.is_file():
        known = ", ".join(sorted(p.stem for p in folder.glob("*.yaml")))
        refuse(key, f"no recogniser {name!r} (conf/recogniser/: {known})")
    return OmegaConf.to_container(OmegaConf.load(path), resolve=True)


def refuse_idle_recogniser_pins(
    exp: Experiment, declared: dict, methods: dict[str, MethodSpec], given: dict[str, Any]
) -> None:
    """Recogniser arguments would change nothing where no recogniser runs: a cell that pins them
    (or its own recogniser group) for a method that sees no pictures is refused, and so is a
    command-line ``recogniser=<name>`` or ``recogniser.<arg>`` that no cell with a recogniser takes
    (each pins the argument or runs its own recogniser group)."""
    for name, cell in declared.items():
        for field_name in ("recogniser", "recogniser_group"):
            if getattr(cell, field_name) and not methods[name].uses_recogniser:
                refuse(
                    f"experiment.cells.{name}.{field_name}",
                    f"method {methods[name].name} "
                    "recognises no pictures, so the recogniser's arguments cannot apply",
                )
    seeing = [name for name in declared if methods[name].uses_recogniser]
    for key in given:
        if key != "recogniser" and not key.startswith("recogniser."):
            continue
        arg = key.removeprefix("recogniser").removeprefix(".")
        if seeing and all(
            declared[n].recogniser_group or (arg and arg in declared[n].recogniser) for n in seeing
        ):
            refuse(
                key,
                f"every cell of experiment {exp.name} with a recogniser pins it "
                f"(experiment.cells.*.recogniser.{arg or '<arg>'}) or runs its own "
                "(experiment.cells.*.recogniser_group); the override cannot apply",
            )


#: Command-line keys that only some methods read: (what uses it, test on the cell's method).
ONLY_FOR = {
    "recogniser": (
        "methods that recognise pictures (safety: fewshot)",
        lambda m: m.uses_recogniser,
    ),
    "support": ("methods that recognise pictures (safety: fewshot)", lambda m: m.uses_recogniser),
    "rule": ("methods that recognise pictures (safety: fewshot)", lambda m: m.uses_recogniser),
    "threshold": ("methods that recognise pictures (safety: fewshot)", lambda m: m.uses_recogniser),
    "substitution": (
        "methods with a dynamic support set (dynamic_support: true)",
        lambda m: m.dynamic_support,
    ),
    "images_dir": (
        "methods that recognise pictures (safety: fewshot)",
        lambda m: m.uses_recogniser,
    ),
}


def refuse_inapplicable(configs: dict[str, TrialsConfig], given: dict[str, Any]) -> None:
    """An override that no cell reads would change nothing: refuse it, naming the key."""
    for key in given:
        head = key.split(".")[0]
        if head == "robot" and not any(c.world == "robot3d" for c in configs.values()):
            refuse(
                key, "read only with world=robot3d; this run has none: the override cannot apply"
            )
        if head == "threshold" and not any(c.rule == "open_set" for c in configs.values()):
            refuse(
                key, "read only with rule=open_set; this run has none: the override cannot apply"
            )
        if head in ONLY_FOR:
            who, uses = ONLY_FOR[head]
            if not any(uses(c.method) for c in configs.values()):
                names = ", ".join(sorted({c.method.name for c in configs.values()}))
                refuse(key, f"read only by {who}; this run has {names}: the override cannot apply")


def generated_key(exp: Experiment | None, name: str) -> str | None:
    """``experiment.layouts.sizes.<i>`` for a cell its layout sets generate, else None."""
    if exp is None or exp.layouts is None or name in exp.cells:
        return None
    for i, s in enumerate(exp.layouts.sizes):
        if f"_{s.size}_L" in name:
            return f"experiment.layouts.sizes.{i}"
    return None
