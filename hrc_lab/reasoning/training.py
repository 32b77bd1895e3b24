"""Training a ``reasoning`` model of a run's config (``REASONERS.build``): Ch.4's reasoning module on the stage
observations of task episodes (as Table 4.1; also Table 4.3's reasoning) and Ch.5's graph semantic planner on
assembly scenarios (5.2.2; Fig. 5.7, Table 5.2). ``trainer(prefix)`` gives the fit its Lightning Trainer
(:meth:`hrc_lab.run_context.RunContext.trainer`: per-epoch metrics and checkpoints under ``prefix``)."""

from __future__ import annotations

import time
from collections.abc import Callable

from hrc_lab.env.assembly.spec import AssembleToOrderSpec, Scenario
from hrc_lab.env.robot.spec import Episode, PackageToOrderSpec
from hrc_lab.reasoning import REASONERS
from hrc_lab.reasoning.base import Reasoner
from hrc_lab.reasoning.episodes import observations_of
from hrc_lab.reasoning.semantic_planner import SemanticPlanner


def train(cfg, spec: PackageToOrderSpec, episodes: list[Episode], trainer: Callable, seed: int,
          prefix: str = "") -> tuple[Reasoner, float]:
    """The reasoner of the ``reasoning`` config ``cfg`` fitted on the stage observations of ``episodes``, and the
    seconds the fit took."""
    reasoner = REASONERS.build(cfg, spec=spec, seed=seed)
    start = time.perf_counter()
    reasoner.fit(observations_of(episodes), trainer(prefix))
    return reasoner, time.perf_counter() - start


def train_planner(cfg, spec: AssembleToOrderSpec, train: list[Scenario], trainer: Callable, seed: int,
                  prefix: str = "") -> SemanticPlanner:
    """The graph semantic planner of the ``reasoning`` config ``cfg`` fitted on the scenarios ``train``."""
    planner = REASONERS.build(cfg, spec=spec, seed=seed)
    planner.fit(train, trainer(prefix))
    return planner
