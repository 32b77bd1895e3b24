"""Identity augmentation of package-to-order stage observations (hrc_lab's, not the thesis'; ``reasoning=hrc``).

The expert of Sec. 4.4.1 packs the lowest-numbered selected, unpacked product first (CASE 1; CASE 2 continues the
same way after the human), so a stage's labels depend on the product numbers only through the order of the
selected products that are still to be packed. Where a product stands, which number an unselected or an already
packed product has, and which product comes first in the chain graph of Sec. 4.2.1 carry no information for P_o or
P_g. A training set of a few selections does not show this: in Fig. 4.7 CASE 1, 4of5 at λ = 0.8, seeds 2 and 3 hold
out the one selection without product 1, so every demonstration has product 1 selected and packed first, and
"product 1 first, then the lowest-numbered selected one" fits every demonstration as well as the expert's rule.

:func:`relabel` renumbers the products of an observation with a permutation that keeps the order of the selected,
unpacked products (so the labels stay the expert's) and puts every other product, packed or unselected, at a
random number; the products waiting in the pending area swap places at random, so that a pending cell names no
product either. The relabelled observation is another scene the expert would label the same way: an unselected
product may come first in the chain, and packed sets need not be prefixes of the selection (as after CASE 2's
human).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from hrc_lab.env.robot.spec import PLACE, StageObservation

PER_PRODUCT = ("positions", "present", "selected", "packed", "goal_slot")  # StageObservation's (m, ...) arrays


def order_keeping_permutation(to_pack: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """(m,) new number of every product: the products flagged in ``to_pack`` keep their relative order, every
    other product gets a random number among the rest."""
    m = len(to_pack)
    numbers = rng.permutation(m)
    kept = np.flatnonzero(to_pack)
    sigma = np.empty(m, dtype=int)
    sigma[kept] = np.sort(numbers[: len(kept)])
    sigma[np.flatnonzero(~to_pack)] = numbers[len(kept):]
    return sigma


def relabel(obs: StageObservation, rng: np.random.Generator) -> StageObservation:
    """``obs`` with its products renumbered by :func:`order_keeping_permutation` of the selected products still
    to be packed (the held one included), and the positions of the present products in the pending area (not
    packed, not held) shuffled among them. The labels are the expert's for the new numbering: the same P_g label and
    stage, P_o pointing at the renumbered target at a picking stage."""
    to_pack = obs.selected & ~obs.packed
    sigma = order_keeping_permutation(to_pack, rng)
    arrays = {}
    for key in PER_PRODUCT:
        value = getattr(obs, key)
        renumbered = np.empty_like(value)
        renumbered[sigma] = value
        arrays[key] = renumbered
    held = int(sigma[obs.held]) if obs.held >= 0 else -1
    target = int(sigma[obs.target])
    waiting = np.flatnonzero(arrays["present"] & ~arrays["packed"] & (np.arange(len(sigma)) != held))
    positions = arrays["positions"].copy()
    positions[waiting] = arrays["positions"][rng.permutation(waiting)]
    arrays["positions"] = positions
    return dataclasses.replace(obs, **arrays, target=target, held=held,
                               o_label=0 if obs.stage == PLACE else 1 + target)


def augmented(observations: list[StageObservation], copies: int, seed: int) -> list[StageObservation]:
    """The observations followed by ``copies`` relabelled copies of each (:func:`relabel`, one stream per seed)."""
    rng = np.random.default_rng([seed, 45])
    return observations + [relabel(obs, rng) for _ in range(copies) for obs in observations]
