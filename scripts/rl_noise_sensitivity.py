"""How much exploration noise a trained Ch.3 agent's placements survive: replays a finished Fig. 3.13 / 3.12 run's
last agent of subtask 0 (``agents/subtask0/``) on scenes of its training seed stream, its deterministic action plus
Gaussian noise of std ``sigma`` on the [-1, 1] actions, or replaced by a uniform random action with probability
``eps`` (the HER reference implementation's two kinds of exploration), and prints the success rate per setting.

    .venv/bin/python scripts/rl_noise_sensitivity.py <MLflow run id> [--tracking-uri URI] [--episodes 20]
"""

import argparse
import os
import tempfile

import numpy as np
import torch
from mlflow.tracking import MlflowClient

from hrc_lab.rl.agent import HerDDPG
from hrc_lab.rl.goal_env import make_goal_env
from hrc_lab.tracking import saved_run

SETTINGS = ((0.0, 0.0), (0.05, 0.0), (0.1, 0.0), (0.2, 0.0), (0.0, 0.1), (0.2, 0.3))  # (sigma, eps)
SCENE_SEED = 500  # episode k resets with SCENE_SEED + k


def success_rate(agent, env, sigma: float, eps: float, episodes: int) -> float:
    rng = np.random.default_rng(0)
    successes = []
    for k in range(episodes):
        obs, _ = env.reset(seed=SCENE_SEED + k)
        done = False
        while not done:
            action, _ = agent.predict(obs, deterministic=True)
            action = np.clip(action + sigma * rng.standard_normal(action.shape), -1, 1)
            if rng.random() < eps:
                action = rng.uniform(-1, 1, action.shape)
            obs, _, terminated, truncated, info = env.step(action)
            done = terminated or truncated
        successes.append(info["is_success"])
    return float(np.mean(successes))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run_id")
    parser.add_argument("--tracking-uri", default="sqlite:///runs/mlflow.db")
    parser.add_argument("--episodes", type=int, default=20)
    args = parser.parse_args()
    torch.set_num_threads(1)
    os.environ.setdefault("MLFLOW_ENABLE_ARTIFACTS_PROGRESS_BAR", "false")
    client = MlflowClient(args.tracking_uri)
    with tempfile.TemporaryDirectory() as tmp:
        saved = saved_run(client, args.run_id, tmp)
        env = make_goal_env(saved.cfg.env, saved.cfg.rl, seed=saved.seed, subtask=0)
        agent = HerDDPG.load(saved.folder / "subtask0" / "agent.zip", env=env, device="cpu")
        print("| noise std | random-action share | success rate |\n|---|---|---|")
        for sigma, eps in SETTINGS:
            print(f"| {sigma:g} | {eps:g} | {success_rate(agent, env, sigma, eps, args.episodes):.2f} |", flush=True)
        env.close()


if __name__ == "__main__":
    main()
