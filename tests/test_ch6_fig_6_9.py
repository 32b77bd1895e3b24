"""Fig. 6.9 (thesis 6.4.2): data sets of k object types, the two stages' image-based accuracies, the config's
checks and a tiny run logging both per k (its report section: tests/test_report_ch6_grasp.py)."""

from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from hrc_lab.config import validate_config
from hrc_lab.data.vmrd import AnnotatedScene
from hrc_lab.env.clutter.spec import ClutterObject, ClutterScene, ClutterSpec
from hrc_lab.experiments.ch6_grasp import component_accuracy, fewer_types, type_subsets
from hrc_lab.registry import ConfigError


def test_fewer_types_keeps_the_most_numerous_part_types():
    spec = ClutterSpec()  # at most 3 a, 2 b, 1 c; 3-6 parts
    one, two = fewer_types(spec, 1), fewer_types(spec, 2)
    assert one.max_counts == {"a": 3, "b": 0, "c": 0} and (one.min_objects, one.max_objects) == (3, 3)
    assert two.max_counts == {"a": 3, "b": 2, "c": 0} and (two.min_objects, two.max_objects) == (3, 5)
    assert fewer_types(spec, 3) == spec  # every type: Table 6.3's scenes (and their cache)


def image_of(*classes: str) -> AnnotatedScene:
    objects = [ClutterObject(c, np.full(3, np.nan), np.full(4, np.nan), np.zeros(4, np.float32)) for c in classes]
    scene = ClutterScene(0, np.zeros((8, 8, 3), np.uint8), objects, np.full((8, 8), -1))
    return AnnotatedScene("id", scene, [[] for _ in classes])


def test_a_data_sets_type_subsets_keep_the_images_of_its_most_frequent_classes():
    train = [image_of("mug", "book"), image_of("mug", "mug"), image_of("apple", "book"), image_of("book", "mug")]
    test = [image_of("mug"), image_of("book", "mug"), image_of("apple", "mug")]

    def ctx(*counts):
        return SimpleNamespace(cfg=SimpleNamespace(env=SimpleNamespace(vmrd_root="/data/VMRD", image_size=64),
                                                   protocol=SimpleNamespace(type_counts=list(counts))))

    subsets = type_subsets(ctx(1, 2, 3), train, test)  # mug 4, book 3, apple 1 in the training images
    assert {k: (len(a), len(b)) for k, (a, b) in subsets.items()} == {1: (1, 1), 2: (3, 2), 3: (4, 3)}
    with pytest.raises(ValueError, match=r"protocol.type_counts must be values in 1..3 .*got \[4\]"):
        type_subsets(ctx(4), train, test)
    with pytest.raises(ValueError, match=r"protocol.type_counts: /data/VMRD has no trainval or no test image .*"
                                         r"\['mug'\]"):
        type_subsets(ctx(1), train, test[1:])


def test_component_accuracy_separates_the_graspability_from_the_solutions():
    outcomes = pd.DataFrame({
        "scene": [0, 0, 1, 1, 1, 2],
        "grasp_ok": [True, True, True, False, True, True],
        "ungraspable": [True, False, True, True, False, False],
        "solution_ok": [False, True, True, True, True, True],
    })
    metrics = component_accuracy(outcomes, objects=[2, 3, 1])
    assert metrics["grasp_ia"] == pytest.approx(2 / 3)  # image 1 has a wrong graspability
    assert metrics["solution_ia"] == 0.5 and metrics["solution_images"] == 2  # image 2 has nothing to solve
    assert (metrics["grasp_ia_n2"], metrics["grasp_ia_n3"], metrics["grasp_ia_n1"]) == (1.0, 0.0, 1.0)
    assert (metrics["solution_ia_n2"], metrics["solution_ia_n3"]) == (0.0, 1.0) and "solution_ia_n1" not in metrics
    assert np.isnan(component_accuracy(outcomes[outcomes.scene == 2], objects=[2, 3, 1])["solution_ia"])


def test_fig_6_9_config_validates_and_names_a_bad_key(compose_config):
    validated = validate_config(compose_config("experiment=ch6/fig_6_9"))
    assert validated.protocol.type_counts == [1, 2, 3] and validated.grasp.name == "gnn_att"
    with pytest.raises(ConfigError, match=r"protocol.type_counts must be values in 1..3 .*got \[1, 4\]"):
        validate_config(compose_config("experiment=ch6/fig_6_9", "protocol.type_counts=[1,4]"))
    with pytest.raises(ConfigError, match=r"protocol.type_counts must be values in 1..2 .*got \[3\]"):
        validate_config(compose_config("experiment=ch6/fig_6_9", "env.max_counts.c=0", "env.max_objects=5",
                                       "protocol.type_counts=[3]"))
    with pytest.raises(ConfigError, match=r"protocol.type_counts must be distinct values >= 1, got \[2, 2\]"):
        validate_config(compose_config("experiment=ch6/fig_6_9", "protocol.type_counts=[2,2]"))


def test_fig_6_9_logs_both_stages_per_number_of_types(run_job):
    """A tiny detector (ground-truth boxes) and solver: k = 1 renders scenes of part a alone, k = 3 reads Table
    6.3's; both stages' image-based accuracies land in MLflow per k, with the per-k table."""
    job = run_job("experiment=ch6/fig_6_9", "hydra.mode=RUN", "trainer.max_epochs=1", "grasp.steps=2",
                  "grasp.detector.steps=2", "grasp.detector.width=4", "grasp.detector.fpn_channels=8",
                  "grasp.detector.representation_size=16", "grasp.detector.mode=oracle", "protocol.train_images=4",
                  "protocol.test_images=2", "protocol.type_counts=[1,3]")
    for k in (1, 3):
        for name in ("grasp_ia", "ia", "test_images", "train_grasp_acc"):
            assert 0 <= job.metrics[f"types{k}_{name}"] == pytest.approx(job.run.data.metrics[f"types{k}_{name}"])
        assert f"types{k}_solution_ia" in job.metrics
    assert job.metrics["types1_objects"] == 3  # part a alone: 3 parts a scene
    logged = {a.path for a in job.client.list_artifacts(job.run.info.run_id, "tables")}
    assert "tables/fig_6_9.csv" in logged
