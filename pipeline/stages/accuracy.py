"""Stage ``accuracy``: the few-shot accuracy study of the paper's section 4.2.1 (Tables 1 and 2).

On the rendered query and support pictures with the meta-trained checkpoint (docs/fewshot.md).

    python -m pipeline accuracy [recogniser=relation_net|protonet|oracle|fixed_accuracy] [recogniser.checkpoint=...] [study.repeats=...]

Writes ``out_dir``/baseline.csv, table1.csv, table2.csv and summary.json for the report stage.
"""
from __future__ import annotations

import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch

from pipeline.fewshot.accuracy_study import run_study
from pipeline.fewshot.study_tables import baseline_frame, summary, table1_frame, table2_frame
from pipeline.files import write_json_atomic
from pipeline.stages._common import stage_main
from pipeline.stages._recognisers import build_recogniser
from pipeline.stages._schema import AccuracyConfig
from pipeline.world.pictures import CATEGORIES, N_PICTURES, picture_category


def run(cfg: AccuracyConfig, overrides: list[str] = ()) -> dict:
    config = cfg.study
    torch.set_num_threads(cfg.threads)
    start = time.perf_counter()
    recogniser = build_recogniser(cfg.recogniser, substitution_way=0, carry_over=False)
    names = list(CATEGORIES)
    categories = np.array([picture_category(p) for p in range(N_PICTURES)])
    result = run_study(recogniser, categories, config, progress=cfg.progress)
    out = Path(cfg.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    baseline_frame(result, names).to_csv(out / "baseline.csv", index=False)
    table1_frame(result, config.repeats).to_csv(out / "table1.csv", index=False)
    table2_frame(result).to_csv(out / "table2.csv", index=False)
    data = summary(result, names)
    data["config"] = {"recogniser": dict(cfg.recogniser), **asdict(config)}
    if hasattr(recogniser, "checkpoint"):
        data["checkpoint_metrics"] = recogniser.checkpoint["metrics"]
    write_json_atomic(out / "summary.json", data, sort_keys=True)  # no wall-clock figures: the same inputs give the same bytes
    print(
        f"query accuracy, original support set: {result.baseline_correct.sum()}/{result.per_category_total.sum()} "
        f"({100 * result.baseline_accuracy:.1f}%; paper 42.5%); per category "
        + ", ".join(f"{n} {c}/{t}" for n, c, t in zip(names, result.baseline_correct, result.per_category_total))
    )
    for n, (w, ns) in sorted(result.table2.items()):
        print(f"  {n} substitution(s): {100 * w:.2f}%  (no same picture {100 * ns:.2f}%)")
    print(f"accuracy study in {time.perf_counter() - start:.1f} s")
    return data


def written(cfg: AccuracyConfig, data: dict) -> list[str]:
    return [cfg.out_dir]


def main() -> None:
    stage_main("accuracy", run)
