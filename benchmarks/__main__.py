"""``python -m benchmarks``: list the benchmark scripts (run one with ``python -m benchmarks.<name>``)."""

import pkgutil

import benchmarks

for module in sorted(
    m.name for m in pkgutil.iter_modules(benchmarks.__path__) if not m.name.startswith("_")
):
    doc = (
        (__import__(f"benchmarks.{module}", fromlist=["__doc__"]).__doc__ or "")
        .strip()
        .splitlines()
    )
    print(f"python -m benchmarks.{module:<18} {doc[0] if doc else ''}")
