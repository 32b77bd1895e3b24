"""Motion module (Ch.3/4): the variational loss on known inputs, network shapes, the base frame of the dynamic
planner, the jitter of r, and two-level rollouts of a few steps in the robot cells."""

from __future__ import annotations

import math

import lightning.pytorch as pl
import numpy as np
import pandas as pd
import pytest
import torch

from hrc_lab.env.robot.factory import make_env
from hrc_lab.env.robot.settings import ErrorCorrectionConfig, PackageToOrderConfig
from hrc_lab.motion.configs import STAGE_STARTS, ClassifierConfig, NDPConfig, SubgoalConfig
from hrc_lab.motion.networks import NeuralDynamicPlanner, TaskConditionedVI, variational_loss
from hrc_lab.motion.subgoal import DynamicPlanner, StageClassifier, base_frame, build_subgoal_planner, jitter_r
from hrc_lab.motion.two_level import (
    CAPPED,
    COLLISION,
    HORIZON,
    REACHED,
    Rollout,
    TwoLevelMotion,
    capped_share,
    classifier_pairs,
    correction_input,
    correction_pairs,
    correction_reference,
    dynamics_pairs,
    grasp_shift,
    package_pairs,
    picking_label,
    reach,
    run_correction,
    run_package,
)

HALF_LOG_2PI = 0.5 * math.log(2 * math.pi)


def test_kl_term_is_zero_at_the_prior_and_known_away_from_it():
    target = torch.zeros(4, 3)
    _, _, kl = variational_loss(torch.zeros(4, 3), torch.ones(4, 3), target, 1.0, 1.0)
    assert kl.item() == pytest.approx(0.0, abs=1e-6)
    # D_kl[N(1, 1) || N(0, 1)] = 0.5 per dimension; D_kl[N(0, e^-1) || N(0, 1)] = 0.5 (e^-2 - 1) + 1 per dimension
    _, _, kl = variational_loss(torch.ones(4, 3), torch.ones(4, 3), target, 1.0, 1.0)
    assert kl.item() == pytest.approx(1.5, rel=1e-5)
    _, _, kl = variational_loss(torch.zeros(2, 3), torch.full((2, 3), math.exp(-1)), torch.zeros(2, 3), 1.0, 1.0)
    assert kl.item() == pytest.approx(3 * (0.5 * (math.exp(-2) - 1) + 1), rel=1e-5)


def test_nll_term_is_the_gaussian_negative_log_likelihood_of_the_reparameterised_sample():
    mean, std, target, sigma = torch.tensor([[0.5, -1.0]]), torch.tensor([[0.2, 0.3]]), torch.tensor([[1.0, 0.0]]), 0.5
    torch.manual_seed(7)
    eps = torch.randn(1, 2)
    torch.manual_seed(7)
    loss, nll, kl = variational_loss(mean, std, target, sigma, kl_weight=0.1)
    z = mean + std * eps
    expected = (0.5 * ((target - z) / sigma) ** 2 + math.log(sigma) + HALF_LOG_2PI).sum()
    assert nll.item() == pytest.approx(expected.item(), rel=1e-5)
    assert loss.item() == pytest.approx(nll.item() + 0.1 * kl.item(), rel=1e-6)


def test_network_shapes_and_label_conditioning():
    x, labels = torch.randn(5, 6), torch.eye(4)[[0, 1, 2, 3, 0]]
    mean, std = TaskConditionedVI(6, 4, hidden=16)(x, labels)
    assert mean.shape == std.shape == (5, 3) and (std > 0).all()
    conditioned = TaskConditionedVI(6, 4, hidden=16)
    assert not torch.allclose(conditioned(x, labels)[0], conditioned(x, torch.eye(4)[[1, 2, 3, 0, 1]])[0])
    blind = TaskConditionedVI(6, 4, hidden=16, use_labels=False)
    assert torch.allclose(blind(x, labels)[0], blind(x, torch.zeros_like(labels))[0])
    mean, std = TaskConditionedVI(6, 4, hidden=16, stochastic=False)(x, labels)
    assert (std == 0).all()
    assert NeuralDynamicPlanner(hidden=16)(torch.randn(7, 3)).shape == (7, 3)
    assert NeuralDynamicPlanner(hidden=16, directions=True)(torch.randn(7, 3)).shape == (7, 3, 3)


def test_base_frame_splits_delta_into_radial_tangential_vertical():
    base = np.zeros(3)
    r = np.array([[0.0, 1.0, 0.5], [1.0, 0.0, 0.5]])
    delta = np.array([[0.0, 0.2, -0.1], [0.0, 0.3, 0.0]])
    np.testing.assert_allclose(base_frame(delta, r, base), [[0.2, 0.0, -0.1], [0.0, 0.3, 0.0]], atol=1e-12)


def test_jitter_moves_only_r_and_keeps_targets():
    x, labels, subgoals = np.arange(18.0).reshape(3, 6), np.array([0, 1, 2]), np.ones((3, 3))
    xs, ls, ss = jitter_r(x, labels, subgoals, std=0.01, copies=2, seed=0)
    assert xs.shape == (9, 6) and ls.tolist() == [0, 1, 2] * 3 and ss.shape == (9, 3)
    np.testing.assert_array_equal(xs[:, :3], np.tile(x[:, :3], (3, 1)))
    assert 0 < np.abs(xs[3:, 3:] - np.tile(x[:, 3:], (2, 1))).max() < 0.1
    assert jitter_r(x, labels, subgoals, 0.0, 2, 0)[0] is x


def tiny_trainer() -> pl.Trainer:
    return pl.Trainer(max_epochs=1, logger=False, enable_checkpointing=False, enable_progress_bar=False,
                      enable_model_summary=False)


def expert_demos(env, n: int, **segmentation):
    from hrc_lab.data.recording import record_episode
    from hrc_lab.data.segmentation import stage_subgoals
    from hrc_lab.env.robot.expert import ScriptedExpert

    expert, demos = ScriptedExpert(env), []
    for _ in range(n):
        demo = record_episode(env, expert)
        if segmentation:
            demo.stage_bounds, demo.stage_subgoals = stage_subgoals(demo, env.stage_label, **segmentation)
        demos.append(demo)
    return demos


@pytest.fixture(scope="module")
def package_models():
    env = make_env(PackageToOrderConfig(n_objects=3, n_selected=2), seed=0)
    demos = expert_demos(env, 2)
    pairs = package_pairs(demos)
    assert pairs.x.shape[1] == 6 and set(pairs.labels) <= {0, 1, 2}
    planner = build_subgoal_planner(SubgoalConfig(steps=20), 3).fit(pairs.x, pairs.labels, pairs.subgoals,
                                                                     tiny_trainer)
    config = NDPConfig(steps=20, hidden=16)
    ndp = DynamicPlanner(config, env.max_joint_step, env.base_position())
    ndp.fit(*dynamics_pairs(demos, config), tiny_trainer)
    return env, planner, ndp


def test_package_rollout_of_a_few_steps(package_models):
    env, planner, ndp = package_models
    out = run_package(env, TwoLevelMotion(planner, ndp, max_steps=2))
    assert 0 < out.steps <= 2 * 6 * len(env.expert_plan()) + len(env.expert_plan())
    assert out.planning_ms and all(ms > 0 for ms in out.planning_ms)
    assert out.failure in ("", "pick", "placement", "collision", "horizon")
    assert out.success == (out.failure == "")


def test_dynamic_planner_acts_within_the_joint_limit(package_models):
    env, _, ndp = package_models
    action = ndp.act(env.lip_target_position(), env.lip_target_position() + np.array([0.3, 0.0, -0.2]))
    assert action.shape == (3,) and np.all(np.abs(action) <= env.max_joint_step + 1e-9)


def test_correction_rollout_of_a_few_steps():
    env = make_env(ErrorCorrectionConfig(task="one_object"), seed=0)
    demos = expert_demos(env, 2, k=5, mode="resample")
    pairs = correction_pairs(demos)
    assert pairs.x.shape[1] == 12 and len(pairs.x) % 5 == 0
    classifier = StageClassifier(ClassifierConfig(hidden=16, steps=20), 4).fit(*classifier_pairs(demos), tiny_trainer)
    planner = build_subgoal_planner(SubgoalConfig(steps=20), 4).fit(pairs.x, pairs.labels, pairs.subgoals,
                                                                     tiny_trainer)
    config = NDPConfig(steps=20, hidden=16)
    ndp = DynamicPlanner(config, env.max_joint_step, env.base_position())
    ndp.fit(*dynamics_pairs(demos, config), tiny_trainer)
    for place_through_grasp in (False, True):
        out, final = run_correction(env, planner, ndp, classifier, n_subgoals=2, max_steps=2,
                                    place_through_grasp=place_through_grasp)
        assert out.steps > 0 and final.shape == (3, 3)
        assert out.failure in ("", "pick", "collision", "horizon")
        assert out.picks and set(out.picks) <= {1, 2}  # the object c(x) sent each picking stage to


def test_grasp_shift_moves_placing_subgoals_by_the_lips_horizontal_offset_from_the_held_part():
    """Placing red (label 3) with the lip 1 cm beside and 2 cm behind red's centre (and 2.5 cm above it): its
    sub-goals move by (1, -2, 0) cm, so the part lands where the planner put a centred grip's lip; picking (label
    2) moves nothing."""
    objects = np.array([[0.0, 0.0, 0.8], [0.1, 0.1, 0.8], [0.2, -0.2, 0.8]])
    lip = objects[2] + [0.01, -0.02, 0.025]
    assert np.allclose(grasp_shift(objects.ravel(), lip, 3), [0.01, -0.02, 0.0])
    assert np.allclose(grasp_shift(objects.ravel(), lip, 1), lip - objects[1] - [0, 0, lip[2] - objects[1][2]])
    assert np.allclose(grasp_shift(objects.ravel(), lip, 2), 0.0)


def test_path_targets_are_the_end_effector_later_in_the_same_stage():
    """``motion.ndp.targets=path``: s is the demonstrated end effector h steps after r's step, never across a stage
    change; with path_steps [1, 3] every step that has a same-stage successor h steps on gives one pair per h."""
    env = make_env(ErrorCorrectionConfig(task="one_object"), seed=0)
    demo = expert_demos(env, 1, k=2, mode="resample")[0]
    r, s, a = dynamics_pairs([demo], NDPConfig(targets="path", path_steps=[1, 3]))
    designed = dynamics_pairs([demo], NDPConfig())
    labels = demo.stage_labels
    expected = [t for h in (1, 3) for t in range(len(demo) - h) if labels[t] == labels[t + h]]
    assert len(r) == len(s) == len(a) == len(expected) and len(designed[0]) == len(demo)
    first = expected[0]  # h = 1
    np.testing.assert_allclose(s[0], demo.obs["robot0_eef_pos"][first + 1])
    np.testing.assert_allclose(r[0], demo.obs["lip_target_pos"][first])
    np.testing.assert_allclose(a[0], demo.actions[first, :3])
    # path_action=mean: the expert's mean step over the h steps from r to s (h = 3 pairs follow the h = 1 ones)
    r3, s3, mean = dynamics_pairs([demo], NDPConfig(targets="path", path_steps=[1, 3], path_action="mean"))
    np.testing.assert_allclose(r3, r)
    np.testing.assert_allclose(s3, s)
    np.testing.assert_allclose(mean[0], demo.actions[first, :3])  # h = 1: the one step
    threes = [t for t in range(len(demo) - 3) if labels[t] == labels[t + 3]]  # the h = 3 pairs, last in the list
    np.testing.assert_allclose(mean[len(expected) - len(threes)], demo.actions[threes[0]:threes[0] + 3, :3].mean(0))
    with pytest.raises(ValueError, match="motion.ndp.path_action"):
        NDPConfig(path_action="mean")  # designed waypoints have no h steps
    with pytest.raises(ValueError, match="motion.ndp.path_action"):
        NDPConfig(targets="path", path_action="sum")
    with pytest.raises(ValueError, match="motion.ndp.targets"):
        NDPConfig(targets="waypoints")
    with pytest.raises(ValueError, match="motion.ndp.path_steps"):
        NDPConfig(targets="path", path_steps=[0])


def test_ground_truth_stage_labels_go_for_the_experts_objects_in_order():
    """The diagnosis switch of Table 3.1: the expert's plan, not c(x), names each picking stage's object; a
    classifier that always answers 'pick red' cannot change that."""
    env = make_env(ErrorCorrectionConfig(task="two_object"), seed=0)  # case 1: blue first, then red
    demos = expert_demos(env, 2, k=2, mode="resample")
    pairs = correction_pairs(demos)
    planner = build_subgoal_planner(SubgoalConfig(steps=5), 4).fit(pairs.x, pairs.labels, pairs.subgoals, tiny_trainer)
    config = NDPConfig(steps=5, hidden=16)
    ndp = DynamicPlanner(config, env.max_joint_step, env.base_position())
    ndp.fit(*dynamics_pairs(demos, config), tiny_trainer)
    always_red = lambda x: np.full(len(x), 2)  # noqa: E731
    wrong, _ = run_correction(env, planner, ndp, always_red, n_subgoals=2, max_steps=2)
    right, _ = run_correction(env, planner, ndp, always_red, n_subgoals=2, max_steps=2, stage_labels="ground_truth")
    assert wrong.picks[0] == 2 and right.picks[0] == env.expert_plan()[0] == 1


def test_a_stage_start_that_looks_like_placing_blue_picks_by_the_rule():
    """c(x) says "placing blue" (label 1) where blue has just been placed; of the picking labels it ranks red's
    above blue's. The object of c(x)'s label sends the arm back to blue, its most likely picking label to red."""
    class JustPlacedBlue:
        def scores(self, x):
            return np.array([[0.5, 3.0, 1.0, 0.0]])

        def __call__(self, x):
            return self.scores(x).argmax(-1)

    x = np.zeros(12)
    assert picking_label(JustPlacedBlue(), x, "classifier") == 0
    assert picking_label(JustPlacedBlue(), x, "picking_classifier") == 2
    with pytest.raises(ValueError, match="picking label rule"):
        picking_label(JustPlacedBlue(), x, "ground_truth")


def test_the_selected_planner_input_keeps_the_labelled_object_green_and_r():
    objects, r = np.arange(9.0).reshape(3, 3), np.array([10.0, 11.0, 12.0])
    assert correction_input(objects, r, 1).tolist() == [*range(9), 10.0, 11.0, 12.0]  # full (3.3)
    np.testing.assert_array_equal(correction_input(objects, r, 2, "selected"), [6, 7, 8, 0, 1, 2, 10, 11, 12])
    np.testing.assert_array_equal(correction_input(objects, r, 1, "selected"), [3, 4, 5, 0, 1, 2, 10, 11, 12])
    with pytest.raises(ValueError, match="planner input must be one of"):
        correction_input(objects, r, 0, "relative")
    env = make_env(ErrorCorrectionConfig(task="one_object"), seed=0)
    assert correction_pairs(expert_demos(env, 1, k=2, mode="resample"), planner_input="selected").x.shape[1] == 9


@pytest.mark.parametrize("experiment,overrides", [
    ("ch4/table_4_2", ["env=package_to_order_2of3", "protocol.demos=3", "protocol.trials=2"]),
    ("ch3/table_3_1", ["protocol.demos=2", "protocol.trials=1", "protocol.max_steps_per_subgoal=3",
                        "protocol.placement_oracle=true"]),
])
def test_motion_experiment_end_to_end(experiment, overrides, run_job):
    tiny = ["hydra.mode=RUN", "trainer.max_epochs=1", "motion.steps=10", "motion.ndp.steps=10",
            "motion.classifier.steps=10"]
    job = run_job(f"experiment={experiment}", *tiny, *overrides)
    assert job.metrics["planning_ms"] > 0 and "(MLflow run " in job.log
    if experiment == "ch3/table_3_1":
        assert 0 <= job.metrics["stage1_right"] <= 1  # where c(x) sent the picking stages, logged per run
    assert job.run.data.metrics["planning_ms"] == pytest.approx(job.metrics["planning_ms"], nan_ok=True)


def test_label_per_subgoal_separates_sub_goals_that_share_an_observation():
    """Same observation and stage, different sub-goal index: only the per-sub-goal labels can tell them apart."""
    rng = np.random.default_rng(0)
    x = np.repeat(rng.normal(size=(8, 6)), 3, axis=0)
    labels, indices = np.zeros(24, dtype=int), np.tile(np.arange(3), 8)
    subgoals = np.stack([indices * 0.1, np.zeros(24), np.zeros(24)], axis=1)
    results = {}
    for per_subgoal in (False, True):
        config = SubgoalConfig(kind="mlp", steps=300, r_jitter_m=0.0, label_per_subgoal=per_subgoal)
        planner = build_subgoal_planner(config, 2, 3).fit(x, labels, subgoals, tiny_trainer, indices)
        results[per_subgoal] = np.abs(planner.predict(x, labels, indices)[0] - subgoals).max()
    assert results[True] < 0.02 < 0.05 < results[False]
    with pytest.raises(ValueError, match="label_per_subgoal"):
        planner.predict(x, labels)
    with pytest.raises(ValueError, match=r"\[0, 3\)"):
        planner.predict(x[:1], labels[:1], np.array([3]))


def test_gpr_kernel_ard_ignores_an_input_the_sub_goal_does_not_depend_on():
    """Sub-goals depend (non-linearly) on the object alone; at test r lies 6 training stds away. ARD length scales
    extrapolate over r, one isotropic length scale (the other reading of the thesis' "RBF kernel") is as short as
    the object needs and falls back to the mean."""
    rng = np.random.default_rng(0)
    objects = rng.uniform(-0.2, 0.2, (100, 3))
    r = 0.5 + rng.normal(0.0, 0.01, (100, 3))
    def subgoal(part):
        return 0.1 * np.sin(10 * part)

    subgoals = subgoal(objects)
    test_objects = rng.uniform(-0.15, 0.15, (10, 3))
    test_x = np.hstack([test_objects, np.full((10, 3), 0.56)])
    errors = {}
    for kernel in ("ard", "isotropic"):
        config = SubgoalConfig(kind="gpr", gpr_kernel=kernel, r_jitter_m=0.0)
        planner = build_subgoal_planner(config, 1).fit(np.hstack([objects, r]), np.zeros(100, dtype=int), subgoals)
        mean, _ = planner.predict(test_x, np.zeros(10, dtype=int))
        errors[kernel] = np.linalg.norm(mean - subgoal(test_objects), axis=1).max()
    assert errors["ard"] < 0.01 < 0.05 < errors["isotropic"]


def test_relative_to_r_feeds_every_position_minus_r(compose_config):
    from hrc_lab.config import validate_config

    rng = np.random.default_rng(0)
    part, green, r = rng.uniform(-0.2, 0.2, (4, 3)), rng.uniform(-0.2, 0.2, (4, 3)), rng.uniform(0, 1, (4, 3))
    relative = build_subgoal_planner(SubgoalConfig(relative_to_r=True), 1)
    assert np.allclose(relative._features(np.hstack([part, green, r])), np.hstack([part - r, green - r, r]))
    assert np.array_equal(build_subgoal_planner(SubgoalConfig(), 1)._features(np.hstack([part, r])),
                          np.hstack([part, r]))  # the default: absolute positions
    with pytest.raises(ValueError, match="relative_to_r needs x"):
        relative._features(np.zeros((1, 5)))
    cfg = compose_config("experiment=ch3/table_3_1", "motion.planner_input=selected", "motion.relative_to_r=true")
    assert validate_config(cfg).motion.relative_to_r


def test_relative_targets_make_a_pick_point_fixed_on_its_part_wherever_the_part_lies():
    """Sub-goals 2 cm above a part that lies anywhere; r far from every training r at test. In the world frame the
    regression must learn to copy the part's position from few examples; relative to the stage's reference the
    target is one point, and predictions come back in the world frame."""
    rng = np.random.default_rng(0)
    parts = rng.uniform(-0.3, 0.3, (12, 3))
    x = np.hstack([parts, rng.uniform(0.4, 0.6, (12, 3))])
    subgoals = parts + [0.0, 0.0, 0.02]
    test_parts = rng.uniform(-0.3, 0.3, (20, 3))
    test_x = np.hstack([test_parts, np.full((20, 3), 0.7)])
    errors = {}
    for relative in (False, True):
        config = SubgoalConfig(kind="mlp", steps=300, r_jitter_m=0.0, relative_targets=relative)
        planner = build_subgoal_planner(config, 1).fit(x, np.zeros(12, dtype=int), subgoals, tiny_trainer,
                                                       references=parts)
        mean, _ = planner.predict(test_x, np.zeros(20, dtype=int), references=test_parts)
        errors[relative] = np.linalg.norm(mean - test_parts - [0.0, 0.0, 0.02], axis=1).max()
    assert errors[True] < 0.005 < 0.02 < errors[False]
    with pytest.raises(ValueError, match="relative_targets needs"):
        planner.predict(test_x, np.zeros(20, dtype=int))
    with pytest.raises(ValueError, match=r"shape \(20, 3\)"):
        planner.predict(test_x, np.zeros(20, dtype=int), references=test_parts[:3])
    assert correction_reference(np.arange(9.0), 2).tolist() == [6.0, 7.0, 8.0]  # picking red: red
    assert correction_reference(np.arange(9.0), 3).tolist() == [0.0, 1.0, 2.0]  # placing red: green


def test_correction_pairs_start_each_stage_as_demonstrated_and_as_executed():
    """A picking stage (steps 0-3) then a placing stage (steps 4-8) of object 1 (blue), two sub-goals each."""
    from types import SimpleNamespace

    steps = np.arange(10, dtype=float)[:, None]
    objects = np.hstack([np.zeros((10, 3)), steps * [0, 0, 0.01] + [0.1, 0.2, 0.8], np.ones((10, 3))])
    lip = steps * [0.01, 0, 0] + [0, 0, 1.0]
    points = np.array([[[0, 0, 0.9], [0.1, 0.2, 0.82]], [[0.1, 0.3, 0.9], [0.1, 0.4, 0.82]]])
    demo = SimpleNamespace(obs={"object_pos": objects, "lip_target_pos": lip},
                           stage_bounds=np.array([[1, 0, 0, 4], [1, 1, 4, 9]]), stage_subgoals=points)
    executed = correction_pairs([demo], ("executed",))
    demonstrated = correction_pairs([demo], ("demonstrated",))
    both = correction_pairs([demo], STAGE_STARTS)
    assert len(both.x) == len(executed.x) + len(demonstrated.x) == 8
    assert list(executed.labels) == [0, 0, 1, 1] and list(executed.indices) == [0, 1, 0, 1]
    # placing, as executed: from the picking stage's last sub-goal, with the objects as they were before the lift
    np.testing.assert_allclose(executed.x[2, 9:], points[0, 1])
    np.testing.assert_allclose(executed.x[2, :9], objects[0])
    # placing, as demonstrated: the lip and the (lifted) objects at the detected change point
    np.testing.assert_allclose(demonstrated.x[2, 9:], lip[4])
    np.testing.assert_allclose(demonstrated.x[2, :9], objects[4])
    for pairs in (executed, demonstrated):  # within a stage, r is the previous sub-goal
        np.testing.assert_allclose(pairs.x[3, 9:], points[1, 0])
        np.testing.assert_allclose(pairs.subgoals, points.reshape(-1, 3))
    # the stage's reference: blue (object 1) where its picking stage began, then green (object 0) for placing
    np.testing.assert_allclose(executed.references, [objects[0, 3:6]] * 2 + [objects[0, :3]] * 2)
    with pytest.raises(ValueError, match="stage starts"):
        correction_pairs([demo], ("planned",))


class _LineEnv:
    """A lip that moves 1 cm along x per step; optionally a collision or the episode's end at a given step."""

    def __init__(self, collide_at: int | None = None, done_at: int | None = None) -> None:
        self.x, self.collide_at, self.done_at, self.collisions, self.done = 0.0, collide_at, done_at, [], False

    def eef_position(self):
        return np.array([self.x, 0.0, 0.0])

    lip_target_position = eef_position

    def step(self, action):
        self.x += 0.01
        steps = round(self.x / 0.01)
        self.collisions = ["arm-table"] if steps == self.collide_at else []
        self.done = steps == self.done_at


class _ZeroPlanner:
    def act(self, r, s):
        return np.zeros(3)


@pytest.mark.parametrize("env,goal,status,steps", [
    (_LineEnv(), 0.05, REACHED, 5),
    (_LineEnv(), 0.30, CAPPED, 10),  # 10 steps reach 0.10 m of 0.30: the cap, not a failure
    (_LineEnv(collide_at=3), 0.30, COLLISION, 3),
    (_LineEnv(done_at=4), 0.30, HORIZON, 4),
])
def test_reach_says_why_it_stopped(env, goal, status, steps):
    assert reach(env, _ZeroPlanner(), np.array([goal, 0.0, 0.0]), False, 10, 0.004) == (steps, status)


def test_rollouts_count_capped_subgoals():
    out = Rollout()
    for status in (REACHED, CAPPED, CAPPED, REACHED):
        out.count(7, status)
    assert (out.steps, out.subgoals, out.capped) == (28, 4, 2)
    trials = pd.DataFrame({"subgoals": [4, 6], "capped": [2, 1]})
    assert capped_share(trials) == 0.3
    assert math.isnan(capped_share(pd.DataFrame({"subgoals": [0], "capped": [0]})))


def test_correction_demos_records_until_n_are_kept(monkeypatch):
    """Every other episode fails (as action noise can make it): recording goes on until n are kept, and stops
    at MAX_ATTEMPTS_PER_DEMO * n when too few succeed."""
    from types import SimpleNamespace

    import hrc_lab.data.recording as recording
    import hrc_lab.data.segmentation as segmentation
    import hrc_lab.env.robot.expert as expert
    from hrc_lab.motion.demonstrations import MAX_ATTEMPTS_PER_DEMO, correction_demos

    def demos_with(success_every: int) -> tuple[int, int]:
        episodes = iter(range(1000))
        monkeypatch.setattr(recording, "record_episode", lambda env, *a: SimpleNamespace(
            success=next(episodes) % success_every == 0))
        kept = correction_demos(env, 5, subgoals_per_stage=5, segmentation_penalty=0.0, desc="test")
        return len(kept), next(episodes)  # kept, episodes recorded (the next episode's number)

    env = SimpleNamespace(stage_label=None, expert_plan=lambda: [1])
    monkeypatch.setattr(expert, "ScriptedExpert", lambda *a, **k: None)
    monkeypatch.setattr(segmentation, "stage_subgoals", lambda *a, **k: ([(0, 1), (1, 2)], []))
    assert demos_with(2) == (5, 9)  # episodes 0, 2, 4, 6, 8 kept: 9 recorded
    assert demos_with(100) == (1, MAX_ATTEMPTS_PER_DEMO * 5)
