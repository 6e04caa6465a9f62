"""Small deterministic recognisers and an in-memory episode sink for the tests."""

from __future__ import annotations

import numpy as np

from pipeline.rl.sink import split_batch
from pipeline.world.pictures import N_CATEGORIES, N_PICTURES, picture_category

TRUE = np.array([picture_category(p) for p in range(N_PICTURES)], dtype=np.int8)


class TableRecogniser:
    """Names the true category for pictures in ``correct`` and the next category otherwise.
    With ``dynamic=True`` a misrecognised picture is learnt (becomes correct) after a collision,
    a caricature of the dynamic support set."""

    def __init__(self, correct=(), dynamic=False):
        self.correct0 = set(correct)
        self.dynamic = dynamic
        self.correct: dict[int, set] = {}
        self.learnt: list[tuple[int, int, int]] = []

    def start_run(self, run, seed):
        self.correct[run] = set(self.correct0)

    def predictions(self, run):
        pred = (TRUE + 1) % N_CATEGORIES
        for p in self.correct[run]:
            pred[p] = TRUE[p]
        return pred.astype(np.int8)

    def scores(self, run, picture_ids):
        pred = self.predictions(run)
        out = np.full((len(picture_ids), N_CATEGORIES), 0.1, dtype=np.float32)
        out[np.arange(len(picture_ids)), pred[np.asarray(picture_ids, dtype=int)]] = 0.9
        return out

    def learn_from_collision(self, run, picture_id, true_category):
        self.learnt.append((run, picture_id, true_category))
        if not self.dynamic:
            return -1
        self.correct[run].add(picture_id)
        return len(self.learnt) % 5


def always_right():
    return TableRecogniser(correct=range(N_PICTURES))


def always_wrong():
    return TableRecogniser(correct=())


class ListSink:
    def __init__(self):
        self.batches: list[dict] = []
        self.all_episodes: list[dict] = []
        self.substitutions: list[dict] = []

    def episodes(self, **batch):
        self.batches.append(batch)
        self.all_episodes.extend(split_batch(batch))

    def substitution(self, **fields):
        self.substitutions.append(fields)

    def by_run(self, run):
        return sorted((e for e in self.all_episodes if e["run"] == run), key=lambda e: e["episode"])


#: fig8's Prototypical Network cells run their own recogniser group
#: (conf/recogniser/protonet.yaml), which needs the rendered pictures and the trained
#: model; these overrides give them the oracle, for the tests that run fig8 where neither exists
#: (CI's clean checkout).
FIG8_WITHOUT_MODELS = [
    f"experiment.cells.{cell}.recogniser_group=oracle"
    for cell in ("fewshot_protonet", "fewshot_dss_protonet")
]


#: The input normalisation of :func:`untrained_network`'s checkpoints.
SYNTHETIC_NORM = {"mean": [0.4, 0.4, 0.4], "std": [0.25, 0.25, 0.25]}


def untrained_network(root, kind: str = "relation_net"):
    """A synthetic picture set in ``root/images`` and an untrained 24 px network of ``kind``
    (``relation_net`` or ``protonet``) saved as ``root/<kind>.pt`` (seeded): what tests of the
    recognisers' plumbing need, without rendered pictures or a trained model. Returns
    ``(checkpoint, network)``."""
    import torch

    from pipeline.fewshot.checkpoint import save_checkpoint
    from pipeline.fewshot.model import ModelConfig, RelationNetwork
    from pipeline.fewshot.protonet import PrototypicalNetwork
    from pipeline.fewshot.settings import ProtoConfig
    from pipeline.fewshot.synthetic import write_synthetic_dataset

    if not (root / "images").exists():
        write_synthetic_dataset(root / "images", n_train=5, n_val=5, per_class=2, seed=1)
    torch.manual_seed(0)
    if kind == "relation_net":
        net = RelationNetwork(ModelConfig(24, 1))
        with torch.no_grad():
            net(torch.randn(5, 5, 3, 24, 24), torch.randn(10, 3, 24, 24))
    else:
        net = PrototypicalNetwork(ProtoConfig(24))
    net.eval()
    ckpt = save_checkpoint(
        root / f"{kind}.pt", net, normalisation=SYNTHETIC_NORM, config={}, metrics={}
    )
    return ckpt, net
