"""Synthetic episode records for the records tests and benchmarks (``from synthetic_records import
...`` in tests, ``from tests.synthetic_records import ...`` from the repository root): the fields,
dtypes and flag semantics the trial runner hands to its sink. Not a simulation: the robot
random-walks on the free cells, a step toward an obstacle is a recognition, a wrong recognition a
collision with self-recovery.
"""

from __future__ import annotations

import io
from collections.abc import Iterator
from typing import Any

import numpy as np

from pipeline.records import RecordWriter
from pipeline.records import schema as S
from pipeline.world.maze import ACTION_NAMES, MOVES
from pipeline.world.pictures import CATEGORIES

MAZE_5X5 = {
    "layout": ["S...X", ".X...", "...X.", "X....", "..X.G"],
    "categories": list(CATEGORIES),
    "actions": ACTION_NAMES,
    "moves": MOVES,
}  # what the trials stage records
LAYOUT_5X5 = MAZE_5X5["layout"]


def maze_layout(size: int = 11, n_obstacles: int | None = None, seed: int = 0) -> list[str]:
    """A square layout with start top-left, goal bottom-right and ``n_obstacles`` obstacle cells."""
    rng = np.random.default_rng(seed)
    n_obstacles = n_obstacles if n_obstacles is not None else max(1, size * size // 8)
    grid = np.full((size, size), ".")
    cells = rng.choice(np.arange(1, size * size - 1), size=n_obstacles, replace=False)
    grid.flat[cells] = "X"
    grid[0, 0], grid[-1, -1] = "S", "G"
    return ["".join(r) for r in grid]


def obstacle_assignment(layout: list[str], run: int, seed: int = 0) -> list[dict[str, int]]:
    """A per-run assignment of the 10 physical obstacles to the layout's obstacle cells."""
    rng = np.random.default_rng([seed, run])
    width = len(layout[0])
    cells = [r * width + c for r, row in enumerate(layout) for c, ch in enumerate(row) if ch == "X"]
    physical = rng.permutation(np.resize(rng.permutation(10), len(cells)))
    return [
        {
            "cell": cell,
            "physical": int(p),
            "category": int(p) // 2,
            "instance": int(p) % 2,
            "orientation": int(rng.integers(4)),
        }
        for cell, p in zip(cells, physical)
    ]


def tiny_png(seed: int, size: int = 8) -> bytes:
    """A small deterministic PNG (needs Pillow)."""
    from PIL import Image

    Image.fromarray(
        np.random.default_rng(seed).integers(0, 256, (size, size, 3), dtype=np.uint8)
    ).save(buf := io.BytesIO(), format="PNG")
    return buf.getvalue()


def episodes(
    layout: list[str],
    *,
    runs: int,
    episodes_per_run: int,
    seed: int = 0,
    min_steps: int = 20,
    max_steps: int = 200,
    n_categories: int = 5,
    scores: bool = True,
) -> Iterator[dict[str, Any]]:
    """Yield one episode's fields (``split_batch``'s form; :func:`make_batch` joins them into a sink batch) in
    run-major order, plus a ``_substitutions`` list of substitution keyword dicts (pass those to
    ``sink.substitution``)."""
    height, width = len(layout), len(layout[0])
    obstacle = np.array([ch == "X" for row in layout for ch in row])
    deltas = np.array(MOVES)
    for run in range(runs):
        rng = np.random.default_rng([seed, run])
        assignment = {o["cell"]: o for o in obstacle_assignment(layout, run, seed)}
        for ep in range(episodes_per_run):
            n = int(rng.integers(min_steps, max_steps + 1))
            acts = rng.integers(0, 4, n).astype(np.int8)
            states = np.empty(n, np.int32)
            flags = np.zeros(n, np.uint8)
            rewards = np.zeros(n, np.float32)
            r_rows, u_rows, subs, pos = [], [], [], 0
            for t in range(n):
                states[t] = pos
                row, col = divmod(pos, width)
                nr, nc = row + deltas[acts[t], 0], col + deltas[acts[t], 1]
                if not (0 <= nr < height and 0 <= nc < width):
                    continue
                nxt = nr * width + nc
                if obstacle[nxt]:
                    ob = assignment[nxt]
                    pic = (
                        ob["category"] * 8
                        + ob["instance"] * 4
                        + int((acts[t] + 2 - ob["orientation"]) % 4)
                    )
                    correct = rng.random() < 0.8
                    pred = (
                        ob["category"]
                        if correct
                        else int((ob["category"] + 1 + rng.integers(4)) % n_categories)
                    )
                    r_rows.append((t, pos, acts[t], pic, pred, ob["category"]))
                    if correct:
                        flags[t] |= S.FLAG_RESELECTED
                        u_rows.append((t, pos, acts[t], 0))
                    else:
                        flags[t] |= S.FLAG_COLLIDED | S.FLAG_RECOVERED
                        rewards[t] = -1.0
                        u_rows.append((t, pos, acts[t], 1))
                        subs.append(
                            {
                                "run": run,
                                "episode": ep,
                                "step": t,
                                "picture": pic,
                                "category": ob["category"],
                                "position": int(rng.integers(5)),
                            }
                        )
                    continue
                pos = nxt
            if n < max_steps:
                flags[-1] |= S.FLAG_GOAL
                rewards[-1] = 1.0
            else:
                flags[-1] |= S.FLAG_TRUNCATED
            m = len(r_rows)
            rec = {
                k: np.array([r[i] for r in r_rows], dtype=dt)
                for i, (k, dt) in enumerate(
                    [
                        ("step", np.int32),
                        ("state", np.int32),
                        ("action", np.int8),
                        ("picture", np.int16),
                        ("predicted", np.int8),
                        ("true", np.int8),
                    ]
                )
            }
            rec["scores"] = (
                rng.random((m, n_categories)).astype(np.float32)
                if scores
                else np.zeros((0, 0), np.float32)
            )
            unsafe = {
                k: np.array([u[i] for u in u_rows], dtype=dt)
                for i, (k, dt) in enumerate(
                    [
                        ("step", np.int32),
                        ("state", np.int32),
                        ("action", np.int8),
                        ("source", np.int8),
                    ]
                )
            }
            yield {
                "run": run,
                "episode": ep,
                "states": states,
                "actions": acts,
                "rewards": rewards,
                "flags": flags,
                "recognitions": rec,
                "unsafe_added": unsafe,
                "summary": {
                    "steps": n,
                    "collisions": int(((flags & S.FLAG_COLLIDED) != 0).sum()),
                    "return_": float(rewards.sum()),
                    "reached_goal": n < max_steps,
                    "prevented": int(((flags & S.FLAG_RESELECTED) != 0).sum()),
                    "epsilon": 0.1,
                    "greedy_optimal": bool(n < max_steps and ep % 3 == 2),
                },
                "_substitutions": subs,
            }


def make_batch(eps: list[dict[str, Any]]) -> dict[str, Any]:
    """The sink batch (``pipeline/rl/sink.py``) of consecutive episodes ``eps`` of one run, given as
    per-episode fields (the inverse of ``split_batch``; a ``q_values`` table [n_states, n_actions] each, if any)."""

    def cat(key, sub=None):
        parts = [(e[sub] if sub else e).get(key, ()) for e in eps]
        return np.concatenate([np.asarray(p) for p in parts]) if parts else np.zeros(0)

    def rows(sub, keys):
        n = [len(e[sub].get("step", ())) for e in eps]
        out = {k: cat(k, sub) for k in keys}
        out["episode"] = np.repeat([e["episode"] for e in eps], n).astype(np.int32)
        return out

    batch = {
        "run": eps[0]["run"],
        "episode": np.array([e["episode"] for e in eps], np.int32),
        "steps": np.array([len(e["states"]) for e in eps], np.int32),
        "states": cat("states"),
        "actions": cat("actions"),
        "rewards": cat("rewards"),
        "flags": cat("flags"),
        "recognitions": rows(
            "recognitions", ("step", "state", "action", "picture", "predicted", "true")
        ),
        "unsafe_added": rows("unsafe_added", ("step", "state", "action", "source")),
        "summary": {
            k: np.array([e["summary"][k] for e in eps]) for k in eps[0]["summary"] if k != "steps"
        },
    }
    scores = [e["recognitions"]["scores"] for e in eps if len(e["recognitions"].get("step", ()))]
    batch["recognitions"]["scores"] = (
        np.concatenate(scores).astype(np.float32) if scores else np.zeros((0, 0), np.float32)
    )
    if "q_values" in eps[0]:
        batch["q_values"] = np.stack([e["q_values"] for e in eps])
    return batch


def batches(
    layout: list[str], *, batch_size: int = 4, **kw
) -> Iterator[tuple[dict[str, Any], list[dict]]]:
    """:func:`episodes` grouped as the trial runner hands them over: (batch of up to ``batch_size``
    consecutive episodes of one run, the per-episode fields)."""
    group: list[dict[str, Any]] = []
    for f in episodes(layout, **kw):
        if group and (f["run"] != group[0]["run"] or len(group) == batch_size):
            yield make_batch(group), group
            group = []
        group.append(f)
    if group:
        yield make_batch(group), group


def write_synthetic(
    path,
    *,
    runs: int = 3,
    episodes_per_run: int = 10,
    seed: int = 0,
    size: int = 5,
    flush_every: int = 5,
    pictures: bool = True,
    batch_size: int = 4,
    **kw,
) -> list[dict[str, Any]]:
    """Write a small synthetic record file, ``batch_size`` episodes a sink batch; return the episode
    fields written (each with its ``_substitutions``)."""
    layout = LAYOUT_5X5 if size == 5 else maze_layout(size, seed=seed)
    written = []
    pics = {pid: tiny_png(pid) for pid in range(40)} if pictures else None
    with RecordWriter(
        path,
        metadata={
            "config": {"experiment": "synthetic", "seed": seed, "runs": runs},
            "seeds": list(range(runs)),
        },
        maze={**MAZE_5X5, "layout": layout},
        runs=[obstacle_assignment(layout, r, seed) for r in range(runs)],
        pictures=pics,
        flush_every=flush_every,
        **kw,
    ) as w:
        for batch, group in batches(
            layout, batch_size=batch_size, runs=runs, episodes_per_run=episodes_per_run, seed=seed
        ):
            for s in (s for f in group for s in f["_substitutions"]):
                w.substitution(
                    **s
                )  # as the runner does: while the episodes run, before their batch
            w.episodes(**batch)
            written += group
    return written
