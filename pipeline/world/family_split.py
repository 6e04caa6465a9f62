"""The meta-training families' split: train / validation / test, held apart by a structural distance.

Ravi and Larochelle split miniImageNet's 100 classes 64 / 16 / 20: training classes, validation
classes that pick the checkpoint, and test classes that give the quoted accuracy. Our classes are
procedural families (``metaset.py``), and two families drawn independently can be near-twins (the
same part kinds in reversed order, or the same tiers with a handle added): a validation or test
family that twins a training family measures memory, not few-shot learning. So families are
compared by their *structure*: every validation and test family is kept at least
``min_distance`` from every training family, and every test family that far from every validation
family as well (a test family that twins a validation family would be measured on a class the
checkpoint was chosen on).

:func:`family_distance` of two families is the sum of

* the tiers: the cheapest matching of one family's tiers to the other's, *in any order* (so a
  reversed stack is no different), where matching two tiers costs the Jaccard distance of their
  allowed part kinds (0 for the same kinds, 1 for none shared) and a tier left unmatched costs 1;
* 1 if the legs differ (none, a pedestal, a ring of legs), 1 if one has radial arms and the other
  not, 1 if one has a side handle and the other not.

Proportions, leg and arm counts and colours are what instances of one family vary in, so they do
not count. With ``min_distance`` 2 (``render.yaml``'s ``min_family_distance``) a held-out family
differs from every training family by at least two whole parts: a tier of another kind and the
legs, say, or an extra tier and a handle. No two families are further apart than
:data:`MAX_DISTANCE` (4 tiers, legs, arms, handle), so a larger ``min_distance`` is refused at
once; so is a split for which :data:`MAX_MISSES` draws in a row give no family far enough.
"""

from __future__ import annotations

from collections.abc import Iterator
from itertools import permutations

from pipeline.config.fields import refuse
from pipeline.world.metaset import MAX_TIERS, Family, family_stream

#: The default least distance between a held-out (validation or test) family and every training family.
MIN_DISTANCE = 2.0
#: The largest distance of two families: every tier unmatched or unlike, legs, arms and handle.
MAX_DISTANCE = MAX_TIERS + 3.0
#: Draws in a row without a family far enough from the training families that end the search.
MAX_MISSES = 2000


def tier_distance(a: tuple[str, ...], b: tuple[str, ...]) -> float:
    """Jaccard distance of two tiers' allowed part kinds: 0 the same kinds, 1 none shared."""
    sa, sb = set(a), set(b)
    return 1.0 - len(sa & sb) / len(sa | sb)


def tiers_distance(a: list[tuple[str, ...]], b: list[tuple[str, ...]]) -> float:
    """The cheapest matching of the tiers of ``a`` to those of ``b`` in any order; a tier left
    unmatched costs 1 (families have at most 4 tiers: every matching is tried)."""
    if len(a) > len(b):
        a, b = b, a
    best = float(len(b))
    for chosen in permutations(range(len(b)), len(a)):
        cost = sum(tier_distance(a[i], b[j]) for i, j in enumerate(chosen))
        best = min(best, cost + len(b) - len(a))
    return best


def family_distance(a: Family, b: Family) -> float:
    """The structural distance of two families (module docstring); symmetric, 0 for twins."""
    return (
        tiers_distance([t.kinds for t in a.tiers], [t.kinds for t in b.tiers])
        + float(a.leg_style != b.leg_style)
        + float((a.arm_counts != (0,)) != (b.arm_counts != (0,)))
        + float(a.handle != b.handle)
    )


def nearest_distance(family: Family, others: list[Family]) -> float:
    """The distance from ``family`` to the nearest of ``others`` (infinite if there are none)."""
    return min((family_distance(family, o) for o in others), default=float("inf"))


def far_from_all(family: Family, others: list[Family], min_distance: float) -> bool:
    """Whether ``family`` is at least ``min_distance`` from each of ``others`` (stops at the first
    that is nearer)."""
    return all(family_distance(family, o) >= min_distance for o in others)


def split_families(
    n_train: int, n_val: int, n_test: int, seed: int, min_distance: float = MIN_DISTANCE
) -> dict[str, list[Family]]:
    """Training, validation and test families, deterministic in ``seed``: the first ``n_train``
    families of :func:`~pipeline.world.metaset.family_stream`, then the next ``n_val`` that are at
    least ``min_distance`` from every training family (validation), then the next ``n_test`` that
    are that far from every training and every validation family (test), in the order drawn. Refuses (:class:`~pipeline.errors.ConfigError`, naming the render
    stage's key) a ``min_distance`` over :data:`MAX_DISTANCE`, and a split the grammar cannot give:
    :data:`MAX_MISSES` draws in a row, or 200 per held-out family in all, without one far enough."""
    for name, n in (("train", n_train), ("validation", n_val), ("test", n_test)):
        if n < 0:
            raise ValueError(f"number of {name} classes must be >= 0, got {n}")
    if min_distance < 0:
        raise ValueError(f"min_distance must be >= 0, got {min_distance}")
    n_held = n_val + n_test
    kept_apart = (n_train and n_held) or (n_val and n_test)
    if kept_apart and not min_distance <= MAX_DISTANCE:
        refuse(
            "min_family_distance",
            f"no two families are further apart than "
            f"{MAX_DISTANCE:g} ({MAX_TIERS} tiers, legs, arms, handle); got {min_distance}: "
            "lower min_family_distance",
        )
    stream: Iterator[Family] = family_stream(seed)
    train = [next(stream) for _ in range(n_train)]
    val = _draw_apart(stream, n_val, train, min_distance, "validation", n_held)
    test = _draw_apart(stream, n_test, train + val, min_distance, "test", n_held)
    return {"train": train, "val": val, "test": test}


def _draw_apart(
    stream: Iterator[Family],
    n: int,
    apart_from: list[Family],
    min_distance: float,
    split: str,
    n_held: int,
) -> list[Family]:
    """The next ``n`` families of ``stream`` at least ``min_distance`` from each of ``apart_from``
    (in the order drawn); refuses, naming ``min_family_distance``, when :data:`MAX_MISSES` draws in
    a row, or 200 per held-out family of the split (``n_held`` in all) in all, give none."""
    chosen: list[Family] = []
    tries, misses, limit = 0, 0, 200 * (n_held + 1)
    while len(chosen) < n:
        tries += 1
        misses += 1
        if tries > limit or misses > MAX_MISSES:
            refuse(
                "min_family_distance",
                f"only {len(chosen)} of {n} {split} "
                f"families are at distance >= {min_distance} from the {len(apart_from)} families "
                f"drawn before them (none in the last {misses - 1} of {tries - 1} draws); lower "
                "min_family_distance or the number of classes",
            )
        fam = next(stream)
        if far_from_all(fam, apart_from, min_distance):
            chosen.append(fam)
            misses = 0
    return chosen
