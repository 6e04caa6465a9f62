"""Where the configs are: the top-level ``conf/`` folder of a checkout, shipped in the wheel as the
package ``pipeline.conf`` (``setup.py``), so a checkout and an installed pipeline read the same files.

The code that lists or reads them (the methods, the recognisers, the built-in mazes) finds them
through :func:`conf_dir`, and Hydra through :func:`hydra_configs`, both on the file system.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from functools import cache
from pathlib import Path

import pipeline
from pipeline.errors import ConfigError

#: The file that marks a config folder (and makes ``conf/`` the wheel's package ``pipeline.conf``).
MARKER = "__init__.py"


def conf_dir(*parts: str) -> Path:
    """The config folder, or ``parts`` below it (``conf_dir("method")``)."""
    return config_root().joinpath(*parts)


@cache
def config_root() -> Path:
    """``pipeline/conf/`` inside an installed package (the wheel puts ``conf/`` there), else the
    ``conf/`` beside the package's folder (a checkout, or a copy of one). A folder without
    :data:`MARKER` is not taken: a checkout from before the move to ``conf/`` can keep an untracked
    ``pipeline/conf/`` of byte code, which git does not delete."""
    package = Path(pipeline.__file__).parent
    candidates = (package / "conf", package.parent / "conf")
    for folder in candidates:
        if (folder / MARKER).is_file():
            return folder
    raise ConfigError(
        f"no config folder: neither {candidates[0]} (an installed pipeline) nor {candidates[1]} (a "
        f"checkout) holds {MARKER}; restore conf/ with `git checkout -- conf` or reinstall"
    )


@contextmanager
def hydra_configs() -> Iterator[None]:
    """Hydra's global state initialised on :func:`conf_dir`, for ``hydra.compose``."""
    from hydra import initialize_config_dir

    with initialize_config_dir(config_dir=str(config_root()), version_base="1.3"):
        yield
