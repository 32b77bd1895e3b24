"""The package-to-order task episodes the reasoning module learns from and is scored on (Sec. 4.4.1): scenes of
chosen goal configurations with fresh random positions (:func:`~hrc_lab.env.robot.spec.sample_episode`), and the
stage observations they hold."""

from __future__ import annotations

import math

from hrc_lab.env.robot.spec import (
    Episode,
    PackageToOrderSpec,
    goal_configurations,
    sample_episode,
    stage_observations,
)


def episodes_for(spec, configurations, rng, repeats: int = 1, case: int = 1, n_missing=0) -> list[Episode]:
    """``repeats`` episodes of every configuration with fresh random positions; ``n_missing`` may be a callable
    drawing the number of absent products per episode."""
    draw = n_missing if callable(n_missing) else (lambda: n_missing)
    return [
        sample_episode(spec, configuration, rng, case=case, n_missing=draw())
        for configuration in configurations
        for _ in range(repeats)
    ]


def random_episodes(spec, n: int, rng, case: int = 1, n_missing=0) -> list[Episode]:
    """``n`` episodes of goal configurations drawn uniformly from all of them."""
    configurations = goal_configurations(spec)
    chosen = rng.integers(len(configurations), size=n)
    return episodes_for(spec, [configurations[i] for i in chosen], rng, case=case, n_missing=n_missing)


def demo_repeats(spec: PackageToOrderSpec, min_demos: int) -> int:
    """Repeats of every goal configuration so that a full demo set has at least ``min_demos`` episodes."""
    return max(1, math.ceil(min_demos / len(goal_configurations(spec))))


def observations_of(episodes: list[Episode]) -> list:
    """The stage observations of every episode, in order: what a reasoner is trained and predicts on."""
    return [obs for episode in episodes for obs in stage_observations(episode)]
