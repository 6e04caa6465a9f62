"""``learn_from``: which substituted pictures a query's recognition sees (the repetition study's
split of the DSS gain by source, pipeline/fewshot/learn_from.py)."""

import numpy as np
import pytest
from fakes import SYNTHETIC_NORM, untrained_network

from pipeline.config.recognisers import build_recogniser
from pipeline.errors import ConfigError
from pipeline.fewshot.data import load_split, to_tensor
from pipeline.fewshot.learn_from import LEARN_FROM, learning_groups, table_by_group
from pipeline.fewshot.recogniser import RelationRecogniser
from pipeline.world.pictures import picture_id

CATEGORIES = np.repeat(np.arange(5), 8)  # the 40 query pictures' categories, by picture id


def test_groups_of_each_setting():
    assert learning_groups("all", CATEGORIES) is None
    np.testing.assert_array_equal(learning_groups("same_category", CATEGORIES), CATEGORIES)
    np.testing.assert_array_equal(learning_groups("same_picture", CATEGORIES), np.arange(40))
    named = np.repeat([f"obstacle {k}" for k in range(10)], 4)
    objects = learning_groups("same_object", CATEGORIES, named)
    np.testing.assert_array_equal(objects, np.repeat(np.arange(10), 4))


def test_unknown_setting_and_missing_obstacles_are_refused():
    with pytest.raises(ValueError, match="learn_from must be one of all, same_category"):
        learning_groups("same_face", CATEGORIES)
    with pytest.raises(ValueError, match="needs each query picture's obstacle"):
        learning_groups("same_object", CATEGORIES)


def test_each_group_sees_only_its_own_substitutions():
    """A column's score is the sum of its members' codes (a fake eq. 2): each picture's row shows
    which members it saw."""

    def column(members):
        return np.full(4, float(sum(members)))

    groups = np.array([0, 0, 1, 2])
    original = np.array([[-1, -2], [-3, -4]])
    members = np.array([[0, -2], [2, 3]])  # picture 0 into category 0; pictures 2, 3 into 1
    table = table_by_group(column, members, original, groups)
    np.testing.assert_array_equal(table[:, 0], [-2, -2, -3, -3])  # group 0 sees picture 0
    np.testing.assert_array_equal(table[:, 1], [-7, -7, -2, 0])  # groups 1 and 2 their own


def test_the_table_is_each_groups_own_view_asking_only_for_the_columns_that_differ():
    """Against the definition (every group, every category, its own column), over random
    support sets: the same table; columns asked for only where a group gave a category a picture."""
    rng = np.random.default_rng(0)
    original = -np.arange(1, 26).reshape(5, 5)
    for groups in (np.arange(40), CATEGORIES, np.repeat(np.arange(10), 4)):
        for _ in range(20):
            members = original.copy()
            for _ in range(rng.integers(0, 12)):
                picture = int(rng.integers(40))
                members[CATEGORIES[picture], rng.integers(5)] = picture
            asked = []

            def column(m, asked=asked):
                asked.append(tuple(m))
                return np.sin(np.arange(40) + sum(int(x) * 1.7**k for k, x in enumerate(m)))

            defined = np.empty((40, 5))
            for group in np.unique(groups):
                rows = groups == group
                own = (members >= 0) & (groups[np.maximum(members, 0)] == group)
                for c in range(5):
                    defined[rows, c] = column(np.where(own, members, original)[c])[rows]
            asked.clear()
            np.testing.assert_array_equal(
                table_by_group(column, members, original, groups), defined
            )
            givers = {(c, groups[m]) for c in range(5) for m in members[c] if m >= 0}
            assert len(asked) == 5 + len(givers)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    root = tmp_path_factory.mktemp("learn_from")
    ckpt, _ = untrained_network(root)
    return root, ckpt


def test_reach_grows_from_the_picture_to_every_picture(files):
    """After one substitution the changed scores reach the picture itself, its object's four
    faces, its category's eight pictures or all forty; ``all`` is the recogniser without the key."""
    root, ckpt = files
    changed = {}
    for learn_from in LEARN_FROM:
        rec = RelationRecogniser.from_files(ckpt, root / "images", learn_from=learn_from)
        rec.start_run(0, seed=3)
        before = rec.scores(0, np.arange(40)).copy()
        rec.learn_from_collision(0, picture_id=picture_id(1, 0, 1), true_category=1)
        after = rec.scores(0, np.arange(40))
        changed[learn_from] = np.flatnonzero(np.abs(after - before).max(axis=1) > 0).tolist()
        assert ("learn_from" in rec.describe()) == (learn_from != "all")
    assert changed["same_picture"] == [picture_id(1, 0, 1)]
    assert changed["same_object"] == list(range(8, 12))
    assert changed["same_category"] == list(range(8, 16))
    assert len(changed["all"]) > 8  # other categories' scores of every picture move too
    plain = RelationRecogniser.from_files(ckpt, root / "images")
    plain.start_run(0, seed=3)
    plain.learn_from_collision(0, picture_id=picture_id(1, 0, 1), true_category=1)
    full = RelationRecogniser.from_files(ckpt, root / "images", learn_from="all")
    full.start_run(0, seed=3)
    full.learn_from_collision(0, picture_id=picture_id(1, 0, 1), true_category=1)
    np.testing.assert_array_equal(plain.scores(0, np.arange(40)), full.scores(0, np.arange(40)))


def test_the_config_key_is_applied_or_refused(files):
    root, ckpt = files
    node = {
        "_target_": "pipeline.fewshot.recogniser.RelationRecogniser.from_files",
        "checkpoint": str(ckpt),
        "images_dir": str(root / "images"),
    }
    rec = build_recogniser(
        {**node, "learn_from": "same_object"}, substitution_way=1, carry_over=False
    )
    assert rec.learn_from == "same_object" and rec.describe()["learn_from"] == "same_object"
    with pytest.raises(ConfigError, match="learn_from must be one of"):
        build_recogniser({**node, "learn_from": "faces"}, substitution_way=1, carry_over=False)
    images = load_split(root / "images", "query", 24).images
    assert to_tensor(images, **SYNTHETIC_NORM).shape[0] == 40
