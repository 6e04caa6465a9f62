"""The MCAP record schema (DESIGN.md "Records"): Protobuf messages, topics and timestamps.

One file holds every episode of every run of one trial cell. Per file:

* MCAP **metadata** records (written first, so a killed run keeps them): ``recording`` (format
  version, time unit), ``config`` (resolved config as YAML and JSON), ``seeds``, ``versions``
  (package versions), ``maze`` (layout rows of ``S``/``G``/``X``/``.``, width, height, and the
  caller's action names, moves and category names), ``obstacles`` (the per-run obstacle
  assignment, JSON), ``info`` (any other key of the writer's ``metadata``), and ``closed``
  (counts; written by ``close()`` only, so its absence marks an unfinished file).
* The query pictures **once**, as ``foxglove.CompressedImage`` on ``/pictures/<id>`` (and the
  initial support-set thumbnails, when given, on ``/support/<category>/<position>``).
* ``/episodes``: ONE :data:`EpisodeBatch` message per batch the trial runner hands to its sink
  (consecutive finished episodes of one run, ``pipeline/rl/sink.py``): the per-episode summaries,
  the steps of all its episodes concatenated, its recognitions and unsafe-set additions (each row
  naming its episode), all as packed arrays (struct-of-arrays), and optionally the Q tables at the
  episodes' ends. Its log time is that of the batch's first episode at step 0, so a message
  stamped before an episode may hold it (readers select by run, then filter rows).
* ``/substitutions``: one :data:`SUBSTITUTION` message per support-set substitution (section 3.3).

Timestamps come from (run, episode, step), never from the wall clock (:func:`log_time_ns`):
one step is 1 ms, one episode 1 s, one run 10^6 s, so the same data gives the same bytes and the
Rerun / Foxglove time axis reads "run r, episode e, step t" as r*10^6 + e seconds + t ms.

The flag bits and unsafe-set sources mirror ``pipeline/rl/codes.py`` (``StepFlag``, ``Source``;
``records`` imports nothing from ``rl``; a test checks that the two agree).
"""
from __future__ import annotations

from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage

FORMAT_VERSION = "2"  # 2: one EpisodeBatch message per sink batch (1: one Episode per episode)
PACKAGE = "fsrl.records"

TOPIC_EPISODES = "/episodes"
TOPIC_SUBSTITUTIONS = "/substitutions"
TOPIC_PICTURES = "/pictures"  # + "/<picture id>"
TOPIC_SUPPORT = "/support"  # + "/<category>/<position>"

# Flag bits of Steps.flags and sources of unsafe-set additions (same names and values as
# pipeline/rl/codes.py StepFlag and Source).
FLAG_RESELECTED = 1
FLAG_COLLIDED = 2
FLAG_RECOVERED = 4
FLAG_GOAL = 8
FLAG_TRUNCATED = 16
FLAG_NAMES = {"reselected": FLAG_RESELECTED, "collided": FLAG_COLLIDED, "recovered": FLAG_RECOVERED,
              "goal": FLAG_GOAL, "truncated": FLAG_TRUNCATED}
SOURCE_NAMES = ("recognition", "collision", "ssrl_rule")

# Timestamps: log_time_ns = run * RUN_NS + episode * EPISODE_NS + step * STEP_NS.
STEP_NS = 1_000_000  # 1 ms
EPISODE_NS = 1_000 * STEP_NS  # 1 s: at most 1,000 steps an episode
RUN_NS = 1_000_000 * EPISODE_NS  # 10^6 s: at most 10^6 episodes a run
MAX_RUN = (2**63 - 1) // RUN_NS - 1  # about 9,000 runs


def log_time_ns(run: int, episode: int, step: int = 0) -> int:
    """Timestamp (ns) of ``step`` of ``episode`` of ``run``: deterministic, never the wall clock."""
    if not 0 <= step < EPISODE_NS // STEP_NS:
        raise ValueError(f"step {step} out of range 0..{EPISODE_NS // STEP_NS - 1} for a record timestamp")
    if not 0 <= episode < RUN_NS // EPISODE_NS:
        raise ValueError(f"episode {episode} out of range 0..{RUN_NS // EPISODE_NS - 1} for a record timestamp")
    if not 0 <= run <= MAX_RUN:
        raise ValueError(f"run {run} out of range 0..{MAX_RUN} for a record timestamp")
    return run * RUN_NS + episode * EPISODE_NS + step * STEP_NS


def split_log_time(t: int) -> tuple[int, int, int]:
    """Inverse of :func:`log_time_ns`: ``(run, episode, step)``."""
    run, rest = divmod(int(t), RUN_NS)
    episode, rest = divmod(rest, EPISODE_NS)
    return run, episode, rest // STEP_NS


_F = descriptor_pb2.FieldDescriptorProto

# (message name, doc, fields as (name, number, type, label, type_name))
_REP = _F.LABEL_REPEATED
_OPT = _F.LABEL_OPTIONAL
_MESSAGES: list[tuple[str, list[tuple[str, int, int, int, str]]]] = [
    ("EpisodeSummaries", [  # one entry per episode of the batch
        ("steps", 1, _F.TYPE_UINT32, _REP, ""),
        ("collisions", 2, _F.TYPE_UINT32, _REP, ""),
        ("return_", 3, _F.TYPE_DOUBLE, _REP, ""),
        ("reached_goal", 4, _F.TYPE_BOOL, _REP, ""),
        ("prevented", 5, _F.TYPE_UINT32, _REP, ""),
        ("epsilon", 6, _F.TYPE_DOUBLE, _REP, ""),          # at the end of the episode
        ("greedy_optimal", 7, _F.TYPE_BOOL, _REP, ""),     # the greedy policy walks an optimal path
    ]),
    ("Steps", [  # one entry per executed step of the batch's episodes, concatenated
        ("states", 1, _F.TYPE_INT32, _REP, ""),     # cell index row * width + col before the step
        ("actions", 2, _F.TYPE_INT32, _REP, ""),    # executed action, 0 N, 1 E, 2 S, 3 W
        ("rewards", 3, _F.TYPE_FLOAT, _REP, ""),
        ("flags", 4, _F.TYPE_UINT32, _REP, ""),     # bits: FLAG_*
    ]),
    ("Recognitions", [  # one entry per picture seen (section 3.2.1)
        ("episode", 1, _F.TYPE_UINT32, _REP, ""),
        ("step", 2, _F.TYPE_INT32, _REP, ""),
        ("state", 3, _F.TYPE_INT32, _REP, ""),
        ("action", 4, _F.TYPE_INT32, _REP, ""),
        ("picture", 5, _F.TYPE_INT32, _REP, ""),
        ("predicted", 6, _F.TYPE_INT32, _REP, ""),
        ("true_category", 7, _F.TYPE_INT32, _REP, ""),
        ("n_categories", 8, _F.TYPE_UINT32, _OPT, ""),  # columns of scores; 0 when no scores
        ("scores", 9, _F.TYPE_FLOAT, _REP, ""),         # relation scores (eq. 2), row-major [n, n_categories]
    ]),
    ("UnsafeAdditions", [  # one entry per (s, a) added to the unsafe set A_d (eqs. 7-8)
        ("episode", 1, _F.TYPE_UINT32, _REP, ""),
        ("step", 2, _F.TYPE_INT32, _REP, ""),
        ("state", 3, _F.TYPE_INT32, _REP, ""),
        ("action", 4, _F.TYPE_INT32, _REP, ""),
        ("source", 5, _F.TYPE_INT32, _REP, ""),  # 0 recognition, 1 collision, 2 ssrl rule
    ]),
    ("EpisodeBatch", [  # consecutive finished episodes of one run (the sink's batch)
        ("run", 1, _F.TYPE_UINT32, _OPT, ""),
        ("episode", 2, _F.TYPE_UINT32, _REP, ""),  # the batch's episode indices, consecutive
        ("summary", 3, _F.TYPE_MESSAGE, _OPT, ".fsrl.records.EpisodeSummaries"),
        ("steps", 4, _F.TYPE_MESSAGE, _OPT, ".fsrl.records.Steps"),
        ("recognitions", 5, _F.TYPE_MESSAGE, _OPT, ".fsrl.records.Recognitions"),
        ("unsafe_added", 6, _F.TYPE_MESSAGE, _OPT, ".fsrl.records.UnsafeAdditions"),
        ("n_actions", 7, _F.TYPE_UINT32, _OPT, ""),  # columns of q_values; 0 when absent
        ("q_values", 8, _F.TYPE_FLOAT, _REP, ""),    # optional Q tables at episode ends, [E, n_states, n_actions]
    ]),
    ("Substitution", [  # the dynamic support set changed (section 3.3, Figure 5)
        ("run", 1, _F.TYPE_UINT32, _OPT, ""),
        ("episode", 2, _F.TYPE_UINT32, _OPT, ""),
        ("step", 3, _F.TYPE_UINT32, _OPT, ""),
        ("picture", 4, _F.TYPE_INT32, _OPT, ""),   # query picture id that entered the support set
        ("category", 5, _F.TYPE_INT32, _OPT, ""),  # support-set class it entered
        ("position", 6, _F.TYPE_INT32, _OPT, ""),  # replaced shot 0..K-1
        ("support_accuracy", 7, _F.TYPE_DOUBLE, _OPT, ""),  # query accuracy of the support set after it
    ]),
]


def _file_descriptor() -> descriptor_pb2.FileDescriptorProto:
    fdp = descriptor_pb2.FileDescriptorProto(name="fsrl/records.proto", package=PACKAGE, syntax="proto3")
    for name, fields in _MESSAGES:
        msg = fdp.message_type.add(name=name)
        for fname, number, ftype, label, type_name in fields:
            f = msg.field.add(name=fname, number=number, type=ftype, label=label)
            if type_name:
                f.type_name = type_name
    return fdp


FILE_DESCRIPTOR_PROTO = _file_descriptor()
_pool = descriptor_pool.DescriptorPool()
_pool.Add(FILE_DESCRIPTOR_PROTO)


def _cls(name: str):
    return message_factory.GetMessageClass(_pool.FindMessageTypeByName(f"{PACKAGE}.{name}"))


EpisodeBatch = _cls("EpisodeBatch")
Substitution = _cls("Substitution")
Steps = _cls("Steps")
Recognitions = _cls("Recognitions")
UnsafeAdditions = _cls("UnsafeAdditions")
EpisodeSummaries = _cls("EpisodeSummaries")


def file_descriptor_set(message_class) -> bytes:
    """Serialized ``FileDescriptorSet`` of ``message_class`` and its dependencies: the MCAP schema
    data for encoding ``protobuf`` (what Foxglove, Rerun and mcap-protobuf-support decode)."""
    fds = descriptor_pb2.FileDescriptorSet()
    seen: set[str] = set()

    def add(fd) -> None:
        for dep in fd.dependencies:
            if dep.name not in seen:
                seen.add(dep.name)
                add(dep)
        fd.CopyToProto(fds.file.add())

    add(message_class.DESCRIPTOR.file)
    return fds.SerializeToString(deterministic=True)


__all__ = [
    "CompressedImage", "EpisodeBatch", "EpisodeSummaries", "FLAG_NAMES",
    "FORMAT_VERSION", "Recognitions", "SOURCE_NAMES", "Steps", "Substitution", "TOPIC_EPISODES",
    "TOPIC_PICTURES", "TOPIC_SUBSTITUTIONS", "TOPIC_SUPPORT", "UnsafeAdditions", "file_descriptor_set",
    "log_time_ns", "split_log_time",
]
