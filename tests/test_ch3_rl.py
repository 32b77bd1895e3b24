"""Ch.3 guided RL experiments (Fig. 3.13, 3.12, 3.9; hrc_lab/experiments/ch3_rl.py): config errors through the
experiment files (before any work), and a tiny Fig. 3.13 job end to end whose per-epoch metrics land in MLflow
with steps and whose agent is an artifact. (The rl schema's own checks are in tests/test_rl.py; every experiment
file composes and validates in tests/test_config.py.)"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from hrc_lab.config import validate_config
from hrc_lab.registry import ConfigError

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("experiment,overrides,key", [
    ("ch3/fig_3_13", ["rl.lam=1.2"], "rl.lam"),
    ("ch3/fig_3_13", ["rl.delta_g=0"], "rl.delta_g"),
    ("ch3/fig_3_13", ["rl.guidance=oracle"], "rl.guidance"),
    ("ch3/fig_3_13", ["protocol.epochs=0"], "protocol.epochs"),
    ("ch3/fig_3_13", ["rl.cycles_per_epoch=0"], "rl.cycles_per_epoch"),
    ("ch3/fig_3_13", ["rl.n_envs=0"], "rl.n_envs"),
    ("ch3/fig_3_13", ["rl=none"], "rl"),
    ("ch3/fig_3_12", ["rl.guidance=ndp_direction"], "rl.guidance=ndp_direction needs motion.ndp.mode"),
    ("ch3/fig_3_12", ["rl.reward=shaped"], "rl.reward"),
    ("ch3/fig_3_13", ["rl.stage_labels=oracle"], "rl.stage_labels"),
    ("ch3/fig_3_13", ["protocol.final_eval_episodes=-1"], "protocol.final_eval_episodes"),
    ("ch3/fig_3_9", ["rl=ddpg_her"], "rl"),
    ("ch3/fig_3_9", ["protocol.within_m=0"], "protocol.within_m"),
])
def test_experiment_config_errors_name_the_key(compose_config, experiment, overrides, key):
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        validate_config(compose_config(f"experiment={experiment}", *overrides))


TINY = ["hydra.mode=RUN", "env=error_correction_one_object_case1", "seed=0", "trainer.max_epochs=1",
        "motion.steps=10", "motion.ndp.steps=10", "motion.classifier.steps=10", "protocol.demos=2", "protocol.epochs=2",
        "rl.cycles_per_epoch=1", "rl.episodes_per_cycle=1", "rl.gradient_steps=8", "protocol.eval_episodes=1",
        "protocol.checkpoint_every=1", "rl.steps_per_subtask=8", "rl.learning_starts=8", "rl.batch_size=8",
        "rl.demo_batch_size=2", "rl.net_arch=[16]", "rl.buffer_size=200", "protocol.expert_demos=2",
        "rl.bc_pretrain_steps=4", "rl.critic_warmup_steps=2", "protocol.final_eval_episodes=2"]


def test_fig_3_13_logs_per_epoch_metrics_with_steps_and_the_agent(run_job, job_report, tmp_path, monkeypatch,
                                                                   capsys):
    job = run_job("experiment=ch3/fig_3_13", "rl.lam=1", *TINY)
    client, run_id = job.client, job.run.info.run_id
    for metric in ("success_rate", "collision_rate", "grip_rate", "moved_rate", "train_guidance_rate",
                   "env_steps_per_s", "updates_per_s", "train_grip_rate", "train_moved_rate", "train_final_distance"):
        assert [m.step for m in client.get_metric_history(run_id, metric)] == [1, 2], metric
    # the update diagnostics of the epochs that updated (epoch 1's 8 steps are rl.learning_starts): targets within
    # the clipped return range [-1 / (1 - gamma), 0]
    for metric in ("critic_loss", "actor_loss", "q_policy", "target_q", "bc_loss", "bc_share"):
        assert [m.step for m in client.get_metric_history(run_id, metric)] == [2], metric
    assert -50 <= job.run.data.metrics["target_q"] <= 0 and 0 <= job.run.data.metrics["bc_share"] <= 1
    # 3.3's action: the joints (with wrist 3) and no suction dimension; the cup grips what it touches
    assert job.run.data.params["rl.suction"] == "auto"
    guidance = [m.value for m in client.get_metric_history(run_id, "train_guidance_rate")]
    assert all(0 <= g <= 1 for g in guidance) and max(guidance) > 0  # lambda 1: guided episodes correct
    assert client.get_metric_history(run_id, "updates_per_s")[-1].value > 0  # trained after the first episode
    assert job.run.data.tags["method"] == "ddpg_her_guided_lam1"  # runs differing in rl.lam have their own names
    artifacts = {a.path: a.file_size for a in client.list_artifacts(run_id, "agents/subtask0")}
    assert artifacts["agents/subtask0/agent.zip"] < 2**20  # networks and counters, not the agent pickled twice
    assert 0 <= job.metrics["final_success_rate"] <= 1 and job.metrics["n_subtasks"] == 1
    # the final policy on its own held-out scenes, per subtask and over the plan
    assert job.metrics["final_policy_success_rate"] == job.run.data.metrics["final_policy_success_rate_subtask0"]
    assert 0 <= job.metrics["final_policy_distance"] < 1
    # the report draws the curve from the metric history; its row of λ 1 reads the final policy's SR
    import dataclasses

    from hrc_lab.report.ch3_rl import PLAN

    # the plan's Fig. 3.13 studies but the default are left out with this test's settings: no row reads them
    rows = tuple(dataclasses.replace(row, as_written=None) if row.as_written and row.as_written.study.startswith(
        "fig_3_13_") else row for row in PLAN.rows)
    report = job_report(job, "ch3_rl", rows=rows)
    assert re.search(rf"\| one object case1 \| 1 +\| {job.metrics['final_policy_success_rate']:.2f} +\|", report)
    assert "| Hybrid guidance (λ = 0.7): final SR | thesis | 0.95 | 0.91 |" in report
    assert "final policy SR" in report and "2 held-out scenes" in report and "evaluations that held the part" in report
    assert 0 <= job.metrics["final_grip_rate"] <= 1
    # scripts/rl_final_policies.py replays the run's evaluation from its saved agent; with --final the final
    # policy's scenes, scoring what the run logged as final_policy_success_rate
    import runpy
    import sys

    argv = ["rl_final_policies.py", job.run.data.tags["sweep"], "--tracking-uri", job.tracking_uri, "--episodes", "2",
            "--final"]
    monkeypatch.setattr(sys, "argv", argv)
    runpy.run_path(str(ROOT / "scripts" / "rl_final_policies.py"), run_name="__main__")
    table = capsys.readouterr().out
    assert "| one_object_case1 |     1 |          2 |" in table and "yaw within 0.01" in table
    row = next(line for line in table.splitlines() if line.startswith("| one_object_case1"))
    cells = [float(c) for c in row.strip("|").split("|")[1:]]  # lam, episodes, seeds, SR, ..., held the part, ...
    assert cells[3] == round(job.metrics["final_policy_success_rate"], 3)
    assert cells[9] == round(job.run.data.metrics["final_policy_grip_rate_subtask0"], 3)  # the same scenes
    assert (tmp_path / "report" / "ch3_rl" / "fig_3_13.png").exists()


def test_fig_3_9_measures_the_distance_to_the_planners_subgoal(run_job):
    """Fig. 3.9's goal-state positional difference is |sub-goal - end effector| in both arms (the unguided arm's
    planner only tracks its sub-goals), one row per control step that still has its state (not the reset after
    the last), and the task-goal distance beside it."""
    job = run_job("experiment=ch3/fig_3_9", TINY[0], "env=error_correction_place", *TINY[2:7], "protocol.demos=2",
                  "protocol.episodes=2", "rl.steps_per_subtask=8")
    metrics = job.metrics
    for arm in ("guided", "unguided"):
        assert 0 < metrics[f"mean_distance_{arm}"] < 1 and 0 < metrics[f"mean_goal_distance_{arm}"] < 1
        steps = [m.step for m in job.client.get_metric_history(job.run.info.run_id, f"distance_{arm}")]
        assert steps == list(range(1, 8))  # steps 1..7 of 8: the 8th step's state is gone with the reset


@pytest.mark.slow
def test_a_killed_fig_3_13_run_resumes_from_its_agent_checkpoint(run_job):
    """A run killed after its checkpoints: resume_from loads the saved agent (and replay buffer), copies the
    per-epoch curve into the new run and trains only the epochs that were missing (here none)."""
    first = run_job("experiment=ch3/fig_3_13", "rl.lam=0.7", *TINY)
    client, parent = first.client, first.run.info.run_id
    client.set_terminated(parent, "KILLED")
    second = run_job("experiment=ch3/fig_3_13", "rl.lam=0.7", *TINY, f"resume_from={parent}")
    assert second.run.info.run_id != parent and second.run.data.tags["resumed_from"] == parent
    for metric in ("success_rate", "train_guidance_rate"):
        old = [(m.step, m.value) for m in client.get_metric_history(parent, metric)]
        assert sorted((m.step, m.value) for m in client.get_metric_history(second.run.info.run_id, metric)) == old
    assert second.metrics["final_success_rate"] == first.metrics["final_success_rate"]


def test_the_guide_cache_key_names_what_trains_the_guide(compose_config, monkeypatch):
    """The guide (hrc_lab.experiments.ch3_rl.guide_cache_key) is keyed by the seed, the env, the motion config, the
    protocol's demonstration keys, the trainer and the CPU kernels; the arms of a Fig. 3.13 sweep (lambda, delta_g,
    H_lo) and the RL budget share it, and Fig. 3.12's env has its own."""
    from hrc_lab.experiments.ch3_rl import guide_cache_key

    def key(*overrides, experiment="ch3/fig_3_13", seed=0):
        return guide_cache_key(validate_config(compose_config(f"experiment={experiment}", *overrides)), seed)

    base = key()
    shared = [["rl.lam=1"], ["rl.lam=0.7", "rl.delta_g=0.02"], ["rl.subgoal_steps=30"], ["protocol.epochs=3"],
              ["protocol.eval_episodes=5"], ["rl.net_arch=[64]"], ["trainer.default_root_dir=/elsewhere"]]
    for overrides in shared:
        assert key(*overrides) == base, overrides
    own = [["env=error_correction_two_object_case1"], ["motion.steps=17000"], ["motion.ndp.steps=5"],
           ["motion.place_through_grasp=false"], ["protocol.demos=19"], ["protocol.placement_noise=0.01"],
           ["protocol.stage_starts=[demonstrated]"], ["protocol.subgoal_path=eef"], ["trainer.max_epochs=5"],
           ["env.sim.yaw_action=false"]]
    keys = {base, key(seed=1), key(experiment="ch3/fig_3_12")}
    for overrides in own:
        keys.add(key(*overrides))
    assert len(keys) == len(own) + 3  # each changes the key, and to a key of its own
    monkeypatch.setenv("MKL_CBWR", "COMPATIBLE")
    assert key() != base


def test_the_arms_of_one_seed_and_env_share_one_trained_guide(run_job):
    """Two guided arms of a sweep (lambda 1 and 0.7, seed 0, one env) in one runs_dir: the first trains the guide and
    caches it, the second loads it (tag guide_cache), logs the same networks and the fits' curves, and trains as it
    would have with a guide of its own (the bit-identity check of the whole job: scripts/check_rl_identity.py)."""
    first = run_job("experiment=ch3/fig_3_13", "rl.lam=1", *TINY)
    second = run_job("experiment=ch3/fig_3_13", "rl.lam=0.7", *TINY)
    tag_first, tag_second = first.run.data.tags["guide_cache"], second.run.data.tags["guide_cache"]
    assert tag_first.startswith("miss ") and tag_second == "hit " + tag_first.split()[1]
    assert list((first.runs_dir / "cache" / "ch3").glob("guide_*.pkl"))
    client = first.client

    def artifact(run, path):
        return Path(client.download_artifacts(run.info.run_id, path)).read_bytes()

    for path in ("model/subgoal.pt", "model/ndp.pt"):
        assert artifact(first.run, path) == artifact(second.run, path), path
    fits = [key for key in first.run.data.metrics if key.startswith(("classifier-", "subgoal-", "ndp-"))]
    assert fits
    for key in fits:
        assert ([(m.step, m.value) for m in client.get_metric_history(first.run.info.run_id, key)]
                == [(m.step, m.value) for m in client.get_metric_history(second.run.info.run_id, key)]), key
