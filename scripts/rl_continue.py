"""Does a trained Ch.3 agent place more precisely at a smaller learning rate or with less exploration? Continues a
Fig. 3.13 / 3.12 run's saved agent of subtask 0 (``agents/subtask0/``, with its replay and demonstration buffers)
for ``--epochs`` epochs of the run's loop (:mod:`hrc_lab.rl.trainer`: cycles of episodes, gradient steps, one target
update), unguided, on training scenes of a fresh seed stream, at Adam step size ``--lr`` and exploration ``--noise``
/ ``--random-eps``; after each epoch the deterministic policy is evaluated on ``--episodes`` held-out scenes
(:func:`hrc_lab.rl.evaluation.evaluation_env`). Prints one line per epoch.

    .venv/bin/python scripts/rl_continue.py <MLflow run id> --lr 1e-4 [--noise 0.2] [--random-eps 0.3]
        [--epochs 6] [--episodes 40] [--tracking-uri URI]
"""

import argparse
import os
import tempfile

import numpy as np
import torch
from mlflow.tracking import MlflowClient
from stable_baselines3.common.noise import NormalActionNoise

from hrc_lab.rl.agent import evaluate, learn_episodes, load_agent
from hrc_lab.rl.evaluation import evaluation_env, evaluation_seed
from hrc_lab.rl.trainer import episodes_per_epoch, goal_env_factory, training_envs
from hrc_lab.tracking import saved_run

CONTINUED_SCENES = 777  # the continued training's scene seed: the run's seed + this (not its training scenes)
FIRST_EPOCH = 900  # evaluation k draws the held-out scenes of evaluation_seed(FIRST_EPOCH + k), apart from the run's


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run_id")
    parser.add_argument("--lr", type=float, required=True, help="Adam's step size of the continued training")
    parser.add_argument("--noise", type=float, default=0.2, help="Gaussian exploration noise std")
    parser.add_argument("--random-eps", type=float, default=0.3, help="share of uniformly random actions")
    parser.add_argument("--epochs", type=int, default=6)
    parser.add_argument("--episodes", type=int, default=40, help="held-out evaluation episodes per epoch")
    parser.add_argument("--tracking-uri", default="sqlite:///runs/mlflow.db")
    args = parser.parse_args()
    torch.set_num_threads(1)
    os.environ.setdefault("MLFLOW_ENABLE_ARTIFACTS_PROGRESS_BAR", "false")
    with tempfile.TemporaryDirectory() as tmp:
        saved = saved_run(MlflowClient(args.tracking_uri), args.run_id, tmp)
        rl = saved.cfg.rl
        envs = training_envs(goal_env_factory(saved.cfg.env, rl, saved.seed + CONTINUED_SCENES, subtask=0), 1)
        agent = load_agent(saved.folder / "subtask0", envs)
    n_actions = agent.action_space.shape[0]
    agent.action_noise = NormalActionNoise(np.zeros(n_actions), np.full(n_actions, args.noise))
    agent.random_eps = args.random_eps
    agent.set_learning_rate(args.lr)
    test = evaluation_env(saved.cfg.env, rl, saved.seed, 0)
    done = agent.num_timesteps // test.horizon
    scores = evaluate(agent, test, args.episodes, seed=evaluation_seed(FIRST_EPOCH))
    print(f"saved agent: held-out SR {scores['success_rate']:.3f}", flush=True)
    for epoch in range(1, args.epochs + 1):
        learn_episodes(agent, done + epoch * episodes_per_epoch(rl))
        scores = evaluate(agent, test, args.episodes, seed=evaluation_seed(FIRST_EPOCH + epoch))
        print(f"lr {args.lr:g} noise {args.noise:g} random-eps {args.random_eps:g} epoch +{epoch}: held-out SR "
              f"{scores['success_rate']:.3f}, final distance {scores['final_distance']:.3f} m", flush=True)
    envs.close()
    test.close()


if __name__ == "__main__":
    main()
