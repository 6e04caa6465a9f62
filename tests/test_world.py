import numpy as np

from pipeline.world.geometry import build_geometry
from pipeline.world.maze import load_layout, parse_layout
from pipeline.world.pictures import N_PICTURES, face_seen, picture_id, picture_parts
from pipeline.world.placement import Placement, picture_table, random_placement

# 3x3 with one obstacle in the middle:  S . .  /  . X .  /  . . G
CROSS = parse_layout("S..\n.X.\n..G\n")


def test_critical_states_and_dangerous_pairs_of_eqs_3_and_4():
    g = build_geometry(CROSS)
    # the four neighbours of the centre (cell 4) are critical; each has one action toward it
    assert g.critical_states.tolist() == [1, 3, 5, 7]
    assert g.dangerous_pairs.tolist() == [[1, 2], [3, 1], [5, 3], [7, 0]]
    assert g.side[1, 2] == 0 and g.side[7, 0] == 2  # cell 1 lies north of the obstacle
    # a move into an obstacle or off the grid leaves the robot in place
    assert g.next_cell[1, 2] == 1 and g.next_cell[0, 0] == 0 and g.next_cell[0, 1] == 1
    assert g.ssrl_pairs[0].tolist() == [[1, 2], [5, 3], [7, 0], [3, 1]]


def test_faces_and_orientation():
    assert [face_seen(d, 0) for d in range(4)] == [0, 1, 2, 3]
    assert [face_seen(d, 1) for d in range(4)] == [3, 0, 1, 2]  # turned a quarter clockwise
    g = build_geometry(CROSS)
    table = picture_table(g, Placement(np.array([7], np.int16), np.array([1], np.int8)))
    # physical 7 = category 3 (basin), instance 1; from the north side (d=0) the face is 3
    assert table[1, 2] == picture_id(3, 1, 3) == 31
    assert table[5, 3] == picture_id(3, 1, 0)
    assert (table >= 0).sum() == 4


def test_faces_toward_other_obstacles_are_never_seen():
    layout = parse_layout("S...\n.XX.\n...G\n")
    g = build_geometry(layout)
    table = picture_table(g, Placement(np.array([0, 2], np.int16), np.array([0, 0], np.int8)))
    seen = set(table[table >= 0].tolist())
    assert picture_id(0, 0, 1) not in seen  # obstacle 0's east face touches obstacle 1
    assert picture_id(1, 0, 3) not in seen
    assert len(seen) == 6


def test_placement_without_repetition_then_balanced():
    rng = np.random.default_rng(3)
    p9 = random_placement(9, rng)
    assert len(set(p9.physical.tolist())) == 9
    p16 = random_placement(16, rng)
    counts = np.bincount(p16.physical, minlength=10)
    assert counts.min() == 1 and counts.max() == 2
    p49 = random_placement(49, rng)
    counts = np.bincount(p49.physical, minlength=10)
    assert counts.min() >= 4 and counts.max() <= 5
    assert set(p49.orientation.tolist()) <= {0, 1, 2, 3}


def test_picture_ids_round_trip():
    assert [picture_parts(picture_id(*picture_parts(p))) for p in range(N_PICTURES)] == [
        picture_parts(p) for p in range(N_PICTURES)
    ]
    assert picture_parts(39) == (4, 1, 3)


def test_5x5_sees_pictures_from_every_critical_state():
    g = build_geometry(load_layout("5x5"))
    assert len(g.critical_states) == 14 and len(g.dangerous_pairs) == 22
