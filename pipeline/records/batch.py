"""One sink batch of episodes (``pipeline/rl/sink.py``): its boundary check and its encoding as an
``fsrl.records.EpisodeBatch`` message (schema in :mod:`.schema`).

Cost per batch, not per episode or step: the integers of the whole batch (episode ids, summaries,
steps, recognitions, unsafe-set additions) are concatenated once and varint-encoded in one numpy
pass (:mod:`.wire`), then cut into packed fields; floats are raw little-endian bytes. The output is
byte-for-byte what the Protobuf runtime serializes (:func:`encode_batch_protobuf`, the reference;
tests compare), so any Protobuf decoder (ours, Foxglove, Rerun) reads it with the file's schema.
"""
from __future__ import annotations

import itertools
from collections.abc import Mapping
from typing import Any

import numpy as np

from . import schema as S
from . import wire as W

BATCH_KEYS = frozenset({"run", "episode", "steps", "states", "actions", "rewards", "flags", "recognitions",
                        "unsafe_added", "summary"})
OPTIONAL_BATCH_KEYS = frozenset({"q_values"})
SUMMARY_KEYS = ("collisions", "return_", "reached_goal", "prevented", "epsilon", "greedy_optimal")
RECOGNITION_KEYS = ("episode", "step", "state", "action", "picture", "predicted", "true")
UNSAFE_KEYS = ("episode", "step", "state", "action", "source")
EPISODE_KEYS = frozenset({"run", "episode", "states", "actions", "rewards", "flags", "recognitions",
                          "unsafe_added", "summary"})  # one episode (RecordWriter.episode); "steps" optional


def _a(x: Any, where: str, n: int | None = None) -> np.ndarray:
    a = np.asarray(x)
    if a.ndim != 1:
        raise ValueError(f"{where}: expected a 1-D array, got shape {a.shape}")
    if n is not None and len(a) != n:
        raise ValueError(f"{where}: length {len(a)}, expected {n}")
    return a


def _table(d: Mapping[str, Any] | None, keys: tuple[str, ...], where: str) -> tuple[list[np.ndarray], int]:
    """The columns ``keys`` of a dict of equal-length arrays (an empty or missing dict: no rows)."""
    if not d or len(d.get("step", ())) == 0:
        return [np.zeros(0, np.int64)] * len(keys), 0
    missing = [k for k in keys if k not in d]
    if missing:
        raise ValueError(f"{where}: missing columns {missing}; expected {list(keys)}")
    n = len(d["step"])
    return [_a(d[k], f"{where}.{k}", n) for k in keys], n


def check_batch(batch: Mapping[str, Any]) -> dict[str, Any]:
    """Check a sink batch at the boundary (fields, lengths, episode ids) and return its parts:
    ``run``, ``episode`` (int64[E]), ``ints`` (the 21 integer columns in wire order), ``sizes``,
    ``rewards`` / ``return_`` / ``epsilon`` / ``scores`` / ``q_values`` arrays, ``n_categories``,
    ``n_actions``. Raises ValueError / TypeError naming the bad field."""
    missing, unknown = BATCH_KEYS - batch.keys(), batch.keys() - BATCH_KEYS - OPTIONAL_BATCH_KEYS
    if missing or unknown:
        raise TypeError(f"episode batch: missing fields {sorted(missing)}, unknown fields {sorted(unknown)} "
                        "(see pipeline/rl/sink.py)")
    run = int(batch["run"])
    where = f"episode batch of run {run}"
    episode = _a(batch["episode"], f"{where}.episode")
    e = len(episode)
    steps = _a(batch["steps"], f"{where}.steps", e)
    t = int(steps.sum()) if e else 0
    states = _a(batch["states"], f"{where}.states", t)
    actions = _a(batch["actions"], f"{where}.actions", t)
    rewards = _a(batch["rewards"], f"{where}.rewards", t).astype("<f4", copy=False)
    flags = _a(batch["flags"], f"{where}.flags", t)
    summary = batch["summary"]
    missing, unknown = set(SUMMARY_KEYS) - summary.keys(), summary.keys() - set(SUMMARY_KEYS)
    if missing or unknown:
        raise ValueError(f"{where}.summary: missing {sorted(missing)}, unknown {sorted(unknown)}; "
                         f"expected {list(SUMMARY_KEYS)}")
    sm = {k: _a(summary[k], f"{where}.summary.{k}", e) for k in SUMMARY_KEYS}
    rec, m = _table(batch["recognitions"], RECOGNITION_KEYS, f"{where}.recognitions")
    un, k = _table(batch["unsafe_added"], UNSAFE_KEYS, f"{where}.unsafe_added")
    ncat, scores = 0, np.zeros(0, "<f4")
    if m:
        sc = np.asarray(batch["recognitions"].get("scores", ()), dtype="<f4")
        if sc.size:
            if sc.ndim != 2 or sc.shape[0] != m:
                raise ValueError(f"{where}.recognitions.scores: expected shape ({m}, n_categories), got {sc.shape}")
            ncat, scores = sc.shape[1], sc
    if e:
        first, last = int(episode[0]), int(episode[-1])
        if last - first != e - 1 or (e > 1 and (np.diff(episode) != 1).any()):
            raise ValueError(f"{where}: episode ids must be consecutive, got {episode.tolist()}")
        for name, col, n in (("recognitions", rec[0], m), ("unsafe_added", un[0], k)):
            if n and (col.min() < first or col.max() > last):
                raise ValueError(f"{where}.{name}.episode: values outside the batch's episodes {first}..{last}")
    n_actions, q = 0, None
    if batch.get("q_values") is not None:
        q = np.asarray(batch["q_values"], dtype="<f4")
        if q.ndim != 3 or q.shape[0] != e:
            raise ValueError(f"{where}.q_values: expected shape ({e}, n_states, n_actions), got {q.shape}")
        n_actions = q.shape[2]
    arrays = [episode, steps, sm["collisions"], sm["reached_goal"], sm["prevented"], sm["greedy_optimal"],
              states, actions, flags, *rec, *un]
    try:
        ints = np.concatenate(arrays, dtype=np.int64, casting="same_kind")
    except TypeError as exc:
        raise ValueError(f"{where}: integer fields must hold integers or booleans ({exc})") from None
    unsigned = 6 * e + 3 * t  # episode ids, summaries, states, actions, flags
    if ints.size and ints[:unsigned].min(initial=0) < 0:
        raise ValueError(f"{where}: negative episode ids, step counts, summary counts, states, actions or flags")
    if m and rec[0].min() < 0 or k and un[0].min() < 0:
        raise ValueError(f"{where}: negative episode id in recognitions or unsafe_added")
    return {"run": run, "episode": episode, "ints": ints, "sizes": [e] * 6 + [t] * 3 + [m] * 7 + [k] * 5,
            "rewards": rewards, "return_": sm["return_"].astype("<f8", copy=False),
            "epsilon": sm["epsilon"].astype("<f8", copy=False), "scores": scores, "n_categories": ncat,
            "q_values": q, "n_actions": n_actions, "n_episodes": e, "n_steps": t}


def one_episode_batch(fields: Mapping[str, Any]) -> dict[str, Any]:
    """The batch of the single episode ``fields`` (what :func:`pipeline.rl.sink.split_batch` gives
    for one episode; ``summary`` may also hold ``steps``; ``q_values`` one [n_states, n_actions])."""
    missing = EPISODE_KEYS - fields.keys()
    unknown = fields.keys() - EPISODE_KEYS - {"steps", "q_values"}
    if missing or unknown:
        raise TypeError(f"episode record: missing fields {sorted(missing)}, unknown fields {sorted(unknown)} "
                        "(see pipeline/rl/sink.py)")
    ep = int(fields["episode"])
    n = len(fields["states"])
    summary = dict(fields["summary"])
    for given in (summary.pop("steps", n), fields.get("steps", n)):
        if int(given) != n:
            raise ValueError(f"episode record (run {fields['run']}, episode {ep}): steps {given} but "
                             f"{n} states")

    def rows(d):
        d = dict(d or {})
        if len(d.get("step", ())):
            d["episode"] = np.full(len(d["step"]), ep, np.int64)
        return d

    out = {"run": int(fields["run"]), "episode": np.array([ep], np.int64), "steps": np.array([n], np.int64),
           "states": fields["states"], "actions": fields["actions"], "rewards": fields["rewards"],
           "flags": fields["flags"], "recognitions": rows(fields["recognitions"]),
           "unsafe_added": rows(fields["unsafe_added"]),
           "summary": {k: np.asarray([v]) for k, v in summary.items()}}
    if fields.get("q_values") is not None:
        out["q_values"] = np.asarray(fields["q_values"])[None]
    return out


SMALL = 400  # integer fields of a kind with at most this many values are encoded by table lookup


def encode_batch(b: Mapping[str, Any]) -> bytes:
    """Serialize a checked batch (:func:`check_batch`) as ``fsrl.records.EpisodeBatch``."""
    ints, sizes = b["ints"], b["sizes"]
    seg: list[bytes] = []
    start = 0
    table = W.VARINT_TABLE
    for first, last in ((0, 6), (6, 9), (9, 16), (16, 21)):  # per-episode, per-step, recognition, unsafe
        group = sizes[first:last]
        bounds = list(itertools.accumulate(group, initial=0))
        values = ints[start:start + bounds[-1]]
        start += bounds[-1]
        if bounds[-1] <= SMALL:  # a few hundred values: a table lookup each beats a dozen numpy calls
            vals = values.tolist()
            if not vals or (min(vals) >= 0 and max(vals) < len(table)):
                seg += [b"".join([table[v] for v in vals[bounds[i]:bounds[i + 1]]]) for i in range(len(group))]
                continue
        payload, cum = W.varints(values)  # one vector pass for the fields of a kind
        if cum is not None:  # not every value < 128: byte offsets of the field boundaries
            bounds = cum[bounds].tolist()
        seg += [payload[bounds[i]:bounds[i + 1]] for i in range(len(group))]
    lf = W.len_field
    summary = (lf(1, seg[1]) + lf(2, seg[2]) + lf(3, b["return_"].tobytes()) + lf(4, seg[3])
               + lf(5, seg[4]) + lf(6, b["epsilon"].tobytes()) + lf(7, seg[5]))
    steps = lf(1, seg[6]) + lf(2, seg[7]) + lf(3, b["rewards"].tobytes()) + lf(4, seg[8])
    rec = b"".join([lf(i + 1, seg[9 + i]) for i in range(7)])
    if rec:
        rec += W.uint_field(8, b["n_categories"]) + lf(9, b["scores"].tobytes())
    unsafe = b"".join([lf(i + 1, seg[16 + i]) for i in range(5)])
    q = b["q_values"]
    return b"".join((W.uint_field(1, b["run"]), lf(2, seg[0]), lf(3, summary), lf(4, steps), lf(5, rec),
                     lf(6, unsafe), W.uint_field(7, b["n_actions"]),
                     lf(8, q.tobytes() if q is not None else b"")))


def encode_batch_protobuf(b: Mapping[str, Any]) -> bytes:
    """Reference encoder through the Protobuf ``Message`` API (slow; tests compare the bytes)."""
    cols = np.split(b["ints"], np.cumsum(b["sizes"])[:-1])
    msg = S.EpisodeBatch(run=b["run"])

    def put(sub, names, arrays):
        for name, arr in zip(names, arrays):
            if len(arr):
                getattr(sub, name).extend(arr.tolist())

    put(msg, ("episode",), cols[0:1])
    put(msg.summary, ("steps", "collisions", "reached_goal", "prevented", "greedy_optimal"),
        [cols[1], cols[2], cols[3].astype(bool), cols[4], cols[5].astype(bool)])
    put(msg.summary, ("return_", "epsilon"), [b["return_"], b["epsilon"]])
    put(msg.steps, ("states", "actions", "rewards", "flags"), [cols[6], cols[7], b["rewards"], cols[8]])
    put(msg.recognitions, ("episode", "step", "state", "action", "picture", "predicted", "true_category"),
        cols[9:16])
    if len(cols[9]):
        msg.recognitions.n_categories = b["n_categories"]
        put(msg.recognitions, ("scores",), [b["scores"].ravel()])
    put(msg.unsafe_added, ("episode", "step", "state", "action", "source"), cols[16:21])
    if b["q_values"] is not None:
        msg.n_actions = b["n_actions"]
        put(msg, ("q_values",), [b["q_values"].ravel()])
    return msg.SerializeToString(deterministic=True)
