"""Scores computed once (pipeline/fewshot/score_cache.py): recognisers that score the same way share
their columns, others do not, and what a trial records is the same with and without sharing."""

import os
import shutil
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
import torch
from fakes import ListSink

from pipeline.fewshot import from_files, score_cache
from pipeline.fewshot.checkpoint import save_checkpoint
from pipeline.fewshot.data import DataError
from pipeline.fewshot.model import ModelConfig, RelationNetwork
from pipeline.fewshot.protonet import PrototypicalNetwork
from pipeline.fewshot.recogniser import ProtoRecogniser, RelationRecogniser
from pipeline.fewshot.settings import ProtoConfig
from pipeline.fewshot.synthetic import write_synthetic_dataset
from pipeline.rl.methods import get_method
from pipeline.rl.runner import run_trials
from pipeline.world.maze import load_layout

NORM = {"mean": [0.4, 0.4, 0.4], "std": [0.25, 0.25, 0.25]}


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    root = tmp_path_factory.mktemp("score_cache")
    write_synthetic_dataset(root / "images", n_train=5, n_val=5, per_class=2, seed=3)
    torch.manual_seed(1)
    net = RelationNetwork(ModelConfig(24, 1))
    with torch.no_grad():
        net(torch.randn(5, 5, 3, 24, 24), torch.randn(10, 3, 24, 24))
    rn = save_checkpoint(root / "rn.pt", net.eval(), normalisation=NORM, config={}, metrics={})
    torch.manual_seed(2)
    proto = PrototypicalNetwork(ProtoConfig(24))
    pn = save_checkpoint(root / "pn.pt", proto.eval(), normalisation=NORM, config={}, metrics={})
    return root / "images", rn, pn


@pytest.fixture(autouse=True)
def fresh_store():
    score_cache.clear()
    yield
    score_cache.clear()


def test_recognisers_of_one_source_share_columns_across_ways_and_runs(files):
    images, rn, _ = files
    first = RelationRecogniser.from_files(rn, images, substitution_way=1)
    assert score_cache.statistics() == {"columns": 5, "hits": 0, "misses": 5, "loaded": 0}
    second = RelationRecogniser.from_files(rn, images, substitution_way=3)
    assert score_cache.statistics() == {"columns": 5, "hits": 5, "misses": 5, "loaded": 0}
    first.start_run(0, seed=4)
    first.replace(
        0, category=2, position=0, picture_id=int(np.flatnonzero(first.query_categories == 2)[0])
    )
    before = first.scores(0, np.arange(40)).copy()
    second.start_run(7, seed=9)
    second.replace(
        7, category=2, position=0, picture_id=int(np.flatnonzero(second.query_categories == 2)[0])
    )
    stats = score_cache.statistics()
    np.testing.assert_array_equal(second.scores(7, np.arange(40)), before)
    assert score_cache.statistics() == {**stats, "hits": stats["hits"] + 1}


def test_another_hue_or_kind_is_another_source(files):
    images, rn, pn = files
    RelationRecogniser.from_files(rn, images)
    RelationRecogniser.from_files(rn, images, query_hue_shift=90.0)
    ProtoRecogniser.from_files(pn, images)
    assert score_cache.statistics() == {"columns": 15, "hits": 0, "misses": 15, "loaded": 0}


@pytest.mark.parametrize("kind", ["relation", "proto"])
def test_a_trial_records_the_same_with_and_without_sharing(files, kind):
    images, rn, pn = files
    load = (
        (lambda: RelationRecogniser.from_files(rn, images, substitution_way=2))
        if kind == "relation"
        else (lambda: ProtoRecogniser.from_files(pn, images, substitution_way=2))
    )
    layout, method = load_layout("7x7"), get_method("fewshot_dss")

    def batches(recogniser):
        sink = ListSink()
        result = run_trials(
            layout, method, 6, 40, seed=5, recogniser=recogniser, sink=sink, progress=False
        )
        return result.summary(), sink.batches, sink.substitutions

    with score_cache.disabled():
        alone = batches(load())
    assert score_cache.statistics()["columns"] == 0
    load()  # another cell's recogniser fills the store first
    shared = batches(load())
    assert score_cache.statistics()["hits"] > 0
    assert alone[0] == shared[0] and alone[2] == shared[2]
    assert_same(alone[1], shared[1])


def assert_same(a, b, where="batches"):
    """``a`` and ``b`` equal to the bit, through lists, dicts and arrays."""
    if isinstance(a, dict):
        assert a.keys() == b.keys(), where
        for key in a:
            assert_same(a[key], b[key], f"{where}.{key}")
    elif isinstance(a, list | tuple):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{where}[{i}]")
    else:
        x, y = np.asarray(a), np.asarray(b)
        assert x.dtype == y.dtype and x.shape == y.shape, where
        assert x.tobytes() == y.tobytes(), where


@pytest.mark.parametrize("kind", ["relation", "proto"])
def test_a_category_state_depends_on_its_members_not_their_order(files, kind):
    """The premise of keying columns by the multiset of members: the class state sums (or
    averages) them in one canonical order, so the same members in other positions score the same
    bits."""
    images, rn, pn = files
    cls, ckpt = (RelationRecogniser, rn) if kind == "relation" else (ProtoRecogniser, pn)
    with score_cache.disabled():
        rec = cls.from_files(ckpt, images, substitution_way=1)
    pictures = np.flatnonzero(rec.query_categories == 1)[:5]
    for run, order in ((0, pictures), (1, pictures[[3, 0, 4, 2, 1]])):
        rec.start_run(run, seed=0)
        for position, picture in enumerate(order):
            rec.replace(run, category=1, position=position, picture_id=int(picture))
    assert rec.support_members(0)[1].tolist() != rec.support_members(1)[1].tolist()
    assert rec.scores(0, np.arange(40)).tobytes() == rec.scores(1, np.arange(40)).tobytes()


# -- score files: the columns kept between runs ---------------------------------------------------
@pytest.fixture
def score_folder(tmp_path, monkeypatch):
    folder = tmp_path / "scores"
    monkeypatch.setenv(score_cache.CACHE_VARIABLE, str(folder))
    return folder


def test_a_trial_records_the_same_from_a_score_file_as_computed(files, score_folder):
    images, rn, _ = files
    layout, method = load_layout("7x7"), get_method("fewshot_dss")

    def batches():
        recogniser = RelationRecogniser.from_files(rn, images, substitution_way=2)
        sink = ListSink()
        result = run_trials(
            layout, method, 6, 40, seed=5, recogniser=recogniser, sink=sink, progress=False
        )
        return result.summary(), sink.batches, sink.substitutions

    cold = batches()
    computed = score_cache.statistics()["misses"]
    score_cache.save_all()
    assert len(list(score_folder.glob("*.npz"))) == 1
    score_cache.clear()  # as in a new process: nothing in memory
    warm = batches()
    assert score_cache.statistics()["loaded"] == computed > 5
    assert score_cache.statistics()["misses"] == 0
    assert cold[0] == warm[0] and cold[2] == warm[2]
    assert_same(cold[1], warm[1])


@pytest.mark.filterwarnings("error::ResourceWarning")  # the damaged file is closed too
def test_a_damaged_score_file_is_set_aside_and_written_anew(files, score_folder):
    images, rn, _ = files
    RelationRecogniser.from_files(rn, images)
    score_cache.save_all()
    (path,) = score_folder.glob("*.npz")
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    score_cache.clear()
    with pytest.warns(score_cache.ScoreCacheWarning, match="not a readable score file"):
        RelationRecogniser.from_files(rn, images)
    assert score_cache.statistics()["misses"] == 5
    score_cache.save_all()
    assert len(score_cache.read_columns(path)) == 5


def test_columns_another_process_wrote_meanwhile_are_kept(files, score_folder):
    images, rn, _ = files
    rec = RelationRecogniser.from_files(rn, images)
    score_cache.save_all()
    (path,) = score_folder.glob("*.npz")
    theirs = {(1, 2, 3, 4, 5): np.arange(40, dtype=np.float32)}
    score_cache.write_columns(path, score_cache.read_columns(path) | theirs)
    rec.start_run(0, seed=4)
    rec.replace(
        0, category=2, position=0, picture_id=int(np.flatnonzero(rec.query_categories == 2)[0])
    )
    rec.scores(0, np.arange(40))  # one new column
    score_cache.save_all()
    kept = score_cache.read_columns(path)
    assert len(kept) == 7
    np.testing.assert_array_equal(kept[1, 2, 3, 4, 5], theirs[1, 2, 3, 4, 5])


@pytest.mark.parametrize("off", ["off", "OFF", "0", "false", "no", "none"])
def test_off_keeps_the_scores_in_memory_only(files, monkeypatch, tmp_path, off):
    images, rn, _ = files
    monkeypatch.chdir(tmp_path)  # not a folder named after the word either
    monkeypatch.setenv(score_cache.CACHE_VARIABLE, off)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert score_cache.cache_folder() is None
    RelationRecogniser.from_files(rn, images)
    score_cache.save_all()
    assert not list(tmp_path.rglob("*.npz"))


def test_the_default_folder_follows_xdg_cache_home(monkeypatch, tmp_path):
    monkeypatch.delenv(score_cache.CACHE_VARIABLE)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert score_cache.cache_folder() == tmp_path / "fewshot-safe-rl" / "score-columns"


def test_another_kernel_path_is_another_score_file(monkeypatch):
    """A column's bits depend on the kernel path (pipeline/kernels.py): a process that took
    another never reads this one's columns."""
    key = score_cache.file_key("source")
    monkeypatch.setattr(score_cache, "kernel_path", lambda: "another path")
    assert score_cache.file_key("source") != key


def test_a_folder_that_cannot_be_written_costs_a_warning_not_the_run(files, monkeypatch, tmp_path):
    images, rn, _ = files
    not_a_folder = tmp_path / "file"
    not_a_folder.write_text("")
    monkeypatch.setenv(score_cache.CACHE_VARIABLE, str(not_a_folder))
    RelationRecogniser.from_files(rn, images)
    with pytest.warns(score_cache.ScoreCacheWarning, match="the score columns were not kept"):
        score_cache.save_all()


# -- a recogniser started from its score file (pipeline/fewshot/from_files.py) --------------------
def _refuse_loading(monkeypatch):
    def refuse(*args):
        raise AssertionError("the checkpoint and pictures were loaded")

    monkeypatch.setattr(from_files.Loaded, "read", refuse)


def test_a_recogniser_whose_columns_are_all_kept_loads_no_network(files, score_folder, monkeypatch):
    images, rn, _ = files
    cold = RelationRecogniser.from_files(rn, images, substitution_way=2)
    score_cache.save_all()
    score_cache.clear()
    _refuse_loading(monkeypatch)
    warm = RelationRecogniser.from_files(rn, images, substitution_way=2)
    assert warm.describe() == cold.describe()
    assert warm.class_names == cold.class_names
    np.testing.assert_array_equal(warm.query_categories, cold.query_categories)
    for rec in (cold, warm):
        rec.start_run(0, seed=3)
    assert warm.scores(0, np.arange(40)).tobytes() == cold.scores(0, np.arange(40)).tobytes()


def test_its_first_missing_column_loads_the_network_then(files, score_folder):
    images, rn, _ = files
    cold = RelationRecogniser.from_files(rn, images)
    score_cache.save_all()
    score_cache.clear()
    warm = RelationRecogniser.from_files(rn, images)
    picture = int(np.flatnonzero(cold.query_categories == 3)[0])
    for rec in (cold, warm):
        rec.start_run(0, seed=3)
        rec.replace(0, category=3, position=1, picture_id=picture)  # a column not in the file
    assert warm.scores(0, np.arange(40)).tobytes() == cold.scores(0, np.arange(40)).tobytes()
    assert score_cache.statistics()["misses"] == 1  # the warm one's (the cold one's store is gone)
    assert warm.checkpoint == cold.checkpoint
    assert warm.parts.keys() == cold.parts.keys()


def test_files_changed_under_a_started_recogniser_are_refused(files, score_folder, tmp_path):
    images, rn, _ = files
    checkpoint = tmp_path / "rn.pt"
    checkpoint.write_bytes(rn.read_bytes())
    RelationRecogniser.from_files(checkpoint, images)
    score_cache.save_all()
    score_cache.clear()
    warm = RelationRecogniser.from_files(checkpoint, images)
    checkpoint.write_bytes(checkpoint.read_bytes() + b"\0")
    warm.start_run(0, seed=3)
    warm.replace(0, category=4, position=1, picture_id=int(warm.query_categories.argmax()))
    with pytest.raises(DataError, match="changed while the recogniser was in use"):
        warm.scores(0, np.arange(40))


def test_other_files_are_another_score_file(files, score_folder, tmp_path):
    images, rn, _ = files
    RelationRecogniser.from_files(rn, images)
    copy = tmp_path / "images"
    shutil.copytree(images, copy)
    RelationRecogniser.from_files(rn, copy)  # the same bytes elsewhere: the same source
    assert score_cache.statistics()["misses"] == 5
    picture = next(p for p in sorted(copy.rglob("*.png")) if "query" in str(p))
    picture.write_bytes(next(p for p in sorted(copy.rglob("*.png")) if p != picture).read_bytes())
    RelationRecogniser.from_files(rn, copy)
    score_cache.save_all()
    assert score_cache.statistics()["misses"] == 10
    assert len(list(score_folder.glob("*.npz"))) == 2


def test_a_process_started_from_score_files_imports_no_torch(files, score_folder):
    """The point of starting from the score file: a study whose columns were all computed before
    pays neither torch's import nor the checkpoint (pipeline/threads.py gives the recorded thread
    count; pipeline/kernels.py the kernel path)."""
    images, rn, _ = files
    script = (
        "import sys\n"
        "from pipeline.kernels import pin_kernels\n"
        "from pipeline.threads import trials_budget\n"
        "pin_kernels(); trials_budget(0, 1).apply()\n"
        "from pipeline.fewshot.recogniser import RelationRecogniser\n"
        f"rec = RelationRecogniser.from_files({str(rn)!r}, {str(images)!r})\n"
        "rec.start_run(0, seed=1)\n"
        "print(rec.predictions(0).tolist(), rec.describe(), 'torch' in sys.modules)\n"
    )
    env = {**os.environ, score_cache.CACHE_VARIABLE: str(score_folder)}
    runs = [
        subprocess.run(
            [sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True
        ).stdout
        for _ in range(2)
    ]
    assert runs[0].endswith(" True\n") and runs[1].endswith(" False\n")
    assert runs[0].removesuffix(" True\n") == runs[1].removesuffix(" False\n")


def test_processes_saving_at_once_keep_each_others_columns(score_folder, monkeypatch):
    """A study's worker processes end together: each merges what the file holds with its own
    columns, one after the other (a lock), so neither loses the other's."""
    path = score_folder / "source.npz"
    stores = [score_cache.ColumnStore(path=path) for _ in range(2)]
    for i, store in enumerate(stores):
        store.column((i, i), lambda i=i: np.full(40, i, dtype=np.float32))
    read = score_cache.read_score_file

    def slow_read(*args, **kwargs):  # both would read before either writes, without the lock
        got = read(*args, **kwargs)
        time.sleep(0.3)
        return got

    monkeypatch.setattr(score_cache, "read_score_file", slow_read)
    savers = [threading.Thread(target=store.save) for store in stores]
    for saver in savers:
        saver.start()
    for saver in savers:
        saver.join()
    assert set(read(path)[0]) == {(0, 0), (1, 1)}


def test_a_subclass_elsewhere_keys_its_own_code(files, tmp_path, monkeypatch):
    """A recogniser class outside pipeline/fewshot scores with its own code: a change to its file
    is another source, so no column computed by the old code is read back."""
    images, rn, _ = files
    module = tmp_path / "my_recogniser.py"
    module.write_text(
        "from pipeline.fewshot.recogniser import RelationRecogniser\n\n\n"
        "class Mine(RelationRecogniser):\n    pass\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    from my_recogniser import Mine

    def source():
        from_files._code_and_versions.cache_clear()  # the code is read once a process
        return from_files.files_source(Mine, from_files.RecogniserFiles(rn, images))

    before = source()
    theirs = from_files.files_source(RelationRecogniser, from_files.RecogniserFiles(rn, images))
    assert before not in (None, theirs)
    module.write_text(module.read_text() + "\n# changed\n")
    assert source() != before


@pytest.mark.parametrize("shift", [float("nan"), float("inf")])
def test_a_hue_shift_that_is_no_number_of_degrees_is_refused(shift):
    """The files a recogniser is loaded from refuse a hue shift that turns no hue (before any
    file is read)."""
    with pytest.raises(ValueError, match="query_hue_shift must be a finite number of degrees"):
        from_files.RecogniserFiles("no.pt", "no-images", None, shift)


def test_columns_computed_in_worker_processes_are_kept(files, score_folder, tmp_path):
    """A trials stage with two workers: the columns its workers computed are in the score file
    when the stage returns (each worker saves its store as it ends; a worker killed instead
    would lose them, and the next run would load the network again)."""
    from pipeline.stages import run_stage

    images, rn, _ = files
    run_stage(
        "trials",
        [
            "+experiment=fig9",
            f"recogniser.checkpoint={rn}",
            f"recogniser.images_dir={images}",
            "recogniser.input_size=24",
            "recogniser.relation_padding=1",
            "runs=2",
            "episodes=5",
            "workers=2",
            "progress=false",
            f"out={tmp_path / 'out'}",
        ],
    )
    (kept,) = score_folder.glob("*.npz")
    columns, about = score_cache.read_score_file(kept)
    assert about is not None and len(columns) >= 5  # at least the original support set's
