"""The Ch.5 action detector (Sec. 5.2.1) and its baselines: branch and network shapes for the four configs composed
from the real YAMLs, config errors naming the key, and learning tests on synthetic windows whose class lives only in
the hand track or only in the hand crop."""

from __future__ import annotations

import lightning.pytorch as pl
import numpy as np
import pytest
import torch
from omegaconf import OmegaConf

from hrc_lab.config import validate_config
from hrc_lab.perception import PERCEPTIONS
from hrc_lab.perception.action_detector import ActionDetector, ActionWindows
from hrc_lab.perception.configs import ActionDetectorConfig
from hrc_lab.perception.networks import LSTMFCN, ActionDetectorNet, FrameSequenceLSTM, PlainLSTM, VGGStyleCNN
from hrc_lab.registry import ConfigError
from hrc_lab.run_naming import method_of

EXPERIMENT = "experiment=ch5/table_5_2"
BRANCHES = {  # name -> (temporal, spatial), thesis 5.4.1
    "hand_lstm_fcn": ("lstm_fcn", "crop"),
    "cnn_lstm": ("lstm", "crop"),
    "hand_cnn": ("none", "crop"),
    "cnn_lstm_video": ("none", "frames"),
}
# Smaller sizes and a larger learning rate, so that a fit takes about two seconds; the branches are unchanged.
SMALL = (
    "window=16",
    "crop_size=16",
    "frame_size=16",
    "frame_stride=4",
    "cnn_widths=[8,16]",
    "cnn_convs=[1,1]",
    "lstm_hidden=16",
    "fcn_filters=[16,32,16]",
    "spatial_dim=16",
    "fusion_hidden=32",
    "lr=3e-3",
)
COMPOSED: dict[str, dict] = {}  # name -> perception node of the composed experiment (composing takes 0.5 s)


@pytest.fixture(autouse=True)
def one_thread():
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.fixture
def perception_config(compose_config):
    """perception_config(name, *overrides) -> the validated ActionDetectorConfig of conf/perception/<name>.yaml as
    composed into a Ch.5 experiment, with ``key=value`` overrides of the perception node."""

    def _config(name: str, *overrides: str) -> ActionDetectorConfig:
        if name not in COMPOSED:
            composed = compose_config(EXPERIMENT, f"perception={name}")
            COMPOSED[name] = OmegaConf.to_container(composed.perception, resolve=True)
        return PERCEPTIONS.validate(OmegaConf.merge(COMPOSED[name], OmegaConf.from_dotlist(list(overrides))))

    return _config


def synthetic(cfg: ActionDetectorConfig, n: int, signal: str, seed: int) -> dict[str, np.ndarray]:
    """The arrays of n windows of 3 classes told apart by the direction of the hand's motion (``signal="track"``;
    every crop is the same hand image up to noise) or by the crop's colour (``signal="crop"``; the hand moves in a
    random direction). The frames are noise."""
    rng = np.random.default_rng(seed)
    labels = rng.integers(0, 3, n)
    angle = 2 * np.pi * labels / 3 if signal == "track" else rng.uniform(0, 2 * np.pi, n)
    direction = np.stack([np.cos(angle), np.sin(angle)], -1)[:, None]
    progress = np.linspace(0, 1, cfg.window)[None, :, None]
    start = rng.uniform(0.3, 0.7, (n, 1, 2))
    tracks = start + 0.2 * progress * direction + 0.01 * rng.standard_normal((n, cfg.window, 2))
    side = cfg.crop_size
    if signal == "track":
        crops = rng.integers(60, 190, (1, side, side, 3)) + rng.integers(-20, 21, (n, side, side, 3))
    else:
        crops = rng.integers(0, 120, (n, side, side, 3))
        crops[np.arange(n), :, :, labels] += 120
    frames = rng.integers(0, 256, (n, len(cfg.frame_indices), cfg.frame_size, cfg.frame_size, 3), dtype=np.uint8)
    return {
        "tracks": tracks.astype(np.float32),
        "labels": labels.astype(np.int64),
        "crops": crops.astype(np.uint8),
        "frames": frames,
    }


def tiny_trainer(epochs: int) -> pl.Trainer:
    return pl.Trainer(
        max_epochs=epochs,
        logger=False,
        enable_checkpointing=False,
        enable_progress_bar=False,
        enable_model_summary=False,
        accelerator="cpu",
    )


@pytest.mark.parametrize("name", sorted(BRANCHES))
def test_configs_validate_and_name_the_run(compose_config, name):
    cfg = compose_config(EXPERIMENT, f"perception={name}")
    validated = validate_config(cfg)
    assert isinstance(validated.perception, ActionDetectorConfig)
    assert (validated.perception.temporal, validated.perception.spatial) == BRANCHES[name]
    assert method_of(cfg) == name  # named after the detector, not the semantic planner it feeds
    assert PERCEPTIONS.load(name) is ActionDetector


def test_branch_shapes_at_the_default_sizes(perception_config):
    cfg = perception_config("hand_lstm_fcn")
    assert cfg.frame_indices == list(range(2, 45, 3))  # 15 frames of 45, ending at the last
    track = torch.rand(2, cfg.window, 2)
    assert LSTMFCN(cfg)(track).shape == (2, cfg.lstm_hidden + cfg.fcn_filters[-1])  # Eq. 5.1
    assert PlainLSTM(cfg)(track).shape == (2, cfg.lstm_hidden)
    assert VGGStyleCNN(cfg, cfg.crop_size)(torch.rand(2, 3, 64, 64)).shape == (2, cfg.spatial_dim)  # Eq. 5.2
    frames = torch.rand(2, len(cfg.frame_indices), 3, cfg.frame_size, cfg.frame_size)
    assert FrameSequenceLSTM(cfg)(frames).shape == (2, cfg.lstm_hidden)


@pytest.mark.parametrize("name", sorted(BRANCHES))
def test_every_method_gives_logits_from_the_inputs_it_reads(perception_config, name):
    cfg = perception_config(name)
    batch = {"track": torch.rand(2, cfg.window, 2)} if cfg.temporal != "none" else {}
    if cfg.spatial == "crop":
        batch["crop"] = torch.rand(2, 3, cfg.crop_size, cfg.crop_size)
    else:
        batch["frames"] = torch.rand(2, len(cfg.frame_indices), 3, cfg.frame_size, cfg.frame_size)
    assert ActionDetectorNet(cfg, 18)(batch).shape == (2, 18)


def test_the_vgg16_layout_is_accepted(perception_config):
    cfg = perception_config("hand_cnn", "cnn_widths=[64,128,256,512,512]", "cnn_convs=[2,2,3,3,3]")
    cnn = VGGStyleCNN(cfg, cfg.crop_size)
    assert sum(isinstance(m, torch.nn.Conv2d) for m in cnn.modules()) == 13  # VGG16's 13 conv layers
    with torch.no_grad():
        assert cnn(torch.rand(1, 3, 64, 64)).shape == (1, cfg.spatial_dim)


@pytest.mark.parametrize(
    "override, key",
    [
        ("temporal=gru", "perception.temporal"),
        ("spatial=none temporal=none", "perception.temporal and perception.spatial"),
        ("window=0", "perception.window"),
        ("lstm_dropout=1.0", "perception.lstm_dropout"),
        ("fcn_kernels=[8,5]", "perception.fcn_filters"),
        ("cnn_convs=[2,0,2,2]", "perception.cnn_convs"),
        ("crop_size=40", "perception.crop_size"),
        ("frame_stride=50", "perception.frame_stride"),
        ("hiden=3", "perception.hiden"),
    ],
)
def test_bad_values_fail_naming_the_key(perception_config, override, key):
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        perception_config("hand_lstm_fcn", *override.split())


def test_a_bad_value_fails_the_run_config(compose_config):
    with pytest.raises(ConfigError, match=r"perception\.temporal"):
        validate_config(compose_config(EXPERIMENT, "perception=cnn_lstm", "perception.temporal=gru"))


def test_windows_check_their_arrays_and_augment_only_in_training(perception_config):
    cfg = perception_config("hand_lstm_fcn", *SMALL)
    arrays = synthetic(cfg, 4, "crop", seed=0)
    plain, augmented = ActionWindows(cfg, **arrays), ActionWindows(cfg, **arrays, train=True)
    item, moved = plain[1], augmented[1]
    assert sorted(item) == ["crop", "label", "track"]  # the frames are not read by hand_lstm_fcn
    assert torch.equal(item["crop"], torch.from_numpy(arrays["crops"][1]).permute(2, 0, 1) / 255)
    assert torch.equal(item["track"], torch.from_numpy(arrays["tracks"][1]))
    assert moved["crop"].shape == item["crop"].shape and not torch.equal(moved["crop"], item["crop"])
    assert 0 < (moved["track"] - item["track"]).abs().max() < 0.05
    video = perception_config("cnn_lstm_video", *SMALL)
    assert ActionWindows(video, **arrays, train=True)[1]["frames"].shape == (4, 3, 16, 16)
    with pytest.raises(ValueError, match="tracks"):
        ActionWindows(cfg, **{**arrays, "tracks": arrays["tracks"][:, 1:]})
    with pytest.raises(ValueError, match="needs the crop images"):
        ActionWindows(cfg, **{**arrays, "crops": None})


@pytest.mark.parametrize(
    "name, signal, low, high",
    [
        ("hand_lstm_fcn", "track", 0.9, 1.0),  # the motion alone gives the action
        ("hand_lstm_fcn", "crop", 0.9, 1.0),  # the hand-object appearance alone gives the action
        ("hand_cnn", "track", 0.0, 0.6),  # one crop cannot show the motion: chance is 1/3
    ],
)
def test_learning_from_the_track_or_the_crop(perception_config, name, signal, low, high):
    cfg = perception_config(name, *SMALL)
    detector, trainer = ActionDetector(cfg, n_classes=3, seed=0), tiny_trainer(epochs=8)
    test = synthetic(cfg, 150, signal, seed=2)
    train = ActionWindows(cfg, **synthetic(cfg, 192, signal, seed=1), train=True)
    detector.fit(train, trainer, val=ActionWindows(cfg, **test))
    assert {"train_loss", "train_acc", "val_loss", "val_acc"} <= set(trainer.callback_metrics)
    accuracy = (detector.predict_proba(ActionWindows(cfg, **test)).argmax(1) == test["labels"]).mean()
    assert low <= accuracy <= high, f"{name} on the {signal} problem: accuracy {accuracy:.2f}"


@pytest.mark.parametrize("name", sorted(BRANCHES))
def test_classify_one_window_matches_predict_proba(perception_config, name):
    cfg = perception_config(name, *SMALL)
    detector = ActionDetector(cfg, n_classes=18, seed=0)
    arrays = synthetic(cfg, 3, "crop", seed=0)
    label, probabilities = detector.classify(arrays["tracks"][2], arrays["crops"][2], arrays["frames"][2])
    assert 0 <= label < 18 and probabilities.shape == (18,) and label == probabilities.argmax()
    assert probabilities.sum() == pytest.approx(1.0, abs=1e-5)
    np.testing.assert_allclose(probabilities, detector.predict_proba(ActionWindows(cfg, **arrays))[2], atol=1e-5)
