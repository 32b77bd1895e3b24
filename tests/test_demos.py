"""Demonstration datasets: HDF5 round trip, stage segmentation on known trajectories, the collect job end to end."""

import h5py
import numpy as np
import pytest

from hrc_lab.data.demos import DemoWriter, read_demos
from hrc_lab.data.recording import record_episode
from hrc_lab.data.segmentation import PICK, PLACE, agreement, detect_stages, resample, stage_labels, stage_subgoals
from hrc_lab.env.robot.correction_cell import ErrorCorrection
from hrc_lab.env.robot.expert import ScriptedExpert


def piecewise(points, lengths):
    """A trajectory through ``points`` with ``lengths[i]`` steps on segment i (linear in between)."""
    pieces = [np.linspace(a, b, n, endpoint=False) for a, b, n in zip(points[:-1], points[1:], lengths)]
    return np.concatenate([*pieces, np.asarray(points[-1:], dtype=float)])


def test_segmentation_recovers_known_pick_and_place_stages():
    # object 0 rests 20 steps, is lifted (10), carried (15), lowered (5) and rests; object 1 follows.
    a = piecewise([[0, 0, 0.8], [0, 0, 0.8], [0, 0, 0.95], [0.3, 0.2, 0.95], [0.3, 0.2, 0.8], [0.3, 0.2, 0.8]],
                  [20, 10, 15, 5, 49])
    b = piecewise([[0.1, 0, 0.8], [0.1, 0, 0.8], [0.1, 0, 0.95], [0.4, 0.2, 0.95], [0.4, 0.2, 0.8]],
                  [70, 10, 15, 4])
    positions = np.stack([a, b], axis=1)
    stages = detect_stages(positions, penalty=1e-3)
    assert [(s.obj, s.stage) for s in stages] == [(0, PICK), (0, PLACE), (1, PICK), (1, PLACE)]
    truth = [(0, 30), (30, 50), (50, 80), (80, 99)]
    for stage, (start, end) in zip(stages, truth):
        assert abs(stage.start - start) <= 1 and abs(stage.end - end) <= 1
    labels = stage_labels(stages, len(a), lambda obj, stage: 2 * obj + stage)
    expert = np.repeat([0, 1, 2, 3], [30, 20, 30, 20])
    assert agreement(labels, expert) > 0.95


def test_resample_keeps_the_stage_end_and_spaces_points_evenly():
    path = np.linspace([0, 0, 0], [1, 2, 3], 11)
    points = resample(path, 5)
    assert points.shape == (5, 3)
    assert np.allclose(points[-1], [1, 2, 3]) and np.allclose(points[0], [0.2, 0.4, 0.6])


@pytest.fixture(scope="module")
def demo():
    env = ErrorCorrection(task="two_object", case=1, seed=0)
    return record_episode(env, ScriptedExpert(env)), env


def test_dart_noise_perturbs_what_is_executed_and_records_the_experts_action():
    env = ErrorCorrection(task="one_object", case=1, seed=0)
    executed, step = [], env.step
    env.step = lambda action: (executed.append(np.array(action)), step(action))[1]
    demo = record_episode(env, ScriptedExpert(env), action_noise=0.01, rng=np.random.default_rng(0))
    executed = np.array(executed)
    assert np.array_equal(executed[:, -1], demo.actions[:, -1])  # suction exactly as the expert commanded
    noise = executed[:, :-1] - demo.actions[:, :-1]
    assert 0.008 < noise.std() < 0.012 and abs(noise.mean()) < 0.002
    with pytest.raises(ValueError, match="action_noise needs an rng"):
        record_episode(env, ScriptedExpert(env), action_noise=0.01)
    with pytest.raises(ValueError, match="action_noise must be >= 0"):
        record_episode(env, ScriptedExpert(env), action_noise=-0.01, rng=np.random.default_rng(0))


def test_hdf5_round_trip_in_robomimic_layout(tmp_path, demo):
    demo, env = demo
    demo.stage_bounds, demo.stage_subgoals = stage_subgoals(demo, env.stage_label, 5, "resample")
    path = tmp_path / "demos.hdf5"
    with DemoWriter(path, {"env_name": "ErrorCorrection", "type": 1, "env_kwargs": {}}) as writer:
        writer.add(demo)
        writer.add(demo)
    with h5py.File(path) as f:
        assert {"obs", "actions", "states", "rewards", "dones"} <= set(f["data/demo_0"])
        assert f["data"].attrs["total"] == 2 * len(demo)
    loaded, env_args = read_demos(path)
    assert env_args["env_name"] == "ErrorCorrection" and len(loaded) == 2
    back = loaded[1]
    assert back.success == demo.success and back.episode == demo.episode
    for key in ("actions", "states", "stage_labels", "subgoal_indices", "subgoals", "stage_bounds", "stage_subgoals"):
        assert np.allclose(getattr(back, key), getattr(demo, key)), key
    assert set(back.obs) == set(demo.obs)


def test_recorded_states_replay_to_the_same_observations(demo):
    demo, env = demo
    env.reset()
    env.sim.set_state_from_flattened(demo.states[10])
    env.sim.forward()
    assert np.allclose(env.object_positions().ravel(), demo.obs["object_pos"][10], atol=1e-5)


def test_designed_subgoals_are_the_experts(demo):
    demo, env = demo
    bounds, subgoals = stage_subgoals(demo, env.stage_label, 3, "designed")
    assert subgoals.shape == (4, 3, 3)
    first = demo.subgoals[(demo.stage_labels == env.stage_label(bounds[0, 0], bounds[0, 1]))]
    assert np.allclose(subgoals[0, 0], first[0])


def test_placing_subgoals_from_the_commanded_lip_end_where_the_expert_placed(demo):
    """The servo lags one control step, so the episode's last placing stage, which ends as the expert's command
    reaches the place pose, ends with the measured lip above it (Algorithm 1's guide then held parts 1.4-2.3 cm
    too high); ``lip_target`` re-samples the commanded lip's path (a step earlier, as it leads), whose last point is
    the lowest the expert commanded in the stage: its place pose, also where the expert lifts off afterwards."""
    demo, env = demo
    bounds, measured = stage_subgoals(demo, env.stage_label, 5, "resample")
    _, commanded = stage_subgoals(demo, env.stage_label, 5, "resample", path="lip_target")
    placing = [i for i, (_, stage, _, _) in enumerate(bounds) if stage == PLACE]
    assert len(placing) == 2
    for i in placing:
        start, end = bounds[i, 2], min(bounds[i, 3], len(demo))
        assert commanded[i, -1, 2] == pytest.approx(demo.obs["lip_target_pos"][start:end, 2].min(), abs=1e-3)
    last = placing[-1]
    assert commanded[last, -1, 2] < measured[last, -1, 2] - 0.005  # the measured lip still 1-3 cm above it
    with pytest.raises(ValueError, match="sub-goal path must be one of"):
        stage_subgoals(demo, env.stage_label, 5, "resample", path="joints")


def test_collect_job_writes_demos_and_metrics(run_job, base_run_name):
    job = run_job("experiment=data/collect", "env=error_correction_one_object_case2", "protocol.episodes=2",
                  "protocol.subgoals_per_stage=5", "protocol.subgoal_mode=resample")
    demos, _ = read_demos(job.runs_dir / "data" / "one_object_case2_seed0.hdf5")
    assert len(demos) == 2 and demos[0].stage_subgoals.shape[1:] == (5, 3)
    run = job.run
    assert base_run_name(run) == "data/collect-none-one_object_case2-seed0" and run.info.status == "FINISHED"
    assert run.data.metrics["expert_success_rate"] == 1.0
    assert 0.8 <= run.data.metrics["segmentation_agreement"] <= 1.0
    assert run.data.metrics["env_steps_per_s"] > 0


def test_a_stage_without_a_path_is_left_out_not_a_crash(demo, monkeypatch):
    """A change point at a stage's very start (seen with the expert's placement noise) leaves no path to
    re-sample: the stage is left out, and Table 3.1's demonstrations then drop that demo (stages != 2 per object)."""
    import hrc_lab.data.segmentation as segmentation

    demo, env = demo
    stages = detect_stages(demo.obs["object_pos"].reshape(len(demo), -1, 3))
    empty = segmentation.Stage(stages[1].obj, stages[1].stage, stages[1].start, stages[1].start)
    monkeypatch.setattr(segmentation, "detect_stages", lambda *args: [stages[0], empty, *stages[2:]])
    bounds, subgoals = stage_subgoals(demo, env.stage_label, 5, "resample")
    assert len(bounds) == len(subgoals) == len(stages) - 1
