"""Cluttered industrial parts of Ch.6 (Sec. 6.3): the scene spec and the data a rendered scene carries.

Three part types a, b, c (at most 3, 2 and 1 in a scene; a the smallest, c the tallest) are dropped on a table at
random positions and yaw angles and settle under MuJoCo physics, so they overlap and rest on each other
(:mod:`hrc_lab.env.clutter.scenes`, pure MuJoCo). A top-down camera renders the RGB image the detector sees. The
robot grasps only from the top with a fixed gripper orientation; which part it can grasp, and what to move first
when it cannot, is decided by one rule (:mod:`hrc_lab.env.clutter.rule`), the expert the models learn from.

The camera is a pinhole looking straight down at the table centre from ``camera_height``; its field of view is
chosen so the spawn area plus a margin (:attr:`ClutterSpec.view_half_width`) fills the image.
:meth:`ClutterSpec.project` maps world points to pixels (image x along world x, image rows down along -y).

This module imports no simulator: validating a ``conf/env/clutter*.yaml`` stays fast.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

PART_TYPES = ("a", "b", "c")


@dataclass(frozen=True)
class ClutterSpec:
    """Parts, table area, drop, camera and gripper of the clutter cell (``conf/env/clutter*.yaml``). The thesis
    gives no sizes: these are ours, tuned so that every solution occurs."""

    # most parts of each type in a scene (Sec. 6.3)
    max_counts: dict[str, int] = field(default_factory=lambda: {"a": 3, "b": 2, "c": 1})
    # full extents (x, y, z) of each part's box, m: a smallest, c tallest
    part_size: dict[str, list[float]] = field(
        default_factory=lambda: {"a": [0.032, 0.024, 0.018], "b": [0.10, 0.04, 0.03], "c": [0.06, 0.06, 0.07]}
    )
    min_objects: int = 3  # parts per scene: uniform in [min_objects, max_objects]
    max_objects: int = 6
    spawn_half_width: float = 0.06  # parts are dropped within +-this of the table centre (x and y), m
    drop_spacing: float = 0.02  # each part is dropped with its lowest corner this far above the pile, m
    max_drop_tilt_deg: float = 10.0  # initial roll and pitch are uniform within +-this, degrees (yaw is uniform)
    min_visible_fraction: float = 0.1  # a part must show this fraction of its smallest face's pixels, else redraw
    image_size: int = 160  # square top-down RGB image, pixels
    camera_height: float = 0.55  # m above the table centre, looking straight down
    # the image covers the spawn area plus the largest half-footprint plus this, m (sets the field of view)
    view_margin: float = 0.03
    finger_width: float = 0.012  # gripper finger extent across the closing direction (y), m
    finger_thickness: float = 0.008  # finger extent along the closing direction (x), m
    finger_gap: float = 0.003  # opening beyond the part on each side, m
    grasp_depth: float = 0.008  # how far below a part's top the fingers reach, m

    def __post_init__(self) -> None:
        if set(self.max_counts) != set(PART_TYPES) or set(self.part_size) != set(PART_TYPES):
            raise ValueError(f"env.max_counts and env.part_size must list exactly the part types {PART_TYPES}")
        if any(n < 0 for n in self.max_counts.values()):
            raise ValueError(f"env.max_counts must be >= 0, got {self.max_counts}")
        if any(len(s) != 3 or min(s) <= 0 for s in self.part_size.values()):
            raise ValueError(f"env.part_size must give 3 positive extents per part, got {self.part_size}")
        if not 1 <= self.min_objects <= self.max_objects <= sum(self.max_counts.values()):
            raise ValueError(
                f"env.min_objects={self.min_objects} and env.max_objects={self.max_objects} must satisfy "
                f"1 <= min <= max <= {sum(self.max_counts.values())} (the parts env.max_counts allows)"
            )
        if not 32 <= self.image_size <= 1024:
            raise ValueError(f"env.image_size must be in [32, 1024] pixels, got {self.image_size}")
        if min(self.spawn_half_width, self.camera_height, self.finger_width, self.finger_thickness) <= 0:
            raise ValueError("env.spawn_half_width, camera_height, finger_width and finger_thickness must be > 0")
        if self.finger_gap < 0 or self.grasp_depth <= 0:
            raise ValueError("env.finger_gap must be >= 0 and env.grasp_depth > 0")
        if self.drop_spacing < 0 or self.view_margin < 0:
            raise ValueError("env.drop_spacing and env.view_margin must be >= 0")
        if not 0 <= self.max_drop_tilt_deg <= 45:
            raise ValueError(f"env.max_drop_tilt_deg must be in [0, 45], got {self.max_drop_tilt_deg}")
        if not 0 <= self.min_visible_fraction <= 1:
            raise ValueError(f"env.min_visible_fraction must be in [0, 1], got {self.min_visible_fraction}")
        if self.camera_height <= 2 * max(max(s) for s in self.part_size.values()):
            raise ValueError(f"env.camera_height={self.camera_height} m must exceed twice the largest env.part_size")

    @property
    def cell(self) -> str:
        return "clutter"

    @property
    def view_half_width(self) -> float:
        """Half the side of the square the camera sees on the table plane, m."""
        half_footprint = max(float(np.hypot(s[0], s[1])) for s in self.part_size.values()) / 2
        return self.spawn_half_width + half_footprint + self.view_margin

    @property
    def fovy(self) -> float:
        """The camera's (vertical = horizontal) field of view, degrees."""
        return float(np.degrees(2 * np.arctan(self.view_half_width / self.camera_height)))

    @property
    def pixel_scale(self) -> float:
        """The camera's focal length in pixels: a length x at depth d spans ``pixel_scale * x / d`` pixels."""
        return self.image_size / 2 / (self.view_half_width / self.camera_height)

    def project(self, points: np.ndarray) -> np.ndarray:
        """(..., 3) world points -> (..., 2) pixel coordinates (x right, y down; pixel k spans [k, k + 1))."""
        points = np.asarray(points, dtype=float)
        scale = self.pixel_scale
        depth = self.camera_height - points[..., 2]
        u = self.image_size / 2 + scale * points[..., 0] / depth
        v = self.image_size / 2 - scale * points[..., 1] / depth
        return np.stack([u, v], axis=-1)

    def unproject(self, pixels: np.ndarray, depth: np.ndarray) -> np.ndarray:
        """(..., 2) pixel coordinates and their (...) depths along the optical axis (m) -> (..., 3) world points:
        the inverse of :meth:`project`."""
        pixels, depth = np.asarray(pixels, dtype=float), np.asarray(depth, dtype=float)
        scale = self.pixel_scale
        x = (pixels[..., 0] - self.image_size / 2) * depth / scale
        y = -(pixels[..., 1] - self.image_size / 2) * depth / scale
        return np.stack([x, y, self.camera_height - depth], axis=-1)


@dataclass(frozen=True)
class VmrdSpec(ClutterSpec):
    """A data set in VMRD v2's on-disk layout (``conf/env/vmrd.yaml``, Table 6.3; :mod:`hrc_lab.data.vmrd`):
    ``vmrd_root`` names it. Without one, the clutter scenes of this spec (Table 6.1's) are written in that layout
    and read back, so the protocol runs the same way on both. Images of any size are letterboxed to ``image_size``
    pixels square; the data set's classes (VMRD's 31, or our a, b, c) are the detector's and the solver's."""

    vmrd_root: str | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.vmrd_root is not None:
            from hrc_lab.data.vmrd_layout import check_layout

            try:
                check_layout(self.vmrd_root)
            except ValueError as err:
                raise ValueError(f"env.vmrd_root: {err}") from None

    def clutter(self) -> ClutterSpec:
        """The clutter scene spec of the same values (the scenes written when there is no ``vmrd_root``)."""
        return ClutterSpec(**{f.name: getattr(self, f.name) for f in fields(ClutterSpec)})


def box_centre_median(image: np.ndarray, box: np.ndarray) -> float:
    """The median of a (H, W) image (a depth or height map) over the central third of a (4,) px box (x0, y0, x1,
    y1): the part's top as a top-down depth camera sees it, away from the box's edges."""
    x0, y0, x1, y1 = np.asarray(box, dtype=float)
    cx, cy, w, h = (x0 + x1) / 2, (y0 + y1) / 2, (x1 - x0) / 6, (y1 - y0) / 6
    r0, c0 = int(np.floor(cy - h)), int(np.floor(cx - w))
    return float(np.median(image[r0:max(int(np.ceil(cy + h)), r0 + 1), c0:max(int(np.ceil(cx + w)), c0 + 1)]))


@dataclass
class ClutterObject:
    """One settled part: its type, pose and its box in the image."""

    type: str
    position: np.ndarray  # (3,) centre in the world frame, m
    quaternion: np.ndarray  # (4,) w, x, y, z
    box: np.ndarray  # (4,) x0, y0, x1, y1 in pixels: the extent of its visible pixels


@dataclass
class ClutterScene:
    """A rendered scene: the image, its parts, per pixel which part is seen (-1: table) and, from the same camera, the
    depth (None for an image without a depth camera, e.g. a VMRD data set's)."""

    seed: int
    image: np.ndarray  # (H, W, 3) uint8, top-down
    objects: list[ClutterObject]
    segmentation: np.ndarray  # (H, W) int, index into ``objects`` or -1
    # resting[i][j]: part j lies on part i (from the settled contacts)
    resting: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), dtype=bool))
    depth: np.ndarray | None = None  # (H, W) float, m along the optical axis

    @property
    def types(self) -> list[str]:
        return [o.type for o in self.objects]

    @property
    def boxes(self) -> np.ndarray:
        return np.stack([o.box for o in self.objects]).astype(np.float32)
