"""Cluttered scenes of Ch.6 (Sec. 6.3) in pure MuJoCo: drop parts a, b, c on a table, let them settle, render.

One MJCF model (built once per part sizes, counts, camera and image size, with its renderer) holds a textured
table, a key light, a top-down camera (``spec.fovy``: the spawn area plus a margin fills the image) and one free
box per part the spec allows (``max_counts``: a a a b b c). A scene draws from its seed:

- the number of parts, uniform in [min_objects, max_objects], and the counts per type, uniform over the count
  vectors with that total that ``max_counts`` allows (every combination can occur);
- per part a position uniform within +-``spawn_half_width``, a uniform yaw, and roll and pitch uniform within
  +-``max_drop_tilt_deg``; the parts are dropped one at a time, in random order, each with its lowest corner
  ``drop_spacing`` above the highest corner of the pile so far, and the next one falls once it has landed;
- a colour per part (a orange, b blue, c green, each shaded and jittered a little so colour alone is not a perfect
  cue) and the key light's position and strength.

Unused parts wait off camera. After the last drop the physics runs until every part is still; the scene is
redrawn, deterministically from ``(seed, attempt)`` (the part counts are kept), when a part did not come to rest
within :data:`MAX_SETTLE_TIME`, is not entirely in the camera's view, stands on an end (its long axis steeper than
:data:`MAX_END_TILT_DEG`) or shows fewer than ``min_visible_fraction`` of its smallest face's pixels (never zero).
The RGB image and the segmentation (part index or -1) come from the off-screen ``mujoco.Renderer``
(``MUJOCO_GL=egl`` unless set; OSMesa when EGL fails). A part's box is the extent of its visible pixels,
``(x0, y0, x1, y1)`` with x1, y1 exclusive. ``resting[i][j]`` (part j lies on part i) is read from the settled
contacts between the two parts: their force-weighted mean normal is within 45 degrees of vertical, j above.

:func:`save_scenes` / :func:`load_scenes` keep a data set in one compressed ``.npz``. The same seed gives the same
scene and image (on one machine and MuJoCo build). :data:`REDRAWN` counts why scenes were redrawn (diagnostics).
"""

from __future__ import annotations

import atexit
import collections
import itertools
import json
import os
import sys
from dataclasses import asdict
from pathlib import Path

import numpy as np
from tqdm import tqdm

from hrc_lab.data.files import DataFileError, read_npz
from hrc_lab.env.clutter.rule import part_corners, rotation_matrix
from hrc_lab.env.clutter.spec import PART_TYPES, ClutterObject, ClutterScene, ClutterSpec

TIMESTEP = 0.004  # s per physics step
CHECK_EVERY = 10  # steps between two stillness checks (0.04 s)
LAND_TIME = 1.0  # s at most between two drops
LAND_LINEAR, LAND_ANGULAR = 2e-2, 2e-1  # m/s and rad/s: a dropped part has landed, the next one falls
MAX_SETTLE_TIME = 4.0  # s after the last drop before a scene that is still moving is redrawn
STILL_LINEAR, STILL_ANGULAR = 5e-3, 5e-2  # m/s and rad/s: below both, a part is still
MAX_END_TILT_DEG = 45.0  # a part whose long axis (not its z) is steeper than this stands on its end: redraw
VERTICAL_NORMAL = np.cos(np.radians(45))  # a mean contact normal this close to vertical means "lies on"
MIN_SUPPORT_FORCE = 1e-3  # N: weaker contacts between two parts are mere touches (an a weighs 0.16 N)
MAX_ATTEMPTS = 100
PARK_X = 1.0  # unused parts wait on the table at x >= this, far outside the camera's view

BASE_COLOURS = {"a": (0.86, 0.55, 0.22), "b": (0.26, 0.44, 0.74), "c": (0.32, 0.64, 0.34)}
SHADE_RANGE = (0.8, 1.1)  # per-part brightness factor
CHANNEL_JITTER = 0.05  # per-part, per-channel colour offset
LIGHT_SHIFT = 0.25  # m: the key light moves within +-this (x and y) 1.2 m above the table
LIGHT_RANGE = (0.45, 0.75)  # its diffuse strength

SCENE_ARRAYS = ("seeds", "images", "segmentations", "n_objects", "resting", "object_type", "object_position",
                "object_quaternion", "object_box", "spec")  # what save_scenes writes (object_scene: unread)
SCENE_FORMAT = 2  # in the scene caches' keys: 2 = with depth images (1: without)
SCENE_DEPTHS = "depths"  # written when every scene has a depth image, as float16 (0.25 mm steps at 0.55 m)

REDRAWN: collections.Counter = collections.Counter()  # reason -> scenes redrawn in this process


def generate_scene(spec: ClutterSpec, seed: int) -> ClutterScene:
    """The settled, rendered scene of ``seed`` (redrawn from ``(seed, attempt)`` until it passes the checks)."""
    if seed < 0:
        raise ValueError(f"seed must be >= 0, got {seed}")
    cell = _cell(spec)
    counts = _counts(spec, np.random.default_rng(seed))  # drawn once: redrawing does not bias the numbers of parts
    for attempt in range(MAX_ATTEMPTS):
        scene = cell.attempt(spec, seed, counts, np.random.default_rng([seed, attempt]))
        if scene is not None:
            return scene
    raise RuntimeError(f"no valid clutter scene for seed {seed} in {MAX_ATTEMPTS} attempts; check the env.* sizes")


def generate_scenes(spec: ClutterSpec, seeds, progress: bool = True) -> list[ClutterScene]:
    """:func:`generate_scene` for every seed, with a progress bar."""
    seeds = [int(s) for s in seeds]
    return [generate_scene(spec, s) for s in tqdm(seeds, desc="clutter scenes", unit="scene", disable=not progress)]


def save_scenes(path: str | Path, scenes: list[ClutterScene], spec: ClutterSpec | None = None) -> Path:
    """Write ``scenes`` (and optionally the spec they came from) to one compressed ``.npz``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    counts = np.array([len(s.objects) for s in scenes], dtype=np.int64)
    width = int(counts.max(initial=0))
    resting = np.zeros((len(scenes), width, width), dtype=bool)
    for k, scene in enumerate(scenes):
        n = len(scene.objects)
        if n:
            resting[k, :n, :n] = np.asarray(scene.resting, dtype=bool).reshape(n, n)
    objects = [o for s in scenes for o in s.objects]
    depths = {SCENE_DEPTHS: np.stack([s.depth for s in scenes]).astype(np.float16)} if scenes and all(
        s.depth is not None for s in scenes) else {}
    np.savez_compressed(
        path,
        seeds=np.array([s.seed for s in scenes], dtype=np.int64),
        images=np.stack([s.image for s in scenes]).astype(np.uint8),
        segmentations=np.stack([s.segmentation for s in scenes]).astype(np.int8),
        n_objects=counts,
        resting=resting,
        object_scene=np.repeat(np.arange(len(scenes)), counts),
        object_type=np.array([PART_TYPES.index(o.type) for o in objects], dtype=np.int64),
        object_position=np.array([o.position for o in objects], dtype=np.float64).reshape(-1, 3),
        object_quaternion=np.array([o.quaternion for o in objects], dtype=np.float64).reshape(-1, 4),
        object_box=np.array([o.box for o in objects], dtype=np.float32).reshape(-1, 4),
        spec=np.array(json.dumps(asdict(spec), sort_keys=True) if spec is not None else ""),
        **depths,
    )
    return path


def load_scenes(path: str | Path, spec: ClutterSpec | None = None) -> list[ClutterScene]:
    """The scenes of a :func:`save_scenes` file; :class:`DataFileError` when it is missing, unreadable, lacks an
    array or (with ``spec``) was saved with another spec."""
    arrays = read_npz(path, SCENE_ARRAYS)
    try:
        saved = json.loads(str(arrays["spec"]) or "{}")
    except ValueError as err:
        raise DataFileError(f"{path}: its 'spec' array is not the JSON of an env spec") from err
    if spec is not None and saved:
        differ = sorted(k for k, v in asdict(spec).items() if json.loads(json.dumps(v)) != saved.get(k))
        if differ:
            raise DataFileError(f"{path}: holds scenes of another env spec (env.{', env.'.join(differ)} differ)")
    scenes, start = [], 0
    for k, n in enumerate(arrays["n_objects"]):
        n = int(n)
        objects = [
            ClutterObject(
                type=PART_TYPES[int(arrays["object_type"][m])],
                position=arrays["object_position"][m].copy(),
                quaternion=arrays["object_quaternion"][m].copy(),
                box=arrays["object_box"][m].copy(),
            )
            for m in range(start, start + n)
        ]
        scenes.append(
            ClutterScene(
                seed=int(arrays["seeds"][k]),
                image=arrays["images"][k],
                objects=objects,
                segmentation=arrays["segmentations"][k],
                resting=arrays["resting"][k, :n, :n].copy(),
                depth=arrays[SCENE_DEPTHS][k].astype(np.float32) if SCENE_DEPTHS in arrays else None,
            )
        )
        start += n
    return scenes


# --------------------------------------------------------------------------------------------------------------------


def import_mujoco():
    """``import mujoco`` with MUJOCO_GL=egl unless set; if EGL cannot be loaded, retry with OSMesa."""
    if "mujoco" in sys.modules:
        return sys.modules["mujoco"]
    defaulted = "MUJOCO_GL" not in os.environ
    os.environ.setdefault("MUJOCO_GL", "egl")
    try:
        import mujoco
    except (ImportError, AttributeError, OSError):
        if not defaulted:
            raise
        for name in [m for m in sys.modules if m.split(".")[0] in ("mujoco", "OpenGL")]:
            del sys.modules[name]
        os.environ["MUJOCO_GL"] = "osmesa"
        os.environ["PYOPENGL_PLATFORM"] = "osmesa"
        import mujoco
    return mujoco


def _renderer(mujoco, model, size: int):
    """An off-screen renderer; OSMesa when an EGL context cannot be made."""
    try:
        return mujoco.Renderer(model, size, size)
    except Exception:
        if os.environ.get("MUJOCO_GL") != "egl":
            raise
        from mujoco.osmesa import GLContext
        from mujoco.rendering.classic import gl_context

        gl_context.GLContext = GLContext
        os.environ["MUJOCO_GL"] = "osmesa"
        return mujoco.Renderer(model, size, size)


def _mjcf(spec: ClutterSpec, slots: list[str]) -> str:
    size = spec.image_size
    table = 1.5 * spec.view_half_width
    parts = []
    for k, part_type in enumerate(slots):
        half = " ".join(f"{v / 2:.6g}" for v in spec.part_size[part_type])
        parts.append(
            f'<body name="part{k}" pos="{PARK_X + 0.2 * k} 0 0.5"><joint name="part{k}" type="free"/>'
            f'<geom name="part{k}" type="box" size="{half}" density="1200" rgba="0.5 0.5 0.5 1"/></body>'
        )
    return f"""<mujoco model="clutter">
  <option timestep="{TIMESTEP}" integrator="implicitfast"/>
  <visual>
    <global offwidth="{size}" offheight="{size}"/>
    <quality shadowsize="1024"/>
    <headlight ambient="0.3 0.3 0.3" diffuse="0.25 0.25 0.25" specular="0 0 0"/>
  </visual>
  <asset>
    <texture name="table" type="2d" builtin="flat" rgb1="0.62 0.61 0.58" mark="random" random="0.06"
             markrgb="0.5 0.5 0.48" width="512" height="512"/>
    <material name="table" texture="table" texrepeat="2 2" specular="0.1" shininess="0.1"/>
  </asset>
  <default><geom friction="1 0.005 0.0001"/></default>
  <worldbody>
    <light name="key" pos="0.1 -0.1 1.2" dir="0 0 -1" diffuse="0.6 0.6 0.6" specular="0.1 0.1 0.1"
           castshadow="true" cutoff="60"/>
    <geom name="table" type="plane" size="{table:.4f} {table:.4f} 0.01" material="table"/>
    <camera name="top" pos="0 0 {spec.camera_height}" xyaxes="1 0 0 0 1 0" fovy="{spec.fovy:.6f}"/>
    {chr(10).join("    " + p for p in parts).strip()}
  </worldbody>
</mujoco>"""


def _quaternion(yaw: float, pitch: float, roll: float) -> np.ndarray:
    """(w, x, y, z) of R = Rz(yaw) Ry(pitch) Rx(roll)."""
    cy, sy, cp, sp, cr, sr = (f(a / 2) for a in (yaw, pitch, roll) for f in (np.cos, np.sin))
    return np.array(
        [
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ]
    )


class _Cell:
    """The MuJoCo model, data and renderer of one MJCF (parts, sizes, camera, image size), reused scene after scene."""

    def __init__(self, xml: str, slots: list[str], part_size: dict[str, list[float]], image_size: int) -> None:
        self.mj = mj = import_mujoco()
        self.slots = slots  # part type per free body
        self.model = mj.MjModel.from_xml_string(xml)
        self.data = mj.MjData(self.model)
        self.renderer = _renderer(mj, self.model, image_size)
        names = [f"part{k}" for k in range(len(self.slots))]
        self.bodies = [mj.mj_name2id(self.model, mj.mjtObj.mjOBJ_BODY, n) for n in names]
        self.geoms = [mj.mj_name2id(self.model, mj.mjtObj.mjOBJ_GEOM, n) for n in names]
        joints = [mj.mj_name2id(self.model, mj.mjtObj.mjOBJ_JOINT, n) for n in names]
        self.qpos = [int(self.model.jnt_qposadr[j]) for j in joints]
        self.dofs = [int(self.model.jnt_dofadr[j]) for j in joints]
        self.half = [np.asarray(part_size[t], dtype=float) / 2 for t in slots]

    def attempt(
        self, spec: ClutterSpec, seed: int, counts: dict[str, int], rng: np.random.Generator
    ) -> ClutterScene | None:
        """Drop, settle and render the parts of ``counts``; None (and a count in :data:`REDRAWN`) when the scene
        fails a check."""
        mj, model, data = self.mj, self.model, self.data
        active = self.active(counts)
        n = len(active)
        xy = rng.uniform(-spec.spawn_half_width, spec.spawn_half_width, size=(n, 2))
        yaw = rng.uniform(0, 2 * np.pi, size=n)
        tilt = np.radians(spec.max_drop_tilt_deg) * rng.uniform(-1, 1, size=(n, 2))
        order = rng.permutation(n)
        shade = rng.uniform(*SHADE_RANGE, size=n)
        jitter = rng.uniform(-CHANNEL_JITTER, CHANNEL_JITTER, size=(n, 3))
        light = np.array([*rng.uniform(-LIGHT_SHIFT, LIGHT_SHIFT, size=2), 1.2])
        model.light_pos[0] = light
        model.light_dir[0] = -light / np.linalg.norm(light)  # aimed at the table centre
        model.light_diffuse[0] = rng.uniform(*LIGHT_RANGE)

        mj.mj_resetData(model, data)
        for slot in range(len(self.slots)):  # every part waits off camera until it is dropped
            self._set_pose(slot, [PARK_X + 0.2 * slot, 0, self.half[slot][2]], [1, 0, 0, 0])
        mj.mj_forward(model, data)
        dropped: list[int] = []
        for m in order:
            slot = active[m]
            quaternion = _quaternion(yaw[m], tilt[m, 0], tilt[m, 1])
            top = max((self._top(s) for s in dropped), default=0.0)
            height = top + spec.drop_spacing + np.abs(rotation_matrix(quaternion)[2]) @ self.half[slot]
            self._set_pose(slot, [xy[m, 0], xy[m, 1], height], quaternion)
            colour = np.clip(np.array(BASE_COLOURS[self.slots[slot]]) * shade[m] + jitter[m], 0, 1)
            model.geom_rgba[self.geoms[slot]] = [*colour, 1.0]
            mj.mj_forward(model, data)
            dropped.append(slot)
            self._settle([slot], np.sqrt(2 * height / 9.81), LAND_TIME, LAND_LINEAR, LAND_ANGULAR)
        if not self._settle(active, 0.0, MAX_SETTLE_TIME, STILL_LINEAR, STILL_ANGULAR):
            return _redraw("not settled")

        objects = [
            ClutterObject(
                type=self.slots[slot],
                position=data.xpos[self.bodies[slot]].copy(),
                quaternion=data.xquat[self.bodies[slot]].copy(),
                box=np.zeros(4, dtype=np.float32),
            )
            for slot in active
        ]
        for obj in objects:
            pixels = spec.project(part_corners(spec, obj))
            if pixels.min() < 0 or pixels.max() > spec.image_size:
                return _redraw("out of view")
            size = np.asarray(spec.part_size[obj.type])
            longest = int(np.argmax(size))
            steep = abs(rotation_matrix(obj.quaternion)[2, longest]) > np.sin(np.radians(MAX_END_TILT_DEG))
            if size[longest] > size[2] and steep:
                return _redraw("on its end")
        image, segmentation, depth = self._render(active)
        pixels_per_m = spec.image_size / 2 / spec.view_half_width
        for i, obj in enumerate(objects):
            rows, cols = np.nonzero(segmentation == i)
            smallest_face = np.prod(np.sort(spec.part_size[obj.type])[:2]) * pixels_per_m**2
            if len(rows) == 0 or len(rows) < spec.min_visible_fraction * smallest_face:
                return _redraw("hidden")
            obj.box = np.array([cols.min(), rows.min(), cols.max() + 1, rows.max() + 1], dtype=np.float32)
        return ClutterScene(seed, image, objects, segmentation, resting=self._resting(active), depth=depth)

    def active(self, counts: dict[str, int]) -> list[int]:
        """The free bodies a scene of ``counts`` uses, in the order of its objects (by type, then slot)."""
        return [k for t in PART_TYPES for k in [s for s, u in enumerate(self.slots) if u == t][: counts[t]]]

    def _top(self, slot: int) -> float:
        """Height of a part's highest corner, m."""
        geom = self.geoms[slot]
        vertical = np.abs(self.data.geom_xmat[geom].reshape(3, 3)[2])  # |z components| of the part's axes
        return float(self.data.geom_xpos[geom][2] + vertical @ self.half[slot])

    def _set_pose(self, slot: int, position, quaternion) -> None:
        adr, dof = self.qpos[slot], self.dofs[slot]
        self.data.qpos[adr : adr + 7] = [*position, *quaternion]
        self.data.qvel[dof : dof + 6] = 0

    def _settle(self, slots: list[int], fall_time: float, duration: float, linear: float, angular: float) -> bool:
        """Step (at least ``fall_time``, at most ``duration`` s) until the parts in ``slots`` move slower than
        ``linear`` m/s and ``angular`` rad/s; False if they never do."""
        mj, model, data = self.mj, self.model, self.data
        start = data.time
        while data.time - start < duration:
            mj.mj_step(model, data, nstep=CHECK_EVERY)
            if data.time - start < fall_time:
                continue
            velocity = np.array([data.qvel[self.dofs[s] : self.dofs[s] + 6] for s in slots])
            if np.abs(velocity[:, :3]).max() < linear and np.abs(velocity[:, 3:]).max() < angular:
                return True
        return False

    def _resting(self, active: list[int]) -> np.ndarray:
        """resting[i][j]: the force-weighted mean contact normal from part i to part j points up (within 45 deg)."""
        mj, model, data = self.mj, self.model, self.data
        index = {self.geoms[slot]: i for i, slot in enumerate(active)}
        push = np.zeros((len(active), len(active), 3))  # sum over contacts of normal force * normal from i to j
        force = np.zeros(6)
        for k in range(data.ncon):
            contact = data.contact[k]
            i, j = index.get(contact.geom1), index.get(contact.geom2)
            if i is None or j is None:
                continue
            mj.mj_contactForce(model, data, k, force)
            normal = contact.frame[:3] * force[0]  # frame[:3] is the normal, from geom1 to geom2
            push[i, j] += normal
            push[j, i] -= normal
        norm = np.linalg.norm(push, axis=-1)
        return (norm > MIN_SUPPORT_FORCE) & (push[..., 2] > VERTICAL_NORMAL * norm)

    def _render(self, active: list[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(image, segmentation, depth)`` of the top camera: RGB, object index per pixel (-1: none), metres along
        the optical axis."""
        renderer = self.renderer
        renderer.update_scene(self.data, camera="top")
        image = renderer.render().copy()
        renderer.enable_segmentation_rendering()
        try:
            ids = renderer.render()
        finally:
            renderer.disable_segmentation_rendering()
        segmentation = np.full(ids.shape[:2], -1, dtype=np.int8)
        is_geom = ids[..., 1] == int(self.mj.mjtObj.mjOBJ_GEOM)
        for i, slot in enumerate(active):
            segmentation[is_geom & (ids[..., 0] == self.geoms[slot])] = i
        renderer.enable_depth_rendering()
        try:
            depth = renderer.render().copy()
        finally:
            renderer.disable_depth_rendering()
        return image, segmentation, depth


class SceneCamera:
    """The top-down camera of one scene whose parts then move (the robot cell of Algorithm 4): it renders the RGB
    image, the segmentation (object index or -1) and the depth (m along the optical axis) of the scene's parts at
    the poses it is given, exactly as the scene's own image was rendered: same model, camera, part colours and key
    light, re-derived by regenerating the scene from its seed (checked against the scene's image)."""

    def __init__(self, spec: ClutterSpec, scene: ClutterScene) -> None:
        regenerated = generate_scene(spec, scene.seed)
        if not np.array_equal(regenerated.image, scene.image):
            raise ValueError(f"scene {scene.seed}: regenerating it gives another image (another MuJoCo build or "
                             "spec?); its camera cannot be rebuilt")
        self.spec = spec
        self.cell = cell = _cell(spec)
        self.slots = cell.active(collections.Counter(scene.types))
        self.rgba = cell.model.geom_rgba.copy()
        self.light = (cell.model.light_pos.copy(), cell.model.light_dir.copy(), cell.model.light_diffuse.copy())

    def render(self, positions: np.ndarray, quaternions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(image, segmentation, depth)`` with object i at ``positions[i]`` (m, the scene's frame) and
        ``quaternions[i]`` (w, x, y, z); a part moved out of the view is simply not seen."""
        cell, mj = self.cell, self.cell.mj
        model, data = cell.model, cell.data
        model.geom_rgba[:] = self.rgba
        model.light_pos[:], model.light_dir[:], model.light_diffuse[:] = self.light
        for slot in range(len(cell.slots)):
            cell._set_pose(slot, [PARK_X + 0.2 * slot, 0, cell.half[slot][2]], [1, 0, 0, 0])
        for slot, position, quaternion in zip(self.slots, positions, quaternions, strict=True):
            cell._set_pose(slot, position, quaternion)
        mj.mj_forward(model, data)
        return cell._render(self.slots)


def _counts(spec: ClutterSpec, rng: np.random.Generator) -> dict[str, int]:
    """Parts per type: the total uniform in [min_objects, max_objects], then uniform over the allowed counts."""
    total = int(rng.integers(spec.min_objects, spec.max_objects + 1))
    ranges = [range(spec.max_counts[t] + 1) for t in PART_TYPES]
    options = [c for c in itertools.product(*ranges) if sum(c) == total]
    return dict(zip(PART_TYPES, options[int(rng.integers(len(options)))]))


def _redraw(reason: str) -> None:
    REDRAWN[reason] += 1
    return None


_CELLS: dict[str, _Cell] = {}


def _cell(spec: ClutterSpec) -> _Cell:
    """The cell of the spec's MJCF (specs that differ only in counts, drops or gripper share one renderer)."""
    slots = [t for t in PART_TYPES for _ in range(spec.max_counts[t])]
    key = _mjcf(spec, slots)
    if key not in _CELLS:
        _CELLS[key] = _Cell(key, slots, spec.part_size, spec.image_size)
    # the last exit handler registered, so it runs before every eglTerminate registered so far (MuJoCo's, and
    # robosuite's once a robot cell renders videos in this process)
    atexit.unregister(_close_renderers)
    atexit.register(_close_renderers)
    return _CELLS[key]


def _close_renderers() -> None:
    """Free the GL contexts while the display is still up (else ``Renderer.__del__`` complains at exit). When an exit
    handler registered later (a robot cell's renderer, a video recorder) terminated the display first, the contexts
    went with it: the renderers then drop their handles, so their ``__del__`` does not free them again."""
    for cell in _CELLS.values():
        try:
            cell.renderer.close()
        except Exception:  # EGL_NOT_INITIALIZED: the display is gone, and every context on it
            if cell.renderer._gl_context is not None:
                cell.renderer._gl_context._context = None
            cell.renderer._gl_context = cell.renderer._mjr_context = None
    _CELLS.clear()
