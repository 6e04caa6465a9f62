"""Render stage: determinism, counts, split disjointness, query faces, bad input, atomic writes."""

from __future__ import annotations

import colorsys
import csv
import hashlib
from pathlib import Path

import numpy as np
import pytest

from pipeline.config.compose import load_config
from pipeline.errors import ConfigError
from pipeline.files import write_atomic
from pipeline.manifest import COLUMNS, SPLITS
from pipeline.world.camera import side_azimuth
from pipeline.world.metaset import build_meta_instance, make_families
from pipeline.world.obstacle_models import build_obstacle, category_index, obstacle_instance
from pipeline.world.pictures import CATEGORIES, N_PICTURES, picture_id
from pipeline.world.render_plan import PlanConfig, make_plan
from pipeline.world.render_runner import Drawing, render_batch

SMALL = [
    "n_train_classes=3",
    "n_val_classes=2",
    "n_test_classes=2",
    "per_class=4",
    "views_per_obstacle=1",
    "views_per_instance=2",
    "size=32",
    "contact_sheets=true",
    "contact_train_classes=2",
    "contact_per_class=3",
]


def _cfg(tmp: Path, *extra: str):
    return load_config(
        "render", [*SMALL, f"out_dir={tmp / 'images'}", f"figures_dir={tmp / 'figures'}", *extra]
    )


def _run(tmp: Path, *extra: str) -> dict:
    from pipeline.stages.render import run

    return run(_cfg(tmp, *extra))


def _manifest(out: Path) -> list[dict]:
    with open(out / "manifest.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def _digest(out: Path) -> dict[str, str]:
    return {
        str(p.relative_to(out)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(out.rglob("*"))
        if p.is_file()
    }


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("render")
    figures = _run(tmp, "workers=2")
    return tmp, figures


def test_counts_columns_and_query_faces(rendered):
    tmp, figures = rendered
    out = tmp / "images"
    rows = _manifest(out)
    assert tuple(rows[0].keys()) == COLUMNS
    by = {s: [r for r in rows if r["split"] == s] for s in SPLITS}
    assert len(by["query"]) == N_PICTURES == 40
    assert len(by["support"]) == 5 * 5
    assert len(by["train"]) == 3 * 4 and len(by["val"]) == 2 * 4 and len(by["test"]) == 2 * 4
    assert len(by["views"]) == 10  # the ten query obstacles, one view each
    assert figures["pictures"] == len(rows) == 103
    for r in rows:  # every file exists and is a picture of the configured size
        from PIL import Image

        with Image.open(out / r["file"]) as im:
            assert im.size == (32, 32) and im.mode == "RGB"
    ids = sorted(int(r["picture_id"]) for r in by["query"])
    assert ids == list(range(40))
    for r in by["query"]:
        c, i, f = int(r["category"]), int(r["instance"]), int(r["face"])
        assert int(r["picture_id"]) == picture_id(c, i, f)
        assert r["class_name"] == CATEGORIES[c]
        assert float(r["orientation_deg"]) == 0.0  # two objects, neither turned
    assert {(int(r["category"]), int(r["instance"]), int(r["face"])) for r in by["query"]} == {
        (c, i, f) for c in range(5) for i in range(2) for f in range(4)
    }
    for s in ("support", "train", "val", "test", "views"):
        assert all(int(r["picture_id"]) == -1 and int(r["face"]) == -1 for r in by[s])
    assert {
        (int(r["category"]), int(r["instance"]), float(r["orientation_deg"])) for r in by["views"]
    } == {(c, i, 0.0) for c in range(5) for i in range(2)}
    for name in (
        "contact_query",
        "contact_support",
        "contact_train",
        "contact_val",
        "contact_test",
        "contact_views",
    ):
        assert (tmp / "figures" / f"{name}.png").is_file()
    assert not list(out.rglob("*.tmp"))


def test_splits_are_disjoint(rendered):
    rows = _manifest(rendered[0] / "images")
    q = {(r["category"], r["instance"]) for r in rows if r["split"] == "query"}
    s = {(r["category"], r["instance"]) for r in rows if r["split"] == "support"}
    assert q.isdisjoint(s) and {int(r["instance"]) for r in rows if r["split"] == "support"} == {
        2,
        3,
        4,
        5,
        6,
    }
    train = {r["class_name"] for r in rows if r["split"] == "train"}
    val = {r["class_name"] for r in rows if r["split"] == "val"}
    test = {r["class_name"] for r in rows if r["split"] == "test"}
    assert len(train) == 3 and len(val) == 2 and len(test) == 2
    assert train.isdisjoint(val) and train.isdisjoint(test) and val.isdisjoint(test)
    assert not (train | val | test) & set(CATEGORIES)
    files = [r["file"] for r in rows]
    assert len(set(files)) == len(files)


def test_same_config_same_bytes(rendered, tmp_path):
    """One process vs two workers, a second run: identical bytes for every picture and the manifest."""
    first = _digest(rendered[0] / "images")
    _run(tmp_path, "workers=1", "contact_sheets=false")
    assert _digest(tmp_path / "images") == first


def test_seed_changes_pictures(rendered, tmp_path):
    cfg = PlanConfig(
        seed=1,
        n_train_classes=1,
        n_val_classes=0,
        per_class=1,
        views_per_instance=1,
        n_test_classes=0,
        views_per_obstacle=0,
    )
    batches, _ = make_plan(cfg)
    render_batch(batches[0], str(tmp_path), Drawing(32))
    f = batches[0].files[0]
    assert (tmp_path / f).read_bytes() != (rendered[0] / "images" / f).read_bytes()


def test_families_distinct_and_seeded():
    a = make_families(80, seed=0)
    assert len({x.signature() for x in a}) == 80
    assert len({x.name for x in a}) == 80
    assert [x.name for x in a] == [x.name for x in make_families(80, seed=0)]
    assert [x.name for x in a] != [x.name for x in make_families(80, seed=1)]


def test_family_instances_vary_in_colour_parts_and_proportions():
    """A class is a category: its instances differ in colours, finishes, part kinds and counts and
    proportions, so that colour alone does not name the class."""
    families = make_families(80, seed=0)
    for fam in families:
        insts = [build_meta_instance(fam, np.random.default_rng(k)) for k in range(12)]
        assert all(o.name == fam.name for o in insts)
        assert len({o.palette for o in insts}) == 12
        assert len({round(o.extent()[0], 4) for o in insts}) >= 10
        if len(fam.leg_counts) > 1 or len(fam.arm_counts) > 1 or any(t.optional for t in fam.tiers):
            assert len({len(o.parts) for o in insts}) > 1, fam.name
        if any(len(t.kinds) > 1 for t in fam.tiers):
            assert (
                len(
                    {tuple(p.kind for p in o.parts) for o in insts}
                    | {tuple(p.mesh is None for p in o.parts) for o in insts}
                )
                > 1
            ), fam.name
    hues = [
        colorsys.rgb_to_hsv(*build_meta_instance(families[0], np.random.default_rng(k)).palette[0])[
            0
        ]
        for k in range(200)
    ]
    assert np.histogram(hues, bins=6, range=(0, 1))[0].min() >= 15  # any hue, about evenly


def _turn_invariant_shape(obj) -> list:
    """What turning an object about its vertical axis leaves alone: each part's kind, its size
    in its own frame, its height, and a mesh's vertex count and radius."""
    return sorted(
        (
            p.kind,
            tuple(round(float(x), 4) for x in p.size),
            round(float(p.pos[2]), 4),
            0 if p.mesh is None else len(p.mesh.vertices),
            0.0 if p.mesh is None else round(p.mesh.radius(), 4),
        )
        for p in obj.parts
    )


def test_the_two_obstacles_of_a_category_are_two_objects_not_one_turned():
    """Two distinct objects per category (another chair, not the same chair turned).
    A turn about the vertical axis keeps every part's size and height; the two instances differ
    in them, and each is its category's own build, the same on every call."""
    for c in CATEGORIES:
        first, second = (obstacle_instance(c, i, seed=0) for i in (0, 1))
        assert first.name == second.name == c
        assert _turn_invariant_shape(first) != _turn_invariant_shape(second), c
        assert first.palette != second.palette, c
        again = obstacle_instance(c, 1, seed=0)
        assert _turn_invariant_shape(again) == _turn_invariant_shape(second)


def test_query_pictures_show_each_category_as_two_objects():
    """The query batch builds the ten obstacles from ``obstacle_instance`` (instances 0 and 1),
    photographs them unturned, and its pictures of instance 1 show the second object."""
    from pipeline.world.render_plan import query_batch

    batch, rows = query_batch(PlanConfig())
    assert len(batch.objects) == 10
    for k, obj in enumerate(batch.objects):
        category, instance = divmod(k, 2)
        want = obstacle_instance(category, instance, seed=0)
        assert _turn_invariant_shape(obj) == _turn_invariant_shape(want)
    assert {shot.yaw_deg for shot in batch.shots} == {0.0}


def test_obstacle_instances_vary():
    for c in CATEGORIES:
        objs = [build_obstacle(c, np.random.default_rng(k)) for k in range(4)]
        assert all(o.name == c for o in objs)
        sizes = {round(o.extent()[0], 4) for o in objs}
        assert len(sizes) > 1, f"{c}: instances do not vary"


def test_side_azimuth_looks_at_origin():
    # camera on the north side looks south (-y), east looks west, and so on
    assert [side_azimuth(s) for s in range(4)] == [270.0, 180.0, 90.0, 0.0]


# ----------------------------------------------------------------------------- bad input


def test_unknown_category_is_a_clear_error(tmp_path):
    with pytest.raises(ValueError, match="unknown category 'sofa'.*chair, kettle"):
        category_index("sofa")
    with pytest.raises(ValueError, match="unknown category id 7"):
        category_index(7)
    with pytest.raises(ValueError, match="config key 'categories'.*sofa"):
        _run(tmp_path, "categories=[chair,sofa]")


def test_negative_size_is_a_clear_error(tmp_path):
    with pytest.raises(ConfigError, match="config key 'size': must be >= 8; got -5"):
        _run(tmp_path, "size=-5")


def test_missing_parent_is_a_clear_error(tmp_path):
    from pipeline.stages.render import run

    cfg = load_config(
        "render",
        [*SMALL, f"out_dir={tmp_path / 'nope' / 'images'}", f"figures_dir={tmp_path / 'figures'}"],
    )
    with pytest.raises(ConfigError, match="config key 'out_dir'.*does not exist"):
        run(cfg)
    assert not (tmp_path / "nope").exists()


def test_interrupted_write_leaves_no_half_picture(tmp_path, monkeypatch):
    """A crash while writing leaves neither a partial file under the final name nor a manifest."""
    import os

    target = tmp_path / "query" / "x.png"
    real_replace = os.replace

    def boom(src, dst):
        raise KeyboardInterrupt

    monkeypatch.setattr(os, "replace", boom)
    with pytest.raises(KeyboardInterrupt):
        write_atomic(target, b"\x89PNG partial")
    monkeypatch.setattr(os, "replace", real_replace)
    assert not target.exists()
    assert list(target.parent.iterdir()) == []  # the temporary file is removed too


def test_interrupted_stage_keeps_the_previous_pictures_and_removes_its_staging(
    tmp_path, monkeypatch
):
    """A render killed mid-way leaves the previous pictures and their manifest as they were (it
    renders into a staging folder), and removes its staging folder."""
    import pipeline.stages.render as stage

    (tmp_path / "images" / "query").mkdir(parents=True)
    (tmp_path / "images" / "manifest.csv").write_text("previous\n")
    (tmp_path / "images" / "query" / "p.png").write_bytes(b"previous")

    def killed(batches, out_dir, *a, **k):
        (Path(out_dir) / "query").mkdir(parents=True)
        (Path(out_dir) / "query" / "p.png").write_bytes(b"half")
        raise KeyboardInterrupt

    monkeypatch.setattr(stage, "render_all", killed)
    with pytest.raises(KeyboardInterrupt):
        stage.run(_cfg(tmp_path))
    assert (tmp_path / "images" / "manifest.csv").read_text() == "previous\n"
    assert (tmp_path / "images" / "query" / "p.png").read_bytes() == b"previous"
    assert sorted(p.name for p in (tmp_path / "images").iterdir()) == ["manifest.csv", "query"]


def test_a_mujoco_warning_is_a_python_warning_and_leaves_no_log_file(tmp_path, monkeypatch):
    """Issue 44: MuJoCo writes its warnings to MUJOCO_LOG.TXT in the working folder unless a
    handler takes them; pipeline.world.renderer_env installs one."""
    import numpy as np

    from pipeline.world.renderer_env import mujoco

    monkeypatch.chdir(tmp_path)
    model = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><body><freejoint/><geom size="0.1"/></body></worldbody></mujoco>'
    )
    data = mujoco.MjData(model)
    data.qvel[:] = np.nan
    with pytest.warns(RuntimeWarning, match="MuJoCo: Nan, Inf or huge value in QVEL"):
        mujoco.mj_step(model, data)
    assert list(tmp_path.iterdir()) == []
