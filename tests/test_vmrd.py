"""Data sets in VMRD v2's layout (Table 6.3): a VMRD-style annotation the test writes by hand, our scenes written
and read back with the rule's labels, every malformed root or file named in its error, and the refusals before
any training."""

import numpy as np
import pandas as pd
import pytest

from hrc_lab.config import validate_config
from hrc_lab.data.files import DataFileError
from hrc_lab.data.vmrd import check_layout, read_vmrd, write_vmrd
from hrc_lab.env.clutter.rule import blocker_solution, blockers
from hrc_lab.env.clutter.spec import ClutterObject, ClutterScene, ClutterSpec, VmrdSpec
from hrc_lab.experiments.ch6_grasp import image_accuracy, readable_vmrd
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


def test_other_classes_or_image_sizes_are_refused_before_training(tmp_path):
    daily_life = read_vmrd(write_layout(tmp_path), "trainval")
    with pytest.raises(DataFileError, match=r"classes \['book', 'mug'\] are not part types"):
        readable_vmrd(VmrdSpec(vmrd_root=str(tmp_path)), daily_life)
    parts = read_vmrd(write_layout(tmp_path, MUG_ON_BOOK.replace("Book", "a").replace("mug", "b")), "trainval")
    with pytest.raises(DataFileError, match=r"images are \[\(64, 64\)\] pixels; .*env.image_size=160"):
        readable_vmrd(VmrdSpec(vmrd_root=str(tmp_path)), parts)
    readable_vmrd(VmrdSpec(vmrd_root=str(tmp_path), image_size=64), parts)


def test_image_accuracy_needs_every_object_of_an_image_right():
    outcomes = {"scene": [0, 0, 1, 1, 1, 2], "correct": [True, True, True, False, True, True]}
    metrics = image_accuracy(pd.DataFrame(outcomes), objects=[2, 3, 1])
    assert metrics["ia"] == pytest.approx(2 / 3) and metrics["oa"] == pytest.approx(5 / 6)
    assert (metrics["ia_1"], metrics["ia_2"], metrics["ia_3"]) == (1.0, 1.0, 0.0)
