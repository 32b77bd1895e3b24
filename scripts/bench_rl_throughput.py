"""Throughput of RL in the robot loop, before and after, and the per-core limit, measured side by side in one run.

The setting is a default Fig. 3.13 job's training step (``experiment=ch3/fig_3_13``, one object, lambda 0.7, seed 0:
2 x 256 networks, batch 256, 60 steps per episode, the 18,000-step guide, the guided episodes as demonstrations),
without its one-off behaviour-cloning start and critic warm-up (``rl.bc_pretrain_steps=0
rl.critic_warmup_steps=0``: they run once per subtask, not per step). Rows:

- *goal env, random actions*: control steps/s of the goal env alone (no guide, no agent), robosuite's step and the
  lean step (``env.sim.lean_step``);
- *gradient step alone*: one update of the agent (critic, actor, their Adam steps, the normaliser's forward passes)
  on batches drawn beforehand, per update and per collected step (the job's 40 updates per cycle of 120 steps);
- *per-core limit*: 1 / (lean env step + 40 / 120 gradient steps), what one core could collect and train with no
  other work;
- *training, end to end*: collected training steps per second of ``learn`` (collection with guidance, storage,
  HER sampling, normaliser statistics, updates), after a warm-up past ``rl.learning_starts``. *before*:
  robosuite's step, one gradient step per collected step and a target update after each, the per-pass normaliser,
  stable-baselines3's own HER buffer, policy and Adam (hrc_lab before the HER reference's cycle); *after*: this
  tree; with ``--code DIR`` also *at <DIR>*: the same row with another tree's hrc_lab (e.g. the commit before a
  speed-up, ``git archive <commit> hrc_lab conf | tar -x -C DIR``), in a subprocess.

Rates are per second of the process's CPU time (``time.process_time``): on a machine shared with other jobs the
wall clock counts their time too, the CPU clock does not (wall-clock rates are in their own column). Each row runs
``--rounds`` times, the rows interleaved, and the table shows the median.

    .venv/bin/python scripts/bench_rl_throughput.py --code /tmp/before --profile reports/benchmarks/rl_profile.md \\
        --out reports/benchmarks/rl_throughput.md
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import torch
from stable_baselines3 import HerReplayBuffer
from torch import nn

from hrc_lab.rl.normalization import NormalizedCombinedExtractor, RunningNormalizer

OVERRIDES = ["experiment=ch3/fig_3_13", "env=error_correction_one_object_case1", "seed=0", "rl.lam=0.7",
             "rl.bc_pretrain_steps=0", "rl.critic_warmup_steps=0"]


class PerPassNormalizer(RunningNormalizer):
    """The input normaliser as hrc_lab ran it before the reference's loop: every batch a training-mode pass sees
    is added to the statistics, and the float64 mean and std are recomputed on every forward pass."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if self.training:
            self.update(x.detach())
        self._stats = None
        return super().forward(x)


class PerPassExtractor(NormalizedCombinedExtractor):
    """:class:`~hrc_lab.rl.normalization.NormalizedCombinedExtractor` with a :class:`PerPassNormalizer` per key."""

    def __init__(self, observation_space, **kwargs) -> None:
        super().__init__(observation_space, **kwargs)
        self.normalizers = nn.ModuleDict({key: PerPassNormalizer(normalizer.running_sum.numel(), normalizer.clip,
                                                                 normalizer.min_std)
                                          for key, normalizer in self.normalizers.items()})


def job_config(extra: list[str] = ()):
    from hydra import compose, initialize_config_dir

    from hrc_lab.config import validate_config
    from hrc_lab.run_naming import CONF_DIR

    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        return validate_config(compose("config", overrides=[*OVERRIDES, *extra]))


def guide_models(cfg, pickled: Path | None = None):
    """The job's guide: from ``pickled`` (a guide cache file), else from the guide cache (trained into it when no job
    has yet: the same models a job trains, :func:`~hrc_lab.experiments.ch3_rl.load_or_train_guide_models`)."""
    import pickle

    if pickled is not None:
        with open(pickled, "rb") as file:
            return pickle.load(file)["models"]
    from hrc_lab.experiments.ch3_rl import load_or_train_guide_models
    from hrc_lab.run_context import unlogged_trainer

    return load_or_train_guide_models(cfg, cfg.raw.seed, unlogged_trainer(cfg.trainer))[0]


def with_lean_step(env_cfg, lean: bool):
    from hrc_lab.registry import named

    return named(dataclasses.replace(env_cfg, sim=dataclasses.replace(env_cfg.sim, lean_step=lean)), env_cfg.name)


class Row:
    """One row's agent or env, built once; :meth:`measure` times ``steps`` more of its work and returns (CPU
    seconds, wall seconds, steps)."""

    def measure(self) -> tuple[float, float, int]:
        raise NotImplementedError


def timed(work) -> tuple[float, float, int]:
    cpu, wall = time.process_time(), time.perf_counter()
    steps = work()
    return time.process_time() - cpu, time.perf_counter() - wall, steps


class EnvRow(Row):
    def __init__(self, cfg, lean: bool, steps: int) -> None:
        from hrc_lab.rl.goal_env import make_goal_env

        self.env = make_goal_env(with_lean_step(cfg.env, lean), cfg.rl, seed=0, subtask=0)
        self.env.reset(seed=0)
        self.rng, self.steps = np.random.default_rng(0), steps

    def measure(self):
        def work():
            for _ in range(self.steps):
                action = self.rng.uniform(-1, 1, self.env.action_space.shape).astype(np.float32)
                *_, truncated, _ = self.env.step(action)
                if truncated:
                    self.env.reset()
            return self.steps

        return timed(work)


class TrainingRow(Row):
    """``learn`` over ``episodes`` more episodes of a Fig. 3.13 agent (guided envs), after a warm-up past
    ``rl.learning_starts``."""

    def __init__(self, cfg, guide, episodes: int, before: bool = False) -> None:
        from hrc_lab.rl import RLS
        from hrc_lab.rl.agent import learn_episodes
        from hrc_lab.rl.trainer import goal_env_factory, training_envs

        rl, env_cfg = cfg.rl, cfg.env
        if before:  # one update per collected step, targets per step; robosuite's step
            horizon = rl.steps_per_subtask
            rl = RLS.derive(rl, episodes_per_cycle=1, gradient_steps=horizon, target_update="step")
            env_cfg = with_lean_step(env_cfg, False)
        self.envs = training_envs(goal_env_factory(env_cfg, rl, 0, guide, subtask=0), rl.n_envs)
        self.agent = before_agent(rl, self.envs) if before else RLS.build(rl, env=self.envs, seed=0)
        self.episodes, self.learn = episodes, learn_episodes
        self.done = rl.learning_starts // rl.steps_per_subtask + rl.episodes_per_cycle
        learn_episodes(self.agent, self.done)  # warm-up: random actions, the first updates

    def measure(self):
        def work():
            steps = self.agent.num_timesteps
            self.done += self.episodes
            self.learn(self.agent, self.done)
            return self.agent.num_timesteps - steps

        return timed(work)


def before_agent(rl, envs):
    """The agent as hrc_lab built it before: stable-baselines3's policy, HER buffer and Adam, the per-pass
    normaliser."""
    from hrc_lab.rl.agent import ddpg_her_kwargs, with_silent_logger
    from hrc_lab.rl.ddpg import HerDDPG

    kwargs = ddpg_her_kwargs(rl, envs, seed=0)
    kwargs.update(policy="MultiInputPolicy", replay_buffer_class=HerReplayBuffer,
                  policy_kwargs={"net_arch": list(rl.net_arch), "features_extractor_class": PerPassExtractor})
    return with_silent_logger(HerDDPG(**kwargs))


class UpdateRow(Row):
    """The agent's gradient steps alone: ``agent.train`` with its batches drawn beforehand (no sampling in the
    timed part), on the buffer a warmed-up :class:`TrainingRow` filled."""

    def __init__(self, training: TrainingRow, updates: int) -> None:
        self.agent, self.updates = training.agent, updates

    def measure(self):
        agent = self.agent
        batches = [agent._sample(agent.batch_size) for _ in range(self.updates)]
        sample = agent._sample
        drawn = iter(batches)
        agent._sample = lambda batch_size: next(drawn)
        try:
            return timed(lambda: (agent.train(self.updates, agent.batch_size), self.updates)[1])
        finally:
            agent._sample = sample


def other_tree(code: Path, guide_file: Path, episodes: int) -> tuple[float, float, int]:
    """The *after* row with the hrc_lab of ``code``, one measurement in a subprocess."""
    env = {**os.environ, "PYTHONPATH": str(code)}
    done = subprocess.run([sys.executable, __file__, "--row-json", str(Path(guide_file).resolve()), "--episodes",
                           str(episodes)], env=env, cwd=code, capture_output=True, text=True)
    if done.returncode:
        sys.exit(f"the 'after' row with {code}'s hrc_lab failed:\n{done.stderr[-3000:]}")
    return tuple(json.loads(done.stdout.strip().splitlines()[-1]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--episodes", type=int, default=20, help="training episodes timed per row and round (60 "
                                                                   "steps each)")
    parser.add_argument("--env-steps", type=int, default=1200, help="random control steps timed per env row")
    parser.add_argument("--rounds", type=int, default=3, help="measurements per row (interleaved); the median")
    parser.add_argument("--code", type=Path, help="also the 'after' row with this tree's hrc_lab")
    parser.add_argument("--profile", type=Path, help="a markdown profile (scripts/profile_rl_step.py) to put below")
    parser.add_argument("--out", type=Path, help="also write the table (markdown) here")
    parser.add_argument("--row-json", type=Path, help=argparse.SUPPRESS)  # the --code subprocess: guide file
    args = parser.parse_args()
    torch.set_num_threads(1)
    if args.row_json:  # one 'after' measurement with this process's hrc_lab
        cfg = job_config()
        row = TrainingRow(cfg, guide_of(cfg, guide_models(cfg, args.row_json)), args.episodes)
        print(json.dumps(row.measure()))
        return
    cfg = job_config()
    guide = guide_of(cfg, guide_models(cfg))
    from hrc_lab.experiments.ch3_rl import guide_cache_path

    after = TrainingRow(cfg, guide, args.episodes)
    rows = {
        "goal env, random actions|robosuite step": EnvRow(cfg, False, args.env_steps),
        "goal env, random actions|lean step (env step alone)": EnvRow(cfg, True, args.env_steps),
        "gradient step alone|per update": UpdateRow(after, cfg.rl.gradient_steps),
        "training, end to end|before: robosuite step, 1 update per step, targets per step, per-pass normaliser, "
        "SB3's HER buffer, policy and Adam": TrainingRow(cfg, guide, args.episodes, before=True),
        "training, end to end|after: this tree": after,
    }
    if args.code:
        rows[f"training, end to end|after at {args.code.name}"] = None
    times: dict[str, list[tuple[float, float, int]]] = {name: [] for name in rows}
    for _ in range(args.rounds):
        for name, row in rows.items():
            times[name].append(row.measure() if row is not None else
                               other_tree(args.code, guide_cache_path(cfg, cfg.raw.seed), args.episodes))
    table = summarise(times, cfg)
    load = Path("/proc/loadavg").read_text().split()[:3] if Path("/proc/loadavg").exists() else ["?"] * 3
    text = (f"Fig. 3.13's training step (`{' '.join(OVERRIDES)}`), measured by `scripts/bench_rl_throughput.py "
            f"--episodes {args.episodes} --rounds {args.rounds}{' --code ' + str(args.code) if args.code else ''}` "
            f"on {os.cpu_count()} cores at load average {' / '.join(load)} (the end of the run; the machine's "
            "other jobs ran beside it). Rates per second of CPU time, the median of the rounds; `x before`: "
            "against the before row, `% of limit`: against the per-core limit.\n\n"
            + table.to_markdown(index=False, floatfmt=".2f"))
    if args.profile:
        text += "\n\n## Where a step's time goes\n\n" + args.profile.read_text()
    print(text)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text.rstrip("\n") + "\n")


def guide_of(cfg, models):
    from hrc_lab.rl.guidance import CorrectionGuide

    return CorrectionGuide.from_config(cfg.rl, *models, cfg.protocol.subgoals_per_stage)


def summarise(times: dict[str, list[tuple[float, float, int]]], cfg) -> pd.DataFrame:
    def rate(name: str, clock: int) -> float:
        return statistics.median(steps / measured[clock] for measured in times[name] for steps in [measured[2]])

    per_step = cfg.rl.gradient_steps / (cfg.rl.episodes_per_cycle * cfg.rl.steps_per_subtask)
    env = rate("goal env, random actions|lean step (env step alone)", 0)
    update = rate("gradient step alone|per update", 0)
    limit = 1 / (1 / env + per_step / update)
    rows = []
    for name in times:
        what, setting = name.split("|")
        rows.append({"what": what, "setting": setting, "steps/s": rate(name, 0), "steps/s (wall)": rate(name, 1)})
    rows.insert(3, {"what": "per-core limit", "setting": f"1 / (lean env step + {per_step:.3f} x gradient step)",
                    "steps/s": limit, "steps/s (wall)": float("nan")})
    table = pd.DataFrame(rows)
    update_row = table.setting == "per update"
    table.loc[update_row, "setting"] = (f"per update ({1e3 / update:.2f} ms); per collected step: "
                                        f"{1e3 * per_step / update:.2f} ms")
    training = table.what == "training, end to end"
    before = table.loc[training, "steps/s"].iloc[0]
    table.loc[training, "x before"] = table.loc[training, "steps/s"] / before
    table.loc[training, "% of limit"] = 100 * table.loc[training, "steps/s"] / limit
    return table


if __name__ == "__main__":
    main()
