"""The wheel's packages, derived rather than listed: every package under ``pipeline/``, and the
top-level ``conf/`` folder (the Hydra configs) as the package ``pipeline.conf``, its config groups
(``conf/method/``...) as the data folders below it. pyproject.toml cannot say this (its
``packages.find`` sees only folders below ``pipeline/``); everything else is there."""

from setuptools import find_namespace_packages, find_packages, setup

CONFIGS_PACKAGE = "pipeline.conf"
CONFIGS_FOLDER = "conf"
CONFIG_GROUPS = [f"{CONFIGS_PACKAGE}.{group}" for group in find_namespace_packages(CONFIGS_FOLDER)]

setup(
    packages=[*find_packages(include=["pipeline", "pipeline.*"]), CONFIGS_PACKAGE, *CONFIG_GROUPS],
    package_dir={CONFIGS_PACKAGE: CONFIGS_FOLDER},
)
