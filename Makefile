# Two commands do all set-up on a fresh machine:
#   make repro   -> creates .venv, installs everything, runs `dvc repro` (paper profile)
#   make test    -> creates .venv, installs everything, runs the test suite (smoke profile)
# Both install exactly the versions of requirements.lock; `make lock` re-makes it from pyproject.toml.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
LOCK := requirements.lock
PIP_VERSION := 26.3
PIP_TOOLS_VERSION := 7.6.2

.PHONY: setup lint test test-slow repro bench clean-venv lock

$(STAMP): $(LOCK) pyproject.toml setup.py scripts/setup.sh
	PIP_VERSION=$(PIP_VERSION) PY=$(PY) bash scripts/setup.sh
	touch $(STAMP)

setup: $(STAMP)

# The formatter and the linter (rules in pyproject.toml), then the layers contract (.importlinter).
LINT_PATHS := pipeline conf tests benchmarks scripts setup.py
lint: $(STAMP)
	$(BIN)/ruff format --check $(LINT_PATHS)
	$(BIN)/ruff check $(LINT_PATHS)
	$(BIN)/lint-imports

# pytest-xdist: one worker a core (tests/conftest.py pins each to its share), a test file's tests on
# one worker (its module fixtures are built once), the longest files first (tests/conftest.py
# orders them by the last run's durations; xdist keeps that order). `make test-slow`: the
# end-to-end tests.
TEST_WORKERS ?= auto
PYTEST := MUJOCO_GL=$${MUJOCO_GL:-egl} $(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist loadfile \
  --no-loadscope-reorder
test: $(STAMP)
	$(PYTEST)

test-slow: $(STAMP)
	$(PYTEST) -m slow

# dvc.yaml's derived lines first (scripts/dvc_deps.py): an experiment file added to
# conf/experiment/ is a stage of the run with no other edit.
repro: $(STAMP)
	$(BIN)/python -m scripts.dvc_deps --write
	MUJOCO_GL=$${MUJOCO_GL:-egl} PATH=$(abspath $(BIN)):$$PATH $(BIN)/dvc repro

# Lists the benchmarks, then runs one (BENCH=<name>; default robot3d: the robot stage at the paper's
# scale, about 5-10 minutes on 2 cores) and prints its figures.
BENCH ?= robot3d
bench: $(STAMP)
	$(BIN)/python -m benchmarks
	MUJOCO_GL=$${MUJOCO_GL:-egl} $(BIN)/python -m benchmarks.$(BENCH)

# Re-resolves $(LOCK) from pyproject.toml (dependencies + the test extra) with hashes, keeping the
# pins that still fit; `make lock LOCK_ARGS=--upgrade` (or `--upgrade-package NAME`) moves them.
# pip-tools goes into .venv only here. torch must resolve to the CPU wheel pip finds on local disk.
lock:
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install -q "pip==$(PIP_VERSION)" "pip-tools==$(PIP_TOOLS_VERSION)"
	CUSTOM_COMPILE_COMMAND="make lock" $(BIN)/pip-compile -q --generate-hashes --allow-unsafe \
	  --strip-extras --extra test --no-emit-index-url --no-emit-find-links $(LOCK_ARGS) \
	  -o $(LOCK) pyproject.toml
	@grep -qE '^torch==[^ ]+\+cpu ' $(LOCK) || { echo "[lock] ERROR: torch is not the CPU build" >&2; exit 1; }
	@! grep -qiE '^(nvidia-|triton|cuda-)' $(LOCK) || { echo "[lock] ERROR: CUDA packages in $(LOCK)" >&2; exit 1; }

clean-venv:
	rm -rf $(VENV)
