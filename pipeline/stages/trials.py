"""Stage ``trials``: independent runs of one method on one maze; writes ``<out>/summary.json``.

    python -m pipeline trials method=ssrl maze=7x7 runs=100 episodes=500 seed=0 out=runs/ssrl7
"""
from __future__ import annotations

import sys
import time
from dataclasses import asdict

import hydra
import numba
from hydra.core.config_store import ConfigStore
from omegaconf import DictConfig, OmegaConf

from pipeline.rl.methods import METHODS, MethodSpec
from pipeline.rl.runner import run_trials
from pipeline.stages._common import CONF_DIR, ConfigError, require, write_json_atomic
from pipeline.world.maze import MazeError, load_layout

_cs = ConfigStore.instance()
for _name, _spec in METHODS.items():
    _cs.store(group="method", name=_name, node=asdict(_spec))


def method_from_config(cfg: DictConfig) -> MethodSpec:
    try:
        return MethodSpec(**OmegaConf.to_container(cfg.method, resolve=True))
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"config key 'method': {exc}") from None


def build_recogniser(cfg: DictConfig, method: MethodSpec):
    kind = cfg.recogniser.kind
    if not method.uses_recogniser:
        return None
    if kind == "oracle":
        from pipeline.stages._recognisers import OracleRecogniser
        return OracleRecogniser()
    if kind == "relation_net":
        from pipeline.stages._recognisers import relation_net_recogniser
        return relation_net_recogniser(cfg, method)
    raise ConfigError(f"config key 'recogniser.kind': method {method.name!r} needs a recogniser "
                      f"(oracle or relation_net), got {kind!r}")


def run(cfg: DictConfig) -> dict:
    require(int(cfg.runs) >= 1, "runs", f"must be >= 1, got {cfg.runs}")
    require(int(cfg.episodes) >= 1, "episodes", f"must be >= 1, got {cfg.episodes}")
    require(int(cfg.seed) >= 0, "seed", f"must be >= 0, got {cfg.seed}")
    method = method_from_config(cfg)
    try:
        layout = load_layout(str(cfg.maze))
    except MazeError as exc:
        raise ConfigError(f"config key 'maze': {exc}") from None
    recogniser = build_recogniser(cfg, method)
    if int(cfg.threads) > 0:
        numba.set_num_threads(int(cfg.threads))
    t0 = time.perf_counter()
    result = run_trials(layout, method, int(cfg.runs), int(cfg.episodes), int(cfg.seed),
                        recogniser=recogniser, progress=bool(cfg.progress))
    summary = result.summary()
    summary["method_spec"] = asdict(method)
    summary["seconds"] = round(time.perf_counter() - t0, 3)
    write_json_atomic(f"{cfg.out}/summary.json", summary)
    return summary


@hydra.main(config_path=CONF_DIR, config_name="trials", version_base="1.3")
def main(cfg: DictConfig) -> None:
    try:
        summary = run(cfg)
    except ConfigError as exc:
        print(f"error: {exc}", file=sys.stderr)
        raise SystemExit(2) from None
    c = summary["collisions"]
    print(f"{summary['method']} on {summary['maze']}: collisions {c['mean']:.2f} +- {c['std']:.2f} "
          f"over {summary['n_runs']} runs; converged runs {summary['converged_runs']}; "
          f"wrote {cfg.out}/summary.json")
