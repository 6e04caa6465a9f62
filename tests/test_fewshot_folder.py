"""Meta-training on a folder-per-class tree (``data=folder``): the loader, the stage at smoke
scale, and every key the source does not read refused (issue: bring your own meta-training set)."""

import json

import numpy as np
import pytest
from PIL import Image

from pipeline.errors import ConfigError
from pipeline.fewshot.data import DataError, load_folder
from pipeline.fewshot.episodes import require_episodes
from pipeline.stages import run_stage

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


def make_tree(root, classes, per_class=10, seed=0):
    """``root/<class>/<picture>``: one colour per class plus noise, PNG and JPEG, non-square sizes."""
    rng = np.random.default_rng(seed)
    for name in classes:
        folder = root / name
        folder.mkdir(parents=True)
        colour = rng.integers(0, 256, 3)
        for i in range(per_class):
            pixels = np.clip(colour + rng.normal(0, 25, (30 + i, 40, 3)), 0, 255).astype(np.uint8)
            Image.fromarray(pixels).save(folder / f"p{i:02d}.{'jpg' if i % 2 else 'png'}")
    return root


def outputs(folder):
    """Every file the stage writes, inside ``folder`` (never the committed model's)."""
    return [
        f"checkpoint={folder}/rn.pt",
        f"metrics_file={folder}/metrics.json",
        f"history_file={folder}/h.csv",
    ]


@pytest.fixture
def trees(tmp_path):
    train = make_tree(tmp_path / "train", [f"t{c}" for c in range(6)])
    val = make_tree(tmp_path / "val", [f"v{c}" for c in range(5)], seed=1)
    test = make_tree(tmp_path / "test", [f"x{c}" for c in range(5)], seed=2)
    return train, val, test


def test_load_folder_reads_classes_in_name_order_resized(tmp_path):
    root = make_tree(tmp_path / "tree", ["b_cat", "a_dog"], per_class=3)
    (root / "a_dog" / "notes.txt").write_text("not a picture")
    (root / ".cache").mkdir()
    (root / "README").write_text("a file at the top is not a class")
    pics = load_folder(root, 16)
    assert pics.class_names == ("a_dog", "b_cat")
    assert pics.files == (
        "a_dog/p00.png",
        "a_dog/p01.jpg",
        "a_dog/p02.png",
        "b_cat/p00.png",
        "b_cat/p01.jpg",
        "b_cat/p02.png",
    )
    assert pics.labels.tolist() == [0, 0, 0, 1, 1, 1] and (pics.picture_ids == -1).all()
    assert pics.images.shape == (6, 16, 16, 3) and pics.images.dtype == np.uint8
    again = load_folder(root, 16)
    assert np.array_equal(pics.images, again.images)


def test_load_folder_names_what_is_wrong(tmp_path):
    with pytest.raises(DataError, match="no such folder"):
        load_folder(tmp_path / "missing", 16)
    (tmp_path / "flat").mkdir()
    (tmp_path / "flat" / "x.png").write_bytes(b"")
    with pytest.raises(DataError, match="no class folders"):
        load_folder(tmp_path / "flat", 16)
    root = make_tree(tmp_path / "tree", ["a"], per_class=2)
    (root / "empty").mkdir()
    with pytest.raises(DataError, match=r"empty: class folder without pictures"):
        load_folder(root, 16)
    (root / "empty" / "broken.png").write_bytes(b"\x89PNG not really")
    with pytest.raises(DataError, match=r"cannot read picture .*broken\.png"):
        load_folder(root, 16)


def test_require_episodes_refuses_small_splits(tmp_path):
    pics = load_folder(make_tree(tmp_path / "t", ["a", "b", "c"], per_class=4), 8)
    with pytest.raises(DataError, match="3 classes; 5-way episodes need at least 5"):
        require_episodes(pics.by_class(), pics.class_names, 5, 4, "here")
    with pytest.raises(
        DataError, match=r"needs 5 pictures .* too few in a \(4\), b \(4\), c \(4\)"
    ):
        require_episodes(pics.by_class(), pics.class_names, 3, 5, "here")
    require_episodes(pics.by_class(), pics.class_names, 3, 4, "here")


def test_meta_train_on_folders(tmp_path, trees):
    train, val, test = trees
    out = tmp_path / "m"
    args = [
        "data=folder",
        f"data.train_dir={train}",
        f"data.val_dir={val}",
        f"data.test_dir={test}",
        *outputs(out),
        *SHRINK,
    ]
    metrics = run_stage("meta_train", args)
    info = json.loads((out / "rn.train_info.json").read_text())
    assert info["train_dir"] == str(train) and info["val_dir"] == str(val)
    assert info["test_dir"] == str(test) and "images_dir" not in info
    scores = json.loads((out / "rn.validation.json").read_text())
    assert (scores["n_train_classes"], scores["n_val_classes"], scores["n_test_classes"]) == (
        6,
        5,
        5,
    )
    assert 0.0 <= metrics["test_accuracy"] <= 1.0 and (out / "rn.pt").is_file()
    quoted = json.loads((out / "metrics.json").read_text())
    assert quoted == {
        "accuracy": pytest.approx(metrics["test_accuracy"]),
        "ci_lower": pytest.approx(metrics["test_accuracy"] - metrics["test_ci95"]),
        "ci_upper": pytest.approx(metrics["test_accuracy"] + metrics["test_ci95"]),
    }
    first = (out / "metrics.json").read_bytes()
    run_stage("meta_train", args)  # the same trees and seed: the same model selection and figures
    assert (out / "metrics.json").read_bytes() == first


@pytest.mark.parametrize(
    "extra, match",
    [
        (
            ["data=folder", "data.train_dir={train}", "data.test_dir={test}"],
            r"config key 'data\.val_dir': data=folder needs it",
        ),
        (  # a tree without test classes: refused, naming the key (docs/fewshot.md)
            ["data=folder", "data.train_dir={train}", "data.val_dir={val}"],
            r"config key 'data\.test_dir': data=folder needs it .*quoted accuracy",
        ),
        (
            [
                "data=folder",
                "data.train_dir={train}",
                "data.val_dir={train}",
                "data.test_dir={test}",
            ],
            r"config key 'data\.val_dir': it is data\.train_dir",
        ),
        (
            ["data=folder", "data.train_dir={train}", "data.val_dir={val}", "data.test_dir={val}"],
            r"config key 'data\.test_dir': it is data\.val_dir",
        ),
        (
            [
                "data=folder",
                "data.train_dir={train}",
                "data.val_dir={val}",
                "data.test_dir={test}",
                "images_dir={val}",
            ],
            r"config key 'images_dir': data=folder reads",
        ),
        (
            [
                "data=folder",
                "data.train_dir={train}",
                "data.val_dir={val}/missing",
                "data.test_dir={test}",
            ],
            r"config key 'data\.val_dir': .*missing is not a folder",
        ),
        (["data.train_dir={train}"], r"config key 'data\.train_dir': read only with data=folder"),
        (["data.test_dir={test}"], r"config key 'data\.test_dir': read only with data=folder"),
        (
            [
                "data=folder",
                "data.train_dir={train}",
                "data.val_dir={val}",
                "data.test_dir={test}",
                "train.n_query=8",
            ],
            r"training classes .* too few in t0 \(10\)",
        ),
        (["data=bogus"], r"data"),
    ],
)
def test_keys_the_source_does_not_read_are_refused(tmp_path, trees, extra, match):
    train, val, test = trees
    args = [a.format(train=train, val=val, test=test) for a in extra]
    with pytest.raises((ConfigError, DataError), match=match):
        run_stage("meta_train", [*SHRINK, *args, *outputs(tmp_path)])
    assert not (tmp_path / "rn.pt").exists()


@pytest.mark.parametrize(
    "val_classes,test_classes,match",
    [
        ("fghij", "jklmn", r"config key 'data\.test_dir': classes j are in data\.val_dir too"),
        ("efghi", "vwxyz", r"config key 'data\.val_dir': classes e are in data\.train_dir too"),
    ],
)
def test_validation_and_test_classes_must_be_held_out(tmp_path, val_classes, test_classes, match):
    train = make_tree(tmp_path / "train", list("abcde"))
    val = make_tree(tmp_path / "val", list(val_classes))
    test = make_tree(tmp_path / "test", list(test_classes))
    folders = [f"data.train_dir={train}", f"data.val_dir={val}", f"data.test_dir={test}"]
    with pytest.raises(ConfigError, match=match):
        run_stage("meta_train", ["data=folder", *folders, *outputs(tmp_path), *SHRINK])
    assert not (tmp_path / "rn.pt").exists()
