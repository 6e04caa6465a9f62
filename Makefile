# Two commands do all set-up on a fresh machine:
#   make repro   -> creates .venv, installs everything, runs `dvc repro` (paper profile)
#   make test    -> creates .venv, installs everything, runs the test suite (smoke profile)
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: setup test test-slow repro bench clean-venv

$(STAMP): pyproject.toml scripts/setup.sh
	bash scripts/setup.sh
	touch $(STAMP)

setup: $(STAMP)

test: $(STAMP)
	MUJOCO_GL=$${MUJOCO_GL:-egl} $(BIN)/python -m pytest -q

test-slow: $(STAMP)
	MUJOCO_GL=$${MUJOCO_GL:-egl} $(BIN)/python -m pytest -q -m slow

repro: $(STAMP)
	MUJOCO_GL=$${MUJOCO_GL:-egl} PATH=$(abspath $(BIN)):$$PATH $(BIN)/dvc repro

bench: $(STAMP)
	$(BIN)/python -m benchmarks

clean-venv:
	rm -rf $(VENV)
