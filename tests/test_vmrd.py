"""Data sets in VMRD v2's layout (Table 6.3): a VMRD-style annotation the test writes by hand, our scenes written
and read back with the rule's labels, every malformed root or file named in its error, 4:3 images letterboxed to
the detector's square, and Table 6.3 end to end on a data set of other classes."""

import numpy as np
import pandas as pd
import pytest

from hrc_lab.config import validate_config
from hrc_lab.data.files import DataFileError
from hrc_lab.data.vmrd import letterbox, read_vmrd, write_vmrd
from hrc_lab.data.vmrd_layout import check_layout
from hrc_lab.env.clutter.rule import blocker_solution, blockers
from hrc_lab.env.clutter.spec import ClutterObject, ClutterScene, ClutterSpec
from hrc_lab.experiments.ch6_grasp import dataset_classes, image_accuracy
from hrc_lab.registry import ConfigError

# VMRD's own conventions: 1-based inclusive boxes, node ids that need not start at 1, a .jpg image
MUG_ON_BOOK = """<annotation>
  <filename>00001.jpg</filename>
  <size><width>64</width><height>64</height><depth>3</depth></size>
  <object>
    <name>Book</name>
    <bndbox><xmin>5</xmin><ymin>10</ymin><xmax>40</xmax><ymax>50</ymax></bndbox>
    <difficult>0</difficult>
    <index>7</index>
    <father></father>
    <children><num>9</num></children>
  </object>
  <object>
    <name>mug</name>
    <bndbox><xmin>20</xmin><ymin>20</ymin><xmax>30</xmax><ymax>32</ymax></bndbox>
    <difficult>0</difficult>
    <index>9</index>
    <father><num>7</num></father>
    <children></children>
  </object>
</annotation>
"""


def write_layout(root, annotation: str = MUG_ON_BOOK, image_id: str = "00001"):
    import cv2

    for folder in ("Annotations", "JPEGImages", "ImageSets/Main"):
        (root / folder).mkdir(parents=True, exist_ok=True)
    (root / "Annotations" / f"{image_id}.xml").write_text(annotation)
    cv2.imwrite(str(root / "JPEGImages" / f"{image_id}.jpg"), np.full((64, 64, 3), 128, np.uint8))
    (root / "ImageSets" / "Main" / "trainval.txt").write_text(f"{image_id}\n")
    (root / "ImageSets" / "Main" / "test.txt").write_text(f"{image_id}\n\n")
    return root


def test_reads_a_vmrd_annotation(tmp_path):
    [image] = read_vmrd(write_layout(tmp_path), "test")
    assert image.image_id == "00001" and image.scene.image.shape == (64, 64, 3)
    assert image.scene.types == ["book", "mug"]  # class names, lower-cased as VMRN reads them
    assert np.array_equal(image.scene.boxes, [[4, 9, 40, 50], [19, 19, 30, 32]])  # 0-based, x1 and y1 exclusive
    assert image.children == [[1], []]  # the mug lies on the book: move it first
    assert np.isnan(image.scene.objects[0].position).all()  # no pose in such data sets


def hand_scene(seed: int) -> tuple[ClutterScene, ClutterSpec]:
    """b lying on a, an isolated c: the rule blocks a by b."""
    spec = ClutterSpec()
    rng = np.random.default_rng(seed)
    image = rng.integers(0, 255, (spec.image_size, spec.image_size, 3), dtype=np.uint8)
    pose = np.array([1.0, 0, 0, 0])
    objects = [ClutterObject("a", np.array([0.0, 0.0, 0.009]), pose, np.array([70, 70, 80, 78], np.float32)),
               ClutterObject("b", np.array([0.0, 0.0, 0.033]), pose, np.array([60, 68, 100, 82], np.float32)),
               ClutterObject("c", np.array([0.05, 0.05, 0.035]), pose, np.array([110, 20, 130, 40], np.float32))]
    resting = np.zeros((3, 3), bool)
    resting[0, 1] = True
    return ClutterScene(seed, image, objects, np.full(image.shape[:2], -1), resting), spec


def test_our_scenes_written_and_read_back_keep_image_boxes_and_the_rules_labels(tmp_path):
    scenes, spec = zip(*(hand_scene(s) for s in (11, 12)))
    children = [blockers(spec[0], s) for s in scenes]
    assert children[0][0] == [1]  # the rule: b blocks a
    write_vmrd(tmp_path, {"trainval": [scenes[0]], "test": [scenes[1]]}, {"trainval": children[:1],
                                                                           "test": children[1:]})
    [back] = read_vmrd(tmp_path, "test")
    assert back.image_id == "000000012" and back.scene.seed == 12
    assert np.array_equal(back.scene.image, scenes[1].image)  # PNG: the detector reads the pixels it trained on
    assert np.array_equal(back.scene.boxes, scenes[1].boxes) and back.scene.types == ["a", "b", "c"]
    assert back.children == children[1]
    assert [blocker_solution(back.scene, i, b) for i, b in enumerate(back.children)] == [["move", "b"], ["grasp"],
                                                                                         ["grasp"]]


@pytest.mark.parametrize("break_it, message", [
    (lambda root: (root / "Annotations" / "00001.xml").write_text("<annotation><object>"), "not well-formed XML"),
    (lambda root: (root / "Annotations" / "00001.xml").write_text(MUG_ON_BOOK.replace("<num>9</num>", "<num>4</num>")),
     r"object 7 names children \[4\]"),
    (lambda root: (root / "Annotations" / "00001.xml").write_text(MUG_ON_BOOK.replace("<xmax>40", "<xmax>99")),
     "beyond the 64 x 64 image"),
    (lambda root: (root / "Annotations" / "00001.xml").write_text(MUG_ON_BOOK.replace("<index>9", "<index>7")),
     "repeats an object <index>"),
    (lambda root: (root / "Annotations" / "00001.xml").write_text(MUG_ON_BOOK.replace("<name>mug</name>", "")),
     "object 2: has no <name>"),
    (lambda root: (root / "Annotations" / "00001.xml").write_text(MUG_ON_BOOK.replace("<ymin>10", "<ymin>ten")),
     "<bndbox/ymin> is not a number"),
    (lambda root: (root / "JPEGImages" / "00001.jpg").unlink(), "has no image 00001"),
    (lambda root: (root / "JPEGImages" / "00001.jpg").write_bytes(b"not an image"), "not a readable image"),
    (lambda root: (root / "Annotations" / "00001.xml").unlink(), "00001.xml: missing"),
    (lambda root: (root / "ImageSets" / "Main" / "test.txt").write_text("\n"), "test.txt: lists no image"),
])
def test_a_malformed_file_is_named(tmp_path, break_it, message):
    root = write_layout(tmp_path)
    break_it(root)
    with pytest.raises(DataFileError, match=message):
        read_vmrd(root, "test")


def test_a_missing_or_incomplete_root_fails_the_config(tmp_path, compose_config):
    with pytest.raises(DataFileError, match="no such directory"):
        check_layout(tmp_path / "VMRD")
    (tmp_path / "Annotations").mkdir()
    with pytest.raises(DataFileError, match="has no JPEGImages/ folder"):
        check_layout(tmp_path)
    (tmp_path / "JPEGImages").mkdir()
    with pytest.raises(DataFileError, match="trainval.txt: missing"):
        check_layout(tmp_path)
    with pytest.raises(ConfigError, match="env.vmrd_root: .*has no Annotations/ folder"):
        validate_config(compose_config("experiment=ch6/table_6_3", f"env.vmrd_root={tmp_path / 'JPEGImages'}"))
    assert validate_config(compose_config("experiment=ch6/table_6_3")).env.vmrd_root is None


def test_a_4_to_3_image_is_letterboxed_to_the_detectors_square(tmp_path):
    """64 x 56: padded at the bottom to 64 x 64, then halved: the boxes halve, the padding is black, the classes are the
    data set's."""
    import cv2

    root = write_layout(tmp_path, MUG_ON_BOOK.replace("<height>64", "<height>56"))
    cv2.imwrite(str(root / "JPEGImages" / "00001.jpg"), np.full((56, 64, 3), 200, np.uint8))
    [image] = read_vmrd(root, "trainval", image_size=32)
    assert image.scene.image.shape == (32, 32, 3) and image.scene.segmentation.shape == (32, 32)
    assert image.scene.image[:28].min() > 150 and image.scene.image[28:].max() == 0  # rows 28-31: padding
    np.testing.assert_allclose(image.scene.boxes, [[2, 4.5, 20, 25], [9.5, 9.5, 15, 16]])
    assert image.children == [[1], []] and dataset_classes([image]) == ("book", "mug")
    [same] = read_vmrd(root, "trainval", image_size=None)
    assert letterbox(same, 64).scene.boxes.tolist() == same.scene.boxes.tolist()  # the long side already fits


DAILY_CLASSES = ("book", "mug", "remote controller")


def daily_life_layout(root, count: int = 8):
    """``count`` 4:3 images in VMRD's layout, each a book with a mug on it (its child) and a remote controller
    beside, drawn as coloured rectangles at random places; 6 for trainval, the rest for test."""
    import cv2

    rng = np.random.default_rng(0)
    for folder in ("Annotations", "JPEGImages", "ImageSets/Main"):
        (root / folder).mkdir(parents=True, exist_ok=True)
    ids = []
    for k in range(count):
        image = np.full((96, 128, 3), 90, np.uint8)
        x, y = int(rng.integers(4, 60)), int(rng.integers(4, 40))
        boxes = {"book": (x, y, x + 44, y + 30), "mug": (x + 12, y + 8, x + 26, y + 22),
                 "remote controller": (100, int(rng.integers(4, 60)), 118, 0)}
        boxes["remote controller"] = (100, boxes["remote controller"][1], 118, boxes["remote controller"][1] + 30)
        objects = []
        for index, (name, colour) in enumerate(zip(DAILY_CLASSES, ((40, 40, 200), (200, 200, 40), (40, 200, 40)))):
            x0, y0, x1, y1 = boxes[name]
            cv2.rectangle(image, (x0, y0), (x1 - 1, y1 - 1), colour, thickness=-1)
            children = "<num>2</num>" if name == "book" else ""
            father = "<num>1</num>" if name == "mug" else ""
            objects.append(f"<object><name>{name}</name><bndbox><xmin>{x0 + 1}</xmin><ymin>{y0 + 1}</ymin>"
                           f"<xmax>{x1}</xmax><ymax>{y1}</ymax></bndbox><index>{index + 1}</index>"
                           f"<father>{father}</father><children>{children}</children></object>")
        image_id = f"{k + 1:05d}"
        cv2.imwrite(str(root / "JPEGImages" / f"{image_id}.jpg"), image)
        (root / "Annotations" / f"{image_id}.xml").write_text(
            f"<annotation><size><width>128</width><height>96</height><depth>3</depth></size>{''.join(objects)}"
            "</annotation>")
        ids.append(image_id)
    (root / "ImageSets" / "Main" / "trainval.txt").write_text("\n".join(ids[:6]) + "\n")
    (root / "ImageSets" / "Main" / "test.txt").write_text("\n".join(ids[6:]) + "\n")
    return root


@pytest.mark.parametrize("grasp", ["grasp=gnn_att", "grasp=gvmrn_rf grasp.detector.mode=oracle"])
def test_table_6_3_runs_on_a_data_set_of_other_classes_and_image_sizes(tmp_path, run_job, grasp):
    """The thesis' Table 6.3 command on a user's VMRD-layout copy: its classes (one with a space) become the
    detector's and the solver's, its 4:3 images are letterboxed, and the run finishes with image-based accuracy."""
    root = daily_life_layout(tmp_path / "VMRD")
    job = run_job("experiment=ch6/table_6_3", f"env.vmrd_root={root}", *grasp.split(), "hydra.mode=RUN",
                  "trainer.max_epochs=1", "grasp.steps=2", "grasp.detector.steps=2", "grasp.detector.width=4",
                  "grasp.detector.fpn_channels=8", "grasp.detector.representation_size=16")
    assert job.metrics["classes"] == 3 and job.metrics["trainval_images"] == 6 and job.metrics["test_images"] == 2
    assert job.metrics["written_by_hrc_lab"] == 0 and 0 <= job.metrics["ia"] <= 1
    assert job.run.info.status == "FINISHED" and job.run.data.metrics["ia"] == pytest.approx(job.metrics["ia"])


def test_image_accuracy_needs_every_object_of_an_image_right():
    outcomes = {"scene": [0, 0, 1, 1, 1, 2], "correct": [True, True, True, False, True, True]}
    metrics = image_accuracy(pd.DataFrame(outcomes), objects=[2, 3, 1])
    assert metrics["ia"] == pytest.approx(2 / 3) and metrics["oa"] == pytest.approx(5 / 6)
    assert (metrics["ia_1"], metrics["ia_2"], metrics["ia_3"]) == (1.0, 1.0, 0.0)
