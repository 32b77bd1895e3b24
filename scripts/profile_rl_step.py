"""Where a Fig. 3.13 training step's time goes: one ``hrc-lab experiment=ch3/fig_3_13`` job run in this process with
timers around the loop's parts, reported per collected training step.

Every timed function charges its own time (exclusive of the timed functions it calls) to a *part* (physics,
controller, contact scan, cell and goal-env bookkeeping, guide inference, policy inference, replay storage, HER
sampling, normaliser, gradient updates, SB3 and callbacks, MLflow logging, checkpoints, ...) within a *phase*
(collection, updates, evaluation, logging, checkpoints); time in no timed function is "other". Epoch 1 is not
counted (its random warm-up, behaviour-cloning start and critic warm-up run once per subtask): the table covers
epochs 2 to ``protocol.epochs``, the steady state of a job, up to the last epoch's metrics (a checkpoint every
``protocol.checkpoint_every`` epochs is in it when one falls in that range). The clock is the process's CPU time
(``time.process_time``), so the other jobs of a shared machine do not count in it, though they can still slow it
(shared caches, hyperthreads). The wrappers cost about 1 us a call. ``--guide-steps``
trains a shorter guide (its inference costs the same; ``motion.steps`` otherwise, the cached guide when one is
there). Extra arguments are hrc-lab overrides.

    .venv/bin/python scripts/profile_rl_step.py --epochs 3 --out reports/benchmarks/rl_profile.md
"""

from __future__ import annotations

import argparse
import functools
import os
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import pandas as pd

OVERRIDES = ["experiment=ch3/fig_3_13", "hydra.mode=RUN", "env=error_correction_one_object_case1", "seed=0",
             "rl.lam=0.7", "protocol.final_eval_episodes=0"]


class Clock:
    """Exclusive time per (phase, part): a stack of the timed calls running now."""

    def __init__(self) -> None:
        self.totals: dict[tuple[str, str], float] = defaultdict(float)
        self.calls: dict[tuple[str, str], int] = defaultdict(int)
        self.stack: list[tuple[str, str]] = [("other", "other")]
        self.last = time.process_time()
        self.on = False

    def switch(self, to: tuple[str, str] | None) -> None:
        now = time.process_time()
        if self.on:
            self.totals[self.stack[-1]] += now - self.last
        self.last = now
        if to is None:
            self.stack.pop()
        else:
            self.stack.append(to)
            self.calls[to] += self.on

    def reset(self) -> None:
        self.totals.clear()
        self.calls.clear()
        self.last, self.on = time.process_time(), True


CLOCK = Clock()


def timed(owner, name: str, part: str | None = None, phase: str | None = None) -> None:
    """Wrap ``owner.name`` so its exclusive time goes to ``part`` (None: the caller's) within ``phase`` (None: the
    caller's)."""
    fn = getattr(owner, name)

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        top_phase, top_part = CLOCK.stack[-1]
        CLOCK.switch((phase or top_phase, part or top_part))
        try:
            return fn(*args, **kwargs)
        finally:
            CLOCK.switch(None)

    setattr(owner, name, wrapper)


def install() -> None:
    import mujoco
    from stable_baselines3.common.callbacks import CallbackList
    from stable_baselines3.common.vec_env import DummyVecEnv

    import hrc_lab.experiments.ch3_rl as ch3
    import hrc_lab.rl.agent as agent
    import hrc_lab.rl.trainer as trainer
    from hrc_lab.env.robot.cell import HRCCell
    from hrc_lab.env.robot.suction import Suction
    from hrc_lab.rl.buffers import FilledHerReplayBuffer
    from hrc_lab.rl.ddpg import HerDDPG
    from hrc_lab.rl.goal_env import HRCGoalEnv
    from hrc_lab.rl.guidance import CorrectionGuide, GuidedEnv
    from hrc_lab.rl.normalization import RunningNormalizer
    from hrc_lab.tracking import RunTracker

    # phases
    timed(HerDDPG, "collect_rollouts", "SB3 loop", "collection")
    timed(HerDDPG, "train", "updates (forward, backward, Adam)", "updates")
    timed(agent, "evaluate", "evaluation loop", "evaluation")
    timed(RunTracker, "log_metrics", "MLflow logging", "logging")
    timed(ch3, "save_checkpoint", "checkpoints", "checkpoints")
    timed(trainer, "learning_rate_at", "trainer")
    timed(HerDDPG, "learn", "SB3 learn (setup, between cycles)")
    timed(HerDDPG, "_setup_learn", "SB3 learn (setup, between cycles)")
    # parts
    timed(mujoco, "mj_step1", "physics (mj_step1, mj_step2)")
    timed(mujoco, "mj_step2", "physics (mj_step1, mj_step2)")
    timed(HRCCell, "_servo_torques", "controller (servo torques)")
    timed(HRCCell, "_scan_contacts", "contact scan")
    timed(HRCCell, "step", "cell step (rest)")
    timed(HRCCell, "_post_action", "cell step (rest)")
    timed(Suction, "command", "cell step (rest)")
    timed(HRCGoalEnv, "step", "goal env step (obs, reward, info)")
    timed(HRCGoalEnv, "reset", "env reset")
    timed(GuidedEnv, "step", "guided env wrapper")
    timed(GuidedEnv, "correction", "guide inference")
    timed(CorrectionGuide, "reset", "guide inference")
    timed(DummyVecEnv, "step_wait", "VecEnv")
    timed(DummyVecEnv, "reset", "env reset")
    timed(HerDDPG, "_sample_action", "policy inference and exploration")
    timed(HerDDPG, "predict", "policy inference and exploration")
    timed(HerDDPG, "_store_transition", "replay storage (and guided demos)")
    timed(FilledHerReplayBuffer, "sample", "HER sampling")
    timed(FilledHerReplayBuffer, "add", "replay storage (and guided demos)")
    timed(HerDDPG, "update_input_statistics", "normaliser (statistics)")
    timed(RunningNormalizer, "forward", "normaliser (forward)")
    timed(CallbackList, "on_step", "callbacks")
    timed(HerDDPG, "update_diagnostics", "trainer")


def table(steps: int) -> pd.DataFrame:
    total = sum(CLOCK.totals.values())
    rows = [{"phase": phase, "part": part, "calls per step": CLOCK.calls[(phase, part)] / steps,
             "us per step": 1e6 * seconds / steps, "share %": 100 * seconds / total}
            for (phase, part), seconds in CLOCK.totals.items()]
    frame = pd.DataFrame(rows).sort_values("us per step", ascending=False)
    by_phase = frame.groupby("phase")["us per step"].sum().sort_values(ascending=False)
    frame["phase"] = pd.Categorical(frame["phase"], list(by_phase.index))
    frame = frame.sort_values(["phase", "us per step"], ascending=[True, False])
    frame.loc[len(frame)] = {"phase": "total", "part": "", "calls per step": float("nan"),
                             "us per step": 1e6 * total / steps, "share %": 100.0}
    return frame


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--epochs", type=int, default=3, help="protocol.epochs (epoch 1 is not counted)")
    parser.add_argument("--guide-steps", type=int, help="motion.steps of the guide (default: the experiment's)")
    parser.add_argument("--out", type=Path, help="also write the table (markdown) here")
    parser.add_argument("overrides", nargs="*")
    args = parser.parse_args()
    install()
    from hrc_lab.rl.trainer import episodes_per_epoch
    from hrc_lab.tracking import RunTracker

    counted: dict[str, float] = {}
    log = RunTracker.log_metrics

    def log_metrics(self, metrics, step=0):  # the epoch's metrics: start the clock after epoch 1
        log(self, metrics, step)
        if "epoch_s" in metrics:
            if step == 1:
                CLOCK.reset()
                counted["start"], counted["cpu_start"] = time.perf_counter(), time.process_time()
            elif CLOCK.on:
                counted["epochs"] = step - 1
                counted["end"], counted["cpu_end"] = time.perf_counter(), time.process_time()
                if step == args.epochs:  # the job's end (its last checkpoint, MLflow's end of run) is not counted
                    CLOCK.switch(CLOCK.stack[-1])
                    CLOCK.stack.pop()
                    CLOCK.on = False

    RunTracker.log_metrics = log_metrics
    overrides = [*OVERRIDES, f"protocol.epochs={args.epochs}", *args.overrides]
    if args.guide_steps:
        overrides.append(f"motion.steps={args.guide_steps}")
    runs = tempfile.mkdtemp(prefix="rl_profile_")
    from hrc_lab.cli import main as hrc_lab

    sys.argv = ["hrc-lab", f"paths.runs_dir={runs}", *overrides]
    try:
        hrc_lab()
    except SystemExit as exit:
        if exit.code:
            raise
    CLOCK.on = False
    from hydra import compose, initialize_config_dir

    from hrc_lab.config import validate_config  # noqa: F401 (the job's config below)
    from hrc_lab.run_naming import CONF_DIR

    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = validate_config(compose("config", overrides=[o for o in overrides if not o.startswith("hydra.")]))
    horizon = cfg.rl.steps_per_subtask
    steps = counted["epochs"] * episodes_per_epoch(cfg.rl) * horizon
    frame = table(steps)
    wall = counted["end"] - counted["start"]
    cpu = counted["cpu_end"] - counted["cpu_start"]
    load = Path("/proc/loadavg").read_text().split()[:3] if Path("/proc/loadavg").exists() else ["?"] * 3
    text = (f"Epochs 2-{args.epochs} of `hrc-lab {' '.join(overrides)}` (evaluation and logging included): {steps} "
            f"training steps in {cpu:.1f} s of CPU time, {steps / cpu:.1f} training steps per CPU second "
            f"({1e6 * cpu / steps:.0f} us per step); wall clock {wall:.1f} s ({steps / wall:.1f} steps/s) at load "
            f"average {' / '.join(load)} on {os.cpu_count()} cores. `us per step`: CPU time per collected training "
            "step (the clock is the process's CPU time, so other processes on the machine do not count).\n\n"
            + frame.round({"calls per step": 2, "us per step": 1, "share %": 1}).to_markdown(index=False))
    print(text)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text + "\n")


if __name__ == "__main__":
    main()
