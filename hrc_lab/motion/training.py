"""Training the two-level planners from the expert's demonstrations (:mod:`hrc_lab.motion.demonstrations`): Ch.3's
task classifier c(x), sub-goal planner and neural dynamic planner (3.2, as Table 3.1 and Algorithm 1's guide use
them) and Ch.4's motion module (4.2.2; Table 4.2 and ours in Table 4.3).

``trainer(prefix)`` gives each fit its Lightning Trainer (:meth:`hrc_lab.run_context.RunContext.trainer`:
per-epoch metrics and checkpoints under ``prefix``); ``motion`` is the run's ``motion`` config."""

from __future__ import annotations

from collections.abc import Callable

from hrc_lab.motion import MOTIONS


def train_two_level(motion, env, demos, stage_starts: tuple[str, ...], subgoals_per_stage: int,
                    trainer: Callable, seed: int):
    """Task classifier c(x), sub-goal planner (observing ``motion.planner_input``, see
    :func:`~hrc_lab.motion.two_level.correction_input`; pairs from the stage starts ``stage_starts``) and neural
    dynamic planner (joint limit and base frame of the error-correction cell ``env``) from the demonstrations."""
    from hrc_lab.motion.subgoal import DynamicPlanner, StageClassifier
    from hrc_lab.motion.two_level import classifier_pairs, correction_pairs, dynamics_pairs

    classifier = StageClassifier(motion.classifier, 4, seed=seed).fit(*classifier_pairs(demos),
                                                                     lambda: trainer("classifier"))
    pairs = correction_pairs(demos, tuple(stage_starts), motion.planner_input)
    planner = MOTIONS.build(motion, n_labels=4, n_subgoals=subgoals_per_stage, seed=seed)
    planner.fit(pairs.x, pairs.labels, pairs.subgoals, lambda: trainer("subgoal"), pairs.indices, pairs.references)
    ndp = DynamicPlanner(motion.ndp, env.max_joint_step, env.base_position(), seed=seed)
    ndp.fit(*dynamics_pairs(demos, motion.ndp), lambda: trainer("ndp"))
    return classifier, planner, ndp


def train_motion_module(motion, slots: int, env, demos, max_steps: int, tolerance: float, trainer: Callable,
                        seed: int, log_model: Callable):
    """Ours (4.2.2): the sub-goal planner ``motion`` on the demonstrations' sub-goal pairs (labels: picking and the
    cell's ``slots`` goal slots) and the neural dynamic planner on their steps (joint limit and base frame of the
    cell ``env``), as a :class:`~hrc_lab.motion.two_level.TwoLevelMotion`; ``log_model(network, path)`` receives
    each trained network (``model/subgoal.pt``, ``model/ndp.pt``; e.g. ``RunTracker.log_torch_model``)."""
    from hrc_lab.motion.subgoal import DynamicPlanner
    from hrc_lab.motion.two_level import DESIGNED_SUBGOALS, TwoLevelMotion, dynamics_pairs, package_pairs

    pairs = package_pairs(demos)
    planner = MOTIONS.build(motion, n_labels=1 + slots, n_subgoals=DESIGNED_SUBGOALS, seed=seed)
    planner.fit(pairs.x, pairs.labels, pairs.subgoals, lambda: trainer("subgoal"), pairs.indices, pairs.references)
    ndp = DynamicPlanner(motion.ndp, env.max_joint_step, env.base_position(), seed=seed)
    ndp.fit(*dynamics_pairs(demos, motion.ndp), lambda: trainer("ndp"))
    for name, model in (("subgoal", getattr(planner, "network", None)), ("ndp", ndp.network)):
        if model is not None:
            log_model(model, f"model/{name}.pt")
    return TwoLevelMotion(planner, ndp, DESIGNED_SUBGOALS, max_steps, tolerance)
