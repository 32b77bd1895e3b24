"""The expert rule of Ch.6 (Sec. 6.3): which part of a cluttered scene the robot can grasp, and what to move first.

The thesis' labels come from a human expert who knows the robot: it grasps only from the top, with a fixed
gripper orientation (the two fingers close along the world x axis; part orientations are not used). This module
is the one place that rule is written down; every label the Ch.6 models learn from is computed here.

- **Fingers.** To grasp part i, each finger is a box ``finger_thickness`` long along x and ``finger_width`` wide
  along y, centred on i's centre y, placed ``finger_gap`` outside the x-extent of i's footprint (the extent of its
  eight corners) on either side; it comes down from above and reaches ``grasp_depth`` below i's top (its highest
  corner). Part j obstructs a finger when j's oriented box intersects the finger box (a separating-axis test).
- **Blockers.** blockers(i) = the parts resting directly on i (``scene.resting[i][j]``, from the settled contacts)
  plus the parts obstructing a finger. Part i is *graspable* iff it has no blocker.
- **Solution** of part i (the words the decoder learns, Eq. 6.7): ``grasp`` if graspable; ``help`` if any blocker
  has i's own type (two parts of one type too close to separate: the robot cannot free i by moving another type,
  it asks the human co-worker); else ``move t1`` or ``move t1 and t2``, the distinct blocker types sorted.
- **Iteration** (Algorithm 4 with the rule as oracle, :func:`iterative_solution`): from the requested part, the
  next request is the blocker of the named types nearest to the current part (image-plane box-centre distance,
  :func:`resolve_request`), until a part is graspable or the answer is help. A part requested twice (a cycle:
  parts blocking each other) ends the chain with help.

Pure numpy: no simulator import, so hand-built scenes can be labelled in tests.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from hrc_lab.env.clutter.spec import ClutterObject, ClutterScene, ClutterSpec
from hrc_lab.vocabulary import END, PAD, START

GRASP, HELP, MOVE, AND = "grasp", "help", "move", "and"
FINGER_REACH = 1.0  # m above the part's top: the finger (and the gripper above it) comes from far above
OVERLAP_TOLERANCE = 1e-6  # m: boxes that merely touch do not intersect


def solution_words(classes: Iterable[str]) -> tuple[str, ...]:
    """Every word of a solution over objects of ``classes`` (our part types, or a data set's classes), with the
    decoders' control tokens."""
    return (PAD, START, END, GRASP, HELP, MOVE, AND, *classes)


def longest_solution(classes: Iterable[str]) -> int:
    """Words of the longest solution: "move t1 and t2 ..." naming every class but the blocked object's own."""
    return max(1, 2 * (len(tuple(classes)) - 1))


def move_tokens(kinds: Iterable[str]) -> list[str]:
    """``["move", t1, "and", t2, ...]`` for the distinct ``kinds`` in sorted order (a class may contain spaces: one
    token each)."""
    tokens = [MOVE]
    for k, kind in enumerate(sorted(set(kinds))):
        tokens += [kind] if k == 0 else [AND, kind]
    return tokens


def rotation_matrix(quaternion: np.ndarray) -> np.ndarray:
    """(3, 3) rotation of a unit quaternion (w, x, y, z); columns are the part's axes in the world frame."""
    w, x, y, z = np.asarray(quaternion, dtype=float) / np.linalg.norm(quaternion)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def part_corners(spec: ClutterSpec, obj: ClutterObject) -> np.ndarray:
    """(8, 3) world corners of a part's box."""
    half = np.asarray(spec.part_size[obj.type], dtype=float) / 2
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
    return np.asarray(obj.position, dtype=float) + (signs * half) @ rotation_matrix(obj.quaternion).T


def boxes_intersect(
    centre_a: np.ndarray,
    axes_a: np.ndarray,
    half_a: np.ndarray,
    centre_b: np.ndarray,
    axes_b: np.ndarray,
    half_b: np.ndarray,
    tolerance: float = OVERLAP_TOLERANCE,
) -> bool:
    """Whether two oriented boxes overlap by more than ``tolerance`` (separating-axis test over the 15 axes: the
    6 face normals and the 9 edge cross products). ``axes_*`` hold the box axes as columns."""
    candidates = [axes_a[:, k] for k in range(3)] + [axes_b[:, k] for k in range(3)]
    candidates += [np.cross(axes_a[:, k], axes_b[:, m]) for k in range(3) for m in range(3)]
    offset = np.asarray(centre_b, dtype=float) - np.asarray(centre_a, dtype=float)
    for axis in candidates:
        norm = np.linalg.norm(axis)
        if norm < 1e-9:  # parallel edges: covered by the face normals
            continue
        axis = axis / norm
        radius_a = np.sum(half_a * np.abs(axis @ axes_a))
        radius_b = np.sum(half_b * np.abs(axis @ axes_b))
        if abs(offset @ axis) >= radius_a + radius_b - tolerance:
            return False
    return True


def finger_boxes(spec: ClutterSpec, obj: ClutterObject) -> list[tuple[np.ndarray, np.ndarray]]:
    """The two finger volumes for grasping ``obj`` as world axis-aligned boxes (low corner, high corner)."""
    corners = part_corners(spec, obj)
    x0, x1 = corners[:, 0].min(), corners[:, 0].max()
    top = corners[:, 2].max()
    y = float(obj.position[1])
    y0, y1 = y - spec.finger_width / 2, y + spec.finger_width / 2
    z0, z1 = top - spec.grasp_depth, top + FINGER_REACH
    left = (np.array([x0 - spec.finger_gap - spec.finger_thickness, y0, z0]), np.array([x0 - spec.finger_gap, y1, z1]))
    right = (np.array([x1 + spec.finger_gap, y0, z0]), np.array([x1 + spec.finger_gap + spec.finger_thickness, y1, z1]))
    return [left, right]


def obstructs(spec: ClutterSpec, obj: ClutterObject, box: tuple[np.ndarray, np.ndarray]) -> bool:
    """Whether part ``obj`` intersects the axis-aligned ``box`` (low corner, high corner)."""
    low, high = box
    return boxes_intersect(
        (low + high) / 2,
        np.eye(3),
        (high - low) / 2,
        np.asarray(obj.position, dtype=float),
        rotation_matrix(obj.quaternion),
        np.asarray(spec.part_size[obj.type], dtype=float) / 2,
    )


def part_blockers(spec: ClutterSpec, scene: ClutterScene, i: int) -> list[int]:
    """Parts resting directly on part ``i`` plus parts obstructing one of its fingers, sorted."""
    found = {j for j in range(len(scene.objects)) if j != i and _rests_on(scene, i, j)}
    for box in finger_boxes(spec, scene.objects[i]):
        found.update(j for j, other in enumerate(scene.objects) if j != i and obstructs(spec, other, box))
    return sorted(found)


def blockers(spec: ClutterSpec, scene: ClutterScene) -> list[list[int]]:
    """blockers[i]: the parts that keep part i from being grasped (:func:`part_blockers`)."""
    return [part_blockers(spec, scene, i) for i in range(len(scene.objects))]


def graspable(spec: ClutterSpec, scene: ClutterScene) -> np.ndarray:
    """(n,) bool: part i has no blocker."""
    return np.array([not b for b in blockers(spec, scene)], dtype=bool)


def solution_tokens(spec: ClutterSpec, scene: ClutterScene, i: int) -> list[str]:
    """``["grasp"]``, ``["help"]``, ``["move", t1]`` or ``["move", t1, "and", t2]`` for part ``i``."""
    return blocker_solution(scene, i, part_blockers(spec, scene, i))


def solution_types(tokens: list[str]) -> list[str]:
    """The part types a "move t1 [and t2]" solution names (none for grasp or help)."""
    return [t for t in tokens[1:] if t != AND] if tokens and tokens[0] == MOVE else []


def resolve_request(
    scene: ClutterScene, current: int, types: list[str], candidates: Iterable[int] | None = None
) -> int | None:
    """The object of one of ``types`` nearest to ``current`` (box-centre pixel distance), excluding ``current``;
    only among ``candidates`` when given (the rule passes the blockers). None when there is none. Ties go to the
    lower index."""
    pool = range(len(scene.objects)) if candidates is None else candidates
    pool = [j for j in pool if j != current and scene.objects[j].type in types]
    if not pool:
        return None
    centres = {j: _centre(scene.objects[j]) for j in [current, *pool]}
    return min(pool, key=lambda j: (float(np.linalg.norm(centres[j] - centres[current])), j))


def iterative_solution(spec: ClutterSpec, scene: ClutterScene, goal: int) -> list[tuple[int, list[str]]]:
    """Algorithm 4 with the rule as oracle: [(requested part, its solution tokens), ...], starting at ``goal`` and
    ending with a graspable part or help (also when a part would be requested twice)."""
    chain: list[tuple[int, list[str]]] = []
    current = goal
    while True:
        found = part_blockers(spec, scene, current)
        tokens = blocker_solution(scene, current, found)
        chain.append((current, tokens))
        if tokens[0] != MOVE:
            return chain
        following = resolve_request(scene, current, solution_types(tokens), candidates=found)
        assert following is not None  # the named types are the blockers' types
        if any(following == part for part, _ in chain):  # parts blocking each other: moving them cannot help
            chain.append((following, [HELP]))
            return chain
        current = following


def blocker_solution(scene: ClutterScene, i: int, found: list[int]) -> list[str]:
    """The solution tokens of part ``i`` whose blockers are ``found`` (the rule's, or a data set's annotation)."""
    return type_solution(scene.objects[i].type, [scene.objects[j].type for j in found])


def type_solution(own: str, blocker_types: Iterable[str]) -> list[str]:
    """The solution tokens of an object of type ``own`` whose blockers have ``blocker_types``: grasp when there is
    none, help when one has its own type, else move them (also what VMRN's predicted children read as)."""
    kinds = set(blocker_types)
    if not kinds:
        return [GRASP]
    if own in kinds:
        return [HELP]
    return move_tokens(kinds)


def _rests_on(scene: ClutterScene, i: int, j: int) -> bool:
    resting = np.asarray(scene.resting)
    return resting.size > 0 and bool(resting[i, j])


def _centre(obj: ClutterObject) -> np.ndarray:
    box = np.asarray(obj.box, dtype=float)
    return (box[:2] + box[2:]) / 2
