"""Build ``reports/`` from the recorded data alone (paper Tables 1-3, Figures 7-10): the records
of the experiments (a section each, :mod:`pipeline.report.sections`), the accuracy studies, the
models' metrics and the render stage's contact sheets.

Outputs: ``index.md``, ``headline.json`` (:mod:`pipeline.report.headline`), ``tables/*.md|csv``,
``figures/*.png``, swapped in whole (docs/reliability.md, "The report"); the rest of the folder, e.g.
``benchmarks/``, is left alone. The same records give the same bytes. On a terminal a progress bar
names the part being built; elsewhere a line per part says how far the build is.
"""

from __future__ import annotations

import shutil
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path

import pandas as pd
from tqdm import tqdm

from pipeline.files import claim_folder, remove_abandoned, swap_in, work_folder, write_json_atomic
from pipeline.report.accuracy import accuracy_tables
from pipeline.report.claims_section import claims_section
from pipeline.report.experiments import ReportInputError, load_all
from pipeline.report.headline import headline
from pipeline.report.names import PAPER_RECOGNISER
from pipeline.report.network_accuracy import network_accuracy_section
from pipeline.report.scale import check_scales, scales, title_and_scale
from pipeline.report.sections import section


@dataclass
class Inputs:
    runs_dir: Path
    accuracy_dir: Path
    model_metrics: Path
    contact_dir: Path
    out: Path
    experiments_dir: Path | None = None  # conf/experiment/: which experiments have no records
    allow_missing: bool = False  # build without missing experiments/cells, saying so at the top
    allow_mixed_scales: bool = False  # build from records of different profiles, named at the top
    profiles: dict[str, dict] = field(default_factory=dict)
    """The profiles' ``trials`` blocks by name (``conf/profile/``): a record's scale."""
    beside: dict[str, tuple[Path, Path]] = field(default_factory=dict)
    """Other recognisers for Tables 1-2, by kind: (accuracy study folder, metrics file)."""
    models: dict[str, Path] = field(default_factory=dict)
    """The meta-trained models' metrics files by model name: ``headline.json``'s accuracies."""
    networks_accuracy_dir: Path | None = None
    """The other networks' accuracy studies (:mod:`pipeline.report.network_accuracy`)."""


class Report:
    """Collects Markdown sections while tables and figures are written; ``accuracy_dir``: the
    accuracy study's data files, for sections that mark the Relation Network's accuracy."""

    def __init__(self, out: Path, accuracy_dir: Path | None = None):
        self.out = out
        self.accuracy_dir = accuracy_dir
        self.sections: list[str] = []
        (out / "tables").mkdir(parents=True, exist_ok=True)
        (out / "figures").mkdir(parents=True, exist_ok=True)

    def add(self, text: str) -> None:
        self.sections.append(text.rstrip() + "\n")

    def data(self, name: str, df: pd.DataFrame, **options) -> None:
        """``tables/<name>.csv``, the data of a table or figure (``options``: ``float_format``)."""
        df.to_csv(self.out / "tables" / f"{name}.csv", index=False, lineterminator="\n", **options)

    def table(self, name: str, df: pd.DataFrame, caption: str) -> None:
        self.data(name, df)
        md = df.to_markdown(index=False)
        (self.out / "tables" / f"{name}.md").write_text(f"{caption}\n\n{md}\n")
        self.add(f"{caption}\n\n{md}\n\n(`tables/{name}.csv`)\n")

    def figure(self, rel: str, caption: str) -> None:
        self.add(f"![{caption}]({rel})\n\n*{caption}*\n")

    def write(self) -> Path:
        path = self.out / "index.md"
        path.write_text("\n".join(self.sections))
        return path


#: What each of the render stage's contact sheets shows (its row labels included), by file stem.
SHEETS = {
    "contact_query": "The 40 query pictures the robot takes in the maze: two rows per category, its "
    "two objects (two different chairs, kettles, ...), each seen from the north, east, south and "
    "west (left to right).",
    "contact_support": "The support set: five catalogue photographs per category, each of another "
    "instance than the obstacle in the maze, a row per category.",
    "contact_train": "The training families (procedural objects of any colour; a row per family, "
    "its parts from the bottom up, five of its pictures).",
    "contact_val": "The validation families: held out from training, they choose the checkpoint; "
    "each at least the render's min_family_distance (2: two whole parts) from every training family.",
    "contact_test": "The test families: held out from training and from the choice of checkpoint, each at "
    "least the render's min_family_distance from every training family; the quoted accuracy is theirs.",
    "contact_views": "Views of the query obstacles for the colour test: each of the ten obstacles "
    "(a row each) from random sides and distances in the maze; the first few of its views.",
}


def contact_sheets(rep: Report, contact_dir: Path) -> None:
    sheets = sorted(contact_dir.glob("*.png")) if contact_dir.is_dir() else []
    if not sheets:
        return
    rep.add("## The datasets\n")
    for sheet in sheets:
        target = rep.out / "figures" / sheet.name
        shutil.copyfile(sheet, target)
        words = SHEETS.get(sheet.stem, f"The pictures of {sheet.stem.replace('_', ' ')}.")
        rep.figure(f"figures/{sheet.name}", words)


def build_report(inputs: Inputs) -> Path:
    """Build the report into a temporary folder beside ``out`` and swap ``index.md``,
    ``headline.json``, ``tables/`` and ``figures/`` in only when it is complete: a failed build
    leaves the previous report whole."""
    out = inputs.out
    out.mkdir(parents=True, exist_ok=True)
    staging = work_folder(out, ".building")
    try:
        claim_folder(staging)
        _build(replace(inputs, out=staging))
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    swap_in(staging, out)
    remove_abandoned(out, ".building")  # left by killed builds (never a live one's)
    return out / "index.md"


def _build(inputs: Inputs) -> Path:
    with (
        tqdm(total=3, desc="report", unit="part", disable=None) as bar,
        ticking(bar),
    ):  # None: only on a terminal
        return _build_parts(inputs, Parts(bar, 3))


@contextmanager
def ticking(bar: tqdm, every: float = 1.0):
    """Redraw ``bar`` every ``every`` seconds, so its clock moves while a long part runs."""
    done = threading.Event()

    def tick() -> None:
        while not done.wait(every):
            bar.refresh()

    thread = threading.Thread(target=tick, daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join()


class Parts:
    """The report's parts as it builds them: named on ``bar``, and without a terminal (``dvc
    repro``, where the bar is off) in a line that says how many parts are done, the time so far
    and, at the pace so far, the time left."""

    def __init__(self, bar: tqdm, total: int):
        self.bar, self.total, self.done = bar, total, 0
        self.started = time.perf_counter()
        self.paced_from = (self.started, 0)  # the parts after the records: the pace of the rest

    def building(self, part: str) -> None:
        self.bar.set_postfix_str(part)
        if self.bar.disable:
            now, (since, done_then) = time.perf_counter(), self.paced_from
            paced = self.done - done_then
            left = (
                f", about {(now - since) / paced * (self.total - self.done):.0f} s left"
                if paced
                else ""
            )
            elapsed = now - self.started
            print(
                f"[report] {part}: {self.done}/{self.total} parts done ({elapsed:.0f} s{left})",
                flush=True,
            )

    def reading(self, folder: str, read: int, total: int) -> None:
        """The records of ``folder`` are next: ``read`` of ``total`` bytes so far (the first part,
        most of the time), the time left at the pace so far."""
        self.bar.set_postfix_str(f"reading the records of {folder}")
        if self.bar.disable:
            elapsed = time.perf_counter() - self.started
            left = f", about {elapsed / read * (total - read):.0f} s left" if read else ""
            print(
                f"[report] reading the records of {folder}: {read / 1e6:,.0f} of "
                f"{total / 1e6:,.0f} MB read ({elapsed:.0f} s{left})",
                flush=True,
            )

    def more(self, parts: int) -> None:
        """``parts`` more to build, known once the records are read: the pace starts again (reading
        the records is the long first part, and no guide to the rest)."""
        self.total += parts
        self.bar.total = self.total
        self.paced_from = (time.perf_counter(), self.done + 1)

    def finished(self) -> None:
        self.done += 1
        self.bar.update()


def _build_parts(inputs: Inputs, parts: Parts) -> Path:
    """The report, part by part (``parts`` names the one being built and counts those done)."""
    rep = Report(inputs.out, inputs.accuracy_dir)
    experiments = load_all(inputs.runs_dir, parts.reading)
    found = scales(experiments, inputs.profiles)
    check_scales(found, inputs.runs_dir, inputs.allow_mixed_scales)
    title, scale = title_and_scale(
        found, "Few-shot reasoning-based safe RL: our results beside the paper's"
    )
    rep.add(f"# {title}\n\n{scale}\n")
    rep.add(
        "Built by `python -m pipeline report` from the recorded data only (MCAP records of every "
        "episode, the accuracy study's data files, the model's validation metrics). Collisions are "
        "mean ± standard deviation over runs with a 95% percentile-bootstrap interval of the mean "
        "(2000 resamples, seed 0); a pooled row pools its cells' runs, and the runs of a carried-over "
        "support set are one robot's consecutive experiments, not independent ones. Accuracies carry "
        "the interval their table names. Learning curves show the mean over runs per episode with its "
        "95% t interval shaded.\n"
    )
    parts.more(len(experiments))
    parts.finished()
    refuse_missing(rep, inputs, experiments)
    parts.building("claims")
    studies = [inputs.accuracy_dir, *(folder for folder, _ in inputs.beside.values())]
    claims = claims_section(rep, experiments, studies)
    write_json_atomic(inputs.out / "headline.json", headline(claims, inputs.models, experiments))
    parts.building("accuracy")
    accuracy_tables(rep, inputs.accuracy_dir, inputs.model_metrics, inputs.beside)
    if inputs.networks_accuracy_dir is not None:
        seed0 = {PAPER_RECOGNISER: inputs.accuracy_dir}
        seed0.update((kind, folder) for kind, (folder, _) in inputs.beside.items())
        network_accuracy_section(rep, seed0, inputs.networks_accuracy_dir)
    parts.finished()
    not_shown = []
    for exp in experiments:
        parts.building(exp.folder)
        not_shown += section(rep, exp, experiments)
        parts.finished()
    parts.building("contact sheets")
    contact_sheets(rep, inputs.contact_dir)
    if not_shown:
        rep.add(f"Not in this report (no records found): {', '.join(not_shown)}.\n")
    parts.finished()
    return rep.write()


def refuse_missing(rep: Report, inputs: Inputs, experiments: list) -> None:
    """Nothing to report, or experiment files and cells without complete records: refused, unless
    ``allow_missing`` (then the report says at the top what it lacks)."""
    if not experiments and not inputs.accuracy_dir.exists():
        raise ReportInputError(
            f"nothing to report: no experiments under {inputs.runs_dir} and no "
            f"{inputs.accuracy_dir}"
        )
    recorded = {e.name for e in experiments} | {e.folder for e in experiments}
    folder = inputs.experiments_dir
    files = sorted(folder.glob("*.yaml")) if folder and folder.is_dir() else []
    missing = [f"experiment {p.stem}" for p in files if p.stem not in recorded]
    missing += [f"cell {e.folder}/{c}" for e in experiments for c in e.missing]
    if missing and not inputs.allow_missing:
        raise ReportInputError(
            f"no complete records for {', '.join(missing)} under {inputs.runs_dir}; run their "
            "trials, or build without them with allow_missing=true"
        )
    if missing:
        rep.add(
            f"**Missing from this report** (no complete records; built with `allow_missing=true`): "
            f"{', '.join(missing)}.\n"
        )
