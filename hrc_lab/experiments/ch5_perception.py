"""Ch.5 perception protocols (Sec. 5.4.1, 5.4.3): Fig. 5.5 / 5.6 (the action detector and its baselines on
generated action clips), Table 5.2 end to end (generated assembly sessions streamed through MediaPipe tracking ->
action detector -> semantic planner, Algorithm 3) and the annotation of any video with the same pipeline.

The clip set depends on ``protocol.data_seed``, the video spec and the window sizes only; it is tracked once and
cached under ``<paths.runs_dir>/cache/ch5`` (file lock), so every method and seed of a sweep reads the same
windows. Fig. 5.6: ``seed`` fixes the 0.8 / 0.2 split and the initialisation. Table 5.2: one detector trained on
the whole clip set (seed ``data_seed``, cached) serves every job; ``seed`` fixes the sessions and the planner.
"""

from __future__ import annotations

import tempfile
import time
from dataclasses import asdict
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import torch
from matplotlib.figure import Figure
from tqdm import tqdm

from hrc_lab.cache import cache_key, cached
from hrc_lab.data.files import DataFileError, existing_file, load_torch, load_weights
from hrc_lab.env.assembly.spec import (
    SCREW,
    AssembleToOrderSpec,
    Scenario,
    action_labels,
    next_object,
    parse_assembly,
    plan_tokens,
    scenarios,
)
from hrc_lab.env.assembly.video import Clip, SessionStep, render_action_clip, render_session
from hrc_lab.experiments.ch5_planner import train_planner
from hrc_lab.experiments.context import RunContext
from hrc_lab.perception import PERCEPTIONS
from hrc_lab.perception.action_detector import ActionDetector, ActionWindows
from hrc_lab.perception.configs import ActionDetectorConfig
from hrc_lab.perception.dataset import ActionSet, WindowSizes, action_set_key, build_action_set
from hrc_lab.perception.hand_tracking import HandTracker
from hrc_lab.perception.pipeline import ActionPipeline, annotate
from hrc_lab.perception.windows import WindowStream
from hrc_lab.reasoning.hrc_loop import SemanticPlannerLoop

SPLIT, SESSIONS = 60, 61  # random streams
STORED_SIDE, STORED_STRIDE = 64, 3  # crops and frames kept in the cache


def cache_dir(ctx: RunContext) -> Path:
    return Path(ctx.cfg.paths.runs_dir) / "cache" / "ch5"


def window_sizes(ctx: RunContext) -> WindowSizes:
    """The cached windows keep 64 px crops and every 3rd frame at 64 px, whatever the method reads, so that every
    method of a sweep shares one tracked set; :func:`windows` resizes them to the method's sizes."""
    return WindowSizes(STORED_SIDE, STORED_SIDE, STORED_STRIDE, ctx.cfg.protocol.tracker_complexity)


def action_set(ctx: RunContext) -> ActionSet:
    """The tracked clip set of every Table 5.1 action, from the cache when another job already built it."""
    protocol, spec = ctx.cfg.protocol, ctx.cfg.env
    sizes = window_sizes(ctx)
    if ctx.cfg.perception.window != spec.video.window:
        raise ValueError(f"perception.window={ctx.cfg.perception.window} must equal env.video.window")
    key = action_set_key(spec, spec.video, protocol.clips_per_class, protocol.data_seed, sizes)

    def build(path: Path) -> None:
        data = build_action_set(spec, spec.video, protocol.clips_per_class, protocol.data_seed, sizes,
                                protocol.workers)
        data.save(path)

    return ActionSet.load(cached(cache_dir(ctx) / f"actions_{key}.npz", build))


def _resized(images: np.ndarray, side: int) -> np.ndarray:
    if images.shape[-2] == side:
        return images
    flat = images.reshape(-1, *images.shape[-3:])
    out = np.stack([cv2.resize(im, (side, side), interpolation=cv2.INTER_AREA) for im in flat])
    return out.reshape(*images.shape[:-3], side, side, 3)


def windows(cfg: ActionDetectorConfig, data: ActionSet, train: bool = False) -> ActionWindows:
    """The cached windows at the method's crop and frame sizes."""
    frames = None
    if cfg.spatial == "frames":
        if cfg.frame_stride != STORED_STRIDE:
            raise ValueError(f"perception.frame_stride must be {STORED_STRIDE} (cached frames), got {cfg.frame_stride}")
        frames = _resized(data.frames, cfg.frame_size)
    return ActionWindows(cfg, data.tracks, data.labels, crops=_resized(data.crops, cfg.crop_size), frames=frames,
                         train=train)


def stratified_split(labels: np.ndarray, fraction: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``fraction`` of every class for training, the rest for testing."""
    train, test = [], []
    for c in np.unique(labels):
        members = rng.permutation(np.flatnonzero(labels == c))
        cut = int(round(fraction * len(members)))
        train += members[:cut].tolist()
        test += members[cut:].tolist()
    return np.sort(train), np.sort(test)


def train_detector(ctx: RunContext, data: ActionSet, seed: int, prefix: str) -> ActionDetector:
    cfg = ctx.cfg.perception
    detector = PERCEPTIONS.build(cfg, n_classes=len(data.names), seed=seed)
    return detector.fit(windows(cfg, data, train=True), ctx.trainer(prefix))


def shared_detector(ctx: RunContext, data: ActionSet) -> ActionDetector:
    """The detector trained on the whole clip set with seed ``data_seed`` (cached, shared by the jobs)."""
    cfg, protocol = ctx.cfg.perception, ctx.cfg.protocol
    spec = ctx.cfg.env
    identity = {"data": action_set_key(spec, spec.video, protocol.clips_per_class, protocol.data_seed,
                                       window_sizes(ctx)), "perception": asdict(cfg)}
    key = cache_key(identity)

    def build(path: Path) -> None:
        detector = train_detector(ctx, data, protocol.data_seed, "detector")
        torch.save(detector.state_dict(), path)

    path = cached(cache_dir(ctx) / f"detector_{key}.pt", build)
    detector = PERCEPTIONS.build(cfg, n_classes=len(data.names), seed=protocol.data_seed)
    load_weights(path, detector, load_torch(path))
    return detector.eval()


def confusion_figure(confusion: np.ndarray, names: list[str], title: str):
    """Fig. 5.5: row-normalised confusion matrix with counts."""
    fig = Figure(figsize=(8.5, 7.5))
    ax = fig.subplots()
    rates = confusion / np.maximum(confusion.sum(1, keepdims=True), 1)
    ax.imshow(rates, cmap="Blues", vmin=0, vmax=1)
    ax.set_xticks(range(len(names)), names, rotation=90, fontsize=8)
    ax.set_yticks(range(len(names)), names, fontsize=8)
    for i, j in zip(*np.nonzero(confusion)):
        ax.text(j, i, str(confusion[i, j]), ha="center", va="center", fontsize=6,
                color="white" if rates[i, j] > 0.5 else "black")
    ax.set_xlabel("predicted")
    ax.set_ylabel("true")
    ax.set_title(title)
    fig.tight_layout()
    return fig


def tracking_ms_per_frame(ctx: RunContext, frames: np.ndarray) -> float:
    with HandTracker(model_complexity=ctx.cfg.protocol.tracker_complexity) as tracker:
        times = []
        for frame in frames:
            start = time.perf_counter()
            tracker(frame)
            times.append(time.perf_counter() - start)
    return 1e3 * float(np.median(times[1:]))


def classify_ms(detector: ActionDetector, data: ActionSet, count: int) -> float:
    cfg, times = detector.cfg, []
    for i in range(min(count, len(data))):
        crop, frames = _resized(data.crops[i], cfg.crop_size), _resized(data.frames[i], cfg.frame_size)
        start = time.perf_counter()
        detector.classify(data.tracks[i], crop, frames)
        times.append(time.perf_counter() - start)
    return 1e3 * float(np.median(times))


def fig_5_6(ctx: RunContext) -> dict[str, float]:
    cfg, protocol = ctx.cfg.perception, ctx.cfg.protocol
    data = action_set(ctx)
    train, test = stratified_split(data.labels, protocol.train_fraction, ctx.rng(SPLIT))
    detector = train_detector(ctx, data.subset(train), ctx.seed, "detector").eval()
    predicted = detector.predict_proba(windows(cfg, data)).argmax(1)
    correct = predicted == data.labels
    confusion = np.zeros((len(data.names),) * 2, dtype=int)
    np.add.at(confusion, (data.labels, predicted), 1)
    method = ctx.cfg.perception.name
    ctx.tracker.log_figure(confusion_figure(confusion, data.names, f"{method}, seed {ctx.seed}: all clips"),
                           "figures/confusion.png")
    ctx.tracker.log_table(pd.DataFrame(confusion, index=data.names, columns=data.names).reset_index(),
                          "confusion")
    sample = render_action_clip(ctx.cfg.env, ctx.cfg.env.video, data.names[0], int(data.clip_seeds[0]))
    tracking = tracking_ms_per_frame(ctx, sample.frames)
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
def segments_of(labels: list[str]) -> list[tuple[str, int, int]]:
    """Runs of equal frame labels: (label, start, end)."""
    runs, start = [], 0
    for k in range(1, len(labels) + 1):
        if k == len(labels) or labels[k] != labels[start]:
            runs.append((labels[start], start, k))
            start = k
    return runs


def checkpoints(clip: Clip, steps: list[SessionStep]) -> list[tuple[SessionStep, int, int]]:
    """(step, first frame of its placing or screwing segment, the frame the hand has left after it)."""
    runs = segments_of(clip.labels)
    decisive = [(i, r) for i, r in enumerate(runs) if r[0] == SCREW or parse_assembly(r[0])]
    if len(decisive) != len(steps):
        raise RuntimeError(f"session has {len(decisive)} placing/screwing segments for {len(steps)} steps")
    out = []
    for step, (i, (_, start, _)) in zip(steps, decisive):
        gap_end = runs[i + 1][2] if i + 1 < len(runs) and runs[i + 1][0] == "none" else runs[i][2]
        out.append((step, start, gap_end - 1))
    return out


def run_session(detector: ActionDetector, planner, spec: AssembleToOrderSpec, clip: Clip, steps: list[SessionStep],
                goal: int, complexity: int, annotated: list | None = None) -> dict:
    """Stream one session through Algorithm 3 and score it: AD per window (majority label of its frames), SG at
    the end of the gap after every human placement (the guidance on screen against the truth), SC per screw (the
    first control command issued during it). The robot places what the video shows it placed, if it was asked."""
    cfg = detector.cfg
    marks = checkpoints(clip, steps)
    robot_jobs = {start: step.robot for step, start, _ in marks if step.kind == "screw"}
    frame_index = {"now": 0}

    def robot(part: str, position: int):
        due = [s for s in robot_jobs if s <= frame_index["now"] and robot_jobs[s] is not None]
        return robot_jobs.pop(due[-1]) if due else None

    loop = SemanticPlannerLoop(planner, robot, echo=None)
    stream = WindowStream(cfg.window, cfg.crop_size, cfg.frame_size, cfg.frame_stride)
    with HandTracker(model_complexity=complexity) as tracker:
        pipeline = ActionPipeline(detector, action_labels(spec), tracker, stream, loop)
        shown: dict[int, list] = {}
        due = {end: step for step, _, end in marks}
        for k, frame in enumerate(clip.frames):
            frame_index["now"] = k
            state = pipeline.push(frame)
            if k in due:
                shown[k] = list(loop.pairs)
            if annotated is not None:
                annotated.append(annotate(frame, state, loop))
    truth_assembled: set[int] = set()
    sg, sc = [], []
    for step, start, end in marks:
        before = Scenario(goal, frozenset(truth_assembled))
        if step.kind == "assemble":
            truth_assembled.add(step.position)
            now = Scenario(goal, frozenset(truth_assembled))
            plan = planner.plan([shown[end]])[0]
            sg.append(all(plan.guidance[t] == plan_tokens(spec, now, t) for t in spec.types))
        else:
            expected = next_object(spec, before)
            events = [e for k, e in state.events if start <= k <= end and e.label == SCREW]
            sc.append(bool(events) and events[0].plan.next_object == expected
                      and events[0].plan.control == plan_tokens(spec, before, expected))
            truth_assembled.add(step.robot[1])
    ad = []
    for window in state.windows:
        labels = [x for x in clip.labels[window.start : window.end] if x != "none"]
        if labels:
            ad.append(window.label == max(set(labels), key=labels.count))
    return {"ad": ad, "sg": sg, "sc": sc, "tracking_s": state.tracking_s, "classify_s": state.classify_s}


def write_video(frames: list[np.ndarray], path: Path, fps: int) -> None:
    h, w = frames[0].shape[:2]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (w, h))
    for frame in frames:
        writer.write(frame[..., ::-1])
    writer.release()


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
    runs = [r for r in segments_of(clip.labels) if r[0] != "none"][:6]
    fig = Figure(figsize=(12, 6))
    axes = fig.subplots(2, 3)
    for ax, (label, _, end) in zip(axes.ravel(), runs):
        ax.imshow(annotated[min(end + 2, len(annotated) - 1)])
        ax.set_title(f"true: {label}", fontsize=9)
        ax.axis("off")
    fig.tight_layout()
    ctx.tracker.log_figure(fig, "figures/session_strip.png")


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
    cfg = detector.cfg
    stream = WindowStream(cfg.window, cfg.crop_size, cfg.frame_size, cfg.frame_stride)
    out, hands = [], 0
    with HandTracker(model_complexity=protocol.tracker_complexity) as tracker:
        pipeline = ActionPipeline(detector, action_labels(spec), tracker, stream, loop)
        for frame in tqdm(frames, desc="annotate", unit="frame"):
            state = pipeline.push(frame)
            hands += state.observation is not None
            out.append(annotate(frame, state, loop))
    output = Path(protocol.output)
    output.parent.mkdir(parents=True, exist_ok=True)
    write_video(out, output, fps)
    ctx.tracker.log_artifact(output, "videos")
    return {"frames": float(len(frames)), "windows": float(len(state.windows)), "events": float(len(state.events)),
            "tracked_fraction": hands / len(frames)}


def read_video(path: Path) -> tuple[list[np.ndarray], int]:
    """The RGB frames and frame rate (15 when the file gives none) of a video; :class:`DataFileError` when the file
    is missing, not a video OpenCV opens, or holds no frame."""
    path = existing_file(path)
    capture = cv2.VideoCapture(str(path))
    if not capture.isOpened():
        raise DataFileError(f"{path}: not a video OpenCV can open (another format, an unknown codec or corrupt?)")
    fps = int(round(capture.get(cv2.CAP_PROP_FPS))) or 15
    frames = []
    while True:
        ok, frame = capture.read()
        if not ok:
            break
        frames.append(frame[..., ::-1].copy())
    capture.release()
    if not frames:
        raise DataFileError(f"{path}: OpenCV read no frame from it (empty, truncated or an unknown codec?)")
    return frames, fps
