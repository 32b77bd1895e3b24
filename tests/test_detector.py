"""The Ch.6 object detector: output shapes, one training step, box matching and the detector cache (tiny sizes)."""

from __future__ import annotations

import lightning.pytorch as pl
import numpy as np
import pytest
import torch

from hrc_lab.env.clutter.spec import PART_TYPES, ClutterObject, ClutterScene
from hrc_lab.grasp.detection_metrics import detection_quality, match_detections
from hrc_lab.grasp.detector import Detections, DetectorConfig, DetectorModule, ObjectDetector, scene_target
from hrc_lab.grasp.detector_cache import detector_cache_key, load_or_train_detector

SIZE = 64


def tiny_config(**overrides) -> DetectorConfig:
    values = dict(image_size=SIZE, width=4, fpn_channels=8, representation_size=16, steps=1, batch_size=2,
                  warmup_steps=0, score_threshold=0.0, rpn_post_nms_train=32, rpn_post_nms_test=16,
                  rpn_batch_size=32, box_batch_size=16, context_scale=0.0)
    return DetectorConfig(**(values | overrides))


def random_images(n: int = 2) -> list[np.ndarray]:
    rng = np.random.default_rng(0)
    return [rng.integers(0, 256, (SIZE, SIZE, 3), dtype=np.uint8) for _ in range(n)]


def toy_scene(seed: int) -> ClutterScene:
    """Two flat-coloured rectangles (an a and a b) on a grey image."""
    image = np.full((SIZE, SIZE, 3), 128, np.uint8)
    boxes = {"a": np.array([8, 10, 24, 22], np.float32), "b": np.array([30, 36, 60, 50], np.float32)}
    objects = []
    for t, box in boxes.items():
        x0, y0, x1, y1 = box.astype(int)
        image[y0:y1, x0:x1] = (220, 140, 60) if t == "a" else (60, 110, 190)
        objects.append(ClutterObject(t, np.zeros(3), np.array([1.0, 0, 0, 0]), box))
    return ClutterScene(seed=seed, image=image, objects=objects, segmentation=-np.ones((SIZE, SIZE), int))


def test_config_validation_names_the_key():
    with pytest.raises(ValueError, match="grasp.detector.lr"):
        DetectorConfig(lr=0)
    with pytest.raises(ValueError, match="grasp.detector.anchor_sizes"):
        DetectorConfig(anchor_sizes=[[16], [32]])
    with pytest.raises(ValueError, match="grasp.detector.image_size"):
        DetectorConfig(image_size=100)


def test_detect_and_features_for_boxes_shapes():
    detector = ObjectDetector(tiny_config(), PART_TYPES)
    detections = detector.detect(random_images())
    assert len(detections) == 2
    for det in detections:
        n = len(det)
        assert det.boxes.shape == (n, 4) and det.scores.shape == (n,) and det.centres.shape == (n, 2)
        assert tuple(det.features.shape) == (n, 16)
        assert set(det.labels) <= {"a", "b", "c"}
        assert np.all(np.diff(det.scores) <= 0)
    features = detector.features_for_boxes(random_images(), [np.array([[1, 1, 20, 20], [10, 10, 40, 30]]),
                                                             np.zeros((0, 4))])
    assert [tuple(f.shape) for f in features] == [(2, 16), (0, 16)]
    assert detector.training  # a fresh module stays in train mode after inference


def test_same_seed_same_weights():
    a, b = ObjectDetector(tiny_config(), PART_TYPES), ObjectDetector(tiny_config(), PART_TYPES)
    assert all(torch.equal(x, y) for x, y in zip(a.state_dict().values(), b.state_dict().values()))


@pytest.mark.filterwarnings("ignore:.*self.trainer.* reference is not registered")
def test_one_training_step_has_finite_loss():
    detector = ObjectDetector(tiny_config(), PART_TYPES)
    module = DetectorModule(detector.model, tiny_config())
    module.train()
    images, targets = zip(*(scene_target(toy_scene(s), PART_TYPES) for s in range(2)))
    loss = module.training_step((images, targets), 0)
    assert torch.isfinite(loss)
    loss.backward()
    assert any(p.grad is not None and p.grad.abs().sum() > 0 for p in detector.parameters())


def test_match_detections_is_one_to_one_and_label_aware():
    gt = np.array([[0, 0, 10, 10], [20, 20, 40, 40], [50, 50, 60, 60]], np.float32)
    pred = np.array([[21, 21, 40, 40], [0, 0, 10, 11], [0, 0, 10, 10], [50, 50, 60, 60]], np.float32)
    match = match_detections(pred, ["b", "a", "a", "a"], gt, ["a", "b", "c"])
    # gt 0 takes the tighter of the two a boxes, gt 1 its b box, gt 2 (a c) is not matched by an a
    assert match.tolist() == [2, 0, -1]
    assert match_detections(np.zeros((0, 4)), [], gt, ["a", "b", "c"]).tolist() == [-1, -1, -1]
    assert match_detections(pred, ["b", "a", "a", "a"], gt, ["a", "b", "c"], iou=0.99).tolist() == [2, -1, -1]


def test_detection_quality_of_perfect_detections():
    gt = np.array([[0, 0, 10, 10], [20, 20, 40, 40]], np.float32)
    det = Detections(gt.copy(), ["a", "b"], np.array([0.9, 0.8], np.float32), torch.zeros(2, 4))
    quality = detection_quality([det], [gt], [["a", "b"]])
    assert quality["recall"] == quality["precision"] == quality["scene_exact"] == 1.0
    assert quality["ap_a"] == quality["ap_b"] == 1.0 and quality["map"] == 1.0
    assert "ap_c" not in quality  # the classes scored are those of the ground truth and the detections


def test_load_or_train_detector_caches(tmp_path):
    cfg = tiny_config()
    scenes = [toy_scene(s) for s in range(2)]
    key = detector_cache_key(cfg, PART_TYPES, [s.seed for s in scenes])
    assert key != detector_cache_key(cfg, PART_TYPES, [1, 0])
    assert key != detector_cache_key(tiny_config(lr=1e-4), PART_TYPES, [0, 1])
    assert key != detector_cache_key(cfg, ("a", "b"), [0, 1])

    def trainer_factory():
        return pl.Trainer(accelerator="cpu", max_epochs=1, logger=False, enable_checkpointing=False,
                          enable_progress_bar=False, enable_model_summary=False)

    trained, info = load_or_train_detector(cfg, PART_TYPES, scenes, trainer_factory, tmp_path, key)
    assert not info["cached"] and info["train_seconds"] > 0 and (tmp_path / f"detector_{key}.pt").exists()
    loaded, info2 = load_or_train_detector(cfg, PART_TYPES, scenes, trainer_factory, tmp_path, key)
    assert info2["cached"] and info2["train_seconds"] == info["train_seconds"]
    image = [scenes[0].image]
    assert torch.equal(trained.features_for_boxes(image, [scenes[0].boxes])[0],
                       loaded.features_for_boxes(image, [scenes[0].boxes])[0])


def test_context_boxes_are_enlarged_about_the_centre_and_clipped():
    from hrc_lab.grasp.observation import enlarged_boxes

    boxes = np.array([[20, 20, 30, 40], [0, 0, 10, 10]], np.float32)
    np.testing.assert_allclose(enlarged_boxes(boxes, 2.0, SIZE), [[15, 10, 35, 50], [0, 0, 15, 15]])
    np.testing.assert_allclose(enlarged_boxes(boxes, 1.0, SIZE), boxes)
    assert enlarged_boxes(np.zeros((0, 4)), 1.8, SIZE).shape == (0, 4)


def test_context_scale_is_validated_and_shares_the_trained_network():
    with pytest.raises(ValueError, match="grasp.detector.context_scale"):
        tiny_config(context_scale=0.5)
    seeds = [1, 2, 3]
    key = detector_cache_key(tiny_config(), PART_TYPES, seeds)
    assert key == detector_cache_key(tiny_config(context_scale=1.8), PART_TYPES, seeds)
    assert key != detector_cache_key(tiny_config(width=8), PART_TYPES, seeds)
