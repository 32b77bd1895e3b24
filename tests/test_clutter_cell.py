"""The Ch.6 robot cell (issue 22): a rendered scene placed in the robosuite cell is the scene the detector saw, the
depth image gives a part's top within 1 cm, and the gripper picks an isolated part of each type and sets it down."""

from dataclasses import replace

import numpy as np
import pytest

from hrc_lab.env.clutter.rule import graspable, part_corners
from hrc_lab.env.clutter.scenes import generate_scene
from hrc_lab.env.clutter.spec import ClutterSpec

SPEC = ClutterSpec()
SINGLE = replace(SPEC, min_objects=1, max_objects=1)
ONE_PART_SEEDS = {"a": 0, "b": 1, "c": 11}  # single-part scenes of each type (generate_scene(SINGLE, seed))
TRAY = np.array([0.0, 0.3])


@pytest.fixture(scope="module")
def cell():
    from hrc_lab.env.robot.clutter_cell import ClutterCell

    made = ClutterCell(SPEC, seed=0)
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


@pytest.mark.parametrize("part_type", ["a", "b", "c"])
def test_the_gripper_picks_an_isolated_part_of_each_type(part_type):
    from hrc_lab.env.robot.clutter_cell import ClutterCell

    scene = generate_scene(SINGLE, ONE_PART_SEEDS[part_type])
    assert scene.types == [part_type]
    cell = ClutterCell(SINGLE, seed=0)
    try:
        cell.place_scene(scene)
        _, _, depth = cell.image()
        outcome = cell.pick(cell.locate(scene.objects[0].box, depth))
        assert outcome.held == 0 and outcome.touched == []
        assert cell.part_poses()[0][0, 2] > scene.objects[0].position[2] + 0.05  # lifted with the gripper
        cell.put(TRAY, outcome.held)
        position = cell.part_poses()[0][0]
        assert np.linalg.norm(position[:2] - TRAY) < 0.02 and position[2] < SPEC.part_size[part_type][2]
    finally:
        cell.close()
