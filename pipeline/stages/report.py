"""Stage ``report``: tables and figures of the paper, ours beside the paper's, from the records.

    python -m pipeline report [out=reports]
"""
from __future__ import annotations

import sys
from pathlib import Path

import hydra
from omegaconf import DictConfig

from pipeline.report.build import Inputs, build_report
from pipeline.stages._common import CONF_DIR, ConfigError, require


def run(cfg: DictConfig) -> Path:
    require(bool(str(cfg.out).strip()), "out", "must name a folder")
    require(Path(cfg.out).resolve() != Path.cwd().resolve(), "out", "must not be the working folder (it is rebuilt)")
    inputs = Inputs(Path(cfg.runs_dir), Path(cfg.accuracy_dir), Path(cfg.model_metrics), Path(cfg.contact_dir), Path(cfg.out))
    try:
        return build_report(inputs)
    except FileNotFoundError as exc:
        raise ConfigError(f"config key 'runs_dir': {exc}") from None


@hydra.main(config_path=CONF_DIR, config_name="report", version_base="1.3")
def main(cfg: DictConfig) -> None:
    try:
        index = run(cfg)
    except ConfigError as exc:
        print(f"error: {exc}", file=sys.stderr)
        raise SystemExit(2) from None
    print(f"wrote {index}")
