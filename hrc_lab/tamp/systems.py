"""Table 4.3's systems (thesis 4.4.3) as ``TAMPS.build(cfg.tamp)`` makes them. Each owns its steps of the protocol
(:func:`hrc_lab.experiments.ch4_tamp.table_4_3`), which runs every system the same way:

- ``train(ctx)``: learn (or build) the system's modules for the run;
- ``trials(ctx)``: one row per trial on the run's test scenes (``protocol.trials`` of them, cells seeded
  :data:`hrc_lab.seeds.TEST_SCENES`, CASE 1 and CASE 2 alternating), the same scenes for every system;
- ``videos(ctx)``: one rendered CASE 1 and one CASE 2 trial with what the system does written on the frames.

The systems: :class:`OursSystem` (Algorithm 2 with the reasoning module of Table 4.1 and the two-level motion module
of Table 4.2), :class:`RMRRTConnectSystem` (the same reasoning module with OMPL's RRT-Connect as the motion module),
:class:`DRLSystem` (one DDPG + HER agent, no reasoning or motion module). ``ctx`` is the job's
:class:`~hrc_lab.run_context.RunContext`.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd
from tqdm import tqdm

from hrc_lab.env import ENVS
from hrc_lab.seeds import DRL_DEMO_SCENES, DRL_EVAL_SCENES, TEST_SCENES, scene_seed

if TYPE_CHECKING:
    from hrc_lab.run_context import RunContext

CASES = (1, 2)


def case_spec(ctx: RunContext, case: int):
    """The run's cell config in CASE ``case``."""
    spec = ctx.cfg.env
    return ENVS.derive(spec, sim=dataclasses.replace(spec.sim, case=case))


def case_cell(ctx: RunContext, case: int, **render):
    """The run's cell in CASE ``case``, seeded like every system's test cells."""
    return ENVS.build(case_spec(ctx, case), seed=scene_seed(ctx.seed, TEST_SCENES), **render)


def render_args(protocol) -> dict:
    return dict(has_offscreen_renderer=True, camera_names=protocol.camera, camera_heights=protocol.video_height,
                camera_widths=protocol.video_width)


class TampSystem:
    """A system of Table 4.3 (``cfg``: its ``tamp`` config, which names it); the protocol calls :meth:`train`,
    then :meth:`trials`, then :meth:`videos` in the cells ``protocol.video_cells``."""

    def __init__(self, cfg) -> None:
        self.cfg = cfg
        self.name = cfg.name

    def train(self, ctx: RunContext) -> None:
        raise NotImplementedError

    def trials(self, ctx: RunContext) -> pd.DataFrame:
        """``protocol.trials`` rows, trial k in CASE 1 for even k and CASE 2 for odd k, on one test env per case
        (:meth:`trial_env`), each trial the env's next scene (:meth:`trial`)."""
        envs = {case: self.trial_env(ctx, case) for case in CASES}
        rows = []
        label = f"table 4.3 {ctx.cfg.env.cell} {self.name}"
        for trial in tqdm(range(ctx.cfg.protocol.trials), desc=label, unit="trial"):
            case = CASES[trial % 2]
            rows.append({"trial": trial, "case": case, **self.trial(envs[case])})
        for env in envs.values():
            env.close()
        return pd.DataFrame(rows)

    def trial_env(self, ctx: RunContext, case: int):
        """The env the trials of CASE ``case`` run in (seeded like every system's)."""
        raise NotImplementedError

    def trial(self, env) -> dict:
        """One trial from ``env``'s next scene as a row of the trials table."""
        raise NotImplementedError

    def videos(self, ctx: RunContext) -> list:
        raise NotImplementedError


# --- ours and RM+RRT-Connect: Algorithm 2 -------------------------------------------------------------------------


class Algorithm2System(TampSystem):
    """The reasoning module and a motion module in closed loop (:func:`hrc_lab.tamp.algorithm2.run_tamp`): the
    reasoning module is trained on CASE 1 task episodes of every goal configuration (as Table 4.1's full demo set);
    the motion module is :meth:`build_motion`'s."""

    reasoner = None
    motion = None

    def train(self, ctx: RunContext) -> None:
        self.reasoner = self.train_reasoner(ctx)
        self.motion = self.build_motion(ctx)

    @staticmethod
    def train_reasoner(ctx: RunContext):
        from hrc_lab.env.robot.spec import goal_configurations
        from hrc_lab.reasoning.episodes import demo_repeats, episodes_for
        from hrc_lab.reasoning.training import train

        spec = ctx.cfg.env
        episodes = episodes_for(spec, goal_configurations(spec), ctx.rng(0),
                                demo_repeats(spec, ctx.cfg.protocol.min_demos))
        reasoner, seconds = train(ctx.cfg.reasoning, spec, episodes, ctx.trainer, ctx.seed, prefix="reasoning")
        if hasattr(reasoner, "network"):
            ctx.tracker.log_torch_model(reasoner.network, "model/reasoner.pt")
        ctx.tracker.log_metrics({"reasoning_train_s": seconds})
        return reasoner

    def build_motion(self, ctx: RunContext):
        """The motion module that executes the reasoning module's decisions (``run_stage``)."""
        raise NotImplementedError

    def trial_env(self, ctx: RunContext, case: int):
        return case_cell(ctx, case)

    def trial(self, env) -> dict:
        from hrc_lab.tamp.algorithm2 import run_tamp

        return tamp_row(run_tamp(env, self.reasoner, self.motion))

    def videos(self, ctx: RunContext) -> list:
        from hrc_lab.env.robot.recorder import FrameRecorder, save_video
        from hrc_lab.tamp.algorithm2 import run_tamp

        protocol, paths = ctx.cfg.protocol, []
        for case in CASES:
            cell = case_cell(ctx, case, **render_args(protocol))
            recorder = FrameRecorder(cell, protocol.camera, protocol.video_width, protocol.video_height,
                                     protocol.frame_skip)
            out = run_tamp(recorder, self.reasoner, self.motion,
                           on_decision=lambda d, r=recorder: setattr(r, "text", d.text()))
            recorder.text = "packed" if out.success else f"failed: {out.failure}"
            recorder.frames.append(recorder.frame())
            name = f"{self.name}_{ctx.cfg.env.cell}_case{case}.mp4"
            paths += save_video(recorder.frames, ctx.output_dir / name, cell.control_freq / protocol.frame_skip)
            cell.close()
        return paths


class OursSystem(Algorithm2System):
    """Ours (Algorithm 2): the two-level motion module trained on CASE 1 robot demonstrations, drawn from every goal
    configuration (``protocol.motion_demos=all``, Table 4.3's) or one packing arrangement per selection (``fixed``,
    as Table 4.2)."""

    def build_motion(self, ctx: RunContext):
        from hrc_lab.motion.demonstrations import collect_demos, fixed_goal_configurations
        from hrc_lab.motion.training import train_motion_module

        protocol, spec = ctx.cfg.protocol, ctx.cfg.env
        train_env = ENVS.build(spec, seed=ctx.seed)
        if protocol.motion_demos == "fixed":
            train_env.configurations = fixed_goal_configurations(spec)
        demos = collect_demos(train_env, protocol.demos, f"demos {spec.cell}")
        module = train_motion_module(ctx.cfg.motion, spec.slots, train_env, demos, protocol.max_steps_per_subgoal,
                                     protocol.tolerance, ctx.trainer, ctx.seed, ctx.tracker.log_torch_model)
        train_env.close()
        return module


class RMRRTConnectSystem(Algorithm2System):
    """RM+RRT-Connect: the ``motion`` group's planner (OMPL's RRT-Connect, :mod:`hrc_lab.motion.rrt_connect`), which
    needs no training."""

    def build_motion(self, ctx: RunContext):
        from hrc_lab.motion import MOTIONS

        return MOTIONS.build(ctx.cfg.motion, seed=ctx.seed)


def tamp_row(out) -> dict:
    """An Algorithm 2 trial (:class:`~hrc_lab.tamp.algorithm2.TampRollout`) as a trial row."""
    from hrc_lab.tamp.algorithm2 import REASONING_FAILURES

    per_object = list(out.object_planning_ms.values())
    return {
        "success": out.success,
        "failure": out.failure,
        "failure_kind": "" if not out.failure else ("reasoning" if out.failure in REASONING_FAILURES else "motion"),
        "steps": out.steps,
        "objects": len(out.object_steps),
        "object_steps": float(np.mean(list(out.object_steps.values()))) if out.object_steps else np.nan,
        "planning_ms_per_object": float(np.mean(per_object)) if per_object else np.nan,
        "reasoning_ms": float(np.median([d.reasoning_ms for d in out.decisions])) if out.decisions else np.nan,
        "decisions": " ".join(d.text().replace(" ", "_") for d in out.decisions),
        "collision": out.collisions[0] if out.collisions else "",
    }


# --- DRL ------------------------------------------------------------------------------------------------------------


DRL_AGENT_DIR = "agent"


class DRLSystem(TampSystem):
    """DRL: one DDPG + HER agent (:mod:`hrc_lab.rl`) trained on CASE 1 and CASE 2, then its deterministic policy; a
    trial succeeds if the order is packed (Eq. 4.7) with no collision when its episode ends (failures ``collision``
    or ``goal``: the order was not packed when the episode ended)."""

    agent = None

    def train(self, ctx: RunContext) -> None:
        """``protocol.drl_demos`` scripted-expert episodes (either case) into its demonstration buffer, then
        ``protocol.drl_iterations`` cycles of training (:mod:`hrc_lab.rl.trainer`: the thesis' iterations read as
        the HER reference implementation's cycles), CASE 1 or 2 drawn per episode, on ``rl.n_envs`` envs; per epoch
        the training rates, the throughput and ``protocol.drl_eval_episodes`` evaluation episodes go to MLflow, the
        agent to the artifacts (every ``checkpoint_every`` epochs too, from which a killed run resumes)."""
        from hrc_lab.rl import RLS, trainer
        from hrc_lab.rl.agent import add_demonstrations, evaluate, save_agent
        from hrc_lab.rl.evaluation import evaluation_seed
        from hrc_lab.rl.goal_env import make_goal_env

        protocol, rl = ctx.cfg.protocol, ctx.cfg.rl
        envs = trainer.training_envs(trainer.goal_env_factory(ctx.cfg.env, rl, ctx.seed, cases=CASES), rl.n_envs)
        agent = ctx.resume_agent(DRL_AGENT_DIR, envs)
        if agent is None:
            agent = RLS.build(rl, env=envs, seed=ctx.seed)
            if protocol.drl_demos:
                demo_env = make_goal_env(ctx.cfg.env, rl, seed=scene_seed(ctx.seed, DRL_DEMO_SCENES),
                                         cases=CASES)  # not the test scenes
                ctx.tracker.log_metrics({"demo_success_rate": add_demonstrations(agent, demo_env, protocol.drl_demos)})
                demo_env.close()
        test = make_goal_env(ctx.cfg.env, rl, seed=scene_seed(ctx.seed, DRL_EVAL_SCENES),
                             cases=CASES)  # held out from the trials' scenes

        def save(agent) -> None:
            save_agent(agent, ctx.output_dir / DRL_AGENT_DIR, replay_buffer=False)
            ctx.tracker.log_artifact(ctx.output_dir / DRL_AGENT_DIR, DRL_AGENT_DIR)

        epochs = -(-protocol.drl_iterations // rl.cycles_per_epoch)
        done = trainer.completed_epochs(agent, rl)
        if done:  # the resumed run's curve up to its checkpoint, its demonstrations' success rate included
            ctx.tracker.copy_history(done)
        trainer.train_epochs(
            agent, rl, epochs,
            evaluate=(lambda agent, epoch: evaluate(agent, test, protocol.drl_eval_episodes,
                                                    seed=evaluation_seed(epoch)))
            if protocol.drl_eval_episodes else None,
            log=ctx.tracker.log_metrics, save=save, checkpoint_every=protocol.checkpoint_every,
            desc=f"drl {ctx.cfg.env.cell}")
        epoch_times = ctx.tracker.client.get_metric_history(ctx.tracker.run_id, "epoch_s")
        ctx.tracker.log_metrics({"drl_train_s": sum(m.value for m in epoch_times)})  # resumed epochs included
        envs.close()
        test.close()
        self.agent = agent

    def trial_env(self, ctx: RunContext, case: int):
        return drl_goal_env(ctx, case)

    def trial(self, env) -> dict:
        return drl_episode(self.agent, env)

    def videos(self, ctx: RunContext) -> list:
        from hrc_lab.env.robot.recorder import FrameRecorder, save_video

        protocol, paths = ctx.cfg.protocol, []
        for case in CASES:
            goal_env = drl_goal_env(ctx, case, **render_args(protocol))
            cell = goal_env.cell
            goal_env.cell = recorder = FrameRecorder(cell, protocol.camera, protocol.video_width,
                                                     protocol.video_height, protocol.frame_skip)
            recorder.text = "DRL: flat policy, no plan"
            row = drl_episode(self.agent, goal_env)
            recorder.text = "packed" if row["success"] else f"failed: {row['failure']}"
            recorder.frames.append(recorder.frame())
            name = f"drl_{ctx.cfg.env.cell}_case{case}.mp4"
            paths += save_video(recorder.frames, ctx.output_dir / name, cell.control_freq / protocol.frame_skip)
            cell.close()
        return paths


def drl_episode(agent, goal_env) -> dict:
    """One deterministic episode from the goal env's next scene as a trial row: success at its end (Eq. 4.7, no
    collision) and the steps per product until the order was first packed."""
    from hrc_lab.rl.agent import run_episode

    info, first = run_episode(agent, goal_env)
    success = bool(info["is_success"])
    n = goal_env.cell.spec.n_selected
    return {"success": success, "failure": "" if success else ("collision" if info["collided"] else "goal"),
            "failure_kind": "" if success else "motion", "steps": goal_env.elapsed_steps,
            "objects": n if success else 0, "object_steps": first / n if success and first else np.nan,
            "planning_ms_per_object": np.nan, "reasoning_ms": np.nan, "decisions": "",
            "collision": info["collisions"][0] if info["collisions"] else ""}


def drl_goal_env(ctx: RunContext, case: int, **render):
    """The DRL agent's goal env on the run's test cell in CASE ``case`` (:func:`case_cell`'s config and seed)."""
    from hrc_lab.rl.goal_env import make_goal_env

    goal_env = make_goal_env(case_spec(ctx, case), ctx.cfg.rl, seed=scene_seed(ctx.seed, TEST_SCENES), **render)
    # its first scene is the first trial's, as for the other systems
    goal_env.cell.reseed(scene_seed(ctx.seed, TEST_SCENES))
    return goal_env
