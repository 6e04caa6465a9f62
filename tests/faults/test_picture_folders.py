"""Hostile picture folders (docs/reliability.md "Checkpoints and image folders"): a rendered
dataset's ``images_dir`` (its ``manifest.csv`` and pictures, ``pipeline/fewshot/data.py``) as the
trials, the accuracy study and meta-training read it with the Relation Network, and the
folder-per-class trees of ``meta_train data=folder``.

Each damage is one clear line naming the folder or the file, before any work: nothing is written
(no ``out`` folder, no checkpoint) and the damaged folder is left as it was. Every damage of a
rendered dataset goes through meta-training, the first of each kind (the manifest, a picture, too
few pictures) through the trials and the accuracy study too (each loads a checkpoint first, about
0.5 s), and every damage of a split through the reader
(:func:`~pipeline.fewshot.data.read_manifest`, :func:`~pipeline.fewshot.data.load_split`) in each
split.
Pictures that are unusual but pictures (another size, grey, with alpha, 16-bit, a palette, JPEG
bytes named ``.png``) are read, resized to the model's input. A folder that cannot be read for
its permissions is skipped as root (root reads it all the same).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import struct
import zlib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch
from entry import cli
from PIL import Image
from test_fewshot_folder import SHRINK, make_tree, outputs

from faults._checks import one_line_error
from pipeline.errors import UserError
from pipeline.fewshot.checkpoint import save_checkpoint
from pipeline.fewshot.data import MANIFEST, DataError, load_folder, load_split, read_manifest
from pipeline.fewshot.model import RelationNetwork
from pipeline.fewshot.settings import ModelConfig
from pipeline.fewshot.synthetic import write_synthetic_dataset
from pipeline.stages import run_stage

SIZE = 24
ROOT_USER = hasattr(os, "geteuid") and os.geteuid() == 0
#: Each stage and the split of the dataset it reads last (a damage there comes after work that
#: reading the other splits would have started).
STAGES = {"trials": "support", "accuracy": "support", "meta_train": "test"}


@pytest.fixture(scope="module", autouse=True)
def one_torch_thread():
    """The trials build their recogniser (and probe its checkpoint) before they set torch's thread
    count: on a busy machine two threads make that probe 20 times slower. Nothing here depends on it."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    """An untrained Relation Network's checkpoint for 24-pixel pictures and a small rendered
    dataset (5 classes in each of train, val and test, the 5 query and support categories),
    unchanged by the cases that damage its hard-linked copies."""
    d = tmp_path_factory.mktemp("pictures")
    torch.manual_seed(0)
    save_checkpoint(
        d / "rn.pt",
        RelationNetwork(ModelConfig(SIZE, 1)),
        normalisation={"mean": [0.5] * 3, "std": [0.25] * 3},
        config={},
        metrics={},
    )
    write_synthetic_dataset(d / "images", n_train=5, n_val=5, n_test=5, per_class=7, size=SIZE)
    before = digest(d / "images")
    yield d
    assert digest(d / "images") == before


def stage_args(stage: str, model: Path, images: Path, out: Path) -> list[str]:
    recogniser = [
        f"recogniser.images_dir={images}",
        f"recogniser.checkpoint={model / 'rn.pt'}",
        f"recogniser.input_size={SIZE}",
        "recogniser.relation_padding=1",
    ]
    return {
        "trials": [
            "method=fewshot",
            *recogniser,
            "runs=2",
            "episodes=4",
            f"out={out}",
            "threads=1",
        ],
        "accuracy": [*recogniser, "study.repeats=1", f"out_dir={out}", "threads=1"],
        "meta_train": [f"images_dir={images}", *outputs(out), *SHRINK],
    }[stage] + ["progress=false"]


def digest(folder: Path) -> dict[str, str]:
    if not folder.is_dir():
        return {}
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and not p.is_symlink()
    }


# ------------------------------------------------------------------ damages of a rendered dataset
def first_of(images: Path, split: str) -> tuple[Path, int]:
    """The first picture of ``split`` in the manifest, and its line in the file."""
    frame = pd.read_csv(images / MANIFEST)
    row = int(np.flatnonzero(frame["split"].to_numpy() == split)[0])
    return images / frame["file"].iloc[row], row + 2


def rewrite(images: Path, change) -> None:
    frame = pd.read_csv(images / MANIFEST)
    change(frame).to_csv(images / MANIFEST, index=False)


def _png_header_only(path: Path, side: int) -> None:
    def chunk(kind: bytes, data: bytes) -> bytes:
        crc = struct.pack(">I", zlib.crc32(kind + data))
        return struct.pack(">I", len(data)) + kind + data + crc

    ihdr = struct.pack(">IIBBBBB", side, side, 8, 2, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IEND", b""))


def _flip(path: Path, at: int) -> None:
    data = bytearray(path.read_bytes())
    data[at] ^= 0xFF
    path.write_bytes(bytes(data))


def _too_few(images: Path, split: str) -> None:
    """The split's first class keeps one picture: too few for an episode or a 5-shot support."""

    def change(f):
        first = f[f["split"] == split]["category"].iloc[0]
        rows = f.index[(f["split"] == split) & (f["category"] == first)]
        return f.drop(rows[1:])

    rewrite(images, change)


def _one_class_fewer(images: Path, split: str) -> None:
    def change(f):
        rows = f[f["split"] == split]
        return f.drop(rows.index[rows["category"] == rows["category"].max()])

    rewrite(images, change)


#: Damage -> (what it does to the dataset folder and its split, the words of the line: ``{dir}``
#: the folder, ``{manifest}`` its manifest, ``{picture}`` the damaged picture, ``{line}`` its
#: manifest line).
DAMAGES = {
    "an empty folder": (
        lambda d, s: [shutil.rmtree(d), d.mkdir()],
        "no picture manifest at {manifest}",
    ),
    "no folder": (lambda d, s: shutil.rmtree(d), "no picture manifest at {manifest}"),
    "a manifest that is a folder": (
        lambda d, s: [(d / MANIFEST).unlink(), (d / MANIFEST).mkdir()],
        "no picture manifest at {manifest}",
    ),
    "an empty manifest": (
        lambda d, s: (d / MANIFEST).write_bytes(b""),
        "{manifest}: not a picture manifest",
    ),
    "a binary manifest": (
        lambda d, s: (d / MANIFEST).write_bytes(bytes(range(256)) * 8),
        "{manifest}: not a picture manifest",
    ),
    "a UTF-16 manifest": (
        lambda d, s: (d / MANIFEST).write_bytes((d / MANIFEST).read_text().encode("utf-16")),
        "{manifest}: not a picture manifest",
    ),
    "the header alone": (
        lambda d, s: (d / MANIFEST).write_text((d / MANIFEST).read_text().split("\n")[0] + "\n"),
        "{manifest}: no rows for split",
    ),
    "no file column": (
        lambda d, s: rewrite(d, lambda f: f.drop(columns="file")),
        "{manifest}: missing column(s) ['file']",
    ),
    "an unknown split": (
        lambda d, s: rewrite(d, lambda f: f.assign(split=f["split"].where(f.index > 0, "nosuch"))),
        "{manifest}: unknown split(s) ['nosuch']",
    ),
    "a word for a category": (
        lambda d, s: rewrite(
            d, lambda f: f.assign(category=f["category"].astype(str).where(f["split"] != s, "abc"))
        ),
        "{manifest}:{line}: column 'category' holds 'abc', not a whole number",
    ),
    "no file name": (
        lambda d, s: rewrite(d, lambda f: f.assign(file=f["file"].where(f["split"] != s, ""))),
        "{manifest}:{line}: column 'file' is empty",
    ),
    "a missing picture": (lambda p: p.unlink(), "cannot read picture {picture}: "),
    "a truncated PNG": (
        lambda p: p.write_bytes(p.read_bytes()[:60]),
        "cannot read picture {picture}: ",
    ),
    "a zero-byte PNG": (lambda p: p.write_bytes(b""), "cannot read picture {picture}: "),
    "text named .png": (lambda p: p.write_text("not a picture"), "cannot read picture {picture}: "),
    "a folder named .png": (lambda p: [p.unlink(), p.mkdir()], "cannot read picture {picture}: "),
    "a symbolic link loop": (
        lambda p: [p.unlink(), p.symlink_to(p)],
        "cannot read picture {picture}: ",
    ),
    "a flipped byte in the PNG header": (lambda p: _flip(p, 20), "cannot read picture {picture}: "),
    "a decompression bomb": (
        lambda p: _png_header_only(p, 20000),
        "cannot read picture {picture}: too large",
    ),
    "a class with one picture": (lambda d, s: _too_few(d, s), "{dir}"),
    "a class fewer": (lambda d, s: _one_class_fewer(d, s), "{dir}"),
}
PICTURE = {k for k, (damage, _) in DAMAGES.items() if damage.__code__.co_argcount == 1}
#: Counts the stages check (how many pictures an episode or the support set needs), not the reader.
COUNTS = {"a class fewer", "a class with one picture"}
KINDS = {"a picture": PICTURE, "a count": COUNTS}
KINDS["the manifest"] = set(DAMAGES) - PICTURE - COUNTS


def kind_firsts() -> list[str]:
    return [next(w for w in DAMAGES if w in members) for members in KINDS.values()]


#: Every damage through meta-training (the cheapest stage: no checkpoint to load), the first
#: damage of each kind through the trials and the accuracy study too.
CASES = [pytest.param(what, "meta_train", id=f"{what}-meta_train") for what in DAMAGES] + [
    pytest.param(what, stage, id=f"{what}-{stage}")
    for stage in ("trials", "accuracy")
    for what in kind_firsts()
]


def own(path: Path) -> Path:
    """``path`` as a file of its own (no longer a hard link to the module's dataset)."""
    if path.is_file():
        data = path.read_bytes()
        path.unlink()
        path.write_bytes(data)
    return path


def copy_dataset(source: Path, images: Path) -> None:
    """The dataset as hard links (a copy of 180 files is slow on a busy disk), its manifest a
    file of its own; a picture is made one of its own before it is changed (:func:`own`)."""
    shutil.copytree(source, images, copy_function=os.link)
    own(images / MANIFEST)


def damage(images: Path, what: str, split: str) -> dict[str, str]:
    """Damage a copy of the dataset; the names its line must hold."""
    picture, line = first_of(images, split)
    own(picture)
    change, _ = DAMAGES[what]
    change(picture) if what in PICTURE else change(images, split)
    return {
        "dir": str(images),
        "manifest": str(images / MANIFEST),
        "picture": str(picture),
        "line": line,
    }


def expected(what: str, names: dict[str, str]) -> str:
    return DAMAGES[what][1].format(**names)


@pytest.mark.parametrize("what,stage", CASES)
def test_a_damaged_rendered_dataset_is_one_line_in_the_stage(model, tmp_path, what, stage):
    images = tmp_path / "images"
    copy_dataset(model / "images", images)
    names = damage(images, what, STAGES[stage])
    before = digest(images)
    with pytest.raises(UserError) as err:
        run_stage(stage, stage_args(stage, model, images, tmp_path / "out"))
    message = str(err.value)
    assert "\n" not in message and expected(what, names) in message, message
    assert not (tmp_path / "out").exists() and digest(images) == before


#: Damages of one split (a picture, a manifest line of it): tried in every split.
OF_A_SPLIT = PICTURE | {"a word for a category", "no file name"}
SPLITS = ["query", "support", "train", "val", "test"]
READER_CASES = [
    pytest.param(what, split, id=f"{what}-{split}")
    for what in DAMAGES
    if what not in COUNTS
    for split in (SPLITS if what in OF_A_SPLIT else SPLITS[:1])
]


@pytest.mark.parametrize("what,split", READER_CASES)
def test_the_reader_names_a_damage_of_any_split(model, tmp_path, what, split):
    images = tmp_path / "images"
    copy_dataset(model / "images", images)
    names = damage(images, what, split)
    with pytest.raises(DataError) as err:
        load_split(images, split, SIZE, read_manifest(images))
    message = str(err.value)
    assert "\n" not in message and expected(what, names) in message, message


@pytest.mark.parametrize("what", sorted(KINDS["the manifest"]))
def test_a_damaged_manifest_the_records_would_keep_pictures_of_is_one_line(model, tmp_path, what):
    """``images_dir`` of a recogniser without pictures of its own (the oracle): the trials read
    its manifest for the pictures the records keep."""
    images = tmp_path / "images"
    copy_dataset(model / "images", images)
    names = damage(images, what, "query")
    args = ["method=fewshot", "recogniser=oracle", f"images_dir={images}", "runs=2", "episodes=4"]
    with pytest.raises(UserError) as err:
        run_stage("trials", [*args, f"out={tmp_path / 'out'}", "progress=false"])
    message = str(err.value)
    assert "\n" not in message and message.startswith("config key 'images_dir': "), message
    assert expected(what, names) in message and not (tmp_path / "out").exists()


def unusual(path: Path) -> dict[str, Image.Image]:
    """Pictures of another kind than the dataset's (84 x 84 RGB): each read and resized."""
    rgb = np.asarray(Image.open(path).convert("RGB"))
    return {
        "wide": Image.fromarray(rgb).resize((200, 40)),
        "one pixel": Image.fromarray(rgb[:1, :1]),
        "grey": Image.fromarray(rgb).convert("L"),
        "grey 16-bit": Image.fromarray(rgb[..., 0].astype(np.uint16) * 257),
        "with alpha": Image.fromarray(rgb).convert("RGBA"),
        "a palette": Image.fromarray(rgb).convert("P"),
        "black and white": Image.fromarray(rgb).convert("1"),
    }


def test_unusual_pictures_are_read_at_the_models_size_and_the_trial_runs(model, tmp_path):
    images = tmp_path / "images"
    copy_dataset(model / "images", images)
    frame = pd.read_csv(images / MANIFEST)
    files = frame[frame["split"] == "query"]["file"].tolist()
    for f, picture in zip(files, unusual(images / files[0]).values()):
        picture.save(own(images / f), format="PNG")
    Image.open(images / files[-1]).convert("RGB").save(own(images / files[-1]), format="JPEG")
    query = load_split(images, "query", SIZE)
    assert query.images.shape == (len(files), SIZE, SIZE, 3) and query.images.dtype == np.uint8
    summary = run_stage("trials", stage_args("trials", model, images, tmp_path / "out"))
    assert summary["n_runs"] == 2 and (tmp_path / "out" / "summary.json").exists()


@pytest.mark.skipif(ROOT_USER, reason="root reads a file whatever its permissions")
@pytest.mark.parametrize("target", ["picture", "manifest", "folder"])
def test_an_unreadable_file_or_folder_is_one_line(model, tmp_path, target):
    images = tmp_path / "images"
    copy_dataset(model / "images", images)
    picture, _ = first_of(images, "support")
    path = {"picture": picture, "manifest": images / MANIFEST, "folder": picture.parent}[target]
    own(path).chmod(0)
    try:
        with pytest.raises(UserError) as err:
            run_stage("trials", stage_args("trials", model, images, tmp_path / "out"))
    finally:
        path.chmod(0o755)
    message = str(err.value)
    assert "\n" not in message and str(path) in message and "ermission" in message, message


# ------------------------------------------------------------------ data=folder trees
def trees(root: Path) -> dict[str, Path]:
    return {
        key: make_tree(root / key, [f"{key[:-4]}{c}" for c in range(5)], per_class=10, seed=i)
        for i, key in enumerate(("train_dir", "val_dir", "test_dir"))
    }


def first_picture(tree: Path) -> Path:
    return sorted(sorted(p for p in tree.iterdir() if p.is_dir())[0].iterdir())[0]


#: Damage -> (what it does to a tree, the words of the line: ``{tree}``, ``{class_}`` (its first
#: class folder), ``{picture}`` (that class's first picture)).
TREE_DAMAGES = {
    "no such folder": (lambda t, c, p: shutil.rmtree(t), "{tree} is not a folder"),
    "a file, not a folder": (
        lambda t, c, p: [shutil.rmtree(t), t.write_text("x")],
        "{tree} is not a folder",
    ),
    "no class folders": (
        lambda t, c, p: [shutil.rmtree(x) for x in t.iterdir()],
        "{tree}: no class folders",
    ),
    "a class without pictures": (
        lambda t, c, p: [x.unlink() for x in c.iterdir()],
        "{class_}: class folder without pictures",
    ),
    "a truncated PNG": (
        lambda t, c, p: p.write_bytes(p.read_bytes()[:60]),
        "cannot read picture {picture}: ",
    ),
    "a zero-byte PNG": (lambda t, c, p: p.write_bytes(b""), "cannot read picture {picture}: "),
    "text named .png": (lambda t, c, p: p.write_text("x"), "cannot read picture {picture}: "),
    "a flipped byte in the PNG header": (
        lambda t, c, p: _flip(p, 20),
        "cannot read picture {picture}: ",
    ),
    "a decompression bomb": (
        lambda t, c, p: _png_header_only(p, 20000),
        "cannot read picture {picture}: too large",
    ),
    "a link to nowhere": (
        lambda t, c, p: (c / "gone.png").symlink_to(t / "nowhere.png"),
        "{class_}/gone.png: a symbolic link that leads nowhere",
    ),
    "a class with one picture": (
        lambda t, c, p: [x.unlink() for x in sorted(c.iterdir())[1:]],
        "too few in " + "{class_name} (1)",
    ),
    "a class fewer": (
        lambda t, c, p: shutil.rmtree(c),
        "4 classes; 5-way episodes need at least 5",
    ),
}
TREE_CASES = [
    pytest.param(what, key, id=f"{what}-{key}")
    for i, what in enumerate(TREE_DAMAGES)
    for key in [("train_dir", "val_dir", "test_dir")[i % 3]]
]


@pytest.mark.parametrize("what,key", TREE_CASES)
def test_a_damaged_class_tree_is_one_line_naming_it(model, tmp_path, what, key):
    folders = trees(tmp_path)
    tree = folders[key]
    class_ = sorted(p for p in tree.iterdir() if p.is_dir())[0]
    picture = first_picture(tree)
    change, words = TREE_DAMAGES[what]
    change(tree, class_, picture)
    before = {k: digest(t) for k, t in folders.items()}
    args = ["data=folder", *(f"data.{k}={t}" for k, t in folders.items())]
    with pytest.raises(UserError) as err:
        run_stage("meta_train", [*args, *outputs(tmp_path / "out"), *SHRINK])
    message = str(err.value)
    names = {"tree": tree, "class_": class_, "picture": picture, "class_name": class_.name}
    assert "\n" not in message and words.format(**names) in message, message
    assert str(tree) in message or key in message, message
    assert not (tmp_path / "out").exists() and {k: digest(t) for k, t in folders.items()} == before


def test_unusual_pictures_in_a_class_tree_are_read_at_the_models_size(tmp_path):
    tree = make_tree(tmp_path / "tree", ["a", "b"], per_class=2)
    for kind, picture in unusual(first_picture(tree)).items():
        picture.save(tree / "a" / f"{kind}.png", format="PNG")
    Image.open(first_picture(tree)).convert("RGB").save(tree / "b" / "jpeg.png", format="JPEG")
    (tree / "b" / "notes.txt").write_text("not a picture, not read")
    pictures = load_folder(tree, SIZE)
    assert pictures.images.shape == (2 + len(unusual(first_picture(tree))) + 3, SIZE, SIZE, 3)
    assert pictures.class_names == ("a", "b")


def _png_header_only(path: Path, side: int) -> None:
    """A PNG that declares ``side`` x ``side`` pixels (PIL's bomb check reads the header)."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (
            struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
        )

    ihdr = struct.pack(">IIBBBBB", side, side, 8, 2, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IEND", b""))


@pytest.mark.parametrize("side", [20000, 10000])  # over PIL's error and its warning limits
def test_a_decompression_bomb_in_a_folder_tree_is_one_line(tmp_path, side):
    root = make_tree(tmp_path / "tree", ["a", "b"], per_class=2)
    _png_header_only(root / "a" / "huge.png", side)
    with pytest.raises(DataError, match=r"huge.png: too large, Image size \("):
        load_folder(root, 24)


def _meta_train(tmp_path, train, val):
    test = make_tree(tmp_path / "test", ["x0", "x1"], per_class=2)
    return cli(
        "meta_train",
        "data=folder",
        f"data.train_dir={train}",
        f"data.val_dir={val}",
        f"data.test_dir={test}",
        "progress=false",
        *outputs(tmp_path / "m"),
        *SHRINK,
    )


def test_a_symbolic_link_loop_as_the_training_folder_is_one_line(tmp_path):
    loop = tmp_path / "loop"
    loop.symlink_to(loop)
    val = make_tree(tmp_path / "val", ["v0", "v1"], per_class=2)
    one_line_error(
        _meta_train(tmp_path, loop, val), "config key 'data.train_dir'", "symbolic link loop"
    )


@pytest.mark.parametrize("target", ["..", "self"])
def test_a_class_folder_linked_to_its_parent_or_itself_is_one_line(tmp_path, target):
    train = make_tree(tmp_path / "train", ["t0", "t1"], per_class=2)
    (train / "link").symlink_to(target)
    val = make_tree(tmp_path / "val", ["v0", "v1"], per_class=2)
    words = ["which holds this tree"] if target == ".." else ["leads nowhere or to itself"]
    one_line_error(_meta_train(tmp_path, train, val), f"{train / 'link'}:", *words)
