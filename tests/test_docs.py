"""The docs speak only of what is in the repository, and the defaults they quote are the configs'.

A default is quoted as ``key=value`` in backticks followed by "by default" (several may share it:
"`a=1`, `b=2` and `c=3` by default"); the key is one of a stage's config
(``conf/<stage>.yaml`` composed, profile ``paper``), written ``<stage>.<key>`` where stages
disagree.
"""

import re
import subprocess
from collections import Counter
from functools import cache
from pathlib import Path

import pytest
import yaml
from omegaconf import OmegaConf

from pipeline.__main__ import available_stages
from pipeline.config.compose import compose

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

#: Things outside the repository that docs once named.
OUTSIDE = ("../shared", "/work/", "FIELD-NOTES", "DESIGN.md")
#: Not docs: generated outputs (they record the paths they were made with) and this file.
NOT_DOCS = ("datasets/", "reports/", "tests/test_docs.py")

CLAIMS = re.compile(r"((?:`[\w.]+=[^`]*`(?:,\s+|\s+and\s+)?)+)\s+by\s+default")
ITEM = re.compile(r"`([\w.]+)=([^`]*)`")


def tracked_files() -> list[Path]:
    try:
        names = subprocess.run(
            ["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True
        ).stdout
    except (OSError, subprocess.CalledProcessError):  # not a git checkout: every file
        return [p for p in ROOT.rglob("*") if p.is_file() and ".git" not in p.parts]
    return [ROOT / n for n in names.splitlines()]


#: Docs teach; measurements live in benchmark outputs and history in CHANGELOG.md, so each page stays short.
MAX_DOC_CHARS = 12_000


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_each_doc_is_under_the_size_limit(doc):
    n = len(doc.read_text())
    assert n < MAX_DOC_CHARS, (
        f"{doc.relative_to(ROOT)}: {n:,} characters, the limit is {MAX_DOC_CHARS:,}: move "
        "measurements to a benchmark output and history to CHANGELOG.md"
    )


def test_no_doc_points_outside_the_repository():
    found = []
    for path in tracked_files():
        rel = path.relative_to(ROOT).as_posix()
        if rel.startswith(NOT_DOCS) or not path.is_file():
            continue
        try:
            text = path.read_text()
        except UnicodeDecodeError:
            continue
        found += [
            f"{rel}:{n}: {word}"
            for n, line in enumerate(text.splitlines(), 1)
            for word in OUTSIDE
            if word in line
        ]
    assert not found, "\n".join(found)


def test_references_to_readme_sections_name_its_headings():
    headings = [
        line.lstrip("#").strip()
        for line in (ROOT / "README.md").read_text().splitlines()
        if line.startswith("#")
    ]
    wrong = []
    for path in tracked_files():
        rel = path.relative_to(ROOT).as_posix()
        if (
            rel.startswith(NOT_DOCS)
            or path.suffix not in (".py", ".md", ".yaml", "")
            or not path.is_file()
        ):
            continue
        text = " ".join(path.read_text().split())  # a reference may be wrapped over two lines
        wrong += [
            f"{rel}: README {name!r}"
            for name in re.findall(r'README "([^"]+)"', text)
            if not any(h.startswith(name) for h in headings)
        ]
    assert not wrong, "\n".join(wrong)


def test_references_to_doc_sections_name_their_headings():
    """``docs/<page>.md "Heading"`` in code, configs and docs names a heading of that page."""
    headings = {
        doc.name: [
            line.lstrip("#").strip()
            for line in doc.read_text().splitlines()
            if line.startswith("#")
        ]
        for doc in DOCS[1:]
    }
    wrong = []
    for path in tracked_files():
        rel = path.relative_to(ROOT).as_posix()
        if (
            rel.startswith(NOT_DOCS)
            or path.suffix not in (".py", ".md", ".yaml", "")
            or not path.is_file()
        ):
            continue
        text = " ".join(path.read_text().split())
        for page, name in re.findall(r'docs/(\w+\.md),? "([^"]+)"', text):
            if page not in headings:
                wrong.append(f"{rel}: no page docs/{page}")
            elif not any(h.startswith(name) for h in headings[page]):
                wrong.append(f"{rel}: docs/{page} {name!r}")
    assert not wrong, "\n".join(wrong)


@cache
def defaults(stage: str) -> dict:
    return OmegaConf.to_container(compose(stage, []), resolve=True, throw_on_missing=False)


def lookup(config: dict, key: str):
    for part in key.split("."):
        if not isinstance(config, dict) or part not in config:
            raise KeyError(key)
        config = config[part]
    return config


def default_of(key: str):
    """The default of ``key`` (``<stage>.<key>`` names the stage); refused if stages disagree."""
    stage, _, rest = key.partition(".")
    if stage in available_stages() and rest:
        return lookup(defaults(stage), rest)
    values = {}
    for stage in available_stages():
        try:
            values[stage] = lookup(defaults(stage), key)
        except KeyError:
            continue
    assert values, f"{key!r} is no stage's config key"
    assert len({repr(v) for v in values.values()}) == 1, (
        f"{key!r} differs between stages {values}: name the stage"
    )
    return next(iter(values.values()))


def claims() -> list[tuple[str, str, str]]:
    """(doc, key, value) of every quoted default."""
    return [
        (doc.name, key, value)
        for doc in DOCS
        for match in CLAIMS.finditer(doc.read_text())
        for key, value in ITEM.findall(match.group(1))
    ]


def test_the_docs_quote_defaults():
    keys = {key for _, key, _ in claims()}
    assert {
        "train.max_minutes",
        "flush_every",
        "bind",
        "quality.studio_shadows",
        "runs_dir",
        "trials.out",
    } <= keys


@pytest.mark.parametrize("doc,key,value", claims())
def test_a_quoted_default_is_the_configs(doc, key, value):
    assert default_of(key) == yaml.safe_load(value), (
        f"{doc}: `{key}={value}` by default, but the config says otherwise"
    )


def fault_counts(request) -> Counter:
    """Cases per family of ``tests/faults``: this session's own items when it collected the whole
    folder with the default markers (``make test``), else ``pytest --collect-only`` in a child."""
    from scripts.fault_census import FAULTS, census, family

    config = request.config
    paths = [Path(a.split("::")[0]).resolve() for a in config.args] or [ROOT / "tests"]
    covering = [p for p in paths if p in (ROOT, ROOT / "tests", FAULTS)]
    inside = [p for p in paths if p.is_relative_to(FAULTS) and p != FAULTS]
    filtered = (
        config.getoption("keyword", default=""),
        config.getoption("markexpr", default=""),
        config.getoption("deselect", default=None),
        config.getoption("lf", default=False),
    ) != ("", "not slow", None, False)
    if not covering or inside or filtered:
        return census()
    items = [i for i in request.session.items if Path(i.fspath).is_relative_to(FAULTS)]
    return Counter(family(i.nodeid) for i in items)


def test_reliability_quotes_the_fault_census(request):
    """docs/reliability.md "The cases" is the table ``python -m scripts.fault_census`` prints."""
    from scripts.fault_census import table

    doc = (ROOT / "docs" / "reliability.md").read_text()
    wanted = table(fault_counts(request))
    assert wanted in doc, f"put this table under 'The cases' in docs/reliability.md:\n{wanted}"


def test_what_the_readme_examples_write_is_ignored_by_git():
    """Issue 44: after the README's examples a user's `git status` stays clean: every `out=` they
    name, the trials' default `out` and the replays folder are ignored."""
    default_out = compose("trials", []).out
    outs = re.findall(r"\bout=([\w/.-]+)", (ROOT / "README.md").read_text())
    paths = [f"{o}/summary.json" for o in [*outs, default_out]] + ["replays/x.rrd"]
    assert outs, "the README's examples name no out= any more: update this test"
    ignored = subprocess.run(
        ["git", "check-ignore", "--no-index", *paths], cwd=ROOT, capture_output=True, text=True
    ).stdout.split()
    assert sorted(ignored) == sorted(paths), set(paths) - set(ignored)
