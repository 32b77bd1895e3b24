"""Demonstrations as HDF5 in robomimic's layout.

    data                     attrs: env_args (JSON: env_name, type, env_kwargs, hrc_lab env config), total
    data/demo_k              attrs: num_samples, model_file (MJCF), episode (JSON: configuration, human order...)
        obs/<key>            (T, d) observation before each action
        actions              (T, 4|5) thesis actions [dq_base, dq_shoulder, dq_elbow, (dq_wrist3,) suction]
        states               (T, 1+nq+nv) flattened MuJoCo state before each action (robosuite's sim.get_state)
        rewards, dones       (T,)
        stage_labels         (T,) pick/place x object label of each step (Ch.3: 0 pick blue ... 3 place red)
        subgoal_indices      (T,) designed sub-goal 0..2 within the stage
        subgoals             (T, 3) the designed sub-goal the expert was heading for
        stage_bounds         (S, 4) change-point stages: object, stage (0 pick, 1 place), first step, end step
        stage_subgoals       (S, k, 3) k sub-goals per detected stage (re-sampled, Ch.3; designed, Ch.4)
    mask/success             names of the demos whose expert episode succeeded

robomimic reads ``data/demo_k/{obs,actions,states,rewards,dones}`` and ``data.attrs["env_args"]``; the extra
datasets are ours.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from hrc_lab.data.files import DataFileError, existing_file, reading

OBS_KEYS = ("robot0_joint_pos", "robot0_eef_pos", "lip_target_pos", "object_pos", "object_yaw", "goal_pos", "held",
            "box_pos")
DATASETS = ("actions", "states", "rewards", "dones", "stage_labels", "subgoal_indices", "subgoals", "stage_bounds",
            "stage_subgoals")


@dataclass
class Demo:
    """One recorded expert episode."""

    obs: dict[str, np.ndarray]
    actions: np.ndarray
    states: np.ndarray
    rewards: np.ndarray
    dones: np.ndarray
    stage_labels: np.ndarray
    subgoal_indices: np.ndarray
    subgoals: np.ndarray
    success: bool
    model_file: str = ""
    episode: dict = field(default_factory=dict)
    stage_bounds: np.ndarray = field(default_factory=lambda: np.zeros((0, 4), dtype=np.int64))
    stage_subgoals: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 3), dtype=np.float32))

    def __len__(self) -> int:
        return len(self.actions)


class DemoWriter:
    """Append demos to a new HDF5 file; ``env_args`` is written on close."""

    def __init__(self, path: str | Path, env_args: dict) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.file = h5py.File(self.path, "w")
        self.data = self.file.create_group("data")
        self.env_args = env_args
        self.names: list[str] = []
        self.successful: list[str] = []
        self.total = 0

    def add(self, demo: Demo) -> str:
        name = f"demo_{len(self.names)}"
        group = self.data.create_group(name)
        group.attrs["num_samples"] = len(demo)
        group.attrs["model_file"] = demo.model_file
        group.attrs["episode"] = json.dumps(demo.episode)
        obs = group.create_group("obs")
        for key, values in demo.obs.items():
            obs.create_dataset(key, data=values, compression="gzip")
        for key in DATASETS:
            group.create_dataset(key, data=getattr(demo, key), compression="gzip")
        self.names.append(name)
        if demo.success:
            self.successful.append(name)
        self.total += len(demo)
        return name

    def close(self) -> None:
        self.data.attrs["env_args"] = json.dumps(self.env_args)
        self.data.attrs["total"] = self.total
        mask = self.file.create_group("mask")
        mask.create_dataset("success", data=np.array(self.successful, dtype="S"))
        self.file.close()

    def __enter__(self) -> DemoWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def read_demos(path: str | Path, successful_only: bool = False) -> tuple[list[Demo], dict]:
    """All demos of a file (in order) and its ``env_args``; :class:`DataFileError` when the file is missing,
    unreadable or lacks what :class:`DemoWriter` writes."""
    path = existing_file(path)
    with reading(path, "HDF5 file"), h5py.File(path, "r") as f:
        data = _member(path, f, "data", "; was it written by hrc_lab's collect job?")
        if "env_args" not in data.attrs:
            raise DataFileError(f"{path}: no data.attrs['env_args']; was it written by hrc_lab's collect job?")
        env_args = _json(path, data.attrs["env_args"], "data.attrs['env_args']")
        successful = {n.decode() for n in _member(path, f, "mask/success", " (the names of the successful demos)")[()]}
        demos = [
            _read_demo(path, data[name], name in successful)
            for name in _demo_names(path, data)
            if not successful_only or name in successful
        ]
    return demos, env_args


def _member(path: Path, group: h5py.Group, key: str, hint: str = "") -> h5py.Group | h5py.Dataset:
    """``group[key]``, or :class:`DataFileError` naming what is missing (``hint`` ends the sentence)."""
    if key not in group:
        where = f"{group.name.lstrip('/')} has" if group.name != "/" else "the file has"
        raise DataFileError(f"{path}: {where} no '{key}'{hint}")
    return group[key]


def _attr(path: Path, group: h5py.Group, key: str):
    """``group.attrs[key]``, or :class:`DataFileError` naming the attribute."""
    if key not in group.attrs:
        raise DataFileError(f"{path}: {group.name.lstrip('/')} has no attribute '{key}'")
    return group.attrs[key]


def _json(path: Path, text, where: str):
    """The JSON value ``text`` read from ``where`` in the file."""
    try:
        return json.loads(text)
    except (TypeError, ValueError) as err:
        raise DataFileError(f"{path}: {where} is not valid JSON") from err


def _demo_names(path: Path, data: h5py.Group) -> list[str]:
    """The ``demo_<k>`` groups under ``data``, by k."""
    names = list(data.keys())
    wrong = [n for n in names if not re.fullmatch(r"demo_\d+", n)]
    if wrong:
        raise DataFileError(f"{path}: data/{wrong[0]} is not a demo_<k> group")
    return sorted(names, key=lambda n: int(n.split("_")[1]))


def _read_demo(path: Path, g: h5py.Group, success: bool) -> Demo:
    """One ``data/demo_<k>`` group as a :class:`Demo`."""
    obs = _member(path, g, "obs")
    return Demo(
        obs={k: obs[k][()] for k in obs},
        **{k: _member(path, g, k)[()] for k in DATASETS},
        success=success,
        model_file=_attr(path, g, "model_file"),
        episode=_json(path, _attr(path, g, "episode"), f"{g.name.lstrip('/')}.attrs['episode']"),
    )
