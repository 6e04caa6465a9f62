"""The colour test (pipeline/fewshot/colour.py): the hue rotation is exact on pure colours and
leaves greys alone; the test's counts; the recogniser turns its query pictures only."""

import numpy as np
import pytest

from pipeline.fewshot.colour import colour_test, hue_rotate
from pipeline.fewshot.recogniser import RelationRecogniser
from pipeline.fewshot.synthetic import write_synthetic_dataset


def test_hue_rotation_of_pure_colours_and_greys():
    px = np.array(
        [[[255, 0, 0], [0, 255, 0], [128, 128, 128], [0, 0, 0], [255, 255, 255]]], dtype=np.uint8
    )
    turned = hue_rotate(px, 120.0)
    assert turned.dtype == np.uint8 and turned.shape == px.shape
    assert turned[0].tolist() == [
        [0, 255, 0],
        [0, 0, 255],
        [128, 128, 128],
        [0, 0, 0],
        [255, 255, 255],
    ]
    assert hue_rotate(px, 240.0)[0, 0].tolist() == [0, 0, 255]
    assert hue_rotate(px, 360.0) is px and hue_rotate(px, 0.0) is px


def test_hue_rotation_keeps_value_and_saturation_and_turns_back():
    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, size=(2, 6, 6, 3), dtype=np.uint8)
    turned = hue_rotate(img, 75.0)
    assert not np.array_equal(turned, img)
    assert np.abs(turned.max(-1).astype(int) - img.max(-1)).max() <= 1  # value = max channel
    back = hue_rotate(turned, 285.0)
    assert np.abs(back.astype(int) - img).max() <= 2  # rounding to uint8 twice


def test_colour_test_counts():
    cats = np.array([0, 0, 1, 1, 2])
    out = colour_test(
        np.array([0, 1, 1, 1, 2]), {120.0: np.array([0, 0, 0, 0, 0]), 60.0: cats}, cats
    )
    assert out["shifts_deg"] == [60.0, 120.0]
    assert (
        out["correct_original"] == 4 and out["correct_per_shift"] == [5, 2] and out["pictures"] == 5
    )
    assert out["predictions_per_shift"][1] == [0, 0, 0, 0, 0] and out["categories"] == [
        0,
        0,
        1,
        1,
        2,
    ]


def test_recogniser_turns_only_its_query_pictures(tmp_path):
    import torch

    from pipeline.fewshot.checkpoint import save_checkpoint
    from pipeline.fewshot.model import ModelConfig, RelationNetwork

    images = tmp_path / "images"
    write_synthetic_dataset(images, n_train=2, n_val=1, per_class=2, seed=1)
    torch.manual_seed(0)
    net = RelationNetwork(ModelConfig(24, 1))
    save_checkpoint(
        tmp_path / "rn.pt",
        net,
        normalisation={"mean": [0.5] * 3, "std": [0.25] * 3},
        config={},
        metrics={},
    )
    plain = RelationRecogniser.from_files(tmp_path / "rn.pt", images)
    turned = RelationRecogniser.from_files(tmp_path / "rn.pt", images, query_hue_shift=180.0)
    again = RelationRecogniser.from_files(tmp_path / "rn.pt", images, query_hue_shift=180.0)
    # each picture's part of a class state (the embedding's half of g_phi's first convolution):
    # the query pictures' parts change, the original support pictures' (codes -1..-25), and so
    # the class states of the original support set, do not
    assert all(not torch.equal(plain.parts[p], turned.parts[p]) for p in range(40))
    assert all(torch.equal(turned.parts[p], again.parts[p]) for p in range(40))
    assert all(torch.equal(plain.parts[-j], turned.parts[-j]) for j in range(1, 26))
    assert (
        "query_hue_shift" not in plain.describe() and turned.describe()["query_hue_shift"] == 180.0
    )
    with pytest.raises(ValueError):
        RelationRecogniser.from_files(tmp_path / "rn.pt", images, query_hue_shift=float("nan"))


def test_the_colour_test_on_the_views_of_the_query_obstacles(tmp_path):
    """pipeline/fewshot/views.py: every views picture against the original support set, as
    rendered and per hue shift; a whole turn changes nothing; a render without views has none."""
    import torch

    from pipeline.fewshot.checkpoint import save_checkpoint
    from pipeline.fewshot.model import ModelConfig, RelationNetwork
    from pipeline.fewshot.views import has_views, views_predictions

    images, bare = tmp_path / "images", tmp_path / "bare"
    write_synthetic_dataset(images, n_train=2, n_val=1, per_class=2, views_per_category=6, seed=1)
    write_synthetic_dataset(bare, n_train=2, n_val=1, per_class=2, seed=1)
    torch.manual_seed(0)
    save_checkpoint(
        tmp_path / "rn.pt",
        RelationNetwork(ModelConfig(24, 1)),
        normalisation={"mean": [0.5] * 3, "std": [0.25] * 3},
        config={},
        metrics={},
    )
    rec = RelationRecogniser.from_files(tmp_path / "rn.pt", images)
    cats, obstacles, original, turned = views_predictions(rec, images, [360.0, 180.0])
    assert cats.tolist() == [c for c in range(5) for _ in range(6)] and original.shape == (30,)
    # each view's obstacle: its category's instance (0 or 1 in the synthetic manifest)
    assert obstacles.tolist() == [2 * c + i for c in range(5) for i in (0, 0, 0, 1, 1, 1)]
    assert np.array_equal(turned[360.0], original)
    _, _, shifted, _ = views_predictions(rec, images, [], base_shift=180.0)
    assert np.array_equal(shifted, turned[180.0])
    counts = colour_test(original, turned, cats, obstacles)
    assert counts["obstacles"] == obstacles.tolist() and "obstacles" not in colour_test(
        original, turned, cats
    )
    assert counts["pictures"] == 30 and counts["correct_per_shift"][1] == counts["correct_original"]
    assert has_views(images) and not has_views(bare)
