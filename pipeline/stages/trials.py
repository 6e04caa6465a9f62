"""Stage ``trials``: independent runs of the methods on the mazes, every episode recorded to MCAP.

    python -m pipeline trials method=ssrl maze=7x7 runs=100 episodes=500 seed=0 out=runs/ssrl7
    python -m pipeline trials +experiment=fig8            # every cell of one paper experiment

One cell (method, maze, substitution way, support restore/carry) writes ``summary.json`` and
``records.mcap`` into its folder: ``<out>/`` for a single cell, ``<out>/<cell>/`` for each cell
of an experiment, plus ``<out>/summary.json`` listing the cells. An ``out`` that already holds
results is refused unless ``overwrite=true`` is given or ``dvc.yaml`` declares it (``dvc repro``
removes a stage's outs before it runs it, and keeps them in its cache). Everything is built in
``<out>/.staging-<pid>/`` and moved in only when complete.
"""

from __future__ import annotations

import copy
import json
import os
import shutil
import time
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numba
import yaml
from hydra.core.override_parser.overrides_parser import OverridesParser
from omegaconf import OmegaConf
from tqdm import tqdm

from pipeline.errors import ConfigError, Interrupted, UserError
from pipeline.files import exclusive_folder, swap_in, write_json_atomic
from pipeline.rl.methods import MethodSpec, load_method
from pipeline.rl.rng import run_seeds
from pipeline.rl.runner import TRACE_CAPACITY, make_run_world, run_trials
from pipeline.schema import check
from pipeline.stages._common import CONF_DIR, one_line, stage_main
from pipeline.stages._recognisers import build_recogniser
from pipeline.stages._schema import Experiment, TrialsConfig
from pipeline.world.geometry import build_geometry
from pipeline.world.maze import ACTION_NAMES, MOVES, Layout, load_layout
from pipeline.world.pictures import CATEGORIES

#: Keys a cell may pin; the top level (experiment globals, command line) gives the others. A cell
#: also pins method fields (``params``) and recogniser arguments (``recogniser``).
CELL_KEYS = ("maze", "substitution", "support")

#: The DVC pipeline, whose declared outs the trials may replace without ``overwrite=true``.
DVC_YAML = Path(CONF_DIR).parent / "dvc.yaml"


@dataclass
class CellRun:
    """One cell as it runs: its full single-cell config (what the records embed) and its layout."""

    name: str
    config: TrialsConfig
    layout: Layout
    recogniser: Any = None
    """Built before any cell runs, so a broken checkpoint is refused up front."""
    pictures: dict[int, bytes] = field(default_factory=dict)
    """The query pictures the records keep, by picture id (read up front, like the recogniser)."""
    support: dict[int, list[bytes]] = field(default_factory=dict)
    """The initial support set the records keep: category -> its K shots in position order."""

    @property
    def method(self) -> MethodSpec:
        return self.config.method


def parse_overrides(overrides: list[str]) -> dict[str, Any]:
    """``key -> value`` of the command line's overrides (group choices by group name)."""
    try:
        parsed = OverridesParser.create().parse_overrides(list(overrides))
    except Exception as exc:  # hydra's OverrideParseException; compose has refused these already
        raise ConfigError(one_line(exc)) from None
    return {o.key_or_group: (None if o.is_delete() else o.value()) for o in parsed}


def experiment_cells(cfg: TrialsConfig, overrides: list[str]) -> dict[str, TrialsConfig]:
    """Every cell of ``cfg.experiment`` (listed and generated: :meth:`Experiment.all_cells`) as a
    single-cell config. The command line applies to every cell that does not pin the key; an
    override that no cell can take is refused."""
    exp: Experiment = cfg.experiment
    declared = exp.all_cells()
    if not declared:
        raise ConfigError(f"config key 'experiment.cells': experiment {exp.name!r} has no cells")
    given = parse_overrides(overrides)
    methods = sorted({c.method for c in declared.values()})
    if "method" in given:
        raise ConfigError(
            f"config key 'method': experiment {exp.name} chooses the method of each cell "
            f"({', '.join(methods)}), so the override cannot apply; override a method field instead (method.alpha=...), "
            f"or run method={given['method']} without +experiment"
        )
    method_over = {
        k.removeprefix("method."): v for k, v in given.items() if k.startswith("method.")
    }
    for key in [*CELL_KEYS, *method_over]:
        if key not in given and f"method.{key}" not in given:
            continue
        pinned = [
            n
            for n, c in declared.items()
            if (getattr(c, key) is not None if key in CELL_KEYS else key in c.params)
        ]
        if len(pinned) == len(declared):
            full = key if key in CELL_KEYS else f"method.{key}"
            raise ConfigError(
                f"config key '{full}': every cell of experiment {exp.name} pins it "
                f"(experiment.cells.*.{key if key in CELL_KEYS else 'params.' + key}); "
                "the override cannot apply"
            )
    loaded: dict[
        str, MethodSpec
    ] = {}  # one load per (method, fields): 2,100 generated cells share seven

    def method_of(name: str, cell) -> MethodSpec:
        fields = {**method_over, **cell.params}
        key = json.dumps([cell.method, fields], sort_keys=True, default=str)
        if key not in loaded:
            loaded[key] = load_method(cell.method, fields, key=f"experiment.cells.{name}.method")
        return loaded[key]

    methods = {name: method_of(name, cell) for name, cell in declared.items()}
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
            ],
            default=str,
        )
        if (
            shape not in checked
        ):  # the ranges of a config that differs from one checked only by its maze
            check(cells[name])
            checked.add(shape)
    problems = exp.report.problems(declared) if exp.report is not None else []
    if problems:
        key, problem = problems[0]
        raise ConfigError(f"config key 'experiment.report.{key}': {problem}")
    return cells


def recogniser_group(name: str, key: str) -> dict[str, Any]:
    """The recogniser config ``conf/recogniser/<name>.yaml`` that a cell chooses."""
    folder = Path(CONF_DIR) / "recogniser"
    path = folder / f"{name}.yaml"
    if not path.is_file():
        known = ", ".join(sorted(p.stem for p in folder.glob("*.yaml")))
        raise ConfigError(f"config key '{key}': no recogniser {name!r} (conf/recogniser/: {known})")
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
                raise ConfigError(
                    f"config key 'experiment.cells.{name}.{field_name}': method {methods[name].name} "
                    "recognises no pictures, so the recogniser's arguments cannot apply"
                )
    seeing = [name for name in declared if methods[name].uses_recogniser]
    for key in given:
        if key != "recogniser" and not key.startswith("recogniser."):
            continue
        arg = key.removeprefix("recogniser").removeprefix(".")
        if seeing and all(
            declared[n].recogniser_group or (arg and arg in declared[n].recogniser) for n in seeing
        ):
            raise ConfigError(
                f"config key '{key}': every cell of experiment {exp.name} with a recogniser pins it "
                f"(experiment.cells.*.recogniser.{arg or '<arg>'}) or runs its own "
                "(experiment.cells.*.recogniser_group); the override cannot apply"
            )


#: Command-line keys that only some methods read: (what uses it, test on the cell's method).
ONLY_FOR = {
    "recogniser": (
        "methods that recognise pictures (safety: fewshot)",
        lambda m: m.uses_recogniser,
    ),
    "support": ("methods that recognise pictures (safety: fewshot)", lambda m: m.uses_recogniser),
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
        if head in ONLY_FOR:
            who, uses = ONLY_FOR[head]
            if not any(uses(c.method) for c in configs.values()):
                names = ", ".join(sorted({c.method.name for c in configs.values()}))
                raise ConfigError(
                    f"config key '{key}': read only by {who}; this run has {names}: "
                    "the override cannot apply"
                )


def resolve_cells(cfg: TrialsConfig, overrides: list[str]) -> list[CellRun]:
    """The cells to run, each with its layout loaded and its recogniser built (once for all the
    cells that ask for the same one: :func:`make_recogniser`)."""
    configs = {"": cfg} if cfg.experiment is None else experiment_cells(cfg, overrides)
    refuse_inapplicable(configs, parse_overrides(overrides))
    declared = cfg.experiment.all_cells() if cfg.experiment is not None else {}
    built: dict[str, Any] = {}
    pictures: dict[str, tuple] = {}
    out = []
    for name, cell in configs.items():
        prefix = f"experiment.cells.{name}." if name else ""
        try:
            layout = load_layout(cell.maze)
        except UserError as exc:
            where = generated_key(cfg.experiment, name) if name else None
            raise ConfigError(f"config key '{where or prefix + 'maze'}': {exc}") from None
        pins = name and (declared[name].recogniser or declared[name].recogniser_group)
        recogniser = make_recogniser(cell, f"{prefix}recogniser" if pins else "recogniser", built)
        shown = json.dumps([pictures_dir(cell) if cell.record != "none" else None], default=str)
        if shown not in pictures:
            pictures[shown] = recorded_pictures(cell)
        out.append(CellRun(name, cell, layout, recogniser, *pictures[shown]))
    return out


def generated_key(exp: Experiment | None, name: str) -> str | None:
    """``experiment.layouts.sizes.<i>`` for a cell its layout sets generate, else None."""
    if exp is None or exp.layouts is None or name in exp.cells:
        return None
    for i, s in enumerate(exp.layouts.sizes):
        if f"_{s.size}_L" in name:
            return f"experiment.layouts.sizes.{i}"
    return None


def recogniser_key(cfg: TrialsConfig) -> str | None:
    """What makes two cells' recognisers interchangeable: the recogniser's arguments and the
    substitution way. None where a recogniser must not be shared: no recogniser, or a support set
    carried over from run to run (it is state of the cell's own runs)."""
    method = cfg.method
    if not method.uses_recogniser or cfg.support == "carry":
        return None
    way = cfg.substitution if method.dynamic_support else 0
    return json.dumps([cfg.recogniser, way], sort_keys=True, default=str)


def make_recogniser(cfg: TrialsConfig, key: str = "recogniser", built: dict | None = None):
    """The cell's recogniser (``conf/recogniser/``), or None for methods that see no pictures;
    ``key`` names the config key in an error (a cell's own when it pins recogniser arguments).

    ``built`` (:func:`recogniser_key` -> recogniser) shares one recogniser among cells: each run
    restores its own support set from the original at its start (``start_run``), so a recogniser
    that served other cells' runs gives the same answers (loading the Relation Network once instead
    of once per cell: 600 times in the generalisation experiment)."""
    method = cfg.method
    if not method.uses_recogniser:
        return None
    share = recogniser_key(cfg) if built is not None else None
    if share is not None and share in built:
        return built[share]
    way = cfg.substitution if method.dynamic_support else 0
    recogniser = build_recogniser(
        cfg.recogniser, substitution_way=way, carry_over=cfg.support == "carry", key=key
    )
    if share is not None:
        built[share] = recogniser
    return recogniser


def pictures_dir(cfg: TrialsConfig) -> str | None:
    """The rendered pictures the records keep, for methods that recognise pictures: the recogniser's
    own ``images_dir`` (relation_net), else the trials key ``images_dir`` (oracle, fixed_accuracy)."""
    own = cfg.recogniser.get("images_dir")
    if not cfg.method.uses_recogniser or not (own or cfg.images_dir):
        return None
    if own and cfg.images_dir and Path(own).resolve() != Path(cfg.images_dir).resolve():
        raise ConfigError(
            f"config key 'images_dir': the recogniser reads its pictures from recogniser.images_dir="
            f"{own}, and the records keep those; leave images_dir out"
        )
    return own or cfg.images_dir


def recorded_pictures(cfg: TrialsConfig) -> tuple[dict[int, bytes], dict[int, list[bytes]]]:
    """The query pictures and the initial support set the records keep (none without ``record`` or
    a :func:`pictures_dir`); a folder that is not a rendered dataset is refused, naming the key."""
    images_dir = pictures_dir(cfg) if cfg.record != "none" else None
    if images_dir is None:
        return {}, {}
    try:
        return query_pictures(images_dir), support_pictures(images_dir)
    except (UserError, OSError) as exc:  # no manifest, missing or unreadable pictures
        key = "images_dir" if cfg.images_dir else "recogniser.images_dir"
        raise ConfigError(f"config key '{key}': {one_line(exc)}") from None


def support_pictures(images_dir: str) -> dict[int, list[bytes]]:
    """PNG bytes of the original support set by category, shot ``k`` of category ``c`` where the
    Relation Network's support set holds it (the order of :func:`pipeline.fewshot.data.load_split`)."""
    from pipeline.fewshot.data import load_split

    support = load_split(
        images_dir, "support", 8
    )  # the order and categories; the pixels are read below
    shots: dict[int, list[bytes]] = {}
    for category, file in zip(support.labels.tolist(), support.files):
        shots.setdefault(category, []).append((Path(images_dir) / file).read_bytes())
    return shots


def query_pictures(images_dir: str) -> dict[int, bytes]:
    """PNG bytes of the query pictures by picture id, from the render stage's manifest."""
    import pandas as pd

    manifest = Path(images_dir) / "manifest.csv"
    if not manifest.exists():
        return {}
    df = pd.read_csv(manifest)
    df = df[df["split"] == "query"]
    return {
        int(p): (Path(images_dir) / f).read_bytes() for p, f in zip(df["picture_id"], df["file"])
    }


#: Recorded configs by everything but the maze (cells over generated layouts differ only there;
#: building a structured config takes about 0.1 s, 2,100 times would take minutes).
_RECORDED: dict[str, dict] = {}

#: Keys that say how cells were run, not what: left out of the records, so the records of a cell
#: are the same bytes whether it ran alone or beside others.
NOT_RECORDED = ("workers",)


def recorded_config(cell: CellRun) -> dict:
    """The config embedded in the records: the cell's own, as it ran (without :data:`NOT_RECORDED`)."""
    rest = replace(cell.config, maze="")
    key = repr(rest)
    if key not in _RECORDED:
        whole = OmegaConf.to_container(OmegaConf.structured(rest), resolve=True)
        _RECORDED[key] = {k: v for k, v in whole.items() if k not in NOT_RECORDED}
    return {
        k: (cell.config.maze if k == "maze" else copy.deepcopy(v))
        for k, v in _RECORDED[key].items()
    }


def run_cell(cell: CellRun, folder: Path, progress: bool | None = None) -> tuple[dict, float]:
    """Run one cell into ``folder`` (records, ``summary.json``); its summary and trial seconds.
    ``progress``: the runner's per-episode bar (default ``cfg.progress``)."""
    cfg, layout, method, name = cell.config, cell.layout, cell.method, cell.name
    runs, episodes, seed = cfg.runs, cfg.episodes, cfg.seed
    recogniser = cell.recogniser
    writer = None
    if cfg.record != "none":
        from pipeline.records.writer import RecordWriter

        geometry = build_geometry(layout)
        placements = [
            make_run_world(geometry, seed, r).placement.as_records(layout.obstacles)
            for r in range(runs)
        ]
        writer = RecordWriter(
            folder / "records.mcap",
            metadata={
                "config": recorded_config(cell),
                "seeds": {
                    "seed": seed,
                    "runs": {r: asdict(run_seeds(seed, r)) for r in range(runs)},
                },
                "info": {
                    "cell": name,
                    "method": method.as_dict(),
                    "maze": layout.name,
                    "substitution": cfg.substitution,
                    "support": cfg.support,
                    "recogniser": recogniser.describe()
                    if hasattr(recogniser, "describe")
                    else None,
                },
            },
            maze={
                "layout": list(layout.rows),
                "name": layout.name,
                "categories": list(CATEGORIES),
                "actions": ACTION_NAMES,
                "moves": MOVES,
            },
            runs=placements,
            pictures=cell.pictures,
            support_pictures=cell.support,
            flush_every=cfg.flush_every,
            steps=cfg.record == "steps",
        )
    t0 = time.perf_counter()
    try:
        result = run_trials(
            layout,
            method,
            runs,
            episodes,
            seed,
            recogniser=recogniser,
            sink=writer,
            progress=cfg.progress if progress is None else progress,
            shared_support=cfg.support == "carry",
        )
    except (KeyboardInterrupt, Interrupted) as exc:
        code = exc.code if isinstance(exc, Interrupted) else 130
        if writer is None:
            raise Interrupted(
                code, f"interrupted; nothing recorded (record=none); {folder} left as it was"
            ) from None
        path = writer.close(complete=False)
        raise Interrupted(
            code, f"interrupted; partial records at {path}: {writer.n_episodes} episodes"
        ) from None
    except BaseException:
        if writer is not None:
            writer.close(complete=False)
        raise
    if writer is not None:
        writer.close()
    seconds = time.perf_counter() - t0
    summary = result.summary()
    summary.update(
        {
            "cell": name,
            "method_spec": method.as_dict(),
            "substitution": cfg.substitution,
            "support": cfg.support,
        }
    )
    write_json_atomic(
        folder / "summary.json", summary
    )  # no wall-clock figures: same seed, same bytes
    return summary, seconds


def memory_estimate(cfg: TrialsConfig, layout: Layout) -> int:
    """Bytes the runner's arrays take for one cell (``pipeline.rl.runner.run_trials``): per-episode
    results (22 bytes a run-episode), Q and A_d (36 bytes a run-cell-action), the step trace when
    recording steps (10 bytes x ``TRACE_CAPACITY`` steps a run) and the per-run summaries."""
    per_run = (
        cfg.episodes * 22
        + layout.n_cells * 4 * 9
        + (TRACE_CAPACITY * 10 if cfg.record == "steps" else 0)
        + 2048
    )
    return cfg.runs * per_run


def available_memory() -> int:
    """``MemAvailable`` of /proc/meminfo (bytes); the physical memory where that is missing."""
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except OSError:
        pass
    return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")


def refuse_what_does_not_fit(cfg: TrialsConfig, cells: list[CellRun]) -> None:
    if cfg.threads > numba.config.NUMBA_NUM_THREADS:
        raise ConfigError(
            f"config key 'threads': at most {numba.config.NUMBA_NUM_THREADS} on this machine; got {cfg.threads}"
        )
    need = max(memory_estimate(c.config, c.layout) for c in cells)
    have = available_memory()
    if need > 0.8 * have:
        raise ConfigError(
            f"config keys 'runs'/'episodes': {cfg.runs} runs x {cfg.episodes} episodes need about "
            f"{need / 2**30:,.1f} GiB; this machine has {have / 2**30:,.1f} GiB available"
        )


def run(cfg: TrialsConfig, overrides: list[str]) -> dict:
    cells = resolve_cells(cfg, overrides)
    refuse_what_does_not_fit(cfg, cells)
    if cfg.threads > 0:
        numba.set_num_threads(cfg.threads)
    with exclusive_folder(cfg.out) as out:
        refuse_overwrite(cfg, out)
        staging = out / f".staging-{os.getpid()}"
        shutil.rmtree(staging, ignore_errors=True)
        index = run_cells(cfg, cells, staging)
        swap_in(staging, out)
        for stale in out.glob(".staging-*"):  # partial records of interrupted runs, now superseded
            shutil.rmtree(stale, ignore_errors=True)
            print(f"removed the partial records of an interrupted run: {stale}")
    return index


def written(cfg: TrialsConfig, index: dict) -> list[Path | str]:
    """``out`` (an experiment) or its files (one cell), and the experiment's metrics and timing files."""
    out = Path(cfg.out)
    if cfg.experiment is None:
        return [
            out / "summary.json",
            *([out / "records.mcap"] if cfg.record != "none" else []),
            *filter(None, [cfg.timing_file]),
        ]
    return [out, *filter(None, [cfg.metrics_file, cfg.timing_file])]


def dvc_outs(dvc_yaml: Path) -> set[Path]:
    """The outs ``dvc_yaml`` declares (``foreach`` items filled in), resolved; none without the file."""
    if not dvc_yaml.is_file():
        return set()
    outs = set()
    for stage in (yaml.safe_load(dvc_yaml.read_text()) or {}).get("stages", {}).values():
        body = stage.get("do", stage)
        for item in stage.get("foreach", [None]):
            for out in body.get("outs", []):
                name = next(iter(out)) if isinstance(out, dict) else out
                outs.add((dvc_yaml.parent / name.replace("${item}", str(item))).resolve())
    return outs


def refuse_overwrite(cfg: TrialsConfig, out: Path) -> None:
    """Results already in ``out`` (anything but hidden entries: the lock, staging folders) are
    replaced only with ``overwrite=true``, or when ``dvc.yaml`` declares ``out``."""
    held = sorted(p.name for p in out.iterdir() if not p.name.startswith("."))
    if not held or cfg.overwrite or out.resolve() in dvc_outs(DVC_YAML):
        return
    shown = ", ".join(held[:3]) + (", ..." if len(held) > 3 else "")
    raise ConfigError(
        f"config key 'out': {out} already holds results ({shown}); give overwrite=true to "
        "replace them, or choose another out"
    )


#: Above this many cells an experiment's progress is a bar (or a line per tenth), not a line per cell.
COMPACT_AT = 30


def cell_line(cfg: TrialsConfig, cell: CellRun, summary: dict, seconds: float) -> str:
    c = summary["collisions"]
    label = f"{cell.name}: " if cell.name else ""
    return (
        f"{label}{cell.method.name} on {cell.layout.name}: collisions {c['mean']:.2f} +- {c['std']:.2f} over "
        f"{cfg.runs} runs, converged runs {summary['converged_runs']} ({seconds:.1f} s)"
    )


def results(
    cfg: TrialsConfig, cells: list[CellRun], out: Path, progress: bool
) -> Iterator[tuple[int, dict, float]]:
    """``(index, summary, seconds)`` of every cell as it completes: one after another, or in
    ``cfg.workers`` processes (:mod:`pipeline.stages._workers`, without per-episode bars);
    ``progress``: each cell's per-episode bar."""
    folders = [out / c.name if c.name else out for c in cells]
    if cfg.workers > 1 and len(cells) > 1:
        from pipeline.stages._workers import run_parallel

        try:
            yield from run_parallel(cells, folders, min(cfg.workers, len(cells)), cfg.threads)
        except (
            KeyboardInterrupt,
            Interrupted,
        ) as exc:  # the workers are stopped: say where the records are
            code = exc.code if isinstance(exc, Interrupted) else 130
            raise Interrupted(
                code, f"interrupted; the finished cells' records are under {out}"
            ) from None
        return
    for i, (cell, folder) in enumerate(zip(cells, folders)):
        yield i, *run_cell(cell, folder, progress)


def run_cells(cfg: TrialsConfig, cells: list[CellRun], out: Path) -> dict:
    """Every cell into ``out`` (the staging folder); the experiment's index and metrics last, in
    cell order whatever the order the cells finished in. Up to :data:`COMPACT_AT` cells, one line
    each; more: a progress bar on a terminal (a line per tenth of the cells elsewhere) and a
    closing line with the totals."""
    by_index: dict[int, tuple[dict, float]] = {}
    compact = len(cells) > COMPACT_AT
    t0 = time.perf_counter()
    bar = tqdm(
        total=len(cells),
        unit="cell",
        desc=cfg.experiment.name if cfg.experiment else "trials",
        disable=None if (compact and cfg.progress) else True,
    )
    tenth = max(1, len(cells) // 10)
    with bar:
        for i, summary, seconds in results(cfg, cells, out, cfg.progress and not compact):
            by_index[i] = (summary, seconds)
            if not compact:
                print(cell_line(cfg, cells[i], summary, seconds))
            elif bar.disable and (len(by_index) % tenth == 0 or len(by_index) == len(cells)):
                print(
                    f"{len(by_index)}/{len(cells)} cells ({time.perf_counter() - t0:.0f} s)",
                    flush=True,
                )
            bar.update()
    summaries = {cells[i].name: by_index[i][0] for i in range(len(cells))}
    timing = {cells[i].name: by_index[i][1] for i in range(len(cells))}
    if compact:
        steps = sum(r["steps"] for s in summaries.values() for r in s["runs"])
        wall = time.perf_counter() - t0
        print(
            f"{len(cells)} cells x {cfg.runs} runs x {cfg.episodes} episodes: {steps:,} agent steps in {wall:.1f} s "
            f"({steps / max(wall, 1e-9):,.0f} steps/s, {cfg.workers} worker{'s' if cfg.workers > 1 else ''})"
        )
    if cfg.timing_file:
        write_json_atomic(cfg.timing_file, {n: round(t, 3) for n, t in timing.items()})
    if "" in summaries:
        return summaries[""]
    index = {
        "experiment": cfg.experiment.name,
        "cells": {
            n: {
                k: s[k]
                for k in (
                    "method",
                    "maze",
                    "substitution",
                    "support",
                    "collisions",
                    "converged_runs",
                )
            }
            for n, s in summaries.items()
        },
    }
    write_json_atomic(out / "summary.json", index)
    if cfg.metrics_file:
        write_json_atomic(
            cfg.metrics_file,
            {
                n: {
                    "collisions_mean": s["collisions"]["mean"],
                    "collisions_std": s["collisions"]["std"],
                    "converged_runs": s["converged_runs"],
                }
                for n, s in summaries.items()
            },
        )
    return index


def main() -> None:
    stage_main("trials", run)
