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
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

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
    """All demos of a file (in order) and its ``env_args``."""
    with h5py.File(path, "r") as f:
        env_args = json.loads(f["data"].attrs["env_args"])
        keep = {n.decode() for n in f["mask/success"][()]} if successful_only else None
        names = sorted(f["data"].keys(), key=lambda n: int(n.split("_")[1]))
        demos = []
        for name in names:
            if keep is not None and name not in keep:
                continue
            g = f["data"][name]
            demos.append(
                Demo(
                    obs={k: g["obs"][k][()] for k in g["obs"]},
                    **{k: g[k][()] for k in DATASETS},
                    success=name in {n.decode() for n in f["mask/success"][()]},
                    model_file=g.attrs["model_file"],
                    episode=json.loads(g.attrs["episode"]),
                )
            )
    return demos, env_args
