"""Does DDPG + HER learn a reach in the robot cell? (hrc_lab.rl.reach): trains the agent of ``rl=ddpg_her`` on
:class:`~hrc_lab.rl.reach.ReachGoalEnv` in the one-object error-correction cell with 3.3's action (wrist 3, cup
always on) and prints the deterministic policy's success rate and final distance on 10 held-out scenes every 25
episodes, for raw and for normalised inputs (``rl.normalize_inputs``).

    .venv/bin/python scripts/rl_reach_check.py [--episodes 400] [--reach 0.15] [--delta-r 0.05] [--raw-only]
"""

import argparse

import torch

from hrc_lab.env.robot.settings import ErrorCorrectionConfig, SimSettings
from hrc_lab.registry import named
from hrc_lab.rl.agent import build_ddpg_her, evaluate, learn_episodes
from hrc_lab.rl.configs import RLConfig
from hrc_lab.rl.reach import make_reach_env


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--episodes", type=int, default=400)
    parser.add_argument("--reach", type=float, default=0.15, help="goal offset per axis, m")
    parser.add_argument("--delta-r", type=float, default=0.05, help="success threshold, m")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--raw-only", action="store_true", help="only the raw-input agent")
    args = parser.parse_args()
    torch.set_num_threads(1)
    cell = named(ErrorCorrectionConfig(task="one_object", sim=SimSettings(yaw_action=True)), "error_correction")
    for normalize in [False] if args.raw_only else [False, True]:
        cfg = RLConfig(suction="auto", delta_r=args.delta_r, net_arch=[64, 64], buffer_size=100_000,
                       normalize_inputs=normalize)
        train = make_reach_env(cell, cfg, seed=args.seed, reach_m=args.reach)
        test = make_reach_env(cell, cfg, seed=args.seed + 1, reach_m=args.reach)
        agent = build_ddpg_her(cfg, train, seed=args.seed)
        print(f"rl.normalize_inputs={normalize}", flush=True)
        for episodes in range(25, args.episodes + 1, 25):
            learn_episodes(agent, episodes)
            scores = evaluate(agent, test, 10, seed=1000)
            print(f"  episode {episodes:4d}  SR {scores['success_rate']:.2f}  final distance "
                  f"{scores['final_distance']:.3f} m", flush=True)


if __name__ == "__main__":
    main()
