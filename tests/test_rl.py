"""Reinforcement learning (thesis 3.2.3 Algorithm 1, 3.3, 3.4.3; the DRL baseline of Table 4.3): the goal env's
sparse reward (Eq. 3.6 / 4.7) on batches, HER relabelling, Algorithm 1's correction rule and guidance ratio, a few
guided and unguided DDPG + HER updates in the real error-correction cell, checkpoints, and the ``rl`` configs."""

from __future__ import annotations

import tempfile
from pathlib import Path

import lightning.pytorch as pl
import numpy as np
import pytest
import torch
from hydra import compose, initialize_config_dir
from hydra.core.global_hydra import GlobalHydra
from stable_baselines3.common.callbacks import CallbackList

from hrc_lab.env.robot.settings import ErrorCorrectionConfig, PackageToOrderConfig, SimSettings
from hrc_lab.motion.configs import ClassifierConfig, NDPConfig, SubgoalConfig
from hrc_lab.motion.subgoal import DynamicPlanner, StageClassifier, build_subgoal_planner
from hrc_lab.registry import ConfigError, named
from hrc_lab.rl import RLS
from hrc_lab.rl.agent import (
    EpisodeMetrics,
    EpisodeProgress,
    PhaseTimes,
    add_demonstrations,
    build_ddpg_her,
    build_guided_ddpg_her,
    ddpg_her_kwargs,
    evaluate,
    learn_episodes,
    load_agent,
    save_agent,
)
from hrc_lab.rl.buffers import FilledHerReplayBuffer
from hrc_lab.rl.configs import RLConfig
from hrc_lab.rl.goal_env import dense_reward, goal_differences, make_goal_env, sparse_reward
from hrc_lab.rl.guidance import CorrectionGuide, GuidedEnv, corrected_action, needs_correction
from hrc_lab.rl.normalization import CLIP, NormalizedCombinedExtractor, RunningNormalizer
from hrc_lab.rl.reach import ReachGoalEnv, make_reach_env


def correction_cell(**values) -> ErrorCorrectionConfig:
    """An error-correction env config as validation makes it (carrying its registry name)."""
    return named(ErrorCorrectionConfig(**values), "error_correction")


def package_cell(**values) -> PackageToOrderConfig:
    return named(PackageToOrderConfig(**values), "package_to_order")

CONF = Path(__file__).resolve().parents[1] / "conf"
STEPS = 8  # control steps per subtask in these tests (40 in the thesis)
# small networks and batches; two episodes of warm-up, then cycles of one episode and one gradient step per step
TINY = dict(steps_per_subtask=STEPS, learning_starts=2 * STEPS, batch_size=16, net_arch=[32, 32], buffer_size=2000,
            cycles_per_epoch=1, episodes_per_cycle=1, gradient_steps=STEPS, demo_batch_size=4, bc_pretrain_steps=8,
            critic_warmup_steps=2)


@pytest.fixture(scope="module", autouse=True)
def one_thread():
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.fixture(scope="module")
def env():
    """Two-object correction, case 1, first subtask (blue from red's place to its own): goal [x, y, z, yaw]."""
    return make_goal_env(correction_cell(task="two_object"), RLConfig(**TINY), seed=0, subtask=0)


def eq_3_6(achieved: np.ndarray, desired: np.ndarray, delta_r: float, dims: int) -> float:
    """Eq. 3.6 written out for one goal: 0 when every object's |P_obj - P_goal| is within delta_r, else -1."""
    for k in range(len(achieved) // dims):
        if np.sqrt(np.sum((achieved[k * dims:(k + 1) * dims] - desired[k * dims:(k + 1) * dims]) ** 2)) > delta_r:
            return -1.0
    return 0.0


class FarGuide:
    """A stub guide whose sub-goal lies 0.5 m beside the lip: every proposed action is corrected (by d = full
    base step, full negative shoulder step, suction on)."""

    def reset(self, env):
        self.target = env.lip() + np.array([0.5, 0.0, 0.0])

    def subgoal(self, env):
        return self.target

    def act(self, env, subgoal):
        return np.array([env.max_joint_step, -env.max_joint_step, 0.0]), 1.0


# --- the goal env ----------------------------------------------------------------------------------------------------


def test_compute_reward_is_eq_3_6_on_batches_and_single_goals(env):
    rng = np.random.default_rng(0)
    desired = rng.uniform(-1, 1, (64, 8))  # two objects, [x, y, z, yaw] each
    offsets = rng.normal(size=(64, 2, 4))
    offsets /= np.linalg.norm(offsets, axis=-1, keepdims=True)
    distances = rng.choice([0.0, 0.5, 0.99, 1.01, 3.0], (64, 2)) * env.delta_r  # in and out of delta_r
    achieved = desired + (offsets * distances[..., None]).reshape(64, 8)
    expected = [eq_3_6(a, d, env.delta_r, 4) for a, d in zip(achieved, desired)]
    batch = sparse_reward(achieved, desired, env.delta_r, 4)
    assert batch.shape == (64,) and batch.dtype == np.float32
    np.testing.assert_array_equal(batch, expected)
    assert {0.0, -1.0} <= set(batch.tolist())
    single = env.compute_reward(achieved[0, :4], desired[0, :4], {})
    assert single.shape == () and float(single) == eq_3_6(achieved[0, :4], desired[0, :4], env.delta_r, 4)
    # a batch of batches (HER samples come as (batch, dim); vectorised envs add a leading axis)
    np.testing.assert_array_equal(env.compute_reward(achieved[:, :4].reshape(8, 8, 4), desired[:, :4].reshape(8, 8, 4),
                                                     {}), sparse_reward(achieved[:, :4], desired[:, :4],
                                                                        env.delta_r, 4).reshape(8, 8))


def test_with_collision_fails_a_transition_after_a_collision_earns_minus_one(env):
    """rl.collision_fails: HER's relabelled rewards read each transition's info (so the buffer keeps the infos)."""
    goals = np.zeros((3, 4), dtype=np.float32)
    infos = [{"collided": True}, {"collided": False}, {}]
    np.testing.assert_array_equal(env.compute_reward(goals, goals, infos), [0.0, 0.0, 0.0])  # Eq. 3.6: off
    env.collision_fails = True
    try:
        np.testing.assert_array_equal(env.compute_reward(goals, goals, infos), [-1.0, 0.0, 0.0])
        assert float(env.compute_reward(goals[0], goals[0], {"collided": True})) == -1.0
    finally:
        env.collision_fails = False
    assert ddpg_her_kwargs(RLConfig(**TINY, collision_fails=True), env, 0)["replay_buffer_kwargs"]["copy_info_dict"]
    assert not ddpg_her_kwargs(RLConfig(**TINY), env, 0)["replay_buffer_kwargs"]["copy_info_dict"]


def test_dense_reward_is_minus_the_summed_distances_and_success_stays_eq_3_6(env):
    """rl.reward=dense (Fig. 3.12's text): R = -sum_k |P_obj - P_goal|, yaw wrapped as Eq. 3.6's; a collided
    transition under rl.collision_fails earns at most -1; is_success is still Eq. 3.6's criterion."""
    rng = np.random.default_rng(1)
    desired = rng.uniform(-1, 1, (16, 8))
    achieved = desired + rng.normal(scale=0.05, size=(16, 8))
    achieved[:, 3] = desired[:, 3] + np.pi / 2  # a quarter turn of a square part: no yaw error
    orders = np.array([4, 4])
    expected = -np.linalg.norm(goal_differences(achieved, desired, 4, orders), axis=-1).sum(axis=-1)
    np.testing.assert_allclose(dense_reward(achieved, desired, 4, orders), expected, rtol=1e-6)
    assert np.linalg.norm(goal_differences(achieved, desired, 4, orders)[:, 0, 3]) < 1e-9
    env.dense = True
    try:
        goals = np.zeros((2, 4), dtype=np.float32)
        far = goals + np.array([0.3, 0.0, 0.0, 0.0], dtype=np.float32)
        np.testing.assert_allclose(env.compute_reward(far, goals, {}), [-0.3, -0.3], rtol=1e-6)
        env.collision_fails = True
        np.testing.assert_allclose(env.compute_reward(far, goals, [{"collided": True}, {}]), [-1.0, -0.3], rtol=1e-6)
        env.collision_fails = False
        obs, _ = env.reset(seed=3)
        obs, reward, _, _, info = env.step(np.zeros(4))
        assert reward == pytest.approx(-env.goal_distances()[0], rel=1e-5) and info["is_success"] is False
        env.cell.set_object_pose(1, env.cell.goals[1])  # blue at its goal: Eq. 3.6's success, R near 0
        env.cell.sim.forward()
        obs, reward, _, _, info = env.step(np.zeros(4))
        assert info["is_success"] is True and -env.delta_r < reward < 0
    finally:
        env.dense, env.collision_fails = False, False
    with pytest.raises(ValueError, match="rl.reward must be one of"):
        RLConfig(reward="shaped")


def test_goal_env_goal_is_the_labelled_objects_pose_and_the_step_reward_agrees(env):
    obs, _ = env.reset(seed=3)
    cell = env.cell
    assert env.goal_objects == [cell.expert_plan()[0]] == [1]  # case 1: blue is corrected first
    np.testing.assert_allclose(obs["desired_goal"], [*cell.goals[1], 0.0], atol=1e-6)
    np.testing.assert_allclose(obs["achieved_goal"][:3], cell.object_positions()[1], atol=1e-6)
    assert obs["observation"].shape == env.observation_space["observation"].shape == (6 + 3 + 4 + 3 * 4 + 1,)
    obs, reward, terminated, truncated, info = env.step(np.zeros(4))
    assert reward == env.compute_reward(obs["achieved_goal"], obs["desired_goal"], {}) == -1.0
    assert not terminated and not truncated and info["is_success"] is False and info["collided"] is False
    cell.set_object_pose(1, cell.goals[1])  # blue at its goal: R = 0
    cell.sim.forward()
    obs, reward, *_ = env.step(np.zeros(4))
    assert reward == 0.0 and env.goal_distances()[0] < env.delta_r
    # the seeded scene repeats; the second subtask starts with blue at its goal and asks for red
    first, _ = env.reset(seed=3)
    np.testing.assert_array_equal(first["desired_goal"], env.reset(seed=3)[0]["desired_goal"])
    second = make_goal_env(correction_cell(task="two_object"), RLConfig(**TINY), seed=0, subtask=1)
    second.reset(seed=3)
    assert second.goal_objects == [2] and second.cell.object_positions()[1] == pytest.approx(second.cell.goals[1])
    with pytest.raises(ValueError, match="subtask must be in"):
        make_goal_env(correction_cell(task="one_object"), RLConfig(**TINY), subtask=1)


def test_package_goal_is_every_product_with_the_selected_ones_in_their_slots():
    config = package_cell(n_objects=3, n_selected=2, sim=SimSettings(horizon=200))
    goal_env = make_goal_env(config, RLConfig(**TINY), seed=0)
    obs, _ = goal_env.reset(seed=1)
    cell = goal_env.cell
    assert goal_env.horizon == 2 * STEPS and obs["desired_goal"].shape == (9,)
    selected = cell.episode.goal_slot >= 0
    goals = obs["desired_goal"].reshape(3, 3)
    np.testing.assert_allclose(goals[~selected], cell.object_positions()[~selected], atol=1e-5)  # the rest stay
    np.testing.assert_allclose(goals[selected], cell.episode.packed_positions[selected], atol=1e-5)
    assert goal_env.compute_reward(obs["achieved_goal"], obs["desired_goal"], {}) == -1.0
    with pytest.raises(ValueError, match="n_missing"):
        make_goal_env(package_cell(n_objects=3, n_selected=2, sim=SimSettings(n_missing=1)), RLConfig())


# --- DDPG + HER ----------------------------------------------------------------------------------------------------


def test_unguided_ddpg_her_updates_and_relabels_with_eq_3_6(env):
    agent = build_ddpg_her(RLConfig(**TINY), env, seed=0)
    before = [p.detach().clone() for p in agent.actor.parameters()]
    timer, progress = PhaseTimes(), EpisodeProgress(4, "test")
    learn_episodes(agent, 4, CallbackList([timer, progress]))
    assert timer.collect_s > 0 and timer.train_s > 0 and progress.bar.n == 4
    assert agent.num_timesteps == 4 * STEPS and agent._n_updates == 2 * STEPS  # trained after episodes 3 and 4
    assert any(not torch.equal(a, b) for a, b in zip(before, agent.actor.parameters()))
    buffer = agent.replay_buffer
    assert buffer.size() == 4 * STEPS
    batch = buffer.sample(256)
    desired = batch.observations["desired_goal"].numpy()
    recomputed = env.compute_reward(batch.next_observations["achieved_goal"].numpy(), desired, {})
    np.testing.assert_array_equal(batch.rewards.numpy().ravel(), recomputed)
    # with n_sampled_goal=4, 80 % of the goals are relabelled to achieved goals of the same episode
    stored = buffer.next_observations["achieved_goal"][: buffer.size(), 0]
    original = buffer.observations["desired_goal"][: buffer.size(), 0]
    relabelled = ~np.any(np.all(desired[:, None] == original[None], axis=-1), axis=1)
    assert 0.5 < relabelled.mean() < 1.0
    assert np.all(np.any(np.all(desired[relabelled][:, None] == stored[None], axis=-1), axis=1))
    assert set(np.unique(recomputed)) == {0.0, -1.0}  # random motions leave blue in place: its pose is reached


def test_filled_buffer_samples_only_stored_transitions_of_finished_episodes(env):
    agent = build_ddpg_her(RLConfig(**{**TINY, "buffer_size": 50_000}), env, seed=0)
    learn_episodes(agent, 2)
    buffer = agent.replay_buffer
    assert isinstance(buffer, FilledHerReplayBuffer) and buffer.size() == 2 * STEPS
    batch = buffer.sample(512)
    stored = buffer.observations["observation"][: buffer.size(), 0]
    sampled = batch.observations["observation"].numpy()
    assert np.all(np.any(np.all(sampled[:, None] == stored[None], axis=-1), axis=1))
    rows = {tuple(r) for r in sampled}
    assert len(rows) > STEPS  # spread over both episodes, not one row


def _filled_agent(env, **values):
    """A DDPG + HER agent past its warm-up, with two episodes of random actions in its buffer."""
    agent = build_ddpg_her(RLConfig(**{**TINY, **values}), env, seed=0)
    learn_episodes(agent, 2)
    agent.learning_starts = 0
    return agent


def test_her_paper_random_actions_replace_the_noisy_policy_in_a_random_eps_share_of_steps(env):
    obs = {k: v[None] for k, v in env.reset(seed=3)[0].items()}
    for random_eps, expected in ((0.0, 0.0), (0.3, 0.3), (1.0, 1.0)):
        agent = _filled_agent(env, random_eps=random_eps, action_noise_std=0.01)
        agent._last_obs = obs
        policy = agent.policy.scale_action(agent.predict(obs, deterministic=True)[0])
        draws = np.array([agent._sample_action(0, agent.action_noise)[1][0] for _ in range(400)])
        random = np.any(np.abs(draws - policy) > 0.05, axis=1)  # farther than the noise from the policy's action
        assert abs(random.mean() - expected) < 0.08, (random_eps, random.mean())
        if random_eps == 1.0:  # uniform on [-1, 1]: mean 0, std 1 / sqrt(3)
            assert np.all(np.abs(draws.mean(0)) < 0.1) and np.all(np.abs(draws.std(0) - 3 ** -0.5) < 0.06)


def test_guided_episodes_without_exploration_act_with_the_current_policy(env):
    """rl.guided_exploration=false (Algorithm 1's guided branch: "Select action a_t according to current policy"):
    in a guided episode the sampled action is the policy's own, without Gaussian noise or random actions; the
    unguided episodes (and every episode with the default) still explore."""
    obs = {k: v[None] for k, v in env.reset(seed=3)[0].items()}
    for lam, exploration, noiseless in ((1.0, False, True), (0.0, False, False), (1.0, True, False)):
        cfg = RLConfig(**{**TINY, "guidance": "ndp", "guided_exploration": exploration, "random_eps": 0.3})
        agent = build_guided_ddpg_her(cfg, GuidedEnv(env, FarGuide(), lam, cfg.delta_g, seed=0), seed=0)
        learn_episodes(agent, 2)
        agent.learning_starts, agent._last_obs = 0, obs
        policy = agent.policy.scale_action(agent.predict(obs, deterministic=True)[0])
        draws = np.array([agent._sample_action(0, agent.action_noise)[1][0] for _ in range(50)])
        assert np.allclose(draws, policy, atol=1e-6) == noiseless, (lam, exploration)
    # which episodes are guided comes from the reset infos, without a call into the env (its process)
    cfg = RLConfig(**{**TINY, "guidance": "ndp", "guided_exploration": False})
    agent = build_guided_ddpg_her(cfg, GuidedEnv(env, FarGuide(), 0.5, cfg.delta_g, seed=0), seed=0)
    flags = []
    for episodes in range(1, 9):
        learn_episodes(agent, episodes)  # episodes in all
        flags.append(bool(agent._noiseless_envs(1)[0]))
        assert flags[-1] == agent.env.get_attr("guided")[0]
    assert 0 < sum(flags) < len(flags)
    with pytest.raises(ValueError, match="rl.guided_exploration=false needs guided episodes"):
        RLConfig(guided_exploration=False)


def test_her_paper_action_penalty_pulls_the_actor_towards_zero_where_the_critic_is_flat(env):
    sizes = {}
    for action_l2 in (0.0, 1.0):
        # without input normalisation, whose running statistics would move the actor's outputs by themselves
        agent = _filled_agent(env, action_l2=action_l2, learning_rate=1e-2, normalize_inputs=False)
        agent.critic.q1_forward = lambda obs, actions: 0.0 * actions.sum(dim=1, keepdim=True)  # a flat critic
        batch = agent.replay_buffer.sample(64).observations
        before = agent.actor(batch).detach()
        agent.train(gradient_steps=50, batch_size=64)
        sizes[action_l2] = (before.abs().mean().item(), agent.actor(batch).detach().abs().mean().item())
    assert sizes[0.0][0] == pytest.approx(sizes[0.0][1])  # no penalty, a flat critic: the actor does not move
    assert sizes[1.0][1] < 0.5 * sizes[1.0][0]


def test_her_paper_clipped_targets_keep_the_critic_within_the_returns_of_sparse_rewards(env):
    means = {}
    for clip_return in (False, True):
        agent = _filled_agent(env, clip_return=clip_return, learning_rate=1e-2)
        agent.critic_target.forward = lambda obs, actions: (torch.full((len(actions), 1), 1000.0),)  # wild targets
        agent.train(gradient_steps=100, batch_size=64)
        batch = agent.replay_buffer.sample(64)
        means[clip_return] = agent.critic(batch.observations, batch.actions)[0].mean().item()
    assert means[False] > 100  # chases r + 0.98 * 1000
    assert -1 / (1 - 0.98) - 1 < means[True] < 1  # within [-1 / (1 - gamma), 0], up to the fit


def test_demonstrations_fill_the_demo_buffer_with_whole_relabelled_episodes():
    """Table 4.3's DRL learns from the scripted expert's episodes too: full-horizon episodes in HER's demonstration
    buffer, whose relabelled rewards are Eq. 4.7's; the package cell's expert packs a 2of3 order within 50 steps per
    product. Every batch then holds demo_batch_size of them, and the normaliser has seen them."""
    env = make_goal_env(package_cell(n_objects=3, n_selected=2), RLConfig(**{**TINY, "steps_per_subtask": 50}),
                        seed=0, cases=(1, 2))
    agent = build_ddpg_her(RLConfig(**{**TINY, "steps_per_subtask": 50}), env, seed=0)
    assert add_demonstrations(agent, env, 2, seed=1) == 1.0
    assert env.moved() > 0.1  # the exploration diagnostic sees the packed products leave their starts
    buffer = agent.demo_buffer
    assert agent.replay_buffer.size() == 0  # demonstrations are not the agent's own steps
    assert buffer.size() == 2 * env.horizon and buffer.ep_length[: buffer.size(), 0].tolist() == [env.horizon] * 200
    batch = buffer.sample(64)
    recomputed = env.compute_reward(batch.next_observations["achieved_goal"].numpy(),
                                    batch.observations["desired_goal"].numpy(), {})
    np.testing.assert_array_equal(batch.rewards.numpy().ravel(), recomputed)
    assert agent.num_timesteps == 0
    assert agent.actor.features_extractor.normalizers["observation"].running_count == 2 * env.horizon
    learn_episodes(agent, 3)
    data, n_demo = agent._sample(16)
    assert n_demo == 4 and len(data.actions) == 16


def test_a_later_subtasks_demonstrations_move_its_own_object():
    """In subtask 1 of the two-object correction the first object starts at its goal: the expert moves the second
    one only (it used to run the whole plan from the first object and never reached the second: 0 of 50 succeeded)."""
    rl = RLConfig(**{**TINY, "steps_per_subtask": 40, "suction": "auto", "delta_r": 0.01})
    env = make_goal_env(correction_cell(task="two_object", sim=SimSettings(yaw_action=True)), rl, seed=20_000,
                        subtask=1)
    agent = build_ddpg_her(rl, env, seed=0)
    assert add_demonstrations(agent, env, 2) >= 0.5  # the fig_3_13 config: 9 of 10 (2026-12-03)
    assert env.goal_objects == [env.cell.expert_plan()[1]]


def test_demonstrations_are_cloned_then_the_critic_warms_up_before_the_actor_follows_it(env):
    cfg = RLConfig(**{**TINY, "bc_pretrain_steps": 40, "critic_warmup_steps": 5}, learning_rate=1e-2)
    agent = build_ddpg_her(cfg, env, seed=0)
    add_demonstrations(agent, env, 1, seed=1)
    learn_episodes(agent, 2)  # the warm-up of random actions: no update yet
    batch = agent.demo_buffer.sample(64)

    def cloning_error() -> float:
        return (agent.actor(batch.observations) - batch.actions).pow(2).sum(1).mean().item()

    untrained = cloning_error()
    critic = [p.detach().clone() for p in agent.critic.parameters()]
    agent.train(gradient_steps=5, batch_size=16)  # cloning, then 5 critic-only steps
    assert cloning_error() < 0.5 * untrained and agent.critic_warmup_until == 5
    # the target actor copied the cloned actor, and neither moved in the warm-up (polyak of equal tensors)
    assert all(torch.allclose(a, b) for a, b in zip(agent.actor.parameters(), agent.actor_target.parameters()))
    assert any(not torch.equal(a, b) for a, b in zip(critic, agent.critic.parameters()))
    agent.train(gradient_steps=2, batch_size=16)  # past the warm-up: the actor learns (and is not cloned again)
    assert not all(torch.allclose(a, b) for a, b in zip(agent.actor.parameters(), agent.actor_target.parameters()))


def test_auto_suction_acts_with_the_joints_only_and_grips_what_the_cup_touches():
    """rl.suction=auto, 3.3's action [q'_base, q'_shoulder, q'_elbow, q'_wrist3]: no suction dimension; the cup is
    on in every step, grips the part under it and, with rl.release=never, keeps it; the scripted demonstrations
    (which release) refuse."""
    cfg = RLConfig(**TINY, suction="auto", release="never")
    auto = make_goal_env(correction_cell(task="one_object", sim=SimSettings(horizon=400, yaw_action=True)), cfg, seed=0,
                         subtask=0)
    assert auto.action_space.shape == (4,) and not auto.suction_action
    # rl.wrist3=relative: a wrist-3 action of 0 sends the yaw-holding delta (the base's)
    np.testing.assert_allclose(auto.to_cell_action(np.array([1.0, -1.0, 0.5, 0.0])),
                               [auto.max_joint_step, -auto.max_joint_step, 0.5 * auto.max_joint_step,
                                auto.max_joint_step, 1.0])
    auto.reset(seed=3)
    cell, part = auto.cell, auto.goal_objects[0]
    assert cell.grip_offset() is None  # nothing in the cup
    from hrc_lab.env.robot.expert import ScriptedExpert

    expert = ScriptedExpert(cell)  # the expert's joint motion, with its suction command dropped
    held_at = None
    for t in range(cfg.steps_per_subtask * 6):
        step = expert.act()
        if step is None:
            break
        auto.step(auto.from_cell_action(step.action))
        if cell.suction.held == part and held_at is None:
            held_at = t
    assert held_at is not None and cell.suction.held == part  # gripped on touch and never released
    offset = cell.grip_offset()  # the lip against the held part's centre: on its top face, near the centre
    np.testing.assert_allclose(offset, cell.eef_position() - cell.object_positions()[part])
    assert np.linalg.norm(offset[:2]) < 0.01 and 0.0 < offset[2] < 0.05
    with pytest.raises(ValueError, match="rl.suction=action"):
        add_demonstrations(build_ddpg_her(cfg, auto, seed=0), auto, 1)
    auto.close()


def test_the_expert_delivers_the_part_at_its_goal_yaw_within_rl_delta_r():
    """With 3.3's wrist-3 action, the expert turns wrist 3 with the base, so the held part keeps its yaw and
    Eq. 3.6 over [x, y, z, psi] is met at delta_r = 0.01 (3.4.3). Without the wrist-3 rule the part arrived turned
    by the base's travel (0.56-1.08 rad over 10 scenes) and no demonstration reached the goal."""
    from hrc_lab.env.robot.expert import ScriptedExpert

    cfg = RLConfig(steps_per_subtask=40, delta_r=0.01)
    env = make_goal_env(correction_cell(task="one_object", sim=SimSettings(horizon=400, yaw_action=True)), cfg,
                        seed=0, subtask=0)
    for seed in (0, 1):
        env.reset(seed=seed)
        expert, info, truncated = ScriptedExpert(env.cell), {}, False
        while not truncated:
            step = expert.act()
            action = np.zeros(env.action_space.shape) if step is None else env.from_cell_action(step.action)
            if step is None:
                action[-1] = -1.0
            _, _, _, truncated, info = env.step(action)
        assert abs(env.cell.object_yaws()[env.goal_objects[0]]) < 0.005
        assert info["is_success"], info["goal_distances"]
    env.close()


# --- Algorithm 1 ---------------------------------------------------------------------------------------------------


def test_correction_rule_on_hand_made_states():
    subgoal = np.array([0.3, 0.1, 1.0])
    assert not needs_correction(subgoal + [0.0, 0.03, 0.0399], subgoal, 0.05)  # |.| = 0.04992: kept
    assert not needs_correction(subgoal + [0.02, -0.02, 0.0], subgoal, 0.05)
    assert needs_correction(subgoal + [0.0, 0.03, 0.0401], subgoal, 0.05)  # |.| = 0.05008: corrected
    assert needs_correction(subgoal + [0.2, 0.0, 0.0], subgoal, 0.05)
    assert not needs_correction(subgoal + [0.2, 0.0, 0.0], subgoal, 0.25)
    # the executed action: the planner's joint deltas (clipped to [-1, 1]) and suction; without a guide's wrist-3
    # delta, wrist 3 stays the policy's
    action = np.array([0.1, 0.2, 0.3, 0.4, -0.5])
    np.testing.assert_allclose(corrected_action(action, np.array([0.5, -1.5, 0.0]), 1.0), [0.5, -1.0, 0.0, 0.4, 1.0])
    np.testing.assert_allclose(action, [0.1, 0.2, 0.3, 0.4, -0.5])  # not modified in place
    # rl.suction=auto: no suction dimension; with a wrist-3 delta from the guide (clipped), it replaces the policy's
    np.testing.assert_allclose(corrected_action(action[:4], np.array([0.5, -1.5, 0.0]), None), [0.5, -1.0, 0.0, 0.4])
    np.testing.assert_allclose(corrected_action(action[:4], np.array([0.5, -1.5, 0.0]), None, wrist3=1.5),
                               [0.5, -1.0, 0.0, 1.0])
    np.testing.assert_allclose(corrected_action(action, np.array([0.5, 0.0, 0.0]), -1.0, wrist3=0.5),
                               [0.5, 0.0, 0.0, 0.5, -1.0])


@pytest.mark.parametrize("lam", [1.0, 0.0])
def test_lambda_one_corrects_every_episode_and_zero_never(env, lam):
    cfg = RLConfig(**TINY, guidance="ndp", lam=lam)
    guided = GuidedEnv(env, FarGuide(), lam, cfg.delta_g, seed=0)
    agent = build_guided_ddpg_her(cfg, guided, seed=0)
    logged = []
    learn_episodes(agent, 3, EpisodeMetrics(lambda metrics, step: logged.append(metrics), every=3))
    assert logged[0]["train_guidance_rate"] == lam
    stored = agent.replay_buffer.actions[: agent.replay_buffer.size(), 0]
    if lam == 1.0:  # the buffer stores the executed (corrected) action
        np.testing.assert_allclose(stored[:, :3], np.tile([1.0, -1.0, 0.0], (3 * STEPS, 1)))
        np.testing.assert_allclose(stored[:, 3], 1.0)
    else:
        assert not np.allclose(stored[:, :3], np.tile([1.0, -1.0, 0.0], (3 * STEPS, 1)))


def test_guided_episodes_as_demonstrations_enter_the_demo_buffer_whole(env):
    cfg = RLConfig(**TINY, guidance="ndp", lam=1.0, guided_episodes="demos")
    agent = build_guided_ddpg_her(cfg, GuidedEnv(env, FarGuide(), 1.0, cfg.delta_g, seed=0), seed=0)
    learn_episodes(agent, 3)
    assert agent.demo_buffer.size() == 3 * STEPS and agent.replay_buffer.size() == 3 * STEPS
    np.testing.assert_allclose(agent.demo_buffer.actions[: 3 * STEPS, 0], agent.replay_buffer.actions[: 3 * STEPS, 0])
    assert agent.demo_buffer.ep_length[: 3 * STEPS, 0].tolist() == [STEPS] * (3 * STEPS)


@pytest.fixture(scope="module")
def two_level_guide(env):
    """The real classifier, sub-goal planner and dynamic planner of hrc_lab.motion, fitted for a few steps on
    made-up pairs whose sub-goals lie ~0.3 m from the arm's start (so the guide corrects)."""
    rng = np.random.default_rng(0)
    cell = env.cell
    trainer = lambda: pl.Trainer(max_epochs=1, logger=False, enable_checkpointing=False,  # noqa: E731
                                 enable_progress_bar=False, enable_model_summary=False)
    x = np.hstack([np.tile(cell.object_positions().ravel(), (64, 1)), cell.eef_position() + rng.normal(0, 0.05,
                                                                                                          (64, 3))])
    labels = rng.integers(0, 4, 64)
    classifier = StageClassifier(ClassifierConfig(hidden=16, steps=5), 4).fit(x, labels, trainer)
    subgoals = cell.eef_position() + [0.3, 0.0, 0.1] + rng.normal(0, 0.02, (64, 3))
    planner = build_subgoal_planner(SubgoalConfig(kind="mlp", steps=5, hidden=16), 4).fit(x, labels, subgoals,
                                                                                           trainer)
    r = x[:, 9:]
    ndp = DynamicPlanner(NDPConfig(steps=5, hidden=16), cell.max_joint_step, cell.base_position())
    ndp.fit(r, subgoals, rng.uniform(-1, 1, (64, 3)) * cell.max_joint_step, trainer)
    return CorrectionGuide.from_config(RLConfig(**TINY, subgoal_steps=3), classifier, planner, ndp, n_subgoals=2)


def test_guided_ddpg_her_with_the_two_level_planner_runs_updates_in_the_cell(env, two_level_guide):
    guided = GuidedEnv(env, two_level_guide, 1.0, 0.05, seed=0)
    agent = build_guided_ddpg_her(RLConfig(**TINY, guidance="ndp", lam=1.0), guided, seed=0)
    logged = []
    learn_episodes(agent, 3, EpisodeMetrics(lambda metrics, step: logged.append((step, metrics)), every=2))
    assert [step for step, _ in logged] == [2] and set(logged[0][1]) == {
        "train_success_rate", "train_collision_rate", "train_grip_rate", "train_moved_rate", "train_final_distance",
        "train_guidance_rate"}
    assert logged[0][1]["train_final_distance"] > 0 and 0 < logged[0][1]["train_guidance_rate"] <= 1
    assert agent._n_updates == STEPS
    assert two_level_guide.object in (1, 2) and two_level_guide.index in (0, 1)


def test_the_guides_picking_rule_names_its_object(env, two_level_guide):
    """``rl.stage_labels``: c(x_1) by its rule, or the object whose goal the episode trains (``ground_truth``),
    whatever c(x_1) says."""
    env.reset(seed=0)
    place_red = lambda x: np.full(len(x), 3)  # noqa: E731  (c(x) says "place red": the rule picks red)
    guide = two_level_guide
    rules = {}
    for rule in ("classifier", "ground_truth"):
        named = CorrectionGuide(place_red, guide.planner, guide.ndp, 2, 3, stage_labels=rule)
        named.reset(env)
        rules[rule] = (named.label, named.object)
    assert env.goal_objects == [1]  # subtask 0 of case 1: blue
    assert rules == {"classifier": (2, 2), "ground_truth": (0, 1)}


def test_the_guides_placing_subgoal_moves_by_the_grips_offset_with_place_through_grasp(env, two_level_guide):
    """``motion.place_through_grasp``: a placing sub-goal is the planner's plus the lip's horizontal offset from
    the part as the cup took it (here blue, marked held with the arm at home); picking sub-goals and the flag's
    default are unchanged."""
    import copy
    import dataclasses

    from hrc_lab.env.robot.cell import PICK, PLACE
    from hrc_lab.motion.two_level import grasp_shift

    env.reset(seed=0)
    planner = copy.copy(two_level_guide.planner)
    planner.config = dataclasses.replace(planner.config, place_through_grasp=True)
    subgoals = {}
    for name, p in (("plain", two_level_guide.planner), ("shifted", planner)):
        guide = CorrectionGuide(two_level_guide.classifier, p, two_level_guide.ndp, 2, 3, stage_labels="ground_truth")
        guide.reset(env)
        subgoals[name, PICK] = guide.subgoal(env).copy()
        env.cell.suction.held = 1  # the cup holds blue: the placing stage starts
        subgoals[name, PLACE] = guide.subgoal(env).copy()
        env.cell.suction.held = -1
        assert guide.stage == PLACE
    cell = env.cell
    shift = grasp_shift(cell.object_positions(), cell.eef_position(), 1)
    assert np.linalg.norm(shift[:2]) > 0.01 and shift[2] == 0.0  # the arm at home, far from blue
    assert np.allclose(subgoals["shifted", PICK], subgoals["plain", PICK])
    assert np.allclose(subgoals["shifted", PLACE] - subgoals["plain", PLACE], shift)


def test_checkpoint_round_trip_resumes_training(env, tmp_path, monkeypatch):
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))  # SB3's default logger would write here
    (tmp_path / "tmp").mkdir()
    cfg = RLConfig(**TINY, guidance="ndp", lam=0.5, guided_episodes="demos")
    guided = GuidedEnv(env, FarGuide(), 0.5, cfg.delta_g, seed=0)
    agent = build_guided_ddpg_her(cfg, guided, seed=0)
    learn_episodes(agent, 3)
    files = save_agent(agent, tmp_path / "ckpt")
    assert [f.name for f in files] == ["agent.zip", "demo_buffer.pkl.gz", "replay_buffer.pkl.gz"]
    assert [f.name for f in save_agent(agent, tmp_path / "small", max_buffer_bytes=10)] == ["agent.zip",
                                                                                            "demo_buffer.pkl.gz"]
    loaded = load_agent(tmp_path / "ckpt", guided)
    obs = env.reset(seed=0)[0]
    np.testing.assert_allclose(loaded.predict(obs, deterministic=True)[0], agent.predict(obs, deterministic=True)[0])
    assert loaded.replay_buffer.size() == 3 * STEPS and loaded.demo_buffer.size() == agent.demo_buffer.size()
    statistics = loaded.actor.features_extractor.normalizers["observation"].running_count
    assert statistics == agent.actor.features_extractor.normalizers["observation"].running_count > 0
    learn_episodes(loaded, 4)
    assert loaded.num_timesteps == 4 * STEPS and loaded.replay_buffer.size() == 4 * STEPS
    # resumed without its replay buffer: the normaliser takes the fresh buffer's new rows, not empty ones
    fresh = load_agent(tmp_path / "small", guided)
    normalizer = fresh.actor.features_extractor.normalizers["observation"]
    count, total = normalizer.running_count.item(), normalizer.running_sum.clone()
    learn_episodes(fresh, 4)
    stored = fresh.replay_buffer.observations["observation"][: fresh.replay_buffer.size(), 0]
    assert normalizer.running_count.item() == count + STEPS and fresh.replay_buffer.size() == STEPS
    torch.testing.assert_close(normalizer.running_sum - total, torch.as_tensor(stored, dtype=torch.float64).sum(0))
    scores = evaluate(loaded, env, episodes=2)
    assert set(scores) == {"success_rate", "collision_rate", "final_distance", "grip_rate", "moved_rate"}
    assert 0 <= scores["success_rate"] <= 1
    assert not any((tmp_path / "tmp").iterdir())  # no SB3-<time> folder per learn call


# --- input normalisation (HER paper) ----------------------------------------------------------------------------------


def test_running_normalizer_standardises_what_it_was_given_and_clips():
    normalizer = RunningNormalizer(3)
    x = torch.tensor([[0.0, 10.0, 2.0], [2.0, 30.0, 2.0]])
    torch.testing.assert_close(normalizer(x), x.clamp(-CLIP, CLIP))  # nothing seen yet: only clipped
    normalizer.train()(x)
    assert normalizer.running_count == 0  # a forward pass, even in training mode, only reads the statistics
    normalizer.update(x.numpy())  # mean [1, 20, 2], std [1, 10, 0 -> the floor 0.01]
    torch.testing.assert_close(normalizer(x), torch.tensor([[-1.0, -1.0, 0.0], [1.0, 1.0, 0.0]]))
    torch.testing.assert_close(normalizer(torch.tensor([[1.0, 20.0, 2.02]])), torch.tensor([[0.0, 0.0, 2.0]]))
    assert normalizer(torch.tensor([[100.0, 20.0, 2.0]]))[0, 0] == CLIP and normalizer.running_count == 2
    copy = RunningNormalizer(3)
    copy.load_state_dict(normalizer.state_dict())  # e.g. a loaded checkpoint: the cached statistics follow
    torch.testing.assert_close(copy(x), normalizer(x))


def test_normalised_agent_takes_its_statistics_from_stored_episodes_with_relabelled_goals(env):
    agent = build_ddpg_her(RLConfig(**TINY), env, seed=0)
    assert isinstance(agent.actor.features_extractor, NormalizedCombinedExtractor)
    learn_episodes(agent, 3)  # trained after episode 3 only (two episodes of warm-up): all 3 episodes are added
    actor, target = agent.critic.features_extractor.normalizers, agent.critic_target.features_extractor.normalizers
    assert set(actor) == {"observation", "achieved_goal", "desired_goal"}
    assert actor["observation"].running_count == 3 * STEPS
    assert actor["desired_goal"].running_count == 3 * STEPS * (1 + 4)  # HER's 4 relabelled goals per original
    torch.testing.assert_close(actor["desired_goal"].running_sum, target["desired_goal"].running_sum)
    # the statistics have a spread (HER mixes relabelled achieved goals with the episodes' goals)
    stats = actor["desired_goal"]
    mean = stats.running_sum / stats.running_count
    assert stats.running_sumsq.sum() > 0 and (stats.running_sumsq / stats.running_count - mean**2).max() > 1e-6
    raw = build_ddpg_her(RLConfig(**TINY, normalize_inputs=False), env, seed=0)
    assert not isinstance(raw.actor.features_extractor, NormalizedCombinedExtractor)


def test_target_networks_move_once_per_cycle_or_after_every_gradient_step(env):
    moved = {}
    for target_update in ("cycle", "step"):
        agent = _filled_agent(env, target_update=target_update, tau=0.5)
        before = [p.detach().clone() for p in agent.critic_target.parameters()]
        online = [p.detach().clone() for p in agent.critic.parameters()]
        agent.train(gradient_steps=1, batch_size=16)  # one step: both update once, from the stepped critic
        once = [p.detach().clone() for p in agent.critic_target.parameters()]
        agent.train(gradient_steps=5, batch_size=16)
        moved[target_update] = sum((a - b).abs().sum().item() for a, b in zip(agent.critic_target.parameters(), once))
        assert any(not torch.equal(a, b) for a, b in zip(before, once)) and online
    assert moved["step"] > 1.5 * moved["cycle"]


def test_learning_rate_falls_linearly_to_its_final_value_at_the_last_epoch(env):
    from hrc_lab.rl.trainer import learning_rate_at

    decaying = RLS.validate({"name": "ddpg_her", "learning_rate": 1e-3, "final_learning_rate": 1e-4})
    assert [round(learning_rate_at(decaying, e, 4), 6) for e in (1, 2, 3, 4)] == [1e-3, 7e-4, 4e-4, 1e-4]
    assert learning_rate_at(RLS.validate({"name": "ddpg_her"}), 3, 4) == 1e-3  # null: the reference's constant
    agent = _filled_agent(env)
    agent.set_learning_rate(2.5e-4)
    agent.train(gradient_steps=1, batch_size=16)
    assert {group["lr"] for opt in (agent.actor.optimizer, agent.critic.optimizer)
            for group in opt.param_groups} == {2.5e-4}


def test_reach_env_goal_is_a_point_near_the_lip_and_its_achieved_goal_is_the_lip():
    cfg = RLConfig(**TINY, suction="auto", delta_r=0.05)
    reach = make_reach_env(correction_cell(task="one_object", sim=SimSettings(yaw_action=True)), cfg, seed=0)
    obs, _ = reach.reset(seed=3)
    assert reach.observation_space["desired_goal"].shape == obs["desired_goal"].shape == (3,)
    np.testing.assert_allclose(obs["achieved_goal"], reach.lip(), atol=1e-6)
    offset = obs["desired_goal"] - obs["achieved_goal"]
    assert np.all(np.abs(offset) <= 0.15 + 1e-6) and offset[2] >= -1e-6
    assert reach.compute_reward(obs["achieved_goal"], obs["desired_goal"], {}) == (
        0.0 if np.linalg.norm(offset) < 0.05 else -1.0)
    obs, reward, *_ = reach.step(np.zeros(reach.action_space.shape, dtype=np.float32))
    assert reward == reach.compute_reward(obs["achieved_goal"], obs["desired_goal"], {})
    with pytest.raises(ValueError, match="reach_m"):
        ReachGoalEnv(reach.cell, reach_m=0.0)


@pytest.mark.slow
def test_ddpg_her_with_normalised_inputs_learns_a_reach_in_the_cell():
    """A learning test that can fail: 125 episodes of 40 steps reach within 5 cm (raw inputs: SR 0 after 400).
    One gradient step per collected step; the targets move once per cycle as in the reference implementation
    (SR 0.6 / 0.7 / 0.9 / 1.0 after 75 / 100 / 125 / 150 episodes, seed 0; with a target update after every
    gradient step, 1.0 from 75)."""
    cfg = RLConfig(suction="auto", delta_r=0.05, net_arch=[64, 64], buffer_size=100_000, gradient_steps=80)
    cell = correction_cell(task="one_object", sim=SimSettings(yaw_action=True))
    agent = learn_episodes(build_ddpg_her(cfg, make_reach_env(cell, cfg, seed=0), seed=0), 125)
    assert evaluate(agent, make_reach_env(cell, cfg, seed=1), episodes=10, seed=1000)["success_rate"] >= 0.7


# --- configs ---------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("values,key", [
    ({"lam": 1.5}, "rl.lam"),
    ({"lam": -0.1}, "rl.lam"),
    ({"delta_g": 0.0}, "rl.delta_g"),
    ({"delta_g": -0.05}, "rl.delta_g"),
    ({"guidance": "expert"}, "rl.guidance"),
    ({"suction": "on"}, "rl.suction"),
    ({"steps_per_subtask": 0}, "rl.steps_per_subtask"),
    ({"goal_selection_strategy": "last"}, "rl.goal_selection_strategy"),
    ({"action_l2": -1.0}, "rl.action_l2"),
    ({"random_eps": 1.3}, "rl.random_eps"),
    ({"lamda": 0.5}, "rl.lamda"),
    ({"yaw_symmetry": 3}, "rl.yaw_symmetry"),
    ({"wrist3": "joint"}, "rl.wrist3"),
    ({"release": "always"}, "rl.release"),
    ({"n_envs": 0}, "rl.n_envs"),
    ({"cycles_per_epoch": 0}, "rl.cycles_per_epoch"),
    ({"episodes_per_cycle": 3, "n_envs": 2}, "rl.episodes_per_cycle"),
    ({"gradient_steps": 0}, "rl.gradient_steps"),
    ({"target_update": "epoch"}, "rl.target_update"),
    ({"demo_batch_size": 256}, "rl.demo_batch_size"),
    ({"guided_episodes": "both"}, "rl.guided_episodes"),
    ({"final_learning_rate": 1e-2}, "rl.final_learning_rate"),
    ({"final_learning_rate": 0.0}, "rl.final_learning_rate"),
])
def test_config_errors_name_the_key(values, key):
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        RLS.validate({"name": "ddpg_her_guided", **values})


def test_builders_reject_the_other_agents_guidance(env):
    with pytest.raises(ValueError, match="rl.guidance: ddpg_her is the unguided agent"):
        RLS.build(RLS.validate({"name": "ddpg_her", "guidance": "ndp"}), env=env)
    with pytest.raises(ValueError, match="rl.guidance: ddpg_her_guided needs"):
        RLS.build(RLS.validate({"name": "ddpg_her_guided", "guidance": "none"}), env=env)


def test_rl_yaml_files_compose_to_their_schemas():
    RLS.store_schemas()  # hrc_lab.config.register_schemas does this once `rl` is one of its groups
    GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
            nodes = {name: compose(config_name=f"rl/{name}").rl for name in ("none", "ddpg_her", "ddpg_her_guided")}
    finally:
        GlobalHydra.instance().clear()
    assert dict(nodes["none"]) == {"name": "none"}
    unguided, guided = RLS.validate(nodes["ddpg_her"]), RLS.validate(nodes["ddpg_her_guided"])
    assert unguided.name == "ddpg_her" and unguided.guidance == "none" and unguided.delta_r is None
    assert guided.name == "ddpg_her_guided" and (guided.guidance, guided.lam, guided.delta_g) == ("ndp", 0.7, 0.05)
    assert guided.delta_r == 0.01 and guided.steps_per_subtask == 40


def test_a_held_start_hands_the_agent_the_lifted_part():
    """rl.start=held (issue 19's placing-only diagnostic): the episode starts with the goal object in the cup,
    lifted to transit height, its step count at 0; the default start leaves it on the table."""
    held = make_goal_env(correction_cell(task="two_object"), RLConfig(**TINY, start="held"), seed=0, subtask=0)
    scene = make_goal_env(correction_cell(task="two_object"), RLConfig(**TINY), seed=0, subtask=0)
    obs, _ = held.reset(seed=3)
    lying, _ = scene.reset(seed=3)
    assert held.cell.suction.held == held.goal_objects[0] and scene.cell.suction.held < 0
    assert obs["observation"][-1] == 1.0 and held.elapsed_steps == 0
    assert obs["achieved_goal"][2] > lying["achieved_goal"][2] + 0.05  # lifted
    keep = np.zeros(held.action_space.shape)
    keep[-1] = 1.0  # joints still, cup on
    _, _, _, _, info = held.step(keep)
    assert info["held"]
    with pytest.raises(ValueError, match="rl.start"):
        RLConfig(start="hovering")
    with pytest.raises(ValueError, match="error correction only"):
        make_goal_env(package_cell(), RLConfig(**TINY, start="held"), seed=0)


def test_a_sequence_start_begins_where_the_expert_left_the_earlier_subtasks():
    """rl.start=sequence: a later subtask starts after the scripted expert's moves of the earlier ones (the placed
    part near its goal, the arm above it, not at home), with a fresh step count and collision record; subtask 0
    starts as the scene does."""
    config = correction_cell(task="two_object")
    sequence = make_goal_env(config, RLConfig(**TINY, start="sequence", suction="auto"), seed=0, subtask=1)
    scene = make_goal_env(config, RLConfig(**TINY), seed=0, subtask=1)
    sequence.reset(seed=3)
    scene.reset(seed=3)
    blue, red = sequence.cell.expert_plan()
    assert sequence.goal_objects == scene.goal_objects == [red] and sequence.elapsed_steps == 0
    placed = sequence.cell.object_positions()[blue]
    assert np.linalg.norm(placed[:2] - sequence.cell.goals[blue][:2]) < 0.01  # where the expert put it
    lip, home = sequence.cell.eef_position(), scene.cell.eef_position()
    assert np.linalg.norm(lip - home) > 0.05 and np.linalg.norm(lip[:2] - placed[:2]) < 0.05  # above blue
    assert sequence.cell.suction.held < 0 and not sequence.cell.collisions
    # the lip rests on the part the expert released: the auto cup stays off until it has left it
    assert sequence.cell.suction.touching() == blue
    _, _, _, _, info = sequence.step(np.zeros(sequence.action_space.shape))
    assert not info["held"] and sequence.cell.suction.held < 0
    first = make_goal_env(config, RLConfig(**TINY, start="sequence"), seed=0, subtask=0)
    first_scene = make_goal_env(config, RLConfig(**TINY), seed=0, subtask=0)
    np.testing.assert_allclose(first.reset(seed=3)[0]["observation"], first_scene.reset(seed=3)[0]["observation"])
    with pytest.raises(ValueError, match="rl.start=sequence"):
        make_goal_env(package_cell(), RLConfig(**TINY, start="sequence"), seed=0)


class _StillAgent:
    """Holds every joint still, the cup on (``rl.suction=action``)."""

    def __init__(self, env):
        self.action = np.zeros(env.action_space.shape)
        self.action[-1] = 1.0

    def predict(self, obs, deterministic=True):
        return self.action, None


def test_evaluation_says_whether_the_policy_held_and_moved_the_part():
    """evaluate's grip_rate / moved_rate (the evaluation twins of the training episodes' rates): a policy that
    keeps still holds the part in every episode that starts with it in the cup and in none that starts with it on
    the table, and moves it in neither."""
    held = make_goal_env(correction_cell(), RLConfig(**TINY, start="held"), seed=0, subtask=0)
    scene = make_goal_env(correction_cell(), RLConfig(**TINY), seed=0, subtask=0)
    from_cup, from_table = evaluate(_StillAgent(held), held, 2), evaluate(_StillAgent(scene), scene, 2)
    assert set(from_cup) == {"success_rate", "collision_rate", "final_distance", "grip_rate", "moved_rate"}
    assert (from_cup["grip_rate"], from_cup["moved_rate"]) == (1.0, 0.0)
    assert (from_table["grip_rate"], from_table["moved_rate"]) == (0.0, 0.0)


def test_run_episode_shows_every_step_to_on_step():
    """``run_episode(on_step=...)`` sees the env and the info of each of the episode's steps, in order."""
    from hrc_lab.rl.agent import run_episode

    held = make_goal_env(correction_cell(), RLConfig(**TINY, start="held"), seed=0, subtask=0)
    seen = []
    info, _ = run_episode(_StillAgent(held), held, seed=0,
                          on_step=lambda env, info: seen.append((env.elapsed_steps, info["held"])))
    assert [step for step, _ in seen] == list(range(1, held.horizon + 1))
    assert all(h for _, h in seen) and info["ever_held"]


# --- the task as 3.3 states it: yaw under the part's symmetry, wrist 3 relative to the base, release on a support ----


def test_yaw_is_scored_under_the_square_parts_fourfold_symmetry(env, monkeypatch):
    """rl.yaw_symmetry=4 (default): a 5 x 5 cm cuboid turned by 90 degrees scores as yaw 0, by 45 degrees as 0.785 rad
    off; the achieved goal carries the wrapped yaw and HER's relabelled goals (wrapped yaws) are scored with the
    wrapped difference. Order 1: the raw yaw (a quarter turn is 1.57 rad off)."""
    raw = make_goal_env(correction_cell(task="two_object"), RLConfig(**TINY, yaw_symmetry=1), seed=0, subtask=0)
    assert env.yaw_orders.tolist() == [4] and raw.yaw_orders.tolist() == [1]
    goal = np.array([0.1, 0.2, 0.82, 0.0])
    for yaw, rewards in ((0.0, (0.0, 0.0)), (np.pi / 2, (0.0, -1.0)), (-np.pi, (0.0, -1.0)), (np.pi / 4, (-1.0, -1.0))):
        achieved = goal + [0.003, 0.0, 0.0, yaw]
        assert (float(env.compute_reward(achieved, goal, {})), float(raw.compute_reward(achieved, goal, {}))) == rewards
    # a relabelled goal just across the wrap from the achieved yaw is 0.004 rad away, not pi / 2
    across = np.array([goal + [0, 0, 0, np.pi / 4 - 0.002], goal + [0, 0, 0, -np.pi / 4 + 0.002]])
    np.testing.assert_array_equal(env.compute_reward(across[:1], across[1:], {}), [0.0])
    np.testing.assert_array_equal(raw.compute_reward(across[:1], across[1:], {}), [-1.0])
    for goal_env, turned in ((env, 0.0), (raw, np.pi / 2)):  # the part at its goal, a quarter turn
        goal_env.reset(seed=3)
        part = goal_env.goal_objects[0]
        goal_env.cell.set_object_pose(part, goal_env.cell.goals[part], yaw=np.pi / 2)
        goal_env.cell.sim.forward()
        obs, reward, *_ = goal_env.step(np.zeros(4))
        assert obs["achieved_goal"][3] == pytest.approx(turned, abs=0.01)
        assert reward == (0.0 if turned == 0.0 else -1.0)
        assert goal_env.goal_distances()[0] == pytest.approx(turned, abs=0.01)
        goal_env.cell.set_object_pose(part, goal_env.cell.goals[part], yaw=np.pi / 4 + 0.1)  # wraps to -pi / 4 + 0.1
        goal_env.cell.sim.forward()
        assert goal_env._achieved()[3] == pytest.approx(-np.pi / 4 + 0.1 if turned == 0.0 else np.pi / 4 + 0.1)
    # a part with a rectangular footprint has twofold symmetry: order 2 from yaw_symmetry=4, 1 from 1
    monkeypatch.setattr(env.cell.cell_objects[1], "half_size", (0.04, 0.025, 0.02))
    assert (env._yaw_order(1), raw._yaw_order(1), env._yaw_order(2)) == (2, 1, 4)
    raw.close()


def test_relative_wrist3_holds_the_held_parts_yaw_while_the_base_turns():
    """rl.wrist3=relative (default): a wrist-3 action of 0 keeps the yaw of the part in the cup while the base turns 5
    degrees a step; rl.wrist3=absolute (the raw joint delta): the part turns with the base."""
    cell = correction_cell(task="one_object", sim=SimSettings(yaw_action=True))
    turned = {}
    for mode in ("relative", "absolute"):
        goal_env = make_goal_env(cell, RLConfig(**TINY, suction="auto", start="held", wrist3=mode), seed=0)
        goal_env.reset(seed=3)
        part, step = goal_env.goal_objects[0], goal_env.max_joint_step
        assert goal_env.cell.suction.held == part
        yaw, base = goal_env.cell.object_yaws()[part], goal_env.cell.arm_qpos()[0]
        for _ in range(6):
            goal_env.step(np.array([1.0, 0.0, 0.0, 0.0]))
        assert goal_env.cell.suction.held == part and goal_env.cell.arm_qpos()[0] - base > 0.4
        turned[mode] = abs(goal_env.cell.object_yaws()[part] - yaw)
        # the remapping, its inverse and the guide's yaw-holding wrist-3 action
        cell_action = goal_env.to_cell_action(np.array([0.5, 0.0, 0.0, 0.2]))
        assert cell_action[3] == pytest.approx((0.7 if mode == "relative" else 0.2) * step)
        np.testing.assert_allclose(goal_env.from_cell_action(cell_action), [0.5, 0.0, 0.0, 0.2], atol=1e-6)
        assert goal_env.hold_yaw_action(0.5) == (0.0 if mode == "relative" else 0.5)
        if mode == "relative":  # clipped to the cell's max joint step
            assert goal_env.to_cell_action(np.array([1.0, 0.0, 0.0, 1.0]))[3] == pytest.approx(step)
        goal_env.close()
    assert turned["relative"] < 0.01 and turned["absolute"] > 0.4
    no_wrist = make_goal_env(correction_cell(task="one_object"), RLConfig(**TINY), seed=0)
    assert no_wrist.hold_yaw_action(0.5) is None
    no_wrist.close()


def test_the_cup_releases_the_part_on_its_support_at_the_goal():
    """rl.release=support (default, rl.suction=auto): driven by the scripted expert's joint motion, the cup releases
    the part once it touches the table at its goal, so it rests there within 1 cm of its goal height and stays when
    the arm rises 10 cm (the cup is on again once the lip has left it); with rl.release=never the cup carries it up."""
    from hrc_lab.env.robot.expert import ScriptedExpert

    cell = correction_cell(task="one_object", sim=SimSettings(horizon=400, yaw_action=True))
    for release in ("support", "never"):
        goal_env = make_goal_env(cell, RLConfig(steps_per_subtask=60, delta_r=0.01, suction="auto", release=release),
                                 seed=0, subtask=0)
        goal_env.reset(seed=0)
        part = goal_env.goal_objects[0]
        expert, truncated, still, up, released = ScriptedExpert(goal_env.cell), False, 0, None, None
        while not truncated:
            step = expert.act()
            if step is not None:
                action = goal_env.from_cell_action(step.action)
            elif (still := still + 1) <= 3:  # the servo settles, then the lip rises 10 cm
                action = np.zeros(4)
            else:
                up = goal_env.cell.eef_position() + [0.0, 0.0, 0.1] if up is None else up
                action = goal_env.from_cell_action([*expert.joint_step(up), 0.0, 1.0])
            _, _, _, truncated, info = goal_env.step(action)
            if released is None and goal_env._cup_off:
                released = goal_env.cell.object_positions()[part].copy()
        position, goal = goal_env.cell.object_positions()[part], goal_env.cell.goals[part]
        if release == "support":
            assert released is not None and np.linalg.norm(released - goal) < 0.01  # released at the goal
            assert not info["held"] and not goal_env._cup_off  # the lip left it: the cup is on again
            assert abs(position[2] - goal[2]) < 0.01 and info["is_success"], info["goal_distances"]
        else:
            assert released is None and info["held"] and position[2] - goal[2] > 0.05
        goal_env.close()
