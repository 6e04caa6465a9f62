"""Checking an episode batch (``pipeline/rl/sink.py``) before it is encoded: every key present,
every column 1-D, of its length and in its field's range, cast to the dtype the codec writes
(:mod:`.codec`; a code column as uint8 when every value is below 128, its own varint byte, else as
int64). Errors name the batch, the column and what was wrong.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from typing import Any

import numpy as np

from .codec import COLUMNS, FIXED, REWARDS, SMALL_REWARDS, SUBS, TRANSITIONS
from .schema import BOOL, CODE, F32, F64, I32, MESSAGES, TRANSITION_PARTS, U32, Field
from .step_columns import PART_LIMITS, scan_steps

_RANGE = {I32: (-(2**31), 2**31), U32: (0, 2**31), CODE: (0, 2**32)}  # of integer fields' values
OPTIONAL = frozenset({"q_values", "substitutions"})  # sink batch keys that may be left out
BATCH_KEYS = frozenset(
    {f.name for f in MESSAGES["EpisodeBatch"]} - {"n_actions"} - OPTIONAL
    | {key for key, _, _ in TRANSITION_PARTS}
    | {REWARDS.name}
)


@functools.cache
def _iinfo(dtype: np.dtype) -> np.iinfo:
    return np.iinfo(dtype)  # numpy builds it anew on every call


def _array(a: Any, f: Field, n: int | None, where: str) -> np.ndarray:
    """``a`` as a 1-D array of length ``n``, of integers or booleans unless ``f`` is a float."""
    a = np.asarray(a)
    if a.ndim != 1 or (n is not None and len(a) != n):
        got = (
            f"length {len(a)}, expected {n}"
            if a.ndim == 1
            else f"a 1-D array expected, got shape {a.shape}"
        )
        raise ValueError(f"{where}: {got}")
    if f.type not in (F32, F64) and a.dtype.kind not in "biu":
        raise ValueError(f"{where}: integer fields must hold integers or booleans, got {a.dtype}")
    return a


def _column(a: Any, f: Field, n: int | None, where: str) -> np.ndarray:
    """``a`` checked (1-D, length ``n``, integers in the field's range) as the field's payload."""
    a = _array(a, f, n, where)
    if f.type in (F32, F64):
        return a.astype(FIXED[f.type], copy=False)
    if f.type == BOOL:
        return (a != 0).view(np.uint8)
    a = a.view(np.uint8) if a.dtype.kind == "b" else a
    (lo, hi), info = _RANGE[f.type], _iinfo(a.dtype)  # checked only where the dtype reaches out
    if len(a) and (info.min < lo and int(a.min()) < lo or info.max >= hi and int(a.max()) >= hi):
        raise ValueError(f"{where}: values {int(a.min())}..{int(a.max())} outside {lo}..{hi - 1}")
    if f.type != CODE:
        return a.astype(FIXED[f.type], copy=False)
    # a code column: bytes when every value is its own varint byte, else int64 for the runtime
    one_byte = info.max < 128 or not len(a) or int(a.max()) < 128
    return a.astype(np.uint8 if one_byte else np.int64, copy=False)


def _steps(batch: Mapping[str, Any], n: int, where: str) -> dict[str, np.ndarray]:
    """The step columns of a batch of ``n`` steps checked, as payload arrays, in one pass
    (:mod:`.step_columns`): the cells, actions and flags as ``transitions`` pairs."""
    parts = {
        key: _array(batch[key], TRANSITIONS, n, f"{where}.{key}") for key, _, _ in TRANSITION_PARTS
    }
    rewards = _array(batch[REWARDS.name], REWARDS, n, f"{where}.{REWARDS.name}")
    found = scan_steps(*parts.values(), rewards)
    for low, high, key in zip(found.low, found.high, parts):
        if low < 0 or high >= PART_LIMITS[key]:
            limit = PART_LIMITS[key] - 1
            raise ValueError(f"{where}.{key}: values {low}..{high} outside 0..{limit}")
    out = {TRANSITIONS.name: found.transitions}
    if found.small_rewards is None:
        return out | {REWARDS.name: rewards.astype(FIXED[REWARDS.type], copy=False)}
    return out | {SMALL_REWARDS.name: found.small_rewards}


def check_batch(batch: Mapping[str, Any], *, with_steps: bool = True) -> dict[str, Any]:
    """Check a sink batch and return ``run``, ``episode``, ``cols`` (message -> field -> payload
    array) and ``scalars`` (message -> field -> int). Raises TypeError / ValueError naming the bad
    field. ``with_steps=False`` (``record=episodes``): the step columns are left out."""
    missing, unknown = BATCH_KEYS - batch.keys(), batch.keys() - BATCH_KEYS - OPTIONAL
    if missing or unknown:
        raise TypeError(
            f"episode batch: missing fields {sorted(missing)}, unknown fields {sorted(unknown)} "
            "(see pipeline/rl/sink.py)"
        )
    run = int(batch["run"])
    where, summary = f"episode batch of run {run}", batch["summary"]
    keys = [f.name for f in COLUMNS["EpisodeSummaries"][1:]]
    if set(keys) != summary.keys():
        raise ValueError(f"{where}.summary: fields {sorted(summary.keys())}; expected {keys}")
    ep = _column(batch["episode"], COLUMNS["EpisodeBatch"][0], None, f"{where}.episode")
    e = len(ep)
    if e and (np.diff(ep.astype(np.int64)) != 1).any():
        raise ValueError(f"{where}: episode ids must be consecutive, got {ep.tolist()}")
    cols = {"EpisodeBatch": {"episode": ep}, "EpisodeSummaries": {}, "Steps": {}}
    for f in COLUMNS["EpisodeSummaries"]:
        value = batch["steps"] if f.name == "steps" else summary[f.name]
        cols["EpisodeSummaries"][f.name] = _column(value, f, e, f"{where}.summary.{f.name}")
    t = int(cols["EpisodeSummaries"]["steps"].sum())
    if with_steps:
        cols["Steps"] = _steps(batch, t, where)
    scalars = {"EpisodeBatch": {"run": run, "n_actions": 0}, "Recognitions": {"n_categories": 0}}
    for sub in ("recognitions", "unsafe_added", "substitutions"):
        d, msg = batch.get(sub) or {}, SUBS[sub]
        n = len(d.get("step", ()))
        names = [f.key or f.name for f in COLUMNS[msg] if f.name != "scores"]
        if n and set(names) - d.keys():
            raise ValueError(f"{where}.{sub}: missing columns {sorted(set(names) - d.keys())}")
        cols[msg] = {
            f.name: _column(d[f.key or f.name], f, n, f"{where}.{sub}.{f.key or f.name}")
            for f in COLUMNS[msg]
            if n and f.name != "scores"
        }
        if (
            n
            and e
            and not ep[0] <= cols[msg]["episode"].min() <= cols[msg]["episode"].max() <= ep[-1]
        ):
            raise ValueError(
                f"{where}.{sub}.episode: values outside the batch's episodes {ep[0]}..{ep[-1]}"
            )
        sc = np.asarray(d.get("scores", ()), "<f4") if sub == "recognitions" and n else np.zeros(0)
        if sc.size and (sc.ndim != 2 or sc.shape[0] != n):
            raise ValueError(
                f"{where}.recognitions.scores: expected shape ({n}, n_categories), got {sc.shape}"
            )
        if sc.size:
            cols[msg]["scores"], scalars[msg]["n_categories"] = sc.ravel(), sc.shape[1]
    if batch.get("q_values") is not None:
        q = np.asarray(batch["q_values"], dtype="<f4")
        if q.ndim != 3 or q.shape[0] != e:
            raise ValueError(
                f"{where}.q_values: expected shape ({e}, n_states, n_actions), got {q.shape}"
            )
        cols["EpisodeBatch"]["q_values"], scalars["EpisodeBatch"]["n_actions"] = (
            q.ravel(),
            q.shape[2],
        )
    return {"run": run, "episode": ep, "cols": cols, "scalars": scalars}
