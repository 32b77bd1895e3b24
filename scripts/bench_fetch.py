"""hrc_lab's DDPG + HER on a gymnasium-robotics Fetch task, against the published curve: trains the agent of
``rl=ddpg_her`` (the HER paper's settings; :func:`hrc_lab.rl.benchmarks.train_fetch`, the loop of the robot cells) for
``--epochs`` epochs of ``--cycles`` cycles, prints the per-epoch success rate of the deterministic policy, and saves
the curve (success rate over training episodes) as a PNG with the published result of the reference implementation
beside it, where there is one (:data:`PUBLISHED`).

    .venv/bin/python scripts/bench_fetch.py [--env FetchPush-v4] [--epochs 1] [--cycles 50] [--n-envs 1] [--seed 0]
        [--out runs/bench_fetch/FetchPush-v4.png]

An epoch here is ``--cycles`` x 2 episodes per env (the reference's 2 rollouts per worker per cycle), i.e. 100
episodes on one env; the reference's FetchPush epoch is 1900 (19 workers), so its ~10-20 epochs to ~1.0 are
~19,000-38,000 episodes: days of this machine's cores, not a check to run by hand. The x axis is episodes, log scale.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import torch

from hrc_lab.rl.benchmarks import FETCH_ENV_IDS, train_fetch
from hrc_lab.rl.configs import RLConfig

# The published anchor (read, not measured here). The report's text, as quoted in a public Q&A thread
# (datascience.stackexchange.com/questions/68190): "We train for 50 epochs (one epoch consists of 19 x 2 x 50 = 1 900
# full episodes), which amounts to a total of 4.75 x 10^6 timesteps." The success level and epochs are read off its
# Fig. 2 (median test success rate, DDPG + HER, sparse reward) as commonly cited: ~1.0 after ~10-20 epochs;
# approximate, and for FetchPush-v1 (mujoco-py), of which gymnasium-robotics' FetchPush-v4 is the port to the
# mujoco bindings. The rl-baselines3-zoo's FetchPush entry trains TQC for 1e6 steps (hyperparams/her.yml), another
# algorithm, so it is no anchor for DDPG.
PUBLISHED = {
    "FetchPush-v4": {
        "source": "Plappert et al. 2018, Multi-Goal Reinforcement Learning: Challenging Robotics Environments and "
                  "Request for Research, arXiv:1802.09464, Fig. 2 (FetchPush-v1, DDPG+HER, 19 MPI workers)",
        "short": "Plappert et al. 2018 (arXiv:1802.09464), Fig. 2: FetchPush-v1, DDPG+HER, 19 workers",
        "success_rate": 1.0,  # approximately, median over seeds
        "epochs": (10, 20),  # the epochs by which the median reaches it, as read off the figure
        "episodes_per_epoch": 19 * 2 * 50,  # workers x rollouts per worker per cycle x cycles
    },
}


def published_point(env_id: str) -> tuple[int, int, float, str] | None:
    """(episodes at the low and high epoch, success rate, short citation) of the published result for ``env_id``, or
    None."""
    ref = PUBLISHED.get(env_id)
    if ref is None:
        return None
    low, high = (epoch * ref["episodes_per_epoch"] for epoch in ref["epochs"])
    return low, high, ref["success_rate"], ref["short"]


def plot(env_id: str, episodes: list[int], success: list[float], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(episodes, success, "o-", label="hrc_lab DDPG + HER (this run)")
    point = published_point(env_id)
    if point is not None:
        low, high, rate, source = point
        middle = (low * high) ** 0.5
        ax.errorbar([middle], [rate], xerr=[[middle - low], [high - middle]], fmt="s", color="C3", capsize=4,
                    label=f"published: ~{rate:.1f} by {low:,}-{high:,} episodes")
        ax.text(0.99, 0.03, source, transform=ax.transAxes, fontsize=6, ha="right", va="bottom")
    ax.set_xscale("log")
    ax.set_ylim(-0.05, 1.05)
    ax.set_xlabel("training episodes (50 steps each)")
    ax.set_ylabel("success rate (deterministic policy)")
    ax.set_title(env_id)
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--env", default="FetchPush-v4", choices=FETCH_ENV_IDS)
    parser.add_argument("--epochs", type=int, default=1)
    parser.add_argument("--cycles", type=int, default=50, help="cycles per epoch (the reference: 50; FetchReach 10)")
    parser.add_argument("--n-envs", type=int, default=1, help="envs in parallel, one process each when > 1")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--eval-episodes", type=int, default=20)
    parser.add_argument("--net-arch", type=int, nargs="+", default=[256, 256, 256])
    parser.add_argument("--out", type=Path, default=None, help="PNG path (default runs/bench_fetch/<env>.png)")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    cfg = RLConfig(net_arch=args.net_arch, cycles_per_epoch=args.cycles, episodes_per_cycle=2 * args.n_envs,
                   n_envs=args.n_envs, learning_starts=0)
    per_epoch = cfg.cycles_per_epoch * cfg.episodes_per_cycle
    rows: list[tuple[int, dict[str, float]]] = []
    start = time.perf_counter()
    success = train_fetch(args.env, cfg, args.epochs, seed=args.seed, eval_episodes=args.eval_episodes,
                          log=lambda metrics, epoch: rows.append((epoch, metrics)))
    print(f"\n{args.env}, seed {args.seed}, {args.n_envs} env(s), {args.cycles} cycles x {cfg.episodes_per_cycle} "
          f"episodes per epoch, nets {args.net_arch}, {time.perf_counter() - start:.0f} s")
    print("| epoch | episodes | success_rate | final_distance | train_success_rate | env_steps_per_s | epoch_s |")
    print("|------:|---------:|-------------:|---------------:|-------------------:|----------------:|--------:|")
    for epoch, m in rows:
        print(f"| {epoch:5d} | {epoch * per_epoch:8d} | {m['success_rate']:12.2f} | {m['final_distance']:14.3f} | "
              f"{m['train_success_rate']:18.2f} | {m['env_steps_per_s']:15.0f} | {m['epoch_s']:7.1f} |")
    point = published_point(args.env)
    if point is not None:
        low, high, rate, _ = point
        print(f"published: success ~{rate:.1f} by {low:,}-{high:,} episodes ({PUBLISHED[args.env]['source']})")
    out = args.out or Path("runs") / "bench_fetch" / f"{args.env}.png"
    plot(args.env, [epoch * per_epoch for epoch, _ in rows], success, out)
    print(f"curve: {out}")


if __name__ == "__main__":
    main()
