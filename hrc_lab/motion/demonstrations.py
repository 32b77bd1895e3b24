"""The scripted expert's demonstrations the two-level motion module learns from: the error-correction cells' with
their change-point stages and re-sampled sub-goals (Ch.3, 3.3; Table 3.1, Fig. 3.10, Algorithm 1's guide) and the
package-to-order cell's (Ch.4, 4.4.2.1; Table 4.2 and ours in Table 4.3)."""

from __future__ import annotations

import numpy as np
from tqdm import tqdm

from hrc_lab.env.robot.spec import combinations

MAX_ATTEMPTS_PER_DEMO = 3


def correction_demos(env, n: int, subgoals_per_stage: int, segmentation_penalty: float, desc: str,
                     placement_noise: float = 0.0, rng: np.random.Generator | None = None, action_noise: float = 0.0,
                     action_rng: np.random.Generator | None = None, subgoal_path: str = "eef") -> list:
    """Expert demonstrations with their change-point stages (PELT penalty ``segmentation_penalty``) and
    ``subgoals_per_stage`` sub-goals per stage re-sampled from the ``subgoal_path`` lip's path (3.3;
    :data:`~hrc_lab.motion.configs.SUBGOAL_PATHS`); the expert aims its placements with
    ``placement_noise`` (m) drawn from ``rng``, and its executed joint deltas carry ``action_noise`` (rad, DART)
    drawn from ``action_rng``.
    Kept: the successful demonstrations whose segmentation found a picking and a placing stage per moved object;
    episodes are recorded until ``n`` are kept or ``MAX_ATTEMPTS_PER_DEMO * n`` were tried (noise can spoil one)."""
    from hrc_lab.data.recording import record_episode
    from hrc_lab.data.segmentation import stage_subgoals
    from hrc_lab.env.robot.expert import ScriptedExpert

    expert, demos = ScriptedExpert(env, placement_noise=placement_noise, rng=rng), []
    with tqdm(total=n, desc=desc, unit="demo") as progress:
        for _ in range(MAX_ATTEMPTS_PER_DEMO * n):
            demo = record_episode(env, expert, action_noise, action_rng)
            demo.stage_bounds, demo.stage_subgoals = stage_subgoals(
                demo, env.stage_label, subgoals_per_stage, "resample", segmentation_penalty, subgoal_path)
            if demo.success and len(demo.stage_bounds) == 2 * len(env.expert_plan()):
                demos.append(demo)
                progress.update()
                if len(demos) == n:
                    break
    return demos


def fixed_goal_configurations(spec) -> list:
    """Training orders in which every selection is packed one way: the k-th lowest product into slot k (each
    product "only allowed to be manipulated to one goal position" per selection, 4.4.2.1)."""
    return [tuple((product, k) for k, product in enumerate(selection)) for selection in combinations(spec)]


def collect_demos(env, n: int, desc: str) -> list:
    """``n`` scripted-expert episodes of the package-to-order cell ``env`` (its goal configurations, e.g.
    :func:`fixed_goal_configurations`); the successful ones."""
    from hrc_lab.data.recording import record_episode
    from hrc_lab.env.robot.expert import ScriptedExpert

    expert = ScriptedExpert(env)
    demos = [record_episode(env, expert) for _ in tqdm(range(n), desc=desc, unit="demo")]
    return [d for d in demos if d.success]
