"""Files a user may hand us fail with DataFileError: the path first, then one sentence on what is wrong."""

from __future__ import annotations

import re

import h5py
import numpy as np
import pytest
import torch

from hrc_lab.data.demos import Demo, DemoWriter, read_demos
from hrc_lab.data.files import DataFileError, load_torch
from hrc_lab.data.video_io import read_video
from hrc_lab.env.clutter.scenes import load_scenes, save_scenes
from hrc_lab.env.clutter.spec import ClutterObject, ClutterScene
from hrc_lab.grasp.detector import DetectorConfig
from hrc_lab.grasp.detector_cache import load_or_train_detector
from hrc_lab.perception.dataset import ActionSet


def raises(path, phrase: str):
    """pytest.raises(DataFileError) whose message starts with ``path`` and contains ``phrase``."""
    return pytest.raises(DataFileError, match=rf"^{re.escape(str(path))}: .*{phrase}")


class Foreign:
    """A Python object a weights-only load refuses."""


def tiny_demo(steps: int = 4) -> Demo:
    return Demo(
        obs={"robot0_eef_pos": np.zeros((steps, 3))}, actions=np.zeros((steps, 4)), states=np.zeros((steps, 5)),
        rewards=np.zeros(steps), dones=np.zeros(steps), stage_labels=np.zeros(steps, np.int64),
        subgoal_indices=np.zeros(steps, np.int64), subgoals=np.zeros((steps, 3)), success=True,
        episode={"configuration": [0]},
    )


@pytest.fixture
def demo_file(tmp_path):
    """A valid two-demo file, as the collect job writes it."""
    path = tmp_path / "demos.hdf5"
    with DemoWriter(path, {"env_name": "ErrorCorrection", "type": 1, "env_kwargs": {}}) as writer:
        writer.add(tiny_demo())
        writer.add(tiny_demo())
    return path


def test_a_valid_demo_file_reads(demo_file):
    demos, env_args = read_demos(demo_file)
    assert len(demos) == 2 and env_args["env_name"] == "ErrorCorrection" and demos[1].episode == {"configuration": [0]}


def test_truncated_hdf5(demo_file):
    data = demo_file.read_bytes()
    demo_file.write_bytes(data[: len(data) // 2])
    with raises(demo_file, r"not a readable HDF5 file \(truncated or corrupt\?\)"):
        read_demos(demo_file)


@pytest.mark.parametrize(
    ("remove", "phrase"),
    [
        (lambda f: f["data"].attrs.__delitem__("env_args"), r"no data.attrs\['env_args'\]; was it written by hrc_lab"),
        (lambda f: f.__delitem__("mask"), "the file has no 'mask/success'"),
        (lambda f: f.__delitem__("data/demo_1/actions"), "data/demo_1 has no 'actions'"),
        (lambda f: f["data/demo_0"].attrs.__delitem__("episode"), "data/demo_0 has no attribute 'episode'"),
    ],
    ids=["env_args", "mask", "demo_dataset", "demo_attribute"],
)
def test_hdf5_missing_what_the_writer_writes(demo_file, remove, phrase):
    with h5py.File(demo_file, "a") as f:
        remove(f)
    with raises(demo_file, phrase):
        read_demos(demo_file)


def test_missing_files(tmp_path):
    for load in (read_demos, load_scenes, ActionSet.load, read_video, load_torch):
        path = tmp_path / "nowhere" / "file"
        with raises(path, "does not exist$"):
            load(path)


def test_a_non_video_given_as_a_video(tmp_path):
    path = tmp_path / "notes.mp4"
    path.write_text("not a video\n")
    with raises(path, "not a video OpenCV can open"):
        read_video(path)


def test_npz_caches(tmp_path):
    part = ClutterObject("a", np.zeros(3), np.array([1.0, 0, 0, 0]), np.array([0, 0, 4, 4], np.float32))
    scene = ClutterScene(0, np.zeros((8, 8, 3), np.uint8), [part], np.zeros((8, 8), np.int8), np.zeros((1, 1), bool))
    path = save_scenes(tmp_path / "scenes.npz", [scene])
    assert load_scenes(path)[0].types == ["a"]
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with raises(path, r"not a readable .npz archive \(truncated or corrupt\?\)"):
        load_scenes(path)
    np.savez_compressed(path, images=np.zeros((1, 8, 8, 3), np.uint8))
    with raises(path, "has no 'seeds', .* arrays; was it written by hrc_lab"):
        load_scenes(path)
    with raises(path, "has no 'tracks', .* arrays"):
        ActionSet.load(path)
    windows = ActionSet(*(np.zeros((1, 2)) for _ in range(6)), names=["screw"])
    windows.save(tmp_path / "actions.npz")
    assert ActionSet.load(tmp_path / "actions.npz").names == ["screw"]


@pytest.fixture
def detector_cache(tmp_path):
    """load_or_train_detector(path contents) for a tiny detector whose cache file is ``tmp_path/detector_k.pt``;
    training is never expected."""
    cfg = DetectorConfig(image_size=32, width=2, fpn_channels=4, representation_size=4)
    path = tmp_path / "detector_k.pt"

    def load():
        return load_or_train_detector(cfg, ("a", "b", "c"), [], lambda: pytest.fail("trained instead of loading"),
                                      tmp_path, "k")

    return path, load


def test_corrupt_model_files(detector_cache):
    path, load = detector_cache
    torch.save({"state_dict": {"w": torch.zeros(3)}, "train_seconds": 1.0}, path)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with raises(path, "not a readable PyTorch weights file"):
        load()
    path.write_bytes(b"\x00garbage")
    with raises(path, "not a readable PyTorch weights file"):
        load()
    torch.save({"state_dict": {}, "train_seconds": Foreign()}, path)
    with raises(path, "holding objects other than tensors"):
        load()


def test_model_files_with_the_wrong_content(detector_cache):
    path, load = detector_cache
    torch.save({"weights": {}}, path)
    with raises(path, "not a detector checkpoint of hrc_lab"):
        load()
    torch.save({"state_dict": {"w": torch.zeros(3)}, "train_seconds": 1.0}, path)
    with raises(path, "its weights do not fit the network of this config"):
        load()
    torch.save({"state_dict": {}, "train_seconds": 1.0, "classes": ["book", "mug"]}, path)
    with raises(path, r"a detector of the classes \['book', 'mug'\], not of \['a', 'b', 'c'\]"):
        load()
