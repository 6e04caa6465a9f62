"""The replay stage's schema: :class:`ReplayConfig` (``conf/replay.yaml``)."""

from __future__ import annotations

from dataclasses import dataclass

from omegaconf import MISSING

from pipeline.config.fields import setting

VIEWERS = ("none", "web", "native")


@dataclass
class ReplayConfig:
    """``python -m pipeline replay``: one recorded episode (or a whole run) in Rerun."""

    file: str = setting(nonempty=True, path=True)
    """An ``.mcap`` record file (or the ``.mcap.partial`` of a killed run)."""
    run: int = setting(ge=0)
    """The run to replay."""
    episode: int | None = setting(None, ge=0)
    """The episode to replay; none: the run's first episode with a recognition."""
    whole_run: bool = MISSING
    """Every episode of the run on one timeline (refused together with ``episode``)."""
    out: str | None = setting(None, path=True)
    """The ``.rrd`` to write; none: ``replays/<experiment>-<cell>-run<run>-ep<episode>.rrd`` (``-all.rrd``
    with ``whole_run``), named from the record file's folders."""
    viewer: str = setting(choices=VIEWERS)
    """Then open the recording: ``none``, ``web`` (serve it to a browser) or ``native`` (needs a display)."""
    bind: str = setting(nonempty=True)
    """IP address the web viewer listens on; off the loopback only with ``allow_remote``."""
    allow_remote: bool = MISSING
    """Allow a ``bind`` reachable from other machines (``0.0.0.0``, a LAN address); warns."""
    web_port: int = setting(ge=0, le=65535)
    """HTTP port of the web viewer; 0 picks a free one (printed)."""
    grpc_port: int = setting(ge=0, le=65535)
    """gRPC port that serves the recording to the viewer; 0 picks a free one."""
