"""Demonstration jobs on the robot cells: ``collect`` (expert episodes -> HDF5, with its success rate, speed and the
stage-segmentation check) and ``render_demo`` (one expert episode rendered off-screen to MP4)."""

from __future__ import annotations

import dataclasses
import json
import shutil
import time
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm import tqdm

from hrc_lab.data.recording import record_episode
from hrc_lab.env import ENVS
from hrc_lab.run_context import RunContext


def _env_args(ctx: RunContext, env) -> dict:
    config = ctx.cfg.env
    return {
        "env_name": type(env).__name__,
        "type": 1,  # robomimic's EnvType.ROBOSUITE_TYPE
        "env_kwargs": {"control_freq": env.control_freq, "horizon": env.horizon},
        "hrc_lab_env": {"name": config.name, **json.loads(json.dumps(dataclasses.asdict(config)))},
        "stage_label_offset": 1 if type(env).__name__ == "ErrorCorrection" else 0,
        "seed": ctx.seed,
    }


def env_speed(env, steps: int = 200) -> float:
    """Control steps per second of the cell alone (arm holding still, suction off), no rendering."""
    env.reset()
    hold = np.zeros(env.policy_action_dim)
    hold[-1] = -1.0
    start = time.perf_counter()
    for _ in range(steps):
        env.step(hold)
    return steps / (time.perf_counter() - start)


def segment(demo, label_of, protocol) -> float:
    """Add the change-point stages and their sub-goals to the demo; return the step-wise agreement of the
    detected stages (picking ending with the lift, as the expert labels it) with the expert's own labels."""
    from hrc_lab.data.segmentation import agreement, detect_stages, stage_labels, stage_subgoals

    demo.stage_bounds, demo.stage_subgoals = stage_subgoals(
        demo, label_of, protocol.subgoals_per_stage, protocol.subgoal_mode, protocol.segmentation_penalty)
    stages = detect_stages(demo.obs["object_pos"].reshape(len(demo), -1, 3), protocol.segmentation_penalty)
    return agreement(stage_labels(stages, len(demo), label_of), demo.stage_labels)


def collect(ctx: RunContext) -> dict[str, float]:
    """Expert demonstrations of one scenario into ``<paths.runs_dir>/data/<scenario>.hdf5`` (or protocol.output)."""
    from hrc_lab.data.demos import DemoWriter
    from hrc_lab.env.robot.expert import ScriptedExpert

    protocol = ctx.cfg.protocol
    scenario = getattr(ctx.cfg.env, "scenario", ctx.cfg.env.cell)
    env = ENVS.build(ctx.cfg.env, seed=ctx.seed)
    expert = ScriptedExpert(env, max_steps_per_subgoal=protocol.max_steps_per_subgoal)
    speed = env_speed(env)
    env.reseed(ctx.seed)  # the demonstrations do not depend on the speed probe
    path = Path(protocol.output or Path(ctx.cfg.paths.runs_dir) / "data" / f"{scenario}_seed{ctx.seed}.hdf5")
    rows = []
    start = time.perf_counter()
    with DemoWriter(path, _env_args(ctx, env)) as writer:
        for _ in tqdm(range(protocol.episodes), desc=f"collect {scenario}", unit="demo"):
            demo = record_episode(env, expert)
            agreement = segment(demo, env.stage_label, protocol)
            name = writer.add(demo)
            rows.append({"demo": name, "success": demo.success, "steps": len(demo),
                         "objects": len(demo.episode["plan"]),
                         "collisions": ";".join(demo.episode["collisions"]), "agreement": agreement})
    elapsed = time.perf_counter() - start
    table = pd.DataFrame(rows)
    ctx.tracker.log_table(table, "demos")
    ctx.tracker.log_text(str(path.resolve()), "dataset_path.txt")
    metrics = {
        "expert_success_rate": float(table.success.mean()),
        "steps_per_demo": float(table.steps.mean()),
        "steps_per_object": float(table.steps.sum() / table.objects.sum()),
        "segmentation_agreement": float(table.agreement.mean()),
        "env_steps_per_s": speed,
        "collect_steps_per_s": float(table.steps.sum() / elapsed),
        "demos_per_min": protocol.episodes / elapsed * 60,
        "n_demos": float(protocol.episodes),
    }
    return metrics


def render_demo(ctx: RunContext) -> dict[str, float]:
    """One expert episode rendered off-screen to ``<output dir>/<scenario>.mp4`` (and ``protocol.publish_dir``)."""
    from hydra.core.hydra_config import HydraConfig

    from hrc_lab.env.robot.expert import ScriptedExpert
    from hrc_lab.env.robot.recorder import FrameRecorder, save_video

    protocol = ctx.cfg.protocol
    scenario = getattr(ctx.cfg.env, "scenario", ctx.cfg.env.cell)
    cell = ENVS.build(ctx.cfg.env, seed=ctx.seed, has_offscreen_renderer=True, camera_names=protocol.camera,
                      camera_heights=protocol.height, camera_widths=protocol.width)
    env = FrameRecorder(cell, protocol.camera, protocol.width, protocol.height, protocol.frame_skip)
    env.reset()
    expert = ScriptedExpert(env)
    info = {"success": False}
    with tqdm(desc=f"render {scenario}", unit="step") as bar:
        while (step := expert.act()) is not None and not env.done:
            _, _, _, info = env.step(step.action)
            bar.update()
    out = Path(HydraConfig.get().runtime.output_dir) / f"{scenario}.mp4"
    paths = save_video(env.frames, out, cell.control_freq / protocol.frame_skip)
    cell.close()
    for path in paths:
        ctx.tracker.log_artifact(path, "video")
        if protocol.publish_dir:
            Path(protocol.publish_dir).mkdir(parents=True, exist_ok=True)
            shutil.copy(path, Path(protocol.publish_dir) / path.name)
    return {"success": float(bool(info.get("success"))), "steps": float(env.steps), "frames": float(len(env.frames))}
