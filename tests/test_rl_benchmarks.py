"""The public anchor of the DRL agent (hrc_lab/rl/benchmarks.py, conf/experiment/rl/fetch.yaml): gymnasium-robotics'
Fetch tasks through the same DDPG + HER and epoch loop as the robot cells. An unknown task is refused naming it,
FetchReach-v4 is learnt within a small budget (the HER reference reaches ~1.0 there within 1-2 epochs of 10
cycles), and the experiment runs end to end into MLflow."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from hrc_lab.config import validate_config
from hrc_lab.registry import ConfigError
from hrc_lab.rl.benchmarks import FETCH_ENV_IDS, make_fetch_env, train_fetch
from hrc_lab.rl.configs import RLConfig


@pytest.fixture(scope="module", autouse=True)
def one_thread():
    """One torch thread, as a job runs (num_threads 1): on two shared cores two threads per gradient step ran the
    reach test ~10x slower."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def test_an_unknown_env_id_is_refused_naming_it_and_the_known_ones():
    with pytest.raises(ValueError, match=r"FetchSlide-v4.*FetchReach-v4.*FetchPush-v4.*FetchPickAndPlace-v4"):
        make_fetch_env("FetchSlide-v4", seed=0)
    with pytest.raises(ValueError, match="FetchReach-v9"):
        train_fetch("FetchReach-v9", RLConfig(), epochs=1)


def test_the_wrapper_gives_the_loop_what_it_reads_from_a_goal_env():
    """horizon and compute_reward on the outermost env (stable-baselines3's HER buffer and the loop read them there),
    and the info keys of EpisodeMetrics."""
    env = make_fetch_env("FetchPush-v4", seed=0)
    assert env.horizon == 50
    obs, _ = env.reset(seed=1)
    obs, reward, _, _, info = env.step(env.action_space.sample())
    assert {"held", "moved_m", "collided", "goal_distances", "is_success"} <= set(info)
    assert info["goal_distances"][0] == pytest.approx(np.linalg.norm(obs["achieved_goal"] - obs["desired_goal"]))
    # moved_m: the object's distance from its start; shifted 3 cm in x by hand, it reads 3 cm at the next step
    joint = env.unwrapped._utils.get_joint_qpos(env.unwrapped.model, env.unwrapped.data, "object0:joint").copy()
    joint[0] += 0.03
    env.unwrapped._utils.set_joint_qpos(env.unwrapped.model, env.unwrapped.data, "object0:joint", joint)
    _, _, _, _, info = env.step(np.zeros(4))
    assert info["moved_m"] == pytest.approx(0.03, abs=0.005)
    goals = np.stack([obs["achieved_goal"], obs["achieved_goal"]])
    assert list(env.compute_reward(goals, np.stack([obs["desired_goal"], obs["achieved_goal"]]), {})) == [reward, 0]
    env.close()
    dense = make_fetch_env("FetchPush-v4", seed=0, reward="dense")  # rl.reward=dense: the env's own dense reward
    obs, _ = dense.reset(seed=1)
    obs, reward, _, _, info = dense.step(dense.action_space.sample())
    assert reward == pytest.approx(-info["goal_distances"][0], rel=1e-5)
    dense.close()


# Budget measured here (2 cores shared with other jobs; success over 20 evaluation episodes after epochs 1, 2, 3 of 10
# cycles, over seeds): net [64, 64]: 0.3-0.85, 0.75-0.9, 0.8-0.95 (seeds 1-2; 0.8-1.0 after epoch 3 over seeds 0-3
# with 10 episodes), failures being episodes that head away from the goal; [128, 128, 128]: 0.65-0.95, 0.9, 0.95
# (seeds 1-3); the reference's [256, 256, 256]: 0.5-0.8, 0.85-1.0 (seeds 1-3) at ~27 s per epoch. So 3 epochs of
# [128, 128, 128], ~20 s each on a shared core.
REACH = RLConfig(net_arch=[128, 128, 128], cycles_per_epoch=10, learning_starts=0, buffer_size=20_000)


@pytest.mark.slow
def test_ddpg_her_learns_fetch_reach_within_three_epochs_of_ten_cycles():
    logged = []
    curve = train_fetch("FetchReach-v4", REACH, epochs=3, seed=0, eval_episodes=20,
                        log=lambda metrics, epoch: logged.append((epoch, metrics)))
    assert [epoch for epoch, _ in logged] == [1, 2, 3] and len(curve) == 3
    assert curve[-1] >= 0.9, f"FetchReach-v4 success after 3 epochs of 10 cycles: {curve}"
    assert logged[-1][1]["final_distance"] < 0.05 and logged[-1][1]["updates_per_s"] > 0


def test_the_fetch_experiment_validates_and_names_the_task(compose_config):
    validated = validate_config(compose_config("experiment=rl/fetch", "protocol.env_id=FetchPush-v4"))
    assert validated.env.env_id == "FetchPush-v4" and validated.env.scenario == "FetchPush-v4"
    assert validated.rl.net_arch == [256, 256, 256] and validated.rl.name == "ddpg_her"
    for override, key in (("protocol.env_id=FetchSlide-v4", "FetchSlide-v4"), ("protocol.epochs=0", "protocol.epochs"),
                          ("protocol.checkpoint_every=0", "protocol.checkpoint_every"),
                          ("env.env_id=FetchPush-v4", "protocol.env_id"),
                          ("rl=ddpg_her_guided", "rl: protocol rl_fetch runs with rl=ddpg_her")):
        with pytest.raises(ConfigError, match=key):
            validate_config(compose_config("experiment=rl/fetch", override))


def test_the_fetch_experiment_runs_end_to_end(run_job, job_report):
    job = run_job("experiment=rl/fetch", "hydra.mode=RUN", "seed=0", "protocol.epochs=2", "rl.cycles_per_epoch=1",
                  "protocol.eval_episodes=2", "rl.net_arch=[16]", "rl.batch_size=16", "rl.demo_batch_size=4",
                  "rl.gradient_steps=2", "rl.buffer_size=1000")
    client, run_id = job.client, job.run.info.run_id
    for metric in ("success_rate", "final_distance", "train_success_rate", "env_steps_per_s", "updates_per_s",
                   "epoch_s"):
        assert [m.step for m in client.get_metric_history(run_id, metric)] == [1, 2], metric
    assert 0 <= job.metrics["final_success_rate"] <= job.metrics["best_success_rate"] <= 1
    assert job.metrics["n_episodes"] == 4
    # the report's anchor section: the curve's last epochs pooled, and the wall time the epochs logged
    report = job_report(job, "ch3_rl")
    row = next(line for line in report.splitlines() if line.startswith("| FetchReach-v4"))
    cells = [c.strip() for c in row.strip("|").split("|")]  # task, seeds, episodes, final, last 3, best, wall, ...
    curve = [m.value for m in client.get_metric_history(run_id, "success_rate")]
    assert "SR, last 3 epochs" in report and float(cells[4]) == round(sum(curve) / len(curve), 2)
    wall = sum(m.value for m in client.get_metric_history(run_id, "epoch_s")) / 60
    assert float(cells[6]) == round(wall)
    assert job.run.data.tags["scenario"] == "FetchReach-v4" and job.run.data.tags["method"] == "ddpg_her"
    assert job.run.info.run_name.startswith("rl/fetch-ddpg_her-FetchReach-v4-seed0")
    assert "agents/fetch/agent.zip" in {a.path for a in client.list_artifacts(run_id, "agents/fetch")}


def test_every_fetch_id_is_made():
    for env_id in FETCH_ENV_IDS:
        env = make_fetch_env(env_id, seed=0)
        assert env.spec.id == env_id and env.horizon == 50
        env.reset(seed=0)
        if not env.has_object:  # FetchReach: nothing to move
            assert env.step(env.action_space.sample())[-1]["moved_m"] == 0.0
        env.close()


def test_a_killed_fetch_run_resumes_from_its_last_checkpoint(run_job, monkeypatch, tmp_path):
    """Killed in its second epoch, after the first epoch's checkpoint: resume_from loads that agent, copies the first
    epoch's curve and trains only the second (each step logged once), and the run finishes with the whole curve."""
    import signal

    from mlflow.tracking import MlflowClient

    from hrc_lab.interrupts import RunInterrupted
    from hrc_lab.rl import benchmarks

    tiny = ("experiment=rl/fetch", "hydra.mode=RUN", "seed=0", "protocol.epochs=2", "protocol.checkpoint_every=1",
            "rl.cycles_per_epoch=1", "protocol.eval_episodes=2", "rl.net_arch=[16]", "rl.batch_size=16",
            "rl.demo_batch_size=4", "rl.gradient_steps=2", "rl.buffer_size=1000")
    evaluate, calls = benchmarks.evaluate_fetch, []

    def killed_in_epoch_two(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise RunInterrupted(signal.SIGTERM)
        return evaluate(*args, **kwargs)

    monkeypatch.setattr(benchmarks, "evaluate_fetch", killed_in_epoch_two)
    with pytest.raises(RunInterrupted):
        run_job(*tiny)
    monkeypatch.setattr(benchmarks, "evaluate_fetch", evaluate)
    client = MlflowClient(f"sqlite:///{tmp_path / 'runs' / 'mlflow.db'}")  # run_job's store
    (killed,) = client.search_runs([client.get_experiment_by_name("rl/fetch").experiment_id])
    assert killed.info.status == "KILLED"
    parent = killed.info.run_id
    resumed = run_job(*tiny, f"resume_from={parent}")
    run_id = resumed.run.info.run_id
    assert resumed.run.data.tags["resumed_from"] == parent and resumed.run.info.status == "FINISHED"
    steps = [m.step for m in client.get_metric_history(run_id, "success_rate")]
    assert sorted(steps) == [1, 2]  # epoch 1 copied, epoch 2 trained: not both trained afresh
    copied = {m.step: m.value for m in client.get_metric_history(run_id, "success_rate")}
    assert copied[1] == client.get_metric_history(parent, "success_rate")[0].value
    # epoch 1's wall time is the killed run's, to the bit: copied, not trained again
    (first_epoch,) = [m.value for m in client.get_metric_history(run_id, "epoch_s") if m.step == 1]
    assert first_epoch == client.get_metric_history(parent, "epoch_s")[0].value
    assert resumed.metrics["best_success_rate"] == max(copied.values())
    assert resumed.metrics["final_success_rate"] == copied[2] and resumed.metrics["n_episodes"] == 4
