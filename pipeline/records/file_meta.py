"""The per-file metadata of a record file (:class:`FileMeta`), read from a :class:`.scanned.Scan`:
the resolved config, seeds, versions, maze, obstacle assignments, pictures and the closing record,
and how many messages of each kind the file should hold.
"""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from . import schema as S
from .scanned import Damage, Scan, message_kind


@dataclass
class FileMeta:
    """The per-file metadata of one record file."""

    path: Path
    complete: bool  # finished and renamed by RecordWriter.close(), and nothing in it is damaged or missing
    config: dict | None = None
    config_yaml: str | None = None
    seeds: Any = None
    versions: dict[str, str] = field(default_factory=dict)
    maze: dict[str, Any] | None = (
        None  # layout (list of rows), width, height, categories, actions, moves
    )
    obstacles: dict[int, list[dict[str, int]]] = field(default_factory=dict)  # run -> assignment
    info: dict[str, Any] = field(default_factory=dict)
    closed: dict[str, str] | None = None
    record: str = "steps"  # what was recorded: "steps" (every step) or "episodes" (no step rows)
    pictures: dict[int, bytes] = field(default_factory=dict)
    support_pictures: dict[tuple[int, int], bytes] = field(
        default_factory=dict
    )  # (category, position)
    problems: list[str] = field(default_factory=list)  # what the warning said, one sentence each
    partial: bool = False  # a ``.partial`` file: a killed or interrupted run
    damaged: bool = False  # some of its bytes are wrong (not only cut short)
    expected_runs: int | None = None  # what the metadata says it should hold
    expected_episodes: int | None = None  # the same, in the requested window
    lost: str = ""  # short: the runs and episodes lost or missing, for a one-line listing
    readable: bool = True  # False: not one record (metadata, message) could be read

    @property
    def unusable(self) -> str | None:
        """Why nothing at all could be read from the file (None when something could)."""
        why = "; ".join(self.problems) or "it holds no records"
        return None if self.readable else f"{self.path}: {why}; nothing could be read"

    @property
    def status(self) -> str:
        """``complete``, ``DAMAGED``, ``INCOMPLETE`` (cut short or unfinished); ``PARTIAL, ...`` for a ``.partial``."""
        word = "complete" if self.complete else "DAMAGED" if self.damaged else "INCOMPLETE"
        return f"PARTIAL, {word}" if self.partial and not self.complete else word


def _maze(mz: dict[str, str]) -> dict[str, Any]:
    out = {
        "layout": mz["layout"].split("\n"),
        "width": int(mz["width"]),
        "height": int(mz["height"]),
        "categories": json.loads(mz["categories"]) if "categories" in mz else None,
        "actions": mz["actions"].split(",") if "actions" in mz else None,  # names, when given
        "moves": [tuple(m) for m in json.loads(mz["moves"])] if "moves" in mz else None,
    }  # when given
    out.update(json.loads(mz["extra"]) if "extra" in mz else {})
    return out


#: Metadata record -> the :class:`FileMeta` fields it gives (``config_yaml``, ``versions`` and ``closed`` as they are).
_METADATA = {
    "config": lambda rec: {"config": json.loads(rec["json"]) if "json" in rec else None},
    "seeds": lambda rec: {"seeds": json.loads(rec["json"])},
    "maze": lambda rec: {"maze": _maze(rec)},
    "obstacles": lambda rec: {"obstacles": {int(k): v for k, v in json.loads(rec["json"]).items()}},
    "info": lambda rec: {"info": {k: json.loads(v) for k, v in rec.items()}},
}


def file_meta(sc: Scan, pictures: bool) -> FileMeta:
    """The file's metadata records and pictures; one that does not parse is a damaged part, not an error."""
    md = sc.metadata
    fields = {
        "config_yaml": md.get("config", {}).get("yaml"),
        "versions": dict(md.get("versions", {})),
        "closed": md.get("closed"),
        "record": md.get("recording", {}).get("record", "steps"),
    }
    for name, parse in _METADATA.items():
        try:
            fields |= parse(md[name]) if name in md else {}
        except Exception as e:
            sc.damage.append(
                Damage(
                    "metadata", f"metadata record '{name}' does not parse ({type(e).__name__}: {e})"
                )
            )
    meta = FileMeta(
        path=sc.path, complete=False, partial=sc.path.name.endswith(".partial"), **fields
    )
    for topic, msgs in sc.messages.items() if pictures else ():
        try:
            if topic.startswith(S.TOPIC_PICTURES + "/"):
                meta.pictures[int(topic.rsplit("/", 1)[1])] = S.CompressedImage.FromString(
                    msgs[-1][1]
                ).data
            elif topic.startswith(S.TOPIC_SUPPORT + "/"):
                _, _, cat, pos = topic.split("/")
                meta.support_pictures[(int(cat), int(pos))] = S.CompressedImage.FromString(
                    msgs[-1][1]
                ).data
        except Exception as e:
            sc.damage.append(
                Damage(
                    "decode", f"the picture message on {topic} does not decode ({type(e).__name__})"
                )
            )
    return meta


def message_counts(sc: Scan, closed: dict[str, str], n_subs: int) -> dict[str, tuple[int, int]]:
    """kind -> (read, expected) messages, from the summary's statistics or the lost chunks' message indexes."""
    read, held, stats = (
        Counter(),
        Counter(),
        sc.summary.statistics if sc.summary is not None else None,
    )
    for topic, msgs in sc.messages.items():
        read[message_kind(topic)] += len(msgs)
    if stats is not None:
        for cid, n in stats.channel_message_counts.items():
            held[message_kind(sc.channels[cid].topic) if cid in sc.channels else None] += n
        return {k: (read[k], n) for k, n in held.items() if k and k != "episode batches"}
    for d in sc.damage:
        held.update({k: len(v) for k, v in d.held.items()})
    out = {k: (read[k], read[k] + n) for k, n in held.items() if k != "episode batches"}
    if str(closed.get("substitutions", "")).isdigit():
        out["substitutions"] = (n_subs, int(closed["substitutions"]))
    return out
