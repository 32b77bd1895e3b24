"""DAgger (Ross, Gordon and Bagnell, 2011, "A reduction of imitation learning and structured prediction to no-regret
online learning") for the Ch.3 two-level planner of Table 3.1 (thesis 3.3, 3.4.2); not in the thesis.

The thesis' demonstrations were given by a person at a keyboard (3.3, Fig. 3.8: goal-state errors up to 0.1 m), so
its second stages start from first parts that are off their goals; the scripted expert places exactly, so ours
never do, and the closed loop's second stages start outside what c(x) and the sub-goal planner were trained on
(reports/ch3_motion.md). DAgger adds the states the learner itself reaches: in each round the learned planner
runs the first manipulation in fresh training scenes, the scripted expert demonstrates the rest from wherever the
loop left the cell, those demonstrations join the data set and every network is retrained on all of it.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from tqdm import tqdm


def dagger(train: Callable, collect: Callable | None, demos: list, rounds: int) -> tuple[object, list]:
    """DAgger's loop: ``train(demos)`` gives the models; each of ``rounds`` rounds adds ``collect(models)``, the
    expert's demonstrations from the states the models reach, to the data set and retrains on the aggregate.
    Returns the last models and the aggregated demonstrations (``rounds`` 0: the models of ``demos`` alone)."""
    models = train(demos)
    for _ in range(rounds):
        new = collect(models)
        if new:
            demos = demos + new
            models = train(demos)
    return models, demos


def takeover_demos(env, loop: Callable, n: int, subgoals_per_stage: int, segmentation_penalty: float, desc: str,
                   placement_noise: float = 0.0, rng: np.random.Generator | None = None,
                   subgoal_path: str = "eef") -> list:
    """DAgger's expert labels in ``n`` fresh scenes of ``env``: ``loop(env, manipulations=1)`` (the learned
    two-level planner, :func:`~hrc_lab.motion.two_level.run_correction`) picks and places the first object, then
    the scripted expert (aiming its placements with ``placement_noise``, as in
    :func:`~hrc_lab.motion.demonstrations.correction_demos`) moves the objects the loop has not moved, from that
    state, recorded and segmented into change-point stages with ``subgoals_per_stage`` sub-goals re-sampled from
    the ``subgoal_path`` lip's path (3.3).
    Kept: the expert's demonstrations whose objects end within the cell's delta_r of their goals without a
    collision, with a picking and a placing stage per object it moved. A scene gives none when the loop failed its
    first manipulation (no later stage to label) or the case has one manipulation only."""
    from hrc_lab.data.recording import record_episode
    from hrc_lab.data.segmentation import stage_subgoals
    from hrc_lab.env.robot.expert import ScriptedExpert

    demos = []
    for _ in tqdm(range(n), desc=desc, unit="scene"):
        out, _ = loop(env, manipulations=1)
        rest = [obj for obj in env.expert_plan() if obj not in out.picks]
        if out.failure or not rest:
            continue
        expert = ScriptedExpert(env, placement_noise=placement_noise, rng=rng, objects=rest)
        demo = record_episode(env, expert, reset=False)
        demo.stage_bounds, demo.stage_subgoals = stage_subgoals(
            demo, env.stage_label, subgoals_per_stage, "resample", segmentation_penalty, subgoal_path)
        placed = np.linalg.norm(env.object_positions()[rest] - env.goals[rest], axis=1) <= env.success_threshold
        if placed.all() and not env.collisions and len(demo.stage_bounds) == 2 * len(rest):
            demos.append(demo)
    return demos
