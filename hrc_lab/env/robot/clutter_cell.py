"""The Ch.6 robot cell (Sec. 6.4.1, Fig. 6.8): a UR5e with robosuite's Robotiq 2F-140 gripper at the clutter table,
where Algorithm 4's proposals are grasped and the scene is imaged again.

The thesis used the 2F-85. Its 85 mm stroke is shorter than part b (100 mm), which the rule grasps along x at any
yaw (a b turned 45 degrees spans 98 mm in x), and robosuite's 2F-85 model, closed on nothing, stalled at a 60 mm gap
and then folded its fingers through each other (measured here); the 2F-140 (same family, 140 mm stroke) spans every
part at every yaw and closes to about 19 mm.

- **World.** The clutter scene's table plane (:mod:`hrc_lab.env.clutter.scenes`) is this cell's table top, its
  centre the table's centre (:data:`TABLE_TOP`); one box per part the spec allows (``max_counts``), with the scene
  world's sizes, density and friction. :meth:`ClutterCell.place_scene` puts the parts of a rendered scene where they
  settled, so the cell starts from the image the detector read.
- **Camera.** :meth:`ClutterCell.image` is the scene's own top-down camera
  (:class:`~hrc_lab.env.clutter.scenes.SceneCamera`: same pose, intrinsics, part colours and light) rendered at
  the cell's current part poses, with depth. The arm waits at its observation pose, outside the view, while an
  image is taken (it is not drawn). :meth:`ClutterCell.locate` turns a detected box into a 3-D grasp point from
  the depth image and the camera model (no orientation: the thesis' depth camera).
- **Grasp** (the rule's, Sec. 6.3): top down, the fingers closing along the world x axis (the wrist is turned a
  quarter turn from robosuite's UR5e default; the gripper is held straight down, :meth:`ClutterCell.top_down`), the
  finger tips ``grip_depth`` below the part's top (default the rule's ``grasp_depth``; never below
  :data:`TIP_CLEARANCE` above the table). Fully open,
  the 2F-140's pads stand about 6 cm either side of the grasp point, where the rule (and the thesis' 2F-85) has the
  fingers just outside the part, so they come down on neighbours the rule calls clear. With a pre-grasp opening
  (:meth:`ClutterCell.grasp_opening`) the fingers open only to the part's x-extent, seen in the depth image, plus
  the rule's ``finger_gap`` and :data:`PRESHAPE_MARGIN` on each side (the gripper's finger command set from a
  measured table of openings, :meth:`ClutterCell.finger_openings`). With an approach yaw
  (:meth:`ClutterCell.grasp_yaw`) the gripper turns about the vertical before it comes down, to a yaw whose finger
  volumes the depth image shows clear of neighbours, and turns home once it has let go. The arm moves
  by robosuite's OSC_POSE controller (delta input), driven to each waypoint by a proportional law that also holds
  the gripper's orientation. :meth:`ClutterCell.pick` reports which part rose with the gripper and which other
  parts the gripper touched; :meth:`ClutterCell.put` sets the held part down at a point and opens.

Physics: robosuite's default 2 ms step, 20 Hz control.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from hrc_lab.env.clutter.scenes import BASE_COLOURS, SceneCamera, import_mujoco
from hrc_lab.env.clutter.spec import PART_TYPES, ClutterScene, ClutterSpec, box_centre_median
from hrc_lab.env.robot.settings import CELL_CAMERA, YAW_ORDERS

import_mujoco()  # before robosuite does: MuJoCo with an off-screen GL (EGL, else OSMesa) for the scene camera
# isort: off
import hrc_lab.env.robot.cell  # noqa: E402, F401  (first: it imports robosuite quietly, once)
from robosuite.controllers import load_composite_controller_config  # noqa: E402
from robosuite.environments.manipulation.manipulation_env import ManipulationEnv  # noqa: E402
from robosuite.models.arenas import TableArena  # noqa: E402
from robosuite.models.objects import BoxObject  # noqa: E402
from robosuite.models.tasks import ManipulationTask  # noqa: E402
from robosuite.utils.transform_utils import mat2quat, quat2axisangle, quat_inverse, quat_multiply  # noqa: E402
# isort: on

GRIPPER = "Robotiq140Gripper"
TABLE_TOP = 0.8  # m: the cell's table top, the clutter scene's z = 0
TABLE_SIZE = (0.8, 0.8, 0.05)
PARK = np.array([0.3, 0.35])  # x, y where unused parts wait (out of the view and of the workspace), 0.1 m apart in x
TRAY = np.array([0.0, 0.3])  # x, y where requested parts are delivered (outside the camera's view)
ASIDE = np.array([[-0.12 + 0.08 * k, -0.3] for k in range(4)])  # free spots where blocking parts are put aside
OBSERVE = np.array([-0.3, 0.0, 0.25])  # the gripper while an image is taken: outside the camera's view, m (scene frame)
APPROACH = 0.10  # m above the grasp point before descending
LIFT = 0.15  # m above the table after a grasp
RELEASE_CLEARANCE = 0.005  # m between the held part and the table when it is set down
GRIP_STEPS = 40  # control steps to close or open the fingers (2 s: the 2F-85 closes ~3 mm per step)
GAIN = 8.0  # OSC delta per m of error (the controller clips to 0.05 m per step)
ORIENTATION_GAIN = 2.0
WAYPOINT_TOLERANCE = 0.004  # m
MAX_WAYPOINT_STEPS = 120
LIFTED = 0.03  # m a part must rise with the gripper to count as held
TURN_WRIST = np.pi / 2  # from robosuite's UR5e home, so the fingers close along world x
OPENING_LEVELS = 11  # finger commands measured between open (-1) and closed (1) for the pre-grasp opening
PRESHAPE_MARGIN = 0.005  # m per side beyond the rule's finger gap: the box centre's error as the part's centre
ORIENTATION_TOLERANCE = 0.03  # rad: a waypoint is reached when the gripper is also turned this close to its goal
# The approach yaw (grasp_yaw): the 2F-140's finger volumes seen from above, measured on the model at the observation
# pose: each fingertip spans ~3.1 cm across the closing axis and ~1 cm beyond its pad; from ~2 cm above the tips the
# inner finger reaches ~4.5 cm beyond the pad. (reach beyond the pad's inner face, m; height above the tips, m)
FINGER_ZONES = ((0.012, 0.0), (0.045, 0.022))
FINGER_HALF_WIDTH = 0.016  # m across the closing axis
YAW_CANDIDATES = 12  # approach yaws tried, every 15 degrees over the gripper's half turn of symmetry
NARROWEST_BIN = 0.004  # m: of the clear yaws, the narrowest opening (in bins of this) wins, then the smallest turn
TOP_FACE_BAND = 0.005  # m: pixels of the box this close below the grasp point's height are the part's top face
TIP_CLEARANCE = 0.002  # m: the finger tips stop this far above the table however deep the grip


@dataclass
class PickOutcome:
    """What a grasp attempt did: ``held`` the object (index into the placed scene's objects) that rose with the
    gripper or None, ``touched`` the other objects the gripper touched, ``steps`` the control steps used."""

    held: int | None
    touched: list[int] = field(default_factory=list)
    steps: int = 0


@dataclass
class Approach:
    """How the gripper comes down on a part (:meth:`ClutterCell.grasp_yaw`): ``yaw`` (rad about the vertical from the
    rule's fingers closing along x), ``half_opening`` (m, None: fully open) and the finger tips' height ``tips``
    (m, scene frame)."""

    yaw: float
    half_opening: float | None
    tips: float


class ClutterCell(ManipulationEnv):
    """See the module docstring. ``spec``: the clutter spec the scenes come from."""

    def __init__(self, spec: ClutterSpec, seed: int | None = None, render: bool = False,
                 grip_depth: float | None = None) -> None:
        """``render``: build robosuite's off-screen renderer, for videos from :data:`CELL_CAMERA`; ``grip_depth``: how
        far below a part's top the finger tips go (m; default the rule's ``spec.grasp_depth``)."""
        self.spec = spec
        self.grip_depth = spec.grasp_depth if grip_depth is None else float(grip_depth)
        if self.grip_depth <= 0:
            raise ValueError(f"grip_depth must be > 0 m, got {self.grip_depth}")
        self.slots = [t for t in PART_TYPES for _ in range(spec.max_counts[t])]
        self.active: list[int] = []
        self.camera: SceneCamera | None = None
        self.on_step: Callable[[], None] | None = None  # called after every control step the cell takes
        self._openings: tuple[np.ndarray, np.ndarray] | None = None  # finger_openings(), measured once
        self._yaw = 0.0  # rad: the gripper's turn about the vertical from its home (a grasp's, pick to put)
        super().__init__(
            robots="UR5e",
            gripper_types=GRIPPER,
            controller_configs=load_composite_controller_config(robot="UR5e"),
            initialization_noise=None,
            use_camera_obs=False,
            has_renderer=False,
            has_offscreen_renderer=render,
            control_freq=20,
            horizon=100_000,
            ignore_done=True,
            hard_reset=False,
            seed=seed,
        )
        self.finger_openings()
        self._hold(OBSERVE, grip=-1.0, steps=GRIP_STEPS)
        # how far the finger tips reach below the gripper site, open and straight down (m)
        self._tip_below_site = self.sim.data.site_xpos[self._eef_site][2] - self._lowest_finger_point()
        self.reset()

    # --- model ------------------------------------------------------------------------------------------------

    def _load_model(self) -> None:
        super()._load_model()
        robot = self.robots[0]
        robot.robot_model.set_base_xpos(robot.robot_model.base_xpos_offset["table"](TABLE_SIZE[0]))
        home = np.array(robot.robot_model.init_qpos, dtype=float)
        home[5] += TURN_WRIST
        robot.init_qpos = home
        arena = TableArena(table_full_size=TABLE_SIZE, table_offset=(0, 0, TABLE_TOP))
        arena.set_origin([0, 0, 0])
        # facing the robot across the table, the clutter, tray and put-aside spots in view (videos only)
        arena.worldbody.append(ET.Element("camera", name=CELL_CAMERA, pos="0.95 0 1.55",
                                          xyaxes="0 1 0 -0.6 0 0.8"))
        self.parts = [
            BoxObject(name=f"part{k}", size=[v / 2 for v in self.spec.part_size[t]], rgba=(*BASE_COLOURS[t], 1),
                      density=1200, friction=(1.0, 0.005, 0.0001))
            for k, t in enumerate(self.slots)
        ]
        self.model = ManipulationTask(mujoco_arena=arena, mujoco_robots=[robot.robot_model], mujoco_objects=self.parts)

    def _setup_references(self) -> None:
        super()._setup_references()
        model = self.sim.model
        self._part_bodies = [model.body_name2id(p.root_body) for p in self.parts]
        self._part_geoms = [{model.geom_name2id(g) for g in p.contact_geoms} for p in self.parts]
        self._gripper_geoms = {model.geom_name2id(g) for g in self.robots[0].gripper["right"].contact_geoms}
        self._eef_site = self.robots[0].eef_site_id["right"]
        self._pads = [model.geom_name2id(n) for n in model.geom_names if n and n.endswith("fingerpad_collision")]
        self._base_body = model.body_name2id(self.robots[0].robot_model.root_body)

    def _reset_internal(self) -> None:
        super()._reset_internal()
        for slot in range(len(self.slots)):
            self._set_part(slot, [*self._parked(slot), self.spec.part_size[self.slots[slot]][2] / 2], [1, 0, 0, 0])
        self.sim.forward()
        self._down = self.top_down(self.sim.data.site_xmat[self._eef_site].reshape(3, 3))
        self._yaw = 0.0

    def reward(self, action=None) -> float:
        return 0.0

    # --- scenes -----------------------------------------------------------------------------------------------

    def place_scene(self, scene: ClutterScene, spec: ClutterSpec | None = None) -> None:
        """Reset the robot, put the scene's parts where they settled (the rest parked) and let them rest; ``spec``:
        the one the scene was rendered from, when its part counts differ from the cell's."""
        self.reset()
        self.camera = SceneCamera(spec or self.spec, scene)
        self.active = self.camera.slots
        for slot, obj in zip(self.active, scene.objects, strict=True):
            self._set_part(slot, obj.position, obj.quaternion)
        self.sim.forward()
        self._hold(OBSERVE, grip=-1.0)

    def part_poses(self) -> tuple[np.ndarray, np.ndarray]:
        """Positions (scene frame, m) and quaternions (w, x, y, z) of the placed scene's objects."""
        bodies = [self._part_bodies[s] for s in self.active]
        positions = self.sim.data.body_xpos[bodies] - [0, 0, TABLE_TOP]
        return positions.copy(), self.sim.data.body_xquat[bodies].copy()

    def image(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(rgb, segmentation, depth)`` of the scene's camera at the current part poses."""
        if self.camera is None:
            raise RuntimeError("place_scene first: the camera is the placed scene's")
        return self.camera.render(*self.part_poses())

    def current_scene(self, seed: int) -> tuple[ClutterScene, list[int]]:
        """The scene as the camera sees it now, with the data the rule reads (poses, visible boxes, which part rests
        on which from the contact forces, as :mod:`hrc_lab.env.clutter.scenes` reads them), and the indices (into
        the placed scene's objects) of the parts in it: those the camera sees at all. The scene carries the camera's
        depth image."""
        from hrc_lab.env.clutter.spec import ClutterObject

        image, segmentation, depth = self.image()
        positions, quaternions = self.part_poses()
        shown = [i for i in range(len(self.active)) if (segmentation == i).any()]
        objects, remap = [], np.full(len(self.active) + 1, -1, dtype=np.int8)
        for k, i in enumerate(shown):
            rows, cols = np.nonzero(segmentation == i)
            box = np.array([cols.min(), rows.min(), cols.max() + 1, rows.max() + 1], dtype=np.float32)
            objects.append(ClutterObject(self.object_type(i), positions[i], quaternions[i], box))
            remap[i] = k
        scene = ClutterScene(seed, image, objects, remap[segmentation], self._resting(shown), depth=depth)
        return scene, shown

    def locate(self, box: np.ndarray, depth: np.ndarray) -> np.ndarray:
        """The grasp point (scene frame, m) of a detected box: the box centre's pixel at the median depth of the
        central third of the box (the part's top as the depth camera sees it)."""
        x0, y0, x1, y1 = np.asarray(box, dtype=float)
        return self.spec.unproject(np.array([(x0 + x1) / 2, (y0 + y1) / 2]), box_centre_median(depth, box))

    # --- motion -----------------------------------------------------------------------------------------------

    def grasp_opening(self, box: np.ndarray, depth: np.ndarray) -> float:
        """The pre-grasp half opening (m, grasp point to each pad's inner face) for a detected box: half the part's
        x-extent (the box's width in pixels at the depth of the part's top, :meth:`locate`) plus the rule's
        ``finger_gap`` and :data:`PRESHAPE_MARGIN`."""
        x0, y0, x1, y1 = np.asarray(box, dtype=float)
        top = self.locate(box, depth)
        depth_top = self.spec.camera_height - top[2]
        ends = self.spec.unproject(np.array([[x0, (y0 + y1) / 2], [x1, (y0 + y1) / 2]]), np.full(2, depth_top))
        return float(abs(ends[1, 0] - ends[0, 0]) / 2 + self.spec.finger_gap + PRESHAPE_MARGIN)

    def finger_openings(self) -> tuple[np.ndarray, np.ndarray]:
        """(commands, half openings): the gripper's finger command (-1 open ... 1 closed) and the half distance
        between the pads' inner faces it holds, measured at the observation pose over :data:`OPENING_LEVELS`
        commands when the cell is built (then reset, so every :meth:`place_scene` starts from the same state)."""
        if self._openings is None:
            commands = np.linspace(-1.0, 1.0, OPENING_LEVELS)
            halves = []
            for command in commands:
                self._hold(OBSERVE, grip=-1.0, steps=GRIP_STEPS // 2)
                self._set_finger_command(command)
                self._hold(OBSERVE, grip=0.0, steps=GRIP_STEPS)
                halves.append(self._pad_half_opening())
            self._hold(OBSERVE, grip=-1.0, steps=GRIP_STEPS // 2)
            self._openings = (commands, np.asarray(halves))
        return self._openings

    def grasp_yaw(self, box: np.ndarray, depth: np.ndarray, preshape: bool, order: str) -> Approach:
        """The approach yaw (rad about the vertical, 0 the rule's fingers closing along x) whose finger volumes
        (:data:`FINGER_ZONES`, either side of the grasp point along the closing axis, from the pads' inner faces out)
        the depth image shows clearest of neighbours, the pre-grasp half opening at it (the part's top face's extent
        along the closing axis plus the rule's ``finger_gap`` and :data:`PRESHAPE_MARGIN`; None with ``preshape``
        off: fully open) and the finger tips' height. At each yaw the tips may go down to ``grip_depth`` below the
        part's top, but stop :data:`TIP_CLEARANCE` above the highest point a finger volume holds (a part the named
        one rests on, a neighbour's top); a yaw is clear when that still lets them reach the rule's ``grasp_depth``.
        Of the :data:`YAW_CANDIDATES` yaws, the clear ones win, in ``order`` (:data:`YAW_ORDERS`): ``narrowest``, the
        narrowest opening (so the pads face the part's sides), then the smallest turn; ``smallest_turn``, the
        smallest turn (the rule's yaw whenever it is clear); when none is clear, the one in which the highest
        intrusion is lowest, its tips at the rule's depth."""
        if order not in YAW_ORDERS:
            raise ValueError(f"yaw order must be one of {YAW_ORDERS}, got '{order}'")
        point = self.locate(box, depth)
        deepest = self.tips_for(point)
        rule_tips = max(deepest, float(point[2]) - self.spec.grasp_depth)  # the rule's depth (or grip_depth if less)
        rows, cols = np.indices(depth.shape)
        cloud = self.spec.unproject(np.stack([cols + 0.5, rows + 0.5], axis=-1), depth)
        offsets, heights = cloud[..., :2] - point[:2], cloud[..., 2]
        x0, y0, x1, y1 = np.asarray(box, dtype=float)
        in_box = (cols + 0.5 >= x0) & (cols + 0.5 <= x1) & (rows + 0.5 >= y0) & (rows + 0.5 <= y1)
        top_face = in_box & (heights >= point[2] - TOP_FACE_BAND)
        widest = float(self.finger_openings()[1].max())
        best = None
        for k in range(YAW_CANDIDATES):
            yaw = k * np.pi / YAW_CANDIDATES
            yaw = yaw - np.pi if yaw > np.pi / 2 else yaw  # the shorter turn (the gripper is symmetric)
            axis = np.array([np.cos(yaw), np.sin(yaw)])
            along = np.abs(offsets @ axis)
            across = np.abs(offsets @ [-axis[1], axis[0]])
            half = (float(along[top_face].max()) if top_face.any() else 0.0) + self.spec.finger_gap + PRESHAPE_MARGIN
            if preshape and half > widest:
                continue
            half = half if preshape else widest
            floor = deepest  # the lowest the tips may go at this yaw: clear of what the finger volumes hold
            for reach, rise in FINGER_ZONES:
                zone = (across <= FINGER_HALF_WIDTH) & (along >= half) & (along <= half + reach)
                if zone.any():
                    floor = max(floor, float(heights[zone].max()) - rise + TIP_CLEARANCE)
            intrusion = floor - rule_tips  # > 0: not clear even at the rule's depth
            narrowness = round(half / NARROWEST_BIN) if order == "narrowest" else 0
            key = (max(intrusion, 0.0), narrowness, abs(yaw))
            if best is None or key < best[0]:
                best = (key, Approach(yaw, half if preshape else None, min(floor, rule_tips)))
        if best is None:  # the part is wider than the gripper opens at every yaw
            return Approach(0.0, None, deepest)
        return best[1]

    def approach(self, box: np.ndarray, depth: np.ndarray, preshape: bool, choose_yaw: bool, order: str) -> Approach:
        """How to come down on a detected box: :meth:`grasp_yaw` with ``choose_yaw`` (the clear yaws ranked by
        ``order``), else the rule's yaw with the pre-grasp opening (:meth:`grasp_opening`, or fully open without
        ``preshape``) and the tips ``grip_depth`` below the part's top."""
        if choose_yaw:
            return self.grasp_yaw(box, depth, preshape, order)
        return Approach(0.0, self.grasp_opening(box, depth) if preshape else None,
                        self.tips_for(self.locate(box, depth)))

    def pick(self, point: np.ndarray, half_opening: float | None = None, yaw: float = 0.0,
             tips: float | None = None) -> PickOutcome:
        """Open (fully, or with ``half_opening`` to the command whose measured half opening is the smallest at least
        that wide, :meth:`finger_openings`), turn the gripper ``yaw`` (rad about the vertical) from its home, come
        down on ``point`` (scene frame, the part's top) from above until the finger tips are at height ``tips``
        (default ``grip_depth`` below the point, :meth:`grasp_yaw` gives one per yaw), close, lift; from the
        observation pose and back to it with the part (the gripper turns home when :meth:`put` has let go)."""
        self._yaw = float(yaw)
        open_grip = -1.0
        if half_opening is not None:
            commands, halves = self.finger_openings()
            wide_enough = commands[halves >= half_opening]
            if len(wide_enough):
                self._set_finger_command(float(wide_enough.max()))
                open_grip = 0.0  # hold the command
        start = self.timestep
        point = np.asarray(point, dtype=float)
        before = self.part_poses()[0][:, 2]
        touched: set[int] = set()
        grasp = np.array([*point[:2], (self.tips_for(point) if tips is None else tips) + self._tip_below_site])
        self._hold(grasp + [0, 0, APPROACH], grip=open_grip)
        self._hold(grasp, grip=open_grip, touched=touched)
        self._hold(grasp, grip=1.0, steps=GRIP_STEPS, touched=touched)
        self._hold(np.array([*point[:2], LIFT]), grip=1.0)
        rose = self.part_poses()[0][:, 2] - before
        held = int(np.argmax(rose)) if rose.max() > LIFTED else None
        return PickOutcome(held, sorted(touched - {held}), self.timestep - start)

    def put(self, xy: np.ndarray, held: int) -> None:
        """Set the held object down with its centre at ``xy`` (scene frame), open, and go to the observation pose."""
        grip_to_part = self.sim.data.site_xpos[self._eef_site] - TABLE_TOP * np.eye(3)[2] - self.part_poses()[0][held]
        bottom = self.spec.part_size[self.object_type(held)][2] / 2 + RELEASE_CLEARANCE
        self._hold(np.array([*xy, LIFT]) + [*grip_to_part[:2], 0], grip=1.0)
        self._hold(np.array([*xy, bottom]) + grip_to_part, grip=1.0)
        self._hold(np.array([*xy, bottom]) + grip_to_part, grip=-1.0, steps=GRIP_STEPS)
        self._hold(np.array([*xy, LIFT]) + [*grip_to_part[:2], 0], grip=-1.0)
        self._yaw = 0.0
        self._hold(OBSERVE, grip=-1.0)

    @staticmethod
    def top_down(home: np.ndarray) -> np.ndarray:
        """The gripper orientation (rotation matrix) straight down nearest to ``home``: each axis of the home pose
        snapped to the world axis it is closest to. robosuite's UR5e home holds the gripper tilted 2.6 degrees and
        turned 2.8 degrees, so the 2F-140's pads stood 6 mm apart in height and closed off the world x axis."""
        snapped = np.zeros((3, 3))
        for column in range(3):
            row = int(np.argmax(np.abs(home[:, column])))
            snapped[row, column] = np.sign(home[row, column])
        return snapped

    def tips_for(self, point: np.ndarray) -> float:
        """The finger tips' height for a grasp at ``point`` (the part's top): ``grip_depth`` below it, no lower
        than :data:`TIP_CLEARANCE`."""
        return max(float(point[2]) - self.grip_depth, TIP_CLEARANCE)

    def object_type(self, index: int) -> str:
        """The part type of the placed scene's object ``index``."""
        return self.slots[self.active[index]]

    def _hold(self, target: np.ndarray, grip: float, steps: int | None = None, touched: set[int] | None = None) -> None:
        """Drive the gripper site to ``target`` (scene frame) until within tolerance, turned as :meth:`pick` set it
        (or for exactly ``steps`` control steps), fingers commanded ``grip`` (-1 open, 1 closed); contacts of the
        gripper with the placed objects go into ``touched``."""
        goal = np.asarray(target, dtype=float) + [0, 0, TABLE_TOP]
        base = self.sim.data.body_xmat[self._base_body].reshape(3, 3)
        for _ in range(steps or MAX_WAYPOINT_STEPS):
            error = goal - self.sim.data.site_xpos[self._eef_site]
            turn = self._orientation_error()
            if steps is None and np.linalg.norm(error) < WAYPOINT_TOLERANCE and np.linalg.norm(
                    turn) < ORIENTATION_TOLERANCE:
                return
            action = np.zeros(7)
            action[:3] = np.clip(GAIN * base.T @ error, -1, 1)
            action[3:6] = np.clip(ORIENTATION_GAIN * base.T @ turn, -1, 1)
            action[6] = grip
            self.step(action)
            if self.on_step is not None:
                self.on_step()
            if touched is not None:
                touched.update(self._gripper_contacts())

    def _set_finger_command(self, command: float) -> None:
        """Set the gripper's finger command (robosuite's Robotiq140Gripper keeps it in ``current_action`` and moves it
        by 0.2 per step towards the sign of the grip action; a grip action of 0 holds it)."""
        self.robots[0].gripper["right"].current_action = np.array([command, -command])

    def _pad_half_opening(self) -> float:
        """Half the distance between the inner faces of the two finger pads, m."""
        model, data = self.sim.model, self.sim.data
        centres = [data.geom_xpos[g] for g in self._pads]
        thickness = [float(np.min(model.geom_size[g])) for g in self._pads]  # the pads are thin boxes
        return float(np.linalg.norm(centres[0][:2] - centres[1][:2]) / 2 - np.mean(thickness))

    def _orientation_error(self) -> np.ndarray:
        """Axis-angle (world frame) that turns the gripper's current orientation into its home one turned by the
        grasp's yaw about the vertical."""
        current = mat2quat(self.sim.data.site_xmat[self._eef_site].reshape(3, 3))
        c, s = np.cos(self._yaw), np.sin(self._yaw)
        goal = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ self._down
        turn = quat_multiply(mat2quat(goal), quat_inverse(current))  # (x, y, z, w)
        return quat2axisangle(turn if turn[3] >= 0 else -turn)  # the shorter way round

    def _resting(self, shown: list[int]) -> np.ndarray:
        """resting[i][j]: part j lies on part i (force-weighted mean contact normal within 45 degrees of vertical)."""
        import mujoco

        from hrc_lab.env.clutter.scenes import MIN_SUPPORT_FORCE, VERTICAL_NORMAL

        model, data = self.sim.model._model, self.sim.data._data
        index = {g: k for k, i in enumerate(shown) for g in self._part_geoms[self.active[i]]}
        push, force = np.zeros((len(shown), len(shown), 3)), np.zeros(6)
        for c in range(data.ncon):
            contact = data.contact[c]
            i, j = index.get(contact.geom1), index.get(contact.geom2)
            if i is None or j is None or i == j:
                continue
            mujoco.mj_contactForce(model, data, c, force)
            normal = contact.frame[:3] * force[0]
            push[i, j] += normal
            push[j, i] -= normal
        norm = np.linalg.norm(push, axis=-1)
        return (norm > MIN_SUPPORT_FORCE) & (push[..., 2] > VERTICAL_NORMAL * norm)

    def _lowest_finger_point(self) -> float:
        """The world height of the lowest corner of the gripper's finger geoms now."""
        model, data = self.sim.model, self.sim.data
        signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
        lowest = np.inf
        for geom in self._gripper_geoms:
            if "finger" not in (model.geom_id2name(geom) or ""):
                continue
            corners = data.geom_xpos[geom] + (signs * model.geom_size[geom]) @ data.geom_xmat[geom].reshape(3, 3).T
            lowest = min(lowest, float(corners[:, 2].min()))
        return lowest

    def _gripper_contacts(self) -> set[int]:
        """The placed objects the gripper touches now."""
        data, found = self.sim.data, set()
        owner = {g: i for i, slot in enumerate(self.active) for g in self._part_geoms[slot]}
        for contact in data.contact[: data.ncon]:
            for mine, other in ((contact.geom1, contact.geom2), (contact.geom2, contact.geom1)):
                if mine in self._gripper_geoms and other in owner:
                    found.add(owner[other])
        return found

    def _parked(self, slot: int) -> np.ndarray:
        return PARK + [0.1 * slot, 0]

    def _set_part(self, slot: int, position, quaternion) -> None:
        self.sim.data.set_joint_qpos(self.parts[slot].joints[0],
                                     np.concatenate([np.asarray(position, dtype=float) + [0, 0, TABLE_TOP],
                                                     quaternion]))
        self.sim.data.set_joint_qvel(self.parts[slot].joints[0], np.zeros(6))
