"""Ch.5 perception protocols (Sec. 5.4.1, 5.4.3): Fig. 5.5 / 5.6 (the action detector and its baselines on
generated action clips), Table 5.2 end to end (generated assembly sessions streamed through MediaPipe tracking ->
action detector -> semantic planner, Algorithm 3) and the annotation of any video with the same pipeline.

The clip set depends on ``protocol.data_seed``, the video spec and the window sizes only; it is tracked once and
cached under ``<paths.runs_dir>/cache/ch5`` (file lock), so every method and seed of a sweep reads the same
windows. Fig. 5.6: ``seed`` fixes the 0.8 / 0.2 split and the initialisation. Table 5.2: one detector trained on
the whole clip set (seed ``data_seed``, cached) serves every job; ``seed`` fixes the sessions and the planner.

This module reads the run's config and logs; the work is in :mod:`hrc_lab.perception`: the clip set, its split and
cache (:mod:`~hrc_lab.perception.dataset`), its windows at a method's sizes
(:func:`~hrc_lab.perception.action_detector.action_windows`), the shared detector
(:mod:`~hrc_lab.perception.detector_cache`), session scoring (:mod:`~hrc_lab.perception.sessions`), latency
(:mod:`~hrc_lab.perception.latency`), figures (:mod:`~hrc_lab.perception.figures`) and video files
(:mod:`~hrc_lab.perception.video_io`).
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm import tqdm

from hrc_lab.env.assembly.spec import action_labels, scenarios
from hrc_lab.env.assembly.video import Clip, render_action_clip, render_session
from hrc_lab.experiments.ch5_planner import train_planner
from hrc_lab.experiments.context import RunContext
from hrc_lab.perception.action_detector import ActionDetector, action_windows
from hrc_lab.perception.dataset import ActionSet, action_set_key, cached_action_set, stored_sizes, stratified_split
from hrc_lab.perception.detector_cache import load_or_train_action_detector, train_action_detector
from hrc_lab.perception.figures import confusion_figure, session_strip
from hrc_lab.perception.latency import classify_ms, tracking_ms_per_frame
from hrc_lab.perception.pipeline import annotate_frames
from hrc_lab.perception.sessions import run_session
from hrc_lab.perception.video_io import read_video, write_video
from hrc_lab.reasoning.hrc_loop import SemanticPlannerLoop

SPLIT, SESSIONS = 60, 61  # random streams


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
    spec, protocol = ctx.cfg.env, ctx.cfg.protocol
    data = action_set(ctx)
    detector = shared_detector(ctx, data)
    everything = scenarios(spec)
    rng = ctx.rng(SESSIONS)
    chosen = rng.permutation(len(everything))[: max(1, round(protocol.train_ratio * len(everything)))]
    planner = train_planner(ctx, spec, [everything[j] for j in chosen], prefix="planner")
    rows, results = [], {"normal": [], "fast": []}
    total = protocol.sessions + protocol.fast_sessions
    for i in tqdm(range(total), desc=f"sessions {spec.cell}", unit="session"):
        fast = i >= protocol.sessions
        goal = int(rng.integers(spec.n_goals))
        seed = int(rng.integers(2**31))
        clip, steps = render_session(spec, spec.video, goal, seed, protocol.p_screw, fast)
        annotated = [] if i == 0 else None
        result = run_session(detector, planner, spec, clip, steps, goal, protocol.tracker_complexity, annotated)
        results["fast" if fast else "normal"].append(result)
        rows.append({"session": i, "fast": fast, "goal": goal, "frames": len(clip.frames),
                     **{f"{k}_acc": np.mean(result[k]) if result[k] else np.nan for k in ("ad", "sg", "sc")},
                     **{f"n_{k}": len(result[k]) for k in ("ad", "sg", "sc")}})
        if annotated:
            log_session_media(ctx, annotated, clip, spec.video.fps)
    ctx.tracker.log_table(pd.DataFrame(rows), "table_5_2_sessions")
    metrics = {}
    for kind, suffix in (("normal", ""), ("fast", "_fast")):
        for k in ("ad", "sg", "sc"):
            values = [v for r in results[kind] for v in r[k]]
            metrics[f"{k}_acc{suffix}"] = float(np.mean(values)) if values else float("nan")
    every = results["normal"] + results["fast"]
    metrics["tracking_ms_per_frame"] = 1e3 * float(np.median([t for r in every for t in r["tracking_s"]]))
    metrics["classify_ms"] = 1e3 * float(np.median([t for r in every for t in r["classify_s"]]))
    metrics["n_sessions"] = float(protocol.sessions)
    metrics["n_fast_sessions"] = float(protocol.fast_sessions)
    return metrics


def log_session_media(ctx: RunContext, annotated: list[np.ndarray], clip: Clip, fps: int) -> None:
    """The first session as an annotated MP4 and a strip of frames at the end of its first placing segments."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "session_annotated.mp4"
        write_video(annotated, path, fps)
        ctx.tracker.log_artifact(path, "videos")
    ctx.tracker.log_figure(session_strip(annotated, clip.labels), "figures/session_strip.png")


# -- any video -----------------------------------------------------------------------------------------------------
def annotate_video(ctx: RunContext) -> dict[str, float]:
    """Run the whole pipeline on ``protocol.input`` (any video OpenCV reads; a generated session when null) and
    write the annotated MP4 to ``protocol.output``."""
    spec, protocol = ctx.cfg.env, ctx.cfg.protocol
    data = action_set(ctx)
    detector = shared_detector(ctx, data)
    everything = scenarios(spec)
    planner = train_planner(ctx, spec, everything, prefix="planner")
    if protocol.input is None:
        clip, _ = render_session(spec, spec.video, 0, ctx.seed, 0.3, fast=False)
        frames, fps = list(clip.frames), spec.video.fps
    else:
        frames, fps = read_video(Path(protocol.input))
    loop = SemanticPlannerLoop(planner, lambda part, position: (part, position), echo=None)
    out, state, hands = annotate_frames(detector, action_labels(spec), loop, frames, protocol.tracker_complexity)
    output = Path(protocol.output)
    output.parent.mkdir(parents=True, exist_ok=True)
    write_video(out, output, fps)
    ctx.tracker.log_artifact(output, "videos")
    return {"frames": float(len(frames)), "windows": float(len(state.windows)), "events": float(len(state.events)),
            "tracked_fraction": hands / len(frames)}
