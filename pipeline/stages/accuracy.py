"""Stage ``accuracy``: the few-shot accuracy study of the paper's section 4.2.1 (Tables 1 and 2).

On the rendered query and support pictures with the meta-trained checkpoint (docs/fewshot.md).

    python -m pipeline accuracy [recogniser=<name of conf/recogniser/>] [recogniser.checkpoint=...] [study.repeats=...]

Writes ``out_dir``/baseline.csv, table1.csv, table2.csv, draws.csv (every random draw),
families.csv (``study.family_episodes`` fresh episodes of the validation and of the test families:
which families each drew and its queries of each classified right,
``pipeline.fewshot.family_accuracy``) and summary.json (with the colour test: the query pictures
hue-turned by each of ``study.hue_shifts``, ``pipeline.fewshot.colour``, and the same on the
render's 400 ``views`` pictures of the query obstacles, ``pipeline.fewshot.views``, each picture
with its obstacle; and the held-out families' accuracy with episode- and family-level intervals)
for the report stage.
"""

from __future__ import annotations

import inspect
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

from pipeline.config.fields import refuse
from pipeline.config.recognisers import (
    build_recogniser,
    recogniser_arguments,
    recognisers_taking,
)
from pipeline.fewshot.accuracy_study import run_study
from pipeline.fewshot.colour import colour_test
from pipeline.fewshot.family_accuracy import family_study
from pipeline.fewshot.study_tables import (
    baseline_frame,
    draws_frame,
    summary,
    table1_frame,
    table2_frame,
)
from pipeline.fewshot.views import has_views, views_predictions
from pipeline.files import write_atomic, write_json_atomic
from pipeline.schemas.fewshot import AccuracyConfig
from pipeline.stages import stage_main
from pipeline.threads import torch_budget
from pipeline.world.pictures import CATEGORIES, N_FACES, N_PICTURES, picture_category


def _hue_turned_predictions(
    cfg: AccuracyConfig, overrides: list[str]
) -> dict[float, np.ndarray] | None:
    """The colour test's predictions (``pipeline.fewshot.colour``), per hue shift, for a recogniser
    that reads pictures (its target takes ``query_hue_shift``); None for the others, which refuse
    ``study.hue_shifts`` (before the study runs)."""
    shifts = list(cfg.study.hue_shifts)
    target, _ = recogniser_arguments(cfg.recogniser)
    if "query_hue_shift" not in inspect.signature(target).parameters:
        if shifts and any(o.lstrip("+~").startswith("study.hue_shifts") for o in overrides):
            refuse(
                "study.hue_shifts",
                f"the colour test turns query pictures, and "
                f"{cfg.recogniser['_target_']} reads none; use recogniser="
                + "|".join(recognisers_taking("query_hue_shift")),
            )
        return None
    base = float(cfg.recogniser.get("query_hue_shift", 0.0))
    shifted = {}
    for shift in shifts:
        rec = build_recogniser(
            {**cfg.recogniser, "query_hue_shift": base + shift},
            substitution_way=0,
            carry_over=False,
        )
        rec.start_run(0, cfg.study.seed)
        shifted[shift] = rec.predictions(0)
    return shifted


def _views_colour_test(cfg: AccuracyConfig, recogniser) -> dict | None:
    """The colour test on the ``views`` pictures (:mod:`pipeline.fewshot.views`): None for a
    recogniser that reads no pictures, with ``study.hue_shifts`` empty, or when ``images_dir`` has
    no views split (the report says so)."""
    target, _ = recogniser_arguments(cfg.recogniser)
    if "query_hue_shift" not in inspect.signature(target).parameters or not cfg.study.hue_shifts:
        return None
    if not has_views(cfg.recogniser["images_dir"]):
        return None
    categories, obstacles, original, turned = views_predictions(
        recogniser,
        cfg.recogniser["images_dir"],
        list(cfg.study.hue_shifts),
        float(cfg.recogniser.get("query_hue_shift", 0.0)),
    )
    return colour_test(original, turned, categories, obstacles)


def _family_study(cfg: AccuracyConfig, recogniser, overrides: list[str]):
    """The held-out families' episodes (``families.csv``) and accuracy with family-level intervals
    (:mod:`pipeline.fewshot.family_accuracy`); None with ``study.family_episodes`` 0 or for a
    recogniser without a trained network, which refuses the key when it is given (before the
    study runs)."""
    episodes = cfg.study.family_episodes
    if getattr(recogniser, "checkpoint", None) is None or not hasattr(recogniser, "network"):
        if episodes and any(o.lstrip("+~").startswith("study.family_episodes") for o in overrides):
            refuse(
                "study.family_episodes",
                f"it measures a meta-trained network on the held-out families, and "
                f"{cfg.recogniser['_target_']} has none; use recogniser=relation_net|protonet",
            )
        return None
    if not episodes:
        return None
    return family_study(
        recogniser.network,
        recogniser.checkpoint,
        cfg.recogniser["images_dir"],
        episodes,
        cfg.study.seed,
    )


def run(cfg: AccuracyConfig, overrides: list[str] = ()) -> dict:
    config = cfg.study
    torch_budget(cfg.threads).apply()
    start = time.perf_counter()
    recogniser = build_recogniser(cfg.recogniser, substitution_way=0, carry_over=False)
    turned = _hue_turned_predictions(cfg, list(overrides))
    families = _family_study(cfg, recogniser, list(overrides))
    names = list(CATEGORIES)
    categories = np.array([picture_category(p) for p in range(N_PICTURES)])
    result = run_study(recogniser, categories, config, progress=cfg.progress)
    out = Path(cfg.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    baseline_frame(result, names).to_csv(out / "baseline.csv", index=False)
    table1_frame(result, config.repeats).to_csv(out / "table1.csv", index=False)
    table2_frame(result).to_csv(out / "table2.csv", index=False)
    draws_frame(result, names).to_csv(out / "draws.csv", index=False)
    data = summary(result, names)
    obstacles = [p // N_FACES for p in range(N_PICTURES)]  # a picture id's (category, instance)
    data["colour_test"] = (
        None
        if turned is None
        else colour_test(result.baseline_predictions, turned, categories, obstacles)
    )
    data["colour_test_views"] = _views_colour_test(cfg, recogniser)
    data["families"] = None if families is None else families[1]
    if families is not None:
        write_atomic(out / "families.csv", families[0].to_csv(index=False))
    data["config"] = {"recogniser": dict(cfg.recogniser), **asdict(config)}
    if hasattr(recogniser, "checkpoint"):
        data["checkpoint_metrics"] = recogniser.checkpoint["metrics"]
    write_json_atomic(
        out / "summary.json", data, sort_keys=True
    )  # no wall-clock figures: the same inputs give the same bytes
    print(
        f"query accuracy, original support set: {result.baseline_correct.sum()}/{result.per_category_total.sum()} "
        f"({100 * result.baseline_accuracy:.1f}%; paper 42.5%); per category "
        + ", ".join(
            f"{n} {c}/{t}"
            for n, c, t in zip(names, result.baseline_correct, result.per_category_total)
        )
    )
    colour = data["colour_test"]
    if colour and colour["shifts_deg"]:
        n = colour["pictures"] * len(colour["shifts_deg"])
        print(
            f"colour test, hue-turned query pictures: {sum(colour['correct_per_shift'])}/{n} "
            f"({100 * sum(colour['correct_per_shift']) / n:.1f}%) against {colour['correct_original']}/{colour['pictures']}"
        )
    views = data["colour_test_views"]
    if views:
        n = views["pictures"] * len(views["shifts_deg"])
        print(
            f"views of the query obstacles: {views['correct_original']}/{views['pictures']} correct; "
            f"hue-turned {sum(views['correct_per_shift'])}/{n}"
        )
    for split, words in (("test", "test"), ("val", "validation")):
        found = (data["families"] or {}).get(split)
        if found:
            print(
                f"{words} families: {100 * found['accuracy']:.2f}% over {found['episodes']} episodes; "
                "95% interval over episodes [{:.2f}, {:.2f}], over {} families [{:.2f}, {:.2f}]".format(
                    *(100 * x for x in found["episode_ci"]),
                    found["families"],
                    *(100 * x for x in found["family_ci"]),
                )
            )
    for n, (w, ns) in sorted(result.table2.items()):
        print(f"  {n} substitution(s): {100 * w:.2f}%  (no same picture {100 * ns:.2f}%)")
    print(f"accuracy study in {time.perf_counter() - start:.1f} s")
    return data


def written(cfg: AccuracyConfig, data: dict) -> list[str]:
    return [cfg.out_dir]


def main() -> None:
    stage_main("accuracy", run)
