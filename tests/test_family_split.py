"""The meta-training families' train / validation / test split (pipeline/world/family_split.py):
the structural distance sees through reordered stacks, and no held-out family is a near-twin of a
training family (issue 29: 13 of 16 validation families had one)."""

from __future__ import annotations

from dataclasses import replace

import pytest

from pipeline.world.family_split import (
    MIN_DISTANCE,
    family_distance,
    nearest_distance,
    split_families,
    tiers_distance,
)
from pipeline.world.metaset import make_families
from pipeline.world.render_plan import PlanConfig, make_plan
from pipeline.world.sheet_labels import family_words

PAPER = {"n_train": 64, "n_val": 16, "n_test": 20, "seed": 0}


def test_a_reversed_stack_is_a_twin_and_each_part_counts():
    fam = next(f for f in make_families(40, seed=0) if len(f.tiers) >= 3)
    reversed_twin = replace(fam, tiers=fam.tiers[::-1], name="twin")
    assert family_distance(fam, reversed_twin) == 0.0 == family_distance(fam, fam)
    with_handle = replace(reversed_twin, handle=not fam.handle)
    assert family_distance(fam, with_handle) == 1.0 == family_distance(with_handle, fam)
    other_legs = replace(with_handle, leg_style="ring" if fam.leg_style != "ring" else "none")
    assert family_distance(fam, other_legs) == 2.0
    assert tiers_distance([("box",)], [("box", "cylinder")]) == 0.5  # Jaccard of the kinds
    assert tiers_distance([("box",)], [("box",), ("torus",)]) == 1.0  # an extra tier
    assert tiers_distance([("box",), ("cone",)], [("cone",), ("box",)]) == 0.0  # any order


def test_the_old_split_had_near_twins_the_new_one_has_none():
    old = make_families(80, seed=0)
    assert sum(nearest_distance(f, old[:64]) < MIN_DISTANCE for f in old[64:]) >= 10
    split = split_families(**PAPER)
    assert [len(split[k]) for k in ("train", "val", "test")] == [64, 16, 20]
    assert [f.name for f in split["train"]] == [f.name for f in old[:64]]  # training unchanged
    for fam in split["val"] + split["test"]:
        assert nearest_distance(fam, split["train"]) >= MIN_DISTANCE, fam.name
    for fam in split["test"]:
        assert nearest_distance(fam, split["val"]) >= MIN_DISTANCE, fam.name
    names = [f.name for k in ("train", "val", "test") for f in split[k]]
    assert len(set(names)) == len(names)
    assert [f.name for f in split_families(**PAPER)["test"]] == [f.name for f in split["test"]]


def test_test_families_are_apart_from_validation_ones_and_validation_is_unchanged():
    """Issue 42: 6 of the 20 test families drawn after the validation ones (kept apart from
    training only) were within the distance of a validation family; now none is, the validation
    families (which chose the checkpoint) are the same ones, and the test keeps 14 of its 20."""
    split = split_families(**PAPER)
    stream = iter(make_families(400, seed=0))
    train = [next(stream) for _ in range(64)]
    held = [f for f in stream if nearest_distance(f, train) >= MIN_DISTANCE][:36]
    old_val, old_test = held[:16], held[16:]
    assert sum(nearest_distance(f, old_val) < MIN_DISTANCE for f in old_test) == 6
    assert [f.name for f in split["val"]] == [f.name for f in old_val]
    assert len({f.name for f in split["test"]} & {f.name for f in old_test}) == 14


def test_the_render_plan_keeps_its_held_out_families_apart():
    """make_plan applies min_family_distance: every val and test class of the manifest is at least
    that far from every training class, and a larger distance gives other held-out classes."""
    names = {}
    for distance in (0.0, 2.5):
        cfg = PlanConfig(
            n_train_classes=10,
            n_val_classes=3,
            n_test_classes=3,
            per_class=1,
            views_per_instance=1,
            views_per_obstacle=0,
            min_family_distance=distance,
        )
        _, rows = make_plan(cfg)
        split = split_families(10, 3, 3, cfg.seed, distance)
        by_name = {f.name: f for fams in split.values() for f in fams}
        held = {r["class_name"] for r in rows if r["split"] in ("val", "test")}
        train = [
            by_name[n]
            for n in dict.fromkeys(r["class_name"] for r in rows if r["split"] == "train")
        ]
        assert len(held) == 6 and all(nearest_distance(by_name[n], train) >= distance for n in held)
        names[distance] = held
    assert names[0.0] != names[2.5]


def test_an_impossible_distance_is_refused_in_one_line():
    with pytest.raises(ValueError, match=r"lower min_family_distance"):
        split_families(64, 16, 20, 0, min_distance=50.0)
    with pytest.raises(ValueError, match="min_distance must be >= 0"):
        split_families(1, 1, 1, 0, min_distance=-1.0)


def test_family_names_read_as_words():
    assert family_words("f065_cylinder-cylinder?-bowl+handle") == (
        "family 65, bottom to top: cylinder; cylinder (some instances); bowl; with a handle"
    )
    assert family_words("f004_disc-box|disc?+legs+arms+handle").endswith(
        "box or disc (some instances); with legs, radial arms and a handle"
    )
    assert family_words("chair") == "chair"  # not a family name: as it is


def test_the_render_stage_passes_its_split_keys_on_and_refuses_bad_view_distances():
    from pipeline.config.compose import load_config
    from pipeline.errors import ConfigError
    from pipeline.stages.render import plan_config

    cfg = load_config(
        "render", ["min_family_distance=3.0", "n_test_classes=7", "views_distance=[1.0,1.5]"]
    )
    plan = plan_config(cfg)
    assert (plan.min_family_distance, plan.n_test_classes, plan.views_distance) == (
        3.0,
        7,
        (1.0, 1.5),
    )
    assert load_config("render").n_test_classes == 20  # the paper profile: Ravi and Larochelle's 20
    with pytest.raises(ConfigError, match=r"config key 'views_distance'"):
        plan_config(load_config("render", ["views_distance=[1.5,1.0]"]))


def test_contact_sheet_rows_say_what_they_show(tmp_path):
    from pipeline.world.render_plan import query_batch
    from pipeline.world.sheet_labels import query_rows, views_rows

    _, rows = query_batch(PlanConfig())
    labels = [label for label, files in query_rows(rows, tmp_path)]
    assert labels[:2] == [
        "chair object 1: seen from north, east, south, west",
        "chair object 2: seen from north, east, south, west",
    ]
    assert len(labels) == 10 and all(len(f) == 4 for _, f in query_rows(rows, tmp_path))
    assert views_rows(rows, tmp_path, 8) == []  # no views rows: no sheet
