"""Ch.6 clutter cell: the graspability rule on hand-built scenes, the spec's checks, and one rendered scene."""

import numpy as np
import pytest

import hrc_lab.config  # noqa: F401  (stores the schemas that conf/env/clutter.yaml extends)
from hrc_lab.env import ENVS
from hrc_lab.env.clutter.rule import (
    blockers,
    boxes_intersect,
    graspable,
    iterative_solution,
    part_corners,
    resolve_request,
    solution_tokens,
    solution_words,
)
from hrc_lab.env.clutter.spec import PART_TYPES, ClutterObject, ClutterScene, ClutterSpec
from hrc_lab.registry import ConfigError

SPEC = ClutterSpec()
A, B, C = (SPEC.part_size[t] for t in "abc")  # a: 0.032 x 0.024 x 0.018, b: 0.10 x 0.04 x 0.03, c: 0.06^2 x 0.07


def part(kind: str, x: float, y: float, z: float | None = None, yaw: float = 0.0) -> ClutterObject:
    """A part lying flat (or at centre height ``z``), its box the projection of its corners."""
    z = SPEC.part_size[kind][2] / 2 if z is None else z
    obj = ClutterObject(kind, np.array([x, y, z]), np.array([np.cos(yaw / 2), 0, 0, np.sin(yaw / 2)]), np.zeros(4))
    pixels = SPEC.project(part_corners(SPEC, obj))
    obj.box = np.concatenate([pixels.min(axis=0), pixels.max(axis=0)]).astype(np.float32)
    return obj


def scene(*objects: ClutterObject, resting: tuple[tuple[int, int], ...] = ()) -> ClutterScene:
    """resting: (i, j) pairs, part j lies on part i."""
    matrix = np.zeros((len(objects), len(objects)), dtype=bool)
    for i, j in resting:
        matrix[i, j] = True
    size = SPEC.image_size
    image = np.zeros((size, size, 3), np.uint8)
    return ClutterScene(0, image, list(objects), np.full((size, size), -1, np.int8), matrix)


def test_a_part_with_another_on_top_is_blocked_and_named():
    on_top = scene(part("a", 0, 0), part("c", 0.01, 0, z=A[2] + C[2] / 2), resting=((0, 1),))
    assert graspable(SPEC, on_top).tolist() == [False, True]
    assert blockers(SPEC, on_top) == [[1], []]
    assert solution_tokens(SPEC, on_top, 0) == ["move", "c"]
    # resting alone blocks, wherever the rule is told the part lies
    far = scene(part("a", 0, 0), part("c", 0.08, 0.08), resting=((0, 1),))
    assert solution_tokens(SPEC, far, 0) == ["move", "c"] and solution_tokens(SPEC, far, 1) == ["grasp"]


def test_a_neighbour_in_the_fingers_path_blocks_only_along_x():
    x_side = scene(part("a", 0, 0), part("b", A[0] / 2 + B[0] / 2, 0))  # b touches a's +x face
    assert solution_tokens(SPEC, x_side, 0) == ["move", "b"]
    assert solution_tokens(SPEC, x_side, 1) == ["grasp"]  # a is lower than b's fingers reach
    y_side = scene(part("a", 0, 0), part("b", 0, A[1] / 2 + B[1] / 2))  # touches a's +y face: fingers pass
    assert graspable(SPEC, y_side).all()
    rotated = scene(part("a", 0, 0), part("b", 0.06, 0, yaw=np.pi / 2))  # b across a's +x side, clear of it
    assert graspable(SPEC, rotated).all()


def test_two_parts_of_one_type_side_by_side_ask_for_help():
    pair = scene(part("a", 0, 0), part("a", A[0] + 0.005, 0.004), part("c", 0.0, 0.09))
    assert [solution_tokens(SPEC, pair, i) for i in range(3)] == [["help"], ["help"], ["grasp"]]


def test_an_isolated_part_is_graspable_and_two_types_are_sorted():
    assert solution_tokens(SPEC, scene(part("c", 0, 0)), 0) == ["grasp"]
    crowded = scene(part("a", 0, 0), part("c", -(A[0] / 2 + C[0] / 2), 0), part("b", A[0] / 2 + B[0] / 2, 0))
    assert solution_tokens(SPEC, crowded, 0) == ["move", "b", "and", "c"]
    words = {"<start>", "<end>", "<pad>", "grasp", "help", "move", "and", "a", "b", "c"}
    assert set(solution_words(PART_TYPES)) == words


def test_iterative_solution_follows_the_nearest_blocker_to_a_graspable_part():
    a_c = scene(part("a", 0, 0), part("c", A[0] / 2 + C[0] / 2, 0), part("c", -0.09, 0.09))
    assert iterative_solution(SPEC, a_c, 0) == [(0, ["move", "c"]), (1, ["grasp"])]
    # a blocked by b, b carries c: a -> b -> c
    chain = scene(
        part("a", 0, 0), part("b", A[0] / 2 + B[0] / 2, 0), part("c", 0.07, 0, z=B[2] + C[2] / 2), resting=((1, 2),)
    )
    assert iterative_solution(SPEC, chain, 0) == [(0, ["move", "b"]), (1, ["move", "c"]), (2, ["grasp"])]
    # parts blocking each other: the chain ends with help
    loop = scene(part("a", 0, 0), part("b", 0.08, 0.08), resting=((0, 1), (1, 0)))
    assert iterative_solution(SPEC, loop, 0) == [(0, ["move", "b"]), (1, ["move", "a"]), (0, ["help"])]


def test_resolve_request_takes_the_nearest_box_of_the_named_types():
    s = scene(part("a", 0, 0), part("b", 0.05, 0.05), part("b", -0.03, 0), part("c", 0.02, 0))
    assert resolve_request(s, 0, ["b"]) == 2
    assert resolve_request(s, 0, ["b", "c"]) == 3
    assert resolve_request(s, 0, ["b"], candidates=[1]) == 1
    assert resolve_request(s, 0, ["a"]) is None


def test_oriented_boxes_intersect_only_when_they_overlap():
    axes = np.eye(3)
    r = np.sqrt(0.5)
    turned = np.array([[r, -r, 0], [r, r, 0], [0, 0, 1]])  # 45 degrees about z
    half = np.array([0.5, 0.5, 0.5])
    # the axis-aligned bounds overlap in both cases; only the second turned cube reaches the first one's corner
    assert not boxes_intersect(np.zeros(3), axes, half, np.array([0.9, 0.9, 0]), turned, half)
    assert boxes_intersect(np.zeros(3), axes, half, np.array([0.7, 0.7, 0]), turned, half)
    assert not boxes_intersect(np.zeros(3), axes, half, np.array([1.0, 0, 0]), axes, half)  # touching faces


def test_config_matches_the_defaults_and_errors_name_the_key(compose_config):
    assert ENVS.validate(compose_config("env=clutter").env) == ClutterSpec()
    with pytest.raises(ConfigError, match="env.min_objects"):
        ENVS.validate({"name": "clutter", "min_objects": 5, "max_objects": 4})
    with pytest.raises(ValueError, match="env.image_size"):
        ClutterSpec(image_size=8)


def test_a_generated_scene_is_deterministic_and_consistent(tmp_path):
    from hrc_lab.env.clutter.scenes import generate_scene, load_scenes, save_scenes

    spec = ClutterSpec(image_size=64)
    first, again = generate_scene(spec, 3), generate_scene(spec, 3)
    assert np.array_equal(first.image, again.image) and np.array_equal(first.segmentation, again.segmentation)
    assert first.image.shape == (64, 64, 3) and first.image.dtype == np.uint8
    n = len(first.objects)
    assert spec.min_objects <= n <= spec.max_objects and first.resting.shape == (n, n)
    boxes = first.boxes
    assert (boxes[:, :2] >= 0).all() and (boxes[:, 2:] <= 64).all() and (boxes[:, 2:] > boxes[:, :2]).all()
    for i in range(n):
        rows, cols = np.nonzero(first.segmentation == i)
        assert len(rows) > 0 and boxes[i].tolist() == [cols.min(), rows.min(), cols.max() + 1, rows.max() + 1]
    assert set(np.unique(first.segmentation)) <= set(range(-1, n))
    (loaded,) = load_scenes(save_scenes(tmp_path / "scenes.npz", [first], spec), spec)
    assert np.array_equal(loaded.image, first.image) and np.array_equal(loaded.resting, first.resting)
    assert loaded.types == first.types and np.allclose(loaded.boxes, boxes)


def test_every_scene_size_the_env_allows_is_drawn():
    """Table 6.2 fixes the number of parts (min_objects = max_objects = count, any count up to the sum of
    env.max_counts): the counts per type add up to it within max_counts, and the scene has that many parts."""
    from dataclasses import replace

    from hrc_lab.env.clutter.scenes import _counts, generate_scene

    spec = ClutterSpec(image_size=64, max_counts={"a": 4, "b": 2, "c": 1})
    rng = np.random.default_rng(0)
    for total in range(1, 8):
        counts = _counts(replace(spec, min_objects=total, max_objects=total), rng)
        assert sum(counts.values()) == total and all(counts[t] <= spec.max_counts[t] for t in "abc")
    scene = generate_scene(replace(spec, min_objects=7, max_objects=7), 7)
    assert sorted(scene.types) == ["a"] * 4 + ["b"] * 2 + ["c"]
