"""RM+RRT-Connect (Table 4.3, thesis 4.4.3): OMPL's RRT-Connect around an obstacle of the package cell, its failures
(a goal in collision, a lip out of reach, a goal it cannot connect) within the time limit, one whole pick-and-place
with ground-truth decisions, and the ``motion/rrt_connect`` config."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
from hydra import compose, initialize_config_dir
from hydra.core.global_hydra import GlobalHydra

from hrc_lab.config import register_schemas
from hrc_lab.env import ENVS
from hrc_lab.env.robot.cell import PICK, PLACE
from hrc_lab.env.robot.settings import PackageToOrderConfig
from hrc_lab.motion import MOTIONS
from hrc_lab.motion.configs import RRTConnectConfig
from hrc_lab.motion.rrt_connect import RRTConnectMotion, densify, solve_rrt_connect
from hrc_lab.motion.two_level import RELEASE, Rollout
from hrc_lab.registry import ConfigError, named

CONF = Path(__file__).resolve().parents[1] / "conf"
FINE = np.deg2rad(0.1)  # joint spacing at which a planned path is replayed through the collision checker


@pytest.fixture(scope="module")
def cfg() -> RRTConnectConfig:
    """The composed ``motion/rrt_connect`` config, validated."""
    register_schemas()
    GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
            node = compose(config_name="motion/rrt_connect").motion
    finally:
        GlobalHydra.instance().clear()
    return MOTIONS.validate(node)


@pytest.fixture(scope="module")
def env():
    return ENVS.build(named(PackageToOrderConfig(n_objects=3, n_selected=2), "package_to_order"), seed=0)


def wall_crossing(env, motion: RRTConnectMotion) -> tuple[np.ndarray, np.ndarray]:
    """Joint configurations with the lip 3 cm above the box floor level, 7 cm outside its south wall and 5 cm
    inside it: the straight joint-space line between them runs the cup through the wall."""
    env.reset()
    box, half_y = env.box_position(), env.box_half_extent()[1]
    outside = motion.ik(env, box + [0.0, -half_y - 0.07, 0.03], env.commanded_qpos()[:3])
    inside = motion.ik(env, box + [0.0, -half_y + 0.05, 0.03], outside)
    assert outside is not None and inside is not None
    return outside, inside


def test_rrt_connect_finds_a_collision_free_path_around_the_box_wall(cfg, env):
    motion = MOTIONS.build(cfg, seed=0)
    assert isinstance(motion, RRTConnectMotion)
    q_start, q_goal = wall_crossing(env, motion)
    contact = motion.checker(env, clearance=0.0)
    blocked = [contact.collision(q) for q in densify(np.array([q_start, q_goal]), FINE)]
    assert any(c and "box_wall" in c for c in blocked)
    result = motion.plan(env, q_start, q_goal)
    assert result.failure == "" and 0 < result.planning_ms < 1e3 * cfg.timeout_s
    assert np.allclose(result.path[0], q_start) and np.allclose(result.path[-1], q_goal) and len(result.path) > 2
    assert all(contact.valid(q) for q in densify(result.path, FINE))
    again = MOTIONS.build(cfg, seed=0).plan(env, q_start, q_goal)  # OMPL seeded from the module's seed
    assert np.array_equal(again.path, result.path)


def test_unreachable_goals_fail_with_their_reason_within_the_time_limit(cfg, env):
    motion = RRTConnectMotion(RRTConnectConfig(timeout_s=0.5), seed=0)
    env.reset()
    q = env.commanded_qpos()[:3]
    assert motion.ik(env, np.array([2.0, 0.0, 1.0]), q) is None  # 2 m away: out of reach
    top = env.object_positions()[0] + [0.0, 0.0, env.spec.product_size / 2 + 0.002]
    at_top = motion.ik(env, top, q, motion.checker(env, target=0, clearance=0.0))  # the descent's end: the
    assert at_top is not None  # product being picked is no obstacle, for the planner it is
    result = motion.plan(env, q, at_top)
    assert result.path is None and result.failure == "goal_in_collision"
    out = Rollout()  # a product picked for a goal slot beyond the table's end: no IK solution to place it
    assert motion.run_stage(env, 0, PICK, 0, out), out.failure
    env.episode.slot_positions[0] = [1.5, 0.0, 0.83]
    begin = time.perf_counter()
    assert not motion.run_stage(env, 0, PLACE, 0, out)
    assert out.failure == "ik" and len(out.planning_ms) == 2 and time.perf_counter() - begin < 1.0


def test_a_goal_it_cannot_connect_is_a_timeout_not_a_hang():
    cfg = RRTConnectConfig(timeout_s=0.3)
    begin = time.perf_counter()  # a wall at base = 0 splits the space
    path = solve_rrt_connect(lambda q: abs(q[0]) > 0.1, -np.ones(3), np.ones(3), np.array([-0.5, 0.0, 0.0]),
                             np.array([0.5, 0.0, 0.0]), cfg, seed=1)
    assert path is None and time.perf_counter() - begin < cfg.timeout_s + 0.5


def test_one_pick_and_place_with_ground_truth_decisions(cfg, env):
    motion = MOTIONS.build(cfg, seed=0)
    env.reset()
    obj = env.expert_plan()[0]
    slot = int(env.episode.goal_slot[obj])
    out = Rollout()
    assert motion.run_stage(env, obj, PICK, slot, out), out.failure
    assert env.suction.held == obj
    assert motion.run_stage(env, obj, PLACE, slot, out), out.failure
    env.step(RELEASE)
    assert np.linalg.norm(env.object_positions()[obj] - env.goals[obj]) <= env.success_threshold
    assert env.suction.held == -1 and not env.collisions and out.failure == ""
    assert len(out.planning_ms) == 2 and all(ms > 0 for ms in out.planning_ms)
    assert 0 < out.steps < 100


@pytest.mark.parametrize("key, value", [("timeout_s", 0.0), ("range_rad", -0.1), ("collision_resolution", 1.5),
                                        ("clearance_m", -0.01), ("ik_iterations", 0), ("hover_m", 0.0)])
def test_config_errors_name_the_key(key, value):
    with pytest.raises(ValueError, match=f"motion.{key}"):
        RRTConnectConfig(**{key: value})
    with pytest.raises(ConfigError, match=f"motion.{key}"):
        MOTIONS.validate({"name": "rrt_connect", key: value})
