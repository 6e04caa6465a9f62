"""Stage ``report``: tables and figures of the paper, ours beside the paper's, from the records.

python -m pipeline report [out=reports]
"""

from __future__ import annotations

from pathlib import Path

import yaml

from pipeline.config.compose import CONF_DIR
from pipeline.config.fields import refuse
from pipeline.report.build import Inputs, build_report
from pipeline.report.scale import MixedScalesError
from pipeline.schemas.report import ReportConfig
from pipeline.stages import stage_main


def profile_trials() -> dict[str, dict]:
    """Each profile's ``trials`` block by name (``conf/profile/*.yaml``): what names the
    scale of the records (:mod:`pipeline.report.scale`)."""
    return {
        p.stem: (yaml.safe_load(p.read_text()) or {}).get("trials")
        for p in sorted((Path(CONF_DIR) / "profile").glob("*.yaml"))
    }


def run(cfg: ReportConfig, overrides: list[str] = ()) -> Path:
    if Path(cfg.out).resolve() == Path.cwd().resolve():
        refuse("out", "must not be the working folder (it is rebuilt)")
    inputs = Inputs(
        Path(cfg.runs_dir),
        Path(cfg.accuracy_dir),
        Path(cfg.model_metrics),
        Path(cfg.contact_dir),
        Path(cfg.out),
        experiments_dir=Path(CONF_DIR) / "experiment",
        allow_missing=cfg.allow_missing,
        allow_mixed_scales=cfg.allow_mixed_scales,
        profiles=profile_trials(),
        beside={"protonet": (Path(cfg.protonet_accuracy_dir), Path(cfg.protonet_metrics))},
        models={"relation_net": Path(cfg.model_metrics), "protonet": Path(cfg.protonet_metrics)},
        networks_accuracy_dir=Path(cfg.networks_accuracy_dir),
    )
    try:
        index = build_report(inputs)
    except MixedScalesError as exc:
        refuse("runs_dir", str(exc))
    except FileNotFoundError as exc:
        refuse("runs_dir", str(exc))
    except OSError as exc:
        refuse("out", f"cannot write the report into {cfg.out} ({exc.strerror})")
    return index


def main() -> None:
    stage_main("report", run)
