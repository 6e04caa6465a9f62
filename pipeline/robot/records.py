"""What only the robot has, recorded beside a cell's ``records.mcap`` in ``robot.mcap`` (issue 30;
docs/robot3d.md "Records"). The grid's records (``pipeline/records``, format 6) are unchanged:
``records.mcap`` of a robot cell holds its episodes, recognitions (``picture = -1``: a live
picture) and substitutions exactly as a grid cell's.

Topics (one message per episode; log time ``pipeline.records.schema.log_time_ns(run, episode)``,
never the wall clock, so a seed gives the same bytes):

* ``/robot/episode`` (JSON): ``run``, ``episode``, ``sim_time`` (simulated seconds),
  ``poses`` (rows ``t, x, y, yaw`` at 10 Hz, t from the episode's start), ``contacts`` (``step``,
  world ``point``, ``time``) and ``pictures`` (``step``, ``state``, ``action``, ``scores``,
  ``true``, ``prevented``, ``substituted``; the image on the next topic).
* ``/robot/camera`` (``foxglove.CompressedImage``, PNG): every live picture that was classified,
  in the order of the episodes' ``pictures`` (log time: its step).

The metadata record ``robot`` holds the world's settings and the maze's cell size.
"""

from __future__ import annotations

import io
import json
from pathlib import Path
from typing import Any

import numpy as np
from mcap.reader import make_reader
from mcap.writer import Writer
from PIL import Image

from pipeline.errors import UserError
from pipeline.records import schema as S

LIBRARY = "pipeline.robot/1"
TOPIC_EPISODE, TOPIC_CAMERA = "/robot/episode", "/robot/camera"


def _png(image: np.ndarray) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(np.asarray(image, np.uint8)).save(buf, format="PNG", optimize=False)
    return buf.getvalue()


class RobotRecordWriter:
    """``robot.mcap``: the ``robot_sink`` of :func:`pipeline.robot.trials.run_robot_trials`."""

    def __init__(self, path: str | Path, settings: dict[str, Any]):
        self.path = Path(path)
        self._file = open(self.path, "wb")
        self._mcap = Writer(self._file, enable_data_crcs=True)
        self._mcap.start(profile="", library=LIBRARY)
        json_schema = self._mcap.register_schema("robot.Episode", "jsonschema", b"{}")
        image_schema = self._mcap.register_schema(
            S.CompressedImage.DESCRIPTOR.full_name,
            "protobuf",
            S.file_descriptor_set(S.CompressedImage),
        )
        self._episode = self._mcap.register_channel(TOPIC_EPISODE, "json", json_schema)
        self._camera = self._mcap.register_channel(TOPIC_CAMERA, "protobuf", image_schema)
        self._mcap.add_metadata("robot", {k: json.dumps(v) for k, v in sorted(settings.items())})
        self.n_episodes = 0

    def episode(self, *, run, episode, sim_time, poses, pictures, contacts) -> None:
        body = {
            "run": run,
            "episode": episode,
            "sim_time": sim_time,
            "poses": [[round(t, 6), *(round(v, 5) for v in p)] for t, *p in poses],
            "contacts": contacts,
            "pictures": [{k: v for k, v in p.items() if k != "image"} for p in pictures],
        }
        t = S.log_time_ns(run, episode)
        data = json.dumps(body, default=_plain, separators=(",", ":")).encode()
        self._mcap.add_message(self._episode, log_time=t, publish_time=t, data=data)
        for p in pictures:
            t = S.log_time_ns(run, episode, p["step"])
            msg = S.CompressedImage(frame_id="robot_camera", data=_png(p["image"]), format="png")
            self._mcap.add_message(
                self._camera, log_time=t, publish_time=t, data=msg.SerializeToString()
            )
        self.n_episodes += 1

    def close(self) -> Path:
        self._mcap.finish()
        self._file.close()
        return self.path


def _plain(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"cannot record {type(o).__name__}")


class RobotRecordsError(UserError):
    """A ``robot.mcap`` that cannot be read: damaged, cut short, or not a robot's records."""


def read_robot_records(path: str | Path) -> tuple[dict, list[dict]]:
    """``(settings, episodes)`` of a ``robot.mcap``; each episode's pictures get their ``image``
    (H, W, 3 uint8) back. A file that cannot be read whole is a :class:`RobotRecordsError` naming
    it (its ``records.mcap``, written beside it, is read on its own)."""
    try:
        settings, episodes, images = _read(path)
    except Exception as exc:  # mcap's, zstd's, JSON's, PNG's errors on a damaged file
        first = (str(exc).splitlines() or [""])[0]
        raise RobotRecordsError(
            f"{path}: cannot read the robot's records ({type(exc).__name__}: {first})"
        ) from None
    if not settings:
        raise RobotRecordsError(f"{path}: not a robot's records (no 'robot' metadata)")
    wanted = sum(len(ep["pictures"]) for ep in episodes)
    if wanted != len(images):
        raise RobotRecordsError(
            f"{path}: its episodes list {wanted} live pictures, the file holds {len(images)}"
        )
    it = iter(images)
    for ep in episodes:
        for p in ep["pictures"]:
            p["image"] = next(it)
    return settings, episodes


def _read(path: str | Path) -> tuple[dict, list[dict], list[np.ndarray]]:
    with open(path, "rb") as f:
        reader = make_reader(f)
        settings = {}
        for record in reader.iter_metadata():
            if record.name == "robot":
                settings = {k: json.loads(v) for k, v in record.metadata.items()}
        episodes, images = [], []
        for _, channel, message in reader.iter_messages(log_time_order=False):
            if channel.topic == TOPIC_EPISODE:
                episodes.append(json.loads(message.data))
            elif channel.topic == TOPIC_CAMERA:
                img = S.CompressedImage()
                img.ParseFromString(message.data)
                images.append(np.asarray(Image.open(io.BytesIO(img.data)).convert("RGB")))
    return settings, episodes, images
