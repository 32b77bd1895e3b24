"""The labelled action-window data set of Fig. 5.5 / 5.6: generated clips of every Table 5.1 action, tracked once
with MediaPipe and cached, so that training runs never re-run the tracker.

Clip k of action a is rendered from the seed (data_seed, a, k) (:func:`hrc_lab.env.assembly.video.render_action_clip`),
so the set is the same on every machine. Tracking runs in ``workers`` processes (joblib), one clip per task.
:func:`cached_action_set` builds it once per cache folder (the windows at :func:`stored_sizes`, whatever the method
reads; :func:`hrc_lab.perception.action_detector.action_windows` resizes them to a method's sizes) and
:func:`stratified_split` splits it by class.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import cv2
import numpy as np
from joblib import Parallel, delayed
from tqdm import tqdm

from hrc_lab.cache import cache_key, cached
from hrc_lab.data.files import read_npz
from hrc_lab.env.assembly.spec import AssembleToOrderSpec, action_labels
from hrc_lab.env.assembly.video import GENERATOR_VERSION, AssemblyVideoSpec, render_action_clip
from hrc_lab.perception.hand_tracking import HandTracker
from hrc_lab.perception.windows import window_features


@dataclass(frozen=True)
class WindowSizes:
    """What a cached window keeps: crop side, downscaled frame side and the frame stride (perception config)."""

    crop_size: int
    frame_size: int
    frame_stride: int
    model_complexity: int = 0  # MediaPipe hand landmark model: 0 lite, 1 full


ACTION_SET_ARRAYS = ("tracks", "crops", "frames", "labels", "tracked", "clip_seeds", "names")  # what save() writes
STORED_SIDE, STORED_STRIDE = 64, 3  # crops and frames kept in the cache (:func:`stored_sizes`)


@dataclass
class ActionSet:
    """Windows as arrays: tracks (N, T, 2), crops (N, S, S, 3), frames (N, T', F, F, 3), labels (N,) indices into
    ``names``, ``tracked`` (N,) the fraction of frames with a hand, ``clip_seeds`` (N,) to re-render a clip."""

    tracks: np.ndarray
    crops: np.ndarray
    frames: np.ndarray
    labels: np.ndarray
    tracked: np.ndarray
    clip_seeds: np.ndarray
    names: list[str]

    def __len__(self) -> int:
        return len(self.labels)

    def subset(self, index: np.ndarray) -> ActionSet:
        return ActionSet(self.tracks[index], self.crops[index], self.frames[index], self.labels[index],
                         self.tracked[index], self.clip_seeds[index], self.names)

    def save(self, path: Path) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp.npz")
        np.savez_compressed(tmp, tracks=self.tracks, crops=self.crops, frames=self.frames, labels=self.labels,
                            tracked=self.tracked, clip_seeds=self.clip_seeds, names=np.array(self.names))
        tmp.replace(path)

    @classmethod
    def load(cls, path: Path) -> ActionSet:
        """The set :meth:`save` wrote; :class:`DataFileError` when the file is missing, unreadable or lacks an array."""
        data = read_npz(path, ACTION_SET_ARRAYS)
        return cls(data["tracks"], data["crops"], data["frames"], data["labels"], data["tracked"], data["clip_seeds"],
                   [str(n) for n in data["names"]])


def clip_seed(data_seed: int, label_index: int, k: int) -> int:
    return int(np.random.SeedSequence([data_seed, label_index, k]).generate_state(1)[0])


def _track_clip(ato: AssembleToOrderSpec, video: AssemblyVideoSpec, label: str, seed: int, sizes: WindowSizes):
    clip = render_action_clip(ato, video, label, seed)
    with HandTracker(model_complexity=sizes.model_complexity) as tracker:
        observations = [tracker(frame) for frame in clip.frames]
    return window_features(clip.frames, observations, video.window, sizes.crop_size, sizes.frame_size,
                           sizes.frame_stride)


def build_action_set(ato: AssembleToOrderSpec, video: AssemblyVideoSpec, clips_per_class: int, data_seed: int,
                     sizes: WindowSizes, workers: int = 1) -> ActionSet:
    """Render and track ``clips_per_class`` clips of every action; clips where MediaPipe never finds the hand are
    dropped (their count is the set's size shortfall)."""
    names = action_labels(ato)
    jobs = [(i, label, clip_seed(data_seed, i, k)) for i, label in enumerate(names) for k in range(clips_per_class)]
    run = Parallel(n_jobs=workers, return_as="generator")(
        delayed(_track_clip)(ato, video, label, seed, sizes) for _, label, seed in jobs
    )
    kept = [(i, seed, features) for (i, _, seed), features in
            zip(jobs, tqdm(run, total=len(jobs), desc="render + track clips", unit="clip")) if features is not None]
    return ActionSet(
        tracks=np.stack([f.track for _, _, f in kept]),
        crops=np.stack([f.crop for _, _, f in kept]),
        frames=np.stack([f.frames for _, _, f in kept]),
        labels=np.array([i for i, _, _ in kept], dtype=np.int64),
        tracked=np.array([f.tracked for _, _, f in kept], dtype=np.float32),
        clip_seeds=np.array([s for _, s, _ in kept], dtype=np.int64),
        names=names,
    )


def action_set_key(ato: AssembleToOrderSpec, video: AssemblyVideoSpec, clips_per_class: int, data_seed: int,
                   sizes: WindowSizes) -> str:
    """A short hash of everything the cached set depends on."""
    spec = {"ato": asdict(ato), "video": asdict(video), "clips": clips_per_class, "seed": data_seed,
            "sizes": asdict(sizes), "generator": GENERATOR_VERSION}
    spec["ato"].pop("n_goals", None)  # clips do not depend on which goals are in play
    return cache_key(spec)



def stored_sizes(model_complexity: int) -> WindowSizes:
    """The cached windows keep 64 px crops and every 3rd frame at 64 px, whatever the method reads, so that every
    method of a sweep shares one tracked set; :func:`hrc_lab.perception.action_detector.action_windows` resizes
    them to the method's sizes."""
    return WindowSizes(STORED_SIDE, STORED_SIDE, STORED_STRIDE, model_complexity)


def cached_action_set(cache_dir: Path, ato: AssembleToOrderSpec, video: AssemblyVideoSpec, clips_per_class: int,
                      data_seed: int, sizes: WindowSizes, workers: int = 1) -> ActionSet:
    """The set of :func:`build_action_set`, from ``<cache_dir>/actions_<key>.npz`` when another job already built it
    (:func:`hrc_lab.cache.cached`: parallel jobs wait for the first)."""
    key = action_set_key(ato, video, clips_per_class, data_seed, sizes)

    def build(path: Path) -> None:
        data = build_action_set(ato, video, clips_per_class, data_seed, sizes, workers)
        data.save(path)

    return ActionSet.load(cached(Path(cache_dir) / f"actions_{key}.npz", build))


def resized_images(images: np.ndarray, side: int) -> np.ndarray:
    """RGB images (..., H, W, 3) at ``side`` x ``side`` px (INTER_AREA); ``images`` itself when already that size."""
    if images.shape[-2] == side:
        return images
    flat = images.reshape(-1, *images.shape[-3:])
    out = np.stack([cv2.resize(im, (side, side), interpolation=cv2.INTER_AREA) for im in flat])
    return out.reshape(*images.shape[:-3], side, side, 3)


def stratified_split(labels: np.ndarray, fraction: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``fraction`` of every class for training, the rest for testing."""
    train, test = [], []
    for c in np.unique(labels):
        members = rng.permutation(np.flatnonzero(labels == c))
        cut = int(round(fraction * len(members)))
        train += members[:cut].tolist()
        test += members[cut:].tolist()
    return np.sort(train), np.sort(test)
