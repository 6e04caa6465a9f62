"""The configs, shipped inside the package: one YAML file per stage (``trials.yaml``...), the config
groups (``method/``, ``recogniser/``, ``experiment/``, ``profile/``, ``model/``, ``data/``) and the
built-in maze layouts (``mazes/*.txt``, paper section 4.1, Figures 6 and 11).

They are package data (``pyproject.toml``), so a regular ``pip install`` finds them as well as a
checkout: Hydra reads them through :data:`HYDRA_PATH` (``pkg://pipeline.conf``), and the code that lists or reads them
directly (the methods, the recognisers, the built-in mazes) through :func:`conf_dir`. This file
makes the folder a package, which Hydra's ``pkg://`` config source requires.
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

#: The configs' module, and Hydra's config path for them: found through the import system in any
#: install.
HYDRA_MODULE = __name__
HYDRA_PATH = f"pkg://{HYDRA_MODULE}"


def conf_dir(*parts: str) -> Path:
    """The packaged config folder, or ``parts`` below it (``conf_dir("method")``), on the file
    system (the package is installed as files, never zipped)."""
    return Path(files(__name__).joinpath(*parts))
