"""The MCAP record schema (docs/records.md "The schema"): topics, timestamps and :data:`MESSAGES`,
the one table of fields (order, numbers, wire types, frame columns) that the Protobuf descriptors,
the encoder, the decoder and the reader's frames derive from (:mod:`.codec`). Flag bits and sources
mirror ``pipeline/rl/codes.py`` (a test checks); action names, moves and category names are the
caller's (``maze``).
"""

from __future__ import annotations

from typing import NamedTuple

from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage  # noqa: F401
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from mcap_protobuf.schema import build_file_descriptor_set

# 7: a step's cell, action and flags as one column of pairs (Steps.transitions); 6: format 5
# without its unused Substitution message; 5: substitutions in the batches;
# 4: states as codes; 3: fixed-width packed columns; 2: varint columns; 1: one Episode each
FORMAT_VERSION = "7"
PACKAGE = "fsrl.records"
LIBRARY = "pipeline.records/" + FORMAT_VERSION  # the header's library string of this writer's files
TOPIC_EPISODES = "/episodes"
TOPIC_PICTURES = "/pictures"  # + "/<picture id>"
TOPIC_SUPPORT = "/support"  # + "/<category>/<position>"

FLAG_NAMES = {"reselected": 1, "collided": 2, "recovered": 4, "goal": 8, "truncated": 16}
FLAG_BITS = 5  # flags are below 2**FLAG_BITS: Steps.transitions holds action * 32 + flags
FLAG_RESELECTED, FLAG_COLLIDED, FLAG_RECOVERED, FLAG_GOAL, FLAG_TRUNCATED = FLAG_NAMES.values()
SOURCE_NAMES = ("recognition", "collision", "ssrl_rule")

STEP_NS = 1_000_000  # 1 ms
EPISODE_NS = 1_000 * STEP_NS  # 1 s: at most 1,000 steps an episode
RUN_NS = 1_000_000 * EPISODE_NS  # 10^6 s: at most 10^6 episodes a run
MAX_RUN = (2**63 - 1) // RUN_NS - 1  # about 9,000 runs
MAX_STEP, MAX_EPISODE = EPISODE_NS // STEP_NS, RUN_NS // EPISODE_NS  # a step, an episode below


def log_time_ns(run: int, episode: int, step: int = 0) -> int:
    """Timestamp (ns) of ``step`` of ``episode`` of ``run``: deterministic, never the wall clock."""
    if not (0 <= step < MAX_STEP and 0 <= episode < MAX_EPISODE and 0 <= run <= MAX_RUN):
        for what, v, n in (
            ("step", step, MAX_STEP),
            ("episode", episode, MAX_EPISODE),
            ("run", run, MAX_RUN + 1),
        ):
            if not 0 <= v < n:
                raise ValueError(f"{what} {v} out of range 0..{n - 1} for a record timestamp")
    return run * RUN_NS + episode * EPISODE_NS + step * STEP_NS


def split_log_time(t: int) -> tuple[int, int, int]:
    """Inverse of :func:`log_time_ns`: ``(run, episode, step)``."""
    run, rest = divmod(int(t), RUN_NS)
    episode, rest = divmod(rest, EPISODE_NS)
    return run, episode, rest // STEP_NS


_F = descriptor_pb2.FieldDescriptorProto
I32, U32, F32, F64, BOOL = (
    _F.TYPE_SFIXED32,
    _F.TYPE_FIXED32,
    _F.TYPE_FLOAT,
    _F.TYPE_DOUBLE,
    _F.TYPE_BOOL,
)
CODE = _F.TYPE_UINT32  # packed: a varint column, one byte a value below 128; scalar: a plain uint32
SMALL = _F.TYPE_SINT32  # packed zigzag varints, written only when all values are in -64..63


class Field(NamedTuple):
    name: str  # Protobuf field name (what Foxglove and Rerun show)
    number: int
    type: int | str  # a TYPE_* or the name of a sub-message
    column: str = ""  # the reader's frame column ("" for scalars and sub-messages)
    dtype: str = ""  # its numpy dtype
    key: str = ""  # the sink batch key (pipeline/rl/sink.py) when not the field name
    repeated: bool = True


#: What ``Steps.transitions`` holds a step, in order: (sink batch key, frame column, dtype); the
#: second value is action * 32 + flags (flags below 32). Fields 1, 2 and 4 were format 6's columns.
TRANSITION_PARTS = (
    ("states", "state", "int32"),
    ("actions", "action", "int8"),
    ("flags", "flags", "uint8"),
)

# message -> fields. Frames: EpisodeSummaries and EpisodeBatch.episode -> episodes; Steps -> steps;
# Recognitions -> recognitions; UnsafeAdditions -> unsafe; Substitutions -> substitutions.
MESSAGES: dict[str, list[Field]] = {
    "EpisodeSummaries": [  # one entry per episode of the batch
        Field("steps", 1, U32, "steps", "int32"),
        Field("collisions", 2, U32, "collisions", "int32"),
        Field("return_", 3, F64, "return_", "float64"),
        Field("reached_goal", 4, BOOL, "reached_goal", "bool"),
        Field("prevented", 5, U32, "prevented", "int32"),
        Field("epsilon", 6, F64, "epsilon", "float64"),  # at the end of the episode
        Field("greedy_optimal", 7, BOOL, "greedy_optimal", "bool"),  # greedy policy optimal after
    ],
    "Steps": [  # the steps of the batch's episodes, concatenated
        # two values a step (TRANSITION_PARTS): the cell before the step (row * width + col), then
        # action * 32 + flags (an index into the maze record's actions; FLAG_NAMES bits)
        Field("transitions", 6, CODE),
        Field("rewards", 3, F32, "reward", "float32"),  # one a step
        # a batch whose rewards are all whole numbers in -64..63 (the rules give -1, 0, 1) has them
        # here, one byte each, instead of in ``rewards`` (4 bytes each)
        Field("small_rewards", 5, SMALL, "reward", "float32", key="rewards"),
    ],
    "Recognitions": [  # one entry per picture seen (section 3.2.1)
        Field("episode", 1, U32, "episode", "int32"),
        Field("step", 2, I32, "step", "int32"),
        Field("state", 3, I32, "state", "int32"),
        Field("action", 4, CODE, "action", "int8"),
        Field("picture", 5, I32, "picture", "int16"),
        Field("predicted", 6, I32, "predicted", "int8"),
        Field("true_category", 7, I32, "true", "int8", key="true"),
        Field("n_categories", 8, CODE, repeated=False),  # columns of scores; 0 when no scores
        Field("scores", 9, F32, "scores", "float32"),  # relation scores (eq. 2), [n, n_categories]
    ],
    "UnsafeAdditions": [  # one entry per (s, a) added to the unsafe set A_d (eqs. 7-8)
        Field("episode", 1, U32, "episode", "int32"),
        Field("step", 2, I32, "step", "int32"),
        Field("state", 3, I32, "state", "int32"),
        Field("action", 4, CODE, "action", "int8"),
        Field("source", 5, CODE, "source", "int8"),  # an index into SOURCE_NAMES
    ],
    "Substitutions": [  # one entry per support-set change (section 3.3); a run's start: -1s
        Field("episode", 1, U32, "episode", "int32"),
        Field("step", 2, I32, "step", "int32"),
        Field("picture", 3, I32, "picture", "int16"),  # entered the support set
        Field("category", 4, I32, "category", "int8"),  # the class it entered
        Field("position", 5, I32, "position", "int8"),  # replaced shot 0..K-1
        Field("support_accuracy", 6, F64, "support_accuracy", "float64"),  # on the queries, after
    ],
    "EpisodeBatch": [  # consecutive finished episodes of one run (the sink's batch)
        Field("run", 1, CODE, repeated=False),
        Field("episode", 2, U32, "episode", "int32"),
        Field("summary", 3, "EpisodeSummaries", repeated=False),
        Field("steps", 4, "Steps", repeated=False),
        Field("recognitions", 5, "Recognitions", repeated=False),
        Field("unsafe_added", 6, "UnsafeAdditions", repeated=False),
        Field("n_actions", 7, CODE, repeated=False),  # columns of q_values; 0 when absent
        Field("q_values", 8, F32, "q_values", "float32"),  # optional [E, n_states, n_actions]
        Field("substitutions", 9, "Substitutions", repeated=False),
    ],
}


def _file() -> descriptor_pb2.FileDescriptorProto:
    """The schema of :data:`MESSAGES` (proto3: every repeated number column packed)."""
    fdp = descriptor_pb2.FileDescriptorProto(
        name="fsrl/records.proto", package=PACKAGE, syntax="proto3"
    )
    for name, fields in MESSAGES.items():
        msg = fdp.message_type.add(name=name)
        for f in fields:
            sub = isinstance(f.type, str)
            d = msg.field.add(
                name=f.name,
                number=f.number,
                type=_F.TYPE_MESSAGE if sub else f.type,
                label=_F.LABEL_REPEATED if f.repeated else _F.LABEL_OPTIONAL,
            )
            if sub:
                d.type_name = f".{PACKAGE}.{f.type}"
    return fdp


FILE_DESCRIPTOR_PROTO = _file()


def message_classes(*, view: bool = False) -> dict:
    """Message name -> class of :data:`MESSAGES`. ``view``: the raw views, every repeated number
    column declared ``bytes`` instead (same number, wire type and framing as a packed column, so
    the same bytes): a column is set as ``array.tobytes()`` and read with ``np.frombuffer``."""
    fd = descriptor_pb2.FileDescriptorProto.FromString(FILE_DESCRIPTOR_PROTO.SerializeToString())
    for d in (d for m in fd.message_type for d in m.field) if view else ():
        if d.label == _F.LABEL_REPEATED and d.type != _F.TYPE_MESSAGE:
            d.type, d.label = _F.TYPE_BYTES, _F.LABEL_OPTIONAL
    pool = descriptor_pool.DescriptorPool()
    pool.Add(fd)
    find = pool.FindMessageTypeByName
    return {n: message_factory.GetMessageClass(find(f"{PACKAGE}.{n}")) for n in MESSAGES}


CLASSES = message_classes()
EpisodeBatch, Steps = CLASSES["EpisodeBatch"], CLASSES["Steps"]


def file_descriptor_set(message_class) -> bytes:
    """The MCAP schema data for encoding ``protobuf``: ``message_class``'s ``FileDescriptorSet``
    (mcap-protobuf-support's builder), what Foxglove, Rerun and mcap-protobuf decode."""
    return build_file_descriptor_set(message_class).SerializeToString(deterministic=True)
