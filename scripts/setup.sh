#!/usr/bin/env bash
# Creates .venv and installs the package with its pinned dependencies.
# torch==2.13.0 is pinned: an unpinned torch pulls a multi-GB CUDA build.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PY:-python3}

# System libraries for MuJoCo's offscreen renderer (Mesa's software EGL).
if ! ldconfig -p 2>/dev/null | grep -q "libEGL_mesa.so"; then
  if command -v apt-get >/dev/null 2>&1 && [ "$(id -u)" = "0" ]; then
    echo "[setup] installing Mesa EGL (libegl1 libegl-mesa0 libgl1-mesa-dri)"
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libegl1 libegl-mesa0 libgl1-mesa-dri
  else
    echo "[setup] WARNING: Mesa EGL (libEGL_mesa.so) not found and cannot apt-get install it; rendering will fail" >&2
  fi
fi

if [ ! -x .venv/bin/python ]; then
  "$PY" -m venv .venv
fi
.venv/bin/python -m pip install -q --upgrade pip
.venv/bin/python -m pip install -q "torch==2.13.0"
.venv/bin/python -m pip install -q -e ".[test]"
.venv/bin/rerun analytics disable >/dev/null 2>&1 || true
# DVC's site cache inside the project, by absolute path: a relative core.site_cache_dir is taken from
# the cwd and breaks `dvc exp run --temp`/queued runs ("unable to open database file").
# .dvc/config.local and .dvc/site_cache are git-ignored (.dvc/.gitignore).
.venv/bin/dvc config --local core.site_cache_dir "$(pwd)/.dvc/site_cache"
echo "[setup] done: $(.venv/bin/python -c 'import torch,numpy;print("torch",torch.__version__,"numpy",numpy.__version__)')"
