"""The report stage's schema: :class:`ReportConfig` (``conf/report.yaml``)."""

from __future__ import annotations

from dataclasses import dataclass

from omegaconf import MISSING

from pipeline.config.fields import setting


@dataclass
class ReportConfig:
    """``python -m pipeline report``: rebuild the report from the recorded data alone."""

    runs_dir: str = setting(nonempty=True, path=True)
    """The trials' records: ``<runs_dir>/<experiment>/<cell>/records.mcap``."""
    accuracy_dir: str = setting(nonempty=True, path=True)
    """The accuracy stage's data files (the Relation Network's)."""
    model_metrics: str = setting(nonempty=True, path=True)
    """The Relation Network's validation metrics (meta_train)."""
    protonet_accuracy_dir: str = setting(nonempty=True, path=True)
    """The Prototypical Network's accuracy study, shown beside the Relation Network's (Tables 1-2)."""
    protonet_metrics: str = setting(nonempty=True, path=True)
    """The Prototypical Network's validation metrics (meta_train model=protonet)."""
    networks_accuracy_dir: str = setting(nonempty=True, path=True)
    """The other networks' accuracy studies, a ``<kind>_seed<k>`` folder each (accuracy across networks)."""
    contact_dir: str = setting(nonempty=True, path=True)
    """The render stage's contact sheets, copied to the report's figures."""
    out: str = setting(nonempty=True, path=True)
    """``index.md``, ``tables/`` and ``figures/`` (replaced only by a complete build)."""
    allow_missing: bool = MISSING
    """Build without experiments or cells that have no complete records (listed at the top)."""
    allow_mixed_scales: bool = MISSING
    """Build from cells recorded at different scales (profiles), each named at the top."""
