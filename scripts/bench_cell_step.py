"""Control steps per second of the DRL goal env (``HRCGoalEnv`` on an error-correction cell with the wrist-3 action,
``RLConfig(suction="auto", delta_r=0.01)``) with ``env.sim.lean_step`` off (robosuite's step) and on, in one run on
the same machine: N random actions each, the episodes' resets included (what training sees). Prints a markdown table.

    nice -n 5 .venv/bin/python scripts/bench_cell_step.py [--steps 1000] [--task one_object] [--seed 0]
"""

import argparse
import time

import numpy as np

from hrc_lab.env.robot.settings import ErrorCorrectionConfig, SimSettings
from hrc_lab.registry import named
from hrc_lab.rl.configs import RLConfig
from hrc_lab.rl.goal_env import make_goal_env


def steps_per_second(lean_step: bool, steps: int, task: str, seed: int) -> float:
    """Random actions from a seeded generator through a fresh goal env; wall-clock control steps per second."""
    env_cfg = named(ErrorCorrectionConfig(task=task, sim=SimSettings(yaw_action=True, lean_step=lean_step)),
                    "error_correction")
    env = make_goal_env(env_cfg, RLConfig(suction="auto", delta_r=0.01), seed=seed)
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    start = time.perf_counter()
    for _ in range(steps):
        _, _, terminated, truncated, _ = env.step(rng.uniform(-1.0, 1.0, env.action_space.shape))
        if terminated or truncated:
            env.reset()
    elapsed = time.perf_counter() - start
    env.close()
    return steps / elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=1000, help="control steps per setting")
    parser.add_argument("--task", default="one_object", help="error-correction task (env.task)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    rates = {lean: steps_per_second(lean, args.steps, args.task, args.seed) for lean in (False, True)}
    print(f"HRCGoalEnv on error_correction/{args.task} (yaw_action), suction=auto, {args.steps} random steps each\n")
    print("| lean_step | control steps/s | speed-up |")
    print("|---|---:|---:|")
    for lean, rate in rates.items():
        print(f"| {str(lean).lower()} | {rate:.0f} | {rate / rates[False]:.2f}x |")


if __name__ == "__main__":
    main()
