"""Ch.3 hybrid hierarchical guided RL (thesis 3.2.3 Algorithm 1, 3.3, 3.4.3): Fig. 3.13 (error correction, guidance
ratio lambda), Fig. 3.12 (place and stack, NDP guidance vs none) and Fig. 3.9 (the end effector's
distance to the planner's sub-goal, the goal-state positional difference, in guided vs unguided exploration).

The two-level planner (task classifier c(x), sub-goal planner h, neural dynamic planner d) is trained from the
scripted expert's demonstrations as in Table 3.1 (:func:`hrc_lab.motion.training.train_two_level`); it then
guides a stable-baselines3 DDPG + HER agent (:mod:`hrc_lab.rl`) in a fraction ``rl.lam`` of the episodes.

**Epoch**: the HER reference implementation's, which the thesis' 550 epochs are read as (:mod:`hrc_lab.rl.trainer`):
``rl.cycles_per_epoch`` cycles of ``rl.episodes_per_cycle`` training episodes of ``rl.steps_per_subtask`` control
steps, each cycle followed by ``rl.gradient_steps`` gradient steps and one target update; then
``protocol.eval_episodes`` evaluation episodes of the deterministic policy on held-out scenes (no noise, no
guidance). The subtasks of a correction plan are trained in sequence, one agent each, ``protocol.epochs`` epochs
per subtask; epoch ``k * epochs + e`` of the run is epoch ``e`` of subtask ``k``. Every epoch logs
``success_rate``, ``collision_rate``, ``final_distance``, ``grip_rate`` and ``moved_rate`` (evaluation;
:func:`~hrc_lab.rl.agent.evaluate`), ``train_success_rate``, ``train_collision_rate``, ``train_grip_rate``,
``train_moved_rate``, ``train_final_distance`` and ``train_guidance_rate`` (that epoch's training episodes,
exploration noise and guidance included; :class:`~hrc_lab.rl.agent.EpisodeMetrics`), ``env_steps_per_s``,
``updates_per_s``, ``epoch_s`` and ``learning_rate`` as MLflow metrics with ``step`` = the epoch. After its last
epoch each subtask's agent, the final policy, plays ``protocol.final_eval_episodes`` held-out scenes that no epoch
saw: ``final_policy_success_rate`` (mean over the subtasks), the lower-noise final SR.
"""

from __future__ import annotations

import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pandas as pd

from hrc_lab.cache import cache_key, cached
from hrc_lab.env import ENVS
from hrc_lab.run_context import RunContext
from hrc_lab.seeds import EXPERT_DEMO_SCENES, scene_seed

AGENTS_DIR = "agents"


def guided(ctx: RunContext) -> bool:
    """Whether the run's agent is ever guided (``rl=ddpg_her_guided`` with lambda > 0)."""
    return ctx.cfg.rl.name == "ddpg_her_guided" and ctx.cfg.rl.lam > 0


GUIDE_DEMO_STREAM = 5  # the guide's demonstrations draw from the run's random stream [seed, 5] (RunContext.rng)


def guide_demos(cfg, seed: int):
    """The ``protocol.demos`` expert demonstrations of ``cfg.env`` the guide learns from, with the env they ran in."""
    from hrc_lab.motion.demonstrations import correction_demos

    protocol = cfg.protocol
    env = ENVS.build(cfg.env, seed=seed)
    demos = correction_demos(env, protocol.demos, protocol.subgoals_per_stage, protocol.segmentation_penalty,
                             f"demos {cfg.env.cell}", protocol.placement_noise,
                             np.random.default_rng([seed, GUIDE_DEMO_STREAM]), subgoal_path=protocol.subgoal_path)
    if not demos:
        raise RuntimeError(f"no successful expert demonstration in {protocol.demos} for {cfg.env.cell}")
    return env, demos


def train_guide_models(cfg, seed: int, trainer, stage_starts: tuple[str, ...] | None = None, demonstrations=None):
    """Classifier c(x), sub-goal planner and neural dynamic planner of the Ch.3 two-level planner, trained as Table
    3.1 trains them on the guide's demonstrations (``demonstrations``: :func:`guide_demos`' (env, demos), made here
    when None; ``trainer(prefix)`` builds each Lightning Trainer; ``stage_starts`` replaces
    ``protocol.stage_starts``). Also used by ``scripts/ch3_guide_rollouts.py``."""
    from hrc_lab.motion.training import train_two_level

    env, demos = demonstrations or guide_demos(cfg, seed)
    return train_two_level(cfg.motion, env, demos, tuple(stage_starts or cfg.protocol.stage_starts),
                           cfg.protocol.subgoals_per_stage, trainer, seed)


GUIDE_CACHE_FORMAT = 1  # raise when the cached file's contents or what trains the guide change
# the protocol keys the guide's demonstrations and training read (guide_demos, train_guide_models)
GUIDE_PROTOCOL_KEYS = ("demos", "subgoals_per_stage", "segmentation_penalty", "placement_noise", "subgoal_path",
                       "stage_starts")
# trainer keys that change what a fit shows or where it writes, not what it trains
TRAINER_DISPLAY_KEYS = ("default_root_dir", "enable_progress_bar", "enable_model_summary")


def guide_cache_key(cfg, seed: int) -> str:
    """The guide's cache key: everything :func:`train_guide_models` depends on. The seed, the env (its demonstrations'
    scenes and cell), the ``motion`` config (classifier, sub-goal planner, NDP), the protocol keys of
    :data:`GUIDE_PROTOCOL_KEYS`, the trainer's settings (but where it writes and what it prints), the CPU kernels
    and torch's thread count (other kernels or threads round differently, :mod:`hrc_lab.kernels`), and
    :data:`GUIDE_CACHE_FORMAT`. Not the ``rl`` config: lambda, delta_g and H_lo use the guide, they do not train it
    (so the arms of a Fig. 3.13 sweep with one seed and env share it)."""
    import torch

    from hrc_lab.kernels import cpu_kernels

    trainer = {k: v for k, v in asdict(cfg.trainer).items() if k not in TRAINER_DISPLAY_KEYS}
    return cache_key({"format": GUIDE_CACHE_FORMAT, "seed": int(seed), "env": asdict(cfg.env),
                      "motion": asdict(cfg.motion),
                      "protocol": {k: getattr(cfg.protocol, k) for k in GUIDE_PROTOCOL_KEYS},
                      "trainer": trainer, "kernels": cpu_kernels(), "threads": torch.get_num_threads()}, length=16)


def guide_cache_path(cfg, seed: int) -> Path:
    return Path(cfg.paths.runs_dir) / "cache" / "ch3" / f"guide_{guide_cache_key(cfg, seed)}.pkl"


def load_or_train_guide_models(cfg, seed: int, trainer, fitted_metrics=None, path: Path | None = None):
    """:func:`train_guide_models` once per :func:`guide_cache_key`: from ``<paths.runs_dir>/cache/ch3/guide_<key>.pkl``
    (``path``) when a job already trained it, else trained (the global generators seeded with ``seed`` first, as a
    job starts, so the models do not depend on what ran before in the process) and saved there; parallel jobs wait
    for the first (:func:`hrc_lab.cache.cached`). ``fitted_metrics()``: the metric histories the fits logged
    (``{key: [(step, value), ...]}``), stored with the models, so a job that loads them can log them as its own.
    Returns (classifier, planner, ndp), the stored metric histories and whether they came from the cache."""
    import pickle

    import lightning.pytorch as pl

    path = guide_cache_path(cfg, seed) if path is None else path
    trained: list = []

    def build(partial: Path) -> None:
        pl.seed_everything(seed, workers=True, verbose=False)
        models = train_guide_models(cfg, seed, trainer)
        metrics = fitted_metrics() if fitted_metrics is not None else {}
        trained.append((models, metrics))
        with open(partial, "wb") as file:
            pickle.dump({"format": GUIDE_CACHE_FORMAT, "models": models, "metrics": metrics}, file,
                        protocol=pickle.HIGHEST_PROTOCOL)

    cached(path, build)
    if trained:
        return trained[0][0], trained[0][1], False
    with open(path, "rb") as file:
        saved = pickle.load(file)
    if not isinstance(saved, dict) or saved.get("format") != GUIDE_CACHE_FORMAT:
        raise RuntimeError(f"{path}: not a guide of cache format {GUIDE_CACHE_FORMAT}; delete it to retrain")
    return saved["models"], saved["metrics"], True


def train_guide(ctx: RunContext):
    """The Ch.3 two-level planner (:func:`train_guide_models`, once per sweep's seed and env:
    :func:`load_or_train_guide_models`) as Algorithm 1's guide (:class:`~hrc_lab.rl.guidance.CorrectionGuide`), its
    networks logged into the run; a job that found it cached logs the fits' metrics the cache stores (tag
    ``guide_cache``: ``hit`` or ``miss`` and the key)."""
    from hrc_lab.rl.guidance import CorrectionGuide

    tracker = ctx.tracker
    before = set(tracker.client.get_run(tracker.run_id).data.metrics)

    def fitted_metrics() -> dict[str, list[tuple[int, float]]]:
        logged = set(tracker.client.get_run(tracker.run_id).data.metrics) - before
        return {key: [(m.step, m.value) for m in sorted(tracker.client.get_metric_history(tracker.run_id, key),
                                                         key=lambda m: (m.timestamp, m.step))]
                for key in sorted(logged)}

    (classifier, planner, ndp), metrics, hit = load_or_train_guide_models(ctx.cfg, ctx.seed, ctx.trainer,
                                                                          fitted_metrics)
    tracker.client.set_tag(tracker.run_id, "guide_cache", f"{'hit' if hit else 'miss'} "
                                                          f"{guide_cache_key(ctx.cfg, ctx.seed)}")
    if hit:  # the fits' curves, as the job that trained the guide logged them
        from mlflow.entities import Metric

        now = int(time.time() * 1000)
        batch = [Metric(key, float(value), now, int(step)) for key, history in metrics.items()
                 for step, value in history]
        for start in range(0, len(batch), 500):
            tracker.client.log_batch(tracker.run_id, metrics=batch[start : start + 500])
    tracker.log_torch_model(planner.network, "model/subgoal.pt")
    tracker.log_torch_model(ndp.network, "model/ndp.pt")
    return CorrectionGuide.from_config(ctx.cfg.rl, classifier, planner, ndp, ctx.cfg.protocol.subgoals_per_stage)


def training_envs(ctx: RunContext, guide, subtask: int):
    """The run's ``rl.n_envs`` training envs of ``subtask``, guided by ``guide`` when the run is guided."""
    from hrc_lab.rl import trainer

    factory = trainer.goal_env_factory(ctx.cfg.env, ctx.cfg.rl, ctx.seed, guide, subtask=subtask)
    return trainer.training_envs(factory, ctx.cfg.rl.n_envs)


def save_checkpoint(ctx: RunContext, agent, subtask: int) -> None:
    """The agent (its demonstrations, and its replay buffer when small) under the run's ``agents/subtask<k>/``."""
    from hrc_lab.rl.agent import save_agent

    folder = f"{AGENTS_DIR}/subtask{subtask}"
    save_agent(agent, ctx.output_dir / folder)
    ctx.tracker.log_artifact(ctx.output_dir / folder, folder)


EPOCH_METRICS = ("success_rate", "collision_rate", "final_distance", "grip_rate", "moved_rate",
                 "train_success_rate", "train_collision_rate", "train_grip_rate", "train_moved_rate",
                 "train_final_distance", "train_guidance_rate", "env_steps_per_s", "updates_per_s", "epoch_s",
                 "learning_rate", "subtask")


def add_expert_demos(ctx: RunContext, agent, subtask: int) -> None:
    """``protocol.expert_demos`` scripted-expert episodes of ``subtask`` into the agent's demonstration buffer, on
    scenes of their own seed stream (not the training or evaluation scenes)."""
    from hrc_lab.rl.agent import add_demonstrations
    from hrc_lab.rl.goal_env import make_goal_env

    env = make_goal_env(ctx.cfg.env, ctx.cfg.rl, seed=scene_seed(ctx.seed, EXPERT_DEMO_SCENES), subtask=subtask)
    success = add_demonstrations(agent, env, ctx.cfg.protocol.expert_demos)
    ctx.tracker.log_metrics({f"expert_demo_success_rate_subtask{subtask}": success})
    env.close()


def train_subtasks(ctx: RunContext) -> dict[str, float]:
    """Train one agent per subtask of the env's correction plan, in sequence, ``protocol.epochs`` epochs each
    (module docstring; the loop is :func:`hrc_lab.rl.trainer.train_epochs`); per-epoch metrics with step = epoch;
    the final agents as artifacts."""
    from hrc_lab.rl import RLS
    from hrc_lab.rl.agent import evaluate
    from hrc_lab.rl.evaluation import FINAL_EVALUATION_SEED, evaluation_env, evaluation_seed
    from hrc_lab.rl.goal_env import make_goal_env
    from hrc_lab.rl.trainer import completed_epochs, episodes_per_epoch, train_epochs

    protocol, rl = ctx.cfg.protocol, ctx.cfg.rl
    guide = train_guide(ctx) if guided(ctx) else None
    probe = make_goal_env(ctx.cfg.env, rl, seed=ctx.seed, subtask=0)
    n_subtasks = len(probe.cell.expert_plan())
    horizon = probe.horizon
    probe.close()
    finals: list[dict[str, float]] = []  # each subtask's final policy on protocol.final_eval_episodes scenes
    for subtask in range(n_subtasks):
        envs = training_envs(ctx, guide, subtask)
        test = evaluation_env(ctx.cfg.env, rl, ctx.seed, subtask)
        agent = ctx.resume_agent(f"{AGENTS_DIR}/subtask{subtask}", envs)
        if agent is None:
            agent = RLS.build(rl, env=envs, seed=ctx.seed)
            if protocol.expert_demos:
                add_expert_demos(ctx, agent, subtask)
        done = completed_epochs(agent, rl)
        if done:  # the curve of the subtask's epochs the checkpoint holds
            ctx.tracker.copy_history(subtask * protocol.epochs + done, after_step=subtask * protocol.epochs,
                                     keys=EPOCH_METRICS)
        train_epochs(agent, rl, protocol.epochs,
                     evaluate=lambda agent, epoch, test=test: evaluate(agent, test, protocol.eval_episodes,
                                                                       seed=evaluation_seed(epoch)),
                     log=lambda metrics, step, k=subtask: ctx.tracker.log_metrics({**metrics, "subtask": float(k)},
                                                                                  step=step),
                     save=lambda agent, k=subtask: save_checkpoint(ctx, agent, k),
                     checkpoint_every=protocol.checkpoint_every, step_offset=subtask * protocol.epochs,
                     desc=f"{ctx.cfg.env.cell} subtask {subtask}")
        if protocol.final_eval_episodes:  # the final policy on scenes of its own
            final = evaluate(agent, test, protocol.final_eval_episodes, seed=FINAL_EVALUATION_SEED)
            finals.append(final)
            ctx.tracker.log_metrics({f"final_policy_{key}_subtask{subtask}": v for key, v in final.items()})
        envs.close()
        test.close()
    # the run's curves as MLflow holds them (a resumed run's include the epochs it copied)
    history = {key: {m.step: m.value for m in ctx.tracker.client.get_metric_history(ctx.tracker.run_id, key)}
               for key in EPOCH_METRICS}
    curves = pd.DataFrame(history).rename_axis("epoch").reset_index().sort_values("epoch")
    ctx.tracker.log_table(curves, "epochs")
    last = curves.groupby("subtask").tail(1)
    collected = n_subtasks * protocol.epochs * episodes_per_epoch(rl) * horizon
    final_policy = {name: float(np.mean([f[key] for f in finals])) for name, key in
                    {"final_policy_success_rate": "success_rate", "final_policy_collision_rate": "collision_rate",
                     "final_policy_distance": "final_distance"}.items()} if finals else {}
    return {
        **final_policy,  # mean over the plan's subtasks of each final policy's scores
        # the overall success rate: mean over the plan's subtasks of the last epoch's evaluation
        "final_success_rate": float(last.success_rate.mean()),
        "final_collision_rate": float(last.collision_rate.mean()),
        "final_distance": float(last.final_distance.mean()),
        "final_grip_rate": float(last.grip_rate.mean()),
        "final_moved_rate": float(last.moved_rate.mean()),
        "final_train_success_rate": float(last.train_success_rate.mean()),
        "final_train_grip_rate": float(last.train_grip_rate.mean()),
        "final_train_moved_rate": float(last.train_moved_rate.mean()),
        "final_train_distance": float(last.train_final_distance.mean()),
        "best_success_rate": float(curves.groupby("subtask").success_rate.max().mean()),
        "mean_guidance_rate": float(curves.train_guidance_rate.mean()),
        "mean_env_steps_per_s": float(curves.env_steps_per_s.mean()),
        "mean_updates_per_s": float(curves.updates_per_s.mean()),
        "n_subtasks": float(n_subtasks),
        "n_env_steps": float(collected),
    }


def fig_3_13(ctx: RunContext) -> dict[str, float]:
    """Error correction: hybrid (lambda 0.7) vs full guidance (1) vs pure exploration (0); per-epoch curves."""
    return train_subtasks(ctx)


def fig_3_12(ctx: RunContext) -> dict[str, float]:
    """Place and stack: DRL guided by the direction-only NDP (lambda > 0) vs unguided DRL (lambda 0)."""
    return train_subtasks(ctx)


def fig_3_9(ctx: RunContext) -> dict[str, float]:
    """The goal-state positional difference |Delta| = |p'_T - r| (the distance from the end effector to the
    two-level planner's current sub-goal, as in 3.2.2 and Fig. 3.8, where the demonstrations' |Delta| stays under
    0.12 m) over exploration episodes of random actions (SB3's warm-up: ``rl.learning_starts`` is raised above the
    episodes' steps, so no network acts), corrected by Algorithm 1 in every episode (lambda 1) or never (lambda 0),
    on the same seeded scenes. In the unguided arm the guide only keeps track of its sub-goals; it never acts.
    Per control step, the mean over episodes is logged as ``distance_guided`` / ``distance_unguided`` with step =
    control step; ``goal_distance_*`` is the end effector's distance to the task goal (the object's goal)."""
    from stable_baselines3.common.callbacks import BaseCallback

    from hrc_lab.rl import RLS
    from hrc_lab.rl.agent import learn_episodes
    from hrc_lab.rl.goal_env import make_goal_env
    from hrc_lab.rl.guidance import GuidedEnv

    protocol = ctx.cfg.protocol
    guide = train_guide(ctx)
    rows = []

    class Distances(BaseCallback):
        def __init__(self, arm: str) -> None:
            super().__init__()
            self.arm, self.episode = arm, 0

        def _on_step(self) -> bool:
            if self.locals["dones"][0]:  # the vec env has already reset: the last step's state is gone
                self.episode += 1
                return True
            env = self.model.get_env().envs[0].unwrapped
            if self.arm == "unguided":  # the guide follows its sub-goals without acting
                if env.elapsed_steps == 1:
                    guide.reset(env)
                subgoal = guide.subgoal(env)
            else:
                subgoal = guide.current  # the sub-goal Algorithm 1 corrected towards in this step
            eef = env.cell.eef_position()
            rows.append({"arm": self.arm, "episode": self.episode, "step": env.elapsed_steps,
                         "distance": float(np.linalg.norm(eef - subgoal)),
                         "goal_distance": float(np.linalg.norm(eef - env.desired_goal()[:3]))})
            return True

    for arm, lam in (("guided", 1.0), ("unguided", 0.0)):
        rl = RLS.derive(ctx.cfg.rl, lam=lam,
                        learning_starts=protocol.episodes * ctx.cfg.rl.steps_per_subtask * 10 + 1)
        env = make_goal_env(ctx.cfg.env, rl, seed=ctx.seed, subtask=0)
        env.reset(seed=ctx.seed)  # the same scenes for both arms
        if lam:
            env = GuidedEnv(env, guide, lam, rl.delta_g, seed=ctx.seed)
        agent = RLS.build(rl, env=env, seed=ctx.seed)
        learn_episodes(agent, protocol.episodes, Distances(arm))
        env.close()
    frame = pd.DataFrame(rows)
    ctx.tracker.log_table(frame, "distances")
    curve = frame.groupby(["arm", "step"]).distance.mean()
    for arm in ("guided", "unguided"):
        for step, value in curve[arm].items():
            ctx.tracker.log_metrics({f"distance_{arm}": float(value)}, step=int(step))
    metrics = {}
    for arm, part in frame.groupby("arm"):
        metrics[f"mean_goal_distance_{arm}"] = float(part.goal_distance.mean())
        metrics[f"mean_distance_{arm}"] = float(part.distance.mean())
        metrics[f"p95_distance_{arm}"] = float(part.distance.quantile(0.95))
        metrics[f"within_{protocol.within_m:g}_{arm}"] = float((part.distance <= protocol.within_m).mean())
    return metrics
