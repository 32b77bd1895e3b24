"""Table 4.3 (thesis 4.4.3): the whole TAMP system in the robot cell against a flat DRL agent and against the
reasoning module with RRT-Connect. One Hydra job = one (cell, system ``tamp``, seed).

The system is ``TAMPS.build(cfg.tamp)`` (:mod:`hrc_lab.tamp.systems`), which trains its modules, runs the trials
and renders its videos:

- ``tamp=ours``: Algorithm 2 (:func:`hrc_lab.tamp.algorithm2.run_tamp`) with the reasoning module trained as in
  Table 4.1 and the two-level motion module trained as in Table 4.2, both on CASE 1 only;
- ``tamp=rm_rrt_connect``: the same reasoning module (same data, same seed) with OMPL's RRT-Connect as the motion
  module (:mod:`hrc_lab.motion.rrt_connect`);
- ``tamp=drl``: one DDPG + HER agent (:mod:`hrc_lab.rl`) trained on CASE 1 and CASE 2, then its deterministic
  policy; a trial succeeds if the order is packed (Eq. 4.7) with no collision when its episode ends.

Every system is tested on the same ``protocol.trials`` scenes (cells seeded with :mod:`hrc_lab.seeds`' test scenes;
trials alternate CASE 1 and CASE 2). Per object: planning time (reasoning decisions + motion planning, wall clock,
batch 1), control steps and simulated execution time (steps / env.sim.control_freq). Failure reasons as in
:mod:`hrc_lab.tamp.algorithm2`; DRL's are ``collision`` or ``goal`` (the order was not packed when the episode
ended).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from hrc_lab.run_context import RunContext
from hrc_lab.tamp import TAMPS
from hrc_lab.tamp.systems import CASES


def summarise(trials: pd.DataFrame, control_freq: float) -> dict[str, float]:
    """Success rates (all, per case), per-object planning and execution, and the failure breakdown."""
    done = trials[trials.objects > 0]
    metrics = {
        "sr": float(trials.success.mean()),
        **{f"sr_case{c}": float(trials[trials.case == c].success.mean()) for c in CASES},
        "planning_ms_per_object": float(done.planning_ms_per_object.median()) if len(done) else np.nan,
        "reasoning_ms": float(trials.reasoning_ms.median()),
        "steps_per_object": float(done.object_steps.mean()) if len(done) else np.nan,
        "n_trials": float(len(trials)),
    }
    metrics["execution_s_per_object"] = metrics["steps_per_object"] / control_freq
    for kind in ("reasoning", "motion"):
        metrics[f"fail_{kind}"] = float((trials.failure_kind == kind).mean())
        for c in CASES:
            metrics[f"fail_{kind}_case{c}"] = float((trials[trials.case == c].failure_kind == kind).mean())
    for failure in sorted(set(trials.failure) - {""}):
        metrics[f"fail_{failure}"] = float((trials.failure == failure).mean())
    return metrics


def table_4_3(ctx: RunContext) -> dict[str, float]:
    protocol, spec = ctx.cfg.protocol, ctx.cfg.env
    system = TAMPS.build(ctx.cfg.tamp)
    system.train(ctx)
    trials = system.trials(ctx)
    videos = system.videos(ctx) if spec.cell in protocol.video_cells else []
    for path in videos:
        ctx.tracker.log_artifact(path, "videos")
    ctx.tracker.log_table(trials, "trials")
    metrics = summarise(trials, spec.sim.control_freq)
    ctx.tracker.log_table(pd.DataFrame([{"method": system.name, "seed": ctx.seed, "cell": spec.cell, **metrics}]),
                          "table_4_3")
    return metrics
