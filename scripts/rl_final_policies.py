"""Where do the final policies of a Ch.3 RL sweep (``ch3/fig_3_13``, ``ch3/fig_3_12``) miss Eq. 3.6's goal? Loads
every finished run's last agent per subtask (``agents/subtask<k>/``), replays the run's last evaluation (its
held-out scenes, the deterministic policy; with ``--final`` the scenes of ``protocol.final_eval_episodes``, which
no epoch saw, so runs from before that key get the same measurement) and splits |P_obj - P_goal| into the
position error and the yaw error (``--per-episode``: every episode's error along x and y beside the lip's offset
from the part's centre when the cup first held it); also Eq. 3.6's success (mean and std over the seeds' rates)
and how many episodes held the part, moved it more than 2 cm, or collided. Prints one row per (scenario, lambda).

    .venv/bin/python scripts/rl_final_policies.py 2026-12-02_06-55-00 [--tracking-uri URI] [--episodes 10]
        [--final] [--per-episode]

A run id instead of a sweep replays that run's saved agents whatever its status (e.g. a long run's latest
checkpoint, on the held-out scenes of its configured last epoch).
"""

import argparse
import os
import tempfile

import numpy as np
import pandas as pd
import torch
from mlflow.tracking import MlflowClient

from hrc_lab.rl.agent import MOVED_M, HerDDPG, run_episode
from hrc_lab.rl.evaluation import FINAL_EVALUATION_SEED, evaluation_env, evaluation_seed
from hrc_lab.tracking import saved_run


def replay(agent: HerDDPG, env, seed: int) -> dict[str, float]:
    """One evaluation episode; the last step's position and yaw errors (the farthest goal object), the part's
    error along x and y and the lip's horizontal offset from the part's centre when the cup first held it."""
    grip = []

    def first_hold(env, info) -> None:
        if info["held"] and not grip:
            grip.append(env.cell.grip_offset())

    info, _ = run_episode(agent, env, seed=seed, on_step=first_hold)
    error = (info["achieved_goal"] - info["desired_goal"]).reshape(-1, env.dims_per_object)
    farthest = int(np.argmax(np.linalg.norm(error[:, :3], axis=1)))
    offset = grip[0] if grip else np.full(3, np.nan)
    return {"position_m": float(np.linalg.norm(error[:, :3], axis=1).max()),
            "dx_m": float(error[farthest, 0]), "dy_m": float(error[farthest, 1]),
            "grip_dx_m": float(offset[0]), "grip_dy_m": float(offset[1]),
            "yaw_rad": float(np.abs(error[:, 3]).max()) if env.dims_per_object == 4 else float("nan"),
            "success": bool(info["is_success"]), "held": info["ever_held"], "moved": info["ever_moved"],
            "collided": bool(info["collided"]),
            "delta_r": env.delta_r}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("sweep", help="the sweep's folder name (MLflow tag `sweep`), or one MLflow run id")
    parser.add_argument("--tracking-uri", default="sqlite:///runs/mlflow.db")
    parser.add_argument("--episodes", type=int, default=10, help="evaluation episodes per agent")
    parser.add_argument("--final", action="store_true",
                        help="the final policy's scenes (hrc_lab.rl.evaluation.FINAL_EVALUATION_SEED), not the last "
                             "epoch's")
    parser.add_argument("--per-episode", action="store_true",
                        help="also print every episode's position error, sorted (how far the failures are)")
    args = parser.parse_args()
    torch.set_num_threads(1)
    os.environ.setdefault("MLFLOW_ENABLE_ARTIFACTS_PROGRESS_BAR", "false")
    client = MlflowClient(args.tracking_uri)
    experiments = [e.experiment_id for e in client.search_experiments()]
    runs = client.search_runs(experiments, f"attributes.run_id = '{args.sweep}'")  # a run id: that run, any status
    runs = runs or client.search_runs(experiments, f"tags.sweep = '{args.sweep}' and attributes.status = 'FINISHED'")
    rows = []
    for run in runs:
        if "agents" not in {a.path for a in client.list_artifacts(run.info.run_id)}:
            continue  # the sweep's summary run
        with tempfile.TemporaryDirectory() as tmp:
            saved = saved_run(client, run.info.run_id, tmp)
            cfg, seed = saved.cfg, saved.seed
            for folder in sorted(saved.folder.glob("subtask*")):
                subtask = int(folder.name.removeprefix("subtask"))
                env = evaluation_env(cfg.env, cfg.rl, seed, subtask)
                agent = HerDDPG.load(folder / "agent.zip", env=env, device="cpu")
                first = FINAL_EVALUATION_SEED if args.final else evaluation_seed(cfg.protocol.epochs)
                for k in range(args.episodes):
                    rows.append({"scenario": run.data.tags["cell"], "lam": float(cfg.rl.lam), "seed": seed,
                                 "subtask": subtask,
                                 **replay(agent, env, seed=first + k)})
                env.close()
        print(f"{run.data.tags.get('mlflow.runName', run.info.run_id)}: {len(rows)} episodes", flush=True)
    if not rows:
        raise SystemExit(f"no finished run with saved agents in sweep {args.sweep} at {args.tracking_uri}")
    frame = pd.DataFrame(rows)
    delta_r = frame.delta_r.iloc[0]
    groups = frame.groupby(["scenario", "lam"])
    per_seed = frame.groupby(["scenario", "lam", "seed"]).success.mean().groupby(level=["scenario", "lam"])
    table = pd.DataFrame({
        "episodes": groups.size(),
        "seeds": per_seed.size(),
        "SR": per_seed.mean(),
        "SR std over seeds": per_seed.std(ddof=0),
        "median position error (m)": groups.position_m.median(),
        "median absolute yaw error (rad)": groups.yaw_rad.median(),
        f"position within {delta_r:g}": groups.position_m.apply(lambda s: (s <= delta_r).mean()),
        f"yaw within {delta_r:g}": groups.yaw_rad.apply(lambda s: (s <= delta_r).mean()),
        "held the part": groups.held.mean(),
        f"moved it > {MOVED_M * 100:g} cm": groups.moved.mean(),
        "collided": groups.collided.mean(),
    })
    print(table.round(3).reset_index().to_markdown(index=False))
    if args.per_episode:
        for (scenario, lam), group in groups:
            errors = " ".join(f"{100 * e:.2f}" for e in sorted(group.position_m))
            print(f"{scenario}, lambda {lam:g}: position error per episode (cm, sorted): {errors}")
        print("per episode, cm: the part minus its goal (x, y) and the lip minus the part's centre when the cup "
              "first held it (x, y)")
        for row in frame.itertuples():
            print(f"{row.scenario}, lambda {row.lam:g}, seed {row.seed}, subtask {row.subtask}: success "
                  f"{row.success}, part - goal ({100 * row.dx_m:+.1f}, {100 * row.dy_m:+.1f}), grip "
                  f"({100 * row.grip_dx_m:+.1f}, {100 * row.grip_dy_m:+.1f})")


if __name__ == "__main__":
    main()
