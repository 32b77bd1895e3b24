"""The Ch.5 robot cell (Algorithm 3's PickandPlace, thesis 5.2.3): seeded resets, every (part, position) pair of
the goals placed by the robot, commands it cannot carry out refused with their reason, the worker's parts in the
cell, and layout errors naming the key."""

from __future__ import annotations

import numpy as np
import pytest

from hrc_lab.config import validate_config
from hrc_lab.env.robot.factory import make_env
from hrc_lab.env.robot.settings import AssembleToOrderConfig, AssemblyCellLayout
from hrc_lab.registry import ConfigError

SPEC = AssembleToOrderConfig()


@pytest.fixture(scope="module")
def cell():
    env = make_env(SPEC, seed=0)
    yield env
    env.close()


def test_the_cell_resets_deterministically_for_a_seed(cell):
    cell.reseed(3)
    cell.reset()
    first = cell.object_positions()
    cell.reseed(3)
    cell.reset()
    np.testing.assert_array_equal(cell.object_positions(), first)
    cell.reseed(4)
    cell.reset()
    assert not np.allclose(cell.object_positions(), first)  # the bin jitter comes from the seed
    assert cell.assembly() == [] and cell.part_types == ["o1", "o1", "o1", "o2", "o2", "o3"]
    assert not cell.collisions


@pytest.mark.parametrize("goal", range(len(SPEC.goals)))
def test_pick_and_place_builds_every_goal(cell, goal):
    """Every (part type, position) pair of the goal configurations, placed by the robot in p1..p6 order."""
    cell.reseed(goal)
    cell.reset()
    target = [(part, p) for p, part in enumerate(SPEC.goal(goal), start=1)]
    for part, position in target:
        placement = cell.pick_and_place(part, position)
        assert placement.success, (part, position, placement.reason)
        assert placement.error_m <= SPEC.robot.place_tolerance and 0 < placement.steps <= 400
        assert placement.sim_s == pytest.approx(placement.steps / cell.control_freq)
    assert cell.assembly() == target and not cell.collisions
    resting = cell.object_positions()[[cell.assembled[p] for p in range(1, 7)]]
    for (part, position), centre in zip(target, resting):
        np.testing.assert_allclose(centre, cell.position_pose(position, part), atol=SPEC.robot.place_tolerance)


def test_commands_it_cannot_carry_out_move_nothing_and_say_why(cell):
    cell.reseed(0)
    cell.reset()
    assert cell.human_place("o3", 1).success  # the worker took the only o3
    before = cell.object_positions()
    cases = {
        ("o3", 4): "no o3 left in its bin",
        ("o1", 1): "p1 is occupied by o3",
        ("o3", 2): "o3 cannot go to p2",  # Table 5.1: o3 only at p1, p4, p5
        ("o9", 2): "unknown part type o9",
        ("o1", 7): "no position p7",
    }
    for (part, position), reason in cases.items():
        placement = cell.pick_and_place(part, position)
        assert not placement.success and reason in placement.reason and placement.steps == 0
        assert placement.started_at != placement.started_at  # NaN: the robot never moved
    np.testing.assert_array_equal(cell.object_positions(), before)
    refused = cell.human_place("o2", 1)  # the worker's side is checked the same way
    assert not refused.success and "occupied" in refused.reason


def test_the_robot_places_beside_the_workers_parts(cell):
    cell.reseed(1)
    cell.reset()
    for part, position in (("o1", 2), ("o2", 4)):
        assert cell.human_place(part, position).success
    human = cell.object_positions()[[cell.assembled[2], cell.assembled[4]]]
    for part, position in (("o1", 3), ("o2", 1), ("o3", 5)):
        placement = cell.pick_and_place(part, position)
        assert placement.success, (part, position, placement.reason)
    np.testing.assert_allclose(cell.object_positions()[[cell.assembled[2], cell.assembled[4]]], human, atol=2e-3)
    assert cell.assembly() == [("o2", 1), ("o1", 2), ("o1", 3), ("o2", 4), ("o3", 5)] and not cell.collisions


def test_return_to_bin_clears_a_position_for_the_right_part(cell):
    """hrc_lab's recovery: a wrong part goes back to its bin slot, the position is free for the goal's part."""
    cell.reseed(2)
    cell.reset()
    slots = cell.bin_slots.copy()
    assert cell.human_place("o1", 1).success  # a wrong placement: goal 0 wants o3 on p1
    index = cell.assembled[1]
    refused = cell.return_to_bin(2)
    assert not refused.success and "p2 is free" in refused.reason and refused.steps == 0
    removal = cell.return_to_bin(1)
    assert removal.success, removal.reason
    assert (removal.part, removal.position, removal.index) == ("o1", 1, index) and removal.steps > 0
    assert cell.part_at(1) is None and index in cell.in_bin("o1")
    np.testing.assert_allclose(cell.object_positions()[index][:2], slots[index][:2], atol=SPEC.robot.place_tolerance)
    placement = cell.pick_and_place("o3", 1)
    assert placement.success, placement.reason
    assert cell.part_at(1) == "o3" and cell.assembly() == [("o3", 1)] and not cell.collisions


def test_layout_errors_name_the_key(compose_config):
    with pytest.raises(ValueError, match=r"env\.robot\.position_spacing"):
        AssemblyCellLayout(position_spacing=0.03)
    with pytest.raises(ValueError, match=r"env\.robot\.part_half_sizes\.o2"):
        AssemblyCellLayout(part_half_sizes={"o1": [0.02, 0.02, 0.02], "o2": [0.01, 0.02, 0.02]})
    with pytest.raises(ValueError, match=r"bins\.o3"):
        AssembleToOrderConfig(robot=AssemblyCellLayout(bins={"o1": [-0.16, -0.3], "o2": [0.08, -0.3]}))
    with pytest.raises(ConfigError, match=r"env\.robot\.place_tolerance"):
        validate_config(compose_config("experiment=ch5/hrc_session", "env.robot.place_tolerance=0"))
    with pytest.raises(ConfigError, match=r"protocol\.video_session"):
        validate_config(compose_config("experiment=ch5/hrc_session", "protocol.video_session=10"))
