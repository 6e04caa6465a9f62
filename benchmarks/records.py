"""Recording speed and size: the MCAP record writer and reader at paper scale (DESIGN.md "Records").

    python -m benchmarks.records [--runs 100] [--episodes 500] [--no-trial] [--json PATH]

1. Synthetic workload: ``runs x episodes`` episodes of 20-200 steps (long at first, shorter as
   "learning" proceeds), a few recognitions, unsafe-set additions and substitutions, handed to
   :class:`pipeline.records.RecordWriter` in sink batches of 25 episodes of one run (the trial
   runner hands over 100 at a time); prints episodes/s, bytes per step, and the read-back speed of
   :func:`pipeline.records.read_records`.
2. The real trial (when ``pipeline.rl.runner`` is present): the 11x11 few-shot experiment
   (``fewshot_dss``, 100 x 500) with a deterministic half-right recogniser, timed without a sink,
   with a sink that drops everything (the runner's own cost of emitting episodes), and with the
   record writer; the recording overhead is reported relative to the trial without recording.
   Times are CPU seconds of this process (``time.process_time``, numba on one thread), the best of
   ``--repeat`` repetitions: a busy shared machine disturbs them less than wall-clock time.
"""
from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from pipeline.records import RecordWriter, read_records
from tests.synthetic_records import make_batch, maze_layout, obstacle_assignment, tiny_png

BATCH = 25  # episodes a sink batch (the trial runner's chunk_episodes)


def synthetic_workload(runs: int, episodes: int, seed: int = 0, width: int = 11):
    """Sink batches of ``BATCH`` episodes of one run, each with its substitutions, shaped like the
    trial runner's."""
    rng = np.random.default_rng(seed)
    n_cells = width * width
    out = []
    for run in range(runs):
        for ep in range(episodes):
            n = int(np.clip(20 + 180 * np.exp(-ep / 60) + rng.normal(0, 10), 20, 200))
            flags = np.zeros(n, np.uint8)
            u = rng.random(n)
            flags[u < 0.02] = 1  # reselected after a correct recognition
            flags[(u >= 0.02) & (u < 0.03)] = 2 | 4  # collided and recovered
            flags[-1] |= 8 if n < 200 else 16
            rewards = np.where(flags & 2, -1.0, 0.0).astype(np.float32)
            rewards[-1] += 1.0 if n < 200 else 0.0
            seen = np.flatnonzero(flags & 3).astype(np.int32)
            m = len(seen)
            states = rng.integers(0, n_cells, n).astype(np.int32)
            actions = rng.integers(0, 4, n).astype(np.int8)
            true = rng.integers(0, 5, m).astype(np.int8)
            predicted = np.where(flags[seen] & 1, true, (true + 1) % 5).astype(np.int8)
            rec = {"step": seen, "state": states[seen], "action": actions[seen],
                   "picture": (true * 8 + rng.integers(0, 8, m)).astype(np.int16), "predicted": predicted,
                   "true": true, "scores": rng.random((m, 5)).astype(np.float32)}
            unsafe = {"step": seen, "state": states[seen], "action": actions[seen],
                      "source": np.where(flags[seen] & 1, 0, 1).astype(np.int8)}
            subs = [{"run": run, "episode": ep, "step": int(s), "picture": int(rec["picture"][i]),
                     "category": int(true[i]), "position": int(rng.integers(5))}
                    for i, s in enumerate(seen) if flags[s] & 2]
            out.append(({"run": run, "episode": ep, "states": states, "actions": actions, "rewards": rewards,
                         "flags": flags, "recognitions": rec, "unsafe_added": unsafe,
                         "summary": {"steps": n, "collisions": int((flags & 2).astype(bool).sum()),
                                     "return_": float(rewards.sum()), "reached_goal": n < 200,
                                     "prevented": int((flags & 1).sum()), "epsilon": 0.1,
                                     "greedy_optimal": ep > episodes // 2}}, subs))
    return [(make_batch([f for f, _ in out[i:i + BATCH]]), [s for _, subs in out[i:i + BATCH] for s in subs])
            for i in range(0, len(out), BATCH)]


def _best(fn, repeat: int):
    """(CPU s, wall s, result) of the fastest of ``repeat`` calls (a shared machine adds noise)."""
    best = None
    for _ in range(repeat):
        cpu0, wall0 = time.process_time(), time.perf_counter()
        out = fn()
        t = (time.process_time() - cpu0, time.perf_counter() - wall0, out)
        best = t if best is None or t[0] < best[0] else best
    return best


def bench_synthetic(runs: int, episodes: int, folder: Path, repeat: int = 3) -> dict:
    work = synthetic_workload(runs, episodes)
    steps = sum(len(b["states"]) for b, _ in work)
    n_eps = sum(len(b["episode"]) for b, _ in work)
    n_subs = sum(len(s) for _, s in work)
    layout = maze_layout(11)
    path = folder / "synthetic.mcap"
    pictures = {p: tiny_png(p, 84) for p in range(40)}

    def write():
        with RecordWriter(path, metadata={"config": {"benchmark": "records"}, "seeds": list(range(runs))},
                          maze={"layout": layout}, runs=[obstacle_assignment(layout, r) for r in range(runs)],
                          pictures=pictures, flush_every=500) as w:
            for batch, subs in work:
                for s in subs:
                    w.substitution(**s)
                w.episodes(**batch)

    cpu, wall, _ = _best(write, repeat)
    size = path.stat().st_size
    rcpu, rwall, recs = _best(lambda: read_records(path), repeat)
    assert len(recs.steps) == steps and len(recs.episodes) == n_eps
    pictures_bytes = sum(len(b) for b in recs.meta.pictures.values())
    return {"episodes": n_eps, "batches": len(work), "steps": steps, "substitutions": n_subs,
            "write_cpu_s": round(cpu, 3), "write_wall_s": round(wall, 3),
            "episodes_per_s": round(n_eps / cpu), "messages_per_s": round((len(work) + n_subs) / cpu),
            "us_per_episode": round(cpu / n_eps * 1e6, 2), "us_per_batch": round(cpu / len(work) * 1e6, 1),
            "file_bytes": size, "bytes_per_step": round((size - pictures_bytes) / steps, 3),
            "bytes_per_step_incl_pictures": round(size / steps, 3),
            "read_cpu_s": round(rcpu, 3), "read_wall_s": round(rwall, 3),
            "read_steps_per_s": round(steps / rcpu)}


def bench_trial(runs: int, episodes: int, folder: Path, repeat: int = 3) -> dict | None:
    try:
        import numba

        from pipeline.rl.methods import get_method
        from pipeline.rl.runner import run_trials
        from pipeline.rl.oracle import OracleRecogniser
        from pipeline.world.maze import load_layout
    except ImportError as exc:
        print(f"(trial benchmark skipped: {exc})")
        return None

    class HalfRight(OracleRecogniser):
        """Right on even picture ids, wrong on odd ones (both branches of Algorithm 1)."""

        def predictions(self, run):
            p = super().predictions(run)
            p[1::2] = (p[1::2] + 1) % 5
            return p

        def scores(self, run, pics):
            return np.full((len(pics), 5), 0.2, np.float32)

    class Drop:
        def episodes(self, **batch):
            pass

        def substitution(self, **fields):
            pass

    numba.set_num_threads(1)
    layout, method = load_layout("11x11"), get_method("fewshot_dss")
    run_trials(layout, method, 2, 10, seed=0, recogniser=HalfRight(), progress=False, sink=Drop())  # compile

    def trial(sink):
        return run_trials(layout, method, runs, episodes, seed=0, recogniser=HalfRight(), progress=False,
                          sink=sink)

    path = folder / "trial.mcap"

    def recorded():
        with RecordWriter(path, maze={"layout": list(layout.rows)}, flush_every=500) as w:
            trial(w)
        return w

    base_cpu, base_wall, res = _best(lambda: trial(None), repeat)
    drop_cpu, drop_wall, _ = _best(lambda: trial(Drop()), repeat)
    rec_cpu, rec_wall, w = _best(recorded, repeat)
    steps = int(res.steps.sum())
    return {"method": "fewshot_dss", "maze": "11x11", "runs": runs, "episodes": episodes, "steps": steps,
            "trial_cpu_s": round(base_cpu, 3), "trial_emitting_cpu_s": round(drop_cpu, 3),
            "trial_recording_cpu_s": round(rec_cpu, 3),
            "writer_overhead_cpu_s": round(rec_cpu - drop_cpu, 3),
            "recording_overhead_vs_trial": round((rec_cpu - base_cpu) / base_cpu, 2),
            "writer_only_overhead_vs_trial": round((rec_cpu - drop_cpu) / base_cpu, 2),
            "wall_s": {"trial": round(base_wall, 3), "emitting": round(drop_wall, 3), "recording": round(rec_wall, 3)},
            "episodes_recorded": w.n_episodes, "substitutions_recorded": w.n_substitutions,
            "file_bytes": path.stat().st_size, "bytes_per_step": round(path.stat().st_size / steps, 3)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--episodes", type=int, default=500)
    ap.add_argument("--no-trial", action="store_true", help="skip the real-trial comparison")
    ap.add_argument("--repeat", type=int, default=3, help="time the best of this many repetitions")
    ap.add_argument("--json", default="reports/benchmarks/records.json")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        syn = bench_synthetic(args.runs, args.episodes, folder, args.repeat)
        print(f"synthetic {args.runs} x {args.episodes}: {syn['episodes']} episodes, {syn['steps']} steps, "
              f"{syn['substitutions']} substitutions, {syn['batches']} batches of {BATCH}")
        print(f"  write: {syn['write_cpu_s']} s CPU ({syn['write_wall_s']} s wall): {syn['episodes_per_s']} "
              f"episodes/s, {syn['messages_per_s']} messages/s, {syn['us_per_episode']} us/episode, {syn['us_per_batch']} us/batch")
        print(f"  size: {syn['file_bytes']} bytes, {syn['bytes_per_step']} bytes/step "
              f"({syn['bytes_per_step_incl_pictures']} with the 40 pictures)")
        print(f"  read: {syn['read_cpu_s']} s CPU ({syn['read_wall_s']} s wall), {syn['read_steps_per_s']} steps/s")
        trial = None if args.no_trial else bench_trial(args.runs, args.episodes, folder, args.repeat)
        if trial:
            print(f"trial {trial['method']} {trial['maze']} {trial['runs']} x {trial['episodes']} "
                  f"({trial['steps']} steps), CPU s: no sink {trial['trial_cpu_s']}, runner emitting to a "
                  f"dropping sink {trial['trial_emitting_cpu_s']}, recording {trial['trial_recording_cpu_s']}")
            print(f"  recording overhead {trial['recording_overhead_vs_trial']:.0%} of the trial "
                  f"(writer alone {trial['writer_only_overhead_vs_trial']:.0%}); "
                  f"{trial['bytes_per_step']} bytes/step")
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps({"synthetic": syn, "trial": trial}, indent=2) + "\n")
        print(f"wrote {args.json}")


if __name__ == "__main__":
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")
    main()
