"""robosuite cells: creation, stepping, seeding, action limits, suction, collisions and the scripted expert."""

import numpy as np
import pytest

from hrc_lab.env.robot.correction_cell import ErrorCorrection
from hrc_lab.env.robot.expert import ScriptedExpert, run_episode
from hrc_lab.env.robot.factory import make_env
from hrc_lab.env.robot.package_cell import PackageToOrder
from hrc_lab.env.robot.settings import ErrorCorrectionConfig, PackageToOrderConfig, SimSettings
from hrc_lab.env.robot.spec import PackageToOrderSpec

SPEC_2OF3 = PackageToOrderSpec(n_objects=3, n_selected=2)


@pytest.fixture(scope="module")
def pto():
    return PackageToOrder(SPEC_2OF3, case=1, seed=0, horizon=400)


@pytest.fixture(scope="module")
def ec():
    return ErrorCorrection(task="one_object", case=1, seed=0)


def test_reset_builds_the_scene_of_the_task_spec(pto):
    obs = pto.reset()
    spec = pto.spec
    positions = obs["object_pos"].reshape(spec.n_objects, 3)
    nominal = spec.nominal_pending()
    assert np.all(np.abs(positions[:, :2] - nominal) <= np.asarray(spec.pick_jitter) + 1e-3)
    assert np.allclose(positions[:, 2], spec.table_z + spec.product_size / 2, atol=2e-3)
    structured = pto.structured_observation()
    assert structured["selected"].sum() == spec.n_selected
    assert structured["stage"] == 0 and structured["held"] == -1
    assert len(pto.raw_observation()) == 6 + 3 + 4 + 4 * spec.n_objects + 3 * spec.n_objects


def test_step_returns_info_and_sparse_reward(pto):
    pto.reset()
    _, reward, done, info = pto.step(np.array([0.0, 0.0, 0.0, -1.0]))
    assert reward == -1.0 and not done
    assert {"collision", "collided", "held", "goal_distances", "success"} <= set(info)
    with pytest.raises(ValueError, match="shape"):
        pto.step(np.zeros(6))


def test_same_seed_same_scene_and_trajectory():
    a = ErrorCorrection(task="two_object", case=2, seed=3)
    b = ErrorCorrection(task="two_object", case=2, seed=3)
    for env in (a, b):
        env.reset()
    assert np.allclose(a.object_positions(), b.object_positions())
    expert_a, expert_b = ScriptedExpert(a), ScriptedExpert(b)
    for _ in range(15):
        a.step(expert_a.act().action)
        b.step(expert_b.act().action)
    assert np.allclose(a.sim.get_state().flatten(), b.sim.get_state().flatten())
    c = ErrorCorrection(task="two_object", case=2, seed=4)
    c.reset()
    assert not np.allclose(a.goals, c.goals)


def test_joint_deltas_are_clipped_to_five_degrees_and_keep_the_tool_down(ec):
    ec.reset()
    before = ec.commanded_qpos()
    ec.step(np.array([np.deg2rad(20), np.deg2rad(-20), 0.0, -1.0]))
    change = ec.commanded_qpos() - before
    assert np.allclose(change[:3], np.deg2rad([5, -5, 0]), atol=1e-9)
    for _ in range(5):
        ec.step(np.array([0.0, 0.0, 0.0, -1.0]))
    tool_axis = ec.sim.data.site_xmat[ec.robots[0].eef_site_id["right"]].reshape(3, 3)[:, 2]
    assert tool_axis[2] < -0.99  # the tool (site z axis) points down


def test_suction_attaches_the_touched_object_and_releases_it(ec):
    ec.reset()
    expert = ScriptedExpert(ec)
    while ec.suction.held < 0:
        step = expert.act()
        assert step is not None, "the expert finished without picking"
        ec.step(step.action)
    held = ec.suction.held
    assert held == ec.plan[0]
    lifted = ec.object_positions()[held, 2]
    for _ in range(5):
        ec.step(np.array([0.0, -0.05, 0.0, 1.0]))  # shoulder up: the held part follows the cup
    assert ec.object_positions()[held, 2] > lifted + 0.02
    ec.step(np.array([0.0, 0.0, 0.0, -1.0]))
    assert ec.suction.held == -1
    for _ in range(10):
        ec.step(np.array([0.0, 0.0, 0.0, -1.0]))
    assert ec.object_positions()[held, 2] < lifted  # released: it fell


def test_grip_after_step_grips_at_the_end_of_the_step_that_touches():
    """The expert's way down to its first part, replayed with suction on all the way (as the closed loop descends):
    the default cell grips when the next command is applied, one with ``grip_after_step`` at the end of the step in
    which the lip reached the face."""
    env = ErrorCorrection(task="one_object", case=1, seed=0)
    env.reset()
    expert, actions = ScriptedExpert(env), []
    while env.suction.held < 0:
        actions.append(np.array([*expert.act().action[:-1], 1.0]))
        env.step(actions[-1])
    cells = {switch: ErrorCorrection(task="one_object", case=1, seed=0, grip_after_step=switch)
             for switch in (False, True)}
    for cell in cells.values():
        cell.reset()
        for action in actions[:-1]:
            cell.step(action)
    assert cells[False].suction.held == -1 and cells[True].suction.held == env.suction.held >= 0
    cells[False].step(actions[-1])
    assert cells[False].suction.held == env.suction.held
    assert make_env(ErrorCorrectionConfig(sim=SimSettings(grip_after_step=True)), seed=0).grip_after_step


def test_suction_does_nothing_in_the_air(ec):
    ec.reset()
    ec.step(np.array([0.0, 0.0, 0.0, 1.0]))
    assert ec.suction.held == -1


def test_driving_the_arm_into_the_table_is_a_collision_and_disables_the_effector():
    env = ErrorCorrection(task="place", seed=0, disable_effector_on_collision=True)
    env.reset()
    info = {}
    for _ in range(40):
        _, _, _, info = env.step(np.array([0.0, 0.087, 0.0, 1.0]))  # shoulder down, suction requested
        if info["collided"]:
            break
    assert info["collided"] and env.collisions
    assert not env.suction.enabled
    assert not info["success"]


@pytest.mark.parametrize(("make", "kwargs"), [
    (ErrorCorrection, {"task": "one_object", "case": 2}),
    (ErrorCorrection, {"task": "stack"}),
    (PackageToOrder, {"spec": SPEC_2OF3, "case": 2}),
    (PackageToOrder, {"spec": SPEC_2OF3, "n_missing": 1}),
])
def test_expert_succeeds_on_short_episodes(make, kwargs):
    env = make(seed=1, **kwargs)
    results = [run_episode(env)[:2] for _ in range(2)]
    assert all(success for success, _ in results), results
    assert all(steps <= 6 * 30 * len(env.expert_plan()) + len(env.expert_plan()) for _, steps in results)


def test_missing_products_are_restocked_once_the_rest_is_packed():
    env = PackageToOrder(SPEC_2OF3, n_missing=1, seed=2)
    env.reset()
    missing = env.episode.missing[0]
    assert not env.present()[missing] and np.isnan(env.structured_observation()["positions"][missing]).all()
    success, _, _ = run_episode(env)
    assert env.restocked and env.present().all() and success


def test_make_env_from_configs():
    env = make_env(PackageToOrderConfig(n_objects=3, n_selected=3, sim=SimSettings(case=2, horizon=50)), seed=0)
    assert isinstance(env, PackageToOrder) and env.case == 2 and env.horizon == 50
    env = make_env(ErrorCorrectionConfig(task="two_object", sim=SimSettings(success_threshold=0.08)), seed=0)
    assert isinstance(env, ErrorCorrection) and env.success_threshold == 0.08


def test_placement_noise_moves_the_experts_placing_stage_and_only_it(ec):
    """With placement_noise the expert aims its whole placing stage at one point around the goal (x-y only), drawn
    from its own generator (the scene's is untouched); without it, at the goal; picking is unaffected."""
    from hrc_lab.env.robot.cell import PICK, PLACE

    ec.reset()
    obj = ec.plan[0]
    exact, noisy = ScriptedExpert(ec), ScriptedExpert(ec, placement_noise=0.02, rng=np.random.default_rng(0))
    scene_rng = ec.np_random.bit_generator.state
    np.testing.assert_allclose(exact.designed_subgoals(obj, PICK), noisy.designed_subgoals(obj, PICK))
    goal_top = ec.goals[obj] + [0, 0, ec.cell_objects[obj].half_size[2]]
    np.testing.assert_allclose(exact.designed_subgoals(obj, PLACE)[2], goal_top + [0, 0, 0.003])
    shifts = np.array([noisy.designed_subgoals(obj, PLACE) - exact.designed_subgoals(obj, PLACE)
                       for _ in range(200)])
    assert np.allclose(shifts, shifts[:, :1])  # one shift for all three sub-goals of a stage
    assert np.allclose(shifts[..., 2], 0.0)
    assert 0.015 < shifts[:, 0, :2].std() < 0.025
    assert ec.np_random.bit_generator.state == scene_rng
    with pytest.raises(ValueError, match="placement_noise"):
        ScriptedExpert(ec, placement_noise=-0.01)
    with pytest.raises(ValueError, match="rng"):
        ScriptedExpert(ec, placement_noise=0.02)


def test_lean_step_is_robosuites_step_bit_for_bit():
    """``lean_step`` on and off, the same seed and 60 actions (the expert's, every third one random with the suction
    switched on or off at random, a wrist-3 action): the simulator state (joints, object poses), the lip, the held
    object, the collisions, reward, info and robosuite's observations (``step_observations``) agree at every step.
    Tolerance 0: the two paths compute the same floating-point operations (measured difference exactly 0.0)."""
    from hrc_lab.env import ENVS
    from hrc_lab.registry import named

    cells = [ENVS.build(named(ErrorCorrectionConfig(sim=SimSettings(yaw_action=True, lean_step=lean)),
                              "error_correction"), seed=1) for lean in (False, True)]
    full, lean = cells
    lean.step_observations = True
    for cell in cells:
        cell.reset()
    expert, rng, held = ScriptedExpert(full), np.random.default_rng(0), set()
    for t in range(60):
        step = expert.act()
        action = step.action if t % 3 else np.append(rng.uniform(-0.1, 0.1, 4), rng.choice([-1.0, 1.0]))
        (obs, reward, done, info), (lean_obs, lean_reward, lean_done, lean_info) = (c.step(action) for c in cells)
        np.testing.assert_array_equal(lean.sim.get_state().flatten(), full.sim.get_state().flatten())
        np.testing.assert_array_equal(lean.arm_qpos(), full.arm_qpos())
        np.testing.assert_array_equal(lean.eef_position(), full.eef_position())
        np.testing.assert_array_equal(lean.object_positions(), full.object_positions())
        assert (lean.suction.held, lean.collisions, lean_reward, lean_done) == (full.suction.held, full.collisions,
                                                                                  reward, done)
        assert lean_info.keys() == info.keys() and lean_obs.keys() == obs.keys()
        for key in info:
            np.testing.assert_array_equal(lean_info[key], info[key])
        for key in obs:
            np.testing.assert_array_equal(lean_obs[key], obs[key])
        held.add(full.suction.held)
    assert {-1, full.plan[0]} <= held  # the sequence gripped the misplaced cuboid and ran with the cup empty
    lean.step_observations = False
    assert lean.step(np.zeros(5))[0] is None  # no observation unless asked for


def test_the_contact_table_finds_the_collisions_the_rule_finds():
    """Driving the arm down into the table: at every physics substep the table-based scan adds exactly the events
    that judging every contact by the cell's rule (``forbidden_contact``; the scan before the table) names, in the
    same order."""
    env = ErrorCorrection(task="place", seed=0)
    env.reset()
    scan, checked = env._scan_contacts, []  # the scan and its per-step events are the cell's internals under test

    def scan_and_compare():
        expected = list(env._step_collisions)
        for a, b in env.sim.data._data.contact.geom.tolist():
            event = env.forbidden_contact(a, b, env.suction.held)
            if event is not None and event not in expected:
                expected.append(event)
        scan()
        assert env._step_collisions == expected
        checked.append(len(expected))

    env._scan_contacts = scan_and_compare
    for _ in range(40):
        env.step(np.array([0.0, 0.087, 0.0, 1.0]))  # shoulder down, suction requested
    assert len(checked) == 400 and max(checked) >= 2 and env.collisions


def test_the_public_contact_rule_scratch_state_and_success(pto):
    """The cell's rule as RRT-Connect applies it (``pick_target``: an empty cup may touch only the product it
    picks), a scratch state that poses the arm without touching the live simulation, and ``success``."""
    pto.reset()
    cup, product = min(pto.cup_geoms), min(pto.object_geoms(0))
    assert product in pto.object_geoms() and not pto.cup_geoms & (pto.arm_geoms | pto.mount_geoms)
    assert pto.forbidden_contact(cup, product, held=-1) is None  # the cell allows an empty cup on a product
    assert pto.forbidden_contact(cup, product, held=-1, pick_target=0) is None
    assert pto.forbidden_contact(product, cup, held=-1, pick_target=1).startswith("cup-product1: ")
    assert pto.forbidden_contact(cup, product, held=1).startswith("cup-product1: ")  # the cup holds another
    live = pto.sim.get_state().flatten()
    arm = pto.arm_qpos() + [0.3, -0.2, 0.1, 0.1, 0.0, 0.0]
    scratch = pto.scratch_state()
    data = scratch.set_arm_qpos(arm)
    np.testing.assert_allclose(data.site_xpos[pto.robots[0].eef_site_id["right"]], pto.lip_kinematics(arm)[0])
    np.testing.assert_array_equal(pto.sim.get_state().flatten(), live)
    assert pto.success() is False  # nothing packed yet
