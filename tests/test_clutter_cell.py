"""The Ch.6 robot cell (issue 22): a rendered scene placed in the robosuite cell is the scene the detector saw, the
depth image gives a part's top within 1 cm, and the gripper picks an isolated part of each type and sets it down."""

from dataclasses import replace

import numpy as np
import pytest
import torch

import hrc_lab.config  # noqa: F401  (the registries, before hrc_lab.grasp)
from hrc_lab.env.clutter.rule import blocker_solution, blockers, graspable, part_corners
from hrc_lab.env.clutter.scenes import generate_scene
from hrc_lab.env.clutter.spec import ClutterSpec
from hrc_lab.experiments.ch6_grasp import iterative_correct
from hrc_lab.experiments.schemas import Table62RobotProtocol
from hrc_lab.grasp.observation import SceneNodes
from hrc_lab.grasp.solver import NodeReading

SPEC = ClutterSpec()
SINGLE = replace(SPEC, min_objects=1, max_objects=1)
THREE = replace(SPEC, min_objects=3, max_objects=3)
A_UNDER_B = 168  # generate_scene(THREE, 168): a b lies on the only a; the rule: move b, then grasp a
ONE_PART_SEEDS = {"a": 0, "b": 1, "c": 11}  # single-part scenes of each type (generate_scene(SINGLE, seed))
TRAY = np.array([0.0, 0.3])
GRIP_DEPTH = Table62RobotProtocol().grip_depth  # the robot row's


@pytest.fixture(scope="module")
def cell():
    from hrc_lab.env.robot.clutter_cell import ClutterCell

    made = ClutterCell(SPEC, seed=0, grip_depth=GRIP_DEPTH)
    yield made
    made.close()


def test_a_placed_scene_is_the_rendered_one_and_resets_the_same(cell):
    scene = generate_scene(SPEC, 42)
    cell.place_scene(scene)
    positions, quaternions = cell.part_poses()
    assert np.abs(positions - [o.position for o in scene.objects]).max() < 1e-3  # settled where they settled
    image, segmentation, depth = cell.image()
    assert (image != scene.image).any(-1).mean() < 0.01 and (segmentation == scene.segmentation).mean() > 0.99
    cell.place_scene(scene)
    again, turned = cell.part_poses()
    assert np.array_equal(again, positions) and np.array_equal(turned, quaternions)


def test_depth_gives_each_free_parts_top_within_a_centimetre(cell):
    scene = generate_scene(SPEC, 42)
    cell.place_scene(scene)
    _, _, depth = cell.image()
    free = [i for i in range(len(scene.objects)) if not scene.resting[i].any() and graspable(SPEC, scene)[i]]
    assert free
    for i in free:
        obj = scene.objects[i]
        top = np.array([*obj.position[:2], part_corners(SPEC, obj)[:, 2].max()])
        assert np.linalg.norm(cell.locate(obj.box, depth) - top) < 0.01


def test_the_gripper_comes_straight_down_and_its_tips_stop_above_the_table(cell):
    from hrc_lab.env.robot.clutter_cell import TIP_CLEARANCE

    cell.place_scene(generate_scene(SPEC, 42))
    turned = cell.sim.data.site_xmat[cell._eef_site].reshape(3, 3)
    assert np.degrees(np.arccos(-turned[2, 2])) < 0.5  # the gripper's axis within half a degree of vertical
    assert np.allclose(cell.top_down(turned), np.diag([1.0, -1.0, -1.0]))  # the fingers close along x
    tips_now = cell.sim.data.site_xpos[cell._eef_site][2] - cell._lowest_finger_point()
    assert tips_now == pytest.approx(cell._tip_below_site, abs=5e-4)  # measured in the pose it grasps in
    assert cell.tips_for(np.array([0.0, 0.0, 0.1])) == pytest.approx(0.1 - GRIP_DEPTH)
    assert cell.tips_for(np.array([0.0, 0.0, 0.018])) == TIP_CLEARANCE  # an a flat on the table: not into the table


@pytest.mark.slow  # ~14 s a part type: CI's slow step (Algorithm 4's test below picks with the robot by default)
@pytest.mark.parametrize("part_type", ["a", "b", "c"])
def test_the_gripper_picks_an_isolated_part_of_each_type(part_type):
    from hrc_lab.env.robot.clutter_cell import ClutterCell

    scene = generate_scene(SINGLE, ONE_PART_SEEDS[part_type])
    assert scene.types == [part_type]
    cell = ClutterCell(SINGLE, seed=0, grip_depth=GRIP_DEPTH)
    try:
        cell.place_scene(scene)
        _, _, depth = cell.image()
        box = scene.objects[0].box
        outcome = cell.pick(cell.locate(box, depth), cell.grasp_opening(box, depth))  # pre-shaped, as the robot row
        assert outcome.held == 0 and outcome.touched == []
        assert cell.part_poses()[0][0, 2] > scene.objects[0].position[2] + 0.05  # lifted with the gripper
        cell.put(TRAY, outcome.held)
        position = cell.part_poses()[0][0]
        assert np.linalg.norm(position[:2] - TRAY) < 0.02 and position[2] < SPEC.part_size[part_type][2]
    finally:
        cell.close()


def test_the_pre_grasp_opening_is_the_parts_extent_plus_the_rules_gap(cell):
    """The measured finger openings fall from ~6 cm (open) to below 2 cm (closed); an isolated part a's pre-grasp
    half opening is half its x-extent plus the rule's finger gap and the margin (within 5 mm)."""
    from hrc_lab.env.robot.clutter_cell import PRESHAPE_MARGIN

    commands, halves = cell.finger_openings()
    assert commands[0] == -1 and commands[-1] == 1
    assert halves[0] > 0.055 and halves[-1] < 0.02 and (np.diff(halves) < 0.002).all()  # (about) monotone
    scene = generate_scene(SINGLE, ONE_PART_SEEDS["a"])
    cell.place_scene(scene, SINGLE)
    _, _, depth = cell.image()
    corners = part_corners(SPEC, scene.objects[0])
    expected = np.ptp(corners[:, 0]) / 2 + SPEC.finger_gap + PRESHAPE_MARGIN
    assert cell.grasp_opening(scene.objects[0].box, depth) == pytest.approx(expected, abs=0.005)


def _depth_of_blocks(blocks):
    """A depth image of the scene camera over the table with axis-aligned blocks (x0, x1, y0, y1, height), m."""
    rows, cols = np.indices((SPEC.image_size, SPEC.image_size))
    pixels = np.stack([cols + 0.5, rows + 0.5], axis=-1)
    heights = np.zeros(rows.shape)
    for x0, x1, y0, y1, height in blocks:
        xy = SPEC.unproject(pixels, np.full(rows.shape, SPEC.camera_height - height))
        inside = (xy[..., 0] >= x0) & (xy[..., 0] <= x1) & (xy[..., 1] >= y0) & (xy[..., 1] <= y1)
        heights[inside] = np.maximum(heights[inside], height)
    return (SPEC.camera_height - heights).astype(np.float32)


def test_the_approach_yaw_turns_the_fingers_away_from_a_tall_neighbour(cell):
    """A 3 x 3 cm part 3 cm high at the centre: alone, the rule's yaw (0) and its pre-grasp opening; with a 7 cm tall
    wall 1.5 cm beyond it in +x, 12 cm long in y (in the fingers' way at every yaw up to 60 degrees), about a
    quarter turn, the fingers closing along y."""
    part = (-0.015, 0.015, -0.015, 0.015, 0.03)
    corners = SPEC.project(np.array([[-0.015, 0.015, 0.03], [0.015, -0.015, 0.03]]))
    box = np.array([*corners[0], *corners[1]], dtype=np.float32)
    alone = _depth_of_blocks([part])
    approach = cell.grasp_yaw(box, alone, True, "smallest_turn")
    assert approach.yaw == 0.0 and approach.half_opening == pytest.approx(cell.grasp_opening(box, alone), abs=0.004)
    assert approach.tips == pytest.approx(0.03 - GRIP_DEPTH, abs=0.002)  # the full grip depth
    crowded = _depth_of_blocks([part, (0.03, 0.06, -0.06, 0.06, 0.07)])
    approach = cell.grasp_yaw(box, crowded, True, "smallest_turn")
    assert abs(np.degrees(approach.yaw)) >= 75 and approach.half_opening < 0.03
    assert cell.grasp_yaw(box, crowded, True, order="narrowest").yaw == approach.yaw  # only ~a quarter turn is clear
    with pytest.raises(ValueError, match="yaw order"):
        cell.grasp_yaw(box, crowded, True, order="widest")


def test_the_finger_tips_stop_above_the_part_the_named_one_rests_on(cell):
    """A 3 x 3 cm part 2 cm high on an 8 x 8 cm block 5 cm high: the tips go below the part's top only as far as
    the block lets them (2 mm above it), which is deeper than the rule's 8 mm, so the rule's yaw stays clear."""
    from hrc_lab.env.robot.clutter_cell import TIP_CLEARANCE

    corners = SPEC.project(np.array([[-0.015, 0.015, 0.07], [0.015, -0.015, 0.07]]))
    box = np.array([*corners[0], *corners[1]], dtype=np.float32)
    stacked = _depth_of_blocks([(-0.04, 0.04, -0.04, 0.04, 0.05), (-0.015, 0.015, -0.015, 0.015, 0.07)])
    approach = cell.grasp_yaw(box, stacked, True, "smallest_turn")
    assert approach.yaw == 0.0
    assert approach.tips == pytest.approx(0.05 + TIP_CLEARANCE, abs=0.002)
    assert approach.tips < 0.07 - SPEC.grasp_depth


def oracle_nodes(now):
    """The scene as a perfect detector and the rule would read it."""
    found = blockers(THREE, now)
    return SceneNodes(now, now.boxes, list(now.types), torch.zeros(len(found), 1), np.arange(len(found)),
                      np.array([not b for b in found]), [blocker_solution(now, i, b) for i, b in enumerate(found)],
                      found)


def oracle_read(nodes, mask):
    return [NodeReading(float(g), s) for g, s in zip(nodes.rule_graspable, nodes.rule_solution)]


def oracle_episode(cell, max_grasps):
    from hrc_lab.grasp.robot_grasping import run_episode

    scene = generate_scene(THREE, A_UNDER_B)
    return run_episode(cell, scene, THREE, "a", oracle_nodes, oracle_read, max_requests=6, max_grasps=max_grasps,
                       answer_right=lambda nodes, goal, answer: iterative_correct(THREE, nodes, goal, answer),
                       preshape=True, choose_yaw=True, yaw_order="smallest_turn")


def test_algorithm_4_with_the_robot_moves_the_blocker_then_delivers(cell):
    from hrc_lab.env.robot.clutter_cell import ASIDE, TRAY

    episode = oracle_episode(cell, max_grasps=6)
    assert episode.success and episode.failure == ""
    assert [s.action for s in episode.steps] == ["grasp b", "grasp a"] and [s.held for s in episode.steps] == ["b", "a"]
    assert all(s.right for s in episode.steps) and set(episode.steps[0].seconds) == {"render", "detection",
                                                                                        "reasoning", "motion"}
    positions = cell.part_poses()[0]
    kinds = [cell.object_type(i) for i in range(len(positions))]
    assert np.linalg.norm(positions[kinds.index("a"), :2] - TRAY) < 0.03
    assert min(np.linalg.norm(positions[i, :2] - ASIDE[0]) for i, k in enumerate(kinds) if k == "b") < 0.03


def test_the_grasp_bound_ends_the_episode(cell):
    episode = oracle_episode(cell, max_grasps=1)
    assert not episode.success and episode.failure == "iteration_bound" and len(episode.steps) == 1
