"""The fault suite's census: how many hostile cases each family of ``tests/faults/`` holds.

``python -m scripts.fault_census`` prints a Markdown table (family, cases, what it tries: the first
sentence of the family's docstring) and the total, as pytest collects them (every parametrized
case counts once). docs/reliability.md quotes the total; tests/test_docs.py holds the two equal.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FAULTS = ROOT / "tests" / "faults"


def collected() -> list[str]:
    """The node ids pytest collects under ``tests/faults`` (the default markers: no slow cases)."""
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider", FAULTS],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    if done.returncode != 0:
        raise SystemExit(f"pytest could not collect tests/faults:\n{done.stdout}{done.stderr}")
    return [line for line in done.stdout.splitlines() if "::" in line]


def family(node_id: str) -> str:
    return Path(node_id.split("::")[0]).stem.removeprefix("test_")


def what(name: str) -> str:
    """The family's title: its module docstring up to the first colon, bracket or full stop."""
    doc = " ".join(
        (ast.get_docstring(ast.parse((FAULTS / f"test_{name}.py").read_text())) or "").split()
    )
    for stop in (": ", " (", ". "):
        doc = doc.split(stop)[0]
    return doc.rstrip(".").replace("|", "\\|")


def census() -> Counter:
    return Counter(family(n) for n in collected())


def table(counts: Counter) -> str:
    lines = ["| family | cases | what it tries |", "|---|---:|---|"]
    lines += [f"| {name} | {n} | {what(name)} |" for name, n in sorted(counts.items())]
    lines.append(f"| **total** | **{sum(counts.values())}** | |")
    return "\n".join(lines)


if __name__ == "__main__":
    print(table(census()))
