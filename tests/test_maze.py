import pytest

from pipeline.world.maze import (
    MazeError,
    count_shortest_paths,
    load_layout,
    parse_layout,
    shortest_path_length,
)


@pytest.mark.parametrize("name,obstacles,path", [("5x5", 9, 8), ("7x7", 16, 12), ("11x11", 49, 20)])
def test_builtin_mazes_have_the_papers_sizes(name, obstacles, path):
    layout = load_layout(name)
    n = int(name.split("x")[0])
    assert (layout.height, layout.width) == (n, n)
    assert len(layout.obstacles) == obstacles
    assert layout.start == 0 and layout.goal == n * n - 1
    assert shortest_path_length(layout) == path


def test_5x5_has_a_single_optimal_path():
    assert count_shortest_paths(load_layout("5x5")) == 1


def test_any_rectangular_layout_loads_from_a_file(tmp_path):
    f = tmp_path / "wide.txt"
    f.write_text("# a comment\nS..X\n.X.G\n\n")
    layout = load_layout(f)
    assert (layout.height, layout.width, layout.obstacles, layout.goal) == (2, 4, (3, 5), 7)


@pytest.mark.parametrize(
    "text,expected",
    [
        ("S..\n..\n..G\n", "bad.txt:2: ragged row: 2 cells where line 1 has 3"),
        ("S.?\n..G\n", "bad.txt:1:3: unknown character '?'"),
        ("...\n..G\n", "bad.txt: no start cell 'S'"),
        ("S.G\n..G\n", "bad.txt: 2 goal cells 'G' (at line 1 column 3, line 2 column 3)"),
        ("S.X\n.XG\n", "bad.txt:2:3: the goal is unreachable from the start"),
        ("", "bad.txt: empty layout"),
        ("\n\n# only a comment\n", "bad.txt: empty layout"),
        ("S..\n\n..G\n", "bad.txt:2: blank line inside the layout"),
    ],
)
def test_bad_layouts_name_file_line_and_problem(tmp_path, text, expected):
    f = tmp_path / "bad.txt"
    f.write_text(text)
    with pytest.raises(MazeError) as err:
        load_layout(f)
    assert expected in str(err.value).replace(str(tmp_path) + "/", "")


def test_unknown_maze_name_lists_the_builtins():
    with pytest.raises(MazeError, match="neither a file nor a built-in maze.*11x11.*5x5.*7x7"):
        load_layout("9x9")


def test_missing_and_binary_files(tmp_path):
    with pytest.raises(MazeError, match="maze file not found"):
        load_layout(tmp_path / "missing.txt")
    f = tmp_path / "bin.txt"
    f.write_bytes(b"\xff\xfe\x00S")
    with pytest.raises(MazeError, match="not a text file"):
        load_layout(f)


def test_parse_layout_names_its_source():
    with pytest.raises(MazeError, match=r"^<string>: no goal"):
        parse_layout("S..")
