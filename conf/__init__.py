"""The pipeline's Hydra configs: one YAML file per stage (``trials.yaml``...), the config groups
(``method/``, ``recogniser/``, ``experiment/``, ``profile/``, ``model/``, ``data/``) and the built-in
maze layouts (``mazes/*.txt``, paper section 4.1, Figures 6 and 11).

This folder is the one home of the configs: edit them here. The wheel ships it as the package
``pipeline.conf`` (``setup.py`` maps the package to this folder), so an installed pipeline finds
it too. This file marks the folder (``pipeline/config/folder.py`` looks for it) and makes it that package.
"""
