"""The meta_train and accuracy stages end to end on a tiny synthetic dataset (Hydra-composed real
configs, shrunk), and their config errors."""

import json

import numpy as np
import pandas as pd
import pytest

from pipeline.config.compose import load_config
from pipeline.errors import ConfigError
from pipeline.fewshot.synthetic import write_synthetic_dataset
from pipeline.stages import meta_train, run_stage

SHRINK = [
    "train.input_size=24",
    "train.relation_padding=1",
    "train.n_query=3",
    "train.episodes=8",
    "train.val_every=4",
    "train.val_episodes=10",
    "train.eval_episodes=20",
    "train.eval_queries=5",
    "progress=false",
]


def test_defaults_point_at_the_shared_dataset():
    cfg = load_config("meta_train")
    assert (
        cfg.images_dir == "datasets/images" and cfg.checkpoint == "datasets/models/relation_net.pt"
    )
    assert load_config("accuracy").study.repeats == 100


def test_meta_train_then_accuracy(tmp_path):
    images = tmp_path / "images"
    write_synthetic_dataset(images, n_train=6, n_val=5, per_class=10, seed=2)
    paths = [
        f"images_dir={images}",
        f"checkpoint={tmp_path}/m/rn.pt",
        f"metrics_file={tmp_path}/m/metrics.json",
        f"history_file={tmp_path}/m/h.csv",
    ]
    metrics = run_stage("meta_train", paths + SHRINK)
    on_disk = json.loads((tmp_path / "m" / "metrics.json").read_text())
    # metrics.json: the quoted test figure only (one DVC column each); the rest beside the checkpoint
    assert on_disk == meta_train.quoted_metrics(metrics) and set(on_disk) == {
        "accuracy",
        "ci_lower",
        "ci_upper",
    }
    assert on_disk["ci_lower"] < on_disk["accuracy"] < on_disk["ci_upper"]
    scores = json.loads((tmp_path / "m" / "rn.validation.json").read_text())
    assert set(scores) == set(meta_train.SCORE_KEYS) and scores["val_episodes"] == 20
    assert scores["val_accuracy"] == pytest.approx(metrics["val_accuracy"])
    assert scores["test_accuracy"] == pytest.approx(on_disk["accuracy"])
    info = json.loads((tmp_path / "m" / "rn.train_info.json").read_text())
    assert not set(info) & set(meta_train.SCORE_KEYS) and {
        "train_seconds",
        "torch_threads",
        "images_dir",
    } <= set(info)
    assert len(pd.read_csv(tmp_path / "m" / "h.csv")) == 2

    out = tmp_path / "acc"
    data = run_stage(
        "accuracy",
        [
            f"recogniser.images_dir={images}",
            f"recogniser.checkpoint={tmp_path}/m/rn.pt",
            "recogniser.input_size=24",
            "recogniser.relation_padding=1",
            f"out_dir={out}",
            "study.repeats=4",
            "progress=false",
        ],
    )
    t1 = pd.read_csv(out / "table1.csv")
    assert len(t1) == 50
    with_same = t1[t1.variant == "with_same"]
    assert (with_same.total == 32).all()  # 4 repeats x 8 pictures ("x/800" at 100 repeats)
    no_same = t1[t1.variant == "no_same"]
    assert (
        no_same.total
        == [
            28 if s == t else 32
            for s, t in zip(no_same.substituted_category, no_same.tested_category)
        ]
    ).all()
    t2 = pd.read_csv(out / "table2.csv")
    assert t2.substitution_number.tolist() == [0, 1, 2, 3, 4, 5]
    # Table 2 at n = 1 is Table 1's experiment
    assert t2.mean_accuracy[1] == pytest.approx(with_same.correct.sum() / with_same.total.sum())
    assert t2.mean_accuracy_no_same[1] == pytest.approx(no_same.correct.sum() / no_same.total.sum())
    # every draw kept: its rows add up to Tables 1 and 2
    draws = pd.read_csv(out / "draws.csv")
    assert len(draws) == 5 * 5 * 4 * 5  # substitution numbers x categories x repeats x tested
    one = draws[draws.substitutions == 1].groupby(["substituted_category", "tested_category"]).sum()
    assert one.correct.tolist() == with_same.correct.tolist()
    assert one.correct_no_same.tolist() == no_same.correct.tolist()
    assert one.tested_no_same.tolist() == no_same.total.tolist()
    per_n = draws.groupby("substitutions")[
        ["correct", "tested", "correct_no_same", "tested_no_same"]
    ].sum()
    assert (per_n.correct / per_n.tested).tolist() == pytest.approx(t2.mean_accuracy[1:].tolist())
    assert (per_n.correct_no_same / per_n.tested_no_same).tolist() == pytest.approx(
        t2.mean_accuracy_no_same[1:].tolist()
    )
    assert (draws.pictures.str.split().map(len) == draws.substitutions).all()
    base = pd.read_csv(out / "baseline.csv")
    assert len(base) == 40 and data["baseline"]["accuracy"] == pytest.approx(base.correct.mean())
    assert t2.mean_accuracy[0] == pytest.approx(base.correct.mean())
    colour = json.loads((out / "summary.json").read_text())["colour_test"]  # the default hue shifts
    assert colour["shifts_deg"] == [60.0, 120.0, 180.0, 240.0, 300.0] and colour["pictures"] == 40
    assert (
        colour["correct_original"] == base.correct.sum()
        and colour["predictions_original"] == base.predicted.tolist()
    )
    assert [
        sum(np.equal(p, colour["categories"])) for p in colour["predictions_per_shift"]
    ] == colour["correct_per_shift"]
    one = run_stage(
        "accuracy",
        [
            f"recogniser.images_dir={images}",
            f"recogniser.checkpoint={tmp_path}/m/rn.pt",
            "recogniser.input_size=24",
            "recogniser.relation_padding=1",
            f"out_dir={tmp_path}/acc1",
            "study.repeats=1",
            "study.hue_shifts=[180]",
            "progress=false",
        ],
    )
    assert one["colour_test"]["shifts_deg"] == [180.0]
    assert one["colour_test"]["predictions_per_shift"] == [colour["predictions_per_shift"][2]]
    assert one["config"]["hue_shifts"] == [180.0]
    # each query picture's obstacle: its category's instance (picture id // 4)
    assert colour["obstacles"] == [p // 4 for p in range(40)]
    # the held-out families: study.family_episodes fresh episodes of each split (default 300),
    # every episode's families kept (5 rows an episode), the shape the checkpoint was measured with
    families = pd.read_csv(out / "families.csv")
    assert len(families) == 2 * 300 * 5 and (families.tested == 5).all()
    assert data["families"]["episode_shape"] == {"n_way": 5, "k_shot": 5, "eval_queries": 5}
    for split, n in (("val", 5), ("test", 5)):
        found, rows = data["families"][split], families[families.split == split]
        assert found["families"] == n and found["episodes"] == 300
        assert found["accuracy"] == pytest.approx(rows.correct.sum() / rows.tested.sum())
        assert found["family_ci"][0] <= found["accuracy"] <= found["family_ci"][1]
        assert len(found["family_names"]) == n
    assert one["families"]["episodes_per_split"] == 300
    few = run_stage(
        "accuracy",
        [
            f"recogniser.images_dir={images}",
            f"recogniser.checkpoint={tmp_path}/m/rn.pt",
            "recogniser.input_size=24",
            "recogniser.relation_padding=1",
            f"out_dir={tmp_path}/acc2",
            "study.repeats=1",
            "study.hue_shifts=[]",
            "study.family_episodes=7",
            "progress=false",
        ],
    )
    assert few["families"]["test"]["episodes"] == 7 and few["config"]["family_episodes"] == 7
    assert len(pd.read_csv(tmp_path / "acc2" / "families.csv")) == 2 * 7 * 5
    none = run_stage(
        "accuracy",
        [
            f"recogniser.images_dir={images}",
            f"recogniser.checkpoint={tmp_path}/m/rn.pt",
            "recogniser.input_size=24",
            "recogniser.relation_padding=1",
            f"out_dir={tmp_path}/acc3",
            "study.repeats=1",
            "study.family_episodes=0",
            "progress=false",
        ],
    )
    assert none["families"] is None and not (tmp_path / "acc3" / "families.csv").exists()


def test_config_errors_name_the_key(tmp_path):
    with pytest.raises(ConfigError, match=r"train\.bogus"):
        run_stage("meta_train", ["+train.bogus=1"])
    with pytest.raises(
        ConfigError, match=r"config key 'train\.episodes'.*could not be converted to Integer"
    ):
        run_stage("meta_train", ["train.episodes=many"])
    with pytest.raises(ConfigError, match=r"extra"):
        run_stage("accuracy", ["+extra=1"])
    with pytest.raises(ConfigError, match=r"config key 'study.repeats': must be >= 1; got 0"):
        run_stage("accuracy", ["study.repeats=0"])
    with pytest.raises(
        ConfigError, match=r"config key 'study.hue_shifts': the colour test turns query pictures"
    ):
        run_stage(
            "accuracy", ["recogniser=oracle", "study.hue_shifts=[90]", f"out_dir={tmp_path}/o"]
        )
    with pytest.raises(
        ConfigError, match=r"config key 'study.family_episodes': it measures a meta-trained network"
    ):
        run_stage(
            "accuracy",
            ["recogniser=oracle", "study.family_episodes=5", f"out_dir={tmp_path}/o"],
        )
    with pytest.raises(ConfigError, match=r"config key 'study.family_episodes': must be >= 0"):
        run_stage("accuracy", ["study.family_episodes=-1"])
    with pytest.raises(
        ConfigError, match=r"config key 'study.hue_shifts.0'.*could not be converted to Float"
    ):
        run_stage("accuracy", ["study.hue_shifts=[red]"])
    with pytest.raises(
        ConfigError, match=r"config key 'recogniser.query_hue_shift': must be a finite number"
    ):
        run_stage("accuracy", ["recogniser.query_hue_shift=nan", f"out_dir={tmp_path}/o"])
    with pytest.raises(
        ConfigError, match=r"config key 'train.lr_schedule': must be one of constant, cosine, step"
    ):
        run_stage("meta_train", ["train.lr_schedule=linear"])


def test_protonet_meta_train_accuracy_and_report_tables(tmp_path):
    """model=protonet trains a Prototypical Network into its own files; the accuracy study runs it
    with recogniser=protonet; the report's Tables 1-2 show it beside the Relation Network."""
    from pipeline.report.accuracy import accuracy_tables
    from pipeline.report.build import Report

    images = tmp_path / "images"
    write_synthetic_dataset(images, n_train=6, n_val=5, per_class=10, views_per_category=4, seed=2)
    shrink = [s for s in SHRINK if not s.startswith("train.relation_padding")]
    assert load_config("meta_train", ["model=protonet"]).checkpoint == "datasets/models/protonet.pt"
    with pytest.raises(
        ConfigError, match=r"config key 'train.relation_padding': the Prototypical Network has no"
    ):
        run_stage(
            "meta_train",
            ["model=protonet", "train.relation_padding=0", f"images_dir={images}"] + shrink,
        )
    with pytest.raises(ConfigError, match=r"config key 'train.relation_padding'"):
        run_stage(
            "meta_train",
            ["model=protonet", "train.relation_padding=1", f"images_dir={images}"] + shrink,
        )
    dirs = {}
    for model, extra in (("relation_net", ["train.relation_padding=1"]), ("protonet", [])):
        m = tmp_path / model
        run_stage(
            "meta_train",
            [
                f"model={model}",
                f"images_dir={images}",
                f"checkpoint={m}/net.pt",
                f"metrics_file={m}/metrics.json",
                f"history_file={m}/h.csv",
            ]
            + shrink
            + extra,
        )
        assert json.loads((m / "net.train_info.json").read_text())["model"] == model
        args = [
            f"recogniser={model}",
            f"recogniser.images_dir={images}",
            f"recogniser.checkpoint={m}/net.pt",
            "recogniser.input_size=24",
            f"out_dir={m}/acc",
            "study.repeats=2",
            "progress=false",
        ]
        data = run_stage(
            "accuracy",
            args + (["recogniser.relation_padding=1"] if model == "relation_net" else []),
        )
        scores = pd.read_csv(m / "acc" / "baseline.csv").filter(like="score")
        assert data["config"]["recogniser"]["_target_"].endswith(
            ("RelationRecogniser.from_files", "ProtoRecogniser.from_files")
        )
        assert ((scores >= 0) & (scores <= 1)).all().all()
        dirs[model] = m
    with pytest.raises(
        ConfigError,
        match=r"holds a Relation Network \(train.model=relation_net\), not a Prototypical",
    ):
        run_stage(
            "accuracy",
            [
                "recogniser=protonet",
                f"recogniser.images_dir={images}",
                f"recogniser.checkpoint={dirs['relation_net']}/net.pt",
                "progress=false",
            ],
        )
    rep = Report(tmp_path / "report")
    accuracy_tables(
        rep,
        dirs["relation_net"] / "acc",
        dirs["relation_net"] / "metrics.json",
        {"Prototypical Network": (dirs["protonet"] / "acc", dirs["protonet"] / "metrics.json")},
    )
    text = "\n".join(rep.sections)
    assert "## The recogniser" in text
    table = pd.read_csv(tmp_path / "report" / "tables" / "recogniser.csv")
    assert table.recogniser.tolist() == ["Relation Network", "Prototypical Network"]
    # the quoted figure is the test families' (metrics.json), validation beside it (the checkpoint's)
    assert (
        table["test [95%]"]
        .str.match(r"\d+\.\d\d% \[[\d.]+, [\d.]+\] \(20 episodes, 5 families\)")
        .all()
    )
    assert (
        table["validation [95%]"]
        .str.match(r"\d+\.\d\d% \[[\d.]+, [\d.]+\] \(20 episodes, 5 families\)")
        .all()
    )
    assert table["query pictures [95%]"].str.match(r"\d+/40 = ").all()
    assert table["views of the query obstacles [95%]"].str.match(r"\d+/20 = ").all()
    colour = pd.read_csv(tmp_path / "report" / "tables" / "colour_test.csv")
    assert (
        colour.pictures.tolist()
        == [
            "the 40 query pictures (40)",
            "views of the query obstacles (20)",
        ]
        * 2
    )
    assert colour["hue-turned [95%]"].str.match(r"\d+/(200|100) = ").all()
    assert colour["drop, points [95%]"].str.contains(r"\[").all()
    # the held-out families with both intervals, and the colour test per hue shift (obstacles)
    families = pd.read_csv(tmp_path / "report" / "tables" / "recogniser_families.csv")
    assert families.recogniser.tolist() == ["Relation Network"] * 2 + ["Prototypical Network"] * 2
    assert families.families.tolist() == ["test (5)", "validation (5)"] * 2
    assert families["family-level [95%]"].str.match(r"\[[\d.]+, [\d.]+\]").all()
    shifts = pd.read_csv(tmp_path / "report" / "tables" / "colour_test_shifts.csv")
    assert len(shifts) == 2 * 2 * 5  # recognisers x picture sets x hue shifts
    assert shifts.pictures.str.endswith(("(40, 10 obstacles)", "(20, 10 obstacles)")).all()
    assert shifts["change, points [95%, obstacles]"].str.match(r"[+-]\d+\.\d\d \[").all()
    assert "ours, Prototypical Network" in text
    t2 = pd.read_csv(tmp_path / "report" / "tables" / "table2.csv")
    assert (
        "Prototypical Network [95% CI]" in t2.columns
        and t2["Prototypical Network [95% CI]"].str.contains("%").all()
    )
    t1 = pd.read_csv(tmp_path / "report" / "tables" / "table1_with_same.csv")
    assert "overall, Prototypical Network [95% CI]" in t1.columns
