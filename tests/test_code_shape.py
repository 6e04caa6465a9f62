"""The shape the code keeps (issue 25): small modules, and a public API that tests, scripts and
benchmarks use. The other rules are enforced by `make lint`: `ruff` (formatting; at most 60
statements a function in pipeline/, pyproject.toml) and `lint-imports` (every module in its layer,
no import cycles, .importlinter)."""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "pipeline"
MAX_LINES = 400


def test_no_module_of_the_package_is_over_400_lines():
    long = {
        str(p.relative_to(PACKAGE.parent)): n
        for p in sorted(PACKAGE.rglob("*.py"))
        if (n := len(p.read_text().splitlines())) > MAX_LINES
    }
    assert not long, f"split these modules (over {MAX_LINES} lines): {long}"


def is_module(name: str) -> bool:
    path = ROOT.joinpath(*name.split("."))
    return path.with_suffix(".py").is_file() or (path / "__init__.py").is_file()


def private_modules_imported(path: Path) -> list[str]:
    """The modules of ``pipeline`` with a private part (``pipeline.stages._x``, ``from pipeline
    import _x``) that ``path`` imports; ``__main__`` is not private."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            inside = [f"{node.module}.{a.name}" for a in node.names]
            names = [node.module, *(n for n in inside if is_module(n))]
        else:
            continue
        for name in names:
            parts = name.split(".")
            private = [p for p in parts if p.startswith("_") and not p.startswith("__")]
            if parts[0] == "pipeline" and private:
                out.append(f"{path.relative_to(ROOT)}:{node.lineno}: {name}")
    return out


def test_tests_scripts_and_benchmarks_import_no_private_module_of_the_package():
    """A private module (``_x.py``) serves its own package only: what another package, a script, a
    benchmark or a test calls lives in a public module named for what it does."""
    found = [
        hit
        for folder in ("tests", "scripts", "benchmarks")
        for path in sorted((ROOT / folder).rglob("*.py"))
        for hit in private_modules_imported(path)
    ]
    assert not found, "import public modules instead:\n" + "\n".join(found)
