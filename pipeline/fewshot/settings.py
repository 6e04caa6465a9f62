"""The few-shot module's settings as plain dataclasses (no torch import): the networks' shapes
(:class:`ModelConfig` for the Relation Network, with the feature-map sizes it implies;
:class:`ProtoConfig` for the Prototypical Network), the meta-training hyperparameters
(:class:`TrainConfig`, whose ``model`` chooses between them) and the accuracy study's
(:class:`StudyConfig`, :mod:`.accuracy_study`). The stage schemas (``pipeline/schemas/``) type
``conf/meta_train.yaml`` and ``conf/accuracy.yaml`` with them, so checking a config never loads torch.
"""

from __future__ import annotations

from dataclasses import dataclass

from pipeline.config.fields import check, refuse, setting

CHANNELS = 64
HIDDEN = 8


@dataclass(frozen=True)
class ModelConfig:
    """Shape of the network: the input side in pixels and the padding of g_phi's convolutions."""

    input_size: int = 84
    """Square input side in pixels (pictures are resized to it)."""
    relation_padding: int = 0
    """Padding of g_phi's 3x3 convolutions: 0 as in Sung et al.; 1 for inputs below 46 px."""

    def __post_init__(self) -> None:
        if self.relation_padding not in (0, 1):
            raise ValueError(f"relation_padding must be 0 or 1, got {self.relation_padding}")
        feature_shapes(self.input_size, self.relation_padding)  # raises on impossible sizes


def _conv_out(size: int, padding: int) -> int:
    return size + 2 * padding - 2


def feature_shapes(input_size: int, relation_padding: int = 0) -> dict[str, int]:
    """Spatial sizes implied by ``input_size``: ``embedding`` (side of f_varphi's 64-channel map),
    ``relation`` (side after g_phi's second block) and ``fc_in`` (FC-8 input features)."""
    if input_size < 10:
        raise ValueError(f"input_size={input_size} is too small for Conv-4 (need >= 10 px)")
    s = _conv_out(input_size, 0) // 2  # block 1: conv (no pad) + pool
    s = _conv_out(s, 0) // 2  # block 2: conv (no pad) + pool
    embedding = s  # blocks 3 and 4 keep the size (padding 1)
    r = _conv_out(s, relation_padding) // 2
    r = _conv_out(r, relation_padding) // 2
    if r < 1:
        raise ValueError(
            f"input_size={input_size} with relation_padding={relation_padding} leaves an empty "
            f"relation map (embedding {embedding}x{embedding}); use input_size >= 46 or relation_padding=1"
        )
    return {"embedding": embedding, "relation": r, "fc_in": CHANNELS * r * r}


@dataclass(frozen=True)
class ProtoConfig:
    """Shape of the Prototypical Network: only the input side (the embedding is the Relation
    Network's Conv-4 f_varphi, flattened; :mod:`.protonet`)."""

    input_size: int = 84
    """Square input side in pixels (pictures are resized to it)."""

    def __post_init__(self) -> None:
        feature_shapes(self.input_size, 1)  # raises below Conv-4's minimum

    @property
    def embedding_dim(self) -> int:
        """Length of a flattened embedding: 64 x s x s (6400 at 48 px)."""
        s = feature_shapes(self.input_size, 1)["embedding"]
        return CHANNELS * s * s


LR_SCHEDULES = ("constant", "cosine", "step")
#: The few-shot networks ``train.model`` chooses from (and the ``kind`` a checkpoint names).
MODELS = ("relation_net", "protonet")


@dataclass
class TrainConfig:
    """Meta-training hyperparameters (every field is a key of ``conf/meta_train.yaml``'s ``train``)."""

    model: str = setting("relation_net", choices=MODELS)
    """``relation_net`` (Sung et al. 2018, MSE on relation scores) or ``protonet`` (Snell et al.
    2017, cross-entropy on negative squared distances to the class prototypes)."""
    input_size: int = setting(48, ge=10)
    """Square input side in pixels; pictures are resized to it (see :mod:`.model` for map sizes)."""
    relation_padding: int = setting(0, choices=(0, 1))
    """Padding of g_phi's convolutions (0 as in Sung et al.; 1 needed below 46 px); relation_net
    only: ``protonet`` has no g_phi and refuses any value but 0."""
    n_way: int = setting(5, ge=2)
    """Classes per episode (C)."""
    k_shot: int = setting(5, ge=1)
    """Support pictures per class (K); their feature maps are summed."""
    n_query: int = setting(5, ge=1)
    """Query pictures per class in a training episode."""
    episodes: int = setting(1500, ge=1)
    """Training episodes (the loop also stops at ``max_minutes``)."""
    lr: float = setting(1e-3, gt=0.0)
    """Adam learning rate at the start."""
    lr_schedule: str = setting("cosine", choices=LR_SCHEDULES)
    """``constant``, ``cosine`` (to ``lr * min_lr_fraction`` at ``episodes``) or ``step`` (halve every ``lr_step``)."""
    min_lr_fraction: float = setting(0.05, gt=0.0, le=1.0)
    """Final learning rate of the cosine schedule, as a fraction of ``lr``."""
    lr_step: int = setting(1000, ge=1)
    """Episodes between halvings of the ``step`` schedule."""
    flip: bool = True
    """Random horizontal flips of training pictures."""
    val_every: int = setting(150, ge=1)
    """Training episodes between model-selection evaluations on the validation classes."""
    val_episodes: int = setting(200, ge=1)
    """Validation episodes per model-selection evaluation (a fixed, seeded list)."""
    eval_episodes: int = setting(600, ge=1)
    """Fresh validation episodes for the reported accuracy and its 95% interval."""
    eval_queries: int = setting(15, ge=1)
    """Query pictures per class in validation episodes."""
    seed: int = setting(0, ge=0)
    """Seeds the weights, the episode stream and the flips."""
    channels_last: bool = True
    """Use the channels-last memory format (faster convolutions on the CPU)."""
    max_minutes: float = setting(12.5, gt=0.0)
    """Wall-clock budget of the training loop; training stops early when it is spent (a safety
    net: a run it cuts depends on the machine's load, and its ``train_info`` says so)."""
    target_accuracy: float = setting(0.75, ge=0.0, le=1.0)
    """Validation accuracy goal; the time when a selection evaluation first reaches it is recorded."""

    def __post_init__(self) -> None:
        check(self, "train.")
        if self.model == "protonet" and self.relation_padding != 0:
            refuse(
                "train.relation_padding",
                f"{self.relation_padding} means nothing to the "
                "Prototypical Network (it has no relation module g_phi); leave it out (0) with train.model=protonet",
            )
        self.network_config()

    def network_config(self) -> ModelConfig | ProtoConfig:
        """The shape of the network ``model`` names."""
        if self.model == "protonet":
            return ProtoConfig(self.input_size)
        return ModelConfig(self.input_size, self.relation_padding)


#: Hue rotations of the colour test (degrees, :mod:`.colour`): five turns spread round the colour
#: circle.
HUE_SHIFTS = (60.0, 120.0, 180.0, 240.0, 300.0)


@dataclass
class StudyConfig:
    """Accuracy-study settings (``conf/accuracy.yaml``'s ``study``)."""

    repeats: int = setting(100, ge=1)
    """Repetitions per substituted category (the paper: 100, giving x/800)."""
    seed: int = setting(0, ge=0)
    """Seeds the random choice of pictures and positions."""
    hue_shifts: list[float] = setting(default_factory=lambda: list(HUE_SHIFTS))
    """The colour test's hue rotations of the query pictures, degrees (:mod:`.colour`); [] skips it."""
    family_episodes: int = setting(300, ge=0)
    """Fresh episodes per held-out split (validation, test) for their accuracy with intervals over
    episodes and over families (``families.csv``, :mod:`.family_accuracy`); 0 skips it."""
