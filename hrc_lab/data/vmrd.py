"""Data sets in the on-disk layout of VMRD v2 (the Visual Manipulation Relationship Dataset of VMRN; thesis
Sec. 6.4.2, Table 6.3): read one into the scenes the Ch.6 models see, and write our rendered clutter scenes in it.

The layout (Pascal-VOC style)::

    <root>/Annotations/<id>.xml             <annotation>: <filename>, <size> (<width>, <height>, <depth>), then one
                                            <object> per object: <name> (its class), <bndbox> (<xmin>, <ymin>,
                                            <xmax>, <ymax>: 1-based, inclusive pixels), <index> (its node id in the
                                            image), <father> and <children> (node ids, one <num> each)
    <root>/JPEGImages/<id>.jpg              the image (any extension OpenCV reads; we write .png, lossless, so the
                                            detector reads the pixels it was trained on)
    <root>/ImageSets/Main/trainval.txt      the ids of the training images, one per line
    <root>/ImageSets/Main/test.txt          the ids of the test images

Relationships (the manipulation relationship tree of VMRN): an object's children lie on it and must be removed
before it can be grasped; its fathers are the objects it lies on. An object without children can be grasped. When
we write our scenes, a part's children are its blockers under the Sec. 6.3 rule (the parts resting on it and those
in its fingers' way), its fathers the parts it blocks, so reading them back gives the rule's labels.

Every problem with a root or a file raises :class:`~hrc_lab.data.files.DataFileError` naming it: a missing folder or
image set, an XML that does not parse or lacks a field, a relationship naming a node the image does not have, a box
outside the image, an image that cannot be read.
"""

from __future__ import annotations

import hashlib
import xml.etree.ElementTree as ET
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from hrc_lab.data.files import DataFileError
from hrc_lab.data.vmrd_layout import SPLITS, check_layout
from hrc_lab.env.clutter.spec import ClutterObject, ClutterScene

IMAGE_EXTENSIONS = (".jpg", ".jpeg", ".png")


@dataclass
class AnnotatedScene:
    """One image of a VMRD-layout data set as a Ch.6 scene: the image and each object's class and box (its pose,
    which such data sets do not give, is NaN), with ``children[i]``: the objects (indices into ``scene.objects``)
    to remove before object i."""

    image_id: str
    scene: ClutterScene
    children: list[list[int]]


def image_ids(root: str | Path, split: str) -> list[str]:
    """The ids ``ImageSets/Main/<split>.txt`` lists (blank lines skipped)."""
    if split not in SPLITS:
        raise ValueError(f"split must be one of {SPLITS}, got '{split}'")
    path = check_layout(root) / "ImageSets" / "Main" / f"{split}.txt"
    ids = [line.strip() for line in path.read_text().splitlines() if line.strip()]
    if not ids:
        raise DataFileError(f"{path}: lists no image")
    return ids


def read_vmrd(root: str | Path, split: str, image_size: int | None = None) -> list[AnnotatedScene]:
    """Every image of ``split`` with its annotation; with ``image_size``, each one :func:`letterboxed <letterbox>`
    to that square side (the detector's input)."""
    root = Path(root)
    images = (read_image(root, image_id) for image_id in image_ids(root, split))
    return [image if image_size is None else letterbox(image, image_size) for image in images]


def letterbox(image: AnnotatedScene, size: int) -> AnnotatedScene:
    """The image padded at its right or bottom to a square (black), then scaled to ``size`` x ``size`` px, with its
    boxes scaled alike (VMRD's images are 4:3; ours are square already and come back unchanged)."""
    import cv2

    scene = image.scene
    height, width = scene.image.shape[:2]
    if height == width == size:
        return image
    side = max(height, width)
    square = np.zeros((side, side, 3), dtype=scene.image.dtype)
    square[:height, :width] = scene.image
    interpolation = cv2.INTER_AREA if size < side else cv2.INTER_LINEAR
    pixels = np.ascontiguousarray(cv2.resize(square, (size, size), interpolation=interpolation))
    scale = size / side
    objects = [replace(obj, box=np.asarray(obj.box, dtype=np.float32) * np.float32(scale)) for obj in scene.objects]
    resized = replace(scene, image=pixels, objects=objects, segmentation=np.full((size, size), -1, dtype=np.int32))
    return replace(image, scene=resized)


def read_image(root: Path, image_id: str) -> AnnotatedScene:
    """One image and its ``Annotations/<id>.xml``, at the image's own size."""
    import cv2

    path = root / "Annotations" / f"{image_id}.xml"
    names, boxes, nodes, children_ids = _read_annotation(path)
    image_path = next((p for p in (root / "JPEGImages" / f"{image_id}{e}" for e in IMAGE_EXTENSIONS) if p.is_file()),
                      None)
    if image_path is None:
        raise DataFileError(f"{root / 'JPEGImages'}: has no image {image_id} ({', '.join(IMAGE_EXTENSIONS)})")
    bgr = cv2.imread(str(image_path), cv2.IMREAD_COLOR)
    if bgr is None:
        raise DataFileError(f"{image_path}: not a readable image")
    image = np.ascontiguousarray(bgr[..., ::-1])
    height, width = image.shape[:2]
    if len(boxes) and (boxes[:, 2].max() > width or boxes[:, 3].max() > height):
        raise DataFileError(f"{path}: a box reaches beyond the {width} x {height} image")
    index_of = {node: i for i, node in enumerate(nodes)}
    children = []
    for node, kids in zip(nodes, children_ids):
        unknown = [k for k in kids if k not in index_of]
        if unknown:
            raise DataFileError(f"{path}: object {node} names children {unknown} that the image does not have")
        children.append(sorted(index_of[k] for k in kids))
    unknown_pose = np.full(3, np.nan), np.full(4, np.nan)
    objects = [ClutterObject(name, *unknown_pose, box) for name, box in zip(names, boxes)]
    scene = ClutterScene(seed=_seed(image_id), image=image, objects=objects,
                         segmentation=np.full((height, width), -1, dtype=np.int32))
    return AnnotatedScene(image_id, scene, children)


def write_vmrd(root: str | Path, splits: dict[str, list[ClutterScene]],
               children: dict[str, list[list[list[int]]]]) -> Path:
    """Write ``splits`` (``trainval`` and ``test`` lists of scenes; ``children[split][k][i]``: the parts to remove
    before part i of scene k) in VMRD's layout under ``root``; each image's id is its scene seed (9 digits)."""
    import cv2

    root = Path(root)
    for folder in ("Annotations", "JPEGImages", "ImageSets/Main"):
        (root / folder).mkdir(parents=True, exist_ok=True)
    for split in SPLITS:
        ids = []
        for scene, kids in zip(splits[split], children[split], strict=True):
            image_id = f"{scene.seed:09d}"
            cv2.imwrite(str(root / "JPEGImages" / f"{image_id}.png"), np.ascontiguousarray(scene.image[..., ::-1]))
            _annotation(image_id, scene, kids).write(root / "Annotations" / f"{image_id}.xml", encoding="utf-8")
            ids.append(image_id)
        (root / "ImageSets" / "Main" / f"{split}.txt").write_text("\n".join(ids) + "\n")
    return root


def _annotation(image_id: str, scene: ClutterScene, children: list[list[int]]) -> ET.ElementTree:
    top = ET.Element("annotation")
    ET.SubElement(top, "filename").text = f"{image_id}.png"
    size = ET.SubElement(top, "size")
    height, width = scene.image.shape[:2]
    for tag, value in (("width", width), ("height", height), ("depth", 3)):
        ET.SubElement(size, tag).text = str(value)
    fathers = [[j for j, kids in enumerate(children) if i in kids] for i in range(len(scene.objects))]
    for i, obj in enumerate(scene.objects):
        item = ET.SubElement(top, "object")
        ET.SubElement(item, "name").text = obj.type
        box = ET.SubElement(item, "bndbox")
        x0, y0, x1, y1 = (int(round(float(v))) for v in obj.box)  # ours: 0-based, x1 and y1 exclusive
        for tag, value in (("xmin", x0 + 1), ("ymin", y0 + 1), ("xmax", x1), ("ymax", y1)):
            ET.SubElement(box, tag).text = str(value)
        ET.SubElement(item, "index").text = str(i + 1)
        for tag, nodes in (("father", fathers[i]), ("children", children[i])):
            group = ET.SubElement(item, tag)
            for node in nodes:
                ET.SubElement(group, "num").text = str(node + 1)
        ET.SubElement(item, "difficult").text = "0"
    ET.indent(top)
    return ET.ElementTree(top)


def _read_annotation(path: Path) -> tuple[list[str], np.ndarray, list[int], list[list[int]]]:
    """Class names, (n, 4) boxes (0-based, x1 and y1 exclusive), node ids and children's node ids of one XML."""
    if not path.is_file():
        raise DataFileError(f"{path}: missing (every listed image needs its annotation)")
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as err:
        raise DataFileError(f"{path}: not well-formed XML ({err})") from err
    names, boxes, nodes, children = [], [], [], []
    for k, item in enumerate(root.findall("object")):
        where = f"{path}: object {k + 1}"
        names.append(_text(item, "name", where).lower())
        xmin, ymin, xmax, ymax = (_number(item, f"bndbox/{tag}", where) for tag in ("xmin", "ymin", "xmax", "ymax"))
        if not (1 <= xmin <= xmax and 1 <= ymin <= ymax):
            raise DataFileError(f"{where}: box ({xmin}, {ymin}, {xmax}, {ymax}) is empty or starts before pixel 1")
        boxes.append([xmin - 1, ymin - 1, xmax, ymax])
        nodes.append(int(_number(item, "index", where)))
        children.append([int(_number(num, ".", where)) for num in item.findall("children/num")])
        if item.find("children") is None or item.find("father") is None:
            raise DataFileError(f"{where}: has no <father> or <children> (VMRD lists both, maybe empty)")
    if len(set(nodes)) != len(nodes):
        raise DataFileError(f"{path}: repeats an object <index> ({nodes})")
    return names, np.asarray(boxes, dtype=np.float32).reshape(-1, 4), nodes, children


def _text(item: ET.Element, tag: str, where: str) -> str:
    found = item.find(tag)
    if found is None or not (found.text or "").strip():
        raise DataFileError(f"{where}: has no <{tag}>")
    return found.text.strip()


def _number(item: ET.Element, tag: str, where: str) -> float:
    text = item.text if tag == "." else _text(item, tag, where)
    try:
        return float(text)
    except (TypeError, ValueError) as err:
        raise DataFileError(f"{where}: <{tag}> is not a number ({text!r})") from err


def _seed(image_id: str) -> int:
    """The scene seed of an image we wrote (its id), else a stable number from the id (the detector's cache key)."""
    if image_id.isdigit():
        return int(image_id)
    return int(hashlib.sha1(image_id.encode()).hexdigest()[:12], 16)
