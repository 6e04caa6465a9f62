"""Hostile checkpoints. Files that are not checkpoints, of the other network or of another shape, and
checkpoints that load but cannot score (docs/reliability.md "Checkpoints and image folders"): a
normalisation that is empty, of the wrong shape or not finite, weights that are NaN, infinite, of
another type or missing, and a network whose scores of the probe episode are not finite. Each is
refused on load with one line naming the file and the problem (:class:`CheckpointError`), and the
file is left as it was. Tiny networks (24 px), as in tests/test_fewshot_checkpoint.py."""

from __future__ import annotations

import math

import pytest
import torch
from entry import cli

from faults._checks import FAST, one_line_error
from pipeline.errors import UserError
from pipeline.fewshot.checkpoint import CheckpointError, load_checkpoint, probe, save_checkpoint
from pipeline.fewshot.model import ModelConfig, RelationNetwork
from pipeline.fewshot.protonet import PrototypicalNetwork
from pipeline.fewshot.settings import ProtoConfig
from pipeline.stages import run_stage

NORM = {"mean": [0.5, 0.4, 0.3], "std": [0.2, 0.2, 0.2]}
FC1 = "relation.fc1.weight"
RUNNING_VAR = "embedding.layers.0.1.running_var"


@pytest.fixture(scope="module")
def payloads(tmp_path_factory):
    """A good Relation Network and Prototypical Network checkpoint's payloads."""
    root = tmp_path_factory.mktemp("checkpoints")
    torch.manual_seed(3)
    out = {}
    for kind, net in (
        ("relation_net", RelationNetwork(ModelConfig(24, 1))),
        ("protonet", PrototypicalNetwork(ProtoConfig(24))),
    ):
        path = save_checkpoint(
            root / f"{kind}.pt", net.eval(), normalisation=NORM, config={}, metrics={}
        )
        out[kind] = torch.load(path, weights_only=True)
    return out


def _set(entry, key, value):
    def damage(p):
        p[entry][key] = value(p[entry][key]) if callable(value) else value

    return damage


def _weights(change, name=None):
    """Apply ``change`` to every floating weight (or to the weight ``name`` only)."""

    def damage(p):
        for k, v in p["state_dict"].items():
            if (name is None and v.is_floating_point()) or k == name:
                p["state_dict"][k] = change(v.clone())

    return damage


def _one_nan(v):
    v.view(-1)[0] = math.nan
    return v


def _drop(entry, key=None):
    def damage(p):
        del (p if key is None else p[entry])[entry if key is None else key]

    return damage


def _replace(entry, value):
    def damage(p):
        p[entry] = value

    return damage


#: id -> (damage to the payload, what the one line must say)
CASES = {
    "empty normalisation": (
        _replace("normalisation", {}),
        "normalisation without 'mean' and 'std'",
    ),
    "no normalisation": (_drop("normalisation"), r"lacks required entries"),
    "normalisation without std": (_drop("normalisation", "std"), "without 'mean' and 'std'"),
    "empty mean": (_set("normalisation", "mean", []), "'mean' of 0 values, expected 3"),
    "four stds": (_set("normalisation", "std", [0.2] * 4), "'std' of 4 values, expected 3"),
    "nested mean": (_set("normalisation", "mean", [NORM["mean"]]), "'mean' of 1 values"),
    "mean a tensor": (
        _set("normalisation", "mean", torch.tensor(NORM["mean"])),
        "'mean' of type Tensor",
    ),
    "mean a number": (_set("normalisation", "mean", 0.5), "'mean' of type float"),
    "NaN mean": (
        _set("normalisation", "mean", [math.nan, 0.4, 0.3]),
        "'mean' that is not 3 finite",
    ),
    "infinite std": (
        _set("normalisation", "std", [0.2, math.inf, 0.2]),
        "'std' that is not 3 finite",
    ),
    "text std": (_set("normalisation", "std", ["0.2", "0.2", "0.2"]), "'std' that is not 3 finite"),
    "boolean std": (_set("normalisation", "std", [True, True, True]), "'std' that is not 3 finite"),
    "zero std": (_set("normalisation", "std", [0.2, 0.0, 0.2]), "'std' that is not positive"),
    "negative std": (_set("normalisation", "std", [-0.2, 0.2, 0.2]), "'std' that is not positive"),
    "all weights NaN": (_weights(lambda v: v.fill_(math.nan)), r"NaN and 0 infinite values"),
    "all weights inf": (_weights(lambda v: v.fill_(math.inf)), r"with 0 NaN and \d+ infinite"),
    "one NaN in one layer": (_weights(_one_nan, FC1), rf"'{FC1}' with 1 NaN and 0 infinite"),
    "one -inf in a running variance": (
        _weights(lambda v: v.index_fill_(0, torch.tensor([5]), -math.inf), RUNNING_VAR),
        rf"'{RUNNING_VAR}' with 0 NaN and 1 infinite",
    ),
    "negative running variance": (
        _weights(lambda v: v.fill_(-1.0), RUNNING_VAR),
        "scores that are not finite on a probe episode",
    ),
    "float64 weights": (
        _weights(lambda v: v.double(), FC1),
        "of type torch.float64, expected torch.float32",
    ),
    "float16 weights": (
        _weights(lambda v: v.half(), FC1),
        "of type torch.float16, expected torch.float32",
    ),
    "integer weights": (
        _weights(lambda v: v.long(), FC1),
        "of type torch.int64, expected torch.float32",
    ),
    "weight a list": (_weights(lambda v: v.tolist(), FC1), f"'{FC1}' of type list, not a tensor"),
    "weights a list": (_replace("state_dict", [1.0]), "weights of type list, not a mapping"),
    "missing weight": (_drop("state_dict", FC1), rf"does not match .*Missing key\(s\).*{FC1}"),
    "extra weight": (
        _set("state_dict", "relation.fc3.weight", torch.zeros(1)),
        r"Unexpected key\(s\).*relation\.fc3\.weight",
    ),
    "wrong weight shape": (_weights(lambda v: v[:, :-1], FC1), rf"does not match .*{FC1}"),
    "format a list": (_replace("format", ["relation-network/1"]), "has format"),
}


@pytest.mark.parametrize("case", CASES)
def test_a_checkpoint_that_cannot_score_is_refused_in_one_line(payloads, tmp_path, case):
    damage, said = CASES[case]
    payload = {
        k: (dict(v) if isinstance(v, dict) else v) for k, v in payloads["relation_net"].items()
    }
    damage(payload)
    path = tmp_path / "damaged.pt"
    torch.save(payload, path)
    before = path.read_bytes()
    with pytest.raises(CheckpointError, match=said) as caught:
        load_checkpoint(path, ModelConfig(24, 1))
    message = str(caught.value)
    assert message.startswith(f"checkpoint {path} ") and "\n" not in message
    assert path.read_bytes() == before  # the file is left as it was


#: The Prototypical Network's cases (it has no relation module: a layer of its embedding).
LAYER = "embedding.layers.3.0.weight"
PROTO_CASES = {
    "empty normalisation": CASES["empty normalisation"],
    "all weights NaN": CASES["all weights NaN"],
    "one NaN in one layer": (_weights(_one_nan, LAYER), rf"'{LAYER}' with 1 NaN"),
    "float64 weights": (_weights(lambda v: v.double(), LAYER), "of type torch.float64"),
}


@pytest.mark.parametrize("case", PROTO_CASES)
def test_a_prototypical_network_checkpoint_is_checked_the_same_way(payloads, tmp_path, case):
    damage, said = PROTO_CASES[case]
    payload = {k: (dict(v) if isinstance(v, dict) else v) for k, v in payloads["protonet"].items()}
    damage(payload)
    path = tmp_path / "protonet.pt"
    torch.save(payload, path)
    with pytest.raises(CheckpointError, match=said):
        load_checkpoint(path, ProtoConfig(24), kind="protonet")


def test_the_probe_is_fixed_and_leaves_the_global_random_state_alone(payloads, tmp_path):
    path = tmp_path / "good.pt"
    torch.save(payloads["relation_net"], path)
    network, _ = load_checkpoint(path, ModelConfig(24, 1))
    state = torch.get_rng_state()
    scores = probe(network)
    assert torch.equal(torch.get_rng_state(), state)  # the probe draws no global random number
    assert scores.shape == (2, 2) and bool(torch.isfinite(scores).all())
    assert torch.equal(scores, probe(network))


def test_the_trials_stage_refuses_a_nan_checkpoint_before_touching_out(payloads, tmp_path):
    payload = dict(payloads["relation_net"])
    _weights(lambda v: v.fill_(math.nan))(payload)
    path = tmp_path / "nan.pt"
    torch.save(payload, path)
    args = [
        "method=fewshot",
        "recogniser=relation_net",
        f"recogniser.checkpoint={path}",
        "recogniser.input_size=24",
        "recogniser.relation_padding=1",
        f"recogniser.images_dir={tmp_path / 'images'}",
        f"out={tmp_path / 'out'}",
        "runs=1",
        "episodes=1",
        "progress=false",
    ]
    with pytest.raises(UserError, match=rf"checkpoint {path} has weight '.*' with \d+ NaN"):
        run_stage("trials", args)
    assert not (tmp_path / "out").exists()
    done = cli("trials", *args)  # the command line: one line, exit 2
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.count("\n") == 1 and done.stderr.startswith("error: ")
    assert "NaN" in done.stderr and str(path) in done.stderr


# ------------------------------------------------------- through the command line
@pytest.fixture(scope="module")
def tiny_model(tmp_path_factory):
    from pipeline.fewshot.synthetic import write_synthetic_dataset
    from pipeline.stages import run_stage

    d = tmp_path_factory.mktemp("model")
    write_synthetic_dataset(d / "images", n_train=6, n_val=5, per_class=8, seed=1)
    run_stage(
        "meta_train",
        [
            f"images_dir={d / 'images'}",
            f"checkpoint={d}/rn.pt",
            f"metrics_file={d}/metrics.json",
            f"history_file={d}/h.csv",
            "train.input_size=24",
            "train.relation_padding=1",
            "train.episodes=4",
            "train.val_every=2",
            "train.val_episodes=2",
            "train.eval_episodes=4",
            "train.n_query=2",
            "train.eval_queries=2",
            "progress=false",
        ],
    )
    return d


def _with_model(d, *extra):
    return [
        "method=fewshot",
        f"recogniser.images_dir={d / 'images'}",
        "recogniser.input_size=24",
        "recogniser.relation_padding=1",
        *FAST,
        *extra,
    ]


def test_a_small_model_runs_and_is_named_in_the_records(tiny_model, tmp_path):
    from pipeline.fewshot.checkpoint import file_sha256
    from pipeline.records import read_records

    out = cli(
        "trials",
        *_with_model(tiny_model, f"recogniser.checkpoint={tiny_model}/rn.pt", f"out={tmp_path}"),
    )
    assert out.returncode == 0, out.stderr
    info = read_records(tmp_path / "records.mcap", pictures=False).meta.info["info"]["recogniser"]
    assert info["checkpoint"]["sha256"] == file_sha256(tiny_model / "rn.pt")
    assert info["checkpoint"]["model"] == {"input_size": 24, "relation_padding": 1}


@pytest.mark.parametrize(
    "make,words",
    [
        (lambda p, good: p.write_bytes(b""), ["corrupt or not a torch checkpoint"]),
        (
            lambda p, good: p.write_bytes(good.read_bytes()[: len(good.read_bytes()) // 2]),
            ["corrupt"],
        ),
        (lambda p, good: p.write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 100), ["corrupt"]),
        (lambda p, good: None, ["does not exist"]),
    ],
)
def test_bad_checkpoints(tiny_model, tmp_path, make, words):
    bad = tmp_path / "bad.pt"
    make(bad, tiny_model / "rn.pt")
    one_line_error(
        cli(
            "trials",
            *_with_model(tiny_model, f"recogniser.checkpoint={bad}", f"out={tmp_path / 'o'}"),
        ),
        "config key 'recogniser'",
        str(bad),
        *words,
    )
    assert not (tmp_path / "o").exists()


def test_a_bad_checkpoint_stops_workers_before_any_folder(tiny_model, tmp_path):
    """With workers, each recogniser is built in a worker first: the same one line, no ``out``."""
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"")
    args = [a for a in _with_model(tiny_model, f"recogniser.checkpoint={bad}") if "method" not in a]
    out = tmp_path / "o"
    one_line_error(
        cli("trials", "+experiment=fig9", "workers=2", f"out={out}", *args),
        "config key 'recogniser'",
        str(bad),
        "corrupt or not a torch checkpoint",
    )
    assert not out.exists()


def test_a_checkpoint_of_another_shape_is_refused(tiny_model, tmp_path):
    args = _with_model(tiny_model, f"recogniser.checkpoint={tiny_model}/rn.pt", f"out={tmp_path}")
    args = [a for a in args if not a.startswith("recogniser.input_size")]  # the config expects 48
    one_line_error(
        cli("trials", *args), "config key 'recogniser'", "was trained for", "input_size=24"
    )


def test_an_images_folder_without_a_manifest(tiny_model, tmp_path):
    one_line_error(
        cli(
            "trials",
            "method=fewshot",
            f"recogniser.images_dir={tmp_path}",
            f"recogniser.checkpoint={tiny_model}/rn.pt",
            "recogniser.input_size=24",
            "recogniser.relation_padding=1",
            f"out={tmp_path / 'o'}",
            *FAST,
        ),
        "no picture manifest",
    )
