"""The code dependencies and the config parameters of every stage of ``dvc.yaml``, derived.

``python -m scripts.dvc_deps`` checks ``dvc.yaml`` (exit 1 naming each stage that differs);
``python -m scripts.dvc_deps --write`` rewrites it. Nothing here is a hand-kept list:

- **deps (code)**: the import closure of the stage's command, ``python -m pipeline <stage>``:
  ``pipeline/__main__.py``, ``pipeline/stages/<stage>.py``, the schema module the stage composes
  its config with (``pipeline.config.registry.SCHEMA_OF``, imported by name) and the module of every
  ``_target_`` its recogniser files name (imported by Hydra), with every module they import
  (the import graph of import-linter's ``grimp``, imports inside functions included, imports for
  type checkers only left out), every package above them (its ``__init__.py`` runs first), and
  the config folders the code reads as data (``conf_dir("mazes")``, ``CONF_DIR) / "experiment"``).
  A folder whose every file is in the closure is listed as the folder. The experiment file the
  command composes is a dependency too, whole (:data:`STRUCTURE_GROUPS`): it declares cells and
  how the report presents them, structure rather than knobs, and as parameters its cell tables
  and quoted claims made ``dvc params diff`` hundreds of lines, each over a thousand characters.
- **params**: the other files Hydra composes for the command: the stage's file (whole, or without
  the keys its schema declares ``OUTPUT_NEUTRAL``: where outputs go, progress, threads), every
  group file it chooses (whole: a model, a recogniser, a data source; the methods and recognisers
  an experiment's cells name), and of a profile only the keys the composed config reads
  (``${profile.<stage>.<key>}``).

The hand-written parts of dvc.yaml stay: commands, data dependencies (``datasets/...``), outs,
metrics and comments. The generated lines follow a ``# code:`` and a ``# config:`` comment.
"""

from __future__ import annotations

import ast
import re
import shlex
import sys
from functools import cache
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = "pipeline"
DVC_YAML = ROOT / "dvc.yaml"
CODE_MARK = "# code: the import closure of `{cmd}` (python -m scripts.dvc_deps --write)"
CONFIG_MARK = "# config: the files Hydra composes for `{cmd}` (python -m scripts.dvc_deps --write)"
INTERPOLATION = re.compile(r"\$\{profile\.([\w.]+)\}")
WRAP = 100
INDEX_DIR = "datasets/index/"
EXPERIMENT_ITEM = "+experiment=${item}"
RECORDS_MARK = "# records: every experiment's index (python -m scripts.dvc_deps --write)"
#: Config groups whose files are dependencies (whole files), not parameters (module docstring).
STRUCTURE_GROUPS = ("experiment",)
#: The module that imports every recogniser's ``_target_`` (the report's names and colours come
#: from the classes): a stage that imports it depends on every recogniser's module.
EVERY_RECOGNISER = "pipeline.report.names"


def relative(path: Path) -> str:
    return path.resolve().relative_to(ROOT).as_posix()


@cache
def conf_root() -> Path:
    from pipeline.config.folder import conf_dir

    return conf_dir()


def derived_roots() -> tuple[str, str]:
    """The folders whose files this script derives deps on: the package and its configs."""
    return PACKAGE, relative(conf_root())


@cache
def import_graph():
    import grimp

    return grimp.build_graph(PACKAGE, cache_dir=None, exclude_type_checking_imports=True)


def module_file(module: str) -> Path:
    base = ROOT.joinpath(*module.split("."))
    return base / "__init__.py" if base.is_dir() else base.with_suffix(".py")


def module_of(target: str) -> str:
    """The module that defines ``target`` (``pkg.mod.Class.method`` -> ``pkg.mod``)."""
    parts = target.split(".")
    while parts and ".".join(parts) not in import_graph().modules:
        parts.pop()
    if not parts:
        raise ValueError(f"_target_ {target!r} is not in the {PACKAGE} package")
    return ".".join(parts)


def closure(entries: set[str]) -> set[str]:
    """The modules ``entries`` import, directly or not, with the packages above every one."""
    graph = import_graph()
    found = set(entries)
    for module in entries:
        found |= graph.find_upstream_modules(module)
    parents = {".".join(m.split(".")[:i]) for m in found for i in range(1, m.count(".") + 1)}
    return found | parents


def conf_folders_read(modules: set[str]) -> set[str]:
    """The config folders the ``modules`` read as data (not through Hydra): the code's calls
    ``conf_dir("<folder>", ...)`` and paths ``Path(CONF_DIR) / "<folder>"``."""
    out = set()
    for module in modules:
        for node in ast.walk(ast.parse(module_file(module).read_text())):
            folder = conf_folder(node)
            if folder:
                out.add(relative(conf_root() / folder))
    return out


def conf_folder(node: ast.AST) -> str | None:
    def name(n: ast.AST) -> str:
        return getattr(n, "id", getattr(n, "attr", ""))

    def text(n: ast.AST) -> str | None:
        return n.value if isinstance(n, ast.Constant) and isinstance(n.value, str) else None

    if isinstance(node, ast.Call) and name(node.func) == "conf_dir" and node.args:
        return text(node.args[0])
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Div):
        left = node.left
        if isinstance(left, ast.Call) and left.args and name(left.args[0]) == "CONF_DIR":
            return text(node.right)
    return None


def files_under(folder: Path) -> list[Path]:
    ignored = ("__pycache__", ".pyc")
    return [
        p
        for p in folder.rglob("*")
        if p.is_file() and not any(part.endswith(ignored) for part in p.parts)
    ]


def folded(files: set[str]) -> list[str]:
    """``files`` with every folder whose files are all among them named as the folder."""
    out, covered = set(), set()
    for folder in sorted({str(Path(f).parent) for f in files}, key=len):
        if any(folder == c or folder.startswith(c + "/") for c in covered):
            continue
        inside = {relative(p) for p in files_under(ROOT / folder)}
        if folder != PACKAGE and inside and inside <= files:
            out.add(folder)
            covered.add(folder)
    loose = {f for f in files if not any(f.startswith(c + "/") for c in covered)}
    return sorted(out | loose)


def parse_cmd(cmd: str) -> tuple[str, list[str]]:
    """``python -m pipeline <stage> [overrides]`` -> the stage and its config overrides."""
    words = shlex.split(cmd)
    if words[:3] != ["python", "-m", PACKAGE] or len(words) < 4:
        raise ValueError(f"not a stage command: {cmd!r}")
    return words[3], [w for w in words[4:] if "=" in w]


def compose(stage: str, overrides: list[str]):
    """The composed config (interpolations unresolved) and Hydra's group choices."""
    from hydra import compose as hydra_compose
    from omegaconf import OmegaConf

    from pipeline.config.folder import hydra_configs
    from pipeline.config.registry import register

    register(stage)
    with hydra_configs():
        cfg = hydra_compose(config_name=stage, overrides=overrides, return_hydra_config=True)
    choices = {
        group: choice
        for group, choice in OmegaConf.to_container(cfg.hydra.runtime.choices).items()
        if choice and not group.startswith("hydra/")
    }
    config = OmegaConf.to_container(cfg, resolve=False)
    config.pop("hydra")
    return config, choices


def recogniser_names() -> list[str]:
    return sorted(p.stem for p in (conf_root() / "recogniser").glob("*.yaml"))


def experiments() -> list[str]:
    """The experiments of ``conf/experiment/``, in the report's order."""

    def order(path: Path) -> tuple:
        experiment = (yaml.safe_load(path.read_text()) or {}).get("experiment") or {}
        return (experiment.get("report") or {}).get("order", float("inf")), path.stem

    return [p.stem for p in sorted((conf_root() / "experiment").glob("*.yaml"), key=order)]


def cells_read(config: dict) -> tuple[set[str], set[str]]:
    """The methods and recogniser groups an experiment's cells name."""
    experiment = config.get("experiment") or {}
    cells = [
        *(experiment.get("cells") or {}).values(),
        *((experiment.get("layouts") or {}).get("cells") or {}).values(),
    ]
    methods = {c["method"] for c in cells if c.get("method")}
    recognisers = {c["recogniser_group"] for c in cells if c.get("recogniser_group")}
    return methods, recognisers


class Stage:
    """One stage of dvc.yaml (a ``foreach`` stage: every item) as its command composes it."""

    def __init__(self, name: str, definition: dict):
        self.name = name
        body = definition.get("do", definition)
        self.template = body["cmd"]
        self.items = experiments() if EXPERIMENT_ITEM in self.template else [None]
        self.outs = [next(iter(o)) if isinstance(o, dict) else o for o in body.get("outs", [])]
        self.stage, _ = parse_cmd(self.template.replace("${item}", "ITEM"))
        self.groups: dict[str, set[str]] = {}
        self.profile_keys: set[str] = set()
        for item in self.items:
            cmd = self.template.replace("${item}", item) if item else self.template
            config, choices = compose(*parse_cmd(cmd))
            for group, choice in choices.items():
                self.groups.setdefault(group, set()).add(choice)
            methods, recognisers = cells_read(config)
            self.groups.setdefault("method", set()).update(methods)
            self.groups.setdefault("recogniser", set()).update(recognisers)
            self.profile_keys |= set(INTERPOLATION.findall(yaml.safe_dump(config)))
        self.groups = {g: c for g, c in self.groups.items() if c}

    @property
    def command(self) -> str:
        return f"python -m {PACKAGE} {self.stage}"

    def group_file(self, group: str, choice: str) -> str:
        if group == "experiment" and self.items != [None]:
            choice = "${item}"
        return relative(conf_root() / group / f"{choice}.yaml")

    def recogniser_targets(self, every: bool = False) -> set[str]:
        """The modules of the recognisers the command chooses (``every``: of all of them)."""
        out = set()
        chosen = self.groups.get("recogniser", ())
        for choice in recogniser_names() if every else chosen:
            node = yaml.safe_load((conf_root() / "recogniser" / f"{choice}.yaml").read_text())
            out.add(module_of(str(node["_target_"])))
        return out

    def code(self) -> list[str]:
        from pipeline.config.registry import SCHEMA_OF

        entries = {
            f"{PACKAGE}.__main__",
            f"{PACKAGE}.stages.{self.stage}",
            SCHEMA_OF[self.stage].split(":")[0],
            *self.recogniser_targets(),
        }
        modules = closure(entries)
        if EVERY_RECOGNISER in modules:
            modules = closure(entries | self.recogniser_targets(every=True))
        files = {relative(module_file(m)) for m in modules}
        return folded(files) + sorted(conf_folders_read(modules)) + self.structure_files()

    def structure_files(self) -> list[str]:
        """The files of :data:`STRUCTURE_GROUPS` the command composes (dependencies, whole)."""
        files = (
            self.group_file(group, choice)
            for group in STRUCTURE_GROUPS
            for choice in sorted(self.groups.get(group, ()))
        )
        return list(dict.fromkeys(files))  # a foreach stage's items: one ``${item}`` file

    def params(self) -> list[tuple[str, list[str]]]:
        """(file, keys) pairs; no keys: the whole file."""
        from pipeline.config.registry import schema_of

        stage_file = conf_root() / f"{self.stage}.yaml"
        neutral = set(getattr(schema_of(self.stage), "OUTPUT_NEUTRAL", ()))
        keys = [k for k in yaml.safe_load(stage_file.read_text()) if k not in neutral]
        out = [(relative(stage_file), keys if neutral else [])]
        for group in sorted(self.groups):
            if group == "profile" or group in STRUCTURE_GROUPS:
                continue
            files = dict.fromkeys(self.group_file(group, c) for c in sorted(self.groups[group]))
            out += [(file, []) for file in files]
        for choice in sorted(self.groups.get("profile", ())):
            out.append((self.group_file("profile", choice), sorted(self.profile_keys)))
        return out


def flow_list(keys: list[str], indent: int, head: str) -> list[str]:
    """``head [a, b, ...]`` wrapped at :data:`WRAP` columns, continuation lines under the first key."""
    lines, line = [], f"{' ' * indent}{head}["
    hang = " " * len(line)
    for i, key in enumerate(keys):
        word = key + (", " if i < len(keys) - 1 else "]")
        if len(line) + len(word.rstrip()) > WRAP and line.strip() != head.strip() + "[":
            lines.append(line.rstrip())
            line = hang
        line += word
    return [*lines, line]


def params_lines(stage: Stage, indent: int) -> list[str]:
    lines = [" " * indent + CONFIG_MARK.format(cmd=stage.command)]
    for file, keys in stage.params():
        if keys:
            lines += flow_list(keys, indent, f"- {file}: ")
        else:
            lines.append(f"{' ' * indent}- {file}:")
    return lines


def code_lines(stage: Stage, indent: int) -> list[str]:
    pad = " " * indent
    return [pad + CODE_MARK.format(cmd=stage.command), *(f"{pad}- {d}" for d in stage.code())]


def rewritten(text: str, stages: dict[str, Stage]) -> str:
    """``text`` (dvc.yaml) with each stage's code deps and params replaced by the derived ones."""
    lines, out, i = text.splitlines(), [], 0
    current = None
    while i < len(lines):
        line = lines[i]
        top = re.match(r"^  ([\w-]+):\s*(#.*)?$", line)
        if top and top[1] in stages:
            current = stages[top[1]]
        each = re.match(r"^(\s+)foreach:", line)
        if each and current and current.items != [None]:
            out += flow_list(current.items, len(each[1]), "foreach: ")
            while "]" not in lines[i]:  # a flow list wrapped over several lines
                i += 1
            i += 1
            continue
        key = re.match(r"^(\s+)(deps|params):\s*$", line)
        if not (key and current):
            out.append(line)
            i += 1
            continue
        indent = len(key[1]) + 2
        block, i = [], i + 1
        while i < len(lines) and (not lines[i].strip() or indent_of(lines[i]) >= indent):
            block.append(lines[i])
            i += 1
        out.append(line)
        if key[2] == "params":
            out += params_lines(current, indent)
        else:
            records = records_lines(current, stages, indent)
            kept = [b for b in block if is_data_dep(b) and not (records and is_records_dep(b))]
            out += records + kept + code_lines(current, indent)
    return "\n".join(out) + "\n"


def records_lines(stage: Stage, stages: dict[str, Stage], indent: int) -> list[str]:
    """The report's dependencies on the records: the index (``datasets/index/...``) each stage that
    runs an experiment writes, for every experiment."""
    if stage.stage != "report":
        return []
    pad = " " * indent
    indexes = [
        out.replace("${item}", item)
        for s in stages.values()
        if s.items != [None]
        for out in s.outs
        if out.startswith(INDEX_DIR)
        for item in s.items
    ]
    return [pad + RECORDS_MARK, *(f"{pad}- {index}" for index in indexes)]


def is_records_dep(line: str) -> bool:
    return line.strip().startswith(f"- {INDEX_DIR}runs/")


def indent_of(line: str) -> int:
    return len(line) - len(line.lstrip())


def is_data_dep(line: str) -> bool:
    """A hand-written dependency (data, not code): a list item outside the package and its configs."""
    item = line.strip()
    return item.startswith("- ") and not item[2:].startswith(
        tuple(f"{r}/" for r in derived_roots())
    )


def stages_of(text: str) -> dict[str, Stage]:
    definitions = yaml.safe_load(text)["stages"]
    return {name: Stage(name, d) for name, d in definitions.items()}


def derived(text: str | None = None) -> str:
    """dvc.yaml as it should read."""
    text = DVC_YAML.read_text() if text is None else text
    return rewritten(text, stages_of(text))


def main(argv: list[str]) -> int:
    text = DVC_YAML.read_text()
    wanted = derived(text)
    if "--write" in argv:
        DVC_YAML.write_text(wanted)
        print(f"wrote {relative(DVC_YAML)}")
        return 0
    if wanted == text:
        print(f"{relative(DVC_YAML)}: every stage's deps and params are the derived ones")
        return 0
    import difflib

    diff = difflib.unified_diff(text.splitlines(), wanted.splitlines(), "dvc.yaml", "derived", n=1)
    print("\n".join(diff))
    print("dvc.yaml differs from the derived deps and params: python -m scripts.dvc_deps --write")
    return 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
