"""The shape the code keeps (issue 25): small modules. The other rules are enforced by `make lint`:
`ruff` (formatting; at most 60 statements a function in pipeline/, pyproject.toml) and
`lint-imports` (the layers and no import cycles, .importlinter)."""

from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "pipeline"
MAX_LINES = 400


def test_no_module_of_the_package_is_over_400_lines():
    long = {
        str(p.relative_to(PACKAGE.parent)): n
        for p in sorted(PACKAGE.rglob("*.py"))
        if (n := len(p.read_text().splitlines())) > MAX_LINES
    }
    assert not long, f"split these modules (over {MAX_LINES} lines): {long}"
