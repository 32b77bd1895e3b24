"""Ch.5 perception protocols (Sec. 5.4.1, 5.4.3): Fig. 5.5 / 5.6 (the action detector and its baselines on
generated action clips), Table 5.2 end to end (generated assembly sessions streamed through MediaPipe tracking ->
action detector -> semantic planner, Algorithm 3), the same sessions with the robot cell executing the loop's
commands (5.2.3; :mod:`hrc_lab.perception.robot_cell`) and the annotation of any video with the same pipeline.

The clip set depends on ``protocol.data_seed``, the video spec and the window sizes only; it is tracked once and
cached under ``<paths.runs_dir>/cache/ch5`` (file lock), so every method and seed of a sweep reads the same
windows. Fig. 5.6: ``seed`` fixes the 0.8 / 0.2 split and the initialisation. Table 5.2: one detector trained on
the whole clip set (seed ``data_seed``, cached) serves every job; ``seed`` fixes the sessions and the planner.

This module reads the run's config and logs; the work is in :mod:`hrc_lab.perception`: the clip set, its split and
cache (:mod:`~hrc_lab.perception.dataset`), its windows at a method's sizes
(:func:`~hrc_lab.perception.action_detector.action_windows`), the shared detector
(:mod:`~hrc_lab.perception.detector_cache`), session scoring (:mod:`~hrc_lab.perception.sessions`), latency
(:mod:`~hrc_lab.perception.latency`), figures (:mod:`~hrc_lab.perception.figures`) and video files
(:mod:`~hrc_lab.data.video_io`).
"""

from __future__ import annotations

import logging
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm import tqdm

from hrc_lab.data.video_io import read_video, write_video
from hrc_lab.env.assembly.spec import action_labels, scenarios
from hrc_lab.env.assembly.video import Clip, render_action_clip, render_session
from hrc_lab.perception.action_detector import ActionDetector, action_windows
from hrc_lab.perception.dataset import ActionSet, action_set_key, cached_action_set, stored_sizes, stratified_split
from hrc_lab.perception.detector_cache import load_or_train_action_detector, train_action_detector
from hrc_lab.perception.figures import confusion_figure, session_strip
from hrc_lab.perception.latency import classify_ms, tracking_ms_per_frame
from hrc_lab.perception.pipeline import annotate_frames
from hrc_lab.perception.robot_cell import CellHands, SideBySide
from hrc_lab.perception.sessions import run_session
from hrc_lab.reasoning.hrc_loop import SemanticPlannerLoop
from hrc_lab.reasoning.training import train_planner
from hrc_lab.run_context import RunContext

SPLIT, SESSIONS = 60, 61  # random streams
log = logging.getLogger("hrc_lab")


def cache_dir(ctx: RunContext) -> Path:
    return Path(ctx.cfg.paths.runs_dir) / "cache" / "ch5"


def clip_set(ctx: RunContext) -> dict:
    """What the tracked clip set depends on (the arguments of :func:`~hrc_lab.perception.dataset.action_set_key`)."""
    protocol, spec = ctx.cfg.protocol, ctx.cfg.env
    return {"ato": spec, "video": spec.video, "clips_per_class": protocol.clips_per_class,
            "data_seed": protocol.data_seed, "sizes": stored_sizes(protocol.tracker_complexity)}


def action_set(ctx: RunContext) -> ActionSet:
    """The tracked clip set of every Table 5.1 action, from the cache when another job already built it."""
    settings = clip_set(ctx)
    return cached_action_set(cache_dir(ctx), **settings, workers=ctx.cfg.protocol.workers)


def shared_detector(ctx: RunContext, data: ActionSet) -> ActionDetector:
    """The detector trained on the whole clip set with seed ``data_seed`` (cached, shared by the jobs)."""
    return load_or_train_action_detector(ctx.cfg.perception, data, action_set_key(**clip_set(ctx)),
                                         ctx.cfg.protocol.data_seed, lambda: ctx.trainer("detector"), cache_dir(ctx))


def fig_5_6(ctx: RunContext) -> dict[str, float]:
    cfg, protocol = ctx.cfg.perception, ctx.cfg.protocol
    data = action_set(ctx)
    train, test = stratified_split(data.labels, protocol.train_fraction, ctx.rng(SPLIT))
    detector = train_action_detector(cfg, data.subset(train), ctx.seed, lambda: ctx.trainer("detector")).eval()
    predicted = detector.predict_proba(action_windows(cfg, data)).argmax(1)
    correct = predicted == data.labels
    confusion = np.zeros((len(data.names),) * 2, dtype=int)
    np.add.at(confusion, (data.labels, predicted), 1)
    method = ctx.cfg.perception.name
    ctx.tracker.log_figure(confusion_figure(confusion, data.names, f"{method}, seed {ctx.seed}: all clips"),
                           "figures/confusion.png")
    ctx.tracker.log_table(pd.DataFrame(confusion, index=data.names, columns=data.names).reset_index(),
                          "confusion")
    sample = render_action_clip(ctx.cfg.env, ctx.cfg.env.video, data.names[0], int(data.clip_seeds[0]))
    tracking = tracking_ms_per_frame(sample.frames, protocol.tracker_complexity)
    classify = classify_ms(detector, data, protocol.latency_windows)
    ctx.tracker.log_torch_model(detector, "model/action_detector.pt")
    return {
        "train_acc": float(correct[train].mean()),
        "test_acc": float(correct[test].mean()),
        "all_acc": float(correct.mean()),
        "n_train": float(len(train)),
        "n_test": float(len(test)),
        "tracked_fraction": float(data.tracked.mean()),
        "tracking_ms_per_frame": tracking,
        "classify_ms": classify,
        "latency_window_ms": tracking + classify,  # after a window's last frame: track it, then classify
        "latency_window_total_ms": data.tracks.shape[1] * tracking + classify,  # every frame tracked + classify
    }


# -- Table 5.2: whole sessions ----------------------------------------------------------------------------------------
def table_5_2(ctx: RunContext) -> dict[str, float]:
    """Table 5.2 end to end; the robot places what the video shows."""
    return assembly_sessions(ctx, with_robot=False)


def hrc_session(ctx: RunContext) -> dict[str, float]:
    """The HRC loop with the robot (5.2.3, Figs. 5.8-5.10): Table 5.2's sessions, the robot cell executing every
    Semantic Control command and holding every human placement; Table 5.2 extended with the robot's placement
    success and the sessions that end with the goal assembled."""
    return assembly_sessions(ctx, with_robot=True)


def assembly_sessions(ctx: RunContext, with_robot: bool) -> dict[str, float]:
    spec, protocol = ctx.cfg.env, ctx.cfg.protocol
    data = action_set(ctx)
    detector = shared_detector(ctx, data)
    everything = scenarios(spec)
    rng = ctx.rng(SESSIONS)
    chosen = rng.permutation(len(everything))[: max(1, round(protocol.train_ratio * len(everything)))]
    planner = train_planner(ctx.cfg.reasoning, spec, [everything[j] for j in chosen], ctx.trainer, ctx.seed,
                            prefix="planner")
    cell, view = robot_cell(ctx, render=protocol.video) if with_robot else (None, None)
    recovery = with_robot and protocol.recovery
    # the filmed session: Table 5.2's first; with the robot protocol.video_session, or (null) the first that shows
    # the loop recovering and ending assembled when protocol.recovery is on, replayed with the renderer
    wanted = protocol.video_session if with_robot else 0
    if wanted is None and not recovery:
        wanted = 0
    film = protocol.video if with_robot else True
    rows, results, played = [], {"normal": [], "fast": []}, []
    total = protocol.sessions + protocol.fast_sessions

    def play(goal: int, seed: int, clip: Clip, steps: list, annotated: list | None) -> dict:
        if cell is not None:  # each session's cell from the session's seed, so that it can be replayed
            cell.reseed(seed)
            cell.reset()
        return run_session(detector, planner, spec, clip, steps, goal, protocol.tracker_complexity, annotated,
                           cell, view if annotated is not None else None, recovery=recovery)

    for i in tqdm(range(total), desc=f"sessions {spec.cell}", unit="session"):
        fast = i >= protocol.sessions
        goal = int(rng.integers(spec.n_goals))
        seed = int(rng.integers(2**31))
        clip, steps = render_session(spec, spec.video, goal, seed, protocol.p_screw, fast)
        played.append((goal, seed, fast))
        frames = [] if i == wanted and film else None
        result = play(goal, seed, clip, steps, frames)
        results["fast" if fast else "normal"].append(result)
        rows.append({"session": i, "fast": fast, "goal": goal, "frames": len(clip.frames),
                     **{f"{k}_acc": np.mean(result[k]) if result[k] else np.nan for k in ("ad", "sg", "sc")},
                     **{f"n_{k}": len(result[k]) for k in ("ad", "sg", "sc")},
                     **(robot_row(result) if cell is not None else {})})
        if frames is not None:
            log_session_media(ctx, frames, clip, spec.video.fps, "session_side_by_side" if view else
                              "session_annotated")
    if wanted is None and film:  # replay the first session that recovered and ended assembled
        wanted = next((row["session"] for row in rows if row["recoveries"] and row["complete"]), 0)
        goal, seed, fast = played[wanted]
        clip, steps = render_session(spec, spec.video, goal, seed, protocol.p_screw, fast)
        play(goal, seed, clip, steps, frames := [])
        log_session_media(ctx, frames, clip, spec.video.fps, "session_side_by_side")
    ctx.tracker.log_table(pd.DataFrame(rows), "hrc_sessions" if with_robot else "table_5_2_sessions")
    if cell is not None:
        failures = [{"session": row["session"], "reason": reason} for row in rows for reason in row["help"]]
        ctx.tracker.log_table(pd.DataFrame(failures, columns=["session", "reason"]), "robot_help")
        cell.close()
    metrics = {}
    for kind, suffix in (("normal", ""), ("fast", "_fast")):
        for k in ("ad", "sg", "sc"):
            values = [v for r in results[kind] for v in r[k]]
            metrics[f"{k}_acc{suffix}"] = float(np.mean(values)) if values else float("nan")
        for k in ("sg", "sc"):  # the events whose right answer the true assembly so far fixes
            marks = [m for r in results[kind] for m in r[f"{k}_determined"]]
            right = [v for r in results[kind] for v, m in zip(r[k], r[f"{k}_determined"]) if m]
            metrics[f"{k}_determined_share{suffix}"] = float(np.mean(marks)) if marks else float("nan")
            metrics[f"{k}_acc_determined{suffix}"] = float(np.mean(right)) if right else float("nan")
        if cell is not None:
            metrics.update({f"{key}{suffix}": value for key, value in robot_metrics(results[kind]).items()})
    every = results["normal"] + results["fast"]
    metrics["tracking_ms_per_frame"] = 1e3 * float(np.median([t for r in every for t in r["tracking_s"]]))
    metrics["classify_ms"] = 1e3 * float(np.median([t for r in every for t in r["classify_s"]]))
    metrics["n_sessions"] = float(protocol.sessions)
    metrics["n_fast_sessions"] = float(protocol.fast_sessions)
    metrics["filmed_session"] = float(wanted) if film else float("nan")
    if cell is not None:
        latency = [t for r in every for t in r["latency_s"]]
        moved = [p for r in every for p in r["placements"] if p.steps]
        metrics["screw_latency_ms"] = 1e3 * float(np.median(latency)) if latency else float("nan")
        metrics["pick_place_sim_s"] = float(np.mean([p.sim_s for p in moved])) if moved else float("nan")
        metrics["pick_place_wall_s"] = float(np.mean([p.wall_s for p in moved])) if moved else float("nan")
    return metrics


def robot_cell(ctx: RunContext, render: bool):
    """The assembly robot cell of the run's env spec (seeded), and with ``render`` a renderer of its worker-side
    camera at the annotated frames' height (twice the video's), or None."""
    from hrc_lab.env import ENVS
    from hrc_lab.env.robot.recorder import FrameRecorder
    from hrc_lab.env.robot.settings import CELL_CAMERA

    video = ctx.cfg.env.video
    if not render:
        return ENVS.build(ctx.cfg.env, seed=ctx.seed), None
    cell = ENVS.build(ctx.cfg.env, seed=ctx.seed, has_offscreen_renderer=True, camera_names=CELL_CAMERA,
                      camera_heights=2 * video.height, camera_widths=2 * video.width)
    return cell, FrameRecorder(cell, CELL_CAMERA, 2 * video.width, 2 * video.height, frame_skip=2)


def robot_row(result: dict) -> dict:
    """One session's robot columns: commands, refusals, placements, recoveries (with ``protocol.recovery``), whether
    the goal was assembled, and every reason the robot asked for help (refused or failed commands, refused human
    placements, failed removals)."""
    placements = result["placements"]
    executed = [p for p in placements if p.steps]
    return {"robot_commands": len(placements), "robot_refused": len(placements) - len(executed),
            "robot_placed": sum(p.success for p in executed), "human_placed": sum(p.success for p in result["human"]),
            "recoveries": len(result["recoveries"]),
            "recovered": sum(r.placed is not None for r in result["recoveries"]),
            "recovery_log": " | ".join(r.describe() for r in result["recoveries"]),
            "complete": result["complete"], "assembly": " ".join(f"{o}@p{p}" for o, p in result["assembly"]),
            "help": [f"robot {p.part}->p{p.position}: {p.reason}" for p in placements if not p.success]
            + [f"human {p.part}->p{p.position}: {p.reason}" for p in result["human"] if not p.success]
            + [f"removal {p.part} off p{p.position}: {p.reason}" for p in result["removals"] if not p.success]}


def robot_metrics(results: list[dict]) -> dict[str, float]:
    """Table 5.2's robot columns over sessions: the placement success of executed commands, the share of
    commands refused (nothing to pick, position taken, not allowed), and the sessions that end assembled."""
    placements = [p for r in results for p in r["placements"]]
    executed = [p for p in placements if p.steps]
    nan = float("nan")
    return {
        "robot_placement_sr": float(np.mean([p.success for p in executed])) if executed else nan,
        "robot_refused_rate": (len(placements) - len(executed)) / len(placements) if placements else nan,
        "robot_commands": float(len(placements)),
        "recoveries_per_session": float(np.mean([len(r["recoveries"]) for r in results])) if results else nan,
        "complete_rate": float(np.mean([r["complete"] for r in results])) if results else nan,
    }


def log_session_media(ctx: RunContext, annotated: list[np.ndarray], clip: Clip, fps: int, name: str) -> None:
    """The first session as an annotated MP4 (``videos/<name>.mp4``) and a strip of frames at the end of its first
    placing segments."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"{name}.mp4"
        write_video(annotated, path, fps)
        ctx.tracker.log_artifact(path, "videos")
    if len(annotated) == len(clip.frames):  # a side-by-side video has extra frames while the robot moves
        ctx.tracker.log_figure(session_strip(annotated, clip.labels), "figures/session_strip.png")


# -- any video -----------------------------------------------------------------------------------------------------
def annotate_video(ctx: RunContext) -> dict[str, float]:
    """Run the whole pipeline on ``protocol.input`` (any video OpenCV reads; a generated session when null) and
    write the annotated MP4 to ``protocol.output``."""
    spec, protocol = ctx.cfg.env, ctx.cfg.protocol
    data = action_set(ctx)
    detector = shared_detector(ctx, data)
    everything = scenarios(spec)
    planner = train_planner(ctx.cfg.reasoning, spec, everything, ctx.trainer, ctx.seed, prefix="planner")
    if protocol.input is None:
        clip, _ = render_session(spec, spec.video, 0, ctx.seed, 0.3, fast=False)
        frames, fps = list(clip.frames), spec.video.fps
    else:
        frames, fps = read_video(Path(protocol.input))
    cell = side = robot = None
    if protocol.robot:  # the worker's view beside the robot cell, which executes the loop's commands
        cell, view = robot_cell(ctx, render=True)
        side = SideBySide(view, [])
        robot = CellHands(cell, side)
        loop = SemanticPlannerLoop(planner, robot.robot, echo=None, human=robot.human)
    else:
        loop = SemanticPlannerLoop(planner, lambda part, position: (part, position), echo=None)
    out, state, hands = annotate_frames(detector, action_labels(spec), loop, frames, protocol.tracker_complexity,
                                        robot, side)
    if not hands:
        log.warning("no hand was detected in %s: no action, no plan, no robot motion", protocol.input or "the video")
    output = Path(protocol.output)
    output.parent.mkdir(parents=True, exist_ok=True)
    write_video(out, output, fps)
    ctx.tracker.log_artifact(output, "videos")
    metrics = {"frames": float(len(frames)), "windows": float(len(state.windows)),
               "events": float(len(state.events)), "tracked_fraction": hands / len(frames)}
    if robot is not None:
        metrics.update(robot_placed=float(sum(p.success for p in robot.placements)),
                       robot_commands=float(len(robot.placements)))
        cell.close()
    return metrics
